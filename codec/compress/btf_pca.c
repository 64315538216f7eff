/* btf_pca.c - block data matrices and per-block PCA (LAPACKE/OpenBLAS); the view
 * blocks themselves are btf_blocks.c's. */
#include "btf_pca.h"
#include "btf_common.h"
#include "btf_blocks.h"

#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define BTF__AUTO_GRAM_MAX_COLS 2048
#define BTF__RSVD_OVERSAMPLE 8
#define BTF__RSVD_POWER 2
#define BTF__CLIP_STEPS 8        /* subspace steps of the clipped-sample fit */

/* ---------------------------------------------------------------- options */

btf_pca_options btf_pca_resolve(const btf_pca_options *opt)
{
    btf_pca_options o = {0};
    if (opt)
        o = *opt;
    if (o.k == 0)
        o.k = 3;
    if (o.components == 0)
        o.components = 8;
    if (o.grouping == BTF_GROUP_DEFAULT)
        o.grouping = BTF_GROUP_CONSECUTIVE;
    if (o.center == BTF_CENTER_DEFAULT)
        o.center = BTF_CENTER_NONE;
    if (o.rounding == BTF_ROUNDING_DEFAULT)
        o.rounding = BTF_ROUNDING_CUT;
    return o;
}

/* ---------------------------------------------------------------- data matrix */

btf_result btf_pca_block_fill(btf_views *src, const btf_blocks *bl, int b, float *A, btf_error *err)
{
    size_t per = btf_views_floats(src);
    for (int i = bl->start[b]; i < bl->start[b + 1]; i++) {
        btf_result r = btf_views_fill(src, bl->views[i], A + (size_t)(i - bl->start[b]) * per, err);
        if (r != BTF_OK)
            return r;
    }
    return BTF_OK;
}

btf_result btf_pca_block_matrix(const btf *src, const btf_blocks *bl, int b, float *A, btf_error *err)
{
    if (!src || !bl || !A || b < 0 || b >= bl->n_blocks || bl->n_views != src->views.n_dirs)
        return btf_fail(err, BTF_ERR_ARG, "block matrix: bad arguments (block %d)", b);
    btf_views s;
    btf_views_wrap(src, &s);
    return btf_pca_block_fill(&s, bl, b, A, err);
}

/* ---------------------------------------------------------------- per-block PCA */

void btf_pca_block_clear(btf_pca_block *blk)
{
    if (!blk)
        return;
    free(blk->t), free(blk->w), free(blk->sigma);
    memset(blk, 0, sizeof *blk);
}

/* Operator of the (possibly row-centred) matrix Ac = A - m 1^T without forming it. */
typedef struct btf__op {
    const float *A;
    int rows, cols;
    const float *m; /* row means, or NULL when not centring */
} btf__op;

/* Y (rows x n) = Ac X (X: cols x n). */
static void btf__op_mul(const btf__op *op, const float *X, int n, float *Y, float *tmp_n)
{
    cblas_sgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, op->rows, n, op->cols, 1.0f, op->A, op->rows, X,
                op->cols, 0.0f, Y, op->rows);
    if (!op->m)
        return;
    for (int j = 0; j < n; j++) { /* column sums of X */
        double s = 0.0;
        for (int i = 0; i < op->cols; i++)
            s += X[(size_t)j * op->cols + i];
        tmp_n[j] = (float)s;
    }
    cblas_sger(CblasColMajor, op->rows, n, -1.0f, op->m, 1, tmp_n, 1, Y, op->rows);
}

/* Z (cols x n) = Ac^T Y (Y: rows x n). */
static void btf__op_mul_t(const btf__op *op, const float *Y, int n, float *Z, float *tmp_n, float *ones)
{
    cblas_sgemm(CblasColMajor, CblasTrans, CblasNoTrans, op->cols, n, op->rows, 1.0f, op->A, op->rows, Y,
                op->rows, 0.0f, Z, op->cols);
    if (!op->m)
        return;
    cblas_sgemv(CblasColMajor, CblasTrans, op->rows, n, 1.0f, Y, op->rows, op->m, 1, 0.0f, tmp_n, 1);
    cblas_sger(CblasColMajor, op->cols, n, -1.0f, ones, 1, tmp_n, 1, Z, op->cols);
}

/* Orthonormalises the columns of Y (m x n, m >= n) in place: sgeqrf + sorgqr. */
static int btf__orth(float *Y, int m, int n, float *tau)
{
    if (LAPACKE_sgeqrf(LAPACK_COL_MAJOR, m, n, Y, m, tau) != 0)
        return -1;
    return LAPACKE_sorgqr(LAPACK_COL_MAJOR, m, n, n, Y, m, tau) != 0 ? -1 : 0;
}

/* Top p right singular vectors V (cols x p) and values of Ac by the Gram route. */
static btf_result btf__top_gram(const btf__op *op, int p, float *V, float *s, btf_error *err)
{
    int n = op->cols;
    float *G = btf_big_alloc((size_t)n * n * sizeof(float));
    float *ev = malloc((size_t)n * sizeof(float));
    int *supp = malloc(2 * (size_t)p * sizeof(int));
    if (!G || !ev || !supp) {
        free(G), free(ev), free(supp);
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: cannot allocate the %dx%d Gram matrix", n, n);
    }
    cblas_ssyrk(CblasColMajor, CblasUpper, CblasTrans, n, op->rows, 1.0f, op->A, op->rows, 0.0f, G, n);
    if (op->m) { /* Ac^T Ac = A^T A - a 1^T - 1 a^T + (m.m) 1 1^T, a = A^T m */
        float *a = malloc((size_t)n * sizeof(float)), *ones = malloc((size_t)n * sizeof(float));
        if (!a || !ones) {
            free(a), free(ones), free(G), free(ev), free(supp);
            return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory");
        }
        for (int i = 0; i < n; i++)
            ones[i] = 1.0f;
        cblas_sgemv(CblasColMajor, CblasTrans, op->rows, n, 1.0f, op->A, op->rows, op->m, 1, 0.0f, a, 1);
        float mm = cblas_sdot(op->rows, op->m, 1, op->m, 1);
        cblas_ssyr2(CblasColMajor, CblasUpper, n, -1.0f, a, 1, ones, 1, G, n);
        cblas_ssyr(CblasColMajor, CblasUpper, n, mm, ones, 1, G, n);
        free(a), free(ones);
    }
    int found = 0;
    int info = LAPACKE_ssyevr(LAPACK_COL_MAJOR, 'V', 'I', 'U', n, G, n, 0.0f, 0.0f, n - p + 1, n, 0.0f, &found, ev,
                              V, n, supp);
    free(G), free(supp);
    if (info != 0 || found != p) {
        free(ev);
        return btf_fail(err, BTF_ERR_NUMERIC, "PCA: ssyevr failed (info %d, %d of %d eigenpairs)", info, found, p);
    }
    /* ascending -> descending */
    for (int i = 0; i < p / 2; i++) {
        float t = ev[i];
        ev[i] = ev[p - 1 - i];
        ev[p - 1 - i] = t;
        for (int r = 0; r < n; r++) {
            float x = V[(size_t)i * n + r];
            V[(size_t)i * n + r] = V[(size_t)(p - 1 - i) * n + r];
            V[(size_t)(p - 1 - i) * n + r] = x;
        }
    }
    for (int i = 0; i < p; i++)
        s[i] = ev[i] > 0.0f ? sqrtf(ev[i]) : 0.0f;
    free(ev);
    return BTF_OK;
}

/* Randomized range finder (Halko et al.): top p right singular vectors and values. */
static btf_result btf__top_randomized(const btf__op *op, int p, float *V, float *s, btf_error *err)
{
    int mn = op->rows < op->cols ? op->rows : op->cols;
    int l = p + BTF__RSVD_OVERSAMPLE > mn ? mn : p + BTF__RSVD_OVERSAMPLE;
    size_t nY = (size_t)op->rows * l, nZ = (size_t)op->cols * l;
    float *Y = malloc(nY * sizeof(float)), *Z = malloc(nZ * sizeof(float));
    float *tau = malloc((size_t)l * sizeof(float)), *tmp = malloc((size_t)l * sizeof(float));
    float *ones = malloc((size_t)op->cols * sizeof(float)), *sv = malloc((size_t)l * sizeof(float));
    float *U = malloc((size_t)l * l * sizeof(float)), *VT = malloc((size_t)l * op->cols * sizeof(float));
    btf_result r = BTF_OK;
    if (!Y || !Z || !tau || !tmp || !ones || !sv || !U || !VT) {
        r = btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (randomized, %d x %d)", op->rows, l);
        goto done;
    }
    for (int i = 0; i < op->cols; i++)
        ones[i] = 1.0f;
    int seed[4] = {1, 7, 11, 13};
    LAPACKE_slarnv(3, seed, (lapack_int)nZ, Z);
    btf__op_mul(op, Z, l, Y, tmp);
    for (int it = 0; it < BTF__RSVD_POWER; it++) {
        if (btf__orth(Y, op->rows, l, tau) != 0)
            goto qr_fail;
        btf__op_mul_t(op, Y, l, Z, tmp, ones);
        if (btf__orth(Z, op->cols, l, tau) != 0)
            goto qr_fail;
        btf__op_mul(op, Z, l, Y, tmp);
    }
    if (btf__orth(Y, op->rows, l, tau) != 0)
        goto qr_fail;
    btf__op_mul_t(op, Y, l, Z, tmp, ones); /* Z = Ac^T Q = B^T (cols x l) */
    /* B^T = Vb S Ub^T: the right singular vectors of Ac are the left ones of B^T */
    if (LAPACKE_sgesdd(LAPACK_COL_MAJOR, 'S', op->cols, l, Z, op->cols, sv, VT, op->cols, U, l) != 0) {
        r = btf_fail(err, BTF_ERR_NUMERIC, "PCA: sgesdd of the %d x %d projection failed", op->cols, l);
        goto done;
    }
    memcpy(V, VT, (size_t)op->cols * p * sizeof(float));
    memcpy(s, sv, (size_t)p * sizeof(float));
    goto done;
qr_fail:
    r = btf_fail(err, BTF_ERR_NUMERIC, "PCA: QR factorisation failed (randomized)");
done:
    free(Y), free(Z), free(tau), free(tmp), free(ones), free(sv), free(U), free(VT);
    return r;
}

/* Full SVD baseline: explicit centred copy, sgesdd. */
static btf_result btf__top_svd(const btf__op *op, int p, float *V, float *s, btf_error *err)
{
    size_t n = (size_t)op->rows * op->cols;
    int mn = op->rows < op->cols ? op->rows : op->cols;
    float *Ac = btf_big_alloc(n * sizeof(float)), *sv = malloc((size_t)mn * sizeof(float));
    float *VT = malloc((size_t)mn * op->cols * sizeof(float));
    if (!Ac || !sv || !VT) {
        free(Ac), free(sv), free(VT);
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: cannot copy the %d x %d block for sgesdd", op->rows, op->cols);
    }
    memcpy(Ac, op->A, n * sizeof(float));
    if (op->m)
        for (int c = 0; c < op->cols; c++)
            cblas_saxpy(op->rows, -1.0f, op->m, 1, Ac + (size_t)c * op->rows, 1);
    int info;
    float *U = btf_big_alloc((size_t)op->rows * mn * sizeof(float));
    if (!U) {
        free(Ac), free(sv), free(VT);
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (sgesdd U)");
    }
    info = LAPACKE_sgesdd(LAPACK_COL_MAJOR, 'S', op->rows, op->cols, Ac, op->rows, sv, U, op->rows, VT, mn);
    free(Ac), free(U);
    if (info != 0) {
        free(sv), free(VT);
        return btf_fail(err, BTF_ERR_NUMERIC, "PCA: sgesdd failed (info %d)", info);
    }
    for (int j = 0; j < p; j++) {
        s[j] = sv[j];
        for (int c = 0; c < op->cols; c++)
            V[(size_t)j * op->cols + c] = VT[(size_t)c * mn + j];
    }
    free(sv), free(VT);
    return BTF_OK;
}

/* t_j = Ac v_j / |Ac v_j|, w_j = |Ac v_j| v_j: exact projection A V V^T whatever the
 * accuracy of sigma; zero components for (numerically) zero singular values. */
static btf_result btf__finish(const btf__op *op, int p, const float *V, btf_pca_block *out, int off,
                              btf_error *err)
{
    float *tmp = malloc((size_t)(p > 0 ? p : 1) * sizeof(float));
    if (!tmp)
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory");
    float *T = out->t + (size_t)off * op->rows;
    btf__op_mul(op, V, p, T, tmp);
    free(tmp);
    float smax = 0.0f;
    for (int j = 0; j < p; j++) {
        float *tj = T + (size_t)j * op->rows, *wj = out->w + (size_t)(off + j) * op->cols;
        float s = cblas_snrm2(op->rows, tj, 1);
        if (s > smax)
            smax = s;
        if (!(s > 1e-30f) || !isfinite(s) || s <= smax * 1e-7f) { /* rank deficiency: no division */
            memset(tj, 0, (size_t)op->rows * sizeof(float));
            memset(wj, 0, (size_t)op->cols * sizeof(float));
            out->sigma[off + j] = 0.0f;
            continue;
        }
        cblas_sscal(op->rows, 1.0f / s, tj, 1);
        for (int c = 0; c < op->cols; c++)
            wj[c] = s * V[(size_t)j * op->cols + c];
        out->sigma[off + j] = s;
    }
    return BTF_OK;
}

static btf_result btf__block_alloc(btf_pca_block *out, int rows, int cols, int C, btf_error *err)
{
    memset(out, 0, sizeof *out);
    out->rows = rows, out->cols = cols, out->n_comp = C;
    out->t = calloc((size_t)rows * C, sizeof(float));
    out->w = calloc((size_t)cols * C, sizeof(float));
    out->sigma = calloc((size_t)C, sizeof(float));
    if (!out->t || !out->w || !out->sigma) {
        btf_pca_block_clear(out);
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: cannot allocate %d components of %d texels", C, rows);
    }
    return BTF_OK;
}

/* Allocates out for C components of A and fills what needs no decomposition: the
 * energy and, centred, component 0 (the row mean, weight 1); op reads A (centred by
 * that mean), *off is the first component left to find. */
static btf_result btf__block_start(const float *A, int rows, int cols, int C, btf_center center,
                                   btf_pca_block *out, btf__op *op, int *off, btf_error *err)
{
    btf_result r = btf__block_alloc(out, rows, cols, C, err);
    if (r != BTF_OK)
        return r;
    double e = 0.0;
    size_t n = (size_t)rows * cols;
    for (size_t i = 0; i < n; i++)
        e += (double)A[i] * A[i];
    out->energy = e;
    if (!isfinite(e)) {
        btf_pca_block_clear(out);
        return btf_fail(err, BTF_ERR_NUMERIC, "PCA: block data is not finite");
    }
    *op = (btf__op){A, rows, cols, NULL};
    *off = 0;
    if (center == BTF_CENTER_ROW) { /* component 0 = row mean, weight 1 */
        for (int c = 0; c < cols; c++)
            out->w[c] = 1.0f / (float)cols;
        cblas_sgemv(CblasColMajor, CblasNoTrans, rows, cols, 1.0f, A, rows, out->w, 1, 0.0f, out->t, 1);
        for (int c = 0; c < cols; c++)
            out->w[c] = 1.0f;
        out->sigma[0] = 1.0f;
        op->m = out->t;
        *off = 1;
    }
    return BTF_OK;
}

btf_result btf_pca_block_compute(const float *A, int rows, int cols, int C, btf_pca_method method,
                                 btf_center center, btf_pca_block *out, btf_error *err)
{
    if (!A || !out || rows < 1 || cols < 1)
        return btf_fail(err, BTF_ERR_ARG, "PCA: empty block");
    int mn = rows < cols ? rows : cols;
    if (C < 1 || C > mn)
        return btf_fail(err, BTF_ERR_RANGE, "components C = %d: must be 1..%d for a %d x %d block", C, mn, rows,
                        cols);
    btf__op op;
    int off;
    btf_result r = btf__block_start(A, rows, cols, C, center, out, &op, &off, err);
    if (r != BTF_OK)
        return r;
    int p = C - off;
    if (p == 0)
        return BTF_OK;
    float *V = malloc((size_t)cols * p * sizeof(float)), *s = malloc((size_t)p * sizeof(float));
    if (!V || !s) {
        free(V), free(s), btf_pca_block_clear(out);
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory");
    }
    if (method == BTF_PCA_AUTO)
        method = cols <= BTF__AUTO_GRAM_MAX_COLS ? BTF_PCA_GRAM : BTF_PCA_RANDOMIZED;
    if (method == BTF_PCA_GRAM)
        r = btf__top_gram(&op, p, V, s, err);
    else if (method == BTF_PCA_RANDOMIZED)
        r = btf__top_randomized(&op, p, V, s, err);
    else
        r = btf__top_svd(&op, p, V, s, err);
    if (r == BTF_OK)
        r = btf__finish(&op, p, V, out, off, err);
    free(V), free(s);
    if (r != BTF_OK)
        btf_pca_block_clear(out);
    return r;
}

/* Out again (C components, the first n found, the rest zero) as the PCA of A within
 * the orthonormal basis V (cols x (n less the mean)): the Rayleigh-Ritz step,
 * components in descending order. */
static btf_result btf__block_ritz(const float *A, int rows, int cols, int C, int n, btf_center center,
                                  const float *V, btf_pca_block *out, btf_error *err)
{
    btf__op op;
    int off, found = 0;
    btf_pca_block_clear(out);
    btf_result r = btf__block_start(A, rows, cols, C, center, out, &op, &off, err);
    if (r != BTF_OK)
        return r;
    int p = n - off;
    float *Y = malloc((size_t)rows * p * sizeof(float)), *G = malloc((size_t)p * p * sizeof(float));
    float *Q = malloc((size_t)p * p * sizeof(float)), *R = malloc((size_t)cols * p * sizeof(float));
    float *ev = malloc((size_t)p * sizeof(float)), *tmp = malloc((size_t)p * sizeof(float));
    int *supp = malloc(2 * (size_t)p * sizeof(int));
    if (!Y || !G || !Q || !R || !ev || !tmp || !supp)
        r = btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (clipped samples)");
    if (r == BTF_OK) {
        btf__op_mul(&op, V, p, Y, tmp);
        cblas_ssyrk(CblasColMajor, CblasUpper, CblasTrans, p, rows, 1.0f, Y, rows, 0.0f, G, p);
        if (LAPACKE_ssyevr(LAPACK_COL_MAJOR, 'V', 'A', 'U', p, G, p, 0.0f, 0.0f, 0, 0, 0.0f, &found, ev, Q, p,
                           supp) != 0 ||
            found != p)
            r = btf_fail(err, BTF_ERR_NUMERIC, "PCA: ssyevr failed (clipped samples)");
    }
    for (int j = 0; r == BTF_OK && j < p; j++) /* ascending -> descending */
        cblas_sgemv(CblasColMajor, CblasNoTrans, cols, p, 1.0f, V, cols, Q + (size_t)(p - 1 - j) * p, 1, 0.0f,
                    R + (size_t)j * cols, 1);
    if (r == BTF_OK)
        r = btf__finish(&op, p, R, out, off, err);
    free(Y), free(G), free(Q), free(R), free(ev), free(tmp), free(supp);
    if (r != BTF_OK)
        btf_pca_block_clear(out);
    return r;
}

/* ---------------------------------------------------------------- clipped samples */

/* A block's samples exactly at an end of the stored range (0 or 1), where a capture
 * or an import may have clipped the value; owned by btf__clip_fit for one block. */
typedef struct btf__clipped {
    size_t n;
    size_t *at;          /* n indices into A */
    unsigned char *high; /* n: 1 at the top end, 0 at the bottom */
} btf__clipped;

static void btf__clipped_free(btf__clipped *c) { free(c->at), free(c->high), memset(c, 0, sizeof *c); }

/* How many of the n floats at A are exactly 0 or 1. */
static size_t btf__count_at_ends(const float *A, size_t n)
{
    size_t count = 0;
    for (size_t i = 0; i < n; i++)
        count += A[i] == 0.0f || A[i] == 1.0f;
    return count;
}

/* The count (from btf__count_at_ends) clipped samples of A (n floats) into c. */
static btf_result btf__clipped_find(const float *A, size_t n, size_t count, btf__clipped *c, btf_error *err)
{
    memset(c, 0, sizeof *c);
    c->at = malloc(count * sizeof *c->at), c->high = malloc(count);
    if (!c->at || !c->high) {
        btf__clipped_free(c);
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (%zu clipped samples)", count);
    }
    for (size_t i = 0; i < n; i++)
        if (A[i] == 0.0f || A[i] == 1.0f)
            c->high[c->n] = A[i] == 1.0f, c->at[c->n++] = i;
    return BTF_OK;
}

/* The samples of A (n floats) the clipped fit frees, into c: none (c->n 0) when the
 * rule keeps them or fewer than BTF_PCA_CLIPPED_MIN_SHARE of them lie at an end.
 * Freed with btf__clipped_free. */
static btf_result btf__clipped_of(const float *A, size_t n, btf_clipped rule, btf__clipped *c, btf_error *err)
{
    memset(c, 0, sizeof *c);
    size_t count = rule == BTF_CLIPPED_KEEP ? 0 : btf__count_at_ends(A, n);
    if (count == 0 || (double)count < (double)n * BTF_PCA_CLIPPED_MIN_SHARE)
        return BTF_OK;
    return btf__clipped_find(A, n, count, c, err);
}

/* Moves each clipped sample to the model's value (m + Y V^T, p terms) where that lies
 * beyond its end of the range, else back onto the end. */
static void btf__clip_fill(float *A, int rows, int cols, const btf__clipped *c, const float *m, const float *Y,
                           const float *V, int p)
{
    for (size_t q = 0; q < c->n; q++) {
        size_t i = c->at[q];
        int row = (int)(i % (size_t)rows), col = (int)(i / (size_t)rows);
        float v = m ? m[row] : 0.0f;
        for (int j = 0; j < p; j++)
            v += Y[(size_t)j * rows + row] * V[(size_t)j * cols + col];
        A[i] = c->high[q] ? (v > 1.0f ? v : 1.0f) : (v < 0.0f ? v : 0.0f);
    }
}

static void btf__row_means(const float *A, int rows, int cols, const float *inv_cols, float *m)
{
    cblas_sgemv(CblasColMajor, CblasNoTrans, rows, cols, 1.0f, A, rows, inv_cols, 1, 0.0f, m, 1);
}

/* The fit's steps: each fills the clipped samples from the model and takes one
 * subspace step from the last basis. */
static btf_result btf__clip_steps(float *A, int rows, int cols, int p, int centred, const btf__clipped *c,
                                  float *V, btf_error *err)
{
    float *Y = malloc((size_t)rows * p * sizeof(float)), *m = centred ? malloc((size_t)rows * sizeof(float)) : NULL;
    float *ones = malloc((size_t)cols * sizeof(float)), *inv = malloc((size_t)cols * sizeof(float));
    float *tau = malloc((size_t)p * sizeof(float)), *tmp = malloc((size_t)p * sizeof(float));
    btf_result r = BTF_OK;
    if (!Y || (centred && !m) || !ones || !inv || !tau || !tmp)
        r = btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (clipped samples)");
    for (int i = 0; r == BTF_OK && i < cols; i++)
        ones[i] = 1.0f, inv[i] = 1.0f / (float)cols;
    btf__op op = {A, rows, cols, m};
    if (r == BTF_OK && btf__orth(V, cols, p, tau) != 0)
        r = btf_fail(err, BTF_ERR_NUMERIC, "PCA: QR factorisation failed (clipped samples)");
    if (r == BTF_OK && m)
        btf__row_means(A, rows, cols, inv, m);
    for (int s = 0; r == BTF_OK && s <= BTF__CLIP_STEPS; s++) {
        btf__op_mul(&op, V, p, Y, tmp);
        btf__clip_fill(A, rows, cols, c, m, Y, V, p);
        if (s == BTF__CLIP_STEPS)
            break;
        if (m)
            btf__row_means(A, rows, cols, inv, m);
        btf__op_mul_t(&op, Y, p, V, tmp, ones);
        if (btf__orth(V, cols, p, tau) != 0)
            r = btf_fail(err, BTF_ERR_NUMERIC, "PCA: QR factorisation failed (clipped samples)");
    }
    free(Y), free(m), free(ones), free(inv), free(tau), free(tmp);
    return r;
}

/* Fits out's first `found` components (A's PCA) again with A's clipped samples c
 * (btf__clipped_of) free to lie beyond their end of the range
 * (doc/package-format.md section 10.2), then puts them back: A is unchanged,
 * out->energy is A's. */
static btf_result btf__clip_fit(float *A, int rows, int cols, const btf_pca_options *o, int found,
                                const btf__clipped *c, btf_pca_block *out, btf_error *err)
{
    int off = o->center == BTF_CENTER_ROW, p = found - off;
    if (c->n == 0 || p < 1)
        return BTF_OK;
    float *V = malloc((size_t)cols * p * sizeof(float));
    if (!V)
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (clipped samples)");
    memcpy(V, out->w + (size_t)off * cols, (size_t)cols * p * sizeof(float));
    btf_result r = btf__clip_steps(A, rows, cols, p, off, c, V, err);
    if (r == BTF_OK)
        r = btf__block_ritz(A, rows, cols, o->components, found, o->center, V, out, err);
    free(V);
    double e = out->energy;
    for (size_t q = 0; q < c->n; q++) {
        size_t i = c->at[q];
        e -= (double)A[i] * A[i];
        A[i] = c->high[q] ? 1.0f : 0.0f;
        e += (double)A[i] * A[i];
    }
    if (r == BTF_OK)
        out->energy = e;
    return r;
}

/* ---------------------------------------------------------------- the source's rounding */

/* Per count n = 1..C of blk's components, into beyond[n - 1]: the squared misfit of
 * the clipped samples c whose model of n components lies beyond their end of the
 * range, which the clipped fit frees (btf__clip_fill), so no rank is needed for it. */
static void btf__clipped_beyond(const float *A, const btf__clipped *c, const btf_pca_block *blk, double *beyond)
{
    int C = blk->n_comp;
    memset(beyond, 0, (size_t)C * sizeof(double));
    for (size_t q = 0; q < c->n; q++) {
        size_t i = c->at[q];
        int row = (int)(i % (size_t)blk->rows), col = (int)(i / (size_t)blk->rows);
        double v = 0.0;
        for (int j = 0; j < C; j++) {
            v += (double)blk->t[(size_t)j * blk->rows + row] * blk->w[(size_t)j * blk->cols + col];
            if (c->high[q] ? v > 1.0 : v < 0.0)
                beyond[j] += (v - A[i]) * (v - A[i]);
        }
    }
}

/* The fewest of blk's components that leave at most BTF_PCA_ROUNDING_FLOOR times the
 * 8-bit rounding noise of its samples, less what the clipped fit frees (beyond, or
 * NULL); blk->n_comp when none do. What component j removes: sigma_j^2, or for the
 * row mean (centred, component 0) cols x |mean|^2: the centred columns are
 * orthogonal to it. */
static int btf__rounding_rank(const btf_pca_block *blk, btf_center center, const double *beyond)
{
    double floor = BTF_PCA_ROUNDING_FLOOR * (double)blk->rows * (double)blk->cols / (12.0 * 255.0 * 255.0);
    double left = blk->energy;
    for (int j = 0; j < blk->n_comp; j++) {
        double s = blk->sigma[j];
        if (center == BTF_CENTER_ROW && j == 0)
            s = cblas_snrm2(blk->rows, blk->t, 1), s = s * s * blk->cols;
        else
            s *= s;
        left -= s;
        if (left - (beyond ? beyond[j] : 0.0) <= floor)
            return j + 1;
    }
    return blk->n_comp;
}

/* Components n.. of blk set to zero (as a rank-deficient block's are). */
static void btf__block_cut(btf_pca_block *blk, int n)
{
    for (int j = n; j < blk->n_comp; j++) {
        memset(blk->t + (size_t)j * blk->rows, 0, (size_t)blk->rows * sizeof(float));
        memset(blk->w + (size_t)j * blk->cols, 0, (size_t)blk->cols * sizeof(float));
        blk->sigma[j] = 0.0f;
    }
}

/* With BTF_ROUNDING_CUT, blk's components past the source's rounding
 * (btf__rounding_rank, the clipped samples c of A counted as the clipped fit will see
 * them) set to zero; *found: the components left. */
static btf_result btf__rounding_cut(const float *A, const btf__clipped *c, const btf_pca_options *o,
                                    btf_pca_block *blk, int *found, btf_error *err)
{
    *found = blk->n_comp;
    if (o->rounding != BTF_ROUNDING_CUT)
        return BTF_OK;
    double *beyond = c->n ? malloc((size_t)blk->n_comp * sizeof(double)) : NULL;
    if (c->n && !beyond)
        return btf_fail(err, BTF_ERR_NOMEM, "PCA: out of memory (clipped samples)");
    if (beyond)
        btf__clipped_beyond(A, c, blk, beyond);
    btf__block_cut(blk, *found = btf__rounding_rank(blk, o->center, beyond));
    free(beyond);
    return BTF_OK;
}

int btf_pca_model_rank(const btf_pca_model *m)
{
    int most = 0;
    for (int b = 0; m && m->block && b < m->blocks->n_blocks; b++) {
        const btf_pca_block *blk = &m->block[b];
        int n = blk->n_comp;
        while (n > 0 && blk->sigma[n - 1] == 0.0f)
            n--;
        most = n > most ? n : most;
    }
    return most;
}

/* ---------------------------------------------------------------- whole BTF */

double btf_pca_clipped_share(const btf *src)
{
    if (!src || src->count == 0)
        return 0.0;
    size_t n = 0;
    if (src->storage == BTF_U8) {
        const uint8_t *d = src->data;
        for (size_t i = 0; i < src->count; i++)
            n += d[i] == 0 || d[i] == 255;
    } else {
        n = btf__count_at_ends(src->data, src->count);
    }
    return (double)n / (double)src->count;
}

void btf_pca_model_free(btf_pca_model *m)
{
    if (!m)
        return;
    if (m->block && m->blocks)
        for (int b = 0; b < m->blocks->n_blocks; b++)
            btf_pca_block_clear(&m->block[b]);
    free(m->block);
    btf_blocks_free(m->blocks);
    free(m);
}

/* Options against the sizes: k, C in range, known enums. */
static btf_result btf__check_sizes(int V, int L, long rows, const btf_pca_options *opt, btf_error *err)
{
    btf_pca_options o = btf_pca_resolve(opt);
    if (o.k < 1 || o.k > V)
        return btf_fail(err, BTF_ERR_RANGE, "k = %d views per block: must be 1..%d (the number of views)", o.k, V);
    int last = V % o.k ? V % o.k : o.k; /* smallest block */
    long cols = 3L * L * last, mn = rows < cols ? rows : cols;
    if (o.components < 1 || o.components > mn)
        return btf_fail(err, BTF_ERR_RANGE,
                        "components C = %d: must be 1..%ld (texels %ld, columns of the smallest block %ld)",
                        o.components, mn, rows, cols);
    if (o.grouping != BTF_GROUP_CONSECUTIVE && o.grouping != BTF_GROUP_SPATIAL)
        return btf_fail(err, BTF_ERR_ARG, "unknown grouping %d", (int)o.grouping);
    if (o.center != BTF_CENTER_NONE && o.center != BTF_CENTER_ROW)
        return btf_fail(err, BTF_ERR_ARG, "unknown centring %d", (int)o.center);
    if (o.rounding != BTF_ROUNDING_CUT && o.rounding != BTF_ROUNDING_KEEP)
        return btf_fail(err, BTF_ERR_ARG, "unknown rounding rule %d", (int)o.rounding);
    if (o.method < BTF_PCA_AUTO || o.method > BTF_PCA_SVD)
        return btf_fail(err, BTF_ERR_ARG, "unknown PCA method %d", (int)o.method);
    return BTF_OK;
}

btf_result btf_pca_check(const btf *src, const btf_pca_options *opt, btf_error *err)
{
    if (!src || !src->data)
        return btf_fail(err, BTF_ERR_ARG, "compress: no source BTF");
    btf_result r = btf__check_sizes(src->views.n_dirs, src->lights.n_dirs, (long)src->width * src->height, opt, err);
    return r != BTF_OK ? r : btf_check_finite(src, err);
}

btf_result btf_pca_check_views(const btf_views *src, const btf_pca_options *opt, btf_error *err)
{
    if (!src || !src->fill)
        return btf_fail(err, BTF_ERR_ARG, "compress: no source");
    return btf__check_sizes(src->views.n_dirs, src->lights.n_dirs, (long)src->width * src->height, opt, err);
}

btf_result btf_pca_compress(const btf *src, const btf_pca_options *opt, btf_pca_block_fn fn, void *ctx,
                            btf_pca_model **out, btf_error *err)
{
    *out = NULL;
    btf_result r = btf_pca_check(src, opt, err);
    if (r != BTF_OK)
        return r;
    btf_views s;
    btf_views_wrap(src, &s);
    return btf_pca_compress_views(&s, opt, fn, ctx, out, err);
}

btf_result btf_pca_compress_views(btf_views *src, const btf_pca_options *opt, btf_pca_block_fn fn, void *ctx,
                                  btf_pca_model **out, btf_error *err)
{
    if (out)
        *out = NULL;
    btf_result r = btf_pca_check_views(src, opt, err);
    if (r != BTF_OK)
        return r;
    btf_pca_options o = btf_pca_resolve(opt);
    btf_pca_model *m = calloc(1, sizeof *m);
    if (!m)
        return btf_fail(err, BTF_ERR_NOMEM, "compress: out of memory");
    m->width = src->width, m->height = src->height;
    m->lights = src->lights, m->views = src->views;
    m->k = o.k, m->n_comp = o.components, m->center = o.center, m->grouping = o.grouping, m->method = o.method;
    r = btf_blocks_group(&src->views, o.k, o.grouping, &m->blocks, err);
    if (r != BTF_OK) {
        free(m);
        return r;
    }
    m->block = calloc((size_t)m->blocks->n_blocks, sizeof *m->block);
    int rows = src->width * src->height, maxcols = 3 * src->lights.n_dirs * m->blocks->k;
    size_t nA = (size_t)rows * maxcols * sizeof(float);
    float *A = btf_big_alloc(nA);
    if (!m->block || !A) {
        btf_big_free(A, nA);
        btf_pca_model_free(m);
        return btf_fail(err, BTF_ERR_NOMEM, "compress: cannot allocate a %d x %d block matrix", rows, maxcols);
    }
    int cols = 0;
    for (int b = 0; b < m->blocks->n_blocks && r == BTF_OK; b++) {
        r = btf_pca_block_fill(src, m->blocks, b, A, err);
        cols = 3 * src->lights.n_dirs * (m->blocks->start[b + 1] - m->blocks->start[b]);
        if (r == BTF_OK)
            r = btf_pca_block_compute(A, rows, cols, o.components, o.method, o.center, &m->block[b], err);
        int found = o.components;
        btf__clipped c = {0}; /* found once: the rounding cut counts them, the fit frees them */
        if (r == BTF_OK)
            r = btf__clipped_of(A, (size_t)rows * cols, o.clipped, &c, err);
        if (r == BTF_OK)
            r = btf__rounding_cut(A, &c, &o, &m->block[b], &found, err);
        if (r == BTF_OK)
            r = btf__clip_fit(A, rows, cols, &o, found, &c, &m->block[b], err);
        btf__clipped_free(&c);
        if (r == BTF_OK && fn)
            r = fn(ctx, b, A, &m->block[b], err);
        if (r == BTF_OK && o.progress)
            o.progress(o.progress_ctx, b + 1, m->blocks->n_blocks);
        if (!out) /* only the callback wanted it */
            btf_pca_block_clear(&m->block[b]);
    }
    btf_big_free(A, nA);
    if (r != BTF_OK || !out) {
        btf_pca_model_free(m);
        return r;
    }
    *out = m;
    return BTF_OK;
}

float btf_pca_model_value(const btf_pca_model *m, int view, int light, int x, int y, int c, int n)
{
    int b = m->blocks->block_of_view[view];
    const btf_pca_block *blk = &m->block[b];
    int col = (m->blocks->pos_in_block[view] * m->lights.n_dirs + light) * 3 + c;
    size_t row = (size_t)y * m->width + x;
    if (n > blk->n_comp)
        n = blk->n_comp;
    double s = 0.0;
    for (int j = 0; j < n; j++)
        s += (double)blk->t[(size_t)j * blk->rows + row] * blk->w[(size_t)j * blk->cols + col];
    return (float)s;
}
