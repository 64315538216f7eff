/* btf_build.h - one package from one loaded BTF, as `btf compress` and
 * `btf library build` write it: version 1, or version 2 (4 with residual levels).
 *
 *     btf_lod_options lod = {.levels = 4, .residual = 1};
 *     btf_build_package(src, &pca, &pkg, &lod, "lib/wool", &stats, &err);  // 4 levels, version 4
 *
 * lod NULL (or lod->levels 0) is btf_package_compress. Levels compress into the writer
 * temporary OUT.tmp-PID-v1 (which the next writer of OUT cleans up if this one
 * dies) and adds the levels into OUT with btf_lod_build; either way OUT appears
 * only complete. pkg->name NULL becomes the last element of OUT.
 * pkg->thumbnail > 0 gives OUT its thumbnail.png: with levels, btf_lod_build makes it
 * from the levelled package (lod->thumbnail is not used).
 */
#ifndef BTF_BUILD_H
#define BTF_BUILD_H

#include "btf_lod.h"
#include "btf_package.h"

btf_result btf_build_package(const btf *src, const btf_pca_options *pca, const btf_package_options *pkg,
                             const btf_lod_options *lod, const char *out, btf_compress_stats *stats, btf_error *err);
/* The same from a view source (codec/btf_views.h): one block of views in memory. */
btf_result btf_build_package_views(btf_views *src, const btf_pca_options *pca, const btf_package_options *pkg,
                                   const btf_lod_options *lod, const char *out, btf_compress_stats *stats,
                                   btf_error *err);

#endif
