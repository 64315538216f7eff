/* btf_lod.c - spatial levels of a package (version 2 of doc/package-format.md,
 * section 10): the builder (v1 package -> v2 with per-component mip levels); what the
 * readers use (the texel look-up between levels, the chunk selection) is btf_lod_select.c. */
#include "btf_lod.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "btf_lap.h"
#include "btf_manifest.h"
#include "btf_png.h"
#include "btf_lossy.h"
#include "btf_lod_error.h"
#include "btf_webp.h"
#include "btf_wtz.h"
#include "btf_common.h"
#include "btf_read.h"

/* ---------------------------------------------------------------- builder */

#define BTF__LOD_PATH 8400 /* a file path in the output's temporary directory */

/* State of one btf_lod_build call. Index a = position of the component in the v1
 * chunk order; [a * nl + l] = its level l. */
typedef struct btf__lod {
    btf_package *p; /* the complete v1 package (owned) */
    int nl, nb, C, W, H, ch, qmax;
    int resid;       /* 1: version 4, levels < nl-1 may be stored as residuals */
    char *isres;     /* [a*nl+l] version 4: 1 when that level's file is a residual (the smaller coding) */
    char *kind;      /* [a*nl+l] version 4: that level file's encoding: 0 PNG, 1 (BTF_LOSSY_WEBP) a WebP (lossless
                      * and smaller than the PNG, or lossy), 2 (BTF_LOSSY_AVIF) an AVIF (lossy); level 0's lossy
                      * file is copied from a version-3 source */
    int webp;        /* version 4 without btf_lod_options.png_only: each texture file the smaller of PNG and WebP */
    int *quality;    /* [a] version 4 from a version-3 source whose level 0 is a lossy WebP or AVIF: that file's
                      * level (the source's "rd" record), which the coarse levels start from; -1: lossless levels */
    btf_views *src;  /* btf_lod_options.source: the package's source, or NULL (the caller's) */
    const btf_lod_gather *gather; /* btf_lod_options.gather: src's references, or NULL (the caller's) */
    uint8_t **exact; /* [a*nl+l] l >= 1 with quality[a] >= 0: the level's atlas codes before lossy coding */
    int *codec;      /* [a] with quality[a] >= 0: level 0's encoding (BTF_LOSSY_WEBP or BTF_LOSSY_AVIF) */
    uint8_t **lossy; /* [a*nl+l] l >= 1 with quality[a] >= 0: the level's lossy file (its decode is
                      * the level's atlas and texels), NULL otherwise */
    size_t *lossy_n; /* [a*nl+l] bytes of lossy[a*nl+l] */
    btf_lap_pred *pred; /* [a*nl+l] version 4: the residual's predictor (btf_lap_pred_fit) */
    char *w16res;    /* [a] version 4: the 16-bit weights' coding (BTF__W16_*, the smallest kept) */
    int *prev_view;  /* [v] each view's predecessor in its block (btf_wtz_prev_views), for wt-JJ.pz */
    double thr;
    float **lev;     /* [a*nl+l] dequantised texels, nb * Wl * Hl; level 0 borrowed from p->tex */
    uint8_t **atlas; /* [a*nl+l] atlas pixels for l >= 1 */
    double *contrib; /* [a*nl+l] */
    long long *tbytes, *wbytes; /* [a*nl+l] texture file bytes; [a] weight file bytes */
    long long *w8bytes;         /* [a] 8-bit weight file bytes (0: none, the first chunk is level 0) */
    int *w8step;                /* [a] step multiplier s_c of the 8-bit weights (btf__w8_step) */
    uint8_t **w8q;              /* [a] the 8-bit weights written (V*L*3), NULL when none */
    unsigned char *w8webp;      /* [a] version 4: 1 = they are wt-JJ-8.webp (smaller than the PNG), 0 = wt-JJ-8.png */
    int *order;      /* n_chunks * 2: (a, l) in chunk order */
    int n_order;
    double *rmse_full; /* per chunk: RMSE against the complete package */
} btf__lod;

static void btf__lod_free(btf__lod *s)
{
    for (int i = 0; s->lev && i < s->C * s->nl; i++) {
        if (i % s->nl)
            free(s->lev[i]);
        if (s->atlas)
            free(s->atlas[i]);
    }
    for (int i = 0; s->lossy && i < s->C * s->nl; i++)
        free(s->lossy[i]);
    for (int i = 0; s->exact && i < s->C * s->nl; i++)
        free(s->exact[i]);
    free(s->lossy), free(s->lossy_n), free(s->quality), free(s->codec), free(s->exact);
    free(s->lev), free(s->atlas), free(s->contrib), free(s->tbytes), free(s->wbytes), free(s->order);
    for (int a = 0; s->w8q && a < s->C; a++)
        free(s->w8q[a]);
    free(s->w8bytes), free(s->w8step), free(s->w8q), free(s->w8webp), free(s->isres), free(s->kind), free(s->w16res), free(s->pred);
    free(s->prev_view);
    free(s->rmse_full);
    btf_package_free(s->p);
}

int btf_lod_levels(int W, int H, int want)
{
    int nl = 1;
    while (nl < BTF_LOD_MAX_LEVELS && (want > 0 ? nl < want : nl < 4 && (W >> nl) >= 8 && (H >> nl) >= 8) &&
           W % (1 << nl) == 0 && H % (1 << nl) == 0)
        nl++;
    return nl;
}

/* 2x2 box average of the exact previous level into ex (nb tiles of w x h, w = 2 * next). */
static void btf__box(const float *prev, int nb, int w, int h, float *next)
{
    int w2 = w / 2, h2 = h / 2;
    for (int b = 0; b < nb; b++)
        for (int y = 0; y < h2; y++)
            for (int x = 0; x < w2; x++) {
                const float *t = prev + (size_t)b * w * h + (size_t)(2 * y) * w + 2 * x;
                next[(size_t)b * w2 * h2 + (size_t)y * w2 + x] = 0.25f * ((t[0] + t[1]) + (t[w] + t[w + 1]));
            }
}

/* Level l of component a's texels (s->lev) from its atlas codes (s->atlas) and the v1 ranges. */
static void btf__dequant_level(btf__lod *s, int a, int l)
{
    const btf_package *p = s->p;
    int w = s->W >> l, h = s->H >> l, aw = p->atlas_cols * w;
    float *dq = s->lev[a * s->nl + l];
    const uint8_t *px = s->atlas[a * s->nl + l];
    for (int b = 0; b < s->nb; b++) {
        const float *rg = p->chunk[a].tex_range + 2 * b;
        int x0 = (b % p->atlas_cols) * w, y0 = (b / p->atlas_cols) * h;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const uint8_t *o = px + ((size_t)(y0 + y) * aw + (size_t)(x0 + x)) * s->ch;
                unsigned q = s->ch == 3 ? (unsigned)o[0] << 8 | o[1] : o[0];
                dq[(size_t)b * w * h + (size_t)y * w + x] = btf_package_dequant(rg, q);
            }
    }
}

/* Quantises level l of component a from the exact values ex with the v1 ranges. */
static void btf__quant_level(btf__lod *s, int a, int l, const float *ex)
{
    const btf_package *p = s->p;
    int w = s->W >> l, h = s->H >> l, aw = p->atlas_cols * w;
    uint8_t *px = s->atlas[a * s->nl + l];
    for (int b = 0; b < s->nb; b++) {
        const float *rg = p->chunk[a].tex_range + 2 * b;
        int x0 = (b % p->atlas_cols) * w, y0 = (b / p->atlas_cols) * h;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t i = (size_t)b * w * h + (size_t)y * w + x;
                float qf = rg[1] > 0.0f ? rintf((ex[i] - rg[0]) / rg[1]) : 0.0f;
                unsigned q = qf <= 0.0f ? 0u : qf >= (float)s->qmax ? (unsigned)s->qmax : (unsigned)qf;
                uint8_t *o = px + ((size_t)(y0 + y) * aw + (size_t)(x0 + x)) * s->ch;
                if (s->ch == 3)
                    o[0] = (uint8_t)(q >> 8), o[1] = (uint8_t)(q & 255u);
                else
                    o[0] = (uint8_t)q;
            }
    }
    btf__dequant_level(s, a, l);
}

/* Component a's level-0 quality (a WebP quality, or an AVIF quantiser, finer as it
 * falls) as a position on its codec's fine ladder (btf_lossy_fine), coarse to fine:
 * the first rung at least as fine. */
static int btf__ladder_top(const btf__lod *s, int a)
{
    int i = 0, c = s->codec[a], rising = btf_lossy_fine(c, 0) < btf_lossy_fine(c, BTF_LOSSY_FINE - 1);
    while (i < BTF_LOSSY_FINE - 1 && (rising ? btf_lossy_fine(c, i) < s->quality[a]
                                               : btf_lossy_fine(c, i) > s->quality[a]))
        i++;
    return i;
}

/* Level l of component a (its exact codes) coded as a lossy file of codec[a] at quality q
 * into *file (malloc'd, *n bytes) and decoded into px (the level's atlas size). */
static btf_result btf__lossy_code(const btf__lod *s, int a, int l, int q, uint8_t **file, size_t *n, uint8_t *px,
                                  btf_error *err)
{
    const btf_package *p = s->p;
    int aw = p->atlas_cols * (s->W >> l), ah = p->atlas_rows * (s->H >> l);
    btf_result r = btf_lossy_encode(s->codec[a], s->exact[(size_t)a * s->nl + l], aw, ah, q, file, n, err);
    if (r == BTF_OK)
        r = btf_lossy_decode(*file, *n, "lod: lossy level", aw, ah, px, err);
    return r;
}

/* Levels 1..nl-1 of every component. */
static btf_result btf__make_levels(btf__lod *s, btf_error *err)
{
    const btf_package *p = s->p;
    size_t n0 = (size_t)s->nb * s->W * s->H;
    float *ex = malloc(n0 * sizeof(float)), *ex2 = malloc(n0 * sizeof(float));
    for (int a = 0; ex && ex2 && a < s->C; a++) {
        s->lev[a * s->nl] = p->tex[a];
        memcpy(ex, p->tex[a], n0 * sizeof(float));
        for (int l = 1; l < s->nl; l++) {
            int w = s->W >> l, h = s->H >> l;
            btf__box(ex, s->nb, w * 2, h * 2, ex2);
            float *t = ex;
            ex = ex2, ex2 = t;
            s->lev[a * s->nl + l] = malloc((size_t)s->nb * w * h * sizeof(float));
            s->atlas[a * s->nl + l] = calloc((size_t)p->atlas_cols * w * p->atlas_rows * h * s->ch, 1);
            if (!s->lev[a * s->nl + l] || !s->atlas[a * s->nl + l]) {
                free(ex), free(ex2);
                return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (levels)");
            }
            btf__quant_level(s, a, l, ex);
            size_t k = (size_t)a * s->nl + l, nb = (size_t)p->atlas_cols * w * p->atlas_rows * h * s->ch;
            if (s->quality[a] >= 0 && (s->exact[k] = malloc(nb)) != NULL)
                memcpy(s->exact[k], s->atlas[k], nb);
            if (s->quality[a] >= 0 && !s->exact[k]) {
                free(ex), free(ex2);
                return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (levels)");
            }
        }
    }
    int ok = ex && ex2;
    free(ex), free(ex2);
    return ok ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (levels)");
}

/* Per block b, the energy of component a's weights over the block's views (every
 * light and channel): what a unit of texture error costs the reconstruction there. */
static void btf__wsum(const btf__lod *s, int a, double *wsum)
{
    const btf_package *p = s->p;
    int V = p->views.n_dirs, L = p->lights.n_dirs;
    memset(wsum, 0, (size_t)s->nb * sizeof(double));
    for (int v = 0; v < V; v++)
        for (size_t k = 0; k < (size_t)L * 3; k++) {
            double x = p->wt[a][(size_t)v * L * 3 + k];
            wsum[p->blocks->block_of_view[v]] += x * x;
        }
}

/* One coarse level's lossy candidates: every lossy component at every rung of its fine
 * ladder up to its level-0 quality. Owned by btf__match_level, for one level. */
typedef struct btf__steps {
    uint8_t **file; /* [a*BTF_LOSSY_FINE+i] the level coded at rung i (NULL above the top or lossless) */
    size_t *n;      /* its bytes */
    double *noise;  /* the squared error it adds to the reconstruction (texture error x weight energy) */
    int *pick;      /* [a] the rung chosen */
} btf__steps;

static void btf__steps_free(btf__steps *st, int C)
{
    for (int i = 0; st->file && i < C * BTF_LOSSY_FINE; i++)
        free(st->file[i]);
    free(st->file), free(st->n), free(st->noise), free(st->pick);
}

/* Component a's candidates at level l: each rung's file, bytes and noise. */
static btf_result btf__steps_of(const btf__lod *s, int a, int l, btf__steps *st, btf_error *err)
{
    const btf_package *p = s->p;
    int w = s->W >> l, h = s->H >> l, aw = p->atlas_cols * w;
    size_t npx = (size_t)aw * p->atlas_rows * h;
    uint8_t *px = malloc(npx);
    double *wsum = malloc((size_t)s->nb * sizeof(double));
    if (!px || !wsum) {
        free(px), free(wsum);
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (lossy levels)");
    }
    btf__wsum(s, a, wsum);
    const uint8_t *ex = s->exact[(size_t)a * s->nl + l];
    btf_result r = BTF_OK;
    for (int i = 0, top = btf__ladder_top(s, a); r == BTF_OK && i <= top; i++) {
        size_t k = (size_t)a * BTF_LOSSY_FINE + i;
        r = btf__lossy_code(s, a, l, btf_lossy_fine(s->codec[a], i), &st->file[k], &st->n[k], px, err);
        for (int b = 0; r == BTF_OK && b < s->nb; b++) {
            const float *rg = p->chunk[a].tex_range + 2 * b;
            int x0 = (b % p->atlas_cols) * w, y0 = (b / p->atlas_cols) * h;
            double e = 0.0;
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    size_t o = (size_t)(y0 + y) * aw + (size_t)(x0 + x);
                    double d = (double)btf_package_dequant(rg, px[o]) - btf_package_dequant(rg, ex[o]);
                    e += d * d;
                }
            st->noise[k] += e * wsum[b];
        }
    }
    free(px), free(wsum);
    return r;
}

/* Every lossy component's candidates at level l (components on OpenMP's threads). */
static btf_result btf__steps_make(const btf__lod *s, int l, btf__steps *st, btf_error *err)
{
    size_t n = (size_t)s->C * BTF_LOSSY_FINE;
    st->file = calloc(n, sizeof *st->file), st->n = calloc(n, sizeof(size_t));
    st->noise = calloc(n, sizeof(double)), st->pick = calloc((size_t)s->C, sizeof(int));
    if (!st->file || !st->n || !st->noise || !st->pick)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (lossy levels)");
    btf_result r = BTF_OK;
#pragma omp parallel for schedule(dynamic)
    for (int a = 0; a < s->C; a++) {
        btf_error e1 = {{0}};
        btf_result ra = s->quality[a] >= 0 ? btf__steps_of(s, a, l, st, &e1) : BTF_OK;
#pragma omp critical(btf__lod_steps)
        if (ra != BTF_OK && r == BTF_OK)
            r = ra, *err = e1;
    }
    return r;
}

/* The rung of each lossy component that minimises bytes + lambda * noise (lambda < 0:
 * its top, the level-0 quality). */
static void btf__steps_pick(const btf__lod *s, btf__steps *st, double lambda)
{
    for (int a = 0; a < s->C; a++) {
        if (s->quality[a] < 0)
            continue;
        int top = btf__ladder_top(s, a), best = top;
        for (int i = 0; lambda >= 0.0 && i < top; i++) {
            size_t k = (size_t)a * BTF_LOSSY_FINE;
            if ((double)st->n[k + i] + lambda * st->noise[k + i] < (double)st->n[k + best] + lambda * st->noise[k + best])
                best = i;
        }
        st->pick[a] = best;
    }
}

/* Level l as the picked rungs give it: each lossy component's decode the level's atlas
 * and texels. */
static btf_result btf__steps_apply(btf__lod *s, int l, const btf__steps *st, btf_error *err)
{
    const btf_package *p = s->p;
    int aw = p->atlas_cols * (s->W >> l), ah = p->atlas_rows * (s->H >> l);
    btf_result r = BTF_OK;
    for (int a = 0; r == BTF_OK && a < s->C; a++) {
        if (s->quality[a] < 0)
            continue;
        size_t k = (size_t)a * s->nl + l, f = (size_t)a * BTF_LOSSY_FINE + st->pick[a];
        r = btf_lossy_decode(st->file[f], st->n[f], "lod: lossy level", aw, ah, s->atlas[k], err);
        if (r == BTF_OK)
            btf__dequant_level(s, a, l);
    }
    return r;
}

/* The picked files move from st into s->lossy (level l), the level's files from then on. */
static void btf__steps_keep(btf__lod *s, int l, btf__steps *st)
{
    for (int a = 0; a < s->C; a++) {
        if (s->quality[a] < 0)
            continue;
        size_t k = (size_t)a * s->nl + l, f = (size_t)a * BTF_LOSSY_FINE + st->pick[a];
        free(s->lossy[k]);
        s->lossy[k] = st->file[f], s->lossy_n[k] = st->n[f];
        st->file[f] = NULL;
    }
}

/* CIELab of level l as coded now, on pr (btf_lod_error.h). */
static double btf__level_lab(btf__lod *s, const btf_lod_probe *pr, int l)
{
    const float **tex = malloc((size_t)s->C * sizeof *tex);
    for (int a = 0; tex && a < s->C; a++)
        tex[a] = s->lev[a * s->nl + l];
    double lab = tex ? btf_lod_probe_lab(pr, s->p, tex) : -1.0;
    free(tex);
    return lab;
}

static int btf__cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return a < b ? -1 : a > b;
}

/* The multipliers at which some component's best rung changes (the slopes between its
 * rungs), ascending, into *out (malloc'd); their count, -1 out of memory. */
static int btf__steps_slopes(const btf__lod *s, const btf__steps *st, double **out)
{
    double *x = malloc((size_t)s->C * BTF_LOSSY_FINE * BTF_LOSSY_FINE * sizeof(double));
    int n = 0;
    for (int a = 0; x && a < s->C; a++)
        for (int i = 0, top = s->quality[a] >= 0 ? btf__ladder_top(s, a) : -1; i <= top; i++)
            for (int j = i + 1; j <= top; j++) {
                size_t k = (size_t)a * BTF_LOSSY_FINE;
                double db = (double)st->n[k + j] - (double)st->n[k + i], dn = st->noise[k + i] - st->noise[k + j];
                if (db > 0.0 && dn > 0.0)
                    x[n++] = db / dn;
            }
    if (x)
        qsort(x, (size_t)n, sizeof(double), btf__cmp_double);
    *out = x;
    return x ? n : -1;
}

/* Level l's lossy files with a source: the least bytes whose CIELab on pr stays at or
 * below target. Each lossy component is coded at every rung of its fine ladder up to its
 * level-0 quality; for a multiplier lambda each takes the rung of least bytes + lambda
 * x noise (its added squared error, which adds over components); the error falls as
 * lambda grows, so a bisection over the multipliers where a choice changes finds the
 * smallest that meets the target (the level-0 quality throughout when none does). */
static btf_result btf__match_level(btf__lod *s, int l, const btf_lod_probe *pr, double target, btf_error *err)
{
    btf__steps st = {0};
    double *lam = NULL;
    btf_result r = btf__steps_make(s, l, &st, err);
    int n = r == BTF_OK ? btf__steps_slopes(s, &st, &lam) : 0;
    if (n < 0)
        r = btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (lossy levels)");
    int lo = 0, hi = n; /* hi = n: the top rungs (lambda < 0) */
    while (r == BTF_OK && lo < hi) {
        int mid = (lo + hi) / 2;
        btf__steps_pick(s, &st, lam[mid]);
        r = btf__steps_apply(s, l, &st, err);
        double lab = r == BTF_OK ? btf__level_lab(s, pr, l) : -1.0;
        if (lab >= 0.0 && lab <= target)
            hi = mid;
        else
            lo = mid + 1;
    }
    if (r == BTF_OK) {
        btf__steps_pick(s, &st, lo < n ? lam[lo] : -1.0);
        r = btf__steps_apply(s, l, &st, err);
    }
    if (r == BTF_OK)
        btf__steps_keep(s, l, &st);
    free(lam);
    btf__steps_free(&st, s->C);
    return r;
}

/* Level l's lossy files without a source: every lossy component at its level-0 quality. */
static btf_result btf__level_at_top(btf__lod *s, int l, btf_error *err)
{
    btf_result r = BTF_OK;
    for (int a = 0; r == BTF_OK && a < s->C; a++) {
        if (s->quality[a] < 0)
            continue;
        size_t k = (size_t)a * s->nl + l;
        r = btf__lossy_code(s, a, l, s->quality[a], &s->lossy[k], &s->lossy_n[k], s->atlas[k], err);
        if (r == BTF_OK)
            btf__dequant_level(s, a, l);
    }
    return r;
}

/* 1 when the caller gathered the source's references for exactly these levels. */
static int btf__gathered(const btf__lod *s)
{
    const btf_lod_gather *g = s->gather;
    return s->src && g && btf_lod_gather_done(g) && g->n_levels == s->nl && g->width == s->W && g->height == s->H &&
           g->linear == s->p->linear && g->n_views == s->p->views.n_dirs && g->n_lights == s->p->lights.n_dirs;
}

/* The lossy files of every coarse level. With a source (its references gathered by the
 * caller, else read here in one pass) each level takes the least bytes
 * at which its CIELab against the source box-filtered to it, on its texel subsample,
 * stays at or below level 0's (btf__match_level; package-format.md section 10.7): a
 * coarse texel averages its block's errors, so at the level-0 quality a coarse level is
 * more accurate than level 0 (generated tiles at 128x128: 1.80, 1.41, 1.00 against
 * 2.32), which a view that shows it does not need. */
static btf_result btf__match_levels(btf__lod *s, btf_error *err)
{
    int any = 0;
    for (int a = 0; a < s->C; a++)
        any |= s->quality[a] >= 0;
    const btf_lod_probe *ready = any && btf__gathered(s) ? s->gather->pr : NULL;
    btf_lod_probe *pr = any && s->src && !ready ? calloc((size_t)s->nl, sizeof *pr) : NULL;
    if (any && s->src && !ready && !pr)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (level error)");
    btf_result r = pr ? btf_lod_probe_make(s->src, s->p, s->nl, BTF_LOD_ERROR_SAMPLE, pr, err) : BTF_OK;
    ready = ready ? ready : pr;
    double target = ready && r == BTF_OK ? btf__level_lab(s, &ready[0], 0) : -1.0;
    for (int l = 1; r == BTF_OK && any && l < s->nl; l++)
        r = target < 0.0 ? btf__level_at_top(s, l, err) : btf__match_level(s, l, &ready[l], target, err);
    if (pr)
        btf_lod_probe_free(pr, s->nl);
    free(pr);
    return r;
}

/* RMS (0..255) of component a's contribution at level l over its texels and every
 * measured (view, light, channel). */
static void btf__contribs(btf__lod *s)
{
    const btf_package *p = s->p;
    int V = p->views.n_dirs, L = p->lights.n_dirs;
    for (int a = 0; a < s->C; a++) {
        double *wsum = malloc((size_t)s->nb * sizeof(double));
        if (!wsum)
            return; /* contrib stays 0: the order degrades, nothing breaks */
        btf__wsum(s, a, wsum);
        for (int l = 0; l < s->nl; l++) {
            size_t n = (size_t)(s->W >> l) * (s->H >> l);
            double e = 0.0;
            for (int b = 0; b < s->nb; b++) {
                const float *t = s->lev[a * s->nl + l] + (size_t)b * n;
                double tt = 0.0;
                for (size_t i = 0; i < n; i++)
                    tt += (double)t[i] * t[i];
                e += tt / (double)n * wsum[b];
            }
            s->contrib[a * s->nl + l] = 255.0 * sqrt(e / ((double)V * L * 3));
        }
        free(wsum);
    }
}

/* Chunk order (section 10): groups by display level, coarsest first; component a
 * with visibility level vis (coarsest level whose contrib >= thr) appears at every
 * level it is needed: its levels >= vis all in group vis (coarse to fine), then one
 * level per finer group; invisible components close the list. */
static void btf__lod_order(btf__lod *s)
{
    int nl = s->nl;
    s->n_order = 0;
    for (int g = nl - 1; g >= -1; g--)
        for (int a = 0; a < s->C; a++) {
            int vis = -1;
            for (int l = nl - 1; l >= 0 && vis < 0; l--)
                if (s->contrib[a * nl + l] >= s->thr)
                    vis = l;
            if (a == 0)
                vis = nl - 1;
            if (vis != g && !(g >= 0 && vis > g))
                continue;
            int lo = g < 0 ? 0 : g, hi = vis == g ? nl - 1 : g;
            for (int l = hi; l >= lo; l--) {
                s->order[2 * s->n_order] = a;
                s->order[2 * s->n_order + 1] = l;
                s->n_order++;
            }
        }
}

/* Component a's level-l texels upsampled to level 0 (bilinear at the texel centres). */
static void btf__upsample(const btf__lod *s, int a, int l, int b, float *out)
{
    int w = s->W >> l, h = s->H >> l;
    const float *tile = s->lev[a * s->nl + l] + (size_t)b * w * h;
    for (int y = 0; y < s->H; y++)
        for (int x = 0; x < s->W; x++)
            out[(size_t)y * s->W + x] = btf_package_level_sample(tile, l, w, h, x, y);
}

static double btf__dot(const float *x, const float *y, size_t n)
{
    double d = 0.0;
    for (size_t i = 0; i < n; i++)
        d += (double)x[i] * y[i];
    return d;
}

/* RMSE against the complete package after each chunk of the order, at level 0 over
 * every measured pair: |D W^T|^2 = sum_ab (d_a.d_b)(w_a.w_b) per block, where d_a is
 * component a's full texture minus what the chunks so far give (0 if absent). */
static btf_result btf__errors(btf__lod *s, btf_error *err)
{
    const btf_package *p = s->p;
    int C = s->C, V = p->views.n_dirs, L = p->lights.n_dirs;
    size_t N = (size_t)s->W * s->H, CC = (size_t)C * C;
    float *D = malloc((size_t)C * s->nb * N * sizeof(float)), *up = malloc(N * sizeof(float));
    double *G = calloc(CC * s->nb, sizeof(double)), *WW = calloc(CC * s->nb, sizeof(double));
    if (!D || !up || !G || !WW) {
        free(D), free(up), free(G), free(WW);
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (error sums)");
    }
    for (int a = 0; a < C; a++)
        memcpy(D + (size_t)a * s->nb * N, p->tex[a], s->nb * N * sizeof(float));
    for (int v = 0; v < V; v++) {
        double *ww = WW + CC * p->blocks->block_of_view[v];
        for (int a = 0; a < C; a++)
            for (int c = 0; c <= a; c++) {
                double d = 0.0;
                for (size_t k = 0; k < (size_t)L * 3; k++)
                    d += (double)p->wt[a][(size_t)v * L * 3 + k] * p->wt[c][(size_t)v * L * 3 + k];
                ww[(size_t)a * C + c] += d;
                if (c != a)
                    ww[(size_t)c * C + a] += d;
            }
    }
    for (int b = 0; b < s->nb; b++)
        for (int a = 0; a < C; a++)
            for (int c = 0; c < C; c++)
                G[CC * b + (size_t)a * C + c] = btf__dot(D + ((size_t)a * s->nb + b) * N, D + ((size_t)c * s->nb + b) * N, N);
    for (int k = 0; k < s->n_order; k++) {
        int a = s->order[2 * k], l = s->order[2 * k + 1];
        double e = 0.0;
        for (int b = 0; b < s->nb; b++) {
            float *d = D + ((size_t)a * s->nb + b) * N;
            btf__upsample(s, a, l, b, up);
            for (size_t i = 0; i < N; i++)
                d[i] = p->tex[a][(size_t)b * N + i] - up[i];
            for (int c = 0; c < C; c++) {
                double x = btf__dot(d, D + ((size_t)c * s->nb + b) * N, N);
                G[CC * b + (size_t)a * C + c] = G[CC * b + (size_t)c * C + a] = x;
            }
            for (size_t i = 0; i < CC; i++)
                e += G[CC * b + i] * WW[CC * b + i];
        }
        s->rmse_full[k] = 255.0 * sqrt((e > 0.0 ? e : 0.0) / ((double)N * V * L * 3));
    }
    free(D), free(up), free(G), free(WW);
    return BTF_OK;
}


/* Codings of a component's 16-bit weights (doc/package-format.md sections 5.1, 5.3, 9.3,
 * 5.4), or NONE: version 4 writes no 16-bit file where the 8-bit weights are they (7.1). */
enum { BTF__W16_BIN, BTF__W16_RES, BTF__W16_Z, BTF__W16_PZ, BTF__W16_NONE };

static btf_result btf__copy_file(const char *from, const char *to, btf_error *err)
{
    char *data;
    size_t n;
    btf_result r = btf_fs_read(from, (size_t)1 << 30, &data, &n, err);
    if (r == BTF_OK)
        r = btf_fs_write_atomic(to, data, n, err);
    free(data);
    return r;
}

/* The source chunk's texture file (weights = 0: tex-JJ.png or .webp) or weights file
 * (weights = 1: wt-JJ.bin, or version 3's wt-JJ.z). */
static const char *btf__src_file(const btf_chunk_info *ci, int weights)
{
    for (int i = 0; i < ci->n_files; i++)
        if (!strncmp(ci->files[i], "wt-", 3) == !!weights)
            return ci->files[i];
    return NULL;
}

/* Length of a file name without its extension. */
static int btf__stem_len(const char *name)
{
    const char *dot = strrchr(name, '.');
    return dot ? (int)(dot - name) : (int)strlen(name);
}

/* Level file name of component a without its extension: level 0 keeps the v1 name,
 * level l adds -lL; version 4: a level stored as a residual (l < nl-1, level 0
 * included) adds -dL. */
static void btf__level_stem(const btf__lod *s, int a, int l, int residual, char *name, size_t n)
{
    const char *t = btf__src_file(&s->p->chunk[a], 0);
    if (residual)
        snprintf(name, n, "%.*s-d%d", btf__stem_len(t), t, l);
    else if (l == 0)
        snprintf(name, n, "%.*s", btf__stem_len(t), t);
    else
        snprintf(name, n, "%.*s-l%d", btf__stem_len(t), t, l);
}

/* The extension of a level file of encoding kind (btf__lod.kind). */
static const char *btf__kind_ext(int kind)
{
    return kind ? btf_lossy_ext(kind) : ".png";
}

/* The name of the file that holds level l of component a, as written. */
static void btf__level_name(const btf__lod *s, int a, int l, char *name, size_t n)
{
    size_t k = (size_t)a * s->nl + l;
    btf__level_stem(s, a, l, s->isres[k], name, n);
    size_t e = strlen(name);
    snprintf(name + e, n - e, "%s", btf__kind_ext(s->kind[k]));
}

/* Name of component a's 8-bit weights: "wt-JJ.bin" (or "wt-JJ.z") -> "wt-JJ-8.png",
 * or with webp "wt-JJ-8.webp". */
static void btf__w8_name_as(const btf__lod *s, int a, int webp, char *name, size_t n)
{
    const char *w = btf__src_file(&s->p->chunk[a], 1);
    snprintf(name, n, "%.*s-8.%s", btf__stem_len(w), w, webp ? "webp" : "png");
}

/* Name of component a's 8-bit weights as written. */
static void btf__w8_name(const btf__lod *s, int a, char *name, size_t n)
{
    btf__w8_name_as(s, a, s->w8webp[a], name, n);
}

/* Level of component a's first chunk in the order (its coarse weights travel there when > 0). */
static int btf__first_level(const btf__lod *s, int a)
{
    for (int k = 0; k < s->n_order; k++)
        if (s->order[2 * k] == a)
            return s->order[2 * k + 1];
    return 0;
}

/* Step multiplier s_c of component a's 8-bit weights (doc/package-format.md section
 * 10.6): 1 when every 16-bit code is at most 255 (the 8-bit weights are then the 16-bit
 * ones, and no 16-bit file follows: btf__w16_redundant); else the largest whole s with
 * s * step16 <= BTF__W8_NOISE/255 * sqrt(12) / rms(T_a) in every block, so the coarse
 * weights add at most that RMS noise (0..255 scale) per component (the equal-noise
 * allocation of section 4 applied to weights), but at least ceil(q16max / 255) so
 * that 255 codes reach the component's largest 16-bit code (257 for weights spanning
 * the 16 bits), at most 65535. */
#define BTF__W8_NOISE 0.25
static int btf__w8_step(const btf__lod *s, int a)
{
    const btf_package *p = s->p;
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    double m = 65535.0, qmax = 0.0;
    for (size_t k = 0; k < (size_t)V * L * 3; k++) {
        const float *rg = p->chunk[a].wt_range + 2 * p->blocks->block_of_view[k / (3 * (size_t)L)];
        double q = rg[1] > 0.0f ? rint(((double)p->wt[a][k] - rg[0]) / rg[1]) : 0.0;
        qmax = q > qmax ? q : qmax;
    }
    double lo = ceil(qmax / 255.0);
    if (lo <= 1.0)
        return 1;
    for (int b = 0; b < s->nb; b++) {
        const float *t = p->tex[a] + (size_t)b * s->W * s->H;
        double e = 0.0;
        for (size_t k = 0; k < (size_t)s->W * s->H; k++)
            e += (double)t[k] * t[k];
        double rms = sqrt(e / ((double)s->W * s->H)), st = p->chunk[a].wt_range[2 * b + 1];
        if (rms > 0.0 && st > 0.0 && BTF__W8_NOISE / 255.0 * sqrt(12.0) / rms / st < m)
            m = BTF__W8_NOISE / 255.0 * sqrt(12.0) / rms / st;
    }
    m = floor(m) > lo ? floor(m) : lo;
    return m < 1.0 ? 1 : m > 65535.0 ? 65535 : (int)m;
}

/* Version 4: component a's 8-bit weights q (V*L*3) as wt-JJ-8.webp in tmp (an RGB
 * lossless WebP of L x V pixels, doc/package-format.md section 5.2) when that is
 * smaller than its PNG (png, already written, of png_bytes): the PNG removed, w8webp
 * and w8bytes set. */
static btf_result btf__w8_webp(btf__lod *s, int a, const uint8_t *q, const char *tmp, const char *png,
                               long long png_bytes, btf_error *err)
{
    int L = s->p->lights.n_dirs, V = s->p->views.n_dirs;
    uint8_t *f = NULL;
    size_t nf = 0;
    char name[BTF_PACKAGE_NAME_MAX + 8], path[8400];
    btf_result r = btf_webp_encode_rgb(q, L, V, &f, &nf, err); /* index (v*L + l)*3 + c: pixel (l, v) */
    if (r == BTF_OK && (long long)nf < png_bytes) {
        btf__w8_name_as(s, a, 1, name, sizeof name);
        snprintf(path, sizeof path, "%s/%s", tmp, name);
        r = btf_fs_write_atomic(path, f, nf, err);
        if (r == BTF_OK && remove(png) == 0) /* the PNG this writer just made */
            s->w8webp[a] = 1, s->w8bytes[a] = (long long)nf;
    }
    free(f);
    return r;
}

/* Component a's weights requantised to 8 bits at its step multiplier s->w8step[a]
 * (q8 = round(q16 / s_c), the same lo): V*L*3 codes, malloc'd; NULL without memory. */
static uint8_t *btf__w8_codes(const btf__lod *s, int a)
{
    const btf_package *p = s->p;
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    uint8_t *q = malloc((size_t)V * L * 3);
    for (size_t k = 0; q && k < (size_t)V * L * 3; k++) {
        const float *rg = p->chunk[a].wt_range + 2 * p->blocks->block_of_view[k / (3 * (size_t)L)];
        double x = rg[1] > 0.0f ? ((double)p->wt[a][k] - rg[0]) / ((double)s->w8step[a] * rg[1]) : 0.0;
        q[k] = (uint8_t)(x < 0.0 ? 0 : x > 255.0 ? 255 : lround(x));
    }
    return q;
}

/* Version 4 over a version-3 source whose wt-JJ.webp is a lossy WebP (WebP allowed):
 * that file, byte for byte, as component a's wt-JJ-8.webp with s_c = 1 (doc/package-format.md
 * section 5.2); its 8-bit codes are the 16-bit ones the reader decoded from it (the
 * residual wt-JJ-r.z would be zeros); *kept = 0 for any other source file. */
static btf_result btf__w8_lossy(btf__lod *s, int a, const char *in_dir, const char *tmp, int *kept, btf_error *err)
{
    const btf_package *p = s->p;
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    const char *w = btf__src_file(&p->chunk[a], 1);
    char from[8400], to[8400], name[BTF_PACKAGE_NAME_MAX + 8], *data = NULL;
    size_t nd = 0;
    *kept = 0;
    if (!s->webp || !s->resid || btf_wtz_kind_of(w) != BTF_WTZ_WEBP)
        return BTF_OK;
    snprintf(from, sizeof from, "%s/%s", in_dir, w);
    btf_result r = btf_fs_read(from, btf_wtz_max_bytes(V, L), &data, &nd, err);
    if (r == BTF_OK && btf_lossy_codec_of((const uint8_t *)data, nd) == BTF_LOSSY_WEBP) {
        s->w8step[a] = 1;
        btf__w8_name_as(s, a, 1, name, sizeof name);
        snprintf(to, sizeof to, "%s/%s", tmp, name);
        s->w8q[a] = btf__w8_codes(s, a);
        r = s->w8q[a] ? btf_fs_write_atomic(to, data, nd, err) : btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory");
        if (r == BTF_OK)
            s->w8webp[a] = 1, s->w8bytes[a] = (long long)nd, *kept = 1;
    }
    free(data);
    return r;
}

/* Component a's 8-bit weights (btf__w8_codes) as a grey PNG of 3L x V pixels
 * (doc/package-format.md section 5.2) at path; version 4 without png_only: replaced by
 * wt-JJ-8.webp where that is smaller (btf__w8_webp). */
static btf_result btf__write_w8(btf__lod *s, int a, const char *tmp, const char *path, btf_error *err)
{
    int L = s->p->lights.n_dirs, V = s->p->views.n_dirs;
    uint8_t *q = btf__w8_codes(s, a);
    if (!q)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory");
    s->w8q[a] = q; /* version 4 codes the 16-bit weights over these */
    btf_result r = btf_image_write_flags(path, 3 * L, V, 1, 8, q, BTF_IMAGE_PNG_SMALLEST, err);
    s->w8bytes[a] = btf_fs_size(path);
    return r == BTF_OK && s->webp ? btf__w8_webp(s, a, q, tmp, path, s->w8bytes[a], err) : r;
}

/* Name of component a's 16-bit weights in the coding c (BTF__W16_*): "wt-JJ.bin",
 * "wt-JJ-r.z" (over the 8-bit weights, version 4), "wt-JJ.z" or "wt-JJ.pz". */
static void btf__w16_name(const btf__lod *s, int a, int c, char *name, size_t n)
{
    static const char *const ext[] = {".bin", "-r.z", ".z", ".pz"};
    const char *w = btf__src_file(&s->p->chunk[a], 1);
    snprintf(name, n, "%.*s%s", btf__stem_len(w), w, ext[c]);
}

/* Component a's 16-bit weight codes q16 (V*L*3, malloc'd into *q) from the source
 * package's file path: wt-JJ.bin (little-endian) or version 3's wt-JJ.z, wt-JJ.pz or
 * wt-JJ.webp. */
static btf_result btf__read_q16(const btf__lod *s, const char *path, uint16_t **q, btf_error *err)
{
    const btf_package *p = s->p;
    int V = p->views.n_dirs, L = p->lights.n_dirs;
    size_t n = (size_t)V * L * 3, nd = 0;
    const char *base = strrchr(path, '/');
    int z = p->version == 3, kind = btf_wtz_kind_of(base ? base + 1 : path);
    char *raw = NULL;
    btf_result r = btf_fs_read(path, z ? btf_wtz_max_bytes(V, L) : 2 * n, &raw, &nd, err);
    if (r == BTF_OK && !z && nd != 2 * n)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: %zu bytes, expected %zu", path, nd, 2 * n);
    *q = r == BTF_OK ? malloc(n * sizeof **q) : NULL;
    if (r == BTF_OK && !*q)
        r = btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory");
    if (r == BTF_OK && z)
        r = kind < 0 ? btf_fail(err, BTF_ERR_FORMAT, "%s: not a version-3 weights file", path)
                     : btf_wtz_decode_kind(kind, (const uint8_t *)raw, nd, V, L, s->prev_view, *q, path, err);
    for (size_t k = 0; r == BTF_OK && !z && k < n; k++)
        (*q)[k] = (uint16_t)((unsigned)(uint8_t)raw[2 * k] | (unsigned)(uint8_t)raw[2 * k + 1] << 8);
    free(raw);
    return r;
}

/* Component a's 16-bit weights q16 encoded as c (BTF__W16_*) into *out (malloc'd). */
static btf_result btf__encode_w16(const btf__lod *s, int a, const uint16_t *q, int c, uint8_t **out, size_t *len,
                                  btf_error *err)
{
    const btf_package *p = s->p;
    int V = p->views.n_dirs, L = p->lights.n_dirs;
    size_t n = (size_t)V * L * 3;
    if (c == BTF__W16_Z || c == BTF__W16_PZ)
        return btf_wtz_encode_pred(q, V, L, c == BTF__W16_PZ ? s->prev_view : NULL, out, len, err);
    uint16_t *d = malloc(n * sizeof *d);
    if (!d)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory");
    unsigned sc = c == BTF__W16_RES ? (unsigned)s->w8step[a] : 0u;
    for (size_t k = 0; k < n; k++) /* the residual r = (q16 - s_c q8) mod 65536 (section 5.3) */
        d[k] = (uint16_t)((q[k] - (sc ? sc * s->w8q[a][k] : 0u)) & 0xFFFFu);
    btf_result r = BTF_OK;
    if (c == BTF__W16_RES)
        r = btf_wtz_encode(d, (int)(n / 3), 1, out, len, err);
    else if ((*out = malloc(2 * n)) != NULL) {
        for (size_t k = 0; k < n; k++)
            (*out)[2 * k] = (uint8_t)(d[k] & 255u), (*out)[2 * k + 1] = (uint8_t)(d[k] >> 8);
        *len = 2 * n;
    } else
        r = btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory");
    free(d);
    return r;
}

/* 1 in version 4 when component a's 8-bit weights are its 16-bit codes q exactly (s_c
 * = 1, q8 = q16: its wt-JJ-r.z would be zeros, and both dequantise to the same floats),
 * so its level-0 chunk needs no weights file (doc/package-format.md section 7.1). */
static int btf__w16_redundant(const btf__lod *s, int a, const uint16_t *q)
{
    size_t n = (size_t)s->p->views.n_dirs * s->p->lights.n_dirs * 3;
    if (!s->resid || !s->w8q[a] || s->w8step[a] != 1)
        return 0;
    for (size_t k = 0; k < n; k++)
        if (s->w8q[a][k] != q[k])
            return 0;
    return 1;
}

/* Component a's 16-bit weights into tmp in the smallest coding a version allows:
 * version 2 wt-JJ.bin; version 4 also wt-JJ-r.z (with 8-bit weights), wt-JJ.z and wt-JJ.pz,
 * or none where the 8-bit weights are they (btf__w16_redundant). Fills w16res[a] and
 * wbytes[a]. */
static btf_result btf__write_w16(btf__lod *s, int a, const char *in_dir, const char *tmp, btf_error *err)
{
    char from[8400], to[8400], name[BTF_PACKAGE_NAME_MAX + 8];
    uint16_t *q = NULL;
    uint8_t *best = NULL;
    size_t nbest = 0;
    snprintf(from, sizeof from, "%s/%s", in_dir, btf__src_file(&s->p->chunk[a], 1));
    btf_result r = btf__read_q16(s, from, &q, err);
    if (r == BTF_OK && btf__w16_redundant(s, a, q)) {
        s->w16res[a] = BTF__W16_NONE, s->wbytes[a] = 0;
        free(q);
        return BTF_OK;
    }
    for (int c = BTF__W16_BIN; r == BTF_OK && c <= (s->resid ? BTF__W16_PZ : BTF__W16_BIN); c++) {
        uint8_t *z = NULL;
        size_t nz = 0;
        if (c == BTF__W16_RES && !s->w8q[a])
            continue;
        r = btf__encode_w16(s, a, q, c, &z, &nz, err);
        if (r == BTF_OK && (!best || nz < nbest))
            free(best), best = z, nbest = nz, s->w16res[a] = (char)c;
        else
            free(z);
    }
    btf__w16_name(s, a, s->w16res[a], name, sizeof name);
    snprintf(to, sizeof to, "%s/%s", tmp, name);
    if (r == BTF_OK)
        r = btf_fs_write_atomic(to, best, nbest, err);
    s->wbytes[a] = (long long)nbest;
    free(q), free(best);
    return r;
}

/* A grey level file: stem.png (the smallest PNG filter choice), or stem.webp when
 * WebP is allowed (s->webp) and smaller; *webp = 1 then, *bytes the size kept. */
static btf_result btf__write_level_file(const btf__lod *s, const char *stem, int w, int h, const uint8_t *px,
                                        char *webp, long long *bytes, btf_error *err)
{
    const char *ext = ".png";
    btf_result r = btf_image_write_smallest(stem, w, h, px, BTF_IMAGE_PNG_SMALLEST | (s->webp ? 0 : BTF_IMAGE_NO_WEBP),
                                            &ext, bytes, err);
    *webp = !strcmp(ext, ".webp");
    return r;
}

/* Version 4: component a's level-0 atlas bytes (the v1 PNG's) into s->atlas[a * nl]. */
static btf_result btf__level0_atlas(btf__lod *s, int a, const char *in_dir, btf_error *err)
{
    const btf_package *p = s->p;
    char path[8400];
    int w, h;
    snprintf(path, sizeof path, "%s/%s", in_dir, btf__src_file(&p->chunk[a], 0));
    btf_result r = btf_image_read_grey(path, &w, &h, &s->atlas[a * s->nl], err); /* refuses what is not grey */
    if (r == BTF_OK && (w != p->atlas_cols * s->W || h != p->atlas_rows * s->H))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: %dx%d, expected the %dx%d grey atlas", path, w, h,
                     p->atlas_cols * s->W, p->atlas_rows * s->H);
    return r;
}

/* Version 4: level l < nl-1 of component a as its residual over level l+1 with the
 * least-squares predictor (kept in s->pred), into stem.png or stem.webp (*webp = 1);
 * *bytes its size. */
static btf_result btf__write_residual(btf__lod *s, int a, int l, const char *stem, char *webp, long long *bytes,
                                      btf_error *err)
{
    const btf_package *p = s->p;
    int aw = p->atlas_cols * (s->W >> l), ah = p->atlas_rows * (s->H >> l);
    const uint8_t *fine = s->atlas[a * s->nl + l], *coarse = s->atlas[a * s->nl + l + 1];
    uint8_t *res = malloc((size_t)aw * ah);
    if (!res)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (residual)");
    btf_lap_pred *pr = &s->pred[a * s->nl + l];
    *pr = btf_lap_pred_fit(fine, coarse, aw, ah, s->W >> l, s->H >> l);
    btf_result r = btf_lap_encode(fine, coarse, aw, ah, s->W >> l, s->H >> l, pr, res, err);
    /* the smallest PNG filter choice (residuals are noise-like, where filter None often wins) */
    if (r == BTF_OK)
        r = btf__write_level_file(s, stem, aw, ah, res, webp, bytes, err);
    free(res);
    return r;
}

/* Version 4: of two codings of one file (plain, alt) the smaller stays, the other is
 * removed; *chose = 1 when alt stays (ties keep plain), *bytes = the size kept. */
static btf_result btf__keep_smaller(const char *plain, const char *alt, char *chose, long long *bytes, btf_error *err)
{
    long long a = btf_fs_size(plain), b = btf_fs_size(alt);
    *chose = b >= 0 && b < a;
    *bytes = *chose ? b : a;
    if (remove(*chose ? plain : alt) != 0)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot remove (%s)", *chose ? plain : alt, strerror(errno));
    return BTF_OK;
}

/* The lossy encoding of the file at path (btf_lossy_codec_of on its first bytes):
 * BTF_LOSSY_WEBP, BTF_LOSSY_AVIF, or BTF_LOSSY_NONE. */
static int btf__lossy_file(const char *path)
{
    uint8_t head[16];
    FILE *f = fopen(path, "rb");
    size_t n = f ? fread(head, 1, sizeof head, f) : 0;
    if (f)
        fclose(f);
    return btf_lossy_codec_of(head, n);
}

/* Level k's lossy file (s->lossy[k], of component a) in place of the lossless one at
 * path (stem bytes of it before the extension): written as stem.webp or stem.avif,
 * the lossless file removed; path becomes the file kept. */
static btf_result btf__keep_lossy(btf__lod *s, int a, size_t k, char *path, size_t stem, btf_error *err)
{
    char lossy[BTF__LOD_PATH];
    snprintf(lossy, sizeof lossy, "%.*s%s", (int)stem, path, btf_lossy_ext(s->codec[a]));
    btf_result r = btf_fs_write_atomic(lossy, s->lossy[k], s->lossy_n[k], err);
    if (r == BTF_OK && strcmp(lossy, path) != 0 && remove(path) != 0)
        r = btf_fail(err, BTF_ERR_IO, "%s: cannot remove (%s)", path, strerror(errno));
    if (r == BTF_OK) {
        snprintf(path, BTF__LOD_PATH, "%s", lossy);
        s->kind[k] = (char)s->codec[a], s->tbytes[k] = (long long)s->lossy_n[k];
    }
    return r;
}

/* Fills s->quality and s->codec: for each component whose level-0 file in in_dir is a
 * lossy WebP or an AVIF, the level the source's "rd" record gives it (tex_quality, by
 * component) and the file's encoding, so that its coarse levels get the same; -1 for the others, and for all of them
 * when the levels are not 8-bit WebP-allowed (--png) or the record says nothing. */
static void btf__coarse_quality(btf__lod *s, const char *in_dir)
{
    const btf_package *p = s->p;
    cJSON *rd = s->webp && s->ch == 1 && p->rd ? cJSON_Parse(p->rd) : NULL;
    const cJSON *tq = cJSON_GetObjectItemCaseSensitive(rd, "tex_quality");
    for (int a = 0; a < s->C; a++) {
        const cJSON *q = cJSON_IsArray(tq) ? cJSON_GetArrayItem(tq, p->chunk[a].component) : NULL;
        char path[BTF__LOD_PATH];
        snprintf(path, sizeof path, "%s/%s", in_dir, btf__src_file(&p->chunk[a], 0));
        int codec = btf__lossy_file(path), top = btf_lossy_max_level(codec);
        s->codec[a] = codec;
        s->quality[a] = cJSON_IsNumber(q) && q->valuedouble >= 0 && q->valuedouble <= top && codec ? (int)q->valuedouble
                                                                                                    : -1;
    }
    cJSON_Delete(rd);
}

/* Level l of component a into tmp: the direct file (level 0 copied from the v1
 * package unless WebP may replace it, and a lossy WebP unless every texture is to be
 * a PNG: its decode is the level's atlas, and coded again losslessly it would cost
 * more) and, for
 * version 4 below the coarsest level, the residual, the smaller kept; fills tbytes,
 * isres, kind. */
static btf_result btf__write_level(btf__lod *s, int a, int l, const char *in_dir, const char *tmp, btf_error *err)
{
    const btf_package *p = s->p;
    size_t k = (size_t)a * s->nl + l;
    char to[BTF__LOD_PATH], g[BTF__LOD_PATH], name[BTF_PACKAGE_NAME_MAX + 8];
    int aw = p->atlas_cols * (s->W >> l), ah = p->atlas_rows * (s->H >> l);
    btf_result r;
    btf__level_stem(s, a, l, 0, name, sizeof name);
    snprintf(to, sizeof to, "%s/%s", tmp, name);
    const char *t = btf__src_file(&p->chunk[a], 0);
    char from[8400];
    snprintf(from, sizeof from, "%s/%s", in_dir, t);
    int lossy = l == 0 && s->webp ? btf__lossy_file(from) : 0; /* --png: its decode as a PNG, as every texture */
    if (lossy || (l == 0 && !s->webp && !strcmp(t + btf__stem_len(t), ".png"))) { /* the source's own file */
        snprintf(to, sizeof to, "%s/%s%s", tmp, name, btf__kind_ext(lossy));
        r = btf__copy_file(from, to, err);
        s->tbytes[k] = btf_fs_size(to);
        s->kind[k] = (char)lossy;
    } else if (s->ch == 1) {
        size_t stem = strlen(to);
        r = btf__write_level_file(s, to, aw, ah, s->atlas[k], &s->kind[k], &s->tbytes[k], err);
        snprintf(to + stem, sizeof to - stem, "%s", btf__kind_ext(s->kind[k]));
        if (r == BTF_OK && s->lossy[k] && (long long)s->lossy_n[k] < s->tbytes[k])
            r = btf__keep_lossy(s, a, k, to, stem, err);
    } else {
        snprintf(to + strlen(to), sizeof to - strlen(to), ".png");
        r = btf_image_write_flags(to, aw, ah, s->ch, 8, s->atlas[k], BTF_IMAGE_PNG_SMALLEST, err);
        s->tbytes[k] = btf_fs_size(to);
    }
    if (r != BTF_OK || !s->resid || l == s->nl - 1)
        return r;
    char rwebp = 0;
    long long rbytes = -1;
    btf__level_stem(s, a, l, 1, name, sizeof name);
    snprintf(g, sizeof g, "%s/%s", tmp, name);
    r = btf__write_residual(s, a, l, g, &rwebp, &rbytes, err);
    snprintf(g + strlen(g), sizeof g - strlen(g), "%s", rwebp ? ".webp" : ".png");
    r = r == BTF_OK ? btf__keep_smaller(to, g, &s->isres[k], &s->tbytes[k], err) : r;
    if (r == BTF_OK && s->isres[k])
        s->kind[k] = rwebp;
    return r;
}

/* Every texture and weight file into tmp; fills tbytes, wbytes. */
static btf_result btf__write_files(btf__lod *s, const char *in_dir, const char *tmp, btf_error *err)
{
    char to[8400], name[BTF_PACKAGE_NAME_MAX + 8];
    btf_result r = BTF_OK;
    for (int a = 0; r == BTF_OK && a < s->C; a++) {
        int kept = 0, coarse = btf__first_level(s, a) > 0; /* its first chunk carries 8-bit weights */
        if (coarse)
            r = btf__w8_lossy(s, a, in_dir, tmp, &kept, err);
        if (r == BTF_OK && !kept && coarse) {
            btf__w8_name(s, a, name, sizeof name);
            snprintf(to, sizeof to, "%s/%s", tmp, name);
            s->w8step[a] = btf__w8_step(s, a);
            r = btf__write_w8(s, a, tmp, to, err);
        }
        if (r == BTF_OK)
            r = btf__write_w16(s, a, in_dir, tmp, err);
        if (r == BTF_OK && s->resid)
            r = btf__level0_atlas(s, a, in_dir, err);
        for (int l = 0; r == BTF_OK && l < s->nl; l++)
            r = btf__write_level(s, a, l, in_dir, tmp, err);
    }
    return r;
}




/* The v2 chunk list: (component, level) pairs in s->order, with the files each carries. */
static void btf__lod_chunk(const btf__lod *s, int k, char *seen, btf_chunk_info *c, long long *bytes)
{
    const btf_package *p = s->p;
    int a = s->order[2 * k], l = s->order[2 * k + 1];
    const btf_chunk_info *v1 = &p->chunk[a];
    double rmse_end = p->chunk[s->C - 1].rmse, rf_end = p->chunk[s->C - 1].rmse_float;
    c->component = v1->component, c->level = l, c->n_files = 0;
    c->tex_range = v1->tex_range, c->wt_range = v1->wt_range; /* borrowed from the v1 package */
    btf__level_name(s, a, l, c->files[c->n_files++], BTF_PACKAGE_NAME_MAX);
    c->has_pred = s->isres[a * s->nl + l];
    if (c->has_pred)
        c->pred = s->pred[a * s->nl + l];
    *bytes = s->tbytes[a * s->nl + l];
    if (!seen[a] && l > 0) { /* a coarse first chunk carries the 8-bit weights */
        btf__w8_name(s, a, c->files[c->n_files++], BTF_PACKAGE_NAME_MAX);
        *bytes += s->w8bytes[a];
    }
    if ((l == 0 || (!seen[a] && s->w8bytes[a] == 0)) && s->w16res[a] != BTF__W16_NONE) { /* level 0: the 16-bit weights */
        btf__w16_name(s, a, s->w16res[a], c->files[c->n_files++], BTF_PACKAGE_NAME_MAX);
        *bytes += s->wbytes[a];
    }
    seen[a] = 1;
    c->bytes = *bytes;
    c->rmse = sqrt(rmse_end * rmse_end + s->rmse_full[k] * s->rmse_full[k]);
    c->psnr = c->rmse > 0 ? 20.0 * log10(255.0 / c->rmse) : 999.0;
    c->rmse_float = sqrt(rf_end * rf_end + s->rmse_full[k] * s->rmse_full[k]);
    c->contrib = s->contrib[a * s->nl + l];
    c->rmse_full = s->rmse_full[k];
    c->wt8_step = s->w8bytes[a] ? (double)s->w8step[a] : 257.0;
}

/* The v2 manifest: the v1 header with levels and the (component, level) chunk list. */
static char *btf__lod_manifest(btf__lod *s, btf_lod_stats *st, btf_error *err)
{
    btf_package q = *s->p; /* header fields shared with the v1 package; chunks are new */
    q.version = s->resid ? 4 : 2, q.n_levels = s->nl, q.lod_threshold = s->thr, q.n_chunks = s->n_order, q.n_loaded = 0;
    q.chunk = calloc((size_t)s->n_order, sizeof *q.chunk);
    char *seen = calloc((size_t)s->C, 1);
    char *out = NULL;
    if (!q.chunk || !seen)
        btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (manifest)");
    for (int k = 0; q.chunk && seen && k < s->n_order; k++) {
        long long bytes;
        btf__lod_chunk(s, k, seen, &q.chunk[k], &bytes);
        if (st) {
            st->bytes += bytes;
            if (k == 0)
                st->first_chunk = bytes;
        }
    }
    if (q.chunk && seen)
        out = btf_manifest_print(&q, err);
    free(seen);
    free(q.chunk);
    return out;
}



static btf_result btf__lod_setup(btf__lod *s, const char *in_dir, const btf_lod_options *o, btf_error *err)
{
    btf_result r = btf_package_read(in_dir, 0, &s->p, err);
    if (r != BTF_OK)
        return r;
    btf_package *p = s->p;
    if ((p->version != 1 && p->version != 3) || p->n_levels != 1)
        return btf_fail(err, BTF_ERR_ARG, "%s: already has spatial levels (version %d)", in_dir, p->version);
    s->C = p->n_chunks, s->nb = p->blocks->n_blocks, s->W = p->width, s->H = p->height;
    s->ch = p->bits == 16 ? 3 : 1, s->qmax = p->bits == 16 ? 65535 : 255;
    s->resid = (o && o->residual) || p->version == 3; /* rate-distortion steps: version 4 (wt-JJ.z weights) */
    s->webp = s->resid && !(o && o->png_only);
    if (s->resid && p->bits != 8)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: residual levels (version 4) need 8-bit textures, not %d", in_dir,
                        p->bits);
    s->thr = o && o->threshold > 0.0 ? o->threshold : BTF_LOD_THRESHOLD;
    if (o && (o->levels < 0 || o->levels > BTF_LOD_MAX_LEVELS))
        return btf_fail(err, BTF_ERR_ARG, "lod: %d levels (1..%d)", o->levels, BTF_LOD_MAX_LEVELS);
    s->nl = btf_lod_levels(s->W, s->H, o ? o->levels : 0);
    if (o && o->levels > s->nl)
        return btf_fail(err, BTF_ERR_ARG, "lod: %d levels do not divide %dx%d texels (at most %d)", o->levels, s->W,
                        s->H, s->nl);
    for (int a = 0; a < s->C; a++)
        for (int e = 0; e < a; e++)
            if (p->chunk[a].component == p->chunk[e].component)
                return btf_fail(err, BTF_ERR_FORMAT, "%s: component %d in two chunks", in_dir, p->chunk[a].component);
    size_t n = (size_t)s->C * s->nl;
    s->lev = calloc(n, sizeof *s->lev), s->atlas = calloc(n, sizeof *s->atlas);
    s->contrib = calloc(n, sizeof(double)), s->tbytes = calloc(n, sizeof(long long));
    s->wbytes = calloc((size_t)s->C, sizeof(long long)), s->order = calloc(2 * n, sizeof(int));
    s->rmse_full = calloc(n, sizeof(double)), s->w8bytes = calloc((size_t)s->C, sizeof(long long));
    s->w8step = calloc((size_t)s->C, sizeof(int)), s->w8q = calloc((size_t)s->C, sizeof *s->w8q);
    s->w8webp = calloc((size_t)s->C, 1);
    s->isres = calloc(n, 1), s->kind = calloc(n, 1), s->w16res = calloc((size_t)s->C, 1), s->pred = calloc(n, sizeof *s->pred);
    s->quality = calloc((size_t)s->C, sizeof(int)), s->codec = calloc((size_t)s->C, sizeof(int)), s->lossy = calloc(n, sizeof *s->lossy);
    s->lossy_n = calloc(n, sizeof(size_t)), s->exact = calloc(n, sizeof *s->exact);
    s->src = o ? o->source : NULL, s->gather = o ? o->gather : NULL;
    if (s->src && !btf_lod_probe_fits(s->src, p))
        return btf_fail(err, BTF_ERR_ARG, "lod: the source (%s, %dx%d) is not the package's size and directions (%dx%d)",
                        s->src->name ? s->src->name : "?", s->src->width, s->src->height, s->W, s->H);
    s->prev_view = malloc((size_t)p->views.n_dirs * sizeof *s->prev_view);
    if (s->prev_view)
        btf_wtz_prev_views(p->blocks->block_of_view, p->views.n_dirs, s->prev_view);
    if (!s->prev_view || !s->w8q || !s->w8webp || !s->isres || !s->kind || !s->pred || !s->w16res || !s->lev || !s->atlas || !s->contrib || !s->tbytes || !s->wbytes || !s->order || !s->rmse_full || !s->w8bytes || !s->w8step || !s->quality || !s->codec || !s->lossy || !s->lossy_n || !s->exact)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory");
    btf__coarse_quality(s, in_dir);
    return BTF_OK;
}


btf_result btf_lod_build(const char *in_dir, const char *out_dir, const btf_lod_options *opt, btf_lod_stats *stats,
                         btf_error *err)
{
    if (!in_dir || !out_dir || strlen(out_dir) > 4000 || !strcmp(in_dir, out_dir))
        return btf_fail(err, BTF_ERR_ARG, "lod: need two different package directories");
    btf__lod s;
    memset(&s, 0, sizeof s);
    btf_lod_stats st = {0};
    btf_result r = btf__lod_setup(&s, in_dir, opt, err);
    if (r == BTF_OK)
        r = btf__make_levels(&s, err);
    if (r == BTF_OK)
        r = btf__match_levels(&s, err);
    if (r == BTF_OK) {
        btf__contribs(&s);
        btf__lod_order(&s);
        r = btf__errors(&s, err);
    }
    char tmp[BTF_FS_PATH_MAX];
    if (r == BTF_OK)
        r = btf_fs_replaceable(out_dir, btf_manifest_owns_dir, NULL, err);
    if (r == BTF_OK && (r = btf_fs_temp_dir(out_dir, tmp, sizeof tmp, btf_manifest_owns_temp, NULL, err)) == BTF_OK) {
        r = btf__write_files(&s, in_dir, tmp, err);
        char *man = r == BTF_OK ? btf__lod_manifest(&s, &st, err) : NULL;
        if (r == BTF_OK && !man)
            r = BTF_ERR_NOMEM;
        char path[BTF_FS_PATH_MAX + 16];
        snprintf(path, sizeof path, "%s/manifest.json", tmp);
        if (r == BTF_OK)
            r = btf_fs_write_atomic(path, man, strlen(man), err);
        free(man);
        if (r == BTF_OK && opt && opt->thumbnail > 0)
            r = btf_package_thumbnail(tmp, opt->thumbnail, err);
        if (r == BTF_OK)
            r = btf_fs_replace_dir(tmp, out_dir, btf_manifest_owns_dir, NULL, err);
        if (r != BTF_OK)
            btf_fs_rmtree(tmp, NULL);
    }
    if (r == BTF_OK && stats) {
        st.levels = s.nl, st.n_chunks = s.n_order;
        for (int a = 0; a < s.C; a++)
            st.bytes_v1 += s.p->chunk[a].bytes;
        *stats = st;
    }
    btf__lod_free(&s);
    return r;
}
