/* test_gl_util.h - GL helpers shared by the Criterion GL tests (header only). */
#ifndef BTF_TEST_GL_UTIL_H
#define BTF_TEST_GL_UTIL_H

#include <criterion/criterion.h>
#include <stdlib.h>

#include "btf_gl.h"
#include "btf_shader.h"

/* Context on backend b; the test fails with the backend's message if it cannot start. */
static inline btf_gl *open_gl(btf_gl_backend b)
{
    btf_gl *gl = NULL;
    btf_error err = {{0}};
    btf_gl_desc d = {.backend = b};
    cr_assert_eq(btf_gl_create(&d, &gl, &err), BTF_OK, "%s: %s", btf_gl_backend_name(b), err.msg);
    return gl;
}

/* Program `program` of shaders/manifest.json; the test fails with the numbered-source report. */
static inline btf_shader_program *build(btf_gl *gl, const char *program)
{
    btf_shader_desc d = {.program = program};
    btf_shader_program *p = NULL;
    char *report = NULL;
    btf_error err = {{0}};
    btf_result r = btf_shader_build(gl, &d, &p, &report, &err);
    cr_assert_eq(r, BTF_OK, "%s\n%s", err.msg, report ? report : "");
    free(report);
    return p;
}

#endif
