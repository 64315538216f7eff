/* btf_blocks.h - view blocks: the k neighbouring view directions that share one
 * PCA (doc/package-format.md). A package's manifest lists its blocks; the
 * compressor groups them.
 *
 *     btf_blocks *bl = NULL;
 *     if (btf_blocks_group(&views, 3, BTF_GROUP_SPATIAL, &bl, &err) == BTF_OK) {
 *         ... bl->views[bl->start[b] .. bl->start[b + 1] - 1] are block b's ...
 *         btf_blocks_free(bl);
 *     }
 */
#ifndef BTF_BLOCKS_H
#define BTF_BLOCKS_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_grouping {
    BTF_GROUP_DEFAULT = 0,  /* = BTF_GROUP_CONSECUTIVE (measured, doc/package-format.md) */
    BTF_GROUP_CONSECUTIVE,  /* thesis: k consecutive views in canonical order */
    BTF_GROUP_SPATIAL       /* greedy: seed view + its k-1 nearest unassigned views */
} btf_grouping;

typedef enum btf_center {
    BTF_CENTER_DEFAULT = 0, /* = BTF_CENTER_NONE */
    BTF_CENTER_NONE,        /* best rank-C approximation of the block */
    BTF_CENTER_ROW          /* thesis: component 0 = texel mean over the block, weight 1 */
} btf_center;

/* View blocks; heap struct owned by whoever made it (btf_blocks_free). */
typedef struct btf_blocks {
    int n_views, n_blocks, k;
    int *start;         /* n_blocks+1: block b owns views[start[b] .. start[b+1]-1] */
    int *views;         /* n_views view indices, block by block */
    int *block_of_view; /* n_views */
    int *pos_in_block;  /* n_views: position of the view inside its block */
} btf_blocks;

/* Groups the views into blocks of k (the last may be smaller) by g. */
btf_result btf_blocks_group(const btf_dirset *views, int k, btf_grouping g, btf_blocks **out, btf_error *err);
/* Builds blocks from an explicit list (lists[b] has sizes[b] views); checks it is a partition. */
btf_result btf_blocks_from_lists(int n_views, int n_blocks, const int *sizes, const int *const *lists,
                                 btf_blocks **out, btf_error *err);
void btf_blocks_free(btf_blocks *b);
/* Mean angular distance (degrees) between views of the same block: a compactness measure. */
double btf_blocks_spread(const btf_blocks *b, const btf_dirset *views);

/* Columns of block b's data matrix: 3 * n_lights * views in block. */
int btf_blocks_cols(const btf *src, const btf_blocks *bl, int b);
/* Manifest names of a grouping and a centring ("consecutive", "spatial"; "none", "row"). */
const char *btf_blocks_grouping_name(btf_grouping g);
const char *btf_blocks_center_name(btf_center c);

#ifdef __cplusplus
}
#endif
#endif
