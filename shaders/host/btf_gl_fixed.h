/* btf_gl_fixed.h - the light side of shaders/btf_decode.glsl blended once per draw, for
 * draws whose light has one local direction at every fragment: a distant light on a
 * flat surface (the built-in plane). Programs built with BTF_FIXED_LIGHT = 1 read it.
 *
 *     btf_gl_fixed *x; btf_gl_fixed_create(gl, g, &x, &err);
 *     btf_gl_fixed_update(gl, x, g, local_light, n_chunks, &err); // redone only when they change
 *     f->UseProgram(prog->id);
 *     btf_gl_package_bind(gl, g, prog, 0, &err);
 *     btf_gl_fixed_bind(gl, x, prog, BTF_GL_FIXED_UNIT);
 *     ... draw ...
 *     btf_gl_fixed_free(gl, x);
 *
 * For the light's three samples (e, weight w_e; btf_dirtab_interp_vec on the package's
 * table, as btf_decode interpolates) and every view v, slot s and colour channel c:
 * W(v) = sum_e w_e W_q(l_e, v), W_q the weight as u_btf_wt holds it
 * (btf_gl_package_weight), so the decoder's value is the run-time program's up to the
 * rounding of W onto 11/11/10-bit grids of its own range over the views (u_btf_lq), at
 * most half a step of the package's grid (btf_gl_fixed_quant_error).
 * Layout: u_btf_lw RGBA32UI 2D, V x layers, texel (v, h) = slots 4h..4h+3 as R | G << 11
 * | B << 22; u_btf_lq 6 vec4 per layer: lo R, G, B, step R, G, B; slots beyond the
 * prefix get zero grids. Costs V x slots x 9 multiply-adds on the CPU per update.
 * Limitations: one light; a curved surface or a point light needs the run-time path.
 */
#ifndef BTF_GL_FIXED_H
#define BTF_GL_FIXED_H

#include <stdint.h>

#include "btf_gl.h"
#include "btf_gl_package.h"
#include "btf_shader.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_GL_FIXED_UNIT 5 /* texture unit after the package's (0..3) and the environment's (4) */

/* The per-draw weights of one package: made by btf_gl_fixed_create for a btf_gl_package,
 * freed by btf_gl_fixed_free (before the package); the CPU copy is what the texture holds. */
typedef struct btf_gl_fixed {
    GLuint tex;        /* u_btf_lw */
    int n_views, quads;
    uint32_t *codes;   /* n_views x quads x 4: the texture's texels, row h = layer h (malloc'd) */
    float *lq;         /* 24 per layer: u_btf_lq (malloc'd) */
    float light[3];    /* the local light the texture holds */
    int slots;         /* slots in use it holds (btf_gl_package_slots); 0: none yet */
} btf_gl_fixed;

btf_result btf_gl_fixed_create(btf_gl *gl, const btf_gl_package *g, btf_gl_fixed **out, btf_error *err);
void btf_gl_fixed_free(btf_gl *gl, btf_gl_fixed *x);

/* CPU only: x->codes and x->lq for local light `light` (z = normal, any length) and
 * the slots the first n_chunks chunks use (0 = all). */
void btf_gl_fixed_blend(btf_gl_fixed *x, const btf_gl_package *g, const float light[3], int n_chunks);

/* btf_gl_fixed_blend and the upload, unless x already holds this light and prefix. */
btf_result btf_gl_fixed_update(btf_gl *gl, btf_gl_fixed *x, const btf_gl_package *g, const float light[3],
                               int n_chunks, btf_error *err);

/* Binds u_btf_lw to `unit` and sets u_btf_lq of prog (in use); nothing if prog has no
 * u_btf_lw (a run-time program). */
void btf_gl_fixed_bind(btf_gl *gl, const btf_gl_fixed *x, const btf_shader_program *prog, int unit);

/* btf_gl_package_quant_error for a BTF_FIXED_LIGHT program drawn with x: the package's
 * terms plus, per slot, max|T| dL/2 + dT dL/4 (worst) and E[T^2] dL^2/12 (variance), dL the
 * per-draw step of each channel. */
void btf_gl_fixed_quant_error(const btf_gl_fixed *x, const btf_gl_package *g, double *worst, double *rms);

#ifdef __cplusplus
}
#endif
#endif
