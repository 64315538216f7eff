/* btf_package_write.c - package writer: PCA per view block, quantisation, importance
 * order, error curve, files, manifest; the result replaces OUT atomically and only
 * when OUT is empty, absent or a package this project wrote. Format:
 * doc/package-format.md; manifest text: btf_manifest.c. */
#include "btf_compress.h"

#include <cblas.h>
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "btf_manifest.h"
#include "btf_metrics.h"
#include "btf_rd.h"
#include "btf_sample.h"
#include "btf_lossy.h"
#include "btf_wtz.h"
#include "btf_color.h"
#include "btf_common.h"
#include "btf_blocks.h"

#define BTF__SLAB_ROWS 512

/* ---------------------------------------------------------------- small helpers */

/* The linear-light source (btf_package_options.linear): each view of the caller's
 * source, whose impl is, put through the exact sRGB EOTF as it is read. The one
 * place a linear package's samples are converted; every path (PCA, the --rd pass,
 * the budget's candidates, levels) reads its blocks through it. */
static btf_result btf__fill_linear(btf_views *s, int view, float *cols, btf_error *err)
{
    btf_result r = btf_views_fill(s->impl, view, cols, err);
    if (r == BTF_OK)
        btf_color_srgb_decode_n(cols, btf_views_floats(s));
    return r;
}

/* out: src seen as linear light (btf__fill_linear); lives no longer than src. */
static void btf__views_linear(btf_views *src, btf_views *out)
{
    btf_views_over(src, btf__fill_linear, src, out);
}

/* ---------------------------------------------------------------- writer state */

/* State of one package compression; lives for one btf_package_compress call. */
typedef struct btf__writer {
    const btf_views *src; /* sizes and direction sets; samples arrive per block (btf__on_block) */
    const btf_blocks *blocks;
    int C, bits, qmax, ch, W, H, L, V, rows;
    float *tnoise;        /* C: RMS noise (0..255 scale) of component j's texture steps; <= 0 = full range */
    float *wnoise;        /* C: the same for its weights; <= 0 = the full 16-bit range */
    int version;          /* 1, or 3: wt-JJ.z weights (doc/package-format.md section 9.3) */
    int linear;           /* 1: samples are linear light; the Lab curve encodes them to sRGB first */
    char *rd_json;        /* version 3: the manifest's "rd" record (malloc'd), NULL otherwise */
    int acols, arows, aw, ah;
    uint8_t **atlas;      /* C atlases aw*ah*ch */
    const char **tex_ext; /* C: ".png", ".webp" or ".avif", the extension of component j's texture file once written */
    const char **wt_ext;  /* C: ".bin" (version 1), ".z", ".pz" or ".webp" (version 3), its weights file's, once written */
    int *prev_view;       /* V: each view's predecessor in its block (btf_wtz_prev_views), for wt-JJ.pz */
    int wt_webp;          /* version 3: 1 = wt-JJ.webp may be kept (not png_only: no WebP file at all) */
    int codec;            /* the lossy textures' encoding (btf_package_options.lossy, btf_lossy.h) */
    int *quality;         /* C: -1, or the lossy level of component j's texture (version 3, btf_rd_result) */
    uint8_t **lossy;      /* C: component j's lossy WebP or AVIF file (malloc'd, lossy_n[j] bytes; its atlas
                           * holds its decode), NULL for a lossless texture */
    size_t *lossy_n;
    uint8_t **wlossy;     /* C: component j's lossy weights file (malloc'd, wlossy_n[j] bytes; qwt[j] holds its
                           * decode, wt_range[j] its ranges), NULL for weights on steps */
    size_t *wlossy_n;
    const btf_package_channel *chan; /* the caller's channel (btf_compress.h), all zero when none */
    long long *est_bytes; /* C, with btf_package_channel.estimate: component j's estimated file bytes; else NULL */
    uint16_t **qwt;       /* C arrays V*L*3 */
    float **tex_range;    /* C arrays n_blocks*2 */
    float **wt_range;     /* C arrays n_blocks*2 */
    double E;             /* |A|^2 summed over blocks */
    double *Pq, *Pf;      /* C: t_j . (A w_j), quantised / float */
    double *Qq, *Qf;      /* C*C: (t_i.t_j)(w_i.w_j) */
    double *Tqd, *Tfd;    /* rows x C scratch */
    double *Wd;           /* maxcols x 2C scratch: [Wq | Wf] */
    double *Ad, *D;       /* slab scratch, slab rows each */
    int slab;             /* rows of a slab: BTF__SLAB_ROWS, or every row of a smaller material */
    double *TT, *WW;      /* C*C scratch */
    int stride, sub_w, sub_h; /* Lab subsample: every stride-th texel, sub_w x sub_h of them */
    float *ref;           /* sub_w*sub_h x V x L x 3: the source at the subsample, kept from each block */
} btf__writer;

static void btf__writer_free(btf__writer *w)
{
    for (int j = 0; j < w->C; j++) {
        if (w->atlas)
            free(w->atlas[j]);
        if (w->qwt)
            free(w->qwt[j]);
        if (w->tex_range)
            free(w->tex_range[j]);
        if (w->wt_range)
            free(w->wt_range[j]);
    }
    free(w->atlas), free(w->qwt), free(w->tex_range), free(w->wt_range), free(w->tnoise), free(w->wnoise), free(w->rd_json);
    for (int j = 0; w->lossy && j < w->C; j++)
        free(w->lossy[j]);
    for (int j = 0; w->wlossy && j < w->C; j++)
        free(w->wlossy[j]);
    free(w->wlossy), free(w->wlossy_n);
    free(w->tex_ext), free(w->wt_ext), free(w->prev_view), free(w->est_bytes), free(w->quality), free(w->lossy), free(w->lossy_n);
    free(w->Pq), free(w->Pf), free(w->Qq), free(w->Qf);
    free(w->Tqd), free(w->Tfd), free(w->Wd), free(w->Ad), free(w->D), free(w->TT), free(w->WW);
    free(w->ref);
}


static btf_result btf__writer_init(btf__writer *w, const btf_views *src, const btf_blocks *bl, int C, int bits,
                                   int stride, btf_error *err)
{
    memset(w, 0, sizeof *w);
    w->src = src, w->blocks = bl, w->C = C, w->bits = bits;
    w->qmax = bits == 16 ? 65535 : 255;
    w->ch = bits == 16 ? 3 : 1;
    w->W = src->width, w->H = src->height, w->L = src->lights.n_dirs, w->V = src->views.n_dirs;
    w->rows = w->W * w->H;
    w->acols = (int)ceil(sqrt((double)bl->n_blocks));
    w->arows = (bl->n_blocks + w->acols - 1) / w->acols;
    w->aw = w->acols * w->W, w->ah = w->arows * w->H;
    if (w->aw > BTF_MAX_SIDE * 2 || w->ah > BTF_MAX_SIDE * 2)
        return btf_fail(err, BTF_ERR_RANGE, "package: texture atlas %d x %d is too large", w->aw, w->ah);
    int maxcols = 3 * w->L * bl->k;
    size_t C2 = (size_t)C * C;
    w->atlas = calloc((size_t)C, sizeof *w->atlas);
    w->qwt = calloc((size_t)C, sizeof *w->qwt);
    w->tex_range = calloc((size_t)C, sizeof *w->tex_range);
    w->wt_range = calloc((size_t)C, sizeof *w->wt_range);
    w->tnoise = calloc((size_t)C, sizeof(float)), w->wnoise = calloc((size_t)C, sizeof(float));
    w->tex_ext = calloc((size_t)C, sizeof *w->tex_ext);
    w->wt_ext = calloc((size_t)C, sizeof *w->wt_ext);
    w->prev_view = malloc((size_t)w->V * sizeof *w->prev_view);
    w->quality = malloc((size_t)C * sizeof(int));
    w->lossy = calloc((size_t)C, sizeof *w->lossy), w->lossy_n = calloc((size_t)C, sizeof(size_t));
    w->wlossy = calloc((size_t)C, sizeof *w->wlossy), w->wlossy_n = calloc((size_t)C, sizeof(size_t));
    for (int j = 0; w->quality && j < C; j++)
        w->quality[j] = -1;
    w->Pq = calloc((size_t)C, sizeof(double)), w->Pf = calloc((size_t)C, sizeof(double));
    w->Qq = calloc(C2, sizeof(double)), w->Qf = calloc(C2, sizeof(double));
    w->TT = calloc(C2, sizeof(double)), w->WW = calloc(C2, sizeof(double));
    w->Tqd = malloc((size_t)w->rows * C * sizeof(double));
    w->Tfd = malloc((size_t)w->rows * C * sizeof(double));
    w->Wd = malloc((size_t)maxcols * 2 * C * sizeof(double));
    w->slab = w->rows < BTF__SLAB_ROWS ? w->rows : BTF__SLAB_ROWS;
    w->Ad = btf_big_alloc((size_t)w->slab * maxcols * sizeof(double));
    w->D = malloc((size_t)w->slab * 2 * C * sizeof(double));
    w->stride = stride;
    w->sub_w = (w->W + stride - 1) / stride, w->sub_h = (w->H + stride - 1) / stride;
    w->ref = btf_big_alloc((size_t)w->sub_w * w->sub_h * w->V * w->L * 3 * sizeof(float));
    int ok = w->ref && w->tnoise && w->tex_ext && w->wt_ext && w->prev_view && w->quality && w->lossy && w->lossy_n && w->wlossy && w->wlossy_n && w->wnoise && w->atlas && w->qwt && w->tex_range && w->wt_range && w->Pq && w->Pf &&
             w->Qq && w->Qf && w->TT &&
             w->WW && w->Tqd && w->Tfd && w->Wd && w->Ad && w->D;
    for (int j = 0; ok && j < C; j++) {
        w->atlas[j] = calloc((size_t)w->aw * w->ah * w->ch, 1);
        w->qwt[j] = calloc((size_t)w->V * w->L * 3, sizeof(uint16_t));
        w->tex_range[j] = calloc((size_t)bl->n_blocks * 2, sizeof(float));
        w->wt_range[j] = calloc((size_t)bl->n_blocks * 2, sizeof(float));
        ok = w->atlas[j] && w->qwt[j] && w->tex_range[j] && w->wt_range[j];
    }
    if (ok)
        btf_wtz_prev_views(bl->block_of_view, w->V, w->prev_view);
    return ok ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (%d components)", C);
}


/* Quantises block b's textures into the atlases (a lossy component's codes are its
 * atlas's, the decode of its file, already there); dequantised copies into Tqd, floats
 * into Tfd. */
static void btf__quant_textures(btf__writer *w, int b, const btf_pca_block *res)
{
    int tx0 = (b % w->acols) * w->W, ty0 = (b / w->acols) * w->H;
    for (int j = 0; j < w->C; j++) {
        const float *t = res->t + (size_t)j * w->rows;
        float *rg = w->tex_range[j] + 2 * b;
        btf_rd_range(t, (size_t)w->rows, (unsigned)w->qmax, rg);
        float wn = cblas_snrm2(res->cols, res->w + (size_t)j * res->cols, 1);
        rg[1] = btf_rd_step(rg[1], w->tnoise[j], res->cols, wn); /* RMS noise tnoise[j] from this component */
        for (int y = 0; y < w->H; y++)
            for (int x = 0; x < w->W; x++) {
                size_t r = (size_t)y * w->W + x;
                unsigned q = btf_rd_quant(t[r], rg, (unsigned)w->qmax);
                uint8_t *px = w->atlas[j] + ((size_t)(ty0 + y) * w->aw + (size_t)(tx0 + x)) * w->ch;
                if (w->lossy[j]) {
                    q = px[0];
                } else if (w->bits == 16) {
                    px[0] = (uint8_t)(q >> 8);
                    px[1] = (uint8_t)(q & 255u);
                } else {
                    px[0] = (uint8_t)q;
                }
                w->Tqd[(size_t)j * w->rows + r] = btf_package_dequant(rg, q);
                w->Tfd[(size_t)j * w->rows + r] = t[r];
            }
    }
}


/* Quantises block b's weights (16 bits, steps for wnoise) into qwt (a lossy
 * component's codes are the decode of its file, already there); [Wq | Wf] into Wd. */
static void btf__quant_weights(btf__writer *w, int b, const btf_pca_block *res)
{
    const btf_blocks *bl = w->blocks;
    int cols = res->cols;
    for (int j = 0; j < w->C; j++) {
        const float *wj = res->w + (size_t)j * cols;
        float *rg = w->wt_range[j] + 2 * b;
        int lossy = w->wlossy[j] != NULL;
        if (!lossy)
            btf_rd_range(wj, (size_t)cols, 65535u, rg);
        if (!lossy && w->wnoise[j] > 0.0f)
            rg[1] = btf_rd_step(rg[1], w->wnoise[j], w->rows, cblas_snrm2(w->rows, res->t + (size_t)j * w->rows, 1));
        for (int col = 0; col < cols; col++) {
            int pos = col / (3 * w->L), l = (col / 3) % w->L, c = col % 3;
            int v = bl->views[bl->start[b] + pos];
            size_t i = ((size_t)v * w->L + l) * 3 + c;
            unsigned q = lossy ? w->qwt[j][i] : btf_rd_quant(wj[col], rg, 65535u);
            w->qwt[j][i] = (uint16_t)q;
            w->Wd[(size_t)j * cols + col] = btf_package_dequant(rg, q);
            w->Wd[(size_t)(w->C + j) * cols + col] = wj[col];
        }
    }
}


/* Q[i][j] += (T^T T)_ij (W^T W)_ij for one set (quantised or float). */
static void btf__accum_q(btf__writer *w, const double *T, const double *Wm, int cols, double *Q)
{
    int C = w->C;
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, C, C, w->rows, 1.0, T, w->rows, T, w->rows, 0.0, w->TT, C);
    cblas_dgemm(CblasColMajor, CblasTrans, CblasNoTrans, C, C, cols, 1.0, Wm, cols, Wm, cols, 0.0, w->WW, C);
    for (int i = 0; i < C * C; i++)
        Q[i] += w->TT[i] * w->WW[i];
}


/* P_j += t_j . (A w_j) in double, A in row slabs. */
static void btf__accum_p(btf__writer *w, const float *A, int cols)
{
    int C = w->C;
    for (int r0 = 0; r0 < w->rows; r0 += w->slab) {
        int nr = w->rows - r0 < w->slab ? w->rows - r0 : w->slab;
        for (int c = 0; c < cols; c++)
            for (int r = 0; r < nr; r++)
                w->Ad[(size_t)c * nr + r] = A[(size_t)c * w->rows + r0 + r];
        cblas_dgemm(CblasColMajor, CblasNoTrans, CblasNoTrans, nr, 2 * C, cols, 1.0, w->Ad, nr, w->Wd, cols, 0.0,
                    w->D, nr);
        for (int j = 0; j < C; j++) {
            w->Pq[j] += cblas_ddot(nr, w->Tqd + (size_t)j * w->rows + r0, 1, w->D + (size_t)j * nr, 1);
            w->Pf[j] += cblas_ddot(nr, w->Tfd + (size_t)j * w->rows + r0, 1, w->D + (size_t)(C + j) * nr, 1);
        }
    }
}


/* The texel (*x, *y) of the Lab subsample's cell (sx, sy) of w (btf_sample.h). */
static void btf__lab_texel(const btf__writer *w, int sx, int sy, int *x, int *y)
{
    btf_sample_texel(w->stride, w->W, w->H, sx, sy, x, y);
}

/* Keeps block b's samples at the Lab subsample (A's columns: view, light, channel). */
static void btf__keep_ref(btf__writer *w, int b, const float *A)
{
    const btf_blocks *bl = w->blocks;
    size_t rows = (size_t)w->rows, per = (size_t)w->V * w->L * 3;
    for (int i = bl->start[b]; i < bl->start[b + 1]; i++) {
        int v = bl->views[i], pos = i - bl->start[b];
        for (int sy = 0; sy < w->sub_h; sy++)
            for (int sx = 0; sx < w->sub_w; sx++) {
                int x, y;
                btf__lab_texel(w, sx, sy, &x, &y);
                size_t row = (size_t)y * w->W + (size_t)x;
                float *dst = w->ref + ((size_t)sy * w->sub_w + sx) * per + (size_t)v * w->L * 3;
                for (int l = 0; l < w->L; l++)
                    for (int c = 0; c < 3; c++)
                        dst[l * 3 + c] = A[(size_t)((pos * w->L + l) * 3 + c) * rows + row];
            }
    }
}

static btf_result btf__on_block(void *ctx, int b, const float *A, const btf_pca_block *res, btf_error *err)
{
    btf__writer *w = ctx;
    (void)err;
    btf__keep_ref(w, b, A);
    btf__quant_textures(w, b, res);
    btf__quant_weights(w, b, res);
    btf__accum_p(w, A, res->cols);
    btf__accum_q(w, w->Tqd, w->Wd, res->cols, w->Qq);
    btf__accum_q(w, w->Tfd, w->Wd + (size_t)w->C * res->cols, res->cols, w->Qf);
    w->E += res->energy;
    return BTF_OK;
}


/* Squared error of chunk set given by the first n entries of order. */
static double btf__sq_error(const btf__writer *w, const int *order, int n, int quant)
{
    const double *P = quant ? w->Pq : w->Pf, *Q = quant ? w->Qq : w->Qf;
    double e = w->E;
    for (int a = 0; a < n; a++) {
        e -= 2.0 * P[order[a]];
        for (int b = 0; b < n; b++)
            e += Q[(size_t)order[a] * w->C + order[b]];
    }
    return e > 0.0 ? e : 0.0;
}


/* Greedy importance order: component 0 first, then most error reduction per byte. */
static void btf__order(const btf__writer *w, const long long *bytes, int *order)
{
    int C = w->C;
    char *used = calloc((size_t)C, 1);
    order[0] = 0;
    if (used)
        used[0] = 1;
    for (int n = 1; n < C; n++) {
        double cur = btf__sq_error(w, order, n, 1), best = -INFINITY;
        int pick = -1;
        for (int j = 0; j < C; j++) {
            if (used ? used[j] : j < n)
                continue;
            order[n] = j;
            double gain = cur - btf__sq_error(w, order, n + 1, 1);
            double score = gain / (double)(bytes[j] > 0 ? bytes[j] : 1);
            if (pick < 0 || score > best) {
                best = score;
                pick = j;
            }
        }
        order[n] = pick;
        if (used)
            used[pick] = 1;
    }
    free(used);
}


/* Lab (and Delta E) of every prefix on the texel subsample; rgb errors exact elsewhere.
 * The prefixes' sums are shared out among OpenMP's threads above
 * BTF_METRICS_THREAD_MIN_PIXELS pixel pairs; each keeps its texel order, so the
 * curve does not depend on the thread count. */
static btf_result btf__lab_curve(const btf__writer *w, const int *order, btf_metrics *out, btf_error *err)
{
    int C = w->C, V = w->V, L = w->L;
    size_t np = (size_t)V * L;
    float *ref = malloc(np * 3 * sizeof(float)), *test = malloc((size_t)C * np * 3 * sizeof(float));
    float *tv = malloc((size_t)C * sizeof(float)), *ref_lab = malloc(np * 3 * sizeof(float));
    btf_metrics_acc *acc = calloc((size_t)C, sizeof *acc);
    if (!ref || !test || !tv || !acc || !ref_lab) {
        free(ref), free(test), free(tv), free(acc), free(ref_lab);
        return btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (error curve)");
    }
    const float *refs = w->ref;
    int threaded = (size_t)C * np * (size_t)w->sub_w * (size_t)w->sub_h >= BTF_METRICS_THREAD_MIN_PIXELS;
    for (int sy = 0; sy < w->sub_h; sy++)
        for (int sx = 0; sx < w->sub_w; sx++, refs += np * 3) {
            int x, y;
            btf__lab_texel(w, sx, sy, &x, &y);
            for (int v = 0; v < V; v++) {
                int b = w->blocks->block_of_view[v];
                size_t px = ((size_t)((b / w->acols) * w->H + y) * w->aw + (size_t)((b % w->acols) * w->W + x)) * w->ch;
                for (int a = 0; a < C; a++) {
                    int j = order[a];
                    const uint8_t *p = w->atlas[j] + px;
                    unsigned q = w->bits == 16 ? (unsigned)p[0] * 256u + p[1] : p[0];
                    tv[a] = btf_package_dequant(w->tex_range[j] + 2 * b, q);
                }
                for (int l = 0; l < L; l++)
                    for (int c = 0; c < 3; c++) {
                        size_t i = ((size_t)v * L + l) * 3 + c;
                        ref[i] = refs[i];
                        float s = 0.0f;
                        for (int a = 0; a < C; a++) {
                            int j = order[a];
                            s += tv[a] * btf_package_dequant(w->wt_range[j] + 2 * b, w->qwt[j][i]);
                            test[(size_t)a * np * 3 + i] = s;
                        }
                    }
            }
            if (w->linear) /* Lab on the source's scale, as for an sRGB package */
                btf_color_srgb_encode_n(ref, np * 3), btf_color_srgb_encode_n(test, (size_t)C * np * 3);
            btf_metrics_lab(ref, np, ref_lab); /* once for the C prefixes */
            /* one prefix per thread: each sum keeps one writer and its texel order */
#pragma omp parallel for schedule(static) if (threaded)
            for (int a = 0; a < C; a++)
                btf_metrics_add_lab(&acc[a], ref, ref_lab, test + (size_t)a * np * 3, np);
        }
    for (int a = 0; a < C; a++)
        btf_metrics_finish(&acc[a], &out[a]);
    free(ref), free(test), free(tv), free(acc), free(ref_lab);
    return BTF_OK;
}


/* The test hook for file number i (texture j = 2j, its weights 2j + 1, the manifest 2C). */
static btf_result btf__hook(const btf__writer *w, int i, const char *file, btf_error *err)
{
    const btf_package_channel *c = w->chan;
    if (c->write_hook && c->write_hook(c->hook_ctx, i, file))
        return btf_fail(err, BTF_ERR_IO, "%s: write failed (no space left on device, simulated)", file);
    return BTF_OK;
}




/* File `file` of the package: to the channel's sink, or into tmp atomically. */
static btf_result btf__put(const btf__writer *w, const char *tmp, const char *file, const void *data, size_t n,
                           btf_error *err)
{
    const btf_package_channel *c = w->chan;
    btf_result r;
    if (c->sink) {
#pragma omp critical(btf__sink)
        r = c->sink(c->sink_user, file, data, n, err);
        return r;
    }
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", tmp, file);
    return btf_fs_write_atomic(path, data, n, err);
}

/* Version 3's weights of component j: its lossy wt-JJ.webp, else the smallest of
 * wt-JJ.z, wt-JJ.pz and (unless png_only) wt-JJ.webp (btf_wtz_encode_smaller), into
 * *z (malloc'd, *nz bytes), its extension into w->wt_ext[j]. */
static btf_result btf__encode_weights(btf__writer *w, int j, uint8_t **z, size_t *nz, btf_error *err)
{
    if (w->wlossy[j]) { /* the lossy file its codes are the decode of */
        w->wt_ext[j] = ".webp";
        *z = malloc(w->wlossy_n[j]), *nz = w->wlossy_n[j];
        if (*z)
            memcpy(*z, w->wlossy[j], *nz);
        return *z ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "wt-%02d.webp: out of memory", j);
    }
    int kind = BTF_WTZ_Z;
    btf_result r = btf_wtz_encode_smaller(w->qwt[j], w->V, w->L, w->prev_view, w->wt_webp, z, nz, &kind, err);
    w->wt_ext[j] = btf_wtz_ext(kind);
    return r;
}

/* Component j's 16-bit weights as tmp/wt-JJ.bin (version 1) or the smallest of
 * wt-JJ.z, wt-JJ.pz and wt-JJ.webp (version 3); *bytes: its size. */
static btf_result btf__write_weights(btf__writer *w, const char *tmp, int j, long long *bytes, btf_error *err)
{
    size_t n = (size_t)w->V * w->L * 3;
    const uint16_t *q = w->qwt[j];
    uint8_t *buf = NULL;
    size_t nb = 2 * n;
    btf_result r = BTF_OK;
    if (w->version == 3)
        r = btf__encode_weights(w, j, &buf, &nb, err);
    else if ((buf = malloc(2 * n)) != NULL) {
        w->wt_ext[j] = ".bin";
        for (size_t i = 0; i < n; i++)
            buf[2 * i] = (uint8_t)(q[i] & 255u), buf[2 * i + 1] = (uint8_t)(q[i] >> 8);
    } else
        r = btf_fail(err, BTF_ERR_NOMEM, "wt-%02d.bin: out of memory", j);
    char file[BTF_PACKAGE_NAME_MAX];
    snprintf(file, sizeof file, "wt-%02d%s", j, w->wt_ext[j] ? w->wt_ext[j] : ".bin");
    if (r == BTF_OK)
        r = btf__hook(w, 2 * j + 1, file, err);
    if (r == BTF_OK)
        r = btf__put(w, tmp, file, buf, nb, err);
    free(buf);
    *bytes = r == BTF_OK ? (long long)nb : -1;
    return r;
}


/* Version-1 (or 3) manifest text of what w wrote (malloc'd; NULL when out of memory):
 * the chunk list in importance order, serialized by btf_manifest_print. */
static char *btf__manifest(const btf__writer *w, const btf_pca_options *po, const char *name, int stride,
                           const int *order, const long long *bytes, const btf_metrics *lab, const double *rmse,
                           const double *rmse_float, btf_error *err)
{
    btf_package p;
    memset(&p, 0, sizeof p);
    snprintf(p.name, sizeof p.name, "%s", name);
    p.width = w->W, p.height = w->H, p.lights = w->src->lights, p.views = w->src->views;
    p.blocks = (btf_blocks *)w->blocks; /* borrowed: not freed here */
    p.k = po->k, p.n_comp = w->C, p.bits = w->bits, p.center = po->center, p.grouping = po->grouping;
    p.atlas_cols = w->acols, p.atlas_rows = w->arows, p.lab_stride = stride;
    p.version = w->version, p.n_levels = 1, p.n_chunks = w->C, p.linear = w->linear;
    p.rd = w->rd_json; /* borrowed */
    p.chunk = calloc((size_t)w->C, sizeof *p.chunk);
    if (!p.chunk) {
        btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (manifest)");
        return NULL;
    }
    for (int a = 0; a < w->C; a++) {
        btf_chunk_info *c = &p.chunk[a];
        int j = order[a];
        c->component = j, c->n_files = 2, c->bytes = bytes[j];
        snprintf(c->files[0], BTF_PACKAGE_NAME_MAX, "tex-%02d%s", j, w->tex_ext[j]);
        snprintf(c->files[1], BTF_PACKAGE_NAME_MAX, "wt-%02d%s", j, w->wt_ext[j]);
        c->rmse = rmse[a], c->lab = lab[a].lab_thesis, c->delta_e76 = lab[a].delta_e76, c->rmse_float = rmse_float[a];
        c->psnr = rmse[a] > 0 ? 20.0 * log10(255.0 / rmse[a]) : 999.0;
        c->tex_range = w->tex_range[j], c->wt_range = w->wt_range[j]; /* borrowed */
    }
    char *s = btf_manifest_print(&p, err);
    free(p.chunk);
    return s;
}

/* The extension of component j's texture file: its lossy encoding's when it is lossy,
 * a lossless WebP's for version 3 (8 bits) unless o->png_only, else ".png". */
static const char *btf__tex_ext(const btf__writer *w, const btf_package_options *o, int j)
{
    if (w->lossy[j])
        return btf_lossy_ext(w->codec);
    return w->version == 3 && w->ch == 1 && !o->png_only ? ".webp" : ".png";
}

/* Component j's atlas as tmp/tex-JJ.png, or for version 3 (8 bits) as a lossless
 * tmp/tex-JJ.webp unless o->png_only: the smaller of the two on nearly every atlas,
 * as the allocation's ladder assumes (doc/package-format.md section 11.4 has the
 * numbers); *bytes its size. */
static btf_result btf__write_texture(btf__writer *w, const btf_package_options *o, const char *tmp, int j,
                                     long long *bytes, btf_error *err)
{
    char file[BTF_PACKAGE_NAME_MAX];
    w->tex_ext[j] = btf__tex_ext(w, o, j);
    snprintf(file, sizeof file, "tex-%02d%s", j, w->tex_ext[j]);
    uint8_t *enc = NULL;
    size_t n = w->lossy[j] ? w->lossy_n[j] : 0;
    btf_result r = w->lossy[j] ? BTF_OK
                               : btf_image_encode(file, w->aw, w->ah, w->ch, 8, w->atlas[j], BTF_IMAGE_PNG_SMALLEST,
                                                  &enc, &n, err);
    if (r == BTF_OK)
        r = btf__put(w, tmp, file, w->lossy[j] ? w->lossy[j] : enc, n, err);
    free(enc);
    *bytes = r == BTF_OK ? (long long)n : -1;
    return r;
}

/* Writes component j's texture and weights into tmp; *bytes = their sizes. */
static btf_result btf__write_component(btf__writer *w, const btf_package_options *o, const char *tmp, int j,
                                       long long *bytes, btf_error *err)
{
    char file[BTF_PACKAGE_NAME_MAX];
    snprintf(file, sizeof file, "tex-%02d.png", j);
    btf_result r = btf__hook(w, 2 * j, file, err);
    long long s1 = -1, s2 = -1;
    if (r == BTF_OK)
        r = btf__write_texture(w, o, tmp, j, &s1, err);
    if (r == BTF_OK)
        r = btf__write_weights(w, tmp, j, &s2, err);
    *bytes = s1 + s2;
    return r;
}


/* Every component's files, one thread per component at a time (the encoders are
 * single-threaded) above BTF_RD_THREAD_MIN_BYTES of atlases; the first failing
 * component's error is reported. */
static btf_result btf__write_components(btf__writer *w, const btf_package_options *o, const char *tmp,
                                        long long *bytes, btf_error *err)
{
    int C = w->C;
    btf_result *rj = calloc((size_t)C, sizeof *rj);
    btf_error *ej = calloc((size_t)C, sizeof *ej);
    if (!rj || !ej) {
        free(rj), free(ej);
        return btf_fail(err, BTF_ERR_NOMEM, "package: out of memory");
    }
    size_t atlas_bytes = (size_t)C * (size_t)w->aw * (size_t)w->ah * (size_t)w->ch;
#pragma omp parallel for schedule(dynamic, 1) if (atlas_bytes >= BTF_RD_THREAD_MIN_BYTES)
    for (int j = 0; j < C; j++)
        rj[j] = btf__write_component(w, o, tmp, j, &bytes[j], &ej[j]);
    btf_result r = BTF_OK;
    for (int j = 0; j < C && r == BTF_OK; j++)
        if ((r = rj[j]) != BTF_OK && err)
            *err = ej[j];
    free(rj), free(ej);
    return r;
}

/* Writes every file into tmp (or the channel's sink), chooses the order and writes the manifest. */
static btf_result btf__write_all(btf__writer *w, const btf_pca_options *po, const btf_package_options *o,
                                 const char *name, const char *tmp, btf_compress_stats *st, btf_error *err)
{
    int C = w->C;
    long long *bytes = calloc((size_t)C, sizeof *bytes);
    int *order = calloc((size_t)C, sizeof *order);
    double *rmse = calloc((size_t)C, sizeof(double)), *rmsef = calloc((size_t)C, sizeof(double));
    btf_metrics *lab = calloc((size_t)C, sizeof *lab);
    btf_result r = BTF_OK;
    if (!bytes || !order || !rmse || !rmsef || !lab) {
        r = btf_fail(err, BTF_ERR_NOMEM, "package: out of memory");
        goto done;
    }
    if (w->chan->estimate) /* nothing written: the allocation's estimates (version 3 only), the files named as written */
        for (int j = 0; r == BTF_OK && j < C; j++) {
            uint8_t *z = NULL;
            size_t nz = 0;
            bytes[j] = w->est_bytes[j], w->tex_ext[j] = btf__tex_ext(w, o, j);
            r = btf__encode_weights(w, j, &z, &nz, err);
            free(z);
        }
    else
        r = btf__write_components(w, o, tmp, bytes, err);
    if (r != BTF_OK)
        goto done;
    btf__order(w, bytes, order);
    double n_samples = (double)w->rows * w->V * w->L * 3.0;
    for (int a = 0; a < C; a++) {
        rmse[a] = 255.0 * sqrt(btf__sq_error(w, order, a + 1, 1) / n_samples);
        rmsef[a] = 255.0 * sqrt(btf__sq_error(w, order, a + 1, 0) / n_samples);
    }
    int stride = w->stride;
    r = btf__lab_curve(w, order, lab, err);
    if (r != BTF_OK)
        goto done;
    char *text = btf__manifest(w, po, name, stride, order, bytes, lab, rmse, rmsef, err);
    if (!text) {
        r = BTF_ERR_NOMEM;
        goto done;
    }
    if (w->chan->estimate) {
        *w->chan->estimate = text; /* the caller's now */
        text = NULL;
    } else {
        r = btf__hook(w, 2 * C, "manifest.json", err);
        if (r == BTF_OK)
            r = btf__put(w, tmp, "manifest.json", text, strlen(text), err);
    }
    free(text);
    if (r == BTF_OK && st) {
        st->n_chunks = C;
        st->bytes = 0;
        for (int j = 0; j < C; j++)
            st->bytes += bytes[j];
        st->rmse = rmse[C - 1], st->rmse_float = rmsef[C - 1], st->lab = lab[C - 1].lab_thesis;
    }
done:
    free(bytes), free(order), free(rmse), free(rmsef), free(lab);
    return r;
}


/* The manifest's "rd" record (doc/package-format.md section 10.8), malloc'd; NULL when out of memory. */
static char *btf__rd_json(const btf_rd_result *rr, int codec)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "lambda", rr->lambda);
    cJSON_AddNumberToObject(o, "bytes_equal_noise", (double)rr->bytes_equal);
    cJSON_AddNumberToObject(o, "bytes", (double)rr->bytes_rd);
    cJSON_AddNumberToObject(o, "kept", rr->n_kept);
    cJSON *t = cJSON_AddArrayToObject(o, "tex_noise"), *wn = cJSON_AddArrayToObject(o, "wt_noise");
    int lossy = 0, wlossy = 0;
    for (int j = 0; j < rr->n_comp; j++) {
        cJSON_AddItemToArray(t, cJSON_CreateNumber(rr->tex_noise[j]));
        cJSON_AddItemToArray(wn, cJSON_CreateNumber(rr->wt_noise[j]));
        lossy |= rr->tex_quality[j] >= 0, wlossy |= rr->wt_quality[j] >= 0;
    }
    cJSON *wq = wlossy ? cJSON_AddArrayToObject(o, "wt_quality") : NULL;
    for (int j = 0; wq && j < rr->n_comp; j++)
        cJSON_AddItemToArray(wq, cJSON_CreateNumber(rr->wt_quality[j]));
    cJSON *q = lossy ? cJSON_AddArrayToObject(o, "tex_quality") : NULL;
    for (int j = 0; q && j < rr->n_comp; j++)
        cJSON_AddItemToArray(q, cJSON_CreateNumber(rr->tex_quality[j]));
    if (q && codec == BTF_LOSSY_AVIF) /* WebP qualities have no name: older readers know only them */
        cJSON_AddStringToObject(o, "tex_codec", btf_lossy_name(codec));
    char *s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}


/* 1 when m (may be NULL) is the model po makes of a source of src's sizes. */
static int btf__model_fits(const btf_pca_model *m, const btf_views *src, const btf_pca_options *po)
{
    return m && m->width == src->width && m->height == src->height && m->k == po->k &&
           m->n_comp == po->components && m->center == po->center && m->grouping == po->grouping &&
           m->method == po->method && memcmp(&m->lights, &src->lights, sizeof m->lights) == 0 &&
           memcmp(&m->views, &src->views, sizeof m->views) == 0;
}


/* Component j's atlas (its full-range codes) as a lossy WebP or AVIF at its level into
 * w->lossy[j], and the atlas replaced by its decode, as every reader sees it. */
static btf_result btf__lossy_atlas(btf__writer *w, int j, btf_error *err)
{
    btf_result r = btf_lossy_encode(w->codec, w->atlas[j], w->aw, w->ah, w->quality[j], &w->lossy[j], &w->lossy_n[j], err);
    if (r == BTF_OK)
        r = btf_lossy_decode(w->lossy[j], w->lossy_n[j], "package: lossy texture", w->aw, w->ah, w->atlas[j], err);
    return r;
}

/* The lossy components' files (btf_rd_result.tex_quality): every block's codes into
 * the atlases from the model m, then each lossy one encoded and decoded (one thread
 * per component above BTF_RD_THREAD_MIN_BYTES of atlases), so that the error sums,
 * the order and the Lab curve that follow measure the decoded texels. */
static btf_result btf__lossy_atlases(btf__writer *w, const btf_pca_model *m, btf_error *err)
{
    int n = 0;
    for (int j = 0; j < w->C; j++)
        n += w->quality[j] >= 0;
    if (n == 0)
        return BTF_OK;
    for (int b = 0; b < w->blocks->n_blocks; b++)
        btf__quant_textures(w, b, &m->block[b]);
    btf_result *rj = calloc((size_t)w->C, sizeof *rj);
    btf_error *ej = calloc((size_t)w->C, sizeof *ej);
    if (!rj || !ej) {
        free(rj), free(ej);
        return btf_fail(err, BTF_ERR_NOMEM, "package: out of memory");
    }
    size_t atlas_bytes = (size_t)n * (size_t)w->aw * (size_t)w->ah;
#pragma omp parallel for schedule(dynamic, 1) if (atlas_bytes >= BTF_RD_THREAD_MIN_BYTES)
    for (int j = 0; j < w->C; j++)
        rj[j] = w->quality[j] >= 0 ? btf__lossy_atlas(w, j, &ej[j]) : BTF_OK;
    btf_result r = BTF_OK;
    for (int j = 0; j < w->C && r == BTF_OK; j++)
        if ((r = rj[j]) != BTF_OK && err)
            *err = ej[j];
    free(rj), free(ej);
    return r;
}

/* Version 3: steps by rate-distortion from the float model m, then every block's
 * matrix rebuilt once to quantise it and accumulate the exact error sums. */
static btf_result btf__rd_quantise(btf__writer *w, btf_views *src, const btf_pca_model *m, float noise,
                                   const btf_package_options *o, btf_error *err)
{
    const btf_package_channel *c = w->chan;
    btf_rd_params par = {m,           w->acols,     w->arows,  noise,   c->rd_max_bytes, o->png_only,
                         c->rd_ladder, c->estimate ? c->tex_rate_scale : 0.0, c->rd_near, c->rd_tex_fix, w->bits,
                         o->lossy,       o->lossy};
    btf_rd_result rr, *keep = c->rd_out;
    btf_result r = btf_rd_allocate(&par, &rr, err);
    if (r != BTF_OK)
        return r;
    memcpy(w->tnoise, rr.tex_noise, (size_t)w->C * sizeof(float));
    memcpy(w->wnoise, rr.wt_noise, (size_t)w->C * sizeof(float));
    memcpy(w->quality, rr.tex_quality, (size_t)w->C * sizeof(int));
    w->codec = o->lossy;
    w->rd_json = btf__rd_json(&rr, o->lossy);
    if (c->estimate && (w->est_bytes = malloc((size_t)w->C * sizeof(long long))) != NULL)
        memcpy(w->est_bytes, rr.comp_bytes, (size_t)w->C * sizeof(long long));
    if (c->estimate && !w->est_bytes)
        r = btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (estimates)");
    for (int j = 0; r == BTF_OK && j < w->C; j++) /* lossy weights: their file and its decode */
        if (rr.wt_quality[j] >= 0)
            r = btf_rd_wt_lossy(m, j, rr.wt_quality[j], w->wt_range[j], w->qwt[j], &w->wlossy[j], &w->wlossy_n[j], err);
    if (keep)
        *keep = rr;
    else
        btf_rd_result_free(&rr);
    if (r != BTF_OK)
        return r;
    r = btf__lossy_atlases(w, m, err);
    size_t nA = (size_t)w->rows * 3 * w->L * w->blocks->k * sizeof(float);
    float *A = r == BTF_OK ? btf_big_alloc(nA) : NULL;
    if (r == BTF_OK && !A)
        return btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (block matrix)");
    for (int b = 0; r == BTF_OK && b < w->blocks->n_blocks; b++) {
        r = btf_pca_block_fill(src, w->blocks, b, A, err);
        if (r == BTF_OK)
            r = btf__on_block(w, b, A, &m->block[b], err);
    }
    btf_big_free(A, nA);
    return r;
}


static btf_result btf__package_name(const char *out_dir, const btf_package_options *o, char *name, btf_error *err)
{
    const char *n = o->name;
    char base[4096];
    if (!n) {
        snprintf(base, sizeof base, "%s", out_dir);
        size_t len = strlen(base);
        while (len > 1 && base[len - 1] == '/')
            base[--len] = 0;
        const char *slash = strrchr(base, '/');
        n = slash ? slash + 1 : base;
    }
    if (!btf_manifest_valid_name(n))
        return btf_fail(err, BTF_ERR_ARG, "package name '%s': use 1..%d characters of [A-Za-z0-9._-]", n,
                        BTF_PACKAGE_NAME_MAX - 1);
    memcpy(name, n, strlen(n) + 1); /* btf__valid_name bounds the length */
    return BTF_OK;
}


btf_result btf_package_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                const char *out_dir, btf_compress_stats *stats, btf_error *err)
{
    return btf_package_compress_with(src, pca, opt, NULL, out_dir, stats, err);
}

btf_result btf_package_compress_views(btf_views *src, const btf_pca_options *pca, const btf_package_options *opt,
                                      const char *out_dir, btf_compress_stats *stats, btf_error *err)
{
    return btf_package_compress_views_with(src, pca, opt, NULL, out_dir, stats, err);
}

btf_result btf_package_compress_with(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                     const btf_package_channel *ch, const char *out_dir, btf_compress_stats *stats,
                                     btf_error *err)
{
    btf_pca_options po = btf_pca_resolve(pca);
    btf_result r = btf_pca_check(src, &po, err);
    if (r != BTF_OK)
        return r;
    btf_views s;
    btf_views_wrap(src, &s);
    return btf_package_compress_views_with(&s, pca, opt, ch, out_dir, stats, err);
}

btf_result btf_package_compress_views_with(btf_views *src, const btf_pca_options *pca, const btf_package_options *opt,
                                           const btf_package_channel *ch, const char *out_dir,
                                           btf_compress_stats *stats, btf_error *err)
{
    btf_package_options o = {0};
    btf_package_channel c = {0};
    btf_views lin;
    if (opt)
        o = *opt;
    if (ch)
        c = *ch;
    if (o.linear && src) {
        btf__views_linear(src, &lin);
        src = &lin;
    }
    if (o.bits == 0)
        o.bits = 8;
    if (o.bits != 8 && o.bits != 16)
        return btf_fail(err, BTF_ERR_ARG, "bits = %d: must be 8 or 16", o.bits);
    if (!out_dir || !*out_dir || strlen(out_dir) > 4000)
        return btf_fail(err, BTF_ERR_ARG, "package: no output directory");
    char name[BTF_PACKAGE_NAME_MAX];
    btf_result r = btf__package_name(out_dir, &o, name, err);
    if (r != BTF_OK)
        return r;
    btf_pca_options po = btf_pca_resolve(pca);
    /* unless asked: the rounding is the sRGB bytes', and 16 bits keep it (a full-rank round trip) */
    if ((!pca || pca->rounding == BTF_ROUNDING_DEFAULT) && (o.linear || o.bits == 16))
        po.rounding = BTF_ROUNDING_KEEP;
    r = btf_pca_check_views(src, &po, err);
    if (r != BTF_OK)
        return r;
    if (po.components > BTF_PACKAGE_MAX_CHUNKS)
        return btf_fail(err, BTF_ERR_RANGE, "components C = %d: a package holds at most %d", po.components,
                        BTF_PACKAGE_MAX_CHUNKS);
    btf_blocks *bl = NULL;
    r = btf_blocks_group(&src->views, po.k, po.grouping, &bl, err);
    if (r != BTF_OK)
        return r;
    btf__writer w;
    int stride = btf_sample_stride(src->width, src->height, o.lab_max_texels > 0 ? o.lab_max_texels : 256);
    r = btf__writer_init(&w, src, bl, po.components, o.bits, stride, err);
    w.chan = &c;
    w.linear = o.linear != 0;
    /* 16 bits: the full range without rd; rd allocates from the same equal-noise reference as 8 bits */
    float noise = (o.bits != 8 && !o.rd) || o.tex_noise < 0.0f ? 0.0f
                  : (o.tex_noise > 0.0f ? o.tex_noise : BTF_PACKAGE_TEX_NOISE);
    for (int j = 0; r == BTF_OK && j < w.C; j++)
        w.tnoise[j] = noise; /* equal noise; --rd replaces it after the PCA */
    w.version = o.rd ? 3 : 1;
    w.wt_webp = !o.png_only;
    if (r == BTF_OK && o.rd && !(noise > 0.0f))
        r = btf_fail(err, BTF_ERR_ARG, "rate-distortion steps (rd) need tex_noise >= 0");
    if (r == BTF_OK && c.estimate && !o.rd)
        r = btf_fail(err, BTF_ERR_ARG, "package: estimates come from the rate-distortion allocation (rd)");
    char tmp[BTF_FS_PATH_MAX] = "";
    int disk = !c.estimate && !c.sink; /* the files go into tmp, then tmp in place of out_dir */
    if (r == BTF_OK && !c.sink)
        r = btf_fs_replaceable(out_dir, btf_manifest_owns_dir, NULL, err); /* refuse before the work */
    if (r == BTF_OK && disk)
        r = btf_fs_temp_dir(out_dir, tmp, sizeof tmp, btf_manifest_owns_temp, NULL, err);
    int made = r == BTF_OK && disk;
    double t0 = btf_seconds(), t1 = t0;
    if (r == BTF_OK) {
        /* the writer keeps what it needs per block; --rd keeps the model and passes the blocks again */
        btf_pca_model *m = NULL, **slot = o.rd ? c.rd_model : NULL;
        int reuse = slot && btf__model_fits(*slot, src, &po);
        if (slot && !reuse) { /* freed first: never two models in memory */
            btf_pca_model_free(*slot);
            *slot = NULL;
        }
        if (reuse)
            m = *slot;
        else
            r = btf_pca_compress_views(src, &po, o.rd ? NULL : btf__on_block, &w, o.rd ? &m : NULL, err);
        if (r == BTF_OK && o.rd)
            r = btf__rd_quantise(&w, src, m, noise, &o, err);
        if (slot)
            *slot = m; /* the slot owns it now */
        else
            btf_pca_model_free(m);
        t1 = btf_seconds();
    }
    if (r == BTF_OK)
        r = btf__write_all(&w, &po, &o, name, tmp, stats, err);
    if (r == BTF_OK && disk && o.thumbnail > 0)
        r = btf_package_thumbnail(tmp, o.thumbnail, err);
    if (r == BTF_OK && disk)
        r = btf_fs_replace_dir(tmp, out_dir, btf_manifest_owns_dir, NULL, err);
    if (r != BTF_OK && made)
        btf_fs_rmtree(tmp, NULL); /* a failed package */
    if (stats) {
        stats->seconds_pca = t1 - t0;
        stats->seconds_write = btf_seconds() - t1;
    }
    btf__writer_free(&w);
    btf_blocks_free(bl);
    return r;
}
