/* test_gl.c - room gl (shaders/host), suite "gl": the headless GL harness (both backends, both target
 * formats), shader assembly from shaders/manifest.json and error reports. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_dirtab.h"
#include "btf_gl.h"
#include "btf_gl_dirs.h"
#include "btf_shader.h"
#include "fixtures.h"

static const btf_gl_backend backends[2] = {BTF_GL_EGL, BTF_GL_OSMESA};

/* Writes a tiny shaders directory: manifest + the given fragment body. */
static void write_shader_dir(char *dir, size_t n, const char *frag_body)
{
    cr_assert(fx_tmpdir(dir, n));
    fx_put_text(dir, "manifest.json",
                "{\"prefix\": [\"#version 300 es\", \"precision highp float;\"],\n"
                " \"programs\": {\"p\": {\"vertex\": [\"v.vert\"], \"fragment\": [\"common.glsl\", \"f.frag\"]},\n"
                "              \"escape\": {\"vertex\": [\"../v.vert\"], \"fragment\": [\"f.frag\"]}}}\n");
    fx_put_text(dir, "v.vert", "void main() { gl_Position = vec4(0.0); }\n");
    /* no final newline on purpose */
    fx_put_text(dir, "common.glsl", "// common\nfloat twice(float x)\n{\n    return 2.0 * x;\n}");
    fx_put_text(dir, "f.frag", frag_body);
}

static void remove_shader_dir(const char *dir)
{
    const char *names[] = {"manifest.json", "v.vert", "common.glsl", "f.frag"};
    char path[512];
    for (int i = 0; i < 4; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        remove(path);
    }
    rmdir(dir);
}

/* ---------------------------------------------------------------- backend choice */

Test(gl, backend_names_parse)
{
    btf_gl_backend b;
    btf_error err = {{0}};
    cr_assert_eq(btf_gl_backend_parse("egl", &b, &err), BTF_OK);
    cr_assert_eq(b, BTF_GL_EGL);
    cr_assert_eq(btf_gl_backend_parse("osmesa", &b, &err), BTF_OK);
    cr_assert_eq(b, BTF_GL_OSMESA);
    cr_assert_eq(btf_gl_backend_parse(NULL, &b, &err), BTF_OK);
    cr_assert_eq(b, BTF_GL_DEFAULT);
    cr_assert_eq(btf_gl_backend_parse("vulkan", &b, &err), BTF_ERR_ARG);
    cr_assert(strstr(err.msg, "vulkan"), "%s", err.msg);
    cr_assert_str_eq(btf_gl_backend_name(BTF_GL_OSMESA), "osmesa");
}

Test(gl, env_selects_backend)
{
    btf_error err = {{0}};
    btf_gl *gl = NULL;
    setenv("BTF_GL_BACKEND", "osmesa", 1);
    cr_assert_eq(btf_gl_create(NULL, &gl, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_backend_of(gl), BTF_GL_OSMESA);
    /* desktop core profile, not ES: proves OSMesa really runs */
    cr_assert(strncmp(btf_gl_version(gl), "OpenGL ES", 9) != 0, "%s", btf_gl_version(gl));
    btf_gl_free(gl);
    setenv("BTF_GL_BACKEND", "egl", 1);
    cr_assert_eq(btf_gl_create(NULL, &gl, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_backend_of(gl), BTF_GL_EGL);
    cr_assert(strncmp(btf_gl_version(gl), "OpenGL ES 3", 11) == 0, "%s", btf_gl_version(gl));
    btf_gl_free(gl);
    setenv("BTF_GL_BACKEND", "d3d12", 1);
    cr_assert_eq(btf_gl_create(NULL, &gl, &err), BTF_ERR_ARG);
    cr_assert_null(gl);
    cr_assert(strstr(err.msg, "BTF_GL_BACKEND") && strstr(err.msg, "d3d12"), "%s", err.msg);
    unsetenv("BTF_GL_BACKEND");
}

Test(gl, invalid_backend_value)
{
    btf_error err = {{0}};
    btf_gl *gl = NULL;
    btf_gl_desc d = {.backend = (btf_gl_backend)7};
    cr_assert_eq(btf_gl_create(&d, &gl, &err), BTF_ERR_ARG);
    cr_assert_null(gl);
    cr_assert_eq(btf_gl_create(&d, NULL, &err), BTF_ERR_ARG);
    btf_gl_free(NULL);
}

/* An EGL display that cannot start must fail with a message naming EGL, not crash:
 * EGL_PLATFORM is ignored by eglGetPlatformDisplayEXT, so break the vendor list instead. */
Test(gl, egl_unavailable_is_clear_error)
{
    setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/vendor.json", 1);
    btf_error err = {{0}};
    btf_gl *gl = NULL;
    btf_gl_desc d = {.backend = BTF_GL_EGL};
    btf_result r = btf_gl_create(&d, &gl, &err);
    cr_assert_neq(r, BTF_OK);
    cr_assert_null(gl);
    cr_assert(strstr(err.msg, "egl"), "%s", err.msg);
    /* default selection falls back to OSMesa */
    unsetenv("BTF_GL_BACKEND");
    d.backend = BTF_GL_DEFAULT;
    cr_assert_eq(btf_gl_create(&d, &gl, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_backend_of(gl), BTF_GL_OSMESA);
    btf_gl_free(gl);
}

/* ---------------------------------------------------------------- targets */

static void check_clear(btf_gl_backend b, btf_gl_format fmt)
{
    btf_gl *gl = fx_gl_open(b);
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_error err = {{0}};
    btf_gl_target *t = NULL;
    const int w = 7, h = 5; /* odd sizes catch row-alignment mistakes */
    cr_assert_eq(btf_gl_target_create(gl, w, h, fmt, 1, &t, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_bind(gl, t);
    const float c[4] = {0.25f, 0.5f, 0.75f, 1.0f};
    f->ClearColor(c[0], c[1], c[2], c[3]);
    f->Clear(GL_COLOR_BUFFER_BIT);
    if (fmt == BTF_GL_RGBA32F) {
        float px[7 * 5 * 4];
        cr_assert_eq(btf_gl_target_read(gl, t, 0, px, &err), BTF_OK, "%s", err.msg);
        for (int i = 0; i < w * h * 4; i++) /* float clears are exact */
            cr_assert_eq(px[i], c[i % 4], "%s texel %d: %g", btf_gl_backend_name(b), i / 4, (double)px[i]);
    } else {
        unsigned char px[7 * 5 * 4];
        cr_assert_eq(btf_gl_target_read(gl, t, 0, px, &err), BTF_OK, "%s", err.msg);
        for (int i = 0; i < w * h * 4; i++) /* unorm conversion: within one step of round(c*255) */
            cr_assert(abs((int)px[i] - (int)lrintf(c[i % 4] * 255.0f)) <= 1, "%s texel %d: %d",
                      btf_gl_backend_name(b), i / 4, px[i]);
    }
    btf_gl_target_free(gl, t);
    btf_gl_free(gl);
}

Test(gl, clear_rgba8_both_backends)
{
    for (int i = 0; i < 2; i++)
        check_clear(backends[i], BTF_GL_RGBA8);
}

Test(gl, clear_rgba32f_both_backends)
{
    for (int i = 0; i < 2; i++)
        check_clear(backends[i], BTF_GL_RGBA32F);
}

Test(gl, target_bad_arguments)
{
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_error err = {{0}};
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, 0, 4, BTF_GL_RGBA8, 1, &t, &err), BTF_ERR_RANGE);
    cr_assert_eq(btf_gl_target_create(gl, 4, 100000, BTF_GL_RGBA8, 1, &t, &err), BTF_ERR_RANGE);
    cr_assert_eq(btf_gl_target_create(gl, 4, 4, BTF_GL_RGBA8, 5, &t, &err), BTF_ERR_RANGE);
    cr_assert_eq(btf_gl_target_create(gl, 4, 4, (btf_gl_format)9, 1, &t, &err), BTF_ERR_ARG);
    cr_assert_null(t);
    cr_assert_eq(btf_gl_target_create(gl, 4, 4, BTF_GL_RGBA8, 2, &t, &err), BTF_OK, "%s", err.msg);
    unsigned char px[4 * 4 * 4];
    cr_assert_eq(btf_gl_target_read(gl, t, 2, px, &err), BTF_ERR_RANGE);
    cr_assert(strstr(err.msg, "attachment 2"), "%s", err.msg);
    GLuint tex = 0;
    cr_assert_eq(btf_gl_texture_create(gl, -1, 4, BTF_GL_RGBA32F, NULL, &tex, &err), BTF_ERR_RANGE);
    btf_gl_target_free(gl, t);
    btf_gl_target_free(gl, NULL);
    btf_gl_free(gl);
}

/* A trivial program into two float targets at once: each fragment writes its own
 * window coordinates; compared with the pixel centres computed here. */
static void check_gradient(btf_gl_backend b, btf_gl_format fmt)
{
    btf_gl *gl = fx_gl_open(b);
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_error err = {{0}};
    btf_shader_program *p = fx_gl_build(gl, "gradient");
    const int w = 13, h = 6;
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, w, h, fmt, 2, &t, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_bind(gl, t);
    f->UseProgram(p->id);
    f->Uniform2f(f->GetUniformLocation(p->id, "u_size"), (float)w, (float)h);
    btf_gl_draw_fullscreen(gl);
    cr_assert_eq(btf_gl_check(gl, "drawing", &err), BTF_OK, "%s", err.msg);
    float got[2][13 * 6 * 4];
    unsigned char bytes[13 * 6 * 4];
    for (int a = 0; a < 2; a++) {
        if (fmt == BTF_GL_RGBA32F) {
            cr_assert_eq(btf_gl_target_read(gl, t, a, got[a], &err), BTF_OK, "%s", err.msg);
        } else {
            cr_assert_eq(btf_gl_target_read(gl, t, a, bytes, &err), BTF_OK, "%s", err.msg);
            for (int i = 0; i < w * h * 4; i++)
                got[a][i] = bytes[i] / 255.0f;
        }
    }
    /* float: interpolated varyings carry ~1e-7 relative error; 8-bit: one step of 1/255 */
    double tol = fmt == BTF_GL_RGBA32F ? 1e-5 : 1.0 / 255.0 + 1e-6;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *c = &got[0][(y * w + x) * 4], *u = &got[1][(y * w + x) * 4];
            double ex = (x + 0.5) / w, ey = (y + 0.5) / h; /* row 0 = bottom (GL order) */
            double want0[4] = {ex, ey, 0.25, 1.0}, want1[4] = {ex, ey, 1.0 - ex, 0.5};
            for (int k = 0; k < 4; k++) {
                cr_assert(fabs(c[k] - want0[k]) <= tol, "%s (%d,%d)[%d] %g vs %g", btf_gl_backend_name(b), x, y, k,
                          (double)c[k], want0[k]);
                cr_assert(fabs(u[k] - want1[k]) <= tol, "%s uv (%d,%d)[%d] %g vs %g", btf_gl_backend_name(b), x, y,
                          k, (double)u[k], want1[k]);
            }
        }
    btf_gl_target_free(gl, t);
    btf_shader_program_free(gl, p);
    btf_gl_free(gl);
}

Test(gl, trivial_shader_rgba32f_both_backends)
{
    for (int i = 0; i < 2; i++)
        check_gradient(backends[i], BTF_GL_RGBA32F);
}

Test(gl, trivial_shader_rgba8_both_backends)
{
    for (int i = 0; i < 2; i++)
        check_gradient(backends[i], BTF_GL_RGBA8);
}

/* Float texture in, float target out: a texel fetch round trip is bit-exact. */
static void check_texture_roundtrip(btf_gl_backend b)
{
    btf_gl *gl = fx_gl_open(b);
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_error err = {{0}};
    float in[3 * 2 * 4];
    for (int i = 0; i < 24; i++)
        in[i] = (float)i * 0.37f - 3.1f;
    GLuint tex = 0;
    cr_assert_eq(btf_gl_texture_create(gl, 3, 2, BTF_GL_RGBA32F, in, &tex, &err), BTF_OK, "%s", err.msg);
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, 3, 2, BTF_GL_RGBA32F, 1, &t, &err), BTF_OK, "%s", err.msg);
    /* copy the texture into the target through a framebuffer blit-free path: attach as read FBO */
    GLuint fbo = 0;
    f->GenFramebuffers(1, &fbo);
    f->BindFramebuffer(GL_FRAMEBUFFER, fbo);
    f->FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
    float out[24];
    f->ReadBuffer(GL_COLOR_ATTACHMENT0);
    f->ReadPixels(0, 0, 3, 2, GL_RGBA, GL_FLOAT, out);
    cr_assert_eq(btf_gl_check(gl, "reading the texture", &err), BTF_OK, "%s", err.msg);
    cr_assert_arr_eq(out, in, sizeof in, "%s", btf_gl_backend_name(b));
    f->DeleteFramebuffers(1, &fbo);
    btf_gl_texture_free(gl, tex);
    btf_gl_target_free(gl, t);
    btf_gl_free(gl);
}

Test(gl, float_texture_upload_both_backends)
{
    for (int i = 0; i < 2; i++)
        check_texture_roundtrip(backends[i]);
}

/* Both backends alive in one process, used alternately: each keeps its own entry
 * points and results (glvnd must not dispatch one context's calls to the other). */
Test(gl, both_backends_in_one_process)
{
    btf_gl *a = fx_gl_open(BTF_GL_EGL), *o = fx_gl_open(BTF_GL_OSMESA);
    btf_error err = {{0}};
    btf_gl_target *ta = NULL, *to = NULL;
    cr_assert_eq(btf_gl_make_current(a, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_target_create(a, 2, 2, BTF_GL_RGBA32F, 1, &ta, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_make_current(o, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_target_create(o, 2, 2, BTF_GL_RGBA32F, 1, &to, &err), BTF_OK, "%s", err.msg);
    for (int round = 0; round < 2; round++) {
        btf_gl *g[2] = {a, o};
        btf_gl_target *t[2] = {ta, to};
        for (int k = 0; k < 2; k++) {
            cr_assert_eq(btf_gl_make_current(g[k], &err), BTF_OK, "%s", err.msg);
            btf_gl_target_bind(g[k], t[k]);
            btf_gl_fn(g[k])->ClearColor((float)k, (float)round, 0.5f, 1.0f);
            btf_gl_fn(g[k])->Clear(GL_COLOR_BUFFER_BIT);
        }
        for (int k = 0; k < 2; k++) {
            float px[16];
            cr_assert_eq(btf_gl_make_current(g[k], &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(btf_gl_target_read(g[k], t[k], 0, px, &err), BTF_OK, "%s", err.msg);
            cr_assert(px[0] == (float)k && px[1] == (float)round && px[2] == 0.5f, "context %d round %d: %g %g", k,
                      round, (double)px[0], (double)px[1]);
        }
    }
    btf_gl_make_current(a, NULL);
    btf_gl_target_free(a, ta);
    btf_gl_make_current(o, NULL);
    btf_gl_target_free(o, to);
    btf_gl_free(a);
    btf_gl_free(o);
}

/* ---------------------------------------------------------------- shader assembly */

Test(gl, assemble_layout_and_line_map)
{
    char dir[256];
    write_shader_dir(dir, sizeof dir, "out vec4 o;\nvoid main() { o = vec4(twice(N)); }\n");
    btf_shader_define defs[2] = {{"N", "0.5"}, {"EMPTY", NULL}};
    btf_shader_desc d = {.dir = dir, .program = "p", .defines = defs, .n_defines = 2};
    btf_shader_source *s = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_FRAGMENT, &s, &err), BTF_OK, "%s", err.msg);
    const char *want = "#version 300 es\nprecision highp float;\n#define N 0.5\n#define EMPTY\n"
                       "// ---- common.glsl\n// common\nfloat twice(float x)\n{\n    return 2.0 * x;\n}\n"
                       "// ---- f.frag\nout vec4 o;\nvoid main() { o = vec4(twice(N)); }\n";
    cr_assert_str_eq(s->text, want);
    cr_assert_eq(s->n_lines, 13);
    cr_assert_eq(s->n_pieces, 2);
    const char *file = NULL;
    cr_assert_eq(btf_shader_source_line(s, 6, &file), 1);
    cr_assert_str_eq(file, "common.glsl");
    cr_assert_eq(btf_shader_source_line(s, 10, &file), 5); /* last line, written without newline */
    cr_assert_str_eq(file, "common.glsl");
    cr_assert_eq(btf_shader_source_line(s, 13, &file), 2);
    cr_assert_str_eq(file, "f.frag");
    cr_assert_eq(btf_shader_source_line(s, 11, &file), 11); /* marker line: no file */
    cr_assert_null(file);
    btf_shader_source_free(s);
    remove_shader_dir(dir);
}

Test(gl, assemble_bad_inputs)
{
    char dir[256];
    write_shader_dir(dir, sizeof dir, "void main() {}\n");
    btf_error err = {{0}};
    btf_shader_source *s = NULL;
    btf_shader_desc d = {.dir = dir, .program = "nope"};
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_VERTEX, &s, &err), BTF_ERR_MISSING);
    cr_assert(strstr(err.msg, "nope"), "%s", err.msg);
    d.program = "escape"; /* "../v.vert" must not be opened */
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_VERTEX, &s, &err), BTF_ERR_FORMAT);
    cr_assert(strstr(err.msg, "../v.vert"), "%s", err.msg);
    btf_shader_define bad = {"1X", "2"};
    d = (btf_shader_desc){.dir = dir, .program = "p", .defines = &bad, .n_defines = 1};
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_VERTEX, &s, &err), BTF_ERR_ARG);
    btf_shader_define multi = {"X", "1\n#version 100"};
    d.defines = &multi;
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_VERTEX, &s, &err), BTF_ERR_ARG);
    cr_assert_null(s);
    /* missing file named by the manifest */
    char path[512];
    snprintf(path, sizeof path, "%s/common.glsl", dir);
    remove(path);
    d = (btf_shader_desc){.dir = dir, .program = "p"};
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_FRAGMENT, &s, &err), BTF_ERR_MISSING);
    cr_assert(strstr(err.msg, "common.glsl"), "%s", err.msg);
    /* broken manifest */
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    fx_write_text(path, "{\"prefix\": [\"#version 300 es\"], \"programs\": {"); /* truncated */
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_FRAGMENT, &s, &err), BTF_ERR_FORMAT);
    cr_assert(strstr(err.msg, "manifest.json"), "%s", err.msg);
    remove_shader_dir(dir);
    d.dir = "/nonexistent/shaders";
    cr_assert_eq(btf_shader_assemble(&d, BTF_SHADER_FRAGMENT, &s, &err), BTF_ERR_MISSING);
    cr_assert(strstr(err.msg, "/nonexistent/shaders/manifest.json"), "%s", err.msg);
}

Test(gl, log_line_formats)
{
    cr_assert_eq(btf_shader_log_line("0:17(12): error: `x' undeclared"), 17);   /* Mesa */
    cr_assert_eq(btf_shader_log_line("ERROR: 0:9: 'x' : undeclared identifier"), 9); /* ANGLE/WebGL */
    cr_assert_eq(btf_shader_log_line("WARNING: 0:3: extension"), 3);
    cr_assert_eq(btf_shader_log_line("0(42) : error C0000: syntax error"), 42); /* NVIDIA */
    cr_assert_eq(btf_shader_log_line("error: linking failed"), 0);
    cr_assert_eq(btf_shader_log_line(""), 0);
}

Test(gl, annotate_places_messages_under_lines)
{
    btf_shader_source s = {.text = "a\nb\nc\n", .n_lines = 3};
    char *r = btf_shader_annotate(&s, "ERROR: 0:2: 'b' : bad\nnote without line\n");
    cr_assert_not_null(r);
    cr_assert_str_eq(r, "note without line\n   1: a\n   2: b\n      ^^^ ERROR: 0:2: 'b' : bad\n   3: c\n");
    free(r);
}

/* A real compile error on both backends: the message names the file and the line in
 * that file, and the report shows the error right under the numbered line. */
Test(gl, compile_error_reported_at_line_both_backends)
{
    char dir[256];
    write_shader_dir(dir, sizeof dir, "out vec4 o;\nvoid main()\n{\n    o = vec4(twice(undeclared_y));\n}\n");
    for (int i = 0; i < 2; i++) {
        btf_gl *gl = fx_gl_open(backends[i]);
        btf_shader_desc d = {.dir = dir, .program = "p"};
        btf_shader_program *p = NULL;
        char *report = NULL;
        btf_error err = {{0}};
        cr_assert_eq(btf_shader_build(gl, &d, &p, &report, &err), BTF_ERR_FORMAT);
        cr_assert_null(p);
        /* assembled: 2 prefix lines, marker, 5 common lines, marker, then f.frag: its line 4 is line 13 */
        cr_assert(strstr(err.msg, "'p' fragment") && strstr(err.msg, "f.frag line 4"), "%s", err.msg);
        cr_assert_not_null(report);
        const char *at = strstr(report, "  13:     o = vec4(twice(undeclared_y));\n      ^^^ ");
        cr_assert(at, "%s", report);
        cr_assert(strstr(at, "undeclared_y"), "%s", report);
        free(report);
        btf_gl_free(gl);
    }
    remove_shader_dir(dir);
}

Test(gl, link_error_reported)
{
    char dir[256];
    /* the fragment shader reads a varying the vertex shader never writes: a link error */
    write_shader_dir(dir, sizeof dir, "in vec3 v_missing;\nout vec4 o;\nvoid main() { o = vec4(v_missing, 1.0); }\n");
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_shader_desc d = {.dir = dir, .program = "p"};
    btf_shader_program *p = NULL;
    char *report = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_shader_build(gl, &d, &p, &report, &err), BTF_ERR_FORMAT);
    cr_assert(strstr(err.msg, "link failed"), "%s", err.msg);
    free(report);
    btf_gl_free(gl);
    remove_shader_dir(dir);
}

/* ---------------------------------------------------------------- angular interpolation */

#define PROBE_W 64
#define PROBE_MAX (PROBE_W * PROBE_W)

/* Query directions: (theta, phi) pairs or vectors, 4 floats each. Test-local. */
typedef struct probe_set {
    int n;
    float q[PROBE_MAX * 4];
} probe_set;

static void probe_add(probe_set *s, float a, float b, float c)
{
    cr_assert(s->n < PROBE_MAX);
    float *q = &s->q[s->n++ * 4];
    q[0] = a;
    q[1] = b;
    q[2] = c;
    q[3] = 0.0f;
}

static unsigned rng_state = 12345u;
static float frand(void) /* xorshift32, uniform in [0, 1) */
{
    return (float)fx_unit(fx_xorshift32(&rng_state));
}

/* Adversarial and random (theta, phi) queries for set d. */
static void angle_queries(const btf_dirset *d, probe_set *s)
{
    const float phis[] = {0.0f, 359.99f, 360.0f, -0.01f, 720.5f, -359.5f, 1e-4f, 180.0f};
    for (int i = 0; i < 8; i++) { /* pole and its neighbourhood, phi wrap */
        probe_add(s, 0.0f, phis[i], 0);
        probe_add(s, 1e-3f, phis[i], 0);
        probe_add(s, 72.0f, phis[i], 0);
    }
    for (int r = 0; r < d->n_rings; r++) { /* ring thetas, just inside/outside, at and between directions */
        const btf_ring *g = &d->rings[r];
        float step = 360.0f / (float)g->count;
        int stride = 1 + d->n_dirs * 11 / 2500; /* keep room for the other cases */
        for (int k = 0; k <= g->count; k += stride) {
            float dt[] = {0.0f, -1e-3f, 1e-3f, -0.5f, 0.5f};
            for (int j = 0; j < 5; j++) {
                probe_add(s, g->theta_deg + dt[j], g->phi_offset_deg + (float)k * step, 0);
                probe_add(s, g->theta_deg + dt[j], g->phi_offset_deg + ((float)k + 0.5f) * step, 0);
            }
            probe_add(s, g->theta_deg, g->phi_offset_deg + (float)k * step - 1e-3f, 0);
        }
    }
    for (float t = 70.0f; t <= 90.0f; t += 0.5f) /* beyond the outer ring, to the horizon */
        for (int k = 0; k < 7; k++)
            probe_add(s, t, (float)k * 51.7f + 0.3f, 0);
    const float below[] = {90.01f, 95.0f, 120.0f, 180.0f, -5.0f};
    for (int i = 0; i < 5; i++)
        probe_add(s, below[i], 33.0f, 0);
    while (s->n < PROBE_MAX) /* random, uniform on the hemisphere by area */
        probe_add(s, acosf(frand()) * 57.29578f, frand() * 360.0f, 0);
}

/* Random vectors (not normalised, some below the horizon) plus the axes. */
static void vector_queries(probe_set *s)
{
    probe_add(s, 0, 0, 1);
    probe_add(s, 0, 0, 7.5f);
    probe_add(s, 1, 0, 0);
    probe_add(s, 0, -1, 0);
    probe_add(s, -1, 1e-6f, 0.1f);
    probe_add(s, 0.3f, 0.2f, -0.5f);
    probe_add(s, 1e-5f, -2e-5f, 1.0f); /* a hair from the pole: theta must stay accurate */
    probe_add(s, -3e-4f, 1e-4f, 0.5f);
    probe_add(s, 1e30f, 1e30f, 1e30f); /* huge: scaled before squaring */
    probe_add(s, 1e-30f, 0.0f, 1e-30f);
    while (s->n < PROBE_MAX) {
        float x = frand() * 2 - 1, y = frand() * 2 - 1, z = frand() * 1.2f - 0.1f;
        probe_add(s, x * 3, y * 3, z * 3);
    }
}

/* Compares per direction index: the summed weight each index gets from the GPU and
 * from the CPU twin btf_dirtab_interp_vec (angles sanitised as the probe does).
 * Equal index sets where weights are not ~0 and weights within tol follow from this.
 * (The table against the ring walk: tests/codec/test_interp.c.) Returns the largest difference. */
static double compare_interp(const btf_dirset *d, const btf_dirtab *tab, const probe_set *s, int vector,
                             const float *gidx, const float *gw, double tol, const char *what)
{
    double worst = 0;
    for (int i = 0; i < s->n; i++) {
        const float *q = &s->q[i * 4];
        float t = q[0] == q[0] ? fminf(fmaxf(q[0], 0.0f), 90.0f) : 0.0f, ph = isfinite(q[1]) ? q[1] : 0.0f;
        float av[3] = {sinf(t * 0.017453292f) * cosf(ph * 0.017453292f),
                       sinf(t * 0.017453292f) * sinf(ph * 0.017453292f), cosf(t * 0.017453292f)};
        btf_interp c = btf_dirtab_interp_vec(tab, vector ? q : av);
        int ids[6];
        double wc[6] = {0}, wg[6] = {0};
        int n = 0;
        for (int k = 0; k < 6; k++) {
            int id = k < 3 ? c.idx[k] : (int)gidx[i * 4 + k - 3];
            cr_assert(id >= 0 && id < d->n_dirs, "%s query %d: index %d out of range", what, i, id);
            int j = 0;
            while (j < n && ids[j] != id)
                j++;
            if (j == n)
                ids[n++] = id;
            if (k < 3)
                wc[j] += c.w[k];
            else
                wg[j] += gw[i * 4 + k - 3];
        }
        for (int j = 0; j < n; j++) {
            double e = fabs(wc[j] - wg[j]);
            worst = e > worst ? e : worst;
            cr_assert(e <= tol && isfinite(wg[j]),
                      "%s query %d (%g, %g, %g): direction %d weight cpu %.7f gpu %.7f\n cpu idx %d %d %d w %g %g %g\n"
                      " gpu idx %g %g %g w %g %g %g",
                      what, i, (double)q[0], (double)q[1], (double)q[2], ids[j], wc[j], wg[j], c.idx[0], c.idx[1],
                      c.idx[2], (double)c.w[0], (double)c.w[1], (double)c.w[2], (double)gidx[i * 4],
                      (double)gidx[i * 4 + 1], (double)gidx[i * 4 + 2], (double)gw[i * 4], (double)gw[i * 4 + 1],
                      (double)gw[i * 4 + 2]);
        }
    }
    return worst;
}

/* Renders the probe program over s and compares with the CPU reference. */
static double run_probe(btf_gl *gl, btf_shader_program *p, const btf_dirset *d, const probe_set *s, int vector,
                        double tol, const char *what)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_error err = {{0}};
    static float in[PROBE_MAX * 4], idx[PROBE_MAX * 4], w[PROBE_MAX * 4];
    memset(in, 0, sizeof in);
    memcpy(in, s->q, sizeof(float) * 4 * (size_t)s->n);
    GLuint tex = 0;
    cr_assert_eq(btf_gl_texture_create(gl, PROBE_W, PROBE_W, BTF_GL_RGBA32F, in, &tex, &err), BTF_OK, "%s", err.msg);
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, PROBE_W, PROBE_W, BTF_GL_RGBA32F, 2, &t, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_bind(gl, t);
    f->UseProgram(p->id);
    btf_dirtab *tab = NULL;
    btf_gl_dirs gd;
    cr_assert_eq(btf_dirtab_build(d, &tab, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_dirs_upload(gl, tab, NULL, NULL, &gd, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_dirs_bind(gl, &gd, p, 1, &err), BTF_OK, "%s", err.msg);
    f->Uniform1i(f->GetUniformLocation(p->id, "u_vector"), vector);
    f->Uniform1i(f->GetUniformLocation(p->id, "u_dirs"), 0);
    f->ActiveTexture(GL_TEXTURE0);
    f->BindTexture(GL_TEXTURE_2D, tex);
    btf_gl_draw_fullscreen(gl);
    cr_assert_eq(btf_gl_target_read(gl, t, 0, idx, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_target_read(gl, t, 1, w, &err), BTF_OK, "%s", err.msg);
    double worst = compare_interp(d, tab, s, vector, idx, w, tol, what);
    btf_gl_dirs_free(gl, &gd);
    btf_dirtab_free(tab);
    btf_gl_target_free(gl, t);
    btf_gl_texture_free(gl, tex);
    return worst;
}

/* Weights within 1e-4 of the CPU reference (the bound for float targets):
 * both sides run the same float32 operations, so only the GPU's sin/cos/division
 * rounding (a few ulp) separates them; at a triangle edge where the two sides pick
 * different triangles, the vertex they disagree on has weight ~0 on both. */
static void check_interp_angles(btf_gl_backend b)
{
    btf_gl *gl = fx_gl_open(b);
    btf_shader_program *p = fx_gl_build(gl, "dirs_probe");
    btf_dirset sets[2] = {btf_dirset_ubo2003(), btf_dirset_dome151()};
    const char *names[2] = {"ubo2003", "dome151"};
    for (int k = 0; k < 2; k++) {
        static probe_set s;
        s.n = 0;
        rng_state = 777u + (unsigned)k;
        angle_queries(&sets[k], &s);
        char what[64];
        snprintf(what, sizeof what, "%s %s angles", btf_gl_backend_name(b), names[k]);
        double worst = run_probe(gl, p, &sets[k], &s, 0, 1e-4, what);
        cr_log_info("%s: max weight difference %.2e over %d queries", what, worst, s.n);
    }
    btf_shader_program_free(gl, p);
    btf_gl_free(gl);
}

Test(gl, interp_matches_cpu_egl) { check_interp_angles(BTF_GL_EGL); }
Test(gl, interp_matches_cpu_osmesa) { check_interp_angles(BTF_GL_OSMESA); }

static void check_interp_vectors(btf_gl_backend b)
{
    btf_gl *gl = fx_gl_open(b);
    btf_shader_program *p = fx_gl_build(gl, "dirs_probe");
    btf_dirset sets[2] = {btf_dirset_ubo2003(), btf_dirset_dome151()};
    for (int k = 0; k < 2; k++) {
        static probe_set s;
        s.n = 0;
        rng_state = 4242u + (unsigned)k;
        vector_queries(&s);
        double worst = run_probe(gl, p, &sets[k], &s, 1, 1e-4, btf_gl_backend_name(b));
        cr_log_info("%s vectors: max weight difference %.2e", btf_gl_backend_name(b), worst);
    }
    btf_shader_program_free(gl, p);
    btf_gl_free(gl);
}

Test(gl, interp_vec_matches_cpu_both_backends)
{
    check_interp_vectors(BTF_GL_EGL);
    check_interp_vectors(BTF_GL_OSMESA);
}

/* A ring table from neither built-in (no pole, odd offsets and counts, 32 rings =
 * the limit) runs through the same shader without new code. Counts grow with
 * sin(theta) as in measured sets: with far fewer directions per ring the zipper
 * triangles become slivers whose weights amplify float rounding beyond 1e-4. */
Test(gl, interp_arbitrary_ring_table)
{
    btf_ring rings[BTF_MAX_RINGS];
    for (int r = 0; r < BTF_MAX_RINGS; r++)
    {
        float theta = 5.0f + 2.5f * (float)r;
        int count = (int)lrintf(40.0f * sinf(theta * 0.017453293f)) + r % 3;
        rings[r] = (btf_ring){theta, count < 4 ? 4 : count, (float)(r * 13 % 40)};
    }
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_make(rings, BTF_MAX_RINGS, &d, &err), BTF_OK, "%s", err.msg);
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_shader_program *p = fx_gl_build(gl, "dirs_probe");
    static probe_set s;
    s.n = 0;
    angle_queries(&d, &s);
    run_probe(gl, p, &d, &s, 0, 1e-4, "32 rings");
    btf_shader_program_free(gl, p);
    btf_gl_free(gl);
}

/* A direction list (no rings): 90 directions on a jittered golden-angle spiral down
 * to 82 degrees, so triangles reach below the horizon to mirror images. */
static btf_dirset spiral_list(void)
{
    static float dirs[90][2];
    rng_state = 90909u;
    for (int i = 0; i < 90; i++) {
        float z = 1.0f - ((float)i + 0.5f) / 90.0f * (1.0f - cosf(82.0f * 0.017453293f));
        dirs[i][0] = fmaxf(acosf(z) * 57.29578f + (frand() - 0.5f) * 0.8f, 0.0f);
        dirs[i][1] = fmodf((float)i * 137.50776f + (frand() - 0.5f) * 3.0f, 360.0f);
    }
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_make_list((const float(*)[2])dirs, 90, &d, &err), BTF_OK, "%s", err.msg);
    return d;
}

/* The list set's qhull triangles and mirror images through the same shader, both
 * backends, angle and vector queries: 1e-4 as for the ring sets (same float32 ops). */
Test(gl, interp_direction_list_both_backends)
{
    btf_dirset d = spiral_list();
    for (int b = 0; b < 2; b++) {
        btf_gl *gl = fx_gl_open(b ? BTF_GL_OSMESA : BTF_GL_EGL);
        btf_shader_program *p = fx_gl_build(gl, "dirs_probe");
        for (int vector = 0; vector < 2; vector++) {
            static probe_set s;
            s.n = 0;
            rng_state = 515u + (unsigned)vector;
            if (vector)
                vector_queries(&s);
            else
                angle_queries(&d, &s);
            double worst = run_probe(gl, p, &d, &s, vector, 1e-4, vector ? "list vectors" : "list angles");
            cr_log_info("%s list %s: max weight difference %.2e", btf_gl_backend_name(b ? BTF_GL_OSMESA : BTF_GL_EGL),
                        vector ? "vectors" : "angles", worst);
        }
        btf_shader_program_free(gl, p);
        btf_gl_free(gl);
    }
}

/* ---------------------------------------------------------------- PCA decode shader */

#include <dirent.h>

#include "btf_gen.h"
#include "btf_gl_package.h"
#include "btf_render.h"
#include "btf_package.h"
#include "btf_decode.h"

#define DEC_W 16 /* material side: 16x16 texels, 81 x 81 directions */
#define DEC_C 4  /* components */
#define DEC_QW 32 /* queries per render: 32 x 32 */
#define DEC_Q (DEC_QW * DEC_QW)

/* Package of a generated knit (k views per block) in a fresh temp dir; path written to pkg. */
static void make_package_on(char *tmp, size_t n, char *pkg, size_t pn, int bits, btf_dirset d, int k)
{
    cr_assert(fx_tmpdir(tmp, n));
    snprintf(pkg, pn, "%s/knit", tmp);
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf *m = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gen_create(&gp, DEC_W, DEC_W, &d, &d, BTF_F32, &m, &err), BTF_OK, "%s", err.msg);
    btf_pca_options po = {0};
    po.k = k;
    po.components = DEC_C;
    btf_package_options ko = {0};
    ko.bits = bits;
    cr_assert_eq(btf_package_compress(m, &po, &ko, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(m);
}

static void make_package(char *tmp, size_t n, char *pkg, size_t pn, int bits)
{
    make_package_on(tmp, n, pkg, pn, bits, fx_dirs19(), 3);
}

/* Decode queries: q0 = (light, u), q1 = (view, v). Adversarial first, then random. */
static void decode_queries(float *q0, float *q1, int count)
{
    const float uvs[] = {0.0f, 1.0f, 0.5f / DEC_W, 1.0f / DEC_W, 0.5f, 15.5f / DEC_W, 0.999999f, -0.3f, 1.7f, 2.0f};
    const float thetas[] = {0.0f, 1e-3f, 15.0f, 30.0f, 45.0f, 60.0f, 74.99f, 75.0f, 80.0f, 89.9f, 90.0f, 95.0f};
    const float phis[] = {0.0f, 359.99f, 360.0f, 30.0f, 7.5f, 180.0f};
    int i = 0;
    for (int a = 0; a < 10 && i < count; a++)
        for (int b = 0; b < 12 && i < count; b++, i++) {
            float *l = &q0[i * 4], *v = &q1[i * 4];
            fx_dirf(thetas[b], phis[(a + b) % 6], l);
            fx_dirf(thetas[(b * 5 + a) % 12], phis[(a * 7 + b) % 6], v);
            l[3] = uvs[a];
            v[3] = uvs[(a + b) % 10];
        }
    for (; i < count; i++) {
        float *l = &q0[i * 4], *v = &q1[i * 4];
        fx_dirf(acosf(frand()) * 57.29578f, frand() * 360.0f, l);
        fx_dirf(acosf(frand()) * 57.29578f, frand() * 360.0f, v);
        l[3] = frand() * 1.2f - 0.1f;
        v[3] = frand() * 1.2f - 0.1f;
    }
}

/* Renders decode_probe for every query into fmt and compares with btf_decode.
 * Float target: every difference within 1e-4 of the full range (values are on the
 * 0..1 byte/255 scale) plus the GPU layout's worst-case requantisation error Q
 * (btf_gl_package_quant_error: 16-bit textures, 11/11/10-bit weights), and the RMS
 * difference within 3e-5 plus its RMS bound R (independent uniform rounding errors):
 * besides requantisation the GPU differs from the CPU only by float rounding in the
 * direction weights (< 3e-5, see the interpolation tests) times values of order 1.
 * R itself must stay below a tenth of a grey level (0.1/255).
 * RGBA8 target: the CPU value clamped to 0..1, within one step of 1/255 plus Q. */
static double decode_compare(btf_gl *gl, btf_shader_program *prog, const btf_package *p, const btf_gl_package *g,
                             btf_gl_format fmt, const btf_gl_decode_settings *s, const char *what)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_error err = {{0}};
    static float q0[DEC_Q * 4], q1[DEC_Q * 4], out[DEC_Q * 4];
    static unsigned char out8[DEC_Q * 4];
    rng_state = 99u;
    decode_queries(q0, q1, DEC_Q);
    GLuint t0 = 0, t1 = 0;
    cr_assert_eq(btf_gl_texture_create(gl, DEC_QW, DEC_QW, BTF_GL_RGBA32F, q0, &t0, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_texture_create(gl, DEC_QW, DEC_QW, BTF_GL_RGBA32F, q1, &t1, &err), BTF_OK, "%s", err.msg);
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, DEC_QW, DEC_QW, fmt, 1, &t, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_bind(gl, t);
    f->UseProgram(prog->id);
    cr_assert_eq(btf_gl_package_bind(gl, g, prog, 0, &err), BTF_OK, "%s", err.msg);
    btf_gl_package_settings(gl, g, prog, s);
    f->ActiveTexture(GL_TEXTURE4);
    f->BindTexture(GL_TEXTURE_2D, t0);
    f->Uniform1i(f->GetUniformLocation(prog->id, "u_q0"), 4);
    f->ActiveTexture(GL_TEXTURE5);
    f->BindTexture(GL_TEXTURE_2D, t1);
    f->Uniform1i(f->GetUniformLocation(prog->id, "u_q1"), 5);
    btf_gl_draw_fullscreen(gl);
    if (fmt == BTF_GL_RGBA32F)
        cr_assert_eq(btf_gl_target_read(gl, t, 0, out, &err), BTF_OK, "%s", err.msg);
    else
        cr_assert_eq(btf_gl_target_read(gl, t, 0, out8, &err), BTF_OK, "%s", err.msg);
    btf_decode_options o = {0};
    o.filter = s->filter ? BTF_FILTER_BILINEAR : BTF_FILTER_NEAREST;
    o.wrap = s->wrap;
    o.n_chunks = s->n_chunks;
    double q, rms_bound, sq = 0;
    btf_gl_package_quant_error(g, &q, &rms_bound);
    cr_assert(rms_bound < 0.1 / 255.0, "%s: requantisation RMS bound %.3g exceeds 0.1/255", what, rms_bound);
    double worst = 0, tol = (fmt == BTF_GL_RGBA32F ? 1e-4 : 1.0 / 255.0 + 1e-6) + q;
    for (int i = 0; i < DEC_Q; i++) {
        float rgb[3];
        btf_decode(p, q0[i * 4 + 3], q1[i * 4 + 3], &q0[i * 4], &q1[i * 4], &o, rgb);
        for (int c = 0; c < 3; c++) {
            double want = rgb[c], got = out[i * 4 + c];
            if (fmt == BTF_GL_RGBA8) {
                want = want < 0 ? 0 : want > 1 ? 1 : want;
                got = out8[i * 4 + c] / 255.0;
            }
            double e = fabs(got - want);
            worst = e > worst ? e : worst;
            sq += e * e;
            cr_assert(e <= tol, "%s query %d (uv %g %g, light %g %g %g, view %g %g %g) c%d: gpu %.7f cpu %.7f", what,
                      i, (double)q0[i * 4 + 3], (double)q1[i * 4 + 3], (double)q0[i * 4], (double)q0[i * 4 + 1],
                      (double)q0[i * 4 + 2], (double)q1[i * 4], (double)q1[i * 4 + 1], (double)q1[i * 4 + 2], c, got,
                      want);
        }
    }
    if (fmt == BTF_GL_RGBA32F)
        cr_assert(sqrt(sq / (3.0 * DEC_Q)) <= 3e-5 + rms_bound, "%s: RMS difference %.3g above %.3g", what,
                  sqrt(sq / (3.0 * DEC_Q)), 3e-5 + rms_bound);
    btf_gl_target_free(gl, t);
    btf_gl_texture_free(gl, t0);
    btf_gl_texture_free(gl, t1);
    return worst;
}

/* Every partial package 1..C, nearest and bilinear, clamp and wrap, on one backend
 * (k views per block). */
static void check_decode_on(btf_gl_backend b, int bits, btf_gl_format fmt, btf_dirset d, int n_first, int k)
{
    char tmp[256], pkg[300];
    make_package_on(tmp, sizeof tmp, pkg, sizeof pkg, bits, d, k);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(p->n_loaded, DEC_C);
    btf_gl *gl = fx_gl_open(b);
    btf_shader_program *prog = fx_gl_build(gl, "decode_probe");
    btf_gl_package *g = NULL;
    cr_assert_eq(btf_gl_package_upload(gl, p, pkg, &g, &err), BTF_OK, "%s", err.msg);
    double worst = 0;
    for (int n = n_first; n <= DEC_C; n++)
        for (int filter = 0; filter < 2; filter++)
            for (int wrap = 0; wrap < 2; wrap++) {
                btf_gl_decode_settings s = {filter, wrap, n};
                char what[128];
                snprintf(what, sizeof what, "%s %d-bit %s n=%d filter=%d wrap=%d", btf_gl_backend_name(b), bits,
                         fmt == BTF_GL_RGBA8 ? "rgba8" : "rgba32f", n, filter, wrap);
                double e = decode_compare(gl, prog, p, g, fmt, &s, what);
                worst = e > worst ? e : worst;
            }
    cr_log_info("decode %s %d-bit %s: max abs difference %.2e", btf_gl_backend_name(b), bits,
                fmt == BTF_GL_RGBA8 ? "rgba8" : "rgba32f", worst);
    btf_gl_package_free(gl, g);
    btf_shader_program_free(gl, prog);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

static void check_decode(btf_gl_backend b, int bits, btf_gl_format fmt)
{
    check_decode_on(b, bits, fmt, fx_dirs19(), 1, 3);
}

/* The decoder specialised at compile time (btf_gl_package_defines: BTF_FILTER,
 * BTF_LEVELS, BTF_QUADS) decodes as the run-time program does: every prefix (1 and
 * 2 layers of 4 slots: DEC_C = 4 gives one; a 6-component package gives two), both
 * filters, within the same bound. */
Test(gl, decode_specialised_matches_cpu)
{
    char tmp[256], pkg[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(pkg, sizeof pkg, "%s/knit", tmp);
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf *m = NULL;
    btf_error err = {{0}};
    btf_dirset d = fx_dirs19();
    cr_assert_eq(btf_gen_create(&gp, DEC_W, DEC_W, &d, &d, BTF_F32, &m, &err), BTF_OK, "%s", err.msg);
    btf_pca_options po = {0};
    po.k = 3, po.components = 6;
    btf_package_options ko = {0};
    ko.bits = 8;
    cr_assert_eq(btf_package_compress(m, &po, &ko, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(m);
    btf_package *p = NULL;
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_gl_package *g = NULL;
    cr_assert_eq(btf_gl_package_upload(gl, p, pkg, &g, &err), BTF_OK, "%s", err.msg);
    for (int n = 1; n <= p->n_loaded; n++)
        for (int filter = 0; filter < 2; filter++) {
            btf_shader_define defs[BTF_GL_PACKAGE_DEFINES];
            char vals[BTF_GL_PACKAGE_DEFINES][16];
            btf_shader_desc sd = {.program = "decode_probe", .defines = defs,
                                  .n_defines = btf_gl_package_defines(g, filter, n, defs, vals)};
            cr_assert_str_eq(defs[2].name, "BTF_QUADS");
            cr_assert_eq(atoi(vals[2]), (n + 3) / 4, "n = %d: %s layers", n, vals[2]);
            btf_shader_program *prog = NULL;
            char *report = NULL;
            cr_assert_eq(btf_shader_build(gl, &sd, &prog, &report, &err), BTF_OK, "%s\n%s", err.msg,
                         report ? report : "");
            free(report);
            btf_gl_decode_settings s = {filter, 1, n};
            char what[96];
            snprintf(what, sizeof what, "specialised n=%d filter=%d", n, filter);
            decode_compare(gl, prog, p, g, BTF_GL_RGBA32F, &s, what);
            btf_shader_program_free(gl, prog);
        }
    btf_gl_package_free(gl, g);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* The real 81 x 81 sampling, complete package only (compression costs seconds). */
Test(gl, decode_matches_cpu_ubo2003_egl) { check_decode_on(BTF_GL_EGL, 8, BTF_GL_RGBA32F, btf_dirset_ubo2003(), DEC_C, 3); }
/* The largest blocks a budget search chooses: 27 views a block (3 blocks) and every
 * view in one block (one texture tile a component). */
Test(gl, decode_matches_cpu_large_blocks_egl)
{
    check_decode_on(BTF_GL_EGL, 8, BTF_GL_RGBA32F, btf_dirset_ubo2003(), DEC_C, 27);
    check_decode_on(BTF_GL_EGL, 8, BTF_GL_RGBA32F, btf_dirset_ubo2003(), DEC_C, 81);
}

Test(gl, decode_matches_cpu_egl_float) { check_decode(BTF_GL_EGL, 8, BTF_GL_RGBA32F); }
/* A list package: the manifest's triangles, the views' blocks through mirror images. */
Test(gl, decode_matches_cpu_direction_list_egl) { check_decode_on(BTF_GL_EGL, 8, BTF_GL_RGBA32F, spiral_list(), DEC_C, 3); }
Test(gl, decode_matches_cpu_osmesa_float) { check_decode(BTF_GL_OSMESA, 8, BTF_GL_RGBA32F); }
Test(gl, decode_matches_cpu_16bit_both_backends)
{
    check_decode(BTF_GL_EGL, 16, BTF_GL_RGBA32F);
    check_decode(BTF_GL_OSMESA, 16, BTF_GL_RGBA32F);
}
Test(gl, decode_matches_cpu_rgba8_both_backends)
{
    check_decode(BTF_GL_EGL, 8, BTF_GL_RGBA8);
    check_decode(BTF_GL_OSMESA, 8, BTF_GL_RGBA8);
}

/* A package read with only its first 2 chunks (as a client holds mid-stream):
 * only those layers are uploaded and the decode still matches. */
Test(gl, decode_partial_package_read)
{
    char tmp[256], pkg[300];
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, 8);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 2, &p, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(p->n_loaded, 2);
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_shader_program *prog = fx_gl_build(gl, "decode_probe");
    btf_gl_package *g = NULL;
    cr_assert_eq(btf_gl_package_upload(gl, p, pkg, &g, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(g->n_chunks, 2);
    btf_gl_decode_settings s = {1, 0, 0};
    decode_compare(gl, prog, p, g, BTF_GL_RGBA32F, &s, "partial read");
    btf_gl_package_free(gl, g);
    btf_shader_program_free(gl, prog);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* ---------------------------------------------------------------- surface rendering */

#define RW 48 /* render target side */

typedef struct vec3d {
    double x, y, z;
} vec3d;
static vec3d v3(double x, double y, double z) { return (vec3d){x, y, z}; }
static vec3d vsub(vec3d a, vec3d b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static vec3d vadd(vec3d a, vec3d b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static vec3d vmul(vec3d a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static double vdot(vec3d a, vec3d b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static vec3d vcross(vec3d a, vec3d b) { return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
static vec3d vnorm(vec3d a) { return vmul(a, 1.0 / sqrt(vdot(a, a))); }

/* Rotation R (rows r[0..2], world = R * object) and its columns as frame axes. */
typedef struct frame3 {
    vec3d ax, ay, az; /* object x, y, z axes in world */
    vec3d origin;
} frame3;

/* Renders a tilted, rotated, shifted plane (object square [-1,1]^2 at z = 0, uv =
 * ((x+1)/2, (1-y)/2): v along image rows, so the tangent's w is +1) through a
 * perspective camera, with the debug outputs of btf_render.frag. Checks, per pixel
 * well inside the plane: uv and local light/view against a CPU ray cast, and the
 * colour against btf_decode at the GPU's own uv/light/view. */
static void check_render_plane(btf_gl_backend b, int filter, float uv_scale)
{
    char tmp[256], pkg[300];
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, 8);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    btf_gl *gl = fx_gl_open(b);
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_shader_define defs[1] = {{"BTF_RENDER_DEBUG", "1"}};
    btf_shader_desc sd = {.program = "render", .defines = defs, .n_defines = 1};
    btf_shader_program *prog = NULL;
    char *report = NULL;
    cr_assert_eq(btf_shader_build(gl, &sd, &prog, &report, &err), BTF_OK, "%s\n%s", err.msg, report ? report : "");
    btf_gl_package *g = NULL;
    cr_assert_eq(btf_gl_package_upload(gl, p, pkg, &g, &err), BTF_OK, "%s", err.msg);

    /* model: Rz(30) then Rx(-35), shifted */
    double cz = cos(M_PI / 6), sz = sin(M_PI / 6), cx = cos(-35 * M_PI / 180), sx = sin(-35 * M_PI / 180);
    frame3 m;
    m.ax = v3(cz, cx * sz, sx * sz);
    m.ay = v3(-sz, cx * cz, sx * cz);
    m.az = v3(0, -sx, cx);
    m.origin = v3(0.1, -0.05, 0.0);
    /* camera: eye, looking at the origin, up +y, vertical fov 60 degrees */
    vec3d eye = v3(0.4, -0.9, 2.4), fwd = vnorm(vmul(eye, -1.0));
    vec3d right = vnorm(vcross(fwd, v3(0, 1, 0))), up = vcross(right, fwd);
    double th = tan(M_PI / 6), zn = 0.1, zf = 10.0;
    float model[16] = {(float)m.ax.x, (float)m.ax.y, (float)m.ax.z, 0, (float)m.ay.x, (float)m.ay.y, (float)m.ay.z, 0,
                       (float)m.az.x, (float)m.az.y, (float)m.az.z, 0, (float)m.origin.x, (float)m.origin.y,
                       (float)m.origin.z, 1};
    /* view_proj = P * V (column-major) */
    double V[16] = {right.x, up.x, -fwd.x, 0, right.y, up.y, -fwd.y, 0, right.z, up.z, -fwd.z, 0,
                    -vdot(right, eye), -vdot(up, eye), vdot(fwd, eye), 1};
    double P[16] = {1 / th, 0, 0, 0, 0, 1 / th, 0, 0, 0, 0, -(zf + zn) / (zf - zn), -1, 0, 0,
                    -2 * zf * zn / (zf - zn), 0};
    float vp[16];
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 4; r++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += P[k * 4 + r] * V[c * 4 + k];
            vp[c * 4 + r] = (float)s;
        }
    vec3d light = vnorm(v3(-0.5, 0.7, 0.9)); /* towards a distant light, world */

    /* the plane: 2 triangles, attributes pos3 normal3 tangent4 uv2 */
    const float corners[6][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, -1}, {1, 1}, {-1, 1}};
    float vtx[6 * 12];
    for (int i = 0; i < 6; i++) {
        float x = corners[i][0], y = corners[i][1];
        float a[12] = {x, y, 0, 0, 0, 1, 1, 0, 0, 1, (x + 1) / 2, (1 - y) / 2};
        memcpy(&vtx[i * 12], a, sizeof a);
    }
    GLuint vao = 0, vbo = 0;
    f->GenVertexArrays(1, &vao);
    f->BindVertexArray(vao);
    f->GenBuffers(1, &vbo);
    f->BindBuffer(GL_ARRAY_BUFFER, vbo);
    f->BufferData(GL_ARRAY_BUFFER, sizeof vtx, vtx, GL_STATIC_DRAW);
    const int sizes[4] = {3, 3, 4, 2}, offs[4] = {0, 3, 6, 10};
    for (int a = 0; a < 4; a++) {
        f->EnableVertexAttribArray((GLuint)a);
        f->VertexAttribPointer((GLuint)a, sizes[a], GL_FLOAT, GL_FALSE, 12 * sizeof(float),
                               (const void *)(size_t)(offs[a] * sizeof(float)));
    }
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, RW, RW, BTF_GL_RGBA32F, 4, &t, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_bind(gl, t);
    f->ClearColor(0, 0, 0, 0);
    f->Clear(GL_COLOR_BUFFER_BIT);
    f->UseProgram(prog->id);
    cr_assert_eq(btf_gl_package_bind(gl, g, prog, 0, &err), BTF_OK, "%s", err.msg);
    btf_gl_decode_settings ds = {filter, uv_scale > 1.0f, 0};
    btf_gl_package_settings(gl, g, prog, &ds);
    f->UniformMatrix4fv(f->GetUniformLocation(prog->id, "u_model"), 1, GL_FALSE, model);
    f->UniformMatrix4fv(f->GetUniformLocation(prog->id, "u_view_proj"), 1, GL_FALSE, vp);
    f->Uniform3f(f->GetUniformLocation(prog->id, "u_camera"), (float)eye.x, (float)eye.y, (float)eye.z);
    f->Uniform4f(f->GetUniformLocation(prog->id, "u_light"), (float)light.x, (float)light.y, (float)light.z, 0.0f);
    f->Uniform2f(f->GetUniformLocation(prog->id, "u_uv_scale"), uv_scale, uv_scale);
    btf_render_params lp = btf_render_defaults(BTF_RENDER_PLANE); /* the point light alone, exposure 1 */
    btf_render_light_uniforms(gl, prog->id, &lp, NULL);
    f->DrawArrays(GL_TRIANGLES, 0, 6);
    cr_assert_eq(btf_gl_check(gl, "drawing the plane", &err), BTF_OK, "%s", err.msg);
    static float out[4][RW * RW * 4];
    for (int a = 0; a < 4; a++)
        cr_assert_eq(btf_gl_target_read(gl, t, a, out[a], &err), BTF_OK, "%s", err.msg);

    btf_decode_options o = {0};
    o.filter = filter ? BTF_FILTER_BILINEAR : BTF_FILTER_NEAREST;
    o.wrap = uv_scale > 1.0f;
    vec3d ll = v3(vdot(light, m.ax), vdot(light, m.ay), vdot(light, m.az));
    int checked = 0;
    for (int py = 0; py < RW; py++)
        for (int px = 0; px < RW; px++) {
            double nx = 2.0 * (px + 0.5) / RW - 1, ny = 2.0 * (py + 0.5) / RW - 1; /* row 0 = bottom */
            vec3d d = vadd(fwd, vadd(vmul(right, nx * th), vmul(up, ny * th)));
            double s = vdot(vsub(m.origin, eye), m.az) / vdot(d, m.az);
            vec3d hit = vadd(eye, vmul(d, s)), rel = vsub(hit, m.origin);
            double ox = vdot(rel, m.ax), oy = vdot(rel, m.ay);
            const float *c = &out[0][(py * RW + px) * 4];
            if (s <= 0 || fabs(ox) > 0.97 || fabs(oy) > 0.97) /* outside, or within a pixel of the edge */
                continue;
            checked++;
            cr_assert_eq(c[3], 1.0f, "%s pixel (%d,%d) inside the plane not drawn", btf_gl_backend_name(b), px, py);
            const float *uv = &out[1][(py * RW + px) * 4], *gl_l = &out[2][(py * RW + px) * 4],
                        *gl_v = &out[3][(py * RW + px) * 4];
            /* perspective-correct float interpolation: ~1e-6; 1e-4 is 0.002 texels */
            double eu = (ox + 1) / 2 * uv_scale, ev = (1 - oy) / 2 * uv_scale;
            cr_assert(fabs(uv[0] - eu) < 1e-4 && fabs(uv[1] - ev) < 1e-4, "pixel (%d,%d): uv %g %g, expected %g %g",
                      px, py, (double)uv[0], (double)uv[1], eu, ev);
            vec3d ev3 = vnorm(vsub(eye, hit)), lv = v3(vdot(ev3, m.ax), vdot(ev3, m.ay), vdot(ev3, m.az));
            vec3d gv = vnorm(v3(gl_v[0], gl_v[1], gl_v[2])), gl3 = vnorm(v3(gl_l[0], gl_l[1], gl_l[2]));
            cr_assert(vdot(vsub(gv, lv), vsub(gv, lv)) < 1e-8, "pixel (%d,%d): local view %g %g %g, expected %g %g %g",
                      px, py, gv.x, gv.y, gv.z, lv.x, lv.y, lv.z);
            cr_assert(vdot(vsub(gl3, ll), vsub(gl3, ll)) < 1e-8, "pixel (%d,%d): local light", px, py);
            float rgb[3];
            double qw, qr; /* worst-case requantisation (see decode_compare) */
            btf_gl_package_quant_error(g, &qw, &qr);
            btf_decode(p, uv[0], uv[1], gl_l, gl_v, &o, rgb);
            for (int k = 0; k < 3; k++) {
                double want = rgb[k] < 0 ? 0 : rgb[k] > 1 ? 1 : rgb[k];
                cr_assert(fabs(c[k] - want) <= 1e-4 + qw, "%s pixel (%d,%d) c%d: gpu %.7f cpu %.7f",
                          btf_gl_backend_name(b), px, py, k, (double)c[k], want);
            }
        }
    cr_log_info("checked %d pixels", checked);
    cr_assert_gt(checked, RW * RW / 8, "only %d pixels on the plane", checked);
    btf_gl_target_free(gl, t);
    f->DeleteBuffers(1, &vbo);
    f->DeleteVertexArrays(1, &vao);
    btf_gl_package_free(gl, g);
    btf_shader_program_free(gl, prog);
    free(report);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(gl, render_plane_matches_decoder_both_backends)
{
    check_render_plane(BTF_GL_EGL, 0, 1.0f);
    check_render_plane(BTF_GL_OSMESA, 1, 2.0f); /* bilinear, tiled twice */
}

/* A stub device list for btf__gl_pick_device: device i opens when ok[i]; the tries are
 * recorded in order. Lives for one test. */
typedef struct stub_devices {
    const int *ok;
    int tried[8], n_tried;
} stub_devices;

static int stub_try(void *ctx, int i)
{
    stub_devices *d = ctx;
    d->tried[d->n_tried++] = i;
    return d->ok[i] ? 0 : -1;
}

/* The EGL backend takes the first device that gives a GLES 3 context (a GPU driver may
 * list devices that cannot, e.g. a display-only one before the GPU), tries none after
 * it, and fails cleanly when none does: on stub lists, since this machine's Mesa lists
 * one device that always works. */
Test(gl, egl_device_pick_takes_the_first_device_that_opens)
{
    static const int later[4] = {0, 0, 1, 1}, first[3] = {1, 0, 1}, none[3] = {0, 0, 0};
    stub_devices d = {later, {0}, 0};
    cr_expect_eq(btf__gl_pick_device(4, stub_try, &d), 2);
    cr_expect_eq(d.n_tried, 3, "tried %d devices", d.n_tried);
    for (int i = 0; i < d.n_tried; i++)
        cr_expect_eq(d.tried[i], i, "try %d was device %d", i, d.tried[i]);
    d = (stub_devices){first, {0}, 0};
    cr_expect_eq(btf__gl_pick_device(3, stub_try, &d), 0);
    cr_expect_eq(d.n_tried, 1);
    d = (stub_devices){none, {0}, 0};
    cr_expect_eq(btf__gl_pick_device(3, stub_try, &d), -1);
    cr_expect_eq(d.n_tried, 3);
    d = (stub_devices){none, {0}, 0};
    cr_expect_eq(btf__gl_pick_device(0, stub_try, &d), -1);
    cr_expect_eq(d.n_tried, 0);
}

/* The EGL backend finds its display on the surfaceless Mesa platform, or through
 * EGL_EXT_platform_device (how an NVIDIA or AMD driver offers a headless GPU; Mesa
 * lists its software device there too): BTF_EGL_PLATFORM picks one, and either
 * draws the same gradient; btf_gl_platform says which was used. */
Test(gl, egl_finds_a_display_on_either_platform)
{
    static const char *const want[2][2] = {{"surfaceless", "EGL surfaceless Mesa"}, {"device", "EGL device 0 of "}};
    for (int i = 0; i < 2; i++) {
        setenv("BTF_EGL_PLATFORM", want[i][0], 1);
        btf_gl *gl = fx_gl_open(BTF_GL_EGL);
        cr_expect(!strncmp(btf_gl_platform(gl), want[i][1], strlen(want[i][1])), "%s: platform %s", want[i][0],
                  btf_gl_platform(gl));
        cr_expect_gt(strlen(btf_gl_renderer(gl)), 0);
        btf_gl_free(gl);
        check_gradient(BTF_GL_EGL, BTF_GL_RGBA32F);
    }
    unsetenv("BTF_EGL_PLATFORM");
    btf_gl *gl = fx_gl_open(BTF_GL_OSMESA);
    cr_expect_str_eq(btf_gl_platform(gl), "OSMesa");
    btf_gl_free(gl);
}
