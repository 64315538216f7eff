/* btf_pca.h - k-view block PCA of a BTF (the 2015 thesis on streaming BTFs, chapter 4).
 *
 *     btf_pca_options o = {0};   // zero = defaults: k 3, C 8, auto method, no centring
 *     o.k = 3; o.components = 8;
 *     btf_pca_model *m;
 *     btf_error err;
 *     // src: const btf *; no per-block callback (fn = NULL, ctx = NULL)
 *     if (btf_pca_compress(src, &o, NULL, NULL, &m, &err) == BTF_OK) {
 *         float r = btf_pca_model_value(m, view, light, x, y, 0, m->n_comp);
 *         btf_pca_model_free(m);
 *     }
 *
 * Views are grouped into blocks of k (btf_blocks_group); per block the data matrix
 * A (texels x 3*lights*views-in-block, column-major, byte/255 scale) is built on
 * the fly from the BTF, or from a view source that reads each block's views from
 * disk (btf_pca_compress_views, btf_views.h: one block's matrix in memory, never
 * the material), and approximated by C components: A ~= T W^T with T
 * (texels x C, unit columns = left singular vectors) and W (cols x C, V*sigma).
 * C counts component 0 (the row mean when centring, like the thesis).
 * All linear algebra is LAPACKE/OpenBLAS; rank-deficient blocks give zero
 * components, never NaN. See doc/package-format.md for the model.
 *
 * Not done here: quantisation, files, ordering (btf_package.h).
 */
#ifndef BTF_PCA_H
#define BTF_PCA_H

#include "btf.h"
#include "btf_blocks.h"
#include "btf_views.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_pca_method {
    BTF_PCA_AUTO = 0,       /* Gram when a block has <= 2048 columns, else randomized */
    BTF_PCA_GRAM,           /* cblas_ssyrk + LAPACKE_ssyevr for the top C */
    BTF_PCA_RANDOMIZED,     /* randomized range finder: sgemm + sgeqrf/sorgqr + small sgesdd */
    BTF_PCA_SVD             /* full LAPACKE_sgesdd: the slow baseline */
} btf_pca_method;

typedef enum btf_clipped {
    BTF_CLIPPED_DEFAULT = 0, /* = BTF_CLIPPED_FIT */
    BTF_CLIPPED_FIT,         /* samples at 0 or 1 may lie beyond it in the model */
    BTF_CLIPPED_KEEP         /* every sample fitted as stored (the thesis method) */
} btf_clipped;

/* A block with fewer than this share of its samples at 0 or 1 is fitted as stored:
 * the generated tiles' highlights (0.08-0.11% of their samples at 1) gained nothing
 * from the fit at 1e-4 (doc/performance.md section 3), the thesis corduroy's blocks
 * have 0.19-0.96%. */
#define BTF_PCA_CLIPPED_MIN_SHARE 2e-3

typedef enum btf_rounding {
    BTF_ROUNDING_DEFAULT = 0, /* = BTF_ROUNDING_CUT */
    BTF_ROUNDING_CUT,         /* components past the source's 8-bit rounding are zero */
    BTF_ROUNDING_KEEP         /* every component fitted, the rounding's too (the thesis method) */
} btf_rounding;

/* A block's components stop where what they leave, |A - T W^T|^2, is within this
 * many times the 8-bit rounding noise of its samples (rows x cols x (1/255)^2 / 12):
 * the ones after it fit the rounding of the stored bytes, which no display shows
 * (doc/package-format.md section 10.2). The thesis's corduroy at 64x64, k 3: its
 * blocks leave 1.5-2.0x that after 8 components (their published rank), 25-73x
 * after 7; the wool 2.9-3.2x and 34-38x; generated tiles 13x after 64. */
#define BTF_PCA_ROUNDING_FLOOR 4.0

/* Options; zero means default. Plain value. */
typedef struct btf_pca_options {
    int k;                  /* views per block, 1..n_views; 0 = 3 */
    int components;         /* C including component 0; 0 = 8 */
    btf_grouping grouping;
    btf_pca_method method;
    btf_center center;
    btf_clipped clipped;
    btf_rounding rounding;  /* default: the package writer keeps every component of linear and 16-bit packages */
    /* Optional: called after each block with blocks done and the total (progress
     * display); NULL = none. progress_ctx is passed through, owned by the caller. */
    void (*progress)(void *ctx, int done, int total);
    void *progress_ctx;
} btf_pca_options;

/* Columns of block b's data matrix: 3 * n_lights * views in block. */
int btf_blocks_cols(const btf *src, const btf_blocks *bl, int b);
/* Fills A (width*height rows x btf_blocks_cols columns, column-major, ld = rows). */
btf_result btf_pca_block_matrix(const btf *src, const btf_blocks *bl, int b, float *A, btf_error *err);

/* PCA of one block; malloc'd arrays owned by the model that holds it. */
typedef struct btf_pca_block {
    int rows, cols, n_comp;
    float *t;       /* rows x n_comp, column-major: the textures (unit columns, or the mean) */
    float *w;       /* cols x n_comp, column-major: the weights (V * sigma, or 1 for the mean) */
    float *sigma;   /* n_comp: singular values (1 for the mean) */
    double energy;  /* |A|_F^2 in double */
} btf_pca_block;

/* Top C components of A (rows x cols, column-major, ld = rows; not modified).
 * C must be <= min(rows, cols). out's arrays are malloc'd (btf_pca_block_clear). */
btf_result btf_pca_block_compute(const float *A, int rows, int cols, int C, btf_pca_method method,
                                 btf_center center, btf_pca_block *out, btf_error *err);
void btf_pca_block_clear(btf_pca_block *blk);

/* Called once per block while its data matrix is alive (used by the package writer
 * to quantise and to accumulate exact error sums without rebuilding A). */
typedef btf_result (*btf_pca_block_fn)(void *ctx, int block, const float *A, const btf_pca_block *res,
                                       btf_error *err);

/* Whole-BTF float model; owned by the caller, btf_pca_model_free. */
typedef struct btf_pca_model {
    int width, height;
    btf_dirset lights, views;
    btf_blocks *blocks;
    int k, n_comp;
    btf_center center;
    btf_grouping grouping;
    btf_pca_method method; /* as asked (BTF_PCA_AUTO stays AUTO) */
    btf_pca_block *block;  /* n_blocks */
} btf_pca_model;

/* The share of src's samples exactly at 0 or 1 (byte/255 scale): those the clipped
 * fit may move (doc/package-format.md section 10.2). */
double btf_pca_clipped_share(const btf *src);
/* Checks options against the source (k, C in range, finite data). */
btf_result btf_pca_check(const btf *src, const btf_pca_options *opt, btf_error *err);
/* The same checks without reading any data (a non-finite sample fails its block). */
btf_result btf_pca_check_views(const btf_views *src, const btf_pca_options *opt, btf_error *err);
btf_result btf_pca_compress(const btf *src, const btf_pca_options *opt, btf_pca_block_fn fn, void *ctx,
                            btf_pca_model **out, btf_error *err);
/* The same from a view source: each block's views are filled straight into its data
 * matrix (3 * lights * k * texels floats, the peak besides the model); results equal
 * btf_pca_compress on the BTF the source reads, bit for bit. out NULL: no model is
 * kept (each block is released after fn saw it). */
/* Fills block b's matrix (rows x 3L per view, views in block order) from a view
 * source, one view at a time; what btf_pca_compress_views computes each block from. */
btf_result btf_pca_block_fill(btf_views *src, const btf_blocks *bl, int b, float *A, btf_error *err);
btf_result btf_pca_compress_views(btf_views *src, const btf_pca_options *opt, btf_pca_block_fn fn, void *ctx,
                                  btf_pca_model **out, btf_error *err);
void btf_pca_model_free(btf_pca_model *m);
/* The most components any block of m holds that are not zero (rank-deficient or past
 * the source's rounding, BTF_ROUNDING_CUT): at most m->n_comp. */
int btf_pca_model_rank(const btf_pca_model *m);
/* Float reconstruction of one sample from the first n components (n <= n_comp). */
float btf_pca_model_value(const btf_pca_model *m, int view, int light, int x, int y, int c, int n);

/* Resolved defaults (what zero means). */
btf_pca_options btf_pca_resolve(const btf_pca_options *opt);

#ifdef __cplusplus
}
#endif
#endif
