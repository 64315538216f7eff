/* btf_package_compare.c - a package's error against its source over every texel
 * and (view, light) pair, a tile of texels of one view in memory at a time
 * (btf_package.h). */
#include "btf_package.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>

enum { BTF__COMPARE_TILE = 1024 }; /* texels a pass: their textures stay in cache over every light */

/* m texels from texel i0 of (view v, light l) from the first n chunks into b:
 * btf_package_value of each, a chunk at a time where the package has one level (the
 * same sums in the same order, so the same floats). */
static void btf__package_texels(const btf_package *p, int n, int v, int l, size_t i0, size_t m, float *b)
{
    if (p->n_levels > 1) {
        for (size_t i = 0; i < m; i++)
            btf_package_value(p, v, l, (int)((i0 + i) % (size_t)p->width), (int)((i0 + i) / (size_t)p->width), n,
                              b + 3u * i);
        return;
    }
    memset(b, 0, 3u * m * sizeof(float));
    size_t wi = ((size_t)v * p->lights.n_dirs + l) * 3u;
    size_t at = (size_t)p->blocks->block_of_view[v] * p->width * p->height + i0;
    for (int j = 0; j < n; j++) {
        const float *t = p->tex[j] + at, w0 = p->wt[j][wi], w1 = p->wt[j][wi + 1], w2 = p->wt[j][wi + 2];
        for (size_t i = 0; i < m; i++)
            b[3 * i] += t[i] * w0, b[3 * i + 1] += t[i] * w1, b[3 * i + 2] += t[i] * w2;
    }
    btf_package_to_source(p, b, 3u * m);
}

/* Sums of every light of view v, a tile of texels at a time: a and b hold a tile each. */
static void btf__compare_view(const btf_package *p, int n, const btf *ref, int v, float *a, float *b,
                              btf_metrics_acc *acc)
{
    size_t texels = (size_t)ref->width * ref->height;
    for (size_t i0 = 0; i0 < texels; i0 += BTF__COMPARE_TILE) {
        size_t m = texels - i0 < BTF__COMPARE_TILE ? texels - i0 : BTF__COMPARE_TILE;
        for (int l = 0; l < ref->lights.n_dirs; l++) {
            btf_get_texels(ref, v, l, i0, m, a);
            btf__package_texels(p, n, v, l, i0, m, b);
            btf_metrics_add(acc, a, b, m);
        }
    }
}

static btf_result btf__compare_check(const btf_package *p, int n, const btf *ref, btf_error *err)
{
    if (ref->width != p->width || ref->height != p->height)
        return btf_fail(err, BTF_ERR_ARG, "package compare: sizes differ (%dx%d vs %dx%d)", ref->width,
                        ref->height, p->width, p->height);
    if (!btf_dirset_equal(&ref->lights, &p->lights) || !btf_dirset_equal(&ref->views, &p->views))
        return btf_fail(err, BTF_ERR_ARG, "package compare: the direction sets differ");
    if ((ref->storage != BTF_U8 && ref->storage != BTF_F32) || !ref->data)
        return btf_fail(err, BTF_ERR_ARG, "package compare: the reference has no data it can read");
    if (n < 1 || n > p->n_loaded)
        return btf_fail(err, BTF_ERR_ARG, "package compare: %d chunks asked, %d loaded", n, p->n_loaded);
    return BTF_OK;
}

btf_result btf_package_compare(const btf_package *p, int n, const btf *ref, btf_metrics *out, btf_error *err)
{
    if (!p || !ref || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_package_compare: NULL argument");
    btf_result r = btf__compare_check(p, n, ref, err);
    if (r != BTF_OK)
        return r;
    int V = ref->views.n_dirs, failed = 0;
    size_t floats = 3u * BTF__COMPARE_TILE;
    btf_metrics_acc *part = calloc((size_t)V, sizeof *part);
    if (!part)
        return btf_fail(err, BTF_ERR_NOMEM, "package compare: out of memory");
#pragma omp parallel if ((size_t)ref->width * ref->height * ref->lights.n_dirs * (size_t)V >= BTF_METRICS_THREAD_MIN_PIXELS)
    {
        float *a = malloc(floats * sizeof(float)), *b = malloc(floats * sizeof(float));
        if (!a || !b) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 1)
        for (int v = 0; v < V; v++)
            if (a && b)
                btf__compare_view(p, n, ref, v, a, b, &part[v]);
        free(a);
        free(b);
    }
    btf_metrics_acc acc = {0};
    for (int v = 0; v < V; v++) { /* in view order: the same sums whatever the thread count */
        acc.sum_abs += part[v].sum_abs, acc.sum_sq += part[v].sum_sq;
        acc.sum_lab += part[v].sum_lab, acc.sum_de += part[v].sum_de;
        acc.samples += part[v].samples, acc.pixels += part[v].pixels;
    }
    free(part);
    if (failed)
        return btf_fail(err, BTF_ERR_NOMEM, "package compare: out of memory (%zu floats a thread)", 2 * floats);
    btf_metrics_finish(&acc, out);
    return BTF_OK;
}
