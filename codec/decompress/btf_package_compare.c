/* btf_package_compare.c - a package's error against its source over every texel
 * and (view, light) pair, a tile of texels of one view in memory at a time
 * (btf_package.h); several prefixes in one pass. */
#include "btf_package.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>

enum { BTF__COMPARE_TILE = 1024 }; /* texels a pass: their textures stay in cache over every light */

/* m texels from texel i0 of (view v, light l) of a levelled package from the first n
 * chunks into b: btf_package_value of each. */
static void btf__package_texels(const btf_package *p, int n, int v, int l, size_t i0, size_t m, float *b)
{
    for (size_t i = 0; i < m; i++)
        btf_package_value(p, v, l, (int)((i0 + i) % (size_t)p->width), (int)((i0 + i) / (size_t)p->width), n,
                          b + 3u * i);
}

/* Per-thread buffers of one tile (malloc'd, 3 * BTF__COMPARE_TILE floats each): the
 * reference, its Lab, a prefix's decode and the running sum of the chunks; displayed:
 * each decode rounded to the 8-bit codes a display stores before it is measured. */
typedef struct btf__tile_bufs {
    float *a, *a_lab, *b, *sum;
    int displayed;
} btf__tile_bufs;

/* Adds the decode of a prefix in t->b (m texels; rounded first where t->displayed)
 * to acc against the reference in t->a, t->a_lab. */
static void btf__add_decode(btf__tile_bufs *t, size_t m, btf_metrics_acc *acc)
{
    if (t->displayed)
        btf_metrics_displayed(t->b, 3u * m);
    btf_metrics_add_lab(acc, t->a, t->a_lab, t->b, m);
}

/* Adds the decode of prefix ns[i] (tile of m texels from i0 of (v, l)) to acc[i] for
 * every i; a and a_lab hold the reference. Without levels one running sum of the
 * chunks, a chunk at a time, serves every prefix: the same sums in the same order as
 * btf_package_value's, so the same floats. */
static void btf__compare_prefixes(const btf_package *p, const int *ns, int count, int v, int l, size_t i0, size_t m,
                                  btf__tile_bufs *t, btf_metrics_acc *acc)
{
    if (p->n_levels > 1) {
        for (int i = 0; i < count; i++) {
            btf__package_texels(p, ns[i], v, l, i0, m, t->b);
            btf__add_decode(t, m, &acc[i]);
        }
        return;
    }
    int top = 0;
    for (int i = 0; i < count; i++)
        top = ns[i] > top ? ns[i] : top;
    memset(t->sum, 0, 3u * m * sizeof(float));
    size_t wi = ((size_t)v * p->lights.n_dirs + l) * 3u;
    size_t at = (size_t)p->blocks->block_of_view[v] * p->width * p->height + i0;
    for (int j = 0; j < top; j++) {
        const float *tx = p->tex[j] + at, w0 = p->wt[j][wi], w1 = p->wt[j][wi + 1], w2 = p->wt[j][wi + 2];
        for (size_t i = 0; i < m; i++)
            t->sum[3 * i] += tx[i] * w0, t->sum[3 * i + 1] += tx[i] * w1, t->sum[3 * i + 2] += tx[i] * w2;
        for (int i = 0; i < count; i++)
            if (ns[i] == j + 1) {
                memcpy(t->b, t->sum, 3u * m * sizeof(float));
                btf_package_to_source(p, t->b, 3u * m);
                btf__add_decode(t, m, &acc[i]);
            }
    }
}

/* Sums of every light of view v for every prefix (acc[i]), a tile of texels at a
 * time; the reference's Lab once per tile and light. */
static void btf__compare_view(const btf_package *p, const int *ns, int count, const btf *ref, int v,
                              btf__tile_bufs *t, btf_metrics_acc *acc)
{
    size_t texels = (size_t)ref->width * ref->height;
    for (size_t i0 = 0; i0 < texels; i0 += BTF__COMPARE_TILE) {
        size_t m = texels - i0 < BTF__COMPARE_TILE ? texels - i0 : BTF__COMPARE_TILE;
        for (int l = 0; l < ref->lights.n_dirs; l++) {
            btf_get_texels(ref, v, l, i0, m, t->a);
            btf_metrics_lab(t->a, m, t->a_lab);
            btf__compare_prefixes(p, ns, count, v, l, i0, m, t, acc);
        }
    }
}

static btf_result btf__compare_check(const btf_package *p, const int *ns, int count, const btf *ref, btf_error *err)
{
    if (ref->width != p->width || ref->height != p->height)
        return btf_fail(err, BTF_ERR_ARG, "package compare: sizes differ (%dx%d vs %dx%d)", ref->width,
                        ref->height, p->width, p->height);
    if (!btf_dirset_equal(&ref->lights, &p->lights) || !btf_dirset_equal(&ref->views, &p->views))
        return btf_fail(err, BTF_ERR_ARG, "package compare: the direction sets differ");
    if ((ref->storage != BTF_U8 && ref->storage != BTF_F32) || !ref->data)
        return btf_fail(err, BTF_ERR_ARG, "package compare: the reference has no data it can read");
    if (count < 1 || count > BTF_PACKAGE_COMPARE_MAX)
        return btf_fail(err, BTF_ERR_ARG, "package compare: %d prefixes asked (1..%d)", count,
                        BTF_PACKAGE_COMPARE_MAX);
    for (int i = 0; i < count; i++)
        if (ns[i] < 1 || ns[i] > p->n_loaded)
            return btf_fail(err, BTF_ERR_ARG, "package compare: %d chunks asked, %d loaded", ns[i], p->n_loaded);
    return BTF_OK;
}

btf_result btf_package_compare_with(const btf_package *p, const int *ns, int count, const btf *ref,
                                    const btf_compare_options *o, btf_metrics *out, btf_error *err)
{
    if (!p || !ns || !ref || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_package_compare: NULL argument");
    btf_result r = btf__compare_check(p, ns, count, ref, err);
    if (r != BTF_OK)
        return r;
    int V = ref->views.n_dirs, failed = 0;
    size_t floats = 3u * BTF__COMPARE_TILE;
    btf_metrics_acc *part = calloc((size_t)V * count, sizeof *part);
    if (!part)
        return btf_fail(err, BTF_ERR_NOMEM, "package compare: out of memory");
#pragma omp parallel if ((size_t)ref->width * ref->height * ref->lights.n_dirs * (size_t)V >= BTF_METRICS_THREAD_MIN_PIXELS)
    {
        float *buf = malloc(4 * floats * sizeof(float));
        btf__tile_bufs t = {buf, buf + floats, buf + 2 * floats, buf + 3 * floats, o && o->displayed};
        if (!buf) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 1)
        for (int v = 0; v < V; v++)
            if (buf)
                btf__compare_view(p, ns, count, ref, v, &t, part + (size_t)v * count);
        free(buf);
    }
    for (int i = 0; i < count && !failed; i++) {
        btf_metrics_acc acc = {0};
        for (int v = 0; v < V; v++) /* in view order: the same sums whatever the thread count */
            btf_metrics_merge(&acc, &part[(size_t)v * count + i]);
        btf_metrics_finish(&acc, &out[i]);
    }
    free(part);
    if (failed)
        return btf_fail(err, BTF_ERR_NOMEM, "package compare: out of memory (%zu floats a thread)", 4 * floats);
    return BTF_OK;
}

btf_result btf_package_compare_prefixes(const btf_package *p, const int *ns, int count, const btf *ref,
                                        btf_metrics *out, btf_error *err)
{
    return btf_package_compare_with(p, ns, count, ref, NULL, out, err);
}

btf_result btf_package_compare(const btf_package *p, int n, const btf *ref, btf_metrics *out, btf_error *err)
{
    return btf_package_compare_with(p, &n, 1, ref, NULL, out, err);
}
