/* btf_method.h - method families side by side: one small interface that
 * every compression method implements, and a registry of method settings a chart
 * or a test can iterate over.
 *
 *     const btf_method_setting *s;
 *     int n = btf_method_registry(&s);
 *     for (int i = 0; i < n; i++) {
 *         btf_model *m;
 *         if (btf_model_encode(s[i].method, src, &s[i].params, &m, &err) != BTF_OK) continue;
 *         float rgb[3];
 *         btf_model_decode(m, x, y, light_dir, view_dir, rgb);   // any directions
 *         printf("%s %zu bytes\n", s[i].label, btf_model_bytes(m));
 *         btf_model_free(m);
 *     }
 *
 * Methods (codec/btf_m_*.c):
 * - "phong": lit texture, per texel ambient + Lambert + one normalised Blinn-Phong
 *   lobe; non-negative linear least squares per exponent of a fixed grid, best kept
 *   (the thesis section 6.3 "flat" baseline).
 * - "lafortune": per texel ambient + diffuse + 1-2 Lafortune lobes (McAllister's
 *   Lafortune fitting); lobe shapes by Levenberg-Marquardt (GSL) on luminance with bounded
 *   parameters, colours by non-negative least squares. A fit that fails (solver error),
 *   produces a non-finite value, peaks out of bounds or is worse than its grid start
 *   falls back to the
 *   grid start (counted in btf_model.n_fallback): never NaN. A fit stopped by the
 *   iteration cap is validated the same way (counted in btf_model.n_unconverged).
 * - "pca": the project's k-view block PCA (btf_pca.h), float model; "pca-q": the same
 *   written as a package (btf_package.h, 8-bit) and read back.
 * - "lpyr": Laplacian-pyramid PCA (Ma et al.'s Laplacian-pyramid BTF compression):
 *   per level, PCA of the Laplacian coefficients over k-view blocks; decoding may
 *   stop after the coarsest levels.
 *
 * Conventions: sample values are on the byte/255 scale of btf_get (sRGB-encoded).
 * The analytic methods (phong, lafortune) fit in linear light (sRGB decoded) and
 * encode their output back; they evaluate any direction directly (a light below the
 * horizon gets no direct term; a view below the horizon is clamped to it). The
 * tabulated methods (pca, lpyr) interpolate their measured directions with
 * btf_dirset_interp_vec. Decoders never return NaN for finite input; outputs are
 * not clamped (the stability suite, tests/eval/test_stability.c, measures the range).
 * Sizes (btf_model_bytes) count float32 parameters (4 bytes each) except "pca-q",
 * which counts its package files.
 *
 * Limitations: models live in memory only (no file format except pca-q's package).
 * GSL's abort-on-error handler is switched off (gsl_set_error_handler_off) by the
 * first Lafortune encode.
 */
#ifndef BTF_METHOD_H
#define BTF_METHOD_H

#include <stddef.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Encoder parameters; zero means default. Plain value. Each method reads the
 * fields it needs and ignores the others. */
typedef struct btf_method_params {
    int k;             /* pca, lpyr: views per block (clamped to the view count); 0 = 3 */
    int components;    /* pca: C per block; lpyr: C per level and block; 0 = 8 */
    int lobes;         /* lafortune: 1 or 2; 0 = 1 */
    int levels;        /* lpyr: pyramid levels incl. the low-pass top; 0 = 3 (fewer if the size is small) */
    int decode_levels; /* lpyr: decode the coarsest n levels only; 0 = all */
    int max_iter;      /* lafortune: LM iteration cap per texel; 0 = 50 */
    int fit_pairs;     /* lafortune: (view, light) pairs used per texel fit; 0 = 512 */
} btf_method_params;

/* Decode cost estimate per fragment (for the speed axis of a chart). Plain value. */
typedef struct btf_method_cost {
    int fetches; /* stored values read per decoded RGB value (texture fetches, scalar) */
    int flops;   /* arithmetic operations, rough */
} btf_method_cost;

typedef struct btf_method btf_method;

/* An encoded model: public header plus method data. Created by btf_model_encode,
 * owned by the caller, released with btf_model_free. */
typedef struct btf_model {
    const btf_method *method;
    btf_method_params params; /* as given, defaults resolved by the method */
    int width, height;
    btf_dirset lights, views; /* of the source */
    float lo, hi;             /* smallest and largest source sample (byte/255 scale) */
    double seconds;           /* encode wall time */
    int n_fallback;           /* lafortune: texels whose nonlinear fit was rejected (grid start kept) */
    int n_unconverged;        /* lafortune: texels whose LM stopped at max_iter (kept if valid and better) */
    void *impl;               /* method data, owned by the model */
} btf_model;

/* One method family; static constant tables, live forever. */
struct btf_method {
    const char *name;
    const char *summary;
    int tabulated; /* 1: decodes by interpolating measured directions; 0: analytic */
    /* Fills m->impl (and may resolve m->params); src is finite and non-empty here. */
    btf_result (*encode)(const btf *src, btf_model *m, btf_error *err);
    void (*decode)(const btf_model *m, int x, int y, const float light[3], const float view[3], float rgb[3]);
    size_t (*bytes)(const btf_model *m);
    void (*cost)(const btf_model *m, btf_method_cost *out);
    void (*free_impl)(void *impl);
};

extern const btf_method btf_method_phong;
extern const btf_method btf_method_lafortune;
extern const btf_method btf_method_pca;
extern const btf_method btf_method_pca_q;
extern const btf_method btf_method_lpyr;

/* Checks the source (non-empty, finite: BTF_ERR_NUMERIC names a NaN/Inf sample),
 * encodes, times. On failure *out is NULL. */
btf_result btf_model_encode(const btf_method *method, const btf *src, const btf_method_params *params,
                            btf_model **out, btf_error *err);
/* Value at texel (x, y) (clamped to the size) for local directions (z = normal,
 * need not be unit); byte/255 scale; never NaN for finite input. */
void btf_model_decode(const btf_model *m, int x, int y, const float light[3], const float view[3], float rgb[3]);
size_t btf_model_bytes(const btf_model *m);
btf_method_cost btf_model_cost(const btf_model *m);
void btf_model_free(btf_model *m);

/* Method by name ("phong", "lafortune", "pca", "pca-q", "lpyr"); NULL if unknown. */
const btf_method *btf_method_find(const char *name);

/* One setting of the registry; static, lives forever. */
typedef struct btf_method_setting {
    const btf_method *method;
    btf_method_params params;
    const char *label;  /* unique, e.g. "pca k3 C8" */
    const char *family; /* chart line: settings of one family share it, e.g. "pca k3" */
} btf_method_setting;

/* All settings for a chart: families across their parameters, cheapest first
 * within a family. Returns the count. */
int btf_method_registry(const btf_method_setting **out);

/* Per-texel parameters of a phong model (tests, inspection); linear light. */
typedef struct btf_phong_texel {
    float exponent;   /* Blinn-Phong exponent e */
    float ambient[3]; /* a */
    float diffuse[3]; /* kd (times max(l.z, 0)) */
    float spec[3];    /* ks (times (e+8)/8 max(n.h,0)^e max(l.z,0)) */
} btf_phong_texel;
btf_result btf_phong_get(const btf_model *m, int x, int y, btf_phong_texel *out, btf_error *err);

/* Lafortune lobe shape: base = cxy (lx vx + ly vy) + lz vz, lobe = (n+2)/2 max(base,0)^n. */
typedef struct btf_lafortune_texel {
    int lobes;
    float cxy[2], n[2];
    float ambient[3], diffuse[3], spec[2][3];
} btf_lafortune_texel;
btf_result btf_lafortune_get(const btf_model *m, int x, int y, btf_lafortune_texel *out, btf_error *err);

/* lpyr: levels actually built, and the size of level i (0 = finest). */
int btf_lpyr_levels(const btf_model *m);
/* Sets how many of the coarsest levels btf_model_decode uses (0 or > levels = all). */
void btf_lpyr_set_decode_levels(btf_model *m, int n);
/* Value of level i alone (Laplacian coefficient, or the low-pass top) at a measured
 * (view, light) pair and the level's own texel (x, y), channel c: for tests. */
float btf_lpyr_level_value(const btf_model *m, int level, int view, int light, int x, int y, int c);

/* ---- shared helpers for the method implementations (not for users; btf_m_shared.c) ---- */
float btf__srgb_to_linear(float v);
float btf__linear_to_srgb(float v);
/* Unit direction in the local frame from any vector; NaN/zero -> the normal. */
void btf__unit(const float in[3], float out[3]);
/* Unit view direction with a view below the horizon clamped to the horizon at its
 * azimuth (straight below: the normal). */
void btf__unit_view(const float in[3], float out[3]);
/* One (view, light) image of src in linear light (sRGB decoded), width*height*3 floats. */
void btf__image_linear(const btf *src, int view, int light, float *dst);
/* Non-negative least squares min |A x - y|^2 for p <= 6 unknowns from the normal
 * equations G = A^T A (p x p, row-major), g = A^T y, yy = y^T y; exhaustive over
 * active sets. Writes x (p values >= 0) and returns the residual sum of squares. */
double btf__nnls(int p, const double *G, const double *g, double yy, double *x);

#ifdef __cplusplus
}
#endif
#endif
