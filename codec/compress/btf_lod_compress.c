/* btf_lod_compress.c - a package with spatial levels in one call (btf_lod.h):
 * btf_package_compress (or btf_budget_compress) into a writer's temporary, then
 * btf_lod_build into OUT. */
#include "btf_lod.h"
#include "btf_budget.h"
#include "btf_lod_error.h"
#include "btf_manifest.h"

#include "btf_fs.h"
#include "btf_common.h"

#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* OUT.tmp-PID-TAG, the name of one of this writer's temporary packages. */
static btf_result lodc_temp_name(const char *out, const char *tag, char *buf, size_t n, btf_error *err)
{
    if (strlen(out) > 4000)
        return btf_fail(err, BTF_ERR_ARG, "output path too long");
    snprintf(buf, n, "%s.tmp-%ld-%s", out, (long)getpid(), tag);
    return BTF_OK;
}

/* pkg->name, when NULL, becomes OUT's last path element (in name), not the temporary's. */
static void lodc_name(btf_package_options *pkg, const char *out, char *name, size_t n)
{
    if (pkg->name)
        return;
    const char *b = strrchr(out, '/');
    snprintf(name, n, "%s", b && b[1] ? b + 1 : out);
    pkg->name = name;
}

/* Version 1 from whichever of src and views is given. */
static btf_result build_v1(const btf *src, btf_views *views, const btf_pca_options *pca,
                           const btf_package_options *pkg, const char *out, btf_compress_stats *st, btf_error *err)
{
    return src ? btf_package_compress(src, pca, pkg, out, st, err)
               : btf_package_compress_views(views, pca, pkg, out, st, err);
}

/* A view source that passes each view it reads on to a gathering of the level
 * references (btf_lod_error.h), so that the level builder need not read the source
 * again. Lives on build_v2's stack, for one compression. */
typedef struct lodc_tee {
    btf_views *inner;   /* the caller's source */
    btf_lod_gather *g;  /* build_v2's */
} lodc_tee;

static btf_result lodc_tee_fill(btf_views *s, int view, float *cols, btf_error *err)
{
    lodc_tee *t = s->impl;
    btf_result r = btf_views_fill(t->inner, view, cols, err);
    return r == BTF_OK ? btf_lod_gather_add(t->g, view, cols, err) : r;
}

/* Versions 2 and 4: compress into OUT.tmp-PID-v1 (a writer's temporary name), add levels into OUT. */
static btf_result build_v2(const btf *src, btf_views *views, const btf_pca_options *pca, btf_package_options pkg,
                           const btf_lod_options *lod, const char *out, btf_compress_stats *st, btf_error *err)
{
    char tmp[4200], name[BTF_PACKAGE_NAME_MAX];
    if (lodc_temp_name(out, "v1", tmp, sizeof tmp, err) != BTF_OK)
        return BTF_ERR_ARG;
    lodc_name(&pkg, out, name, sizeof name);
    btf_lod_options lo = *lod;
    lo.thumbnail = pkg.thumbnail; /* the levelled package's, decoded from it */
    btf_views wrap;
    if (src)
        btf_views_wrap(src, &wrap);
    lo.source = src ? &wrap : views; /* the coarse levels matched to level 0's error */
    pkg.thumbnail = 0;
    pkg.levels = 1; /* levels follow (btf_package_options.levels) */
    /* a view source, where lossy textures may need matching: its level references
     * gathered as the compression reads it */
    btf_lod_gather g = {0};
    lodc_tee tee = {views, &g};
    btf_views teed;
    int gather = views && pkg.rd && pkg.lossy;
    int n_levels = gather ? btf_lod_levels(views->width, views->height, lod->levels) : 0;
    btf_result r = gather ? btf_lod_gather_begin(views, pkg.linear, n_levels, BTF_LOD_ERROR_SAMPLE, &g, err) : BTF_OK;
    if (gather && r == BTF_OK)
        btf_views_over(views, lodc_tee_fill, &tee, &teed);
    if (r == BTF_OK)
        r = build_v1(src, gather ? &teed : views, pca, &pkg, tmp, st, err);
    lo.gather = &g; /* used when complete */
    btf_lod_stats ls = {0};
    if (r == BTF_OK)
        r = btf_lod_build(tmp, out, &lo, &ls, err);
    btf_lod_gather_free(&g);
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

/* One try of btf_lod_budget_compress: src under b into base (the package without
 * levels), then its levels into lev; *total = lev's manifest and chunk files. */
static btf_result lodc_try(const btf *src, const btf_pca_options *pca, const btf_package_options *pkg,
                           const btf_budget *b, const btf_lod_options *lod, const char *base, const char *lev,
                           btf_budget_result *res, long long *total, btf_error *err)
{
    btf_package_options po = *pkg;
    int thumbnail = po.thumbnail;
    po.thumbnail = 0;
    po.levels = 1; /* as build_v2 */
    btf_result r = btf_budget_compress(src, pca, &po, b, base, res, err);
    btf_lod_options lo = *lod;
    lo.thumbnail = thumbnail;
    btf_views wrap;
    btf_views_wrap(src, &wrap);
    lo.source = &wrap;
    btf_lod_stats ls = {0};
    if (r == BTF_OK)
        r = btf_lod_build(base, lev, &lo, &ls, err);
    char man[4300];
    snprintf(man, sizeof man, "%s/manifest.json", lev);
    *total = ls.bytes + (r == BTF_OK ? btf_fs_size(man) : 0);
    if (r == BTF_OK)
        res->bytes = *total, res->n_chunks = ls.n_chunks;
    return r;
}

btf_result btf_lod_budget_compress(const btf *src, const btf_pca_options *pca, const btf_package_options *pkg,
                                   const btf_budget *budget, const btf_lod_options *lod, const char *out,
                                   btf_budget_result *res, btf_error *err)
{
    if (!lod || lod->levels <= 0)
        return btf_budget_compress(src, pca, pkg, budget, out, res, err);
    btf_package_options po = {0};
    btf_pca_options pc = {0};
    if (pkg)
        po = *pkg;
    if (pca)
        pc = *pca;
    btf_budget b = *budget;
    btf_budget_result rr;
    char base[4200], lev[2][4200], name[BTF_PACKAGE_NAME_MAX];
    lodc_name(&po, out, name, sizeof name);
    btf_result r = lodc_temp_name(out, "v1", base, sizeof base, err);
    if (r == BTF_OK && (r = lodc_temp_name(out, "l0", lev[0], sizeof lev[0], err)) == BTF_OK)
        r = lodc_temp_name(out, "l1", lev[1], sizeof lev[1], err);
    if (r == BTF_OK)
        r = btf_fs_replaceable(out, btf_manifest_owns_dir, NULL, err);
    int best = -1, cur = 0;
    long long total = 0, limit = budget->max_bytes;
    if (limit > 0)
        b.max_bytes = (long long)(limit / BTF_LOD_BUDGET_GUESS);
    for (int t = 0; r == BTF_OK && t < (limit > 0 ? BTF_LOD_BUDGET_TRIES : 1); t++) {
        r = lodc_try(src, &pc, &po, &b, lod, base, lev[cur], &rr, &total, err);
        if (r != BTF_OK)
            break;
        if (limit <= 0 || total <= limit) { /* fits: the best so far (tries only grow after a fit) */
            if (best >= 0)
                btf_fs_rmtree(lev[best], NULL);
            best = cur, cur = 1 - cur, *res = rr;
            if (limit <= 0 || total >= (long long)(limit * BTF_LOD_BUDGET_NEAR))
                break;
        } else
            btf_fs_rmtree(lev[cur], NULL);
        /* the levels' share as measured: the next base budget makes them fit; the
         * settings the first search chose stay (one candidate per further try) */
        b.max_bytes = (long long)((double)b.max_bytes * (double)limit / (double)total * 0.975);
        b.k[0] = rr.k, b.n_k = 1, b.max_components = rr.components;
        pc.center = rr.center == BTF_CENTER_ROW ? BTF_CENTER_ROW : BTF_CENTER_NONE;
    }
    btf_fs_rmtree(base, NULL);
    if (r == BTF_OK && best < 0)
        r = btf_fail(err, BTF_ERR_ARG, "%lld bytes: the levels do not fit (%lld bytes at the smallest try)", limit, total);
    if (r == BTF_OK)
        r = btf_fs_replace_dir(lev[best], out, btf_manifest_owns_dir, NULL, err);
    if (r != BTF_OK && best >= 0)
        btf_fs_rmtree(lev[best], NULL);
    if (r == BTF_OK && limit > 0)
        res->met = 1;
    return r;
}
