/* btf_gl_osmesa.c - OSMesa backend of btf_gl: desktop core-profile 3.3+ context.
 *
 * The same `#version 300 es` shaders compile here (ARB_ES3_compatibility). OSMesa
 * needs a colour buffer to be made current; a tiny one is kept and never drawn to:
 * every pass renders into framebuffer objects, as with EGL. Entry points come from
 * OSMesaGetProcAddress, never from global symbols (glvnd would dispatch them to EGL).
 */
#include "btf_gl.h"
#include "btf_common.h"

#include <GL/osmesa.h>
#include <stdlib.h>

#define BTF__OSMESA_BUF 4 /* side of the dummy default framebuffer, texels */

/* One OSMesa context and its dummy buffer; malloc'd by open, freed by close. */
typedef struct btf__osmesa {
    OSMesaContext ctx;
    unsigned char buf[BTF__OSMESA_BUF * BTF__OSMESA_BUF * 4];
} btf__osmesa;

static void btf__osmesa_close(void *native)
{
    btf__osmesa *o = native;
    if (!o)
        return;
    if (o->ctx) {
        if (OSMesaGetCurrentContext() == o->ctx)
            OSMesaMakeCurrent(NULL, NULL, 0, 0, 0);
        OSMesaDestroyContext(o->ctx);
    }
    free(o);
}

static btf_result btf__osmesa_make_current(void *native, btf_error *err)
{
    btf__osmesa *o = native;
    if (!OSMesaMakeCurrent(o->ctx, o->buf, GL_UNSIGNED_BYTE, BTF__OSMESA_BUF, BTF__OSMESA_BUF))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl osmesa: OSMesaMakeCurrent failed");
    return BTF_OK;
}

static btf_result btf__osmesa_open(void **native, btf_error *err)
{
    static const int attribs[] = {OSMESA_FORMAT,
                                  OSMESA_RGBA,
                                  OSMESA_DEPTH_BITS,
                                  0,
                                  OSMESA_STENCIL_BITS,
                                  0,
                                  OSMESA_PROFILE,
                                  OSMESA_CORE_PROFILE,
                                  OSMESA_CONTEXT_MAJOR_VERSION,
                                  3,
                                  OSMESA_CONTEXT_MINOR_VERSION,
                                  3,
                                  0};
    btf__osmesa *o = calloc(1, sizeof *o);
    if (!o)
        return btf_fail(err, BTF_ERR_NOMEM, "gl osmesa: out of memory");
    o->ctx = OSMesaCreateContextAttribs(attribs, NULL);
    if (!o->ctx) {
        free(o);
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl osmesa: cannot create a core profile 3.3 context");
    }
    btf_result r = btf__osmesa_make_current(o, err);
    if (r != BTF_OK) {
        btf__osmesa_close(o);
        return r;
    }
    *native = o;
    return BTF_OK;
}

static btf__gl_proc btf__osmesa_getproc(void *native, const char *name)
{
    (void)native;
    return (btf__gl_proc)OSMesaGetProcAddress(name);
}

static const char *btf__osmesa_describe(void *native)
{
    (void)native;
    return "OSMesa";
}

const btf__gl_backend_vt btf__gl_osmesa_vt = {
    "osmesa", btf__osmesa_open, btf__osmesa_make_current, btf__osmesa_getproc, btf__osmesa_close, btf__osmesa_describe,
};
