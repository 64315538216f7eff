/* btf_gl_egl.c - EGL backend of btf_gl: surfaceless Mesa display, GLES 3.x context.
 *
 * No window and no pbuffer: the context is made current with EGL_NO_SURFACE
 * (EGL_KHR_surfaceless_context) and every pass renders into framebuffer objects.
 * GL entry points come from eglGetProcAddress (EGL_KHR_get_all_proc_addresses),
 * so they dispatch to this context even when libOSMesa is linked into the binary.
 */
#include "btf_gl.h"
#include "btf_common.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <stdlib.h>

/* One EGL context; malloc'd by btf__egl_open, freed by btf__egl_close. */
typedef struct btf__egl {
    EGLDisplay dpy;
    EGLContext ctx;
} btf__egl;

/* The surfaceless display is a per-process singleton inside EGL: count our users so
 * the last close terminates it and an earlier one does not pull it from under another. */
static int btf__egl_display_users;

static EGLDisplay btf__egl_display(btf_error *err)
{
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_display) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: eglGetPlatformDisplayEXT missing (no EGL_EXT_platform_base)");
        return EGL_NO_DISPLAY;
    }
    EGLDisplay dpy = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (dpy == EGL_NO_DISPLAY) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: no surfaceless Mesa display (error 0x%x)", (unsigned)eglGetError());
        return EGL_NO_DISPLAY;
    }
    EGLint major = 0, minor = 0;
    if (!eglInitialize(dpy, &major, &minor)) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: eglInitialize failed (error 0x%x)", (unsigned)eglGetError());
        return EGL_NO_DISPLAY;
    }
    btf__egl_display_users++;
    return dpy;
}

/* The display stays initialised for the life of the process once the last user is
 * gone: eglTerminate unloads the driver, whose few retained allocations
 * LeakSanitizer could then no longer attribute (tests/lsan.supp names the driver). */
static void btf__egl_display_release(EGLDisplay dpy)
{
    (void)dpy;
    btf__egl_display_users--;
}

static btf_result btf__egl_context(btf__egl *e, btf_error *err)
{
    static const EGLint config_attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                            EGL_OPENGL_ES3_BIT, EGL_NONE};
    static const EGLint ctx_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_NONE};
    EGLConfig config;
    EGLint n = 0;
    if (!eglChooseConfig(e->dpy, config_attribs, &config, 1, &n) || n < 1)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: no config with PBUFFER_BIT and OPENGL_ES3_BIT (error 0x%x)",
                        (unsigned)eglGetError());
    if (!eglBindAPI(EGL_OPENGL_ES_API))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: eglBindAPI(GLES) failed (error 0x%x)",
                        (unsigned)eglGetError());
    e->ctx = eglCreateContext(e->dpy, config, EGL_NO_CONTEXT, ctx_attribs);
    if (e->ctx == EGL_NO_CONTEXT)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: cannot create a GLES 3 context (error 0x%x)",
                        (unsigned)eglGetError());
    return BTF_OK;
}

static void btf__egl_close(void *native)
{
    btf__egl *e = native;
    if (!e)
        return;
    if (e->ctx != EGL_NO_CONTEXT) {
        if (eglGetCurrentContext() == e->ctx)
            eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(e->dpy, e->ctx);
    }
    if (e->dpy != EGL_NO_DISPLAY)
        btf__egl_display_release(e->dpy);
    free(e);
}

static btf_result btf__egl_make_current(void *native, btf_error *err)
{
    btf__egl *e = native;
    if (!eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, e->ctx))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: eglMakeCurrent (surfaceless) failed (error 0x%x)",
                        (unsigned)eglGetError());
    return BTF_OK;
}

static btf_result btf__egl_open(void **native, btf_error *err)
{
    btf__egl *e = calloc(1, sizeof *e);
    if (!e)
        return btf_fail(err, BTF_ERR_NOMEM, "gl egl: out of memory");
    e->dpy = EGL_NO_DISPLAY;
    e->ctx = EGL_NO_CONTEXT;
    btf_result r = BTF_OK;
    e->dpy = btf__egl_display(err);
    if (e->dpy == EGL_NO_DISPLAY)
        r = BTF_ERR_UNSUPPORTED;
    if (r == BTF_OK)
        r = btf__egl_context(e, err);
    if (r == BTF_OK)
        r = btf__egl_make_current(e, err);
    if (r != BTF_OK) {
        btf__egl_close(e);
        return r;
    }
    *native = e;
    return BTF_OK;
}

static btf__gl_proc btf__egl_getproc(void *native, const char *name)
{
    (void)native;
    return (btf__gl_proc)eglGetProcAddress(name);
}

const btf__gl_backend_vt btf__gl_egl_vt = {
    "egl", btf__egl_open, btf__egl_make_current, btf__egl_getproc, btf__egl_close,
};
