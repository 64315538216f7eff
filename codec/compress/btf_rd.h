/* btf_rd.h - rate-distortion choice of the quantisation steps of a package
 * (doc/package-format.md section 10.8): per component one texture and one weight
 * step multiplier, chosen with one Lagrange multiplier (equal slope) so that the
 * quantisation adds the same squared error as the equal-noise allocation of
 * section 4 with fewer bytes. Used by the package writer (btf_package_options.rd).
 * Texture rates of atlases over 9 tiles are measured on a sample of whole tile rows
 * and scaled (section 11), so bytes_equal and bytes_rd are estimates there. With
 * lossy, a component's texture may instead be a lossy WebP or AVIF of its full-range codes
 * (btf_rd_result.tex_quality), its error then estimated from that sample too.
 *
 *     btf_rd_params par = {model, cols, rows, 0.5f, 0, 0, NULL, 0.0, NULL, NULL, 8, 0, 0};  // equal-noise error, lossless WebP, every step measured
 *     btf_rd_result rr;
 *     if (btf_rd_allocate(&par, &rr, &err) == BTF_OK) {
 *         float g = rr.tex_noise[0], h = rr.wt_noise[0];   // component 0's noise multipliers
 *         btf_rd_result_free(&rr);
 *     }
 */
#ifndef BTF_RD_H
#define BTF_RD_H

#include <math.h>

#include "btf.h"
#include "btf_pca.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Below this many bytes in all (components x (atlas + 16-bit weights); the package
 * writer: components x atlas), the allocation's ladders
 * and the package writer's files stay on the calling thread: small packages gain
 * nothing, and a process forked after OpenMP has run (a test's child, a server's
 * worker) cannot start OpenMP threads again (libgomp waits for the parent's). */
#define BTF_RD_THREAD_MIN_BYTES ((size_t)1 << 20)

/* Ladder notches (factors of sqrt 2 in noise) measured either side of a near choice
 * (btf_rd_params.near): tiles at 128x128, the winner written from the whole material
 * after the search on its centre window: see doc/package-format.md section 11.4. */
#define BTF_RD_NEAR_NOTCHES 2

/* The measured ladders of one model (rates and distortions of every candidate step),
 * kept so that a second allocation for the same model skips the measuring (the
 * budget search allocates twice per k: equal-noise error and fitted to the bytes).
 * Owned by the caller: zero it, pass it in btf_rd_params.ladder, btf_rd_ladder_free. */
typedef struct btf_rd_ladder {
    double key[8];          /* the model's sizes, noise, png_only and a sum over its values */
    int n_comp;             /* 0 = empty */
    int n_tex, n_wt;        /* candidate steps per component: dt, rt hold n_comp x n_tex, dw, rw n_comp x n_wt */
    double *dt, *dw, *energy;
    long long *rt, *rw;
} btf_rd_ladder;

/* Inputs of one allocation; plain value, its pointers are borrowed for the call. */
typedef struct btf_rd_params {
    const btf_pca_model *model; /* the float PCA of the package */
    int atlas_cols, atlas_rows; /* the package's atlas grid */
    float tex_noise;            /* equal-noise reference per component (0..255 scale), > 0 */
    /* > 0: instead of the equal-noise error, the least error (PCA truncation plus
     * quantisation) whose kept components' files fit in max_bytes: a component is
     * kept when its energy exceeds its quantised cost D + lambda R, lambda the
     * smallest slope that fits (btf_budget). */
    long long max_bytes;
    int png_only;               /* 1: texture bytes as PNG; 0: as lossless WebP, as written */
    /* NULL, or ladders to reuse when they were measured on this model (same key),
     * else measured and stored there for the next call */
    btf_rd_ladder *ladder;
    double tex_rate_scale; /* > 0: texture bytes counted this many times over (btf_package_options) */
    /* NULL, or an allocation on a model of the same material with at most as many
     * components (btf_budget: the winner's on the centre window, or the candidate a
     * grown one grew from): unless the ladder is reused, its components' steps are
     * measured only within BTF_RD_NEAR_NOTCHES ladder notches of its choices, and at
     * the reference steps (equal-noise texture, 16-bit weights); the ladder measured
     * so is not stored in ladder */
    const struct btf_rd_result *near;
    /* NULL, or one factor per model component: component j's texture rates, at every
     * step, times tex_rate_fix[j] (> 0; others ignored): the atlas as written over its
     * estimate, so that an allocation made again after a write (btf_budget's refit)
     * counts the bytes the writer produces */
    const double *tex_rate_fix;
    int bits; /* texture codes: 8 (or 0), or 16: steps may go down to 1/65535 of a block's range, the
               * atlas then a PNG of (high byte, low byte, 0) pixels, as the writer stores 16 bits */
    /* BTF_LOSSY_WEBP or BTF_LOSSY_AVIF (btf_lossy.h; 8 bits, not png_only): each
     * component's texture may also be its full-range atlas as a lossy WebP or AVIF at
     * one of the BTF_LOSSY_LADDER levels of btf_lossy_ladder, a candidate beside the
     * lossless steps chosen by the same lambda; its error measured on the rate
     * sample's decode (the blocks outside it: their rounding error plus the sample's
     * mean lossy error per texel) */
    int lossy;
    /* 1 (not png_only): each component's weights may also be a lossy WebP of their
     * full-range 8-bit codes (btf_rd_wt_lossy) at one of the BTF_LOSSY_LADDER WebP
     * qualities, a candidate beside the weight steps chosen by the same lambda, its
     * error measured on its decode (btf_rd_result.wt_quality; with spatial levels the
     * same file becomes version 4's wt-JJ-8.webp); 0: steps only */
    int lossy_weights;
} btf_rd_params;

/* What one allocation chose and measured; owned by the caller (btf_rd_result_free). */
typedef struct btf_rd_result {
    int n_comp;
    float *tex_noise;       /* n_comp: RMS noise (0..255) of component j's texture steps */
    float *wt_noise;        /* n_comp: the same for its weights; 0 = the full 16-bit range */
    double lambda;          /* the common slope: squared error (byte/255 scale) per byte */
    double d_target, d_rd;  /* added squared error: equal-noise allocation, chosen (all components) */
    long long bytes_equal;  /* files of the equal-noise allocation (atlases + deflated 16-bit weights) */
    long long bytes_rd;     /* the same files at the chosen steps (with max_bytes: of the kept components) */
    int n_kept;             /* components worth their bytes at lambda (all without max_bytes) */
    long long *comp_bytes;  /* n_comp: component j's files at its chosen steps (counted as bytes_rd is) */
    long long *tex_bytes;   /* n_comp: the texture atlas's share of comp_bytes */
    int *tex_quality;       /* n_comp: -1, or the lossy level of component j's texture (WebP quality
                             * 0..100, AVIF quantiser 0..63: btf_rd_params.lossy's encoding)
                             * (full-range codes: its tex_noise is 0) */
    int *wt_quality;        /* n_comp: -1, or the WebP quality of component j's lossy weights
                             * (btf_rd_wt_lossy; its wt_noise is 0) */
} btf_rd_result;

btf_result btf_rd_allocate(const btf_rd_params *par, btf_rd_result *out, btf_error *err);

/* Component j's weights of model m as a lossy WebP at quality 0..100 (a version-3
 * wt-JJ.webp, doc/package-format.md section 5.5): each block's weights mapped onto
 * 0..255 by their full range (btf_rd_range, into ranges: n_blocks x {lo, step}),
 * pixel (l, v) sample c holding view v, light l, channel c, encoded
 * (btf_webp_encode_rgb_lossy) into *file (malloc'd, *n bytes) and decoded as every
 * reader decodes it into q (V*L*3 codes). The one rule of the writer and the
 * allocation. */
btf_result btf_rd_wt_lossy(const btf_pca_model *m, int j, int quality, float *ranges, uint16_t *q, uint8_t **file,
                           size_t *n, btf_error *err);
void btf_rd_result_free(btf_rd_result *r);
void btf_rd_ladder_free(btf_rd_ladder *l);

/* Quantisation step for values of range step `range_step` (full range / qmax) whose
 * RMS noise, spread over n samples by a factor of norm, is to be `noise` (0..255
 * scale): max(range_step, noise/255 * sqrt(12 n) / norm); noise <= 0 or norm <= 0
 * keeps range_step. The one rule of the writer and the allocation. */
static inline float btf_rd_step(float range_step, float noise, int n, float norm)
{
    if (!(noise > 0.0f) || !(norm > 0.0f))
        return range_step;
    float s = noise / 255.0f * sqrtf(12.0f * (float)n) / norm;
    return s > range_step ? s : range_step;
}

/* Affine range of x[0..n-1] onto 0..qmax: {lo, (hi - lo) / qmax} (step 0 when flat). */
static inline void btf_rd_range(const float *x, size_t n, unsigned qmax, float range[2])
{
    float lo = x[0], hi = x[0];
    for (size_t i = 1; i < n; i++) {
        lo = x[i] < lo ? x[i] : lo;
        hi = x[i] > hi ? x[i] : hi;
    }
    float step = (hi - lo) / (float)qmax;
    range[0] = lo;
    range[1] = (step > 0.0f && isfinite(step)) ? step : 0.0f;
}

/* Nearest q in 0..qmax of x under range {lo, step}. */
static inline unsigned btf_rd_quant(float x, const float range[2], unsigned qmax)
{
    if (range[1] <= 0.0f)
        return 0;
    float q = rintf((x - range[0]) / range[1]);
    return q <= 0.0f ? 0u : q >= (float)qmax ? qmax : (unsigned)q;
}

#ifdef __cplusplus
}
#endif
#endif
