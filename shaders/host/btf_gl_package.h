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
 * Textures (all sampled with texelFetch, WebGL2 core formats only); slot s = the s-th
 * distinct component of the loaded chunks (version 1: chunk s); N spatial levels
 * (version 2; 1 in version 1); the full contract is shaders/README.md, "Spatial levels":
 *   u_btf_tex         sampler2DArray, layer s, mip level l = tex-JJ[-lL].png of slot s
 *                     as stored: R8 (8-bit package) or RGB8 (16-bit: R = high, G = low byte)
 *   u_btf_wt          sampler2DArray RGB32F, L x V texels, layer s = dequantised weights
 *                     of slot s (the most precise loaded), texel (light, view)
 *   u_btf_range       sampler2D RGBA32F, n_blocks x (slots * N): (lo, step, fine, coarse)
 *                     of (block, slot s * N + level l); [fine, coarse] = loaded levels of s
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
    int n_chunks; /* layers uploaded = slots (version 1: the package's loaded chunks) */
    btf_dirset lights, views;
    GLuint tex, wt, range, view_block;
    int n_levels;      /* spatial levels N (1 in version 1) */
    int n_loaded;      /* chunks of the package that were uploaded */
    int *chunk_slot;   /* n_loaded: slot of each loaded chunk (malloc'd) */
    int *chunk_level;  /* n_loaded: level of each loaded chunk (malloc'd) */
    float *range_host; /* n_blocks x (n_chunks * N) x 4: host copy of u_btf_range (malloc'd) */
} btf_gl_package;

/* Uploads p's loaded chunks; dir is the package directory (textures are read from
 * its tex-JJ[-lL].png files, exactly the bytes a browser receives). Version 2: the
 * loaded levels of each component must be contiguous in every prefix of the loaded
 * chunks (true of any prefix of a package written by btf_lod_build). */
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
    int n_chunks; /* first n uploaded chunks (like btf_decode_options.n_chunks); 0 = all */
} btf_gl_decode_settings;

/* Sets u_btf_filter, u_btf_wrap, u_btf_chunks of prog (in use); version 2: also
 * rewrites the loaded level ranges of u_btf_range for the prefix. */
void btf_gl_package_settings(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog,
                             const btf_gl_decode_settings *s);

/* Level of detail of prog (in use): fixed = 0: the render program takes it from
 * screen-space derivatives (u_btf_lod_auto = 1, btf_gl_package_bind's default);
 * fixed = 1: every fragment decodes at `lod` (u_btf_lod; also the lod of btf_decode()). */
void btf_gl_package_lod(btf_gl *gl, const btf_shader_program *prog, int fixed, float lod);

#ifdef __cplusplus
}
#endif
#endif
