/* btf_gl.c - backend-neutral part of the headless GL harness: backend choice,
 * function table, textures, framebuffers, readback. The backends live in
 * btf_gl_egl.c and btf_gl_osmesa.c; this file only calls them through their tables. */
#include "btf_gl.h"
#include "btf_common.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A live context: backend table, backend state, GL entry points. Owned by the caller
 * of btf_gl_create until btf_gl_free. */
struct btf_gl {
    btf_gl_backend backend;
    const btf__gl_backend_vt *vt;
    void *native;
    btf_gl_api fn;
    GLuint vao; /* empty vertex array: core profiles draw nothing without one */
    GLuint timer; /* the query of btf_gl_timer_begin, made on first use */
    int timer_state;           /* 0 not looked up, 1 timer queries, -1 none */
    btf__gl_proc timer_get;    /* glGetQueryObjectui64v(EXT) */
};

/* ---------------------------------------------------------------- backend choice */

const char *btf_gl_backend_name(btf_gl_backend b)
{
    switch (b) {
    case BTF_GL_EGL: return "egl";
    case BTF_GL_OSMESA: return "osmesa";
    case BTF_GL_DEFAULT: return "default";
    }
    return "unknown";
}

btf_result btf_gl_backend_parse(const char *s, btf_gl_backend *out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "gl: NULL argument");
    if (!s || !*s)
        *out = BTF_GL_DEFAULT;
    else if (!strcmp(s, "egl"))
        *out = BTF_GL_EGL;
    else if (!strcmp(s, "osmesa"))
        *out = BTF_GL_OSMESA;
    else
        return btf_fail(err, BTF_ERR_ARG, "gl: unknown backend '%s' (expected egl or osmesa)", s);
    return BTF_OK;
}

static const btf__gl_backend_vt *btf__gl_vt(btf_gl_backend b)
{
    return b == BTF_GL_OSMESA ? &btf__gl_osmesa_vt : &btf__gl_egl_vt;
}

/* ---------------------------------------------------------------- context */

static btf_result btf__gl_load(btf_gl *gl, btf_error *err)
{
#define BTF__GL_LOAD(T, N)                                                                                       \
    gl->fn.N = (T)gl->vt->getproc(gl->native, "gl" #N);                                                          \
    if (!gl->fn.N)                                                                                               \
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl %s: entry point gl%s not found", gl->vt->name, #N);
    BTF_GL_FUNCS(BTF__GL_LOAD)
#undef BTF__GL_LOAD
    return BTF_OK;
}

/* GLES >= 3.0 or desktop GL >= 3.3 (which runs `#version 300 es` via ARB_ES3_compatibility). */
static btf_result btf__gl_check_version(btf_gl *gl, btf_error *err)
{
    const char *v = (const char *)gl->fn.GetString(GL_VERSION);
    if (!v)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl %s: glGetString(GL_VERSION) returned NULL (no current context)",
                        gl->vt->name);
    int es = !strncmp(v, "OpenGL ES ", 10);
    int major = 0, minor = 0;
    if (sscanf(es ? v + 10 : v, "%d.%d", &major, &minor) != 2)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl %s: cannot parse GL_VERSION '%s'", gl->vt->name, v);
    int need_minor = es ? 0 : 3;
    if (major < 3 || (major == 3 && minor < need_minor))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl %s: version '%s' too old (need ES 3.0 or GL 3.3)", gl->vt->name,
                        v);
    return BTF_OK;
}

static btf_result btf__gl_open(btf_gl *gl, btf_gl_backend backend, btf_error *err)
{
    gl->backend = backend;
    gl->vt = btf__gl_vt(backend);
    btf_result r = gl->vt->open(&gl->native, err);
    if (r == BTF_OK)
        r = btf__gl_load(gl, err);
    if (r == BTF_OK)
        r = btf__gl_check_version(gl, err);
    if (r == BTF_OK) {
        gl->fn.GenVertexArrays(1, &gl->vao);
        gl->fn.BindVertexArray(gl->vao);
        r = btf_gl_check(gl, "creating the vertex array", err);
    }
    if (r != BTF_OK && gl->native) {
        gl->vt->close(gl->native);
        gl->native = NULL;
    }
    return r;
}

void btf_gl_free(btf_gl *gl)
{
    if (!gl)
        return;
    if (gl->native) {
        if (gl->vt->make_current(gl->native, NULL) == BTF_OK && gl->vao)
            gl->fn.DeleteVertexArrays(1, &gl->vao);
        if (gl->timer)
            gl->fn.DeleteQueries(1, &gl->timer);
        gl->vt->close(gl->native);
    }
    free(gl);
}

btf_result btf_gl_create(const btf_gl_desc *desc, btf_gl **out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "gl: NULL argument");
    *out = NULL;
    btf_gl_backend backend = desc ? desc->backend : BTF_GL_DEFAULT;
    if (backend != BTF_GL_DEFAULT && backend != BTF_GL_EGL && backend != BTF_GL_OSMESA)
        return btf_fail(err, BTF_ERR_ARG, "gl: invalid backend %d", (int)backend);
    if (backend == BTF_GL_DEFAULT) {
        const char *env = getenv("BTF_GL_BACKEND");
        if (btf_gl_backend_parse(env, &backend, NULL) != BTF_OK)
            return btf_fail(err, BTF_ERR_ARG, "BTF_GL_BACKEND: unknown backend '%s' (expected egl or osmesa)", env);
    }
    btf_gl *gl = calloc(1, sizeof *gl);
    if (!gl)
        return btf_fail(err, BTF_ERR_NOMEM, "gl: out of memory");
    btf_result r;
    if (backend != BTF_GL_DEFAULT) {
        r = btf__gl_open(gl, backend, err); /* named backend: no fallback */
    } else {
        btf_error first = {{0}}, second = {{0}};
        r = btf__gl_open(gl, BTF_GL_EGL, &first);
        if (r != BTF_OK) {
            r = btf__gl_open(gl, BTF_GL_OSMESA, &second);
            if (r != BTF_OK)
                btf_fail(err, r, "gl: no backend available: %s; %s", first.msg, second.msg);
        }
    }
    if (r != BTF_OK) {
        free(gl);
        return r;
    }
    *out = gl;
    return BTF_OK;
}

btf_result btf_gl_make_current(btf_gl *gl, btf_error *err)
{
    if (!gl)
        return btf_fail(err, BTF_ERR_ARG, "gl: NULL context");
    return gl->vt->make_current(gl->native, err);
}

const btf_gl_api *btf_gl_fn(const btf_gl *gl) { return &gl->fn; }
btf_gl_backend btf_gl_backend_of(const btf_gl *gl) { return gl->backend; }
const char *btf_gl_renderer(const btf_gl *gl) { return (const char *)gl->fn.GetString(GL_RENDERER); }

const char *btf_gl_platform(const btf_gl *gl) { return gl->vt->describe(gl->native); }
const char *btf_gl_version(const btf_gl *gl) { return (const char *)gl->fn.GetString(GL_VERSION); }

btf_result btf_gl_check(btf_gl *gl, const char *what, btf_error *err)
{
    GLenum e = gl->fn.GetError();
    if (e == GL_NO_ERROR)
        return BTF_OK;
    while (gl->fn.GetError() != GL_NO_ERROR) {
    }
    return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl %s: GL error 0x%04x while %s", gl->vt->name, (unsigned)e, what);
}

/* ---------------------------------------------------------------- textures */

size_t btf_gl_format_texel_bytes(btf_gl_format f)
{
    return f == BTF_GL_RGBA8 ? 4u : f == BTF_GL_RGBA32F || f == BTF_GL_RGBA32UI ? 16u : 0u;
}

static int btf__gl_format_ok(btf_gl_format f)
{
    return f == BTF_GL_RGBA8 || f == BTF_GL_RGBA32F || f == BTF_GL_RGBA32UI;
}

static btf_result btf__gl_size_ok(int w, int h, btf_error *err)
{
    if (w < 1 || h < 1 || w > BTF_MAX_SIDE || h > BTF_MAX_SIDE)
        return btf_fail(err, BTF_ERR_RANGE, "gl: size %dx%d outside 1..%d", w, h, BTF_MAX_SIDE);
    return BTF_OK;
}

/* Allocates storage of the bound GL_TEXTURE_2D. */
static void btf__gl_tex_storage(btf_gl *gl, int w, int h, btf_gl_format fmt, const void *data)
{
    gl->fn.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    if (fmt == BTF_GL_RGBA32F)
        gl->fn.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, data);
    else if (fmt == BTF_GL_RGBA32UI)
        gl->fn.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32UI, w, h, 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT, data);
    else
        gl->fn.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE, data);
    gl->fn.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl->fn.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl->fn.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl->fn.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

btf_result btf_gl_texture_create(btf_gl *gl, int w, int h, btf_gl_format fmt, const void *data, GLuint *tex,
                                 btf_error *err)
{
    if (!gl || !tex)
        return btf_fail(err, BTF_ERR_ARG, "gl: NULL argument");
    if (!btf__gl_format_ok(fmt))
        return btf_fail(err, BTF_ERR_ARG, "gl: unknown texture format %d", (int)fmt);
    btf_result r = btf__gl_size_ok(w, h, err);
    if (r != BTF_OK)
        return r;
    gl->fn.GenTextures(1, tex);
    gl->fn.BindTexture(GL_TEXTURE_2D, *tex);
    btf__gl_tex_storage(gl, w, h, fmt, data);
    r = btf_gl_check(gl, "creating a texture", err);
    if (r != BTF_OK) {
        gl->fn.DeleteTextures(1, tex);
        *tex = 0;
    }
    return r;
}

void btf_gl_texture_free(btf_gl *gl, GLuint tex)
{
    if (gl && tex)
        gl->fn.DeleteTextures(1, &tex);
}

/* ---------------------------------------------------------------- render targets */

static btf_result btf__gl_target_attach(btf_gl *gl, btf_gl_target *t, btf_error *err)
{
    gl->fn.GenFramebuffers(1, &t->fbo);
    gl->fn.BindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    for (int i = 0; i < t->n_color; i++) {
        gl->fn.GenTextures(1, &t->color[i]);
        gl->fn.BindTexture(GL_TEXTURE_2D, t->color[i]);
        btf__gl_tex_storage(gl, t->width, t->height, t->format, NULL);
        gl->fn.FramebufferTexture2D(GL_FRAMEBUFFER, (GLenum)(GL_COLOR_ATTACHMENT0 + i), GL_TEXTURE_2D, t->color[i], 0);
    }
    GLenum status = gl->fn.CheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl: %s framebuffer incomplete (status 0x%04x)%s",
                        t->format == BTF_GL_RGBA32F ? "RGBA32F" : "RGBA8", (unsigned)status,
                        t->format == BTF_GL_RGBA32F ? ": float targets need EXT_color_buffer_float" : "");
    return btf_gl_check(gl, "creating a framebuffer", err);
}

void btf_gl_target_free(btf_gl *gl, btf_gl_target *t)
{
    if (!t)
        return;
    if (gl) {
        for (int i = 0; i < t->n_color; i++)
            if (t->color[i])
                gl->fn.DeleteTextures(1, &t->color[i]);
        if (t->fbo)
            gl->fn.DeleteFramebuffers(1, &t->fbo);
    }
    free(t);
}

btf_result btf_gl_target_create(btf_gl *gl, int w, int h, btf_gl_format fmt, int n_color, btf_gl_target **out,
                                btf_error *err)
{
    if (!gl || !out)
        return btf_fail(err, BTF_ERR_ARG, "gl: NULL argument");
    *out = NULL;
    if (!btf__gl_format_ok(fmt) || fmt == BTF_GL_RGBA32UI)
        return btf_fail(err, BTF_ERR_ARG, "gl: unknown target format %d", (int)fmt);
    if (n_color < 1 || n_color > BTF_GL_MAX_TARGETS)
        return btf_fail(err, BTF_ERR_RANGE, "gl: %d colour attachments, expected 1..%d", n_color, BTF_GL_MAX_TARGETS);
    btf_result r = btf__gl_size_ok(w, h, err);
    if (r != BTF_OK)
        return r;
    btf_gl_target *t = calloc(1, sizeof *t);
    if (!t)
        return btf_fail(err, BTF_ERR_NOMEM, "gl: out of memory");
    t->width = w;
    t->height = h;
    t->format = fmt;
    t->n_color = n_color;
    r = btf__gl_target_attach(gl, t, err);
    if (r != BTF_OK)
        btf_gl_target_free(gl, t), t = NULL;
    *out = t;
    return r;
}

void btf_gl_target_bind(btf_gl *gl, const btf_gl_target *t)
{
    static const GLenum bufs[BTF_GL_MAX_TARGETS] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1,
                                                    GL_COLOR_ATTACHMENT2, GL_COLOR_ATTACHMENT3};
    gl->fn.BindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    gl->fn.DrawBuffers(t->n_color, bufs);
    gl->fn.Viewport(0, 0, t->width, t->height);
}

btf_result btf_gl_target_read(btf_gl *gl, const btf_gl_target *t, int i, void *dst, btf_error *err)
{
    if (!gl || !t || !dst)
        return btf_fail(err, BTF_ERR_ARG, "gl: NULL argument");
    if (i < 0 || i >= t->n_color)
        return btf_fail(err, BTF_ERR_RANGE, "gl: attachment %d of %d", i, t->n_color);
    gl->fn.BindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    gl->fn.ReadBuffer((GLenum)(GL_COLOR_ATTACHMENT0 + i));
    gl->fn.PixelStorei(GL_PACK_ALIGNMENT, 1);
    if (t->format == BTF_GL_RGBA32F)
        gl->fn.ReadPixels(0, 0, t->width, t->height, GL_RGBA, GL_FLOAT, dst);
    else
        gl->fn.ReadPixels(0, 0, t->width, t->height, GL_RGBA, GL_UNSIGNED_BYTE, dst);
    return btf_gl_check(gl, "reading pixels", err);
}

void btf_gl_draw_fullscreen(btf_gl *gl)
{
    gl->fn.BindVertexArray(gl->vao);
    gl->fn.DrawArrays(GL_TRIANGLES, 0, 3);
}

/* ---------------------------------------------------------------- timer queries */

#define BTF__TIME_ELAPSED 0x88BF     /* GL_TIME_ELAPSED(_EXT) */
#define BTF__GPU_DISJOINT 0x8FBB     /* GL_GPU_DISJOINT_EXT */
#define BTF__QUERY_RESULT 0x8866     /* GL_QUERY_RESULT */
typedef void (*btf__get_query_u64)(GLuint id, GLenum pname, unsigned long long *params);

/* The ui64 result getter when the context can time (looked up once): desktop GL
 * 3.3 has it in core, GLES needs GL_EXT_disjoint_timer_query. Not on a software
 * rasteriser: its queries time the command submission, not the rasterising threads
 * (llvmpipe reports 0.2 ms for a 75 ms frame). */
static btf__get_query_u64 btf__timer_getter(btf_gl *gl)
{
    if (gl->timer_state == 0) {
        int es = gl->backend == BTF_GL_EGL;
        const char *ext = es ? (const char *)gl->fn.GetString(GL_EXTENSIONS) : NULL;
        const char *r = btf_gl_renderer(gl);
        int software = r && (strstr(r, "llvmpipe") || strstr(r, "softpipe") || strstr(r, "swrast"));
        if (!software && (!es || (ext && strstr(ext, "GL_EXT_disjoint_timer_query"))))
            gl->timer_get = gl->vt->getproc(gl->native, es ? "glGetQueryObjectui64vEXT" : "glGetQueryObjectui64v");
        gl->timer_state = gl->timer_get ? 1 : -1;
        while (gl->fn.GetError() != GL_NO_ERROR)
            ;
    }
    return (btf__get_query_u64)gl->timer_get;
}

int btf_gl_timer_begin(btf_gl *gl)
{
    if (!btf__timer_getter(gl))
        return 0;
    while (gl->fn.GetError() != GL_NO_ERROR)
        ;
    if (!gl->timer)
        gl->fn.GenQueries(1, &gl->timer);
    gl->fn.BeginQuery(BTF__TIME_ELAPSED, gl->timer);
    return gl->fn.GetError() == GL_NO_ERROR;
}

long long btf_gl_timer_end(btf_gl *gl)
{
    btf__get_query_u64 get = btf__timer_getter(gl);
    if (!get)
        return -1;
    gl->fn.EndQuery(BTF__TIME_ELAPSED);
    unsigned long long ns = 0;
    get(gl->timer, BTF__QUERY_RESULT, &ns); /* waits for the result */
    GLenum e = gl->fn.GetError();
    GLint disjoint = 0;
    if (gl->backend == BTF_GL_EGL)
        gl->fn.GetIntegerv(BTF__GPU_DISJOINT, &disjoint);
    return e == GL_NO_ERROR && !disjoint ? (long long)ns : -1;
}
