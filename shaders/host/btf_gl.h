/* btf_gl.h - headless OpenGL harness: one API over two backends (EGL, OSMesa).
 *
 * Usage:
 *     btf_gl *gl = NULL;
 *     btf_error err = {0};
 *     btf_gl_desc desc = {0};              // zero = backend from $BTF_GL_BACKEND, else EGL
 *     if (btf_gl_create(&desc, &gl, &err) != BTF_OK) { puts(err.msg); return 1; }
 *     const btf_gl_api *f = btf_gl_fn(gl);  // every GL call goes through this table
 *     btf_gl_target *t = NULL;
 *     btf_gl_target_create(gl, 64, 64, BTF_GL_RGBA32F, 1, &t, &err);
 *     btf_gl_target_bind(gl, t);
 *     f->ClearColor(0, 0, 0, 1); f->Clear(GL_COLOR_BUFFER_BIT);
 *     float px[64 * 64 * 4];
 *     btf_gl_target_read(gl, t, 0, px, &err);
 *     btf_gl_target_free(gl, t);
 *     btf_gl_free(gl);
 *
 * Backends (chosen once, in btf_gl_create; the logic never asks which one runs):
 *   BTF_GL_EGL     EGL surfaceless display (EGL_PLATFORM_SURFACELESS_MESA), a GLES 3.x
 *                  context, no surface: all rendering goes to framebuffer objects.
 *   BTF_GL_OSMESA  OSMesa desktop core-profile 3.3+ context; runs the same
 *                  `#version 300 es` shaders (ARB_ES3_compatibility).
 * BTF_GL_DEFAULT reads $BTF_GL_BACKEND ("egl" or "osmesa"); unset: EGL, and OSMesa
 * when EGL cannot start. An explicitly named backend never falls back: if it cannot
 * start, btf_gl_create fails with a message naming the backend and the cause.
 *
 * GL entry points are fetched per context (eglGetProcAddress / OSMesaGetProcAddress)
 * into a btf_gl_api table. Never call gl* functions directly: with both libraries
 * in one binary the global symbols may resolve to the other one (glvnd dispatch).
 * Only the GLES 3.0 subset is in the table, so code written against it runs on
 * WebGL2 too.
 *
 * Limitations: one thread; a context is made current by btf_gl_create and by
 * btf_gl_make_current (call it when switching between several btf_gl objects).
 * Readback rows are in GL order: row 0 is the bottom row (gl_FragCoord.y = 0.5).
 * Not done here: windows, swap chains, depth-buffered 3D scenes (the caller
 * attaches its own depth buffer through the table if it needs one).
 */
#ifndef BTF_GL_H
#define BTF_GL_H

#include "btf.h"

#ifndef GL_GLES_PROTOTYPES
#define GL_GLES_PROTOTYPES 0 /* no direct gl* calls: use the btf_gl_api table */
#endif
#include <GLES3/gl3.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_gl_backend {
    BTF_GL_DEFAULT = 0, /* $BTF_GL_BACKEND, else EGL with OSMesa as fallback */
    BTF_GL_EGL = 1,
    BTF_GL_OSMESA = 2
} btf_gl_backend;

/* "egl" / "osmesa" / "default". */
const char *btf_gl_backend_name(btf_gl_backend b);
/* Parses "egl" or "osmesa" (case-sensitive); NULL or "" gives BTF_GL_DEFAULT. */
btf_result btf_gl_backend_parse(const char *s, btf_gl_backend *out, btf_error *err);

/* The GL ES 3.0 functions the project uses; X(pointer type, name without "gl"). */
#define BTF_GL_FUNCS(X)                                                                                      \
    X(PFNGLGETSTRINGPROC, GetString)                                                                         \
    X(PFNGLGETERRORPROC, GetError)                                                                           \
    X(PFNGLGETINTEGERVPROC, GetIntegerv)                                                                     \
    X(PFNGLENABLEPROC, Enable)                                                                               \
    X(PFNGLDISABLEPROC, Disable)                                                                             \
    X(PFNGLVIEWPORTPROC, Viewport)                                                                           \
    X(PFNGLCLEARCOLORPROC, ClearColor)                                                                       \
    X(PFNGLCLEARPROC, Clear)                                                                                 \
    X(PFNGLCLEARBUFFERFVPROC, ClearBufferfv)                                                                 \
    X(PFNGLFINISHPROC, Finish)                                                                               \
    X(PFNGLPIXELSTOREIPROC, PixelStorei)                                                                     \
    X(PFNGLREADPIXELSPROC, ReadPixels)                                                                       \
    X(PFNGLREADBUFFERPROC, ReadBuffer)                                                                       \
    X(PFNGLDRAWBUFFERSPROC, DrawBuffers)                                                                     \
    X(PFNGLDRAWARRAYSPROC, DrawArrays)                                                                       \
    X(PFNGLDRAWELEMENTSPROC, DrawElements)                                                                   \
    X(PFNGLCREATESHADERPROC, CreateShader)                                                                   \
    X(PFNGLSHADERSOURCEPROC, ShaderSource)                                                                   \
    X(PFNGLCOMPILESHADERPROC, CompileShader)                                                                 \
    X(PFNGLGETSHADERIVPROC, GetShaderiv)                                                                     \
    X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                                                           \
    X(PFNGLDELETESHADERPROC, DeleteShader)                                                                   \
    X(PFNGLCREATEPROGRAMPROC, CreateProgram)                                                                 \
    X(PFNGLATTACHSHADERPROC, AttachShader)                                                                   \
    X(PFNGLLINKPROGRAMPROC, LinkProgram)                                                                     \
    X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                                                   \
    X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                                                         \
    X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                                                 \
    X(PFNGLUSEPROGRAMPROC, UseProgram)                                                                       \
    X(PFNGLBINDATTRIBLOCATIONPROC, BindAttribLocation)                                                       \
    X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                                                       \
    X(PFNGLUNIFORM1IPROC, Uniform1i)                                                                         \
    X(PFNGLUNIFORM1IVPROC, Uniform1iv)                                                                       \
    X(PFNGLUNIFORM2IPROC, Uniform2i)                                                                         \
    X(PFNGLUNIFORM1FPROC, Uniform1f)                                                                         \
    X(PFNGLUNIFORM1FVPROC, Uniform1fv)                                                                       \
    X(PFNGLUNIFORM2FPROC, Uniform2f)                                                                         \
    X(PFNGLUNIFORM3FPROC, Uniform3f)                                                                         \
    X(PFNGLUNIFORM3FVPROC, Uniform3fv)                                                                       \
    X(PFNGLUNIFORM4FPROC, Uniform4f)                                                                         \
    X(PFNGLUNIFORM4FVPROC, Uniform4fv)                                                                       \
    X(PFNGLUNIFORMMATRIX3FVPROC, UniformMatrix3fv)                                                           \
    X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv)                                                           \
    X(PFNGLGENTEXTURESPROC, GenTextures)                                                                     \
    X(PFNGLDELETETEXTURESPROC, DeleteTextures)                                                               \
    X(PFNGLBINDTEXTUREPROC, BindTexture)                                                                     \
    X(PFNGLACTIVETEXTUREPROC, ActiveTexture)                                                                 \
    X(PFNGLTEXPARAMETERIPROC, TexParameteri)                                                                 \
    X(PFNGLTEXIMAGE2DPROC, TexImage2D)                                                                       \
    X(PFNGLTEXSUBIMAGE2DPROC, TexSubImage2D)                                                                 \
    X(PFNGLTEXIMAGE3DPROC, TexImage3D)                                                                       \
    X(PFNGLTEXSUBIMAGE3DPROC, TexSubImage3D)                                                                 \
    X(PFNGLGENFRAMEBUFFERSPROC, GenFramebuffers)                                                             \
    X(PFNGLDELETEFRAMEBUFFERSPROC, DeleteFramebuffers)                                                       \
    X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                                                             \
    X(PFNGLFRAMEBUFFERTEXTURE2DPROC, FramebufferTexture2D)                                                   \
    X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, CheckFramebufferStatus)                                               \
    X(PFNGLGENRENDERBUFFERSPROC, GenRenderbuffers)                                                           \
    X(PFNGLDELETERENDERBUFFERSPROC, DeleteRenderbuffers)                                                     \
    X(PFNGLBINDRENDERBUFFERPROC, BindRenderbuffer)                                                           \
    X(PFNGLRENDERBUFFERSTORAGEPROC, RenderbufferStorage)                                                     \
    X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, FramebufferRenderbuffer)                                             \
    X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays)                                                             \
    X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)                                                       \
    X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                                                             \
    X(PFNGLGENBUFFERSPROC, GenBuffers)                                                                       \
    X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                                                                 \
    X(PFNGLBINDBUFFERPROC, BindBuffer)                                                                       \
    X(PFNGLBUFFERDATAPROC, BufferData)                                                                       \
    X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)                                                     \
    X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray)                                             \
    X(PFNGLGENQUERIESPROC, GenQueries)                                                                       \
    X(PFNGLDELETEQUERIESPROC, DeleteQueries)                                                                 \
    X(PFNGLBEGINQUERYPROC, BeginQuery)                                                                       \
    X(PFNGLENDQUERYPROC, EndQuery)                                                                           \
    X(PFNGLGETUNIFORMBLOCKINDEXPROC, GetUniformBlockIndex)                                                   \
    X(PFNGLUNIFORMBLOCKBINDINGPROC, UniformBlockBinding)                                                     \
    X(PFNGLBINDBUFFERBASEPROC, BindBufferBase)

/* GL entry points of one context; filled by btf_gl_create, owned by its btf_gl. */
typedef struct btf_gl_api {
#define BTF__GL_FIELD(type, name) type name;
    BTF_GL_FUNCS(BTF__GL_FIELD)
#undef BTF__GL_FIELD
} btf_gl_api;

/* Options for btf_gl_create; zero means default. Caller-owned, read during the call. */
typedef struct btf_gl_desc {
    btf_gl_backend backend;
} btf_gl_desc;

/* A live GL context and its function table. Created by btf_gl_create, freed by btf_gl_free. */
typedef struct btf_gl btf_gl;

btf_result btf_gl_create(const btf_gl_desc *desc, btf_gl **out, btf_error *err);
void btf_gl_free(btf_gl *gl);
/* Makes gl's context current on this thread again. */
btf_result btf_gl_make_current(btf_gl *gl, btf_error *err);
const btf_gl_api *btf_gl_fn(const btf_gl *gl);
btf_gl_backend btf_gl_backend_of(const btf_gl *gl);
/* GL_RENDERER and GL_VERSION strings (owned by GL, valid while gl lives). */
const char *btf_gl_renderer(const btf_gl *gl);
/* How the backend found its context: "EGL surfaceless Mesa", "EGL device 0 of 2",
 * "OSMesa" (static or owned by gl). */
const char *btf_gl_platform(const btf_gl *gl);
/* Elapsed GPU time of what is drawn between btf_gl_timer_begin and _end, through
 * the context's timer queries (GL_EXT_disjoint_timer_query on GLES, core
 * GL_TIME_ELAPSED on desktop GL); btf_gl_timer_begin returns 0 when the context
 * has none or is a software rasteriser (whose queries do not time its threads). _end waits for the result: nanoseconds, or -1 when the query failed or
 * the GPU reported a disjoint period (the measurement is void). */
int btf_gl_timer_begin(btf_gl *gl);
long long btf_gl_timer_end(btf_gl *gl);
const char *btf_gl_version(const btf_gl *gl);
/* BTF_ERR_UNSUPPORTED naming the first pending glGetError code and `what`, else BTF_OK. */
btf_result btf_gl_check(btf_gl *gl, const char *what, btf_error *err);

/* ---------------------------------------------------------------- textures and targets */

typedef enum btf_gl_format {
    BTF_GL_RGBA8 = 1,  /* 8-bit unsigned normalized; data as uint8_t[4] per texel */
    BTF_GL_RGBA32F = 2, /* 32-bit float; data as float[4] per texel */
    BTF_GL_RGBA32UI = 3 /* 32-bit unsigned integer (usampler, not renderable here); data as uint32_t[4] */
} btf_gl_format;

/* Bytes per texel of a format (4 or 16), 0 if unknown. */
size_t btf_gl_format_texel_bytes(btf_gl_format f);

/* 2D texture w x h, NEAREST filtering, CLAMP_TO_EDGE; data may be NULL (undefined
 * contents), else w*h texels, row 0 at texture coordinate t = 0. *tex is the GL name;
 * delete it with btf_gl_texture_free. */
btf_result btf_gl_texture_create(btf_gl *gl, int w, int h, btf_gl_format fmt, const void *data, GLuint *tex,
                                 btf_error *err);
void btf_gl_texture_free(btf_gl *gl, GLuint tex);

#define BTF_GL_MAX_TARGETS 4

/* An offscreen framebuffer with n_color textures of one format.
 * Created by btf_gl_target_create, owned by the caller, freed by btf_gl_target_free
 * (with the btf_gl that made it, before that btf_gl is freed). */
typedef struct btf_gl_target {
    int width, height;
    btf_gl_format format;
    int n_color;
    GLuint fbo;
    GLuint color[BTF_GL_MAX_TARGETS]; /* texture names, usable as shader inputs */
} btf_gl_target;

btf_result btf_gl_target_create(btf_gl *gl, int w, int h, btf_gl_format fmt, int n_color, btf_gl_target **out,
                                btf_error *err);
void btf_gl_target_free(btf_gl *gl, btf_gl_target *t);
/* Binds t's framebuffer, enables all its draw buffers, sets the viewport to its size. */
void btf_gl_target_bind(btf_gl *gl, const btf_gl_target *t);
/* Reads colour attachment i into dst: width*height*4 uint8_t (RGBA8) or float (RGBA32F),
 * rows bottom-up (GL order). */
btf_result btf_gl_target_read(btf_gl *gl, const btf_gl_target *t, int i, void *dst, btf_error *err);

/* Draws one triangle covering the viewport with the current program; the vertex
 * shader makes the positions from gl_VertexID (no attributes, see shaders/fullscreen.vert). */
void btf_gl_draw_fullscreen(btf_gl *gl);

/* ---------------------------------------------------------------- backend interface (internal) */

typedef void (*btf__gl_proc)(void);

/* What a backend provides; one static const table per backend file. */
typedef struct btf__gl_backend_vt {
    const char *name;
    /* Opens a context and makes it current; *native is the backend's own state. */
    btf_result (*open)(void **native, btf_error *err);
    btf_result (*make_current)(void *native, btf_error *err);
    btf__gl_proc (*getproc)(void *native, const char *name);
    void (*close)(void *native);
    /* How the context was found (display platform, device), for btf_gl_platform. */
    const char *(*describe)(void *native);
} btf__gl_backend_vt;

extern const btf__gl_backend_vt btf__gl_egl_vt;    /* btf_gl_egl.c */
extern const btf__gl_backend_vt btf__gl_osmesa_vt; /* btf_gl_osmesa.c */

/* The EGL backend's choice among the devices of EGL_EXT_platform_device (btf_gl_egl.c):
 * tries devices 0..n-1 in order with try_dev (0: it gave a GLES 3 context, which the
 * caller keeps) and returns the first that did, without trying the rest; -1 when none
 * did or n < 1. Separate so that the choice is tested on a stub list. */
int btf__gl_pick_device(int n, int (*try_dev)(void *ctx, int i), void *ctx);

#ifdef __cplusplus
}
#endif
#endif
