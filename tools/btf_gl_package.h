/* btf_gl_package.h - a (possibly partial) package on the GPU, uploaded the way the
 * WebGL2 client does it, plus the uniforms of shaders/btf_decode.glsl.
 *
 *     btf_package *p; btf_package_read("lib/wool", 2, &p, &err);     // first 2 chunks
 *     btf_gl_package *g; btf_gl_package_upload(gl, p, "lib/wool", &g, &err);
 *     f->UseProgram(prog->id);
 *     btf_gl_package_bind(gl, g, prog, 0, &err);   // texture units 0..3, all uniforms
 *     ... draw ...
 *     btf_gl_package_free(gl, g);
 *
 * Textures (all sampled with texelFetch, NEAREST, WebGL2 core formats only):
 *   u_btf_tex         sampler2DArray, layer j = tex-JJ.png of chunk j as stored:
 *                     R8 (8-bit package) or RGB8 (16-bit: R = high byte, G = low byte)
 *   u_btf_wt          sampler2DArray RGB32F, L x V texels, layer j = dequantised weights
 *                     of chunk j, texel (light, view)
 *   u_btf_range       sampler2D RGBA32F, n_blocks x n_chunks: (lo, step, 0, 0) of the
 *                     texture quantisation of (block, chunk)
 *   u_btf_view_block  sampler2D RGBA32F, V x 1: block of view v in .r
 * Limitations: the whole atlas of every loaded chunk is uploaded (no streaming of
 * parts here); sizes are limited by GL_MAX_TEXTURE_SIZE / GL_MAX_ARRAY_TEXTURE_LAYERS.
 */
#ifndef BTF_GL_PACKAGE_H
#define BTF_GL_PACKAGE_H

#include "btf_gl.h"
#include "btf_package.h"
#include "btf_shader.h"

#ifdef __cplusplus
extern "C" {
#endif

/* GPU copy of a package's loaded chunks. Made by btf_gl_package_upload, freed by
 * btf_gl_package_free with the same btf_gl. Keeps a copy of the direction sets. */
typedef struct btf_gl_package {
    int width, height, n_blocks, atlas_cols, bits;
    int n_chunks; /* layers uploaded = the package's loaded chunks */
    btf_dirset lights, views;
    GLuint tex, wt, range, view_block;
} btf_gl_package;

/* Uploads p's loaded chunks; dir is the package directory (textures are read from
 * its tex-JJ.png files, exactly the bytes a browser receives). */
btf_result btf_gl_package_upload(btf_gl *gl, const btf_package *p, const char *dir, btf_gl_package **out,
                                 btf_error *err);
void btf_gl_package_free(btf_gl *gl, btf_gl_package *g);

/* Binds the 4 textures to units first_unit..first_unit+3 and sets every u_btf_*
 * uniform of prog (in use): chunks used = all uploaded. */
btf_result btf_gl_package_bind(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog, int first_unit,
                               btf_error *err);

/* Decoder settings of shaders/btf_decode.glsl; plain value, zero = nearest, clamp, all chunks. */
typedef struct btf_gl_decode_settings {
    int filter;   /* 0 nearest, 1 bilinear (btf_filter values) */
    int wrap;     /* 1: tile; 0: clamp to the edge */
    int n_chunks; /* first n uploaded chunks; 0 = all */
} btf_gl_decode_settings;

/* Sets u_btf_filter, u_btf_wrap, u_btf_chunks of prog (in use). */
void btf_gl_package_settings(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog,
                             const btf_gl_decode_settings *s);

#ifdef __cplusplus
}
#endif
#endif
