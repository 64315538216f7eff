/* btf_lod_error.c - a level's error against the source box-filtered to it (btf_lod_error.h). */
#include "btf_lod_error.h"
#include "btf_sample.h"

#include "btf_metrics.h"
#include "btf_color.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>

/* The source's mean over level texel (x, y)'s block for every (view, light, channel),
 * in linear light for a linear package (whose levels average radiance). */
static void probe_ref(const btf *src, int linear, int f, int x, int y, float *row, float *out)
{
    int V = src->views.n_dirs, L = src->lights.n_dirs;
    size_t per = (size_t)V * L * 3;
    memset(out, 0, per * sizeof(float));
    for (int v = 0; v < V; v++)
        for (int l = 0; l < L; l++) {
            float *o = out + ((size_t)v * L + l) * 3;
            for (int dy = 0; dy < f; dy++) {
                btf_get_texels(src, v, l, (size_t)(y * f + dy) * src->width + (size_t)x * f, (size_t)f, row);
                if (linear)
                    btf_color_srgb_decode_n(row, (size_t)f * 3);
                for (int i = 0; i < f; i++)
                    o[0] += row[3 * i], o[1] += row[3 * i + 1], o[2] += row[3 * i + 2];
            }
            float s = 1.0f / (float)(f * f);
            o[0] *= s, o[1] *= s, o[2] *= s;
        }
    if (linear)
        btf_color_srgb_encode_n(out, per);
}

btf_result btf_lod_probe_make(const btf *src, const btf_package *p, int level, int max_texels, btf_lod_probe *out,
                              btf_error *err)
{
    memset(out, 0, sizeof *out);
    if (!src || src->width != p->width || src->height != p->height || !btf_dirset_equal(&src->views, &p->views) ||
        !btf_dirset_equal(&src->lights, &p->lights) || level < 0 || level > 15)
        return btf_fail(err, BTF_ERR_ARG, "lod: the source is not the package's size and directions");
    int f = 1 << level, w = p->width / f, h = p->height / f, s = btf_sample_stride(w, h, max_texels);
    int sw = (w + s - 1) / s, sh = (h + s - 1) / s;
    size_t per = (size_t)p->views.n_dirs * p->lights.n_dirs * 3, n = (size_t)sw * sh;
    out->level = level, out->w = w, out->h = h, out->n = (int)n;
    out->xy = malloc(2 * n * sizeof(int));
    out->ref = malloc(n * per * sizeof(float)), out->ref_lab = malloc(n * per * sizeof(float));
    float *row = malloc((size_t)f * 3 * sizeof(float));
    if (!out->xy || !out->ref || !out->ref_lab || !row) {
        free(row), btf_lod_probe_free(out);
        return btf_fail(err, BTF_ERR_NOMEM, "lod: out of memory (level error)");
    }
    for (int sy = 0, i = 0; sy < sh; sy++)
        for (int sx = 0; sx < sw; sx++, i++) {
            btf_sample_texel(s, w, h, sx, sy, &out->xy[2 * i], &out->xy[2 * i + 1]);
            probe_ref(src, p->linear, f, out->xy[2 * i], out->xy[2 * i + 1], row, out->ref + (size_t)i * per);
            btf_metrics_lab(out->ref + (size_t)i * per, per / 3, out->ref_lab + (size_t)i * per);
        }
    free(row);
    return BTF_OK;
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

void btf_lod_probe_free(btf_lod_probe *pr)
{
    free(pr->xy), free(pr->ref), free(pr->ref_lab);
    memset(pr, 0, sizeof *pr);
}
