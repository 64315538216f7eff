/* btf_lod.h - spatial levels of detail of a package (doc/package-format.md,
 * version 2) and the scene-driven chunk selection.
 *
 *     btf_lod_options o = {0};  o.levels = 4;
 *     btf_lod_build("lib/wool-v1", "lib/wool", &o, NULL, &err);   // v1 -> v2 with mips
 *
 *     btf_lod_view v = {0};
 *     v.texels_per_pixel = btf_lod_footprint(p->width, 1.0, 300.0); // 300-px thumbnail
 *     v.threshold = BTF_LOD_THRESHOLD;
 *     btf_lod_selection s;
 *     btf_lod_select(p, &v, &s, NULL);  // s.limit = chunks to ask the server for
 *
 * The client (client/btf-lod.js) implements btf_lod_select with the same rule; the
 * shared cases in tests/e2e/ check both.
 *
 * With o.residual = 1 the builder writes version 4 instead (section 12): the same
 * levels and chunks, each finer level stored as a residual over the next coarser one
 * where that is smaller, the 16-bit weights over the 8-bit ones; btf_package_read
 * rebuilds the version-2 levels exactly. 8-bit packages only.
 */
#ifndef BTF_LOD_H
#define BTF_LOD_H

#include "btf_package.h"
#include "btf_views.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_LOD_MAX_LEVELS 15
#define BTF_LOD_THRESHOLD 1.0 /* default visibility threshold: RMS contribution on the 0..255 scale */

/* Options of btf_lod_build; zero means default. Plain value. */
typedef struct btf_lod_options {
    int levels;       /* levels including level 0; 0 = as many as keep tiles >= 8 texels, at most 4 */
    double threshold; /* reference visibility threshold used for the chunk order; 0 = BTF_LOD_THRESHOLD */
    int residual;     /* 1: version 4 (doc/package-format.md section 4.3): every level but the coarsest stored as
                       * a residual over the coarser one (8-bit packages only); 0: version 2 (independent mips),
                       * except from a version-3 package (rate-distortion steps): always version 4 */
    int png_only;     /* with residual: 1 = every texture file a PNG; 0 = each the smaller of PNG and lossless WebP */
    int thumbnail;    /* > 0: out_dir gets thumbnail.png of at most this many pixels a side, decoded from the new
                       * package before it is renamed into place (btf_package_thumbnail); 0 = none */
    btf_views *source; /* NULL, or the package's source (its size and directions; the caller's, read once,
                        * view by view, during the call; btf_views_wrap for a BTF in memory): a lossy component's
                        * coarse levels then take the fewest bytes at which each level's CIELab stays at or below
                        * level 0's (doc/package-format.md section 10.7); NULL: the quality of its level 0 */
    const struct btf_lod_gather *gather; /* NULL, or source's references already gathered for exactly the levels
                                          * built (btf_lod_compress_views, during its compression's pass over
                                          * source): then source is not read; one that is not complete or not for
                                          * these levels is ignored */
} btf_lod_options;

/* The levels btf_lod_build makes of a W x H package when asked for want (0: the default
 * of btf_lod_options.levels). */
int btf_lod_levels(int W, int H, int want);

/* Summary of btf_lod_build (optional). Plain value. */
typedef struct btf_lod_stats {
    int levels, n_chunks;
    long long bytes;       /* all chunk files of the new package */
    long long bytes_v1;    /* all chunk files of the source package */
    long long first_chunk; /* bytes of chunk 0 */
} btf_lod_stats;

/* Reads the complete version-1 (or 3) package in_dir and writes out_dir (a different path)
 * as version 2 (4 from version 3 or with opt->residual): level 0 = the v1 files unchanged, level l = 2x2 box averages of
 * level l-1 (dequantised, requantised with the component's ranges) in tex-JJ-lL.png;
 * chunks are (component, level) pairs in the order of doc/package-format.md section 7.3. */
btf_result btf_lod_build(const char *in_dir, const char *out_dir, const btf_lod_options *opt, btf_lod_stats *stats,
                         btf_error *err);

/* Texels per screen pixel of a material W texels wide, repeated `repeat` times
 * across `pixels` device pixels. <= 0 when pixels <= 0 (nothing visible). */
/* Texel (along one axis, inside a tile) of level `from` that texel x of level `level`
 * takes when a component lacks `level` (doc/package-format.md section 6): a finer
 * level's texel repeats its coarser one (x >> d), a coarser level's texel takes the
 * finer texel at its centre ((x << d) + 2^(d-1)). The GPU packing uses the same. */
int btf_lod_texel_of(int x, int level, int from);
double btf_lod_footprint(int width, double repeat, double pixels);

/* One viewer's view of a material. Plain value. */
typedef struct btf_lod_view {
    double texels_per_pixel; /* btf_lod_footprint; <= 0: off screen, nothing needed */
    double threshold;        /* a component is visible if its RMS contribution at the display level is >= this */
} btf_lod_view;

/* What a view needs. Plain value. */
typedef struct btf_lod_selection {
    int level;        /* finest level the footprint resolves: floor(log2(texels_per_pixel)), clamped */
    int n_components; /* components visible at that level */
    int n_needed;     /* chunks needed */
    int limit;        /* prefix length that holds every needed chunk (the budget "chunks") */
    long long bytes;  /* bytes of that prefix */
} btf_lod_selection;

/* Selection rule (doc/package-format.md section 7.4): level = the largest l < levels
 * with 2^l <= texels_per_pixel (0 below 2); component c is visible when the
 * `contrib` of its chunk at that level is >= threshold (the component of chunk 0
 * always); a chunk is needed when its component is visible and its level >= level.
 * Version-1 packages: every chunk. need (optional, n_chunks bytes) gets 1 per needed
 * chunk. Uses only the manifest (no chunk data). */
void btf_lod_select(const btf_package *p, const btf_lod_view *view, btf_lod_selection *out, unsigned char *need);

/* One package from one loaded BTF, as `btf compress` and `btf library build`
 * write it: version 1 (3 with pkg->rd), or version 2 (4 with residual levels, always
 * with pkg->rd: a version-3 package takes residual levels only).
 *
 *     btf_lod_options lod = {.levels = 4, .residual = 1};
 *     btf_lod_compress(src, &pca, &pkg, &lod, "lib/wool", &stats, &err);  // 4 levels, version 4
 *
 * lod NULL (or lod->levels 0) is btf_package_compress. Levels compress into the writer
 * temporary OUT.tmp-PID-v1 (which the next writer of OUT cleans up if this one
 * dies) and adds the levels into OUT with btf_lod_build; either way OUT appears
 * only complete. pkg NULL means defaults; pkg->name NULL becomes the last element of OUT.
 * pkg->thumbnail > 0 gives OUT its thumbnail.png: with levels, btf_lod_build makes it
 * from the levelled package (lod->thumbnail is not used).
 */
btf_result btf_lod_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *pkg,
                            const btf_lod_options *lod, const char *out, btf_compress_stats *stats, btf_error *err);
/* The same from a view source (btf_views.h): one block of views in memory. */
btf_result btf_lod_compress_views(btf_views *src, const btf_pca_options *pca, const btf_package_options *pkg,
                                  const btf_lod_options *lod, const char *out, btf_compress_stats *stats,
                                  btf_error *err);

/* btf_lod_budget_compress: the first try's budget for the package without levels is
 * max_bytes / GUESS; a try that fits with at least NEAR of max_bytes ends the search;
 * at most TRIES tries (each one budget search and one level build). */
#define BTF_LOD_BUDGET_GUESS 1.2
#define BTF_LOD_BUDGET_NEAR 0.92
#define BTF_LOD_BUDGET_TRIES 3

struct btf_budget;
struct btf_budget_result;
/* btf_budget_compress (btf_budget.h) with levels: the budget's package, then
 * btf_lod_build's levels over it (residual, version 4, when opt->rd), into OUT.
 * With max_error the levels leave the error as it is (level 0 is the budget's
 * package); with max_bytes the levelled package must fit, so the budget without
 * levels shrinks by the levels' share as measured on the previous try. res reports
 * the levelled package (bytes, chunks). Temporaries are OUT.tmp-PID-*. lod NULL or
 * lod->levels 0: btf_budget_compress. */
btf_result btf_lod_budget_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                   const struct btf_budget *budget, const btf_lod_options *lod, const char *out,
                                   struct btf_budget_result *res, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
