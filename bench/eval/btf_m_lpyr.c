/* btf_m_lpyr.c - "lpyr": Laplacian-pyramid PCA (Ma et al.'s Laplacian-pyramid BTF compression).
 *
 * Every (view, light) image F_0 is reduced to F_{i+1} = 2x2 box average of F_i
 * (edge texels repeated for odd sizes); level i < top holds the Laplacian
 * coefficients L_i = F_i - up(F_{i+1}) (nearest upsampling), the top level holds the
 * low-pass F_top. Each level is stored as an F32 BTF of its own size and compressed
 * with the project's k-view block PCA (btf_pca.h, C components, no centring), so
 *     F_0(x, y) = F_top(x >> top, y >> top) + sum_i L_i(x >> i, y >> i)
 * exactly when C is full rank. Decoding may use only the coarsest n levels: the
 * BTF as a far or small surface shows it (the finer levels add detail only).
 * Memory: one full-size float level exists at a time during encoding. */
#include "btf_method.h"

#include <stdlib.h>
#include <string.h>

#include "btf_pca.h"
#include "btf_common.h"

#define BTF__LPYR_MAX 12

/* Pyramid model: one PCA model per level (0 = finest); owned by its btf_model. */
typedef struct btf__lpyr {
    int n_levels;
    int decode_levels; /* coarsest levels used by decode; = n_levels for all */
    btf_pca_model *level[BTF__LPYR_MAX];
} btf__lpyr;

static void btf__lpyr_free(void *impl)
{
    btf__lpyr *p = impl;
    if (!p)
        return;
    for (int i = 0; i < p->n_levels; i++)
        btf_pca_model_free(p->level[i]);
    free(p);
}

/* 2x2 box reduction of every image of f (w x h) into a new F32 BTF of ceil sizes. */
static btf_result btf__reduce(const btf *f, btf **out, btf_error *err)
{
    int w = (f->width + 1) / 2, h = (f->height + 1) / 2;
    btf_result r = btf_create(w, h, &f->lights, &f->views, BTF_F32, out, err);
    if (r != BTF_OK)
        return r;
    float *d = (*out)->data;
    for (int v = 0; v < f->views.n_dirs; v++)
        for (int l = 0; l < f->lights.n_dirs; l++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    for (int c = 0; c < 3; c++) {
                        int x0 = 2 * x, y0 = 2 * y;
                        int x1 = x0 + 1 < f->width ? x0 + 1 : x0, y1 = y0 + 1 < f->height ? y0 + 1 : y0;
                        float s = btf_get(f, v, l, x0, y0, c) + btf_get(f, v, l, x1, y0, c) +
                                  btf_get(f, v, l, x0, y1, c) + btf_get(f, v, l, x1, y1, c);
                        d[btf_index(*out, v, l, x, y, c)] = 0.25f * s;
                    }
    return BTF_OK;
}

/* L = f - up(coarse), an F32 BTF of f's size. */
static btf_result btf__laplacian(const btf *f, const btf *coarse, btf **out, btf_error *err)
{
    btf_result r = btf_create(f->width, f->height, &f->lights, &f->views, BTF_F32, out, err);
    if (r != BTF_OK)
        return r;
    float *d = (*out)->data;
    for (int v = 0; v < f->views.n_dirs; v++)
        for (int l = 0; l < f->lights.n_dirs; l++)
            for (int y = 0; y < f->height; y++)
                for (int x = 0; x < f->width; x++)
                    for (int c = 0; c < 3; c++)
                        d[btf_index(*out, v, l, x, y, c)] =
                            btf_get(f, v, l, x, y, c) - btf_get(coarse, v, l, x / 2, y / 2, c);
    return BTF_OK;
}

/* PCA of one level with k and C clamped to what the level allows. */
static btf_result btf__lpyr_pca(const btf *lev, const btf_method_params *p, btf_pca_model **out, btf_error *err)
{
    btf_pca_options o = {0};
    int V = lev->views.n_dirs;
    o.k = p->k <= 0 ? 3 : p->k > V ? V : p->k;
    int smallest = V % o.k ? V % o.k : o.k;
    long mn = (long)lev->width * lev->height, cols = 3L * lev->lights.n_dirs * smallest;
    mn = cols < mn ? cols : mn;
    o.components = p->components > mn ? (int)mn : p->components;
    o.center = BTF_CENTER_NONE;
    return btf_pca_compress(lev, &o, NULL, NULL, out, err);
}

/* Number of levels: as asked (default 3), no more than halvings down to 1 texel + 1. */
static int btf__lpyr_count(const btf *src, int asked)
{
    int n = asked <= 0 ? 3 : asked, fit = 1, w = src->width, h = src->height;
    while ((w > 1 || h > 1) && fit < BTF__LPYR_MAX) {
        w = (w + 1) / 2, h = (h + 1) / 2;
        fit++;
    }
    return n > fit ? fit : n;
}

static btf_result btf__lpyr_encode(const btf *src, btf_model *m, btf_error *err)
{
    btf_method_params *p = &m->params;
    if (p->components <= 0)
        p->components = 8;
    p->levels = btf__lpyr_count(src, p->levels);
    btf__lpyr *py = calloc(1, sizeof *py);
    if (!py)
        return btf_fail(err, BTF_ERR_NOMEM, "lpyr: cannot allocate the model");
    btf_result r = BTF_OK;
    btf *f = NULL; /* F_i (NULL: the source itself) */
    for (int i = 0; i < p->levels && r == BTF_OK; i++) {
        const btf *fi = f ? f : src;
        btf *coarse = NULL, *lap = NULL;
        if (i + 1 < p->levels) {
            r = btf__reduce(fi, &coarse, err);
            if (r == BTF_OK)
                r = btf__laplacian(fi, coarse, &lap, err);
        }
        if (r == BTF_OK)
            r = btf__lpyr_pca(lap ? lap : fi, p, &py->level[i], err);
        if (r == BTF_OK)
            py->n_levels = i + 1;
        btf_free(lap);
        btf_free(f);
        f = coarse;
    }
    btf_free(f);
    if (r != BTF_OK) {
        btf__lpyr_free(py);
        return r;
    }
    py->decode_levels = p->decode_levels <= 0 || p->decode_levels > py->n_levels ? py->n_levels : p->decode_levels;
    m->impl = py;
    return BTF_OK;
}

static void btf__lpyr_decode(const btf_model *m, int x, int y, const float light[3], const float view[3],
                             float rgb[3])
{
    const btf__lpyr *py = m->impl;
    btf_interp il = btf_dirset_interp_vec(&m->lights, light);
    btf_interp iv = btf_dirset_interp_vec(&m->views, view);
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    for (int i = py->n_levels - py->decode_levels; i < py->n_levels; i++) {
        const btf_pca_model *pm = py->level[i];
        for (int a = 0; a < 3; a++)
            for (int e = 0; e < 3; e++) {
                float w = iv.w[a] * il.w[e];
                if (w == 0.0f)
                    continue;
                for (int c = 0; c < 3; c++)
                    rgb[c] += w * btf_pca_model_value(pm, iv.idx[a], il.idx[e], x >> i, y >> i, c, pm->n_comp);
            }
    }
}

static size_t btf__lpyr_bytes(const btf_model *m)
{
    const btf__lpyr *py = m->impl;
    size_t n = 0;
    for (int i = 0; i < py->n_levels; i++)
        for (int b = 0; b < py->level[i]->blocks->n_blocks; b++) {
            const btf_pca_block *blk = &py->level[i]->block[b];
            n += ((size_t)blk->rows + blk->cols) * blk->n_comp * sizeof(float);
        }
    return n;
}

static void btf__lpyr_cost(const btf_model *m, btf_method_cost *out)
{
    const btf__lpyr *py = m->impl;
    out->fetches = out->flops = 0;
    for (int i = py->n_levels - py->decode_levels; i < py->n_levels; i++) {
        int C = py->level[i]->n_comp;
        out->fetches += 3 * C * (1 + 9);
        out->flops += 3 * C * 2 * 9;
    }
    out->flops += 200;
}

int btf_lpyr_levels(const btf_model *m)
{
    return m && m->method == &btf_method_lpyr ? ((const btf__lpyr *)m->impl)->n_levels : 0;
}

void btf_lpyr_set_decode_levels(btf_model *m, int n)
{
    if (!m || m->method != &btf_method_lpyr)
        return;
    btf__lpyr *py = m->impl;
    py->decode_levels = n <= 0 || n > py->n_levels ? py->n_levels : n;
    m->params.decode_levels = py->decode_levels;
}

float btf_lpyr_level_value(const btf_model *m, int level, int view, int light, int x, int y, int c)
{
    if (!m || m->method != &btf_method_lpyr)
        return 0.0f;
    const btf__lpyr *py = m->impl;
    if (level < 0 || level >= py->n_levels)
        return 0.0f;
    const btf_pca_model *pm = py->level[level];
    if (x < 0 || y < 0 || x >= pm->width || y >= pm->height)
        return 0.0f;
    return btf_pca_model_value(pm, view, light, x, y, c, pm->n_comp);
}

const btf_method btf_method_lpyr = {
    "lpyr", "Laplacian-pyramid PCA: per-level k-view PCA, coarse levels first", 1,
    btf__lpyr_encode, btf__lpyr_decode, btf__lpyr_bytes, btf__lpyr_cost, btf__lpyr_free,
};
