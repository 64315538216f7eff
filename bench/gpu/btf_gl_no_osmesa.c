/* btf_gl_no_osmesa.c - the OSMesa backend table for the GPU bench folder (make
 * bench-gpu), which carries no Mesa: opening it says so. The product links
 * shaders/host/btf_gl_osmesa.c. */
#include "btf_gl.h"
#include "btf_common.h"

static btf_result no_open(void **native, btf_error *err)
{
    *native = NULL;
    return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl osmesa: not in this build (the GPU bench folder uses EGL only)");
}

static btf_result no_current(void *native, btf_error *err)
{
    (void)native;
    return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl osmesa: not in this build");
}

static btf__gl_proc no_proc(void *native, const char *name)
{
    (void)native, (void)name;
    return NULL;
}

static void no_close(void *native) { (void)native; }

static const char *no_describe(void *native)
{
    (void)native;
    return "none";
}

const btf__gl_backend_vt btf__gl_osmesa_vt = {"osmesa", no_open, no_current, no_proc, no_close, no_describe};
