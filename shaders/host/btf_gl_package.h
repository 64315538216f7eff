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
 * The GPU layout (shaders/btf_decode.glsl and shaders/README.md, "GPU layout"): slot s =
 * the s-th distinct component of the loaded chunks (version 1: chunk s); N levels:
 *   u_btf_tex   RGBA16UI array, layer h = slots 4h..4h+3 (channel c = slot 4h+c), mip level l;
 *               values requantised on one grid per component (its manifest ranges over
 *               every block and level), a level a slot lacks filled from its nearest one;
 *               paired (N > 1 drawn with nearest taps) RGBA32UI: each texel's value in
 *               bits 0..15, that of its texel (x/2, y/2) on level l+1 in bits 16..31
 *               (one read, both levels); bilinear keeps RGBA16UI (btf_gl_package_settings)
 *   u_btf_wt    RGBA32UI array, layer h = slots 4h..4h+3 as 11/11/10-bit RGB, texel
 *               (light, view), one grid per (slot, channel)
 *   u_btf_tq, u_btf_wq  the grids (uniform arrays); slots not in use get zero weights
 *   direction tables (btf_gl_dirs.h) on texture units first+2, first+3, block binding 0
 * Limitations: the whole atlas of every loaded chunk is uploaded (no streaming of
 * parts here); sizes are limited by GL_MAX_TEXTURE_SIZE / GL_MAX_ARRAY_TEXTURE_LAYERS;
 * lights + views at most BTF_GL_MAX_VERTS - 4 directions.
 */
#ifndef BTF_GL_PACKAGE_H
#define BTF_GL_PACKAGE_H

#include "btf_gl.h"
#include "btf_gl_dirs.h"
#include "btf_package.h"
#include "btf_shader.h"

#ifdef __cplusplus
extern "C" {
#endif

/* GPU copy of a package's loaded chunks. Made by btf_gl_package_upload, freed by
 * btf_gl_package_free with the same btf_gl. Keeps a pointer to the package (version 2
 * repacks from it when a prefix is chosen): the package must outlive it. */
typedef struct btf_gl_package {
    int width, height, n_blocks, atlas_cols, atlas_rows, bits;
    int n_chunks;      /* slots uploaded (version 1: the package's loaded chunks) */
    btf_dirset lights, views;
    GLuint tex, wt;    /* u_btf_tex, u_btf_wt */
    GLuint env_w;      /* u_btf_env_w: the environment's G_j (doc/lighting.md 3), 11/11/10-bit codes */
    float *env_s;      /* 4 per 4 slots: u_btf_env_s, the scale of each slot's G (malloc'd) */
    btf_gl_dirs dirs;  /* direction tables */
    int n_levels;      /* spatial levels N (1 in version 1) */
    int paired;        /* u_btf_tex is paired RGBA32UI (levels, nearest), else RGBA16UI; the
                          filter of the last btf_gl_package_settings decides (upload: nearest) */
    int n_loaded;      /* chunks of the package that were uploaded */
    int *chunk_slot;   /* n_loaded: slot of each loaded chunk (malloc'd) */
    int *chunk_level;  /* n_loaded: level of each loaded chunk (malloc'd) */
    float *tq;         /* 8 floats per 4 slots: lo[4], step[4] of T (malloc'd) */
    float *wq;         /* 24 floats per 4 slots: lo R, G, B [4 each], step R, G, B (malloc'd) */
    float outer_cos;   /* cos(theta) of the outermost light ring (u_btf_outer_cos) */
    double *ms;        /* 4 per slot: mean square of T, of W per channel (btf_gl_package_quant_error; malloc'd) */
    const btf_package *src;
} btf_gl_package;

/* Uploads p's loaded chunks; dir is the package directory (textures are read from
 * its tex-JJ[-lL].png files, exactly the bytes a browser receives). Version 2: the
 * loaded levels of each component must be contiguous in every prefix of the loaded
 * chunks (true of any prefix of a package written by btf_lod_build). */
btf_result btf_gl_package_upload(btf_gl *gl, const btf_package *p, const char *dir, btf_gl_package **out,
                                 btf_error *err);
void btf_gl_package_free(btf_gl *gl, btf_gl_package *g);

/* Binds the 4 textures to units first_unit..first_unit+3 (u_btf_env_w, where the
 * program has it, to first_unit+4; a BTF_FIXED_LIGHT program has no u_btf_wt, its
 * u_btf_lw is btf_gl_fixed_bind's) and sets every u_btf_*
 * uniform of prog (in use): chunks used = all uploaded, the filter u_btf_tex is laid
 * out for (bilinear where g->paired is 0 on a package with levels, else nearest). */
btf_result btf_gl_package_bind(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog, int first_unit,
                               btf_error *err);

/* Decoder settings of shaders/btf_decode.glsl; plain value, zero = nearest, clamp, all chunks. */
typedef struct btf_gl_decode_settings {
    int filter;   /* 0 nearest, 1 bilinear (btf_filter values) */
    int wrap;     /* 1: tile; 0: clamp to the edge */
    int n_chunks; /* first n uploaded chunks (like btf_decode_options.n_chunks); 0 = all */
} btf_gl_decode_settings;

/* Sets u_btf_filter, u_btf_wrap, u_btf_chunks of prog (in use); version 2: also
 * repacks u_btf_tex for the prefix's loaded levels, with levels laid out anew (same
 * texture name) when the filter asks for the other layout (g->paired): a program drawn
 * with g must be specialised for (or set to) the filter of its last settings. */
void btf_gl_package_settings(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog,
                             const btf_gl_decode_settings *s);

#define BTF_GL_PACKAGE_DEFINES 3

/* The shader defines that specialise the decoder for g drawn with `filter` (0 nearest,
 * 1 bilinear) and its first n_chunks chunks (0 = all): BTF_FILTER, BTF_LEVELS (0 for a
 * package without levels) and BTF_QUADS (4-slot layers in use); shaders/btf_decode.glsl
 * explains why. Fills defs[0..] with names and values (vals holds the value text);
 * returns the count (BTF_GL_PACKAGE_DEFINES). Without them the program decides at run
 * time (same results, slower on software rasterisers). */
int btf_gl_package_defines(const btf_gl_package *g, int filter, int n_chunks, btf_shader_define *defs,
                           char vals[][16]);

/* What the GPU layout's requantisation (16-bit textures, 11/11/10-bit weights) can
 * do to a decoded value (byte/255 scale), per colour channel, the largest channel:
 * worst = sum over slots of max|T| dW/2 + max|W| dT/2 + dT dW/4 (every rounding
 * error at its extreme, aligned); rms = the root of the summed variances
 * E[T^2] dW^2/12 + E[W^2] dT^2/12 of independent uniform rounding errors (the
 * expected square error at a random texel and direction pair, before the angular
 * and spatial interpolation average some of it away). Tests compare the GPU with btf_decode against both. */
void btf_gl_package_quant_error(const btf_gl_package *g, double *worst, double *rms);

/* Slots (4 per layer) that the first n_chunks chunks use (0 = all loaded), at least 1. */
int btf_gl_package_slots(const btf_gl_package *g, int n_chunks);

/* Weight of slot s for light l, view v, colour channel c exactly as u_btf_wt holds it:
 * lo + step q on the slot's grid (the value the run-time decoder dequantises). */
float btf_gl_package_weight(const btf_gl_package *g, int s, int l, int v, int c);

/* Level of detail of prog (in use): fixed = 0: the render program takes it from
 * screen-space derivatives (u_btf_lod_auto = 1, btf_gl_package_bind's default);
 * fixed = 1: every fragment decodes at `lod` (u_btf_lod; also the lod of btf_decode()). */
void btf_gl_package_lod(btf_gl *gl, const btf_shader_program *prog, int fixed, float lod);

#ifdef __cplusplus
}
#endif
#endif
