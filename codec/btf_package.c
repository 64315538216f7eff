/* btf_package.c - package writer (quantisation, importance order, errors, files) and
 * reader. Format: doc/package-format.md. Decoder: btf_decode.c. */
#include "btf_package.h"
#include "btf_lod.h"

#include <cblas.h>
#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "btf_image.h"
#include "btf_metrics.h"

#define BTF__SLAB_ROWS 4096
#define BTF__MANIFEST_MAX (64L << 20)

/* ---------------------------------------------------------------- small helpers */

static double btf__now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int btf__valid_name(const char *s)
{
    size_t n = strlen(s);
    if (n == 0 || n >= BTF_PACKAGE_NAME_MAX || !strcmp(s, ".") || !strcmp(s, ".."))
        return 0;
    for (size_t i = 0; i < n; i++) {
        char c = s[i];
        if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
              c == '-'))
            return 0;
    }
    return 1;
}

/* Dequantisation, the one formula every decoder uses (float32). */
static inline float btf__deq(const float *range, unsigned q)
{
    return range[0] + range[1] * (float)q;
}

/* Affine range of x[0..n-1] onto 0..qmax; writes {lo, step}. */
static void btf__range(const float *x, size_t n, size_t stride, unsigned qmax, float range[2])
{
    float lo = x[0], hi = x[0];
    for (size_t i = 1; i < n; i++) {
        float v = x[i * stride];
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
    }
    float step = (hi - lo) / (float)qmax;
    range[0] = lo;
    range[1] = (step > 0.0f && isfinite(step)) ? step : 0.0f;
}

static inline unsigned btf__quant(float x, const float range[2], unsigned qmax)
{
    if (range[1] <= 0.0f)
        return 0;
    float q = rintf((x - range[0]) / range[1]);
    return q <= 0.0f ? 0u : q >= (float)qmax ? qmax : (unsigned)q;
}

/* Removes the plain files in dir, then dir (the writer never makes subdirectories). */
static void btf__remove_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *e;
        char path[4096];
        while ((e = readdir(d)) != NULL) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
                continue;
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            unlink(path);
        }
        closedir(d);
    }
    rmdir(dir);
}

static long long btf__file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode) ? (long long)st.st_size : -1;
}

/* ---------------------------------------------------------------- writer state */

/* State of one package compression; lives for one btf_package_compress call. */
typedef struct btf__writer {
    const btf *src;
    const btf_blocks *blocks;
    int C, bits, qmax, ch, W, H, L, V, rows;
    float noise;          /* target RMS noise per component (byte/255 scale); <= 0 = full range */
    int acols, arows, aw, ah;
    uint8_t **atlas;      /* C atlases aw*ah*ch */
    uint16_t **qwt;       /* C arrays V*L*3 */
    float **tex_range;    /* C arrays n_blocks*2 */
    float **wt_range;     /* C arrays n_blocks*2 */
    double E;             /* |A|^2 summed over blocks */
    double *Pq, *Pf;      /* C: t_j . (A w_j), quantised / float */
    double *Qq, *Qf;      /* C*C: (t_i.t_j)(w_i.w_j) */
    double *Tqd, *Tfd;    /* rows x C scratch */
    double *Wd;           /* maxcols x 2C scratch: [Wq | Wf] */
    double *Ad, *D;       /* slab scratch */
    double *TT, *WW;      /* C*C scratch */
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
    free(w->atlas), free(w->qwt), free(w->tex_range), free(w->wt_range);
    free(w->Pq), free(w->Pf), free(w->Qq), free(w->Qf);
    free(w->Tqd), free(w->Tfd), free(w->Wd), free(w->Ad), free(w->D), free(w->TT), free(w->WW);
}

static btf_result btf__writer_init(btf__writer *w, const btf *src, const btf_blocks *bl, int C, int bits,
                                   btf_error *err)
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
    w->Pq = calloc((size_t)C, sizeof(double)), w->Pf = calloc((size_t)C, sizeof(double));
    w->Qq = calloc(C2, sizeof(double)), w->Qf = calloc(C2, sizeof(double));
    w->TT = calloc(C2, sizeof(double)), w->WW = calloc(C2, sizeof(double));
    w->Tqd = malloc((size_t)w->rows * C * sizeof(double));
    w->Tfd = malloc((size_t)w->rows * C * sizeof(double));
    w->Wd = malloc((size_t)maxcols * 2 * C * sizeof(double));
    w->Ad = malloc((size_t)BTF__SLAB_ROWS * maxcols * sizeof(double));
    w->D = malloc((size_t)BTF__SLAB_ROWS * 2 * C * sizeof(double));
    int ok = w->atlas && w->qwt && w->tex_range && w->wt_range && w->Pq && w->Pf && w->Qq && w->Qf && w->TT &&
             w->WW && w->Tqd && w->Tfd && w->Wd && w->Ad && w->D;
    for (int j = 0; ok && j < C; j++) {
        w->atlas[j] = calloc((size_t)w->aw * w->ah * w->ch, 1);
        w->qwt[j] = calloc((size_t)w->V * w->L * 3, sizeof(uint16_t));
        w->tex_range[j] = calloc((size_t)bl->n_blocks * 2, sizeof(float));
        w->wt_range[j] = calloc((size_t)bl->n_blocks * 2, sizeof(float));
        ok = w->atlas[j] && w->qwt[j] && w->tex_range[j] && w->wt_range[j];
    }
    return ok ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (%d components)", C);
}

/* Quantises block b's textures into the atlases; dequantised copies into Tqd, floats into Tfd. */
static void btf__quant_textures(btf__writer *w, int b, const btf_pca_block *res)
{
    int tx0 = (b % w->acols) * w->W, ty0 = (b / w->acols) * w->H;
    for (int j = 0; j < w->C; j++) {
        const float *t = res->t + (size_t)j * w->rows;
        float *rg = w->tex_range[j] + 2 * b;
        btf__range(t, (size_t)w->rows, 1, (unsigned)w->qmax, rg);
        float wn = cblas_snrm2(res->cols, res->w + (size_t)j * res->cols, 1);
        if (w->noise > 0.0f && wn > 0.0f) { /* equal RMS noise per component */
            float step = w->noise * sqrtf(12.0f * (float)res->cols) / wn;
            rg[1] = step > rg[1] ? step : rg[1];
        }
        for (int y = 0; y < w->H; y++)
            for (int x = 0; x < w->W; x++) {
                size_t r = (size_t)y * w->W + x;
                unsigned q = btf__quant(t[r], rg, (unsigned)w->qmax);
                uint8_t *px = w->atlas[j] + ((size_t)(ty0 + y) * w->aw + (size_t)(tx0 + x)) * w->ch;
                if (w->bits == 16) {
                    px[0] = (uint8_t)(q >> 8);
                    px[1] = (uint8_t)(q & 255u);
                } else {
                    px[0] = (uint8_t)q;
                }
                w->Tqd[(size_t)j * w->rows + r] = btf__deq(rg, q);
                w->Tfd[(size_t)j * w->rows + r] = t[r];
            }
    }
}

/* Quantises block b's weights (16 bits) into qwt; [Wq | Wf] into Wd. */
static void btf__quant_weights(btf__writer *w, int b, const btf_pca_block *res)
{
    const btf_blocks *bl = w->blocks;
    int cols = res->cols;
    for (int j = 0; j < w->C; j++) {
        const float *wj = res->w + (size_t)j * cols;
        float *rg = w->wt_range[j] + 2 * b;
        btf__range(wj, (size_t)cols, 1, 65535u, rg);
        for (int col = 0; col < cols; col++) {
            int pos = col / (3 * w->L), l = (col / 3) % w->L, c = col % 3;
            int v = bl->views[bl->start[b] + pos];
            unsigned q = btf__quant(wj[col], rg, 65535u);
            w->qwt[j][((size_t)v * w->L + l) * 3 + c] = (uint16_t)q;
            w->Wd[(size_t)j * cols + col] = btf__deq(rg, q);
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
    for (int r0 = 0; r0 < w->rows; r0 += BTF__SLAB_ROWS) {
        int nr = w->rows - r0 < BTF__SLAB_ROWS ? w->rows - r0 : BTF__SLAB_ROWS;
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

static btf_result btf__on_block(void *ctx, int b, const float *A, const btf_pca_block *res, btf_error *err)
{
    btf__writer *w = ctx;
    (void)err;
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

/* Lab (and Delta E) of every prefix on the texel subsample; rgb errors exact elsewhere. */
static btf_result btf__lab_curve(const btf__writer *w, const int *order, int stride, btf_metrics *out,
                                 btf_error *err)
{
    int C = w->C, V = w->V, L = w->L;
    size_t np = (size_t)V * L;
    float *ref = malloc(np * 3 * sizeof(float)), *test = malloc((size_t)C * np * 3 * sizeof(float));
    float *tv = malloc((size_t)C * sizeof(float));
    btf_metrics_acc *acc = calloc((size_t)C, sizeof *acc);
    if (!ref || !test || !tv || !acc) {
        free(ref), free(test), free(tv), free(acc);
        return btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (error curve)");
    }
    for (int y = 0; y < w->H; y += stride)
        for (int x = 0; x < w->W; x += stride) {
            for (int v = 0; v < V; v++) {
                int b = w->blocks->block_of_view[v];
                size_t px = ((size_t)((b / w->acols) * w->H + y) * w->aw + (size_t)((b % w->acols) * w->W + x)) * w->ch;
                for (int a = 0; a < C; a++) {
                    int j = order[a];
                    const uint8_t *p = w->atlas[j] + px;
                    unsigned q = w->bits == 16 ? (unsigned)p[0] * 256u + p[1] : p[0];
                    tv[a] = btf__deq(w->tex_range[j] + 2 * b, q);
                }
                for (int l = 0; l < L; l++)
                    for (int c = 0; c < 3; c++) {
                        size_t i = ((size_t)v * L + l) * 3 + c;
                        ref[i] = btf_get(w->src, v, l, x, y, c);
                        float s = 0.0f;
                        for (int a = 0; a < C; a++) {
                            int j = order[a];
                            s += tv[a] * btf__deq(w->wt_range[j] + 2 * b, w->qwt[j][i]);
                            test[(size_t)a * np * 3 + i] = s;
                        }
                    }
            }
            for (int a = 0; a < C; a++)
                btf_metrics_add(&acc[a], ref, test + (size_t)a * np * 3, np);
        }
    for (int a = 0; a < C; a++)
        btf_metrics_finish(&acc[a], &out[a]);
    free(ref), free(test), free(tv), free(acc);
    return BTF_OK;
}

/* ---------------------------------------------------------------- files */

static btf_result btf__hook(const btf_package_options *o, int *counter, const char *file, btf_error *err)
{
    int i = (*counter)++;
    if (o->write_hook && o->write_hook(o->hook_ctx, i, file))
        return btf_fail(err, BTF_ERR_IO, "%s: write failed (no space left on device, simulated)", file);
    return BTF_OK;
}

static btf_result btf__write_bytes(const char *path, const void *data, size_t n, btf_error *err)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot create (%s)", path, strerror(errno));
    size_t wr = fwrite(data, 1, n, f);
    int bad = wr != n || fflush(f) != 0;
    bad = (fclose(f) != 0) || bad;
    if (bad) {
        unlink(path);
        return btf_fail(err, BTF_ERR_IO, "%s: write failed (%s)", path, strerror(errno));
    }
    return BTF_OK;
}

static btf_result btf__write_weights(const char *path, const uint16_t *q, size_t n, btf_error *err)
{
    uint8_t *buf = malloc(2 * n);
    if (!buf)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    for (size_t i = 0; i < n; i++) {
        buf[2 * i] = (uint8_t)(q[i] & 255u);
        buf[2 * i + 1] = (uint8_t)(q[i] >> 8);
    }
    btf_result r = btf__write_bytes(path, buf, 2 * n, err);
    free(buf);
    return r;
}

static cJSON *btf__rings_json(const btf_dirset *d)
{
    cJSON *o = cJSON_CreateObject(), *a = cJSON_AddArrayToObject(o, "rings");
    for (int r = 0; r < d->n_rings; r++) {
        cJSON *e = cJSON_CreateObject();
        cJSON_AddNumberToObject(e, "theta", d->rings[r].theta_deg);
        cJSON_AddNumberToObject(e, "count", d->rings[r].count);
        cJSON_AddNumberToObject(e, "phi_offset", d->rings[r].phi_offset_deg);
        cJSON_AddItemToArray(a, e);
    }
    return o;
}

static cJSON *btf__ranges_json(const float *rg, int n_blocks)
{
    cJSON *a = cJSON_CreateArray();
    for (int b = 0; b < n_blocks; b++) {
        cJSON *p = cJSON_CreateArray();
        cJSON_AddItemToArray(p, cJSON_CreateNumber(rg[2 * b]));
        cJSON_AddItemToArray(p, cJSON_CreateNumber(rg[2 * b + 1]));
        cJSON_AddItemToArray(a, p);
    }
    return a;
}

static double btf__json_num(double x)
{
    return isfinite(x) ? x : 0.0;
}

/* Manifest text (malloc'd); NULL when out of memory. */
static char *btf__manifest(const btf__writer *w, const btf_pca_options *po, const char *name, int stride,
                           const int *order, const long long *bytes, const btf_metrics *lab, const double *rmse,
                           const double *rmse_float)
{
    const btf_blocks *bl = w->blocks;
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "format", "btf-package");
    cJSON_AddNumberToObject(m, "version", 1);
    cJSON_AddStringToObject(m, "name", name);
    cJSON_AddNumberToObject(m, "width", w->W);
    cJSON_AddNumberToObject(m, "height", w->H);
    cJSON_AddItemToObject(m, "lights", btf__rings_json(&w->src->lights));
    cJSON_AddItemToObject(m, "views", btf__rings_json(&w->src->views));
    cJSON_AddNumberToObject(m, "k", po->k);
    cJSON_AddNumberToObject(m, "components", w->C);
    cJSON_AddStringToObject(m, "center", btf_center_name(po->center));
    cJSON_AddStringToObject(m, "grouping", btf_grouping_name(po->grouping));
    cJSON_AddNumberToObject(m, "bits", w->bits);
    cJSON *blocks = cJSON_AddArrayToObject(m, "blocks");
    for (int b = 0; b < bl->n_blocks; b++) {
        cJSON *a = cJSON_CreateArray();
        for (int i = bl->start[b]; i < bl->start[b + 1]; i++)
            cJSON_AddItemToArray(a, cJSON_CreateNumber(bl->views[i]));
        cJSON_AddItemToArray(blocks, a);
    }
    cJSON *at = cJSON_AddObjectToObject(m, "atlas");
    cJSON_AddNumberToObject(at, "cols", w->acols);
    cJSON_AddNumberToObject(at, "rows", w->arows);
    cJSON_AddNumberToObject(at, "tile_width", w->W);
    cJSON_AddNumberToObject(at, "tile_height", w->H);
    cJSON_AddNumberToObject(at, "width", w->aw);
    cJSON_AddNumberToObject(at, "height", w->ah);
    cJSON_AddNumberToObject(at, "channels", w->ch);
    cJSON *wt = cJSON_AddObjectToObject(m, "weights");
    cJSON_AddNumberToObject(wt, "bits", 16);
    cJSON_AddStringToObject(wt, "layout", "view-light-channel");
    cJSON_AddStringToObject(wt, "endian", "little");
    cJSON *es = cJSON_AddObjectToObject(m, "error_sample");
    cJSON_AddNumberToObject(es, "texel_stride", stride);
    cJSON_AddNumberToObject(es, "texels", (double)(((w->W + stride - 1) / stride) * ((w->H + stride - 1) / stride)));
    cJSON *chunks = cJSON_AddArrayToObject(m, "chunks");
    for (int a = 0; a < w->C; a++) {
        int j = order[a];
        char tex[BTF_PACKAGE_NAME_MAX], wts[BTF_PACKAGE_NAME_MAX];
        snprintf(tex, sizeof tex, "tex-%02d.png", j);
        snprintf(wts, sizeof wts, "wt-%02d.bin", j);
        cJSON *c = cJSON_CreateObject();
        cJSON_AddNumberToObject(c, "id", a);
        cJSON_AddNumberToObject(c, "component", j);
        cJSON *files = cJSON_AddArrayToObject(c, "files");
        cJSON_AddItemToArray(files, cJSON_CreateString(tex));
        cJSON_AddItemToArray(files, cJSON_CreateString(wts));
        cJSON_AddNumberToObject(c, "bytes", (double)bytes[j]);
        cJSON_AddNumberToObject(c, "rmse", btf__json_num(rmse[a]));
        cJSON_AddNumberToObject(c, "lab", btf__json_num(lab[a].lab_thesis));
        cJSON_AddNumberToObject(c, "psnr", btf__json_num(rmse[a] > 0 ? 20.0 * log10(255.0 / rmse[a]) : 999.0));
        cJSON_AddNumberToObject(c, "delta_e76", btf__json_num(lab[a].delta_e76));
        cJSON_AddNumberToObject(c, "rmse_float", btf__json_num(rmse_float[a]));
        cJSON_AddItemToObject(c, "tex_range", btf__ranges_json(w->tex_range[j], bl->n_blocks));
        cJSON_AddItemToObject(c, "wt_range", btf__ranges_json(w->wt_range[j], bl->n_blocks));
        cJSON_AddItemToArray(chunks, c);
    }
    char *s = cJSON_Print(m);
    cJSON_Delete(m);
    return s;
}

/* Texel stride of the Lab subsample: smallest s with ceil(W/s)*ceil(H/s) <= max. */
static int btf__lab_stride(int W, int H, int max_texels)
{
    int s = 1;
    while ((long)((W + s - 1) / s) * ((H + s - 1) / s) > max_texels)
        s++;
    return s;
}

/* Writes every file into tmp, chooses the order and writes the manifest. */
static btf_result btf__write_all(btf__writer *w, const btf_pca_options *po, const btf_package_options *o,
                                 const char *name, const char *tmp, btf_compress_stats *st, btf_error *err)
{
    int C = w->C, counter = 0;
    char path[8192], file[BTF_PACKAGE_NAME_MAX];
    long long *bytes = calloc((size_t)C, sizeof *bytes);
    int *order = calloc((size_t)C, sizeof *order);
    double *rmse = calloc((size_t)C, sizeof(double)), *rmsef = calloc((size_t)C, sizeof(double));
    btf_metrics *lab = calloc((size_t)C, sizeof *lab);
    btf_result r = BTF_OK;
    if (!bytes || !order || !rmse || !rmsef || !lab) {
        r = btf_fail(err, BTF_ERR_NOMEM, "package: out of memory");
        goto done;
    }
    for (int j = 0; j < C && r == BTF_OK; j++) {
        snprintf(file, sizeof file, "tex-%02d.png", j);
        snprintf(path, sizeof path, "%s/%s", tmp, file);
        r = btf__hook(o, &counter, file, err);
        if (r == BTF_OK)
            r = btf_image_write(path, w->aw, w->ah, w->ch, 8, w->atlas[j], err);
        long long s1 = btf__file_size(path);
        snprintf(file, sizeof file, "wt-%02d.bin", j);
        snprintf(path, sizeof path, "%s/%s", tmp, file);
        if (r == BTF_OK)
            r = btf__hook(o, &counter, file, err);
        if (r == BTF_OK)
            r = btf__write_weights(path, w->qwt[j], (size_t)w->V * w->L * 3, err);
        long long s2 = btf__file_size(path);
        if (r == BTF_OK && (s1 < 0 || s2 < 0))
            r = btf_fail(err, BTF_ERR_IO, "%s: written file vanished", tmp);
        bytes[j] = s1 + s2;
    }
    if (r != BTF_OK)
        goto done;
    btf__order(w, bytes, order);
    double n_samples = (double)w->rows * w->V * w->L * 3.0;
    for (int a = 0; a < C; a++) {
        rmse[a] = 255.0 * sqrt(btf__sq_error(w, order, a + 1, 1) / n_samples);
        rmsef[a] = 255.0 * sqrt(btf__sq_error(w, order, a + 1, 0) / n_samples);
    }
    int stride = btf__lab_stride(w->W, w->H, o->lab_max_texels > 0 ? o->lab_max_texels : 256);
    r = btf__lab_curve(w, order, stride, lab, err);
    if (r != BTF_OK)
        goto done;
    char *text = btf__manifest(w, po, name, stride, order, bytes, lab, rmse, rmsef);
    if (!text) {
        r = btf_fail(err, BTF_ERR_NOMEM, "package: cannot build the manifest");
        goto done;
    }
    snprintf(path, sizeof path, "%s/manifest.json", tmp);
    r = btf__hook(o, &counter, "manifest.json", err);
    if (r == BTF_OK)
        r = btf__write_bytes(path, text, strlen(text), err);
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

/* Moves tmp to out; an existing package (or empty directory) at out is replaced. */
static btf_result btf__commit(const char *tmp, const char *out, btf_error *err)
{
    struct stat st;
    char old[4200];
    if (lstat(out, &st) == 0) {
        char man[4200];
        snprintf(man, sizeof man, "%s/manifest.json", out);
        if (!S_ISDIR(st.st_mode))
            return btf_fail(err, BTF_ERR_IO, "%s: exists and is not a package directory", out);
        if (rmdir(out) != 0) { /* not empty: must be a package */
            if (btf__file_size(man) < 0)
                return btf_fail(err, BTF_ERR_IO, "%s: exists, is not empty and has no manifest.json", out);
            snprintf(old, sizeof old, "%s.old-%ld", out, (long)getpid());
            if (rename(out, old) != 0)
                return btf_fail(err, BTF_ERR_IO, "%s: cannot move aside (%s)", out, strerror(errno));
            if (rename(tmp, out) != 0) {
                int e = errno;
                rename(old, out);
                return btf_fail(err, BTF_ERR_IO, "%s: cannot rename into place (%s)", out, strerror(e));
            }
            btf__remove_dir(old);
            return BTF_OK;
        }
    }
    if (rename(tmp, out) != 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot rename into place (%s)", out, strerror(errno));
    return BTF_OK;
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
    if (!btf__valid_name(n))
        return btf_fail(err, BTF_ERR_ARG, "package name '%s': use 1..%d characters of [A-Za-z0-9._-]", n,
                        BTF_PACKAGE_NAME_MAX - 1);
    memcpy(name, n, strlen(n) + 1); /* btf__valid_name bounds the length */
    return BTF_OK;
}

btf_result btf_package_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                const char *out_dir, btf_compress_stats *stats, btf_error *err)
{
    btf_package_options o = {0};
    if (opt)
        o = *opt;
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
    r = btf_pca_check(src, &po, err);
    if (r != BTF_OK)
        return r;
    if (po.components > BTF_PACKAGE_MAX_CHUNKS)
        return btf_fail(err, BTF_ERR_RANGE, "components C = %d: a package holds at most %d", po.components,
                        BTF_PACKAGE_MAX_CHUNKS);
    btf_blocks *bl = NULL;
    r = btf_group_views(&src->views, po.k, po.grouping, &bl, err);
    if (r != BTF_OK)
        return r;
    btf__writer w;
    r = btf__writer_init(&w, src, bl, po.components, o.bits, err);
    w.noise = o.bits != 8 || o.tex_noise < 0.0f ? 0.0f
              : (o.tex_noise > 0.0f ? o.tex_noise : BTF_PACKAGE_TEX_NOISE) / 255.0f;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", out_dir, (long)getpid());
    btf__remove_dir(tmp); /* stale leftover of this pid */
    if (r == BTF_OK && mkdir(tmp, 0755) != 0)
        r = btf_fail(err, BTF_ERR_IO, "%s: cannot create (%s)", tmp, strerror(errno));
    int made = r == BTF_OK;
    double t0 = btf__now(), t1 = t0;
    if (r == BTF_OK) {
        btf_pca_model *m = NULL;
        r = btf_pca_compress(src, &po, btf__on_block, &w, &m, err);
        btf_pca_model_free(m);
        t1 = btf__now();
    }
    if (r == BTF_OK)
        r = btf__write_all(&w, &po, &o, name, tmp, stats, err);
    if (r == BTF_OK)
        r = btf__commit(tmp, out_dir, err);
    if (r != BTF_OK && made)
        btf__remove_dir(tmp);
    if (stats) {
        stats->seconds_pca = t1 - t0;
        stats->seconds_write = btf__now() - t1;
    }
    btf__writer_free(&w);
    btf_blocks_free(bl);
    return r;
}

/* ---------------------------------------------------------------- reader */

void btf_package_free(btf_package *p)
{
    if (!p)
        return;
    for (int i = 0; i < p->n_chunks && p->chunk; i++) {
        free(p->chunk[i].tex_range);
        free(p->chunk[i].wt_range);
    }
    for (int i = 0; i < p->n_loaded; i++) {
        free(p->tex[i]);
        free(p->wt[i]);
    }
    free(p->chunk);
    free(p->tex);
    free(p->wt);
    btf_blocks_free(p->blocks);
    free(p);
}

static int btf__get_int(const cJSON *o, const char *key, int lo, int hi, int *out)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v) || v->valuedouble != floor(v->valuedouble) || v->valuedouble < lo || v->valuedouble > hi)
        return 0;
    *out = (int)v->valuedouble;
    return 1;
}

static btf_result btf__parse_rings(const cJSON *o, const char *what, const char *path, btf_dirset *d,
                                   btf_error *err)
{
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(o, what), "rings");
    int n = cJSON_GetArraySize(a);
    if (!cJSON_IsArray(a) || n < 1 || n > BTF_MAX_RINGS)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"%s\" has no valid ring list", path, what);
    btf_ring rings[BTF_MAX_RINGS];
    for (int i = 0; i < n; i++) {
        const cJSON *e = cJSON_GetArrayItem(a, i);
        const cJSON *t = cJSON_GetObjectItemCaseSensitive(e, "theta"), *p = cJSON_GetObjectItemCaseSensitive(e, "phi_offset");
        if (!cJSON_IsNumber(t) || !cJSON_IsNumber(p) || !btf__get_int(e, "count", 1, BTF_MAX_DIRS, &rings[i].count))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: %s ring %d is malformed", path, what, i);
        rings[i].theta_deg = (float)t->valuedouble;
        rings[i].phi_offset_deg = (float)p->valuedouble;
    }
    btf_result r = btf_dirset_make(rings, n, d, err);
    if (r != BTF_OK)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s rings invalid", path, what);
    return BTF_OK;
}

static btf_result btf__parse_blocks(const cJSON *m, btf_package *p, const char *path, btf_error *err)
{
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(m, "blocks");
    int nb = cJSON_GetArraySize(a), V = p->views.n_dirs;
    if (!cJSON_IsArray(a) || nb < 1 || nb > V)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"blocks\" must list 1..%d blocks", path, V);
    int *sizes = calloc((size_t)nb, sizeof(int)), *flat = calloc((size_t)V, sizeof(int));
    const int **lists = calloc((size_t)nb, sizeof *lists);
    btf_result r = BTF_OK;
    if (!sizes || !flat || !lists) {
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
        goto done;
    }
    int pos = 0;
    for (int b = 0; b < nb && r == BTF_OK; b++) {
        const cJSON *l = cJSON_GetArrayItem(a, b);
        int n = cJSON_GetArraySize(l);
        if (!cJSON_IsArray(l) || n < 1 || pos + n > V) {
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: block %d is not a valid view list", path, b);
            break;
        }
        sizes[b] = n;
        lists[b] = flat + pos;
        for (int i = 0; i < n; i++) {
            const cJSON *v = cJSON_GetArrayItem(l, i);
            if (!cJSON_IsNumber(v)) {
                r = btf_fail(err, BTF_ERR_FORMAT, "%s: block %d entry %d is not a number", path, b, i);
                break;
            }
            flat[pos++] = (int)v->valuedouble;
        }
    }
    if (r == BTF_OK)
        r = btf_blocks_from_lists(V, nb, sizes, lists, &p->blocks, err);
done:
    free(sizes), free(flat), free(lists);
    return r;
}

static btf_result btf__parse_ranges(const cJSON *c, const char *key, int nb, float **out, const char *path, int id,
                                    btf_error *err)
{
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(c, key);
    if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != nb)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"%s\" must have %d entries", path, id, key, nb);
    *out = malloc((size_t)nb * 2 * sizeof(float));
    if (!*out)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    for (int b = 0; b < nb; b++) {
        const cJSON *e = cJSON_GetArrayItem(a, b);
        const cJSON *lo = cJSON_GetArrayItem(e, 0), *st = cJSON_GetArrayItem(e, 1);
        if (cJSON_GetArraySize(e) != 2 || !cJSON_IsNumber(lo) || !cJSON_IsNumber(st) || !isfinite(lo->valuedouble) ||
            !isfinite(st->valuedouble) || st->valuedouble < 0 || fabs(lo->valuedouble) > 1e30 ||
            st->valuedouble > 1e30)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: bad \"%s\" entry %d", path, id, key, b);
        (*out)[2 * b] = (float)lo->valuedouble;
        (*out)[2 * b + 1] = (float)st->valuedouble;
    }
    return BTF_OK;
}

/* Decodes standard base64 (no line breaks, '=' padding) into exactly n bytes; 0 on any error. */
static int btf__base64(const char *s, uint8_t *out, size_t n)
{
    static const char A[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t len = strlen(s), k = 0;
    if (len != (n + 2) / 3 * 4)
        return 0;
    for (size_t i = 0; i < len; i += 4) {
        unsigned v = 0;
        int pad = 0;
        for (int j = 0; j < 4; j++) {
            const char *q = s[i + j] ? strchr(A, s[i + j]) : NULL;
            if (s[i + j] == '=' && i + 4 == len && j >= 2)
                pad++, q = A;
            else if (!q || pad)
                return 0;
            v = v << 6 | (unsigned)(q - A);
        }
        for (int j = 0; j < 3 - pad; j++)
            if (k < n)
                out[k++] = (uint8_t)(v >> (16 - 8 * j));
    }
    return k == n;
}

/* Version 2: ranges of component `comp` from the header's "ranges" (one base64
 * string per component of n_blocks x float32 LE {tex_lo, tex_step, wt_lo, wt_step}). */
static btf_result btf__component_ranges(const cJSON *ranges, btf_chunk_info *ci, int nb, const char *path, int id,
                                        btf_error *err)
{
    const cJSON *s = cJSON_GetArrayItem(ranges, ci->component);
    size_t n = (size_t)nb * 16;
    uint8_t *raw = malloc(n);
    ci->tex_range = malloc((size_t)nb * 2 * sizeof(float));
    ci->wt_range = malloc((size_t)nb * 2 * sizeof(float));
    if (!raw || !ci->tex_range || !ci->wt_range) {
        free(raw);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    }
    int ok = cJSON_IsString(s) && btf__base64(s->valuestring, raw, n);
    for (int b = 0; ok && b < nb; b++)
        for (int j = 0; j < 4; j++) {
            const uint8_t *q = raw + 16 * b + 4 * j;
            uint32_t u = (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24;
            float x;
            memcpy(&x, &u, sizeof x);
            ok = ok && isfinite(x) && fabsf(x) <= 1e30f && (j % 2 == 0 || x >= 0.0f);
            (j < 2 ? ci->tex_range : ci->wt_range)[2 * b + j % 2] = x;
        }
    free(raw);
    return ok ? BTF_OK
              : btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"ranges\" entry %d is not %zu base64 bytes of finite ranges",
                         path, id, ci->component, n);
}

static btf_result btf__parse_chunk(const cJSON *c, const cJSON *root, btf_package *p, int id, const char *path,
                                   btf_error *err)
{
    const cJSON *ranges = cJSON_GetObjectItemCaseSensitive(root, "ranges");
    btf_chunk_info *ci = &p->chunk[id];
    int cid;
    if (!cJSON_IsObject(c) || !btf__get_int(c, "id", id, id, &cid) ||
        !btf__get_int(c, "component", 0, p->n_comp - 1, &ci->component))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: missing or wrong \"id\"/\"component\"", path, id);
    const cJSON *f = cJSON_GetObjectItemCaseSensitive(c, "files");
    int nf = cJSON_GetArraySize(f);
    if (!cJSON_IsArray(f) || nf < 1 || nf > BTF_PACKAGE_MAX_FILES)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: bad \"files\"", path, id);
    ci->n_files = nf;
    for (int i = 0; i < nf; i++) {
        const cJSON *s = cJSON_GetArrayItem(f, i);
        if (!cJSON_IsString(s) || !btf__valid_name(s->valuestring))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: file %d has an invalid name", path, id, i);
        snprintf(ci->files[i], BTF_PACKAGE_NAME_MAX, "%s", s->valuestring);
    }
    ci->level = 0;
    if (p->version >= 2 && !btf__get_int(c, "level", 0, p->n_levels - 1, &ci->level))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: missing or wrong \"level\"", path, id);
    const cJSON *v = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "weights8_step"), ci->component);
    ci->wt8_step = 257.0;
    if (v && (!cJSON_IsNumber(v) || !(v->valuedouble >= 0.0 && v->valuedouble <= 65535.0)))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: bad \"weights8_step\" of component %d", path, id,
                        ci->component);
    if (v && v->valuedouble >= 1.0)
        ci->wt8_step = v->valuedouble;
    if ((v = cJSON_GetObjectItemCaseSensitive(c, "contrib")) && cJSON_IsNumber(v) && isfinite(v->valuedouble))
        ci->contrib = v->valuedouble;
    if ((v = cJSON_GetObjectItemCaseSensitive(c, "bytes")) && cJSON_IsNumber(v))
        ci->bytes = (long long)v->valuedouble;
    struct { const char *k; double *d; } nums[] = {{"rmse", &ci->rmse}, {"lab", &ci->lab}, {"psnr", &ci->psnr},
                                                   {"delta_e76", &ci->delta_e76}, {"rmse_float", &ci->rmse_float}};
    for (size_t i = 0; i < sizeof nums / sizeof nums[0]; i++)
        if ((v = cJSON_GetObjectItemCaseSensitive(c, nums[i].k)) && cJSON_IsNumber(v))
            *nums[i].d = v->valuedouble;
    if (p->version >= 2 && !cJSON_GetObjectItemCaseSensitive(c, "tex_range"))
        return btf__component_ranges(ranges, ci, p->blocks->n_blocks, path, id, err);
    btf_result r = btf__parse_ranges(c, "tex_range", p->blocks->n_blocks, &ci->tex_range, path, id, err);
    if (r == BTF_OK)
        r = btf__parse_ranges(c, "wt_range", p->blocks->n_blocks, &ci->wt_range, path, id, err);
    return r;
}

static btf_result btf__parse_header(const cJSON *m, btf_package *p, const char *path, btf_error *err)
{
    const cJSON *fmt = cJSON_GetObjectItemCaseSensitive(m, "format");
    int version;
    if (!cJSON_IsString(fmt) || strcmp(fmt->valuestring, "btf-package") != 0)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"format\" is not \"btf-package\"", path);
    if (!btf__get_int(m, "version", 1, 2, &version))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: unsupported \"version\" (this reader knows 1 and 2)", path);
    p->version = version;
    p->n_levels = 1;
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    snprintf(p->name, sizeof p->name, "%s", cJSON_IsString(name) ? name->valuestring : "");
    if (!btf__get_int(m, "width", 1, BTF_MAX_SIDE, &p->width) || !btf__get_int(m, "height", 1, BTF_MAX_SIDE, &p->height))
        return btf_fail(err, BTF_ERR_RANGE, "%s: \"width\"/\"height\" missing or outside 1..%d", path, BTF_MAX_SIDE);
    btf_result r = btf__parse_rings(m, "lights", path, &p->lights, err);
    if (r == BTF_OK)
        r = btf__parse_rings(m, "views", path, &p->views, err);
    if (r != BTF_OK)
        return r;
    if (!btf__get_int(m, "components", 1, BTF_PACKAGE_MAX_CHUNKS, &p->n_comp) ||
        !btf__get_int(m, "bits", 8, 16, &p->bits) || (p->bits != 8 && p->bits != 16))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"components\" or \"bits\" missing or invalid", path);
    if (!btf__get_int(m, "k", 1, p->views.n_dirs, &p->k))
        p->k = 0;
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(m, "center");
    p->center = cJSON_IsString(c) && !strcmp(c->valuestring, "row") ? BTF_CENTER_ROW : BTF_CENTER_NONE;
    c = cJSON_GetObjectItemCaseSensitive(m, "grouping");
    p->grouping = cJSON_IsString(c) && !strcmp(c->valuestring, "spatial") ? BTF_GROUP_SPATIAL : BTF_GROUP_CONSECUTIVE;
    r = btf__parse_blocks(m, p, path, err);
    if (r != BTF_OK)
        return r;
    const cJSON *at = cJSON_GetObjectItemCaseSensitive(m, "atlas");
    int tw, th, ch, aw, ah;
    if (!btf__get_int(at, "cols", 1, 4096, &p->atlas_cols) || !btf__get_int(at, "rows", 1, 4096, &p->atlas_rows) ||
        !btf__get_int(at, "tile_width", p->width, p->width, &tw) ||
        !btf__get_int(at, "tile_height", p->height, p->height, &th) ||
        !btf__get_int(at, "channels", p->bits == 16 ? 3 : 1, p->bits == 16 ? 3 : 1, &ch) ||
        !btf__get_int(at, "width", p->atlas_cols * tw, p->atlas_cols * tw, &aw) ||
        !btf__get_int(at, "height", p->atlas_rows * th, p->atlas_rows * th, &ah) ||
        (long)p->atlas_cols * p->atlas_rows < p->blocks->n_blocks)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"atlas\" is inconsistent with the size and block count", path);
    if (version == 2 && (!btf__get_int(m, "levels", 1, 15, &p->n_levels) ||
                         p->width % (1 << (p->n_levels - 1)) || p->height % (1 << (p->n_levels - 1))))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"levels\" missing, outside 1..15 or not dividing %dx%d", path,
                        p->width, p->height);
    return BTF_OK;
}

static char *btf__read_text(const char *path, btf_result *res, btf_error *err)
{
    FILE *f = fopen(path, "rb");
    *res = BTF_ERR_IO;
    if (!f) {
        *res = btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: cannot open (%s)", path,
                        strerror(errno));
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    if (n < 0 || n > BTF__MANIFEST_MAX) {
        fclose(f);
        *res = btf_fail(err, BTF_ERR_RANGE, "%s: size %ld is not a plausible manifest", path, n);
        return NULL;
    }
    char *s = malloc((size_t)n + 1);
    if (!s || fread(s, 1, (size_t)n, f) != (size_t)n) {
        free(s);
        fclose(f);
        btf_fail(err, BTF_ERR_IO, "%s: read failed", path);
        return NULL;
    }
    s[n] = 0;
    fclose(f);
    return s;
}

/* The file of chunk ci ending in ext; weights = 1: only names starting "wt-", 0: only others, -1: any. */
static const char *btf__chunk_file(const btf_chunk_info *ci, const char *ext, int weights)
{
    for (int i = 0; i < ci->n_files; i++) {
        size_t n = strlen(ci->files[i]), e = strlen(ext);
        if (n > e && !strcmp(ci->files[i] + n - e, ext) &&
            (weights < 0 || !strncmp(ci->files[i], "wt-", 3) == !!weights))
            return ci->files[i];
    }
    return NULL;
}

/* Version 2 coarse weights (doc/package-format.md section 10): an 8-bit grey PNG of
 * 3L x V pixels, Wt = lo + wt8_step * step * q with the 16-bit [lo, step]. */
static btf_result btf__load_weights8(const btf_package *p, const char *dir, int i, const char *wf, float *wt,
                                     btf_error *err)
{
    int L = p->lights.n_dirs, V = p->views.n_dirs, w, h, ch;
    char path[4200];
    uint8_t *px = NULL;
    snprintf(path, sizeof path, "%s/%s", dir, wf);
    btf_result r = btf_image_read_u8(path, &w, &h, &ch, &px, err);
    if (r != BTF_OK)
        return r;
    if (w != 3 * L || h != V || ch != 1) {
        free(px);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %dx%d with %d channels, expected %dx%d grey", path, w, h, ch, 3 * L, V);
    }
    for (size_t k = 0; k < (size_t)V * L * 3; k++) {
        const float *rg = p->chunk[i].wt_range + 2 * p->blocks->block_of_view[k / (3 * (size_t)L)];
        wt[k] = rg[0] + (float)p->chunk[i].wt8_step * rg[1] * (float)px[k];
    }
    free(px);
    return BTF_OK;
}

/* Weights of chunk i (dequantised) from its .bin file into wt (V*L*3 floats). */
static btf_result btf__load_weights(const btf_package *p, const char *dir, int i, const char *wf, float *wt,
                                    btf_error *err)
{
    const btf_chunk_info *ci = &p->chunk[i];
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    size_t nwt = (size_t)V * L * 3;
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, wf);
    uint8_t *raw = malloc(2 * nwt);
    if (!raw)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    long long sz = btf__file_size(path);
    FILE *f = sz == (long long)(2 * nwt) ? fopen(path, "rb") : NULL;
    if (!f || fread(raw, 1, 2 * nwt, f) != 2 * nwt) {
        if (f)
            fclose(f);
        free(raw);
        if (sz < 0)
            return btf_fail(err, BTF_ERR_MISSING, "%s: missing", path);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %lld bytes, expected %zu", path, sz, 2 * nwt);
    }
    fclose(f);
    for (size_t k = 0; k < nwt; k++) {
        int v = (int)(k / (3 * (size_t)L));
        wt[k] = btf__deq(ci->wt_range + 2 * p->blocks->block_of_view[v], (unsigned)raw[2 * k] | ((unsigned)raw[2 * k + 1] << 8));
    }
    free(raw);
    return BTF_OK;
}

/* Version 2: a chunk without weights reuses the latest weights of its component. */
static btf_result btf__shared_weights(const btf_package *p, int i, float *wt, btf_error *err)
{
    for (int e = i - 1; e >= 0; e--)
        if (p->chunk[e].component == p->chunk[i].component && p->wt[e]) {
            memcpy(wt, p->wt[e], (size_t)p->views.n_dirs * p->lights.n_dirs * 3 * sizeof(float));
            return BTF_OK;
        }
    return btf_fail(err, BTF_ERR_FORMAT, "chunk %d lists no .bin weights and no earlier chunk of component %d does",
                    i, p->chunk[i].component);
}

/* Loads chunk i's texture (its level's size) and weights (dequantised). */
static btf_result btf__load_chunk(btf_package *p, const char *dir, int i, btf_error *err)
{
    const btf_chunk_info *ci = &p->chunk[i];
    const char *tf = btf__chunk_file(ci, ".png", 0), *wf = btf__chunk_file(ci, ".bin", -1);
    const char *w8 = p->version >= 2 && !wf ? btf__chunk_file(ci, ".png", 1) : NULL;
    char path[4200];
    if (!tf || (!wf && p->version < 2))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d lists no .png texture or no .bin weights", dir, i);
    int nb = p->blocks->n_blocks, W = p->width >> ci->level, H = p->height >> ci->level;
    int ch_want = p->bits == 16 ? 3 : 1, w, h, ch;
    uint8_t *px = NULL;
    snprintf(path, sizeof path, "%s/%s", dir, tf);
    btf_result r = btf_image_read_u8(path, &w, &h, &ch, &px, err);
    if (r != BTF_OK)
        return r;
    if (w != p->atlas_cols * W || h != p->atlas_rows * H || ch != ch_want) {
        free(px);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %dx%d with %d channels, manifest says %dx%d with %d", path, w, h,
                        ch, p->atlas_cols * W, p->atlas_rows * H, ch_want);
    }
    float *tex = malloc((size_t)nb * W * H * sizeof(float));
    float *wt = malloc((size_t)p->views.n_dirs * p->lights.n_dirs * 3 * sizeof(float));
    if (!tex || !wt) {
        free(px), free(tex), free(wt);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    }
    for (int b = 0; b < nb; b++) {
        const float *rg = ci->tex_range + 2 * b;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                const uint8_t *q = px + ((size_t)((b / p->atlas_cols) * H + y) * w + (size_t)((b % p->atlas_cols) * W + x)) * ch;
                unsigned v = p->bits == 16 ? (unsigned)q[0] * 256u + q[1] : q[0];
                tex[((size_t)b * H + y) * W + x] = btf__deq(rg, v);
            }
    }
    free(px);
    r = wf ? btf__load_weights(p, dir, i, wf, wt, err)
       : w8 ? btf__load_weights8(p, dir, i, w8, wt, err)
            : btf__shared_weights(p, i, wt, err);
    if (r != BTF_OK) {
        free(tex), free(wt);
        return r;
    }
    for (int e = 0; wf && e < i; e++) /* finer weights replace the coarse ones of earlier levels */
        if (p->chunk[e].component == ci->component)
            memcpy(p->wt[e], wt, (size_t)p->views.n_dirs * p->lights.n_dirs * 3 * sizeof(float));
    p->tex[i] = tex;
    p->wt[i] = wt;
    p->n_loaded = i + 1;
    return BTF_OK;
}

static int btf__chunk_present(const btf_package *p, const char *dir, int i)
{
    char path[4200];
    for (int f = 0; f < p->chunk[i].n_files; f++) {
        snprintf(path, sizeof path, "%s/%s", dir, p->chunk[i].files[f]);
        if (btf__file_size(path) < 0)
            return 0;
    }
    return 1;
}

btf_result btf_package_read(const char *dir, int n, btf_package **out, btf_error *err)
{
    *out = NULL;
    if (!dir || strlen(dir) > 4000)
        return btf_fail(err, BTF_ERR_ARG, "package: no directory");
    char path[4200];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    btf_result rr;
    char *text = btf__read_text(path, &rr, err);
    if (!text)
        return rr;
    cJSON *m = cJSON_Parse(text);
    free(text);
    if (!m)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not valid JSON", path);
    btf_package *p = calloc(1, sizeof *p);
    btf_result r = p ? btf__parse_header(m, p, path, err) : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    const cJSON *chunks = cJSON_GetObjectItemCaseSensitive(m, "chunks");
    int nc = cJSON_GetArraySize(chunks);
    if (r == BTF_OK && (!cJSON_IsArray(chunks) || nc < 1 || nc > BTF_PACKAGE_MAX_CHUNKS))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: \"chunks\" must list 1..%d chunks", path, BTF_PACKAGE_MAX_CHUNKS);
    if (r == BTF_OK) {
        p->chunk = calloc((size_t)nc, sizeof *p->chunk);
        p->tex = calloc((size_t)nc, sizeof *p->tex);
        p->wt = calloc((size_t)nc, sizeof *p->wt);
        if (!p->chunk || !p->tex || !p->wt)
            r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
        else
            p->n_chunks = nc;
    }
    for (int i = 0; r == BTF_OK && i < nc; i++)
        r = btf__parse_chunk(cJSON_GetArrayItem(chunks, i), m, p, i, path, err);
    cJSON_Delete(m);
    if (r == BTF_OK && n > nc)
        r = btf_fail(err, BTF_ERR_RANGE, "%s: %d chunks requested, the package has %d", dir, n, nc);
    int want = n == 0 ? nc : n;
    if (n < 0) {
        want = 0;
        while (r == BTF_OK && want < nc && btf__chunk_present(p, dir, want))
            want++;
        if (r == BTF_OK && want == 0)
            r = btf_fail(err, BTF_ERR_MISSING, "%s: the files of chunk 0 are missing", dir);
    }
    for (int i = 0; r == BTF_OK && i < want; i++)
        r = btf__load_chunk(p, dir, i, err);
    if (r != BTF_OK) {
        btf_package_free(p);
        return r;
    }
    *out = p;
    return BTF_OK;
}

/* ---------------------------------------------------------------- reconstruction */

void btf_package_value(const btf_package *p, int view, int light, int x, int y, int n, float rgb[3])
{
    if (n <= 0 || n > p->n_loaded)
        n = p->n_loaded;
    int b = p->blocks->block_of_view[view];
    size_t ti = ((size_t)b * p->height + y) * p->width + x, wi = ((size_t)view * p->lights.n_dirs + light) * 3;
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    for (int j = 0; j < n; j++) {
        /* version 2: each component once, at its finest loaded level (upsampled) */
        if (p->n_levels > 1 && btf_lod_chunk_at(p, n, p->chunk[j].component, 0) != j)
            continue;
        float t = p->n_levels > 1 ? btf_lod_texel(p, j, b, x, y) : p->tex[j][ti];
        rgb[0] += t * p->wt[j][wi];
        rgb[1] += t * p->wt[j][wi + 1];
        rgb[2] += t * p->wt[j][wi + 2];
    }
}

btf_result btf_package_reconstruct(const btf_package *p, int n, btf **out, btf_error *err)
{
    btf *b = NULL;
    btf_result r = btf_create(p->width, p->height, &p->lights, &p->views, BTF_F32, &b, err);
    if (r != BTF_OK)
        return r;
    float *d = b->data;
    for (int v = 0; v < p->views.n_dirs; v++)
        for (int l = 0; l < p->lights.n_dirs; l++)
            for (int y = 0; y < p->height; y++)
                for (int x = 0; x < p->width; x++)
                    btf_package_value(p, v, l, x, y, n, d + btf_index(b, v, l, x, y, 0));
    *out = b;
    return BTF_OK;
}
