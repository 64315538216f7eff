/* btf_blocks.c - view blocks: which k view directions share one PCA (consecutive
 * or spatial grouping, or an explicit partition read from a manifest). */
#include "btf_blocks.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

const char *btf_blocks_grouping_name(btf_grouping g)
{
    return g == BTF_GROUP_SPATIAL ? "spatial" : "consecutive";
}

const char *btf_blocks_center_name(btf_center c)
{
    return c == BTF_CENTER_ROW ? "row" : "none";
}

/* ---------------------------------------------------------------- blocks */

void btf_blocks_free(btf_blocks *b)
{
    if (!b)
        return;
    free(b->start), free(b->views), free(b->block_of_view), free(b->pos_in_block), free(b);
}

static btf_result btf__blocks_alloc(int n_views, int n_blocks, btf_blocks **out, btf_error *err)
{
    btf_blocks *b = calloc(1, sizeof *b);
    if (!b)
        return btf_fail(err, BTF_ERR_NOMEM, "view blocks: out of memory");
    b->n_views = n_views;
    b->n_blocks = n_blocks;
    b->start = calloc((size_t)n_blocks + 1, sizeof(int));
    b->views = calloc((size_t)n_views, sizeof(int));
    b->block_of_view = calloc((size_t)n_views, sizeof(int));
    b->pos_in_block = calloc((size_t)n_views, sizeof(int));
    if (!b->start || !b->views || !b->block_of_view || !b->pos_in_block) {
        btf_blocks_free(b);
        return btf_fail(err, BTF_ERR_NOMEM, "view blocks: out of memory");
    }
    *out = b;
    return BTF_OK;
}

/* Fills block_of_view/pos_in_block from start/views; checks the partition. */
static btf_result btf__blocks_index(btf_blocks *b, btf_error *err)
{
    for (int v = 0; v < b->n_views; v++)
        b->block_of_view[v] = -1;
    b->k = 0;
    for (int bl = 0; bl < b->n_blocks; bl++) {
        int n = b->start[bl + 1] - b->start[bl];
        if (n < 1)
            return btf_fail(err, BTF_ERR_FORMAT, "view block %d is empty", bl);
        if (n > b->k)
            b->k = n;
        for (int i = 0; i < n; i++) {
            int v = b->views[b->start[bl] + i];
            if (v < 0 || v >= b->n_views)
                return btf_fail(err, BTF_ERR_RANGE, "view block %d: view %d out of range 0..%d", bl, v,
                                b->n_views - 1);
            if (b->block_of_view[v] >= 0)
                return btf_fail(err, BTF_ERR_FORMAT, "view %d appears in blocks %d and %d", v,
                                b->block_of_view[v], bl);
            b->block_of_view[v] = bl;
            b->pos_in_block[v] = i;
        }
    }
    for (int v = 0; v < b->n_views; v++)
        if (b->block_of_view[v] < 0)
            return btf_fail(err, BTF_ERR_FORMAT, "view %d is in no block", v);
    return BTF_OK;
}

static void btf__group_spatial(const btf_dirset *views, int k, btf_blocks *b)
{
    int n = views->n_dirs, pos = 0;
    char *used = calloc((size_t)n, 1);
    float(*vec)[3] = malloc((size_t)n * sizeof *vec);
    if (!used || !vec) { /* fall back to consecutive: still a valid partition */
        for (int v = 0; v < n; v++)
            b->views[v] = v;
        free(used);
        free(vec);
        return;
    }
    for (int v = 0; v < n; v++)
        btf_dirset_vector(views, v, vec[v]);
    for (int bl = 0; bl < b->n_blocks; bl++) {
        b->start[bl] = pos;
        int seed = 0;
        while (used[seed])
            seed++;
        used[seed] = 1;
        b->views[pos++] = seed;
        for (int m = 1; m < k && pos < n; m++) { /* nearest unassigned to the seed */
            int best = -1;
            float bestdot = -2.0f;
            for (int v = 0; v < n; v++) {
                if (used[v])
                    continue;
                float d = vec[v][0] * vec[seed][0] + vec[v][1] * vec[seed][1] + vec[v][2] * vec[seed][2];
                if (d > bestdot + 1e-6f) {
                    bestdot = d;
                    best = v;
                }
            }
            used[best] = 1;
            b->views[pos++] = best;
        }
    }
    b->start[b->n_blocks] = pos;
    free(used);
    free(vec);
}

btf_result btf_blocks_group(const btf_dirset *views, int k, btf_grouping g, btf_blocks **out, btf_error *err)
{
    *out = NULL;
    if (!views || views->n_dirs < 1)
        return btf_fail(err, BTF_ERR_ARG, "view grouping: empty view set");
    int n = views->n_dirs;
    if (k < 1 || k > n)
        return btf_fail(err, BTF_ERR_RANGE, "k = %d views per block: must be 1..%d (the number of views)", k, n);
    btf_blocks *b;
    btf_result r = btf__blocks_alloc(n, (n + k - 1) / k, &b, err);
    if (r != BTF_OK)
        return r;
    if (g == BTF_GROUP_SPATIAL) {
        btf__group_spatial(views, k, b);
    } else {
        for (int v = 0; v < n; v++)
            b->views[v] = v;
        for (int bl = 0; bl <= b->n_blocks; bl++)
            b->start[bl] = bl * k < n ? bl * k : n;
    }
    r = btf__blocks_index(b, err);
    if (r != BTF_OK) {
        btf_blocks_free(b);
        return r;
    }
    *out = b;
    return BTF_OK;
}

btf_result btf_blocks_from_lists(int n_views, int n_blocks, const int *sizes, const int *const *lists,
                                 btf_blocks **out, btf_error *err)
{
    *out = NULL;
    if (n_views < 1 || n_views > BTF_MAX_DIRS || n_blocks < 1 || n_blocks > n_views)
        return btf_fail(err, BTF_ERR_RANGE, "view blocks: %d blocks for %d views", n_blocks, n_views);
    long total = 0;
    for (int bl = 0; bl < n_blocks; bl++) {
        if (sizes[bl] < 1 || sizes[bl] > n_views)
            return btf_fail(err, BTF_ERR_RANGE, "view block %d has %d views", bl, sizes[bl]);
        total += sizes[bl];
    }
    if (total != n_views)
        return btf_fail(err, BTF_ERR_FORMAT, "view blocks hold %ld views, the view set has %d", total, n_views);
    btf_blocks *b;
    btf_result r = btf__blocks_alloc(n_views, n_blocks, &b, err);
    if (r != BTF_OK)
        return r;
    int pos = 0;
    for (int bl = 0; bl < n_blocks; bl++) {
        b->start[bl] = pos;
        for (int i = 0; i < sizes[bl]; i++)
            b->views[pos++] = lists[bl][i];
    }
    b->start[n_blocks] = pos;
    r = btf__blocks_index(b, err);
    if (r != BTF_OK) {
        btf_blocks_free(b);
        return r;
    }
    *out = b;
    return BTF_OK;
}

double btf_blocks_spread(const btf_blocks *b, const btf_dirset *views)
{
    double sum = 0.0;
    long pairs = 0;
    for (int bl = 0; bl < b->n_blocks; bl++)
        for (int i = b->start[bl]; i < b->start[bl + 1]; i++)
            for (int j = i + 1; j < b->start[bl + 1]; j++) {
                float a[3], c[3];
                btf_dirset_vector(views, b->views[i], a);
                btf_dirset_vector(views, b->views[j], c);
                double d = a[0] * c[0] + a[1] * c[1] + a[2] * c[2];
                d = d > 1.0 ? 1.0 : d < -1.0 ? -1.0 : d;
                sum += acos(d) * 180.0 / M_PI;
                pairs++;
            }
    return pairs ? sum / (double)pairs : 0.0;
}

int btf_blocks_cols(const btf *src, const btf_blocks *bl, int b)
{
    return 3 * src->lights.n_dirs * (bl->start[b + 1] - bl->start[b]);
}

