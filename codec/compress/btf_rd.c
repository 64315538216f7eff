/* btf_rd.c - equal-slope choice of the quantisation steps (btf_rd.h,
 * doc/package-format.md section 10.8): measured rate and distortion of every
 * candidate step multiplier (and with lossy, every lossy WebP quality) per
 * component, then one Lagrange multiplier. */
#include "btf_rd.h"

#include <cblas.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "btf_lossy.h"
#include "btf_webp.h"
#include "btf_wtz.h"
#include "btf_common.h"
#include "btf_blocks.h"
#include "btf_package.h"

#define BTF__RD_TEX_LO (-8) /* texture ladder: tex_noise * 2^(i/2), i = LO..HI */
#define BTF__RD_TEX_HI 6
#define BTF__RD_WT_LO (-10) /* weight ladder: the full 16 bits, then tex_noise * 2^(i/2) */
#define BTF__RD_WT_HI 6
#define BTF__RD_NT (BTF__RD_TEX_HI - BTF__RD_TEX_LO + 1)
/* texture rates are encoded at the even ladder indices (the equal-noise step among
 * them) and interpolated between them, so both ends must be even */
_Static_assert(BTF__RD_TEX_LO % 2 == 0 && BTF__RD_NT % 2 == 1, "texture ladder: even equal-noise index and ends");
#define BTF__RD_NW (BTF__RD_WT_HI - BTF__RD_WT_LO + 2)
/* weight rates are encoded at index 0 (16 bits) and the odd noise steps, interpolated
 * at the even ones between, so the last step must be odd */
_Static_assert(BTF__RD_NW % 2 == 0, "weight ladder: its last noise step at an odd index");
#define BTF__RD_RATE_TILES 9 /* texture rates measured on whole atlas rows holding about this many tiles */
/* Lossy levels beside the lossless steps (btf_rd_params.lossy: btf_lossy_ladder of its
 * encoding): the candidates NT .. NT + NQ - 1 of each component's texture ladder,
 * full-range 8-bit codes. */
#define BTF__RD_NQ BTF_LOSSY_LADDER
/* Lossy weights (with lossy textures: btf_rd_params.lossy_weights):
 * the candidates NW .. NW + NQW - 1 of each component's weight ladder, its weights as a
 * lossy WebP of full-range 8-bit codes (btf_rd_wt_lossy) at the WebP ladder's levels. */
#define BTF__RD_NQW BTF_LOSSY_LADDER
#define BTF__RD_REFINE_PASSES 8 /* choices at most, each after measuring what the last chose interpolated */
_Static_assert(BTF__RD_NQ % 2 == 1, "lossy ladder: both ends at even levels, encoded");
_Static_assert(BTF__RD_NQW % 2 == 1, "lossy weight ladder: both ends at even levels, encoded");

/* Measured candidates of one allocation; lives for one btf_rd_allocate call. */
typedef struct btf__rd {
    const btf_rd_params *par;
    const btf_pca_model *m;
    int C, nb, W, H, rows, L, V, aw;
    int nt;                /* texture candidates per component: NT lossless steps, then NQ lossy qualities with lossy */
    int nw;                /* weight candidates per component: NW steps, then NQW lossy qualities with lossy weights */
    int ch;                /* atlas channels: 1 (8-bit codes) or 3 (16-bit: high, low, 0) */
    unsigned qmax;         /* the largest texture code: 255 or 65535 */
    int *sub_row;          /* per atlas row of tiles: its row in the rate sample, -1 = not sampled */
    int sub_rows;          /* tile rows in the rate sample (its atlas is aw x sub_rows * H) */
    double rate_scale;     /* tiles of the atlas / tiles in the sample */
    double *dt, *dw;       /* C x nt, C x NW: added squared error */
    double *energy;        /* C: |T_j W_j^T|^2 summed over blocks: the error of leaving j out */
    long long *rt, *rw;    /* the same: bytes */
    float *gt, *gw;        /* the ladders' noise values */
    float *wnorm;          /* C x nb: |W_j| per block (computed before the threads start) */
    /* C x nt, C x NW: 1 = the step is measured (near a previous choice, par->near);
     * NULL = every step. An unmeasured step's error is infinite: never chosen. */
    unsigned char *mt, *mw;
    /* C x nt, C x NW: 1 = an interpolated candidate measured since (btf__rd_refine) */
    unsigned char *exact_t, *exact_w;
    int *prev_view; /* V: each view's predecessor in its block (btf_wtz_prev_views), for wt-JJ.pz */
} btf__rd;

/* The rate sample: whole rows of the atlas's tile grid, evenly spaced among the full
 * ones, about BTF__RD_RATE_TILES tiles (all rows when the grid has no more). A row
 * keeps its neighbours and its width, so its files deflate as in the whole atlas;
 * the texture rates are the sample's bytes times rate_scale. 0, or -1 without memory. */
static int btf__rd_sample(btf__rd *r)
{
    int cols = r->par->atlas_cols, rows = r->par->atlas_rows, full = r->nb / cols;
    int want = (BTF__RD_RATE_TILES + cols - 1) / cols;
    r->sub_row = malloc(sizeof(int) * (size_t)rows);
    if (!r->sub_row)
        return -1;
    if (full < 1 || want >= full) { /* too few rows to choose from: every row */
        for (int i = 0; i < rows; i++)
            r->sub_row[i] = i;
        r->sub_rows = rows, r->rate_scale = 1.0;
        return 0;
    }
    for (int i = 0; i < rows; i++)
        r->sub_row[i] = -1;
    for (int i = 0; i < want; i++)
        r->sub_row[(int)(((double)i + 0.5) * full / want)] = i;
    r->sub_rows = want, r->rate_scale = (double)r->nb / ((double)want * cols);
    return 0;
}

/* Texture of component j at noise g: the rate sample's atlas into atlas (aw x
 * sub_rows * H pixels of ch bytes), the added squared error of every block returned
 * (and block b's, before its weights' factor, into eb[b] when eb is not NULL). */
static double btf__rd_tex(const btf__rd *r, int j, float g, uint8_t *atlas, double *eb)
{
    double d = 0.0;
    memset(atlas, 0, (size_t)r->aw * r->sub_rows * r->H * r->ch);
    for (int b = 0; b < r->nb; b++) {
        const btf_pca_block *pb = &r->m->block[b];
        const float *t = pb->t + (size_t)j * r->rows;
        float wn = r->wnorm[(size_t)j * r->nb + b], rg[2];
        btf_rd_range(t, (size_t)r->rows, r->qmax, rg);
        rg[1] = btf_rd_step(rg[1], g, pb->cols, wn);
        int sub = r->sub_row[b / r->par->atlas_cols];
        int tx0 = (b % r->par->atlas_cols) * r->W, ty0 = sub * r->H;
        double e = 0.0;
        for (int y = 0; y < r->H; y++)
            for (int x = 0; x < r->W; x++) {
                float v = t[(size_t)y * r->W + x];
                unsigned qv = btf_rd_quant(v, rg, r->qmax);
                uint8_t *px = atlas + ((size_t)(ty0 + y) * r->aw + (size_t)(tx0 + x)) * r->ch;
                if (sub >= 0 && r->ch == 3)
                    px[0] = (uint8_t)(qv >> 8), px[1] = (uint8_t)(qv & 255u);
                else if (sub >= 0)
                    px[0] = (uint8_t)qv;
                double dv = (double)v - (double)(rg[0] + rg[1] * (float)qv);
                e += dv * dv;
            }
        if (eb)
            eb[b] = e;
        d += e * (double)wn * (double)wn;
    }
    return d;
}

/* Weights of component j at noise g (0 = full 16 bits): q (V*L*3) filled, the added squared error returned. */
static double btf__rd_wt(btf__rd *r, int j, float g, uint16_t *q)
{
    const btf_blocks *bl = r->m->blocks;
    double d = 0.0;
    for (int b = 0; b < r->nb; b++) {
        const btf_pca_block *pb = &r->m->block[b];
        const float *wj = pb->w + (size_t)j * pb->cols;
        float tn = cblas_snrm2(r->rows, pb->t + (size_t)j * r->rows, 1), rg[2];
        btf_rd_range(wj, (size_t)pb->cols, 65535u, rg);
        rg[1] = btf_rd_step(rg[1], g, r->rows, tn);
        double e = 0.0;
        if (g == 0.0f) /* once per component: its energy */
            r->energy[j] += (double)tn * tn * (double)cblas_snrm2(pb->cols, wj, 1) * cblas_snrm2(pb->cols, wj, 1);
        for (int col = 0; col < pb->cols; col++) {
            int pos = col / (3 * r->L), l = (col / 3) % r->L, c = col % 3;
            int v = bl->views[bl->start[b] + pos];
            unsigned qv = btf_rd_quant(wj[col], rg, 65535u);
            q[((size_t)v * r->L + l) * 3 + c] = (uint16_t)qv;
            double dv = (double)wj[col] - (double)(rg[0] + rg[1] * (float)qv);
            e += dv * dv;
        }
        d += e * (double)tn * (double)tn;
    }
    return d;
}

/* 1 when texture candidate i (0 .. nt-1) is interpolated, not encoded: an odd lossy
 * level (its rate and error) or an odd lossless step (its rate; its error is exact). */
static int btf__rd_tex_interpolated(int i)
{
    return (i < BTF__RD_NT ? i : i - BTF__RD_NT) % 2 == 1;
}

/* 1 when weight candidate i (0 .. nw-1) has its rate interpolated: an even noise step
 * between the first and the last (its error is exact), or an odd lossy level (its
 * rate and error). */
static int btf__rd_wt_interpolated(int i)
{
    return i >= BTF__RD_NW ? (i - BTF__RD_NW) % 2 == 1 : i > 1 && i < BTF__RD_NW - 1 && i % 2 == 0;
}

/* Candidates i of one component's ladder (rate, with d its error too; mask NULL or the
 * measured ones) where interp(i), each between two encoded ones: the mean of the
 * neighbours' rates (about linear in the log of the step, or in a lossy level), with d
 * the geometric mean of their errors. */
static void btf__rd_interpolate(long long *rate, double *d, const unsigned char *mask, int from, int to,
                                int (*interp)(int))
{
    for (int i = from; i < to; i++)
        if (interp(i) && (!mask || mask[i])) { /* its neighbours are measured too */
            rate[i] = (rate[i - 1] + rate[i + 1] + 1) / 2;
            if (d)
                d[i] = sqrt(d[i - 1] * d[i + 1]);
        }
}

/* The rate of weights q (V*L*3) as the writer keeps them (btf_wtz_encode_smaller);
 * -1 with an error in e. */
static long long btf__rd_wt_rate(const btf__rd *r, const uint16_t *q, btf_error *e)
{
    uint8_t *z = NULL;
    size_t nz = 0;
    int kind = 0;
    btf_result res = btf_wtz_encode_smaller(q, r->V, r->L, r->prev_view, !r->par->png_only, &z, &nz, &kind, e);
    free(z);
    return res != BTF_OK ? -1 : (long long)nz;
}

/* The squared error component j's texture adds when its full-range atlas (the rate
 * sample's in atlas, each block's rounding error in eb) decodes to dec: exact on the
 * sampled blocks; on the others their rounding error plus the sample's mean lossy
 * error per texel (q units, (dec - q)^2) at their step, the two nearly uncorrelated. */
static double btf__rd_lossy_dist(const btf__rd *r, int j, const uint8_t *atlas, const uint8_t *dec, double *eb)
{
    double lossy = 0.0, d = 0.0;
    long long n = 0;
    for (int b = 0; b < r->nb; b++) { /* the sampled blocks: exact, into eb[b] */
        int sub = r->sub_row[b / r->par->atlas_cols];
        if (sub < 0)
            continue;
        const float *t = r->m->block[b].t + (size_t)j * r->rows;
        float rg[2];
        btf_rd_range(t, (size_t)r->rows, 255u, rg);
        size_t o = (size_t)sub * r->H * r->aw + (size_t)(b % r->par->atlas_cols) * r->W;
        double e = 0.0;
        for (int y = 0; y < r->H; y++)
            for (int x = 0; x < r->W; x++) {
                size_t px = o + (size_t)y * r->aw + x;
                double dq = (double)dec[px] - (double)atlas[px];
                double dv = (double)t[(size_t)y * r->W + x] - (double)(rg[0] + rg[1] * (float)dec[px]);
                lossy += dq * dq, e += dv * dv;
            }
        eb[b] = e, n += r->rows;
    }
    lossy = n ? lossy / (double)n : 0.0;
    for (int b = 0; b < r->nb; b++) { /* the others: their rounding error plus the mean lossy error */
        double wn = r->wnorm[(size_t)j * r->nb + b], e = eb[b];
        if (r->sub_row[b / r->par->atlas_cols] < 0) {
            float rg[2];
            btf_rd_range(r->m->block[b].t + (size_t)j * r->rows, (size_t)r->rows, 255u, rg);
            e += lossy * (double)rg[1] * (double)rg[1] * (double)r->rows;
        }
        d += e * wn * wn;
    }
    return d;
}

/* Lossy candidate n (component j, ladder index i - NT): the rate sample's full-range
 * atlas as a lossy WebP or AVIF (par->lossy), decoded as a reader decodes it; its bytes times rate_scale and
 * its error into r->rt, r->dt. buf: the thread's atlas-sized scratch for the decode,
 * eb its nb doubles. */
static btf_result btf__rd_lossy_candidate(btf__rd *r, int n, uint8_t *atlas, uint8_t *buf, double *eb, btf_error *err)
{
    int j = n / r->nt, ah = r->sub_rows * r->H;
    btf__rd_tex(r, j, 0.0f, atlas, eb);
    uint8_t *file = NULL;
    size_t nw = 0;
    int codec = r->par->lossy;
    btf_result res = btf_lossy_encode(codec, atlas, r->aw, ah, btf_lossy_ladder(codec, n % r->nt - BTF__RD_NT), &file,
                                      &nw, err);
    if (res == BTF_OK)
        res = btf_lossy_decode(file, nw, "rate-distortion: lossy candidate", r->aw, ah, buf, err);
    free(file);
    if (res != BTF_OK)
        return res;
    r->dt[n] = btf__rd_lossy_dist(r, j, atlas, buf, eb);
    r->rt[n] = (long long)llround((double)nw * r->rate_scale);
    return BTF_OK;
}

/* Rate and distortion of texture candidate n = j * nt + i into r->rt, r->dt: the rate
 * sample's atlas encoded as the package writes it, times rate_scale: its lossless
 * WebP bytes, or with png_only or 16-bit codes its PNG's (filter Up), encoded in
 * memory. atlas is the thread's own buffer. */
static btf_result btf__rd_tex_candidate(btf__rd *r, int n, uint8_t *atlas, uint8_t *buf, double *eb, btf_error *err)
{
    if (r->mt && !r->mt[n]) {
        r->dt[n] = INFINITY, r->rt[n] = 0;
        return BTF_OK;
    }
    int interp = btf__rd_tex_interpolated(n % r->nt); /* rates from btf__rd_measure_tex */
    if (n % r->nt >= BTF__RD_NT)
        return interp ? BTF_OK : btf__rd_lossy_candidate(r, n, atlas, buf, eb, err);
    r->dt[n] = btf__rd_tex(r, n / r->nt, r->gt[n % r->nt], atlas, NULL);
    if (interp)
        return BTF_OK;
    int ah = r->sub_rows * r->H;
    uint8_t *f = NULL;
    size_t nf = 0;
    btf_result res = !r->par->png_only && r->ch == 1
                         ? btf_webp_encode_grey(atlas, r->aw, ah, &f, &nf, err)
                         : btf_image_encode("rd-candidate.png", r->aw, ah, r->ch, 8, atlas, BTF_IMAGE_PNG_UP, &f, &nf, err);
    free(f);
    r->rt[n] = res != BTF_OK ? -1 : (long long)llround((double)nf * r->rate_scale);
    return res;
}

btf_result btf_rd_wt_lossy(const btf_pca_model *m, int j, int quality, float *ranges, uint16_t *q, uint8_t **file,
                           size_t *n, btf_error *err)
{
    const btf_blocks *bl = m->blocks;
    int L = m->lights.n_dirs, V = m->views.n_dirs;
    size_t np = (size_t)V * L * 3;
    uint8_t *rgb = malloc(np);
    *file = NULL, *n = 0;
    if (!rgb)
        return btf_fail(err, BTF_ERR_NOMEM, "weights: out of memory (lossy)");
    for (int b = 0; b < bl->n_blocks; b++) {
        const btf_pca_block *pb = &m->block[b];
        const float *wj = pb->w + (size_t)j * pb->cols;
        float *rg = ranges + 2 * b;
        btf_rd_range(wj, (size_t)pb->cols, 255u, rg);
        for (int col = 0; col < pb->cols; col++) {
            int pos = col / (3 * L), l = (col / 3) % L, c = col % 3;
            int v = bl->views[bl->start[b] + pos];
            rgb[((size_t)v * L + l) * 3 + c] = (uint8_t)btf_rd_quant(wj[col], rg, 255u);
        }
    }
    btf_result r = btf_webp_encode_rgb_lossy(rgb, L, V, quality, file, n, err);
    if (r == BTF_OK)
        r = btf_webp_decode_rgb(*file, *n, "weights: lossy candidate", L, V, rgb, err);
    for (size_t i = 0; r == BTF_OK && i < np; i++)
        q[i] = rgb[i];
    if (r != BTF_OK)
        free(*file), *file = NULL, *n = 0;
    free(rgb);
    return r;
}

/* Lossy weight candidate i (NW .. nw - 1) of component j: its file's bytes and the
 * squared error its decode adds (each block's weight errors times its texture's norm
 * squared, as btf__rd_wt counts them) into r->rw, r->dw; q: the thread's V*L*3 scratch. */
static btf_result btf__rd_wt_lossy_candidate(btf__rd *r, int j, int i, uint16_t *q, btf_error *err)
{
    const btf_blocks *bl = r->m->blocks;
    float *rg = malloc(sizeof(float) * 2 * (size_t)r->nb);
    uint8_t *file = NULL;
    size_t n = 0;
    btf_result res = rg ? btf_rd_wt_lossy(r->m, j, btf_lossy_ladder(BTF_LOSSY_WEBP, i - BTF__RD_NW), rg, q, &file, &n, err)
                        : btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (lossy weights)");
    double d = 0.0;
    for (int b = 0; res == BTF_OK && b < r->nb; b++) {
        const btf_pca_block *pb = &r->m->block[b];
        const float *wj = pb->w + (size_t)j * pb->cols;
        float tn = cblas_snrm2(r->rows, pb->t + (size_t)j * r->rows, 1);
        double e = 0.0;
        for (int col = 0; col < pb->cols; col++) {
            int pos = col / (3 * r->L), l = (col / 3) % r->L, c = col % 3;
            int v = bl->views[bl->start[b] + pos];
            double dv = (double)wj[col] - (double)btf_package_dequant(rg + 2 * b, q[((size_t)v * r->L + l) * 3 + c]);
            e += dv * dv;
        }
        d += e * (double)tn * (double)tn;
    }
    r->dw[(size_t)j * r->nw + i] = res == BTF_OK ? d : INFINITY;
    r->rw[(size_t)j * r->nw + i] = (long long)n;
    free(rg), free(file);
    return res;
}

/* A thread's result into *res and its message into err, unless an error is there
 * already (called inside the critical section that ends each parallel region). */
static void btf__rd_first_error(btf_result mine, const btf_error *e, btf_result *res, btf_error *err)
{
    if (mine != BTF_OK && *res == BTF_OK) {
        *res = mine;
        if (err)
            *err = *e;
    }
}

/* 1 when r's ladders are measured on OpenMP's threads (BTF_RD_THREAD_MIN_BYTES):
 * the bytes of every component's atlas and 16-bit weights. */
static int btf__rd_threaded(const btf__rd *r)
{
    size_t atlas = (size_t)r->aw * (size_t)r->par->atlas_rows * (size_t)r->H;
    size_t weights = (size_t)r->V * (size_t)r->L * 3u * sizeof(uint16_t);
    return (size_t)r->C * (atlas + weights) >= BTF_RD_THREAD_MIN_BYTES;
}

/* The candidate of task n: the lossy candidates of every component first, then the
 * lossless steps, so that the long encodes do not come last. */
static int btf__rd_task(const btf__rd *r, int n)
{
    int nq = r->nt - BTF__RD_NT;
    if (n < r->C * nq)
        return (n / nq) * r->nt + BTF__RD_NT + n % nq;
    n -= r->C * nq;
    return (n / BTF__RD_NT) * r->nt + n % BTF__RD_NT;
}

/* What measuring a candidate needs: the weights' norms, the rate sample and the
 * views' predecessors (the writer keeps the smaller of wt-JJ.z and wt-JJ.pz). */
static btf_result btf__rd_prepare(btf__rd *r, btf_error *err)
{
    if (r->wnorm)
        return BTF_OK;
    r->prev_view = malloc((size_t)r->V * sizeof *r->prev_view);
    if (!r->prev_view)
        return btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (views)");
    btf_wtz_prev_views(r->m->blocks->block_of_view, r->V, r->prev_view);
    r->wnorm = malloc(sizeof(float) * (size_t)r->C * (size_t)r->nb);
    if (!r->wnorm)
        return btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (norms)");
    for (int j = 0; j < r->C; j++)
        for (int b = 0; b < r->nb; b++)
            r->wnorm[(size_t)j * r->nb + b] =
                cblas_snrm2(r->m->block[b].cols, r->m->block[b].w + (size_t)j * r->m->block[b].cols, 1);
    if (btf__rd_sample(r) != 0)
        return btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (rate sample)");
    if (r->par->tex_rate_scale > 0.0)
        r->rate_scale *= r->par->tex_rate_scale;
    return BTF_OK;
}

/* Every texture candidate, on OpenMP's threads (PNG encoding is most of the cost). */
static btf_result btf__rd_measure_tex(btf__rd *r, btf_error *err)
{
    btf_result res = btf__rd_prepare(r, err);
    if (res != BTF_OK)
        return res;
#pragma omp parallel if (btf__rd_threaded(r))
    {
        size_t sz = (size_t)r->aw * r->sub_rows * r->H * r->ch;
        uint8_t *atlas = malloc(sz), *buf = r->nt > BTF__RD_NT ? malloc(sz) : NULL;
        double *eb = r->nt > BTF__RD_NT ? malloc(sizeof(double) * (size_t)r->nb) : NULL;
        btf_error e = {{0}};
        btf_result mine = atlas && (r->nt == BTF__RD_NT || (buf && eb))
                              ? BTF_OK
                              : btf_fail(&e, BTF_ERR_NOMEM, "rate-distortion: out of memory (atlas)");
#pragma omp for schedule(dynamic, 1)
        for (int n = 0; n < r->C * r->nt; n++) /* lossy ones first: the longest encodes */
            if (mine == BTF_OK)
                mine = btf__rd_tex_candidate(r, btf__rd_task(r, n), atlas, buf, eb, &e);
#pragma omp critical(btf__rd_result)
        btf__rd_first_error(mine, &e, &res, err);
        free(atlas), free(buf), free(eb);
    }
    /* odd lossless steps: their rates (the package comes out nearly as with every
     * step encoded, at half the encodings); odd lossy levels: rates and errors, at 7
     * encodings of the 13 (doc/package-format.md section 10.8) */
    for (int j = 0; res == BTF_OK && j < r->C; j++) {
        size_t o = (size_t)j * r->nt;
        const unsigned char *mask = r->mt ? r->mt + o : NULL;
        btf__rd_interpolate(r->rt + o, NULL, mask, 1, BTF__RD_NT - 1, btf__rd_tex_interpolated);
        btf__rd_interpolate(r->rt + o, r->dt + o, mask, BTF__RD_NT + 1, r->nt - 1, btf__rd_tex_interpolated);
    }
    return res;
}

/* Every candidate of every component: rates and distortions. */
static btf_result btf__rd_measure(btf__rd *r, btf_error *err)
{
    btf_result res = btf__rd_measure_tex(r, err);
    if (res != BTF_OK)
        return res;
#pragma omp parallel if (btf__rd_threaded(r))
    { /* one component's weight steps per thread at a time: energy[j] has one writer */
        uint16_t *q = malloc((size_t)r->V * r->L * 3 * sizeof(uint16_t));
        btf_error e = {{0}};
        btf_result mine = q ? BTF_OK : btf_fail(&e, BTF_ERR_NOMEM, "rate-distortion: out of memory (weights)");
#pragma omp for schedule(dynamic, 1)
        for (int j = 0; j < r->C; j++)
            for (int i = 0; i < r->nw && mine == BTF_OK; i++) {
                if (r->mw && !r->mw[(size_t)j * r->nw + i]) {
                    r->dw[(size_t)j * r->nw + i] = INFINITY, r->rw[(size_t)j * r->nw + i] = 0;
                    continue;
                }
                if (i >= BTF__RD_NW) { /* an odd level's rate and error interpolated below */
                    mine = btf__rd_wt_interpolated(i) ? BTF_OK : btf__rd_wt_lossy_candidate(r, j, i, q, &e);
                    continue;
                }
                r->dw[(size_t)j * r->nw + i] = btf__rd_wt(r, j, r->gw[i], q);
                if (btf__rd_wt_interpolated(i))
                    continue; /* the rate interpolated below */
                long long rate = btf__rd_wt_rate(r, q, &e);
                mine = rate < 0 ? BTF_ERR_NOMEM : BTF_OK;
                r->rw[(size_t)j * r->nw + i] = rate;
            }
#pragma omp critical(btf__rd_result)
        btf__rd_first_error(mine, &e, &res, err);
        free(q);
    }
    /* even noise steps 2 .. NW-2: their rates, at 10 zlib passes (each of both
     * codings) of the 18; odd lossy levels: rates and errors, at 7 encodings of 13 */
    for (int j = 0; res == BTF_OK && j < r->C; j++) {
        size_t o = (size_t)j * r->nw;
        const unsigned char *mask = r->mw ? r->mw + o : NULL;
        btf__rd_interpolate(r->rw + o, NULL, mask, 1, BTF__RD_NW - 1, btf__rd_wt_interpolated);
        btf__rd_interpolate(r->rw + o, r->dw + o, mask, BTF__RD_NW + 1, r->nw - 1, btf__rd_wt_interpolated);
    }
    return res;
}

/* Index in 0..n-1 minimising d + lambda * rate. */
static int btf__rd_best(const double *d, const long long *rate, int n, double lambda)
{
    int best = 0;
    for (int i = 1; i < n; i++)
        if (d[i] + lambda * (double)rate[i] < d[best] + lambda * (double)rate[best])
            best = i;
    return best;
}

/* Manifest bytes of a version-3 package with n chunks (an estimate for the byte
 * budget: the header's ranges of 16 bytes per block and chunk in base64, the chunk's
 * other fields, plus the header). */
static long long btf__rd_manifest_bytes(const btf__rd *r, int n)
{
    return 2048 + (long long)n * (150 + 22LL * r->nb) + 8LL * r->V;
}

/* Total quantisation distortion and bytes at slope lambda; choices into it, iw when
 * not NULL. With keep: *keep = components whose energy exceeds D + lambda R
 * (component 0 always), bytes counted for those only (plus the manifest). */
static double btf__rd_at(const btf__rd *r, double lambda, int *it, int *iw, long long *bytes, int *keep)
{
    double d = 0.0;
    long long s = 0;
    int kept = 0;
    for (int j = 0; j < r->C; j++) {
        int a = btf__rd_best(r->dt + (size_t)j * r->nt, r->rt + (size_t)j * r->nt, r->nt, lambda);
        int b = btf__rd_best(r->dw + (size_t)j * r->nw, r->rw + (size_t)j * r->nw, r->nw, lambda);
        double dj = r->dt[(size_t)j * r->nt + a] + r->dw[(size_t)j * r->nw + b];
        long long sj = r->rt[(size_t)j * r->nt + a] + r->rw[(size_t)j * r->nw + b];
        d += dj;
        if (!keep || j == 0 || dj + lambda * (double)sj < r->energy[j])
            s += sj, kept++;
        if (it)
            it[j] = a, iw[j] = b;
    }
    if (keep)
        *keep = kept, s += btf__rd_manifest_bytes(r, kept);
    if (bytes)
        *bytes = s;
    return d;
}

/* With lossy candidates, the candidate of a ladder (n errors d and rates s) after a on
 * the way to less error: of those with less error than a, the one removing the most
 * error per byte added (fewer bytes: at once); -1 when none has less. */
static int btf__rd_next(const double *d, const long long *s, int n, int a)
{
    int best = -1;
    double bg = 0.0;
    for (int i = 0; i < n; i++) {
        if (!(d[i] < d[a]))
            continue;
        double g = s[i] > s[a] ? (d[a] - d[i]) / (double)(s[i] - s[a]) : INFINITY;
        if (best < 0 || g > bg || (g == bg && d[i] < d[best]))
            best = i, bg = g;
    }
    return best;
}

/* One ladder notch finer for component j (tex: texture, else weights) from choice *at:
 * the error it removes and the bytes it adds, the candidate into *to; 0 when already
 * at the finest step. */
static int btf__rd_notch(const btf__rd *r, int j, int tex, const int *at, double *dd, long long *ds, int *to)
{
    int n = tex ? r->nt : r->nw, a = *at;
    const double *d = (tex ? r->dt : r->dw) + (size_t)j * n;
    const long long *s = (tex ? r->rt : r->rw) + (size_t)j * n;
    *to = n > (tex ? BTF__RD_NT : BTF__RD_NW) ? btf__rd_next(d, s, n, a) : a - 1;
    if (*to < 0)
        return 0;
    *dd = d[a] - d[*to], *ds = s[*to] - s[a];
    return 1;
}

/* With a byte budget: what lambda's choice leaves of max_bytes, spent one ladder notch
 * finer at a time where the measured error drop per byte is largest (the ladder is
 * discrete, so the bisected slope alone stops short of the budget). Components that
 * lambda left out stay out; *bytes is kept the way btf__rd_at counts it. */
static void btf__rd_fill(const btf__rd *r, double lambda, long long max_bytes, int *it, int *iw, long long *bytes)
{
    unsigned char *kept = malloc((size_t)r->C);
    if (!kept)
        return; /* lambda's choice stands */
    for (int j = 0; j < r->C; j++) { /* as btf__rd_at decided at lambda */
        double dj = r->dt[(size_t)j * r->nt + it[j]] + r->dw[(size_t)j * r->nw + iw[j]];
        long long sj = r->rt[(size_t)j * r->nt + it[j]] + r->rw[(size_t)j * r->nw + iw[j]];
        kept[j] = j == 0 || dj + lambda * (double)sj < r->energy[j];
    }
    for (;;) {
        int bj = -1, btex = 0, bto = 0;
        double best = 0.0;
        long long bds = 0;
        for (int j = 0; j < r->C; j++)
            for (int tex = 0; tex < 2 && kept[j]; tex++) {
                double dd = 0.0;
                long long ds = 0;
                int to = 0;
                if (!btf__rd_notch(r, j, tex, tex ? &it[j] : &iw[j], &dd, &ds, &to) || !(dd > 0.0) ||
                    *bytes + ds > max_bytes)
                    continue;
                double gain = ds > 0 ? dd / (double)ds : INFINITY;
                if (gain > best)
                    best = gain, bj = j, btex = tex, bds = ds, bto = to;
            }
        if (bj < 0)
            break;
        (btex ? it : iw)[bj] = bto;
        *bytes += bds;
    }
    free(kept);
}

/* Index of the ladder step g nearest to noise v (by ratio; v <= 0: index 0, the
 * weights' full 16 bits, when g[0] is 0). */
static int btf__rd_nearest(const float *g, int n, float v)
{
    int best = 0;
    double bd = INFINITY;
    for (int i = 0; i < n; i++) {
        double d = g[i] > 0.0f && v > 0.0f ? fabs(log((double)g[i] / v)) : g[i] == v ? 0.0 : INFINITY;
        if (d < bd)
            bd = d, best = i;
    }
    return best;
}

/* With par->near: component j's lossy candidates to measure, near a lossy choice of
 * quality q (within BTF_RD_NEAR_NOTCHES of it); when it chose a lossless step (q < 0),
 * the finest levels (within twice as many notches of the finest), which border the
 * lossless steps: a component lossless on the centre window can be lossy on the
 * whole material (doc/package-format.md section 11.4). */
static void btf__rd_near_lossy(btf__rd *r, int j, int q)
{
    int lossless = q < 0, a = lossless ? BTF__RD_NQ - 1 : -1;
    for (int i = 0, c = r->par->lossy; !lossless && i < BTF__RD_NQ; i++)
        a = a < 0 || abs(btf_lossy_ladder(c, i) - q) < abs(btf_lossy_ladder(c, a) - q) ? i : a;
    int lo = a - BTF_RD_NEAR_NOTCHES * (lossless ? 2 : 1), hi = a + BTF_RD_NEAR_NOTCHES; /* widened to even ends, encoded */
    lo = lo < 0 ? 0 : lo - (lo % 2), hi = hi >= BTF__RD_NQ ? BTF__RD_NQ - 1 : hi + (hi % 2);
    for (int i = 0; i < r->nt - BTF__RD_NT; i++)
        r->mt[(size_t)j * r->nt + BTF__RD_NT + i] = a >= 0 && i >= lo && i <= hi;
}

/* With par->near (at most as many components): the masks of the steps to measure.
 * For its components those within BTF_RD_NEAR_NOTCHES of its choices (widened to
 * ends whose rates are encoded: even texture steps and lossy levels, odd weight
 * steps) and the references (the
 * equal-noise texture step, the 16-bit weights); every step of the others. Steps
 * outside a range stay out of btf__rd_fill's notches too. 0, or -1 without memory. */
static int btf__rd_near(btf__rd *r)
{
    const btf_rd_result *nr = r->par->near;
    if (!nr || nr->n_comp < 1 || nr->n_comp > r->C || !nr->tex_noise || !nr->wt_noise)
        return 0;
    r->mt = malloc((size_t)r->C * r->nt), r->mw = malloc((size_t)r->C * r->nw);
    if (!r->mt || !r->mw)
        return -1;
    memset(r->mt, 1, (size_t)r->C * r->nt), memset(r->mw, 1, (size_t)r->C * r->nw);
    for (int j = 0; j < nr->n_comp; j++) {
        int a = btf__rd_nearest(r->gt, BTF__RD_NT, nr->tex_noise[j]);
        int lo = a - BTF_RD_NEAR_NOTCHES, hi = a + BTF_RD_NEAR_NOTCHES;
        lo = lo < 0 ? 0 : lo - (lo % 2), hi = hi >= BTF__RD_NT ? BTF__RD_NT - 1 : hi + (hi % 2);
        for (int i = 0; i < BTF__RD_NT; i++)
            r->mt[(size_t)j * r->nt + i] = (i >= lo && i <= hi) || i == -BTF__RD_TEX_LO;
        btf__rd_near_lossy(r, j, nr->tex_quality ? nr->tex_quality[j] : -1);
        int b = btf__rd_nearest(r->gw, BTF__RD_NW, nr->wt_noise[j]); /* lossy weights: every level measured */
        int wlo = b - BTF_RD_NEAR_NOTCHES, whi = b + BTF_RD_NEAR_NOTCHES; /* widened to encoded ends */
        wlo = wlo < 1 ? 0 : wlo - !(wlo % 2), whi = whi >= BTF__RD_NW - 1 ? BTF__RD_NW - 1 : whi + !(whi % 2);
        for (int i = 0; i < BTF__RD_NW; i++)
            r->mw[(size_t)j * r->nw + i] = (i >= wlo && i <= whi) || i == 0;
    }
    return 0;
}

/* What identifies r's model for btf_rd_ladder: its sizes, the noise and file choice
 * of the ladders, and a sum over every block's first texel and weights. */
static void btf__rd_key(const btf__rd *r, double key[8])
{
    double sum = 0.0;
    for (int b = 0; b < r->nb; b++)
        for (int j = 0; j < r->C; j++) {
            const btf_pca_block *pb = &r->m->block[b];
            sum += (double)pb->t[(size_t)j * r->rows] * (j + 1) + (double)pb->w[(size_t)j * pb->cols] * (b + 1);
        }
    double k[8] = {r->C, r->nb, r->W, r->H, (double)r->V * 65536.0 + r->L, r->par->tex_noise,
                   r->par->png_only + 2.0 * r->ch + 8.0 * r->nt + 1024.0 * r->nw, sum};
    memcpy(key, k, sizeof k);
}

/* The ladders of r: from par->ladder when it holds this model's, else measured (and
 * stored there when there is one). */
static btf_result btf__rd_ladder_use(btf__rd *r, btf_error *err)
{
    btf_rd_ladder *l = r->par->ladder;
    double key[8];
    btf__rd_key(r, key);
    size_t nt = (size_t)r->C * r->nt, nw = (size_t)r->C * r->nw, c = (size_t)r->C;
    if (l && l->n_comp == r->C && !memcmp(l->key, key, sizeof key)) {
        memcpy(r->dt, l->dt, nt * sizeof(double)), memcpy(r->rt, l->rt, nt * sizeof(long long));
        memcpy(r->dw, l->dw, nw * sizeof(double)), memcpy(r->rw, l->rw, nw * sizeof(long long));
        memcpy(r->energy, l->energy, c * sizeof(double));
        return BTF_OK;
    }
    if (btf__rd_near(r) != 0)
        return btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (near steps)");
    btf_result res = btf__rd_measure(r, err);
    if (res != BTF_OK || !l || r->mt)
        return res;
    btf_rd_ladder_free(l);
    l->dt = malloc(nt * sizeof(double)), l->rt = malloc(nt * sizeof(long long));
    l->dw = malloc(nw * sizeof(double)), l->rw = malloc(nw * sizeof(long long));
    l->energy = malloc(c * sizeof(double));
    if (!l->dt || !l->rt || !l->dw || !l->rw || !l->energy) {
        btf_rd_ladder_free(l); /* no reuse next time; this allocation goes on */
        return BTF_OK;
    }
    memcpy(l->dt, r->dt, nt * sizeof(double)), memcpy(l->rt, r->rt, nt * sizeof(long long));
    memcpy(l->dw, r->dw, nw * sizeof(double)), memcpy(l->rw, r->rw, nw * sizeof(long long));
    memcpy(l->energy, r->energy, c * sizeof(double));
    memcpy(l->key, key, sizeof key);
    l->n_comp = r->C, l->n_tex = r->nt, l->n_wt = r->nw;
    return BTF_OK;
}

void btf_rd_ladder_free(btf_rd_ladder *l)
{
    if (!l)
        return;
    free(l->dt), free(l->dw), free(l->energy), free(l->rt), free(l->rw);
    memset(l, 0, sizeof *l);
}

void btf_rd_result_free(btf_rd_result *r)
{
    if (!r)
        return;
    free(r->tex_noise), free(r->wt_noise), free(r->comp_bytes), free(r->tex_bytes), free(r->tex_quality);
    free(r->wt_quality);
    memset(r, 0, sizeof *r);
}

static void btf__rd_free(btf__rd *r)
{
    free(r->dt), free(r->dw), free(r->energy), free(r->rt), free(r->rw), free(r->gt), free(r->gw), free(r->wnorm);
    free(r->sub_row), free(r->mt), free(r->mw), free(r->exact_t), free(r->exact_w), free(r->prev_view);
}

/* The factor par->tex_rate_fix puts on the rate of every texture candidate of
 * component j. */
static double btf__rd_rate_factor(const btf__rd *r, int j)
{
    double f = r->par->tex_rate_fix ? r->par->tex_rate_fix[j] : 1.0;
    return f > 0.0 && isfinite(f) ? f : 1.0;
}

/* Those factors applied to the texture rates in use (the ladder keeps them as
 * measured); a step not measured (negative rate) stays so. */
static void btf__rd_fix_rates(btf__rd *r)
{
    for (int j = 0; j < r->C; j++)
        for (int i = 0; i < r->nt; i++) {
            long long *s = &r->rt[(size_t)j * r->nt + i];
            double f = btf__rd_rate_factor(r, j);
            *s = *s < 0 || f == 1.0 ? *s : llround((double)*s * f);
        }
}

/* The chosen candidates (it, iw) whose rates (and a lossy level's error) were
 * interpolated, measured now (an odd lossy level, of a texture or of weights,
 * encoded and decoded, an even weight step coded both ways), so that what the
 * allocation chooses is what the writer writes; returns how many, -1 on an error (in
 * err). The lossless texture steps keep their interpolated odd rates, as before. */
static int btf__rd_refine(btf__rd *r, const int *it, const int *iw, btf_error *err)
{
    if (btf__rd_prepare(r, err) != BTF_OK) /* a ladder reused from par->ladder measured nothing here */
        return -1;
    size_t sz = (size_t)r->aw * r->sub_rows * r->H * r->ch;
    uint8_t *atlas = malloc(sz), *buf = malloc(sz);
    double *eb = malloc(sizeof(double) * (size_t)r->nb);
    uint16_t *q = malloc((size_t)r->V * r->L * 3 * sizeof(uint16_t));
    int n = 0;
    if (!r->exact_t)
        r->exact_t = calloc((size_t)r->C * r->nt, 1), r->exact_w = calloc((size_t)r->C * r->nw, 1);
    if (!atlas || !buf || !eb || !q || !r->exact_t || !r->exact_w)
        n = -1, btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (refine)");
    for (int j = 0; n >= 0 && j < r->C; j++) {
        size_t t = (size_t)j * r->nt + it[j], w = (size_t)j * r->nw + iw[j];
        if (it[j] >= BTF__RD_NT && btf__rd_tex_interpolated(it[j]) && !r->exact_t[t]) {
            if (btf__rd_lossy_candidate(r, (int)t, atlas, buf, eb, err) != BTF_OK)
                n = -1;
            else
                r->rt[t] = llround((double)r->rt[t] * btf__rd_rate_factor(r, j)), r->exact_t[t] = 1, n++;
        }
        if (n >= 0 && iw[j] >= BTF__RD_NW && btf__rd_wt_interpolated(iw[j]) && !r->exact_w[w]) {
            n = btf__rd_wt_lossy_candidate(r, j, iw[j], q, err) != BTF_OK ? -1 : n + 1, r->exact_w[w] = 1;
        } else if (n >= 0 && btf__rd_wt_interpolated(iw[j]) && !r->exact_w[w]) {
            btf__rd_wt(r, j, r->gw[iw[j]], q);
            r->rw[w] = btf__rd_wt_rate(r, q, err);
            n = r->rw[w] < 0 ? -1 : n + 1, r->exact_w[w] = 1;
        }
    }
    free(atlas), free(buf), free(eb), free(q);
    return n;
}

/* One choice over r's candidates as measured: the Lagrange multiplier (bisection in
 * its log) for par->max_bytes or for out->d_target, the steps it picks into it, iw
 * and out->lambda, d_rd, bytes_rd, n_kept. */
static void btf__rd_choose(const btf__rd *r, btf_rd_result *out, int *it, int *iw)
{
    const btf_rd_params *par = r->par;
    double lo = -60.0, hi = 10.0;
    for (int k = 0; k < 80; k++) { /* bisection in log lambda */
        double mid = 0.5 * (lo + hi);
        long long bytes = 0;
        int kept = 0;
        if (par->max_bytes > 0) { /* the smallest slope whose kept components fit */
            btf__rd_at(r, exp(mid), NULL, NULL, &bytes, &kept);
            *(bytes <= par->max_bytes ? &hi : &lo) = mid;
        } else { /* the largest slope adding no more error than the reference */
            *(btf__rd_at(r, exp(mid), NULL, NULL, NULL, NULL) <= out->d_target ? &lo : &hi) = mid;
        }
    }
    out->lambda = exp(par->max_bytes > 0 ? hi : lo);
    out->n_kept = r->C;
    out->d_rd = btf__rd_at(r, out->lambda, it, iw, &out->bytes_rd, par->max_bytes > 0 ? &out->n_kept : NULL);
    if (par->max_bytes > 0 && out->bytes_rd <= par->max_bytes) {
        btf__rd_fill(r, out->lambda, par->max_bytes, it, iw, &out->bytes_rd);
        out->d_rd = 0.0;
        for (int j = 0; j < r->C; j++)
            out->d_rd += r->dt[(size_t)j * r->nt + it[j]] + r->dw[(size_t)j * r->nw + iw[j]];
    }
}

btf_result btf_rd_allocate(const btf_rd_params *par, btf_rd_result *out, btf_error *err)
{
    memset(out, 0, sizeof *out);
    const btf_pca_model *m = par->model;
    if (!m || !(par->tex_noise > 0.0f) || par->atlas_cols < 1 || par->atlas_rows < 1 ||
        (long)par->atlas_cols * par->atlas_rows < m->blocks->n_blocks)
        return btf_fail(err, BTF_ERR_ARG, "rate-distortion: needs a model, tex_noise > 0 and an atlas grid");
    btf__rd r = {0};
    r.par = par, r.m = m, r.C = m->n_comp, r.nb = m->blocks->n_blocks, r.W = m->width, r.H = m->height;
    r.rows = r.W * r.H, r.L = m->lights.n_dirs, r.V = m->views.n_dirs;
    r.aw = par->atlas_cols * r.W;
    r.ch = par->bits == 16 ? 3 : 1, r.qmax = par->bits == 16 ? 65535u : 255u;
    if (par->bits != 0 && par->bits != 8 && par->bits != 16)
        return btf_fail(err, BTF_ERR_ARG, "rate-distortion: %d-bit textures (8 or 16)", par->bits);
    r.nt = BTF__RD_NT + (par->lossy && r.ch == 1 && !par->png_only ? BTF__RD_NQ : 0);
    r.nw = BTF__RD_NW + (par->lossy_weights && !par->png_only ? BTF__RD_NQW : 0);
    r.dt = calloc((size_t)r.C * r.nt, sizeof(double));
    r.dw = calloc((size_t)r.C * r.nw, sizeof(double));
    r.energy = calloc((size_t)r.C, sizeof(double));
    r.rt = calloc((size_t)r.C * r.nt, sizeof(long long));
    r.rw = calloc((size_t)r.C * r.nw, sizeof(long long));
    r.gt = calloc(BTF__RD_NT, sizeof(float)), r.gw = calloc(BTF__RD_NW, sizeof(float));
    out->tex_noise = calloc((size_t)r.C, sizeof(float));
    out->wt_noise = calloc((size_t)r.C, sizeof(float));
    out->comp_bytes = calloc((size_t)r.C, sizeof(long long));
    out->tex_bytes = calloc((size_t)r.C, sizeof(long long));
    out->tex_quality = calloc((size_t)r.C, sizeof(int));
    out->wt_quality = calloc((size_t)r.C, sizeof(int));
    int *it = calloc((size_t)r.C, sizeof(int)), *iw = calloc((size_t)r.C, sizeof(int));
    btf_result res = BTF_OK;
    if (!r.dt || !r.dw || !r.energy || !r.rt || !r.rw || !r.gt || !r.gw || !out->tex_noise || !out->wt_noise ||
        !out->comp_bytes || !out->tex_bytes || !out->tex_quality || !out->wt_quality || !it || !iw)
        res = btf_fail(err, BTF_ERR_NOMEM, "rate-distortion: out of memory (%d components)", r.C);
    for (int i = 0; res == BTF_OK && i < BTF__RD_NT; i++)
        r.gt[i] = par->tex_noise * powf(2.0f, 0.5f * (float)(BTF__RD_TEX_LO + i));
    for (int i = 1; res == BTF_OK && i < BTF__RD_NW; i++) /* gw[0] = 0: the full 16-bit range */
        r.gw[i] = par->tex_noise * powf(2.0f, 0.5f * (float)(BTF__RD_WT_LO + i - 1));
    if (res == BTF_OK)
        res = btf__rd_ladder_use(&r, err);
    if (res == BTF_OK)
        btf__rd_fix_rates(&r);
    if (res == BTF_OK) {
        /* reference: every texture at tex_noise (ladder index -LO), 16-bit weights (index 0) */
        out->d_target = 0.0, out->bytes_equal = 0;
        for (int j = 0; j < r.C; j++) {
            out->d_target += r.dt[(size_t)j * r.nt - BTF__RD_TEX_LO] + r.dw[(size_t)j * r.nw];
            out->bytes_equal += r.rt[(size_t)j * r.nt - BTF__RD_TEX_LO] + r.rw[(size_t)j * r.nw];
        }
        for (int pass = 0; res == BTF_OK && pass < BTF__RD_REFINE_PASSES; pass++) {
            btf__rd_choose(&r, out, it, iw);
            int n = btf__rd_refine(&r, it, iw, err);
            if (n < 0)
                res = BTF_ERR_NOMEM;
            if (n <= 0)
                break;
        }
        out->n_comp = r.C;
        for (int j = 0; j < r.C; j++) {
            int lossy = it[j] >= BTF__RD_NT; /* full-range codes, a lossy file */
            int wlossy = iw[j] >= BTF__RD_NW; /* full-range codes, a lossy file */
            out->tex_noise[j] = lossy ? 0.0f : r.gt[it[j]], out->wt_noise[j] = wlossy ? 0.0f : r.gw[iw[j]];
            out->wt_quality[j] = wlossy ? btf_lossy_ladder(BTF_LOSSY_WEBP, iw[j] - BTF__RD_NW) : -1;
            out->tex_quality[j] = lossy ? btf_lossy_ladder(par->lossy, it[j] - BTF__RD_NT) : -1;
            out->tex_bytes[j] = r.rt[(size_t)j * r.nt + it[j]];
            out->comp_bytes[j] = out->tex_bytes[j] + r.rw[(size_t)j * r.nw + iw[j]];
        }
    }
    free(it), free(iw);
    btf__rd_free(&r);
    if (res != BTF_OK)
        btf_rd_result_free(out);
    return res;
}
