/* btf_lod_compress.c - a package with spatial levels in one call (btf_lod.h):
 * btf_package_compress into a writer's temporary, then btf_lod_build into OUT. */
#include "btf_lod.h"

#include "btf_fs.h"
#include "btf_common.h"

#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* Version 1 from whichever of src and views is given. */
static btf_result build_v1(const btf *src, btf_views *views, const btf_pca_options *pca,
                           const btf_package_options *pkg, const char *out, btf_compress_stats *st, btf_error *err)
{
    return src ? btf_package_compress(src, pca, pkg, out, st, err)
               : btf_package_compress_views(views, pca, pkg, out, st, err);
}

/* Versions 2 and 4: compress into OUT.tmp-PID-v1 (a writer's temporary name), add levels into OUT. */
static btf_result build_v2(const btf *src, btf_views *views, const btf_pca_options *pca, btf_package_options pkg,
                           const btf_lod_options *lod, const char *out, btf_compress_stats *st, btf_error *err)
{
    char tmp[4200], name[BTF_PACKAGE_NAME_MAX];
    if (strlen(out) > 4000)
        return btf_fail(err, BTF_ERR_ARG, "output path too long");
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld-v1", out, (long)getpid());
    if (!pkg.name) {
        const char *b = strrchr(out, '/');
        b = b && b[1] ? b + 1 : out;
        snprintf(name, sizeof name, "%s", b);
        pkg.name = name;
    }
    btf_lod_options lo = *lod;
    lo.thumbnail = pkg.thumbnail; /* the levelled package's, decoded from it */
    pkg.thumbnail = 0;
    btf_result r = build_v1(src, views, pca, &pkg, tmp, st, err);
    if (r != BTF_OK)
        return r;
    btf_lod_stats ls = {0};
    r = btf_lod_build(tmp, out, &lo, &ls, err);
    btf_fs_rmtree(tmp, NULL);
    if (st)
        st->bytes = ls.bytes, st->n_chunks = ls.n_chunks;
    return r;
}

btf_result btf_lod_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *pkg,
                            const btf_lod_options *lod, const char *out, btf_compress_stats *stats, btf_error *err)
{
    btf_package_options none = {0};
    if (lod && lod->levels > 0)
        return build_v2(src, NULL, pca, pkg ? *pkg : none, lod, out, stats, err);
    return build_v1(src, NULL, pca, pkg, out, stats, err);
}

btf_result btf_lod_compress_views(btf_views *src, const btf_pca_options *pca, const btf_package_options *pkg,
                                  const btf_lod_options *lod, const char *out, btf_compress_stats *stats,
                                  btf_error *err)
{
    btf_package_options none = {0};
    if (lod && lod->levels > 0)
        return build_v2(NULL, src, pca, pkg ? *pkg : none, lod, out, stats, err);
    return build_v1(NULL, src, pca, pkg, out, stats, err);
}
