/* btf_gl_egl.c - EGL backend of btf_gl: a headless display, GLES 3.x context.
 *
 * The display: the surfaceless Mesa platform first (llvmpipe or a Mesa GPU driver),
 * then EGL_EXT_platform_device, the first device that gives a GLES 3 context (what
 * an NVIDIA or AMD driver offers without a window system). BTF_EGL_PLATFORM=device
 * skips the Mesa platform (a machine with both Mesa and a GPU driver), =surfaceless
 * skips the devices.
 * No window and no pbuffer: the context is made current with EGL_NO_SURFACE
 * (EGL_KHR_surfaceless_context) and every pass renders into framebuffer objects.
 * GL entry points come from eglGetProcAddress (EGL_KHR_get_all_proc_addresses),
 * so they dispatch to this context even when libOSMesa is linked into the binary.
 */
#include "btf_gl.h"
#include "btf_common.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One EGL context; malloc'd by btf__egl_open, freed by btf__egl_close. */
typedef struct btf__egl {
    EGLDisplay dpy;
    EGLContext ctx;
    char platform[96]; /* how the display was found, for btf_gl_platform */
} btf__egl;

/* The surfaceless display is a per-process singleton inside EGL: count our users so
 * the last close terminates it and an earlier one does not pull it from under another. */
static int btf__egl_display_users;

/* An initialised display of platform for native; EGL_NO_DISPLAY with err set if none. */
static EGLDisplay btf__egl_display(EGLenum platform, void *native, const char *what, btf_error *err)
{
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_display) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: eglGetPlatformDisplayEXT missing (no EGL_EXT_platform_base)");
        return EGL_NO_DISPLAY;
    }
    EGLDisplay dpy = get_display(platform, native, NULL);
    if (dpy == EGL_NO_DISPLAY) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: no %s display (error 0x%x)", what, (unsigned)eglGetError());
        return EGL_NO_DISPLAY;
    }
    EGLint major = 0, minor = 0;
    if (!eglInitialize(dpy, &major, &minor)) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: eglInitialize of the %s display failed (error 0x%x)", what,
                 (unsigned)eglGetError());
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

/* A current GLES 3 context on display dpy (NULL, EGL_NO_DISPLAY: failed already); 0, or
 * -1 with the display released and err set. */
static int btf__egl_try(btf__egl *e, EGLDisplay dpy, btf_error *err)
{
    if (dpy == EGL_NO_DISPLAY)
        return -1;
    e->dpy = dpy;
    if (btf__egl_context(e, err) == BTF_OK && btf__egl_make_current(e, err) == BTF_OK)
        return 0;
    if (e->ctx != EGL_NO_CONTEXT)
        eglDestroyContext(dpy, e->ctx);
    e->ctx = EGL_NO_CONTEXT;
    btf__egl_display_release(dpy);
    e->dpy = EGL_NO_DISPLAY;
    return -1;
}

int btf__gl_pick_device(int n, int (*try_dev)(void *ctx, int i), void *ctx)
{
    for (int i = 0; i < n; i++)
        if (try_dev(ctx, i) == 0)
            return i;
    return -1;
}

/* The devices EGL lists, for btf__egl_try_device; lives for one btf__egl_devices call. */
typedef struct btf__egl_devlist {
    btf__egl *e;
    const EGLDeviceEXT *devs;
    int n;
    btf_error *err;
} btf__egl_devlist;

/* btf__gl_pick_device's try: a GLES 3 context on device i (e->platform names it). */
static int btf__egl_try_device(void *ctx, int i)
{
    btf__egl_devlist *l = ctx;
    char what[48];
    snprintf(what, sizeof what, "device %d of %d", i, l->n);
    if (btf__egl_try(l->e, btf__egl_display(EGL_PLATFORM_DEVICE_EXT, l->devs[i], what, l->err), l->err) != 0)
        return -1;
    snprintf(l->e->platform, sizeof l->e->platform, "EGL %s", what);
    return 0;
}

/* EGL_EXT_platform_device: the first device with a GLES 3 context; 0 or -1. */
static int btf__egl_devices(btf__egl *e, btf_error *err)
{
    PFNEGLQUERYDEVICESEXTPROC query = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    EGLDeviceEXT devs[16];
    EGLint n = 0;
    if (!query || !query(16, devs, &n) || n < 1) {
        btf_fail(err, BTF_ERR_UNSUPPORTED, "gl egl: no EGL device (EGL_EXT_device_enumeration)");
        return -1;
    }
    btf__egl_devlist l = {e, devs, (int)n, err};
    return btf__gl_pick_device((int)n, btf__egl_try_device, &l) >= 0 ? 0 : -1;
}

static btf_result btf__egl_open(void **native, btf_error *err)
{
    btf__egl *e = calloc(1, sizeof *e);
    if (!e)
        return btf_fail(err, BTF_ERR_NOMEM, "gl egl: out of memory");
    e->dpy = EGL_NO_DISPLAY;
    e->ctx = EGL_NO_CONTEXT;
    const char *only = getenv("BTF_EGL_PLATFORM");
    int ok = -1;
    if (!only || strcmp(only, "device") != 0) {
        ok = btf__egl_try(e, btf__egl_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, "surfaceless Mesa", err),
                          err);
        if (ok == 0)
            snprintf(e->platform, sizeof e->platform, "EGL surfaceless Mesa");
    }
    if (ok != 0 && (!only || strcmp(only, "surfaceless") != 0))
        ok = btf__egl_devices(e, err);
    if (ok != 0) {
        btf__egl_close(e);
        return BTF_ERR_UNSUPPORTED;
    }
    *native = e;
    return BTF_OK;
}

static const char *btf__egl_describe(void *native) { return ((btf__egl *)native)->platform; }

static btf__gl_proc btf__egl_getproc(void *native, const char *name)
{
    (void)native;
    return (btf__gl_proc)eglGetProcAddress(name);
}

const btf__gl_backend_vt btf__gl_egl_vt = {
    "egl", btf__egl_open, btf__egl_make_current, btf__egl_getproc, btf__egl_close, btf__egl_describe,
};
