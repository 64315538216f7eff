/* btf_package_compare.c - a package's error against its source over every texel
 * and (view, light) pair, one view in memory at a time (btf_package.h). */
#include "btf_package.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>

/* Image (view, light) of ref as byte/255 floats into a (W * H * 3). */
static void btf__ref_image(const btf *ref, int v, int l, float *a)
{
    size_t n = (size_t)ref->width * ref->height * 3u, at = btf_index(ref, v, l, 0, 0, 0);
    if (ref->storage == BTF_F32) {
        memcpy(a, (const float *)ref->data + at, n * sizeof(float));
        return;
    }
    const uint8_t *s = (const uint8_t *)ref->data + at;
    for (size_t i = 0; i < n; i++)
        a[i] = s[i] * (1.0f / 255.0f);
}

/* Image (view v, light l) of the first n chunks into b (W * H * 3): btf_package_value
 * of every texel, a chunk at a time where the package has one level (the same sums in
 * the same order, so the same floats). */
static void btf__package_image(const btf_package *p, int n, int v, int l, float *b)
{
    size_t texels = (size_t)p->width * p->height;
    if (p->n_levels > 1) {
        for (int y = 0; y < p->height; y++)
            for (int x = 0; x < p->width; x++)
                btf_package_value(p, v, l, x, y, n, b + ((size_t)y * p->width + x) * 3u);
        return;
    }
    memset(b, 0, texels * 3u * sizeof(float));
    size_t wi = ((size_t)v * p->lights.n_dirs + l) * 3u, at = (size_t)p->blocks->block_of_view[v] * texels;
    for (int j = 0; j < n; j++) {
        const float *t = p->tex[j] + at, w0 = p->wt[j][wi], w1 = p->wt[j][wi + 1], w2 = p->wt[j][wi + 2];
        for (size_t i = 0; i < texels; i++)
            b[3 * i] += t[i] * w0, b[3 * i + 1] += t[i] * w1, b[3 * i + 2] += t[i] * w2;
    }
    btf_package_to_source(p, b, texels * 3u);
}

/* Sums of every light of view v: a and b are one image each of scratch. */
static void btf__compare_view(const btf_package *p, int n, const btf *ref, int v, float *a, float *b,
                              btf_metrics_acc *acc)
{
    for (int l = 0; l < ref->lights.n_dirs; l++) {
        btf__ref_image(ref, v, l, a);
        btf__package_image(p, n, v, l, b);
        btf_metrics_add(acc, a, b, (size_t)ref->width * ref->height);
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
    size_t floats = (size_t)ref->width * ref->height * 3u;
    btf_metrics_acc *part = calloc((size_t)V, sizeof *part);
    if (!part)
        return btf_fail(err, BTF_ERR_NOMEM, "package compare: out of memory");
#pragma omp parallel if (floats * (size_t)ref->lights.n_dirs * (size_t)V >= BTF_METRICS_THREAD_MIN_PIXELS)
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
        return btf_fail(err, BTF_ERR_NOMEM, "package compare: out of memory (%zu floats a view)", 2 * floats);
    btf_metrics_finish(&acc, out);
    return BTF_OK;
}
