/* bench_vq.c - vector quantisation (VQ) of the angular weights against the package's
 * own coding (doc/performance.md section 11, "Vector quantisation of the weights").
 * Per material `btf compress SRC OUT --max-error E --quiet --no-thumbnail` (E about
 * the thesis format's error), then per component of the package:
 *
 * - the current coding: the bytes of its 16-bit weights file (wt-JJ.z, .pz or .webp,
 *   whichever the writer kept) and the squared error its quantisation adds in the
 *   texel domain, sum over blocks b of ||T_b||^2 ||W16_b - Wf_b||^2 (T_b the
 *   component's decoded texels of block b, W16 its dequantised weights, Wf the float
 *   PCA weights, recomputed from the source with the manifest's k, components and
 *   centring and checked to lie within half a step of W16);
 * - VQ of Wf, each block's sign turned so that its weights sum to >= 0 (free for a
 *   writer: T W = (-T)(-W); VQ_NO_ALIGN=1 leaves the signs): vectors of d values along
 *   one view's row of lights x RGB (d = 3: one light; d = 12: four lights, the row's
 *   last vector shorter; d = 3L: the whole row), one codebook per component, weighted
 *   Lloyd k-means (weights ||T_b||^2, k-means++ start, fixed seed) at K = 16 ... 4096
 *   (K below the vector count); bytes = the codebook as 16-bit codes over the
 *   component's range (2 K d) + the indices deflated (zlib level 9; one byte each up
 *   to K = 256, else a low and a high byte plane); error = the same texel-domain sum
 *   with the 16-bit codebook;
 * - at equal error: each component's VQ bytes interpolated at its current error (log
 *   bytes linear in error between the two K around it), summed over the components.
 *
 *   vq_MAT_package_bytes              chunk files + manifest as written
 *   vq_MAT_weights_bytes              its 16-bit weights files
 *   vq_MAT_weights_share              weights / package
 *   vq_MAT_weights_added_rmse         RMS (0..255) the weight quantisation adds
 *   vq_MAT_float_match                max |W16 - Wf| / (step / 2) (<= 1: Wf is the writer's)
 *   vq_MAT_dD_KK_bytes                VQ bytes at K = KK, all components (d = row: 3L)
 *   vq_MAT_dD_KK_error_ratio          their error / the current coding's
 *   vq_MAT_dD_bytes                   VQ bytes at each component's current error
 *   vq_MAT_dD_reached                 components whose current error some K reached (the
 *                                     others count their lowest-error K: a lower bound)
 *   vq_MAT_dD_weights_ratio           VQ bytes / current weights bytes
 *   vq_MAT_dD_entropy_weights_ratio   the same with the indices at their order-0 entropy
 *                                     in place of deflate
 *   vq_MAT_dD_indices_weights_ratio   the deflated indices alone (a codebook for free)
 *   vq_MAT_dD_package_bytes           the package with VQ weights
 *   vq_MAT_dD_package_ratio           that / the package as written
 *   vq_MAT_dD_kmeans_cpu              CPU seconds of every k-means run of this d
 *
 * Generated materials at seeds no test uses (64x64, tiles also 128x128); about 2
 * minutes on 2 cores, most of it in `btf compress`'s search. `make bench` runs it with
 * the others; alone: `make build $BUILD/bench/bench_vq`, then `bash bench/run.sh vq`
 * (writes bench/results/vq.txt; VQ_ONLY=NAME: one material). Needs $BUILD/btf (BUILD
 * default build). */
#include "bench_util.h"
#include "btf.h"
#include "btf_fs.h"
#include "btf_package.h"
#include "btf_pca.h"
#include "btf_source.h"
#include "btf_wtz.h"
#include <cblas.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#define VQ_N_K 9        /* K = 16 << 0 ... 16 << 8 = 4096 */
#define VQ_N_D 3        /* vector lengths measured */
#define VQ_MAX_ITER 40  /* Lloyd iterations at most */
#define VQ_TOL 1e-4     /* stop when an iteration lowers the error by less than this share */
#define VQ_SEED 0x5eed5eedULL

/* One material to compress: a name, the `btf compress` source and its error target;
 * entries of the static table below, for the whole run. */
typedef struct vq_case {
    const char *name, *src;
    double max_error;
} vq_case;

static const vq_case cases[] = {
    {"tiles64", "gen:tiles:64:8101", 2.2},
    {"knit64", "gen:knit:64:8102", 2.4},
    {"stone64", "gen:stone:64:8103", 1.6},
    {"tiles128", "gen:tiles:128:8104", 2.2},
};

/* Vector lengths: 0 stands for a view's whole row, 3L values. */
static const int vq_dims[VQ_N_D] = {3, 12, 0};

/* One component's weights as vectors; owned by measure_component, lives while one
 * vector length of that component is measured. */
typedef struct vq_set {
    int n, d;  /* vectors, values a vector holds at most */
    float *x;  /* n * d float PCA weights, a short vector's tail 0 */
    int *len;  /* n: the values vector i holds (d, or fewer at the end of a row) */
    double *w; /* n: ||T_b||^2 of the block of its view (the error's weight) */
} vq_set;

/* How a point's bytes are counted. */
enum { VQ_DEFLATE, VQ_ENTROPY, VQ_INDICES, VQ_N_COUNT };

/* One point of a VQ curve; plain value in measure_length's array, for one component. */
typedef struct vq_point {
    int K;
    double bytes[VQ_N_COUNT]; /* codebook + deflated indices; codebook + their order-0 entropy; indices alone */
    double err;               /* weighted squared error */
} vq_point;

/* Sums over a material's components for one vector length; plain value, run_case's,
 * for one material. */
typedef struct vq_total {
    double at[VQ_N_COUNT];    /* VQ bytes at each component's current error, each count */
    int reached;              /* components whose current error a K reached */
    double bytes[VQ_N_K], err[VQ_N_K];
    int n_at[VQ_N_K];         /* components that had this K (K below their vector count) */
    double cpu;               /* k-means CPU seconds */
} vq_total;

/* What a material's current coding holds, summed over components; plain value,
 * run_case's, for one material. */
typedef struct vq_current {
    long long weights_bytes;
    double err, match; /* texel-domain squared error; max |W16 - Wf| / (step / 2) */
} vq_current;

/* A number in [0, 1) from the state *s (a 64-bit counter and mixer), advanced. */
static double vq_uniform(uint64_t *s)
{
    *s += 0x9e3779b97f4a7c15ULL;
    uint64_t z = *s;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

/* Squared distance over the first len values; stops once it reaches bound. */
static double vq_dist(const float *x, const float *c, int len, double bound)
{
    double s = 0.0;
    for (int i = 0; i < len && s < bound; i++) {
        double e = (double)x[i] - (double)c[i];
        s += e * e;
    }
    return s;
}

/* The codeword nearest vector i; its squared distance in *dist. */
static int vq_nearest(const vq_set *s, int i, const float *cb, int K, double *dist)
{
    const float *x = s->x + (size_t)i * s->d;
    int best = 0;
    double bd = INFINITY;
    for (int k = 0; k < K; k++) {
        double e = vq_dist(x, cb + (size_t)k * s->d, s->len[i], bd);
        if (e < bd)
            bd = e, best = k;
    }
    *dist = bd;
    return best;
}

/* Index i drawn with probability p[i] / sum p. */
static int vq_draw(const double *p, int n, double total, uint64_t *rng)
{
    double r = vq_uniform(rng) * total;
    for (int i = 0; i < n; i++) {
        r -= p[i];
        if (r < 0.0)
            return i;
    }
    return n - 1;
}

/* k-means++ with the error weights: codewords into cb (K x d); returns how many were
 * placed (fewer when the vectors have fewer distinct values). */
static int vq_seed(const vq_set *s, int K, float *cb, double *d2, double *p)
{
    uint64_t rng = VQ_SEED;
    double total = 0.0;
    for (int i = 0; i < s->n; i++)
        total += s->w[i];
    int pick = vq_draw(s->w, s->n, total, &rng), placed = 0;
    for (int i = 0; i < s->n; i++)
        d2[i] = INFINITY;
    while (placed < K) {
        float *c = cb + (size_t)placed * s->d;
        memset(c, 0, (size_t)s->d * sizeof *c);
        memcpy(c, s->x + (size_t)pick * s->d, (size_t)s->len[pick] * sizeof *c);
        placed++, total = 0.0;
        for (int i = 0; i < s->n; i++) {
            double e = vq_dist(s->x + (size_t)i * s->d, c, s->len[i], d2[i]);
            d2[i] = e < d2[i] ? e : d2[i];
            p[i] = s->w[i] * d2[i], total += p[i];
        }
        if (!(total > 0.0))
            break;
        pick = vq_draw(p, s->n, total, &rng);
    }
    return placed;
}

/* Assigns every vector its nearest codeword; the weighted squared error. */
static double vq_assign(const vq_set *s, const float *cb, int K, int *idx)
{
    double e = 0.0, d;
    for (int i = 0; i < s->n; i++) {
        idx[i] = vq_nearest(s, i, cb, K, &d);
        e += s->w[i] * d;
    }
    return e;
}

/* Every codeword the weighted mean of its vectors (value by value: a short vector
 * counts for the values it holds); a codeword without vectors stays. */
static void vq_update(const vq_set *s, const int *idx, int K, float *cb, double *acc)
{
    size_t m = (size_t)K * s->d;
    memset(acc, 0, 2 * m * sizeof *acc);
    for (int i = 0; i < s->n; i++)
        for (int t = 0; t < s->len[i]; t++) {
            size_t a = (size_t)idx[i] * s->d + t;
            acc[2 * a] += s->w[i] * s->x[(size_t)i * s->d + t];
            acc[2 * a + 1] += s->w[i];
        }
    for (size_t a = 0; a < m; a++)
        if (acc[2 * a + 1] > 0.0)
            cb[a] = (float)(acc[2 * a] / acc[2 * a + 1]);
}

/* Lloyd iterations from cb until the error stops falling; idx the last assignment. */
static void vq_lloyd(const vq_set *s, int K, float *cb, int *idx, double *acc)
{
    double prev = INFINITY;
    for (int it = 0; it < VQ_MAX_ITER; it++) {
        double e = vq_assign(s, cb, K, idx);
        if (prev - e <= VQ_TOL * prev)
            return;
        prev = e;
        vq_update(s, idx, K, cb, acc);
    }
    vq_assign(s, cb, K, idx);
}

/* The codebook as the decoder sees it: 16-bit codes over the vectors' range. */
static void vq_round_codebook(const vq_set *s, int K, float *cb)
{
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < (size_t)s->n * s->d; i++)
        lo = s->x[i] < lo ? s->x[i] : lo, hi = s->x[i] > hi ? s->x[i] : hi;
    double step = hi > lo ? ((double)hi - lo) / 65535.0 : 1.0;
    for (size_t a = 0; a < (size_t)K * s->d; a++) {
        double q = floor(((double)cb[a] - lo) / step + 0.5);
        cb[a] = (float)(lo + step * (q < 0.0 ? 0.0 : q > 65535.0 ? 65535.0 : q));
    }
}

/* Bytes of the indices deflated (zlib level 9): one byte each up to K = 256, else
 * the low bytes then the high bytes; -1 on failure. */
static double vq_index_bytes(const int *idx, int n, int K)
{
    int planes = K > 256 ? 2 : 1;
    uLong raw_n = (uLong)n * planes, out_n = compressBound(raw_n);
    uint8_t *raw = malloc(raw_n), *out = malloc(out_n);
    int ok = raw && out;
    for (int i = 0; ok && i < n; i++) {
        raw[i] = (uint8_t)(idx[i] & 255);
        if (planes == 2)
            raw[n + i] = (uint8_t)(idx[i] >> 8);
    }
    ok = ok && compress2(out, &out_n, raw, raw_n, 9) == Z_OK;
    free(raw), free(out);
    return ok ? (double)out_n : -1.0;
}

/* The indices' order-0 entropy in bytes. */
static double vq_index_entropy(const int *idx, int n, int K, double *count)
{
    memset(count, 0, (size_t)K * sizeof *count);
    for (int i = 0; i < n; i++)
        count[idx[i]] += 1.0;
    double bits = 0.0;
    for (int k = 0; k < K; k++)
        if (count[k] > 0.0)
            bits -= count[k] * log2(count[k] / n);
    return bits / 8.0;
}

/* Work arrays of one k-means run; owned by vq_curve, freed at its end. */
typedef struct vq_work {
    float *cb;
    int *idx;
    double *acc, *d2, *p;
} vq_work;

/* VQ of s at K codewords: one point of its curve; -1 in its bytes on failure. */
static void vq_point_at(const vq_set *s, int K, vq_work *wk, vq_point *pt)
{
    int placed = vq_seed(s, K, wk->cb, wk->d2, wk->p);
    vq_lloyd(s, placed, wk->cb, wk->idx, wk->acc);
    vq_round_codebook(s, placed, wk->cb);
    pt->K = K;
    pt->err = vq_assign(s, wk->cb, placed, wk->idx);
    double ib = vq_index_bytes(wk->idx, s->n, placed), cb = 2.0 * placed * s->d;
    pt->bytes[VQ_DEFLATE] = ib < 0.0 ? -1.0 : cb + ib;
    pt->bytes[VQ_ENTROPY] = cb + vq_index_entropy(wk->idx, s->n, placed, wk->p);
    pt->bytes[VQ_INDICES] = ib;
}

/* The curve over K = 16 ... 4096 below the vector count: points into pt, their
 * number returned (-1 on failure); k-means CPU seconds added to *cpu. */
static int vq_curve(const vq_set *s, vq_point *pt, double *cpu)
{
    int kmax = 16 << (VQ_N_K - 1), np = 0;
    size_t big = (size_t)(s->n > kmax ? s->n : kmax);
    vq_work wk = {malloc((size_t)kmax * s->d * sizeof(float)), malloc((size_t)s->n * sizeof(int)),
                  malloc(2 * (size_t)kmax * s->d * sizeof(double)), malloc(big * sizeof(double)),
                  malloc(big * sizeof(double))};
    int ok = wk.cb && wk.idx && wk.acc && wk.d2 && wk.p;
    clock_t t0 = clock();
    for (int K = 16; ok && K <= kmax && K < s->n; K *= 2) {
        vq_point_at(s, K, &wk, &pt[np]);
        ok = pt[np++].bytes[VQ_DEFLATE] >= 0.0;
    }
    *cpu += (double)(clock() - t0) / CLOCKS_PER_SEC;
    free(wk.cb), free(wk.idx), free(wk.acc), free(wk.d2), free(wk.p);
    return ok ? np : -1;
}

/* Bytes (counted as how says) of the curve at error e: log bytes linear in error
 * between the first point at or below e and the one before it; *reached 0 when every
 * point has more error: then its lowest-error point's bytes, a lower bound. */
static double vq_at_error(const vq_point *pt, int np, double e, int how, int *reached)
{
    *reached = 1;
    for (int i = 0; i < np; i++) {
        if (pt[i].err > e)
            continue;
        double bi = pt[i].bytes[how];
        if (i == 0)
            return bi;
        double b0 = pt[i - 1].bytes[how], f = (pt[i - 1].err - e) / (pt[i - 1].err - pt[i].err);
        return exp(log(b0) + f * (log(bi) - log(b0)));
    }
    *reached = 0;
    int best = 0;
    for (int i = 1; i < np; i++)
        best = pt[i].err < pt[best].err ? i : best;
    return np ? pt[best].bytes[how] : 0.0;
}

/* Cuts the flat weights wf (V x L x 3) into vectors of d values along each view's row
 * (d 0: the whole row); the block weights tn[b(v)]. 0 on success. */
static int vq_set_make(const btf_package *p, const float *wf, const double *tn, int d, vq_set *s)
{
    int V = p->views.n_dirs, row = p->lights.n_dirs * 3;
    d = d > 0 ? d : row;
    int per = (row + d - 1) / d;
    s->n = V * per, s->d = d;
    s->x = calloc((size_t)s->n * d, sizeof *s->x);
    s->len = malloc((size_t)s->n * sizeof *s->len);
    s->w = malloc((size_t)s->n * sizeof *s->w);
    if (!s->x || !s->len || !s->w)
        return -1;
    for (int v = 0; v < V; v++)
        for (int a = 0; a < per; a++) {
            int i = v * per + a, t0 = a * d;
            s->len[i] = row - t0 < d ? row - t0 : d;
            s->w[i] = tn[p->blocks->block_of_view[v]];
            memcpy(s->x + (size_t)i * d, wf + (size_t)v * row + t0, (size_t)s->len[i] * sizeof *s->x);
        }
    return 0;
}

/* Frees what vq_set_make allocated. */
static void vq_set_clear(vq_set *s)
{
    free(s->x), free(s->len), free(s->w);
}

/* Component j's float PCA weights from model m in the package's order (V x L x 3). */
static void float_weights(const btf_package *p, const btf_pca_model *m, int j, float *wf)
{
    int L = p->lights.n_dirs;
    for (int v = 0; v < p->views.n_dirs; v++) {
        int b = m->blocks->block_of_view[v], pos = m->blocks->pos_in_block[v];
        const btf_pca_block *blk = &m->block[b];
        for (int t = 0; t < 3 * L; t++)
            wf[(size_t)v * 3 * L + t] = blk->w[(size_t)j * blk->cols + (size_t)pos * 3 * L + t];
    }
}

/* Each block's weights in wf negated where they sum below 0: a block's texture and
 * weights may both change sign at no cost (T W = (-T)(-W)), so a writer would hand one
 * codebook weights of one sign convention. */
static void align_signs(const btf_package *p, float *wf)
{
    int row = 3 * p->lights.n_dirs;
    const btf_blocks *bl = p->blocks;
    for (int b = 0; b < bl->n_blocks; b++) {
        double sum = 0.0;
        for (int i = bl->start[b]; i < bl->start[b + 1]; i++)
            for (int t = 0; t < row; t++)
                sum += wf[(size_t)bl->views[i] * row + t];
        for (int i = bl->start[b]; sum < 0.0 && i < bl->start[b + 1]; i++)
            for (int t = 0; t < row; t++)
                wf[(size_t)bl->views[i] * row + t] = -wf[(size_t)bl->views[i] * row + t];
    }
}

/* Chunk i's texel energy per block (||T_b||^2) into tn. */
static void texel_energy(const btf_package *p, int i, double *tn)
{
    size_t texels = (size_t)p->width * p->height;
    for (int b = 0; b < p->blocks->n_blocks; b++) {
        double s = 0.0;
        for (size_t r = 0; r < texels; r++)
            s += (double)p->tex[i][b * texels + r] * p->tex[i][b * texels + r];
        tn[b] = s;
    }
}

/* The current coding's texel-domain error of chunk i against wf; the largest
 * |W16 - Wf| over half its block's step into *match (kept when larger). */
static double current_error(const btf_package *p, int i, const float *wf, const double *tn, double *match)
{
    int row = 3 * p->lights.n_dirs;
    double e = 0.0;
    for (int v = 0; v < p->views.n_dirs; v++) {
        int b = p->blocks->block_of_view[v];
        double step = p->chunk[i].wt_range[2 * b + 1], ev = 0.0;
        for (int t = 0; t < row; t++) {
            double dw = (double)p->wt[i][(size_t)v * row + t] - wf[(size_t)v * row + t];
            ev += dw * dw;
            if (step > 0.0 && fabs(dw) / (0.5 * step) > *match)
                *match = fabs(dw) / (0.5 * step);
        }
        e += tn[b] * ev;
    }
    return e;
}

/* Size of chunk i's 16-bit weights file in dir; -1 when it has none. */
static long long weights_file_bytes(const btf_package *p, int i, const char *dir)
{
    for (int k = 0; k < p->chunk[i].n_files; k++)
        if (btf_wtz_kind_of(p->chunk[i].files[k]) >= 0) {
            char path[8300];
            snprintf(path, sizeof path, "%s/%s", dir, p->chunk[i].files[k]);
            return btf_fs_size(path);
        }
    return -1;
}

/* One vector length of one component into *t (its current error e). 0 on success. */
static int measure_length(const btf_package *p, const float *wf, const double *tn, int d, double e, vq_total *t)
{
    vq_set s = {0};
    vq_point pt[VQ_N_K];
    int np = vq_set_make(p, wf, tn, d, &s) == 0 ? vq_curve(&s, pt, &t->cpu) : -1, reached = 0;
    vq_set_clear(&s);
    if (np < 0)
        return -1;
    for (int a = 0; a < np; a++) {
        int slot = (int)log2(pt[a].K / 16);
        t->bytes[slot] += pt[a].bytes[VQ_DEFLATE], t->err[slot] += pt[a].err, t->n_at[slot]++;
    }
    for (int how = 0; how < VQ_N_COUNT; how++)
        t->at[how] += vq_at_error(pt, np, e, how, &reached);
    t->reached += reached;
    return 0;
}

/* Chunk i of package p (in dir) against the float model m: current coding into *cur,
 * VQ at every vector length into t. 0 on success. */
static int measure_component(const btf_package *p, const btf_pca_model *m, int i, const char *dir,
                             vq_current *cur, vq_total *t)
{
    size_t n = (size_t)p->views.n_dirs * p->lights.n_dirs * 3;
    float *wf = malloc(n * sizeof *wf);
    double *tn = malloc((size_t)p->blocks->n_blocks * sizeof *tn);
    long long wb = weights_file_bytes(p, i, dir);
    int bad = !wf || !tn || wb < 0;
    if (!bad) {
        float_weights(p, m, p->chunk[i].component, wf);
        texel_energy(p, i, tn);
        double e = current_error(p, i, wf, tn, &cur->match);
        cur->weights_bytes += wb, cur->err += e;
        if (getenv("VQ_NO_ALIGN") == NULL)
            align_signs(p, wf);
        for (int a = 0; !bad && a < VQ_N_D; a++)
            bad = measure_length(p, wf, tn, vq_dims[a], e, &t[a]) != 0;
    }
    free(wf), free(tn);
    return bad ? -1 : 0;
}

/* The float PCA the package was written from: the source with the manifest's k,
 * components, centring and grouping. */
static btf_result float_model(const char *src, const btf_package *p, btf_pca_model **m, btf_error *err)
{
    btf_source_args a = {0};
    btf_views vs;
    btf_result r = btf_source_open_views(src, &a, &vs, err);
    if (r != BTF_OK)
        return r;
    btf_pca_options po = {0};
    po.k = p->k, po.components = p->n_comp, po.center = p->center, po.grouping = p->grouping;
    r = btf_pca_compress_views(&vs, &po, NULL, NULL, m, err);
    btf_views_close(&vs);
    return r;
}

/* The lines of one vector length d of material mat (C components). */
static void print_length(const char *mat, int d, const vq_total *t, const vq_current *cur, long long pkg, int C)
{
    char dn[16];
    snprintf(dn, sizeof dn, d > 0 ? "d%d" : "drow", d);
    for (int k = 0; k < VQ_N_K; k++)
        if (t->n_at[k] == C) {
            printf("vq_%s_%s_K%d_bytes %.0f B\n", mat, dn, 16 << k, t->bytes[k]);
            printf("vq_%s_%s_K%d_error_ratio %.4f x\n", mat, dn, 16 << k, t->err[k] / cur->err);
        }
    double w = (double)cur->weights_bytes, with = (double)pkg - w + t->at[VQ_DEFLATE];
    printf("vq_%s_%s_bytes %.0f B\n", mat, dn, t->at[VQ_DEFLATE]);
    printf("vq_%s_%s_reached %d count\n", mat, dn, t->reached);
    printf("vq_%s_%s_weights_ratio %.4f x\n", mat, dn, t->at[VQ_DEFLATE] / w);
    printf("vq_%s_%s_entropy_weights_ratio %.4f x\n", mat, dn, t->at[VQ_ENTROPY] / w);
    printf("vq_%s_%s_indices_weights_ratio %.4f x\n", mat, dn, t->at[VQ_INDICES] / w);
    printf("vq_%s_%s_package_bytes %.0f B\n", mat, dn, with);
    printf("vq_%s_%s_package_ratio %.4f x\n", mat, dn, with / (double)pkg);
    printf("vq_%s_%s_kmeans_cpu %.2f s\n", mat, dn, t->cpu);
    printf("# %s %s: VQ %.0f B at the current error (%d of %d components reached it), %.3fx the weights "
           "(%.3fx with the indices at their entropy, %.3fx the indices alone), package %.3fx\n",
           mat, dn, t->at[VQ_DEFLATE], t->reached, C, t->at[VQ_DEFLATE] / w, t->at[VQ_ENTROPY] / w,
           t->at[VQ_INDICES] / w, with / (double)pkg);
}

/* The lines of one material. */
static void print_case(const vq_case *c, const btf_package *p, const vq_current *cur, const vq_total *t,
                       long long pkg)
{
    double samples = (double)p->width * p->height * p->views.n_dirs * p->lights.n_dirs * 3;
    printf("vq_%s_package_bytes %lld B\n", c->name, pkg);
    printf("vq_%s_weights_bytes %lld B\n", c->name, cur->weights_bytes);
    printf("vq_%s_weights_share %.4f x\n", c->name, (double)cur->weights_bytes / (double)pkg);
    printf("vq_%s_weights_added_rmse %.4f level\n", c->name, 255.0 * sqrt(cur->err / samples));
    printf("vq_%s_float_match %.4f x\n", c->name, cur->match);
    printf("# %s: k %d, %d chunks, package %lld B, weights %lld B (%.1f%%), their quantisation adds RMS %.4f\n",
           c->name, p->k, p->n_chunks, pkg, cur->weights_bytes, 100.0 * (double)cur->weights_bytes / (double)pkg,
           255.0 * sqrt(cur->err / samples));
    for (int a = 0; a < VQ_N_D; a++)
        print_length(c->name, vq_dims[a], &t[a], cur, pkg, p->n_chunks);
}

/* Every chunk of the package in dir measured; the package's bytes into *pkg. */
static int measure_package(const vq_case *c, const btf_package *p, const btf_pca_model *m, const char *dir,
                           long long *pkg, vq_current *cur, vq_total *t)
{
    *pkg = bench_package_bytes(dir, p);
    for (int i = 0; i < p->n_chunks; i++) {
        if (p->chunk[i].level != 0 || measure_component(p, m, i, dir, cur, t) != 0) {
            fprintf(stderr, "bench_vq: %s: chunk %d not measured\n", c->name, i);
            return -1;
        }
    }
    if (cur->match > 1.001) {
        fprintf(stderr, "bench_vq: %s: the float PCA is not the writer's (|W16 - Wf| %.3f half-steps)\n", c->name,
                cur->match);
        return -1;
    }
    return 0;
}

/* One material: compressed, read, its float PCA recomputed, measured, printed. 0 on success. */
static int run_case(const vq_case *c, const char *btf, const char *tmp)
{
    char dir[600], cmd[2000];
    snprintf(dir, sizeof dir, "%s/%s", tmp, c->name);
    snprintf(cmd, sizeof cmd, "'%s' compress '%s' '%s' --max-error %g --quiet --no-thumbnail", btf, c->src, dir,
             c->max_error);
    fprintf(stderr, "bench_vq: %s\n", cmd);
    btf_package *p = NULL;
    btf_pca_model *m = NULL;
    btf_error err = {{0}};
    if (system(cmd) != 0 || btf_package_read(dir, 0, &p, &err) != BTF_OK ||
        float_model(c->src, p, &m, &err) != BTF_OK) {
        fprintf(stderr, "bench_vq: %s: %s\n", c->name, err.msg[0] ? err.msg : "compress failed");
        btf_package_free(p);
        return -1;
    }
    vq_current cur = {0};
    vq_total t[VQ_N_D];
    memset(t, 0, sizeof t);
    long long pkg = 0;
    int bad = measure_package(c, p, m, dir, &pkg, &cur, t);
    if (!bad)
        print_case(c, p, &cur, t, pkg);
    fflush(stdout);
    btf_pca_model_free(m);
    btf_package_free(p);
    btf_fs_rmtree(dir, NULL);
    return bad;
}

int main(void)
{
    char btf[600], tmp[64];
    if (!bench_btf_and_tmp("vq", btf, tmp))
        return 1;
    openblas_set_num_threads(1); /* the PCA as `btf compress` computes it (one BLAS thread) */
    const char *only = getenv("VQ_ONLY");
    int bad = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        if (!only || !strcmp(only, cases[i].name))
            bad |= run_case(&cases[i], btf, tmp) != 0;
    btf_fs_rmtree(tmp, NULL);
    return bad;
}
