/* btf_lod_error.c - each level's error against the source box-filtered to it (btf_lod_error.h). */
#include "btf_lod_error.h"
#include "btf_sample.h"

#include "btf_metrics.h"
#include "btf_color.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>

/* Level `level`'s subsample and its buffers, for g's sizes (the reference filled later). */
static btf_result probe_alloc(const btf_lod_gather *g, int level, int max_texels, btf_lod_probe *out, btf_error *err)
{
    int f = 1 << level, w = g->width / f, h = g->height / f, s = btf_sample_stride(w, h, max_texels);
    int sw = (w + s - 1) / s, sh = (h + s - 1) / s;
    size_t per = (size_t)g->n_views * g->n_lights * 3, n = (size_t)sw * sh;
    out->level = level, out->w = w, out->h = h, out->n = (int)n;
    out->xy = malloc(2 * n * sizeof(int));
    out->ref = malloc(n * per * sizeof(float)), out->ref_lab = malloc(n * per * sizeof(float));
    if (!out->xy || !out->ref || !out->ref_lab)
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (level error)");
    for (int sy = 0, i = 0; sy < sh; sy++)
        for (int sx = 0; sx < sw; sx++, i++)
            btf_sample_texel(s, w, h, sx, sy, &out->xy[2 * i], &out->xy[2 * i + 1]);
    return BTF_OK;
}

/* Adds view v's block means into pr's reference: cols is the view's planar columns
 * (btf_views.h), in linear light for a linear package (whose levels average radiance). */
static void probe_add_view(btf_lod_probe *pr, const btf_lod_gather *g, int v, const float *cols)
{
    int L = g->n_lights, W = g->width, f = 1 << pr->level;
    size_t per = (size_t)g->n_views * L * 3, texels = (size_t)W * g->height;
    float s = 1.0f / (float)(f * f);
    for (int i = 0; i < pr->n; i++) {
        int x0 = pr->xy[2 * i] * f, y0 = pr->xy[2 * i + 1] * f;
        float *o = pr->ref + (size_t)i * per + (size_t)v * L * 3;
        for (int k = 0; k < L * 3; k++) {
            const float *plane = cols + (size_t)k * texels;
            float sum = 0.0f;
            for (int dy = 0; dy < f; dy++)
                for (int dx = 0; dx < f; dx++)
                    sum += plane[(size_t)(y0 + dy) * W + x0 + dx];
            o[k] = sum * s;
        }
        if (g->linear)
            btf_color_srgb_encode_n(o, (size_t)L * 3);
    }
}

/* btf_lod_gather_begin; with lin_buffer 0 no buffer for a linear source's copy (the
 * caller hands gather_add views already in linear light). */
static btf_result gather_begin(const btf_views *src, int linear, int n_levels, int max_texels, int lin_buffer,
                               btf_lod_gather *g, btf_error *err)
{
    memset(g, 0, sizeof *g);
    if (n_levels < 1 || n_levels > 16 || src->width % (1 << (n_levels - 1)) || src->height % (1 << (n_levels - 1)))
        return btf_fail(err, BTF_ERR_ARG, "lod: %d levels of %dx%d texels", n_levels, src->width, src->height);
    g->n_levels = n_levels, g->linear = linear, g->width = src->width, g->height = src->height;
    g->n_views = src->views.n_dirs, g->n_lights = src->lights.n_dirs;
    g->pr = calloc((size_t)n_levels, sizeof *g->pr), g->seen = calloc((size_t)g->n_views, 1);
    int copy = linear && lin_buffer;
    g->lin = copy ? malloc(btf_views_floats(src) * sizeof(float)) : NULL;
    btf_result r = g->pr && g->seen && (g->lin || !copy) ? BTF_OK
                                                            : btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (level error)");
    for (int l = 0; r == BTF_OK && l < n_levels; l++)
        r = probe_alloc(g, l, max_texels, &g->pr[l], err);
    if (r != BTF_OK)
        btf_lod_gather_free(g);
    return r;
}

btf_result btf_lod_gather_begin(const btf_views *src, int linear, int n_levels, int max_texels, btf_lod_gather *g,
                                btf_error *err)
{
    return gather_begin(src, linear, n_levels, max_texels, 1, g, err);
}

/* btf_lod_gather_add; with decoded 1 a linear source's cols are already in linear light. */
static btf_result gather_add(btf_lod_gather *g, int v, const float *cols, int decoded, btf_error *err)
{
    if (v < 0 || v >= g->n_views)
        return btf_fail(err, BTF_ERR_ARG, "lod: view %d of %d", v, g->n_views);
    if (g->seen[v])
        return BTF_OK;
    if (g->linear && !decoded) {
        size_t nc = (size_t)3 * g->n_lights * g->width * g->height;
        memcpy(g->lin, cols, nc * sizeof(float));
        btf_color_srgb_decode_n(g->lin, nc);
        cols = g->lin;
    }
    for (int l = 0; l < g->n_levels; l++)
        probe_add_view(&g->pr[l], g, v, cols);
    g->seen[v] = 1;
    if (++g->n_seen < g->n_views)
        return BTF_OK;
    size_t per = (size_t)g->n_views * g->n_lights * 3;
    for (int l = 0; l < g->n_levels; l++)
        for (int i = 0; i < g->pr[l].n; i++)
            btf_metrics_lab(g->pr[l].ref + (size_t)i * per, per / 3, g->pr[l].ref_lab + (size_t)i * per);
    return BTF_OK;
}

btf_result btf_lod_gather_add(btf_lod_gather *g, int v, const float *cols, btf_error *err)
{
    return gather_add(g, v, cols, 0, err);
}

int btf_lod_gather_done(const btf_lod_gather *g)
{
    return g->pr && g->n_seen == g->n_views;
}

void btf_lod_gather_free(btf_lod_gather *g)
{
    if (g->pr)
        btf_lod_probe_free(g->pr, g->n_levels);
    free(g->pr), free(g->seen), free(g->lin);
    memset(g, 0, sizeof *g);
}

int btf_lod_probe_fits(const btf_views *src, const btf_package *p)
{
    return src && src->width == p->width && src->height == p->height && btf_dirset_equal(&src->views, &p->views) &&
           btf_dirset_equal(&src->lights, &p->lights);
}

btf_result btf_lod_probe_make(btf_views *src, const btf_package *p, int n_levels, int max_texels, btf_lod_probe *out,
                              btf_error *err)
{
    memset(out, 0, (size_t)n_levels * sizeof *out);
    if (!btf_lod_probe_fits(src, p) || n_levels < 1 || n_levels > 16)
        return btf_fail(err, BTF_ERR_ARG, "lod: the source is not the package's size and directions");
    btf_lod_gather g; /* one view buffer: a linear view is decoded in place */
    btf_result r = gather_begin(src, p->linear, n_levels, max_texels, 0, &g, err);
    size_t nc = btf_views_floats(src);
    float *cols = r == BTF_OK ? malloc(nc * sizeof(float)) : NULL;
    if (r == BTF_OK && !cols)
        r = btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (level error)");
    for (int v = 0; r == BTF_OK && v < p->views.n_dirs; v++) {
        r = btf_views_fill(src, v, cols, err);
        if (r == BTF_OK && p->linear)
            btf_color_srgb_decode_n(cols, nc);
        if (r == BTF_OK)
            r = gather_add(&g, v, cols, 1, err);
    }
    free(cols);
    if (r == BTF_OK) { /* the references move to out */
        memcpy(out, g.pr, (size_t)n_levels * sizeof *out);
        memset(g.pr, 0, (size_t)n_levels * sizeof *out);
    }
    btf_lod_gather_free(&g);
    return r;
}

double btf_lod_probe_lab(const btf_lod_probe *pr, const btf_package *p, const float *const *tex)
{
    int V = p->views.n_dirs, L = p->lights.n_dirs, C = p->n_chunks;
    size_t per = (size_t)V * L * 3, wh = (size_t)pr->w * pr->h;
    float *test = malloc(per * sizeof(float)), *tv = malloc((size_t)(C > 0 ? C : 1) * sizeof(float));
    btf_metrics_acc acc = {0};
    for (int i = 0; test && tv && i < pr->n; i++) {
        size_t t = (size_t)pr->xy[2 * i + 1] * pr->w + (size_t)pr->xy[2 * i];
        for (int v = 0; v < V; v++) {
            int b = p->blocks->block_of_view[v];
            for (int a = 0; a < C; a++)
                tv[a] = tex[a][(size_t)b * wh + t];
            for (size_t k = (size_t)v * L * 3; k < (size_t)(v + 1) * L * 3; k++) {
                float s = 0.0f;
                for (int a = 0; a < C; a++)
                    s += tv[a] * p->wt[a][k];
                test[k] = s;
            }
        }
        btf_package_to_source(p, test, per);
        btf_metrics_add_lab(&acc, pr->ref + (size_t)i * per, pr->ref_lab + (size_t)i * per, test, per / 3);
    }
    btf_metrics m = {0};
    if (test && tv)
        btf_metrics_finish(&acc, &m);
    free(test), free(tv);
    return test && tv ? m.lab_thesis : -1.0;
}

void btf_lod_probe_free(btf_lod_probe *pr, int n_levels)
{
    for (int l = 0; l < n_levels; l++) {
        free(pr[l].xy), free(pr[l].ref), free(pr[l].ref_lab);
        memset(&pr[l], 0, sizeof pr[l]);
    }
}
