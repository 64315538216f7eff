/* btf_lod_error.h - the error of each spatial level of a package against its source
 * box-filtered to that level (doc/package-format.md section 10.7): CIELab over every
 * measured (view, light) pair at a texel subsample of the level (btf_sample.h), as
 * the compressor measures level 0.
 *
 *     btf_lod_probe pr[4];
 *     btf_lod_probe_make(views, p, 4, 256, pr, &err);   // levels 0..3, one pass over the views
 *     double lab = btf_lod_probe_lab(&pr[1], p, tex1);  // tex1[a]: component a at level 1
 *     btf_lod_probe_free(pr, 4);
 */
#ifndef BTF_LOD_ERROR_H
#define BTF_LOD_ERROR_H

#include "btf_package.h"
#include "btf_views.h"

/* One level's reference at its texel subsample; owned by its caller
 * (btf_lod_probe_free), alive while the levels are measured. */
typedef struct btf_lod_probe {
    int level, w, h; /* the level and its texels per tile side (the package's >> level) */
    int n;           /* texels in the subsample */
    int *xy;         /* [2 n] their level texels (x, y) */
    float *ref;      /* [n V L 3] the source's mean over each texel's 2^level x 2^level block, byte/255 scale */
    float *ref_lab;  /* [n V L 3] CIELab of ref (btf_metrics_lab) */
} btf_lod_probe;

#define BTF_LOD_ERROR_SAMPLE 256 /* texels of a level's subsample (as the compressor's for level 0) */

/* The references of btf_lod_probe_make gathered from views its caller reads itself,
 * each view counted once whenever it comes (btf_lod_compress_views: during the
 * compression's own pass, so the source is not read again). Owned by the caller, from
 * btf_lod_gather_begin to btf_lod_gather_free.
 *
 *     btf_lod_gather g;
 *     btf_lod_gather_begin(views, linear, 4, BTF_LOD_ERROR_SAMPLE, &g, &err);
 *     ... btf_lod_gather_add(&g, v, cols, &err) after each btf_views_fill ...
 *     if (btf_lod_gather_done(&g)) ... g.pr[l] as btf_lod_probe_make's out[l] ...
 *     btf_lod_gather_free(&g);
 */
typedef struct btf_lod_gather {
    btf_lod_probe *pr; /* [n_levels] the references, complete once every view is added */
    int n_levels, linear, width, height, n_views, n_lights;
    int n_seen;          /* views added */
    unsigned char *seen; /* [n_views] 1 once added */
    float *lin;          /* linear packages: the view in linear light (scratch) */
} btf_lod_gather;

/* Starts gathering the references of levels 0..n_levels-1 of a package of src's size
 * and direction sets (linear: the package holds linear light, whose levels average
 * radiance), each at most max_texels texels. */
btf_result btf_lod_gather_begin(const btf_views *src, int linear, int n_levels, int max_texels, btf_lod_gather *g,
                                btf_error *err);
/* Adds view v's columns (as btf_views_fill writes them; not modified) to every level's
 * reference, unless v was added before; the last view also computes their CIELab. */
btf_result btf_lod_gather_add(btf_lod_gather *g, int v, const float *cols, btf_error *err);
/* 1 once every view was added (the references are then complete). */
int btf_lod_gather_done(const btf_lod_gather *g);
void btf_lod_gather_free(btf_lod_gather *g);

/* 1 when src has p's size and direction sets: what btf_lod_probe_make reads. */
int btf_lod_probe_fits(const btf_views *src, const btf_package *p);
/* The references of levels 0..n_levels-1 (out[l]) of package p (its sizes and
 * direction sets; a package without levels, whose chunk a is component a) from src,
 * each at most max_texels texels, in one pass over src's views (btf_views_wrap for a
 * BTF in memory). BTF_ERR_ARG when src is not p's size or directions. */
btf_result btf_lod_probe_make(btf_views *src, const btf_package *p, int n_levels, int max_texels, btf_lod_probe *out,
                              btf_error *err);
/* CIELab (btf_metrics.lab_thesis) of p's reconstruction from tex[a] (component a's
 * texels at the probe's level: n_blocks tiles of w x h, as btf_package.tex at level
 * 0) with p's weights, on the source's scale (btf_package_to_source). */
double btf_lod_probe_lab(const btf_lod_probe *pr, const btf_package *p, const float *const *tex);
void btf_lod_probe_free(btf_lod_probe *pr, int n_levels);

#endif
