/* btf_compress.h - the writer's inside channel: what the budget search (btf_budget.c)
 * and the tests pass btf_package_compress beyond the public btf_package_options.
 *
 *     btf_package_channel ch = {0};
 *     ch.estimate = &manifest_text;     // measure, write nothing
 *     btf_package_compress_with(src, &pca, &opt, &ch, out, NULL, &err);
 */
#ifndef BTF_COMPRESS_H
#define BTF_COMPRESS_H

#include "btf_budget.h"
#include "btf_fs.h"
#include "btf_package.h"

#ifdef __cplusplus
extern "C" {
#endif

struct btf_rd_result;
struct btf_rd_ladder;

/* The channel; zero means none of it. Plain value, its pointers the caller's, for one call. */
typedef struct btf_package_channel {
    /* With rd: when not NULL, receives what the allocation chose (the caller frees
     * it with btf_rd_result_free). */
    struct btf_rd_result *rd_out;
    /* With rd: NULL, or what an allocation on a model of the same material with at
     * most as many components chose (btf_rd_params.near): only the steps near its
     * choices are measured. btf_budget passes the window's choice when it writes the
     * winner, and a candidate's when it grows it. */
    const struct btf_rd_result *rd_near;
    /* With rd: NULL, or per component a factor on its texture rates
     * (btf_rd_params.tex_rate_fix): btf_budget's refit, from the atlases it wrote. */
    const double *rd_tex_fix;
    /* With rd: > 0 = steps for the least error within this many bytes instead of the
     * equal-noise error (btf_rd_params.max_bytes; set by btf_budget for --max-bytes). */
    long long rd_max_bytes;
    /* With rd: NULL, or the measured ladders of an earlier compression to reuse when
     * this one's PCA model is the same (btf_rd_params.ladder; btf_budget's pairs). */
    struct btf_rd_ladder *rd_ladder;
    /* With rd: NULL, or a slot for the PCA model. A model already in it is used
     * instead of a new PCA when its sizes, k, components, center, grouping and
     * method match this compression's: the caller promises it was made from this
     * same source (btf_budget's pairs). Otherwise the new model replaces it. The
     * slot owns its model; the caller frees it with btf_pca_model_free. */
    struct btf_pca_model **rd_model;
    /* With rd: NULL, or where to return the manifest instead of writing a package:
     * nothing is written and out_dir is not touched; each chunk's "bytes" is the
     * allocation's estimate of its files (btf_rd_result.comp_bytes, texture files
     * counted as lossless WebP unless png_only), its errors are measured as ever, and
     * the text (malloc'd, the caller frees it) parses with btf_manifest_parse.
     * btf_budget screens its candidates this way and writes only the winner. */
    char **estimate;
    /* With estimate: the texture files' bytes are counted this many times over (0 =
     * once): btf_budget screens on a window of the material and counts its textures
     * as the whole material's (texels of the whole / texels of the window). */
    double tex_rate_scale;
    /* Test hook: called before the writer creates package file number i (texture j
     * = 2j, its weights 2j + 1, the manifest 2C; the components' files from several
     * threads at once, in any order); a nonzero return makes that write fail like a
     * full disk. NULL = none. */
    int (*write_hook)(void *ctx, int i, const char *file);
    void *hook_ctx;
    /* NULL, or where the package's files go instead of out_dir (btf_fs.h): each is
     * handed to sink(sink_user, name, bytes, n) once made, one call at a time, the
     * manifest last; nothing is written to the disk (no temporary directory either),
     * out_dir only names the package, and no thumbnail is made. The fuzz target
     * fuzz_roundtrip.c reads such a package back through btf_fs_memdir. */
    btf_fs_sink_fn sink;
    void *sink_user;
} btf_package_channel;

/* btf_package_compress and btf_package_compress_views with a channel (NULL = none). */
btf_result btf_package_compress_with(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                     const btf_package_channel *ch, const char *out_dir, btf_compress_stats *stats,
                                     btf_error *err);
btf_result btf_package_compress_views_with(btf_views *src, const btf_pca_options *pca, const btf_package_options *opt,
                                           const btf_package_channel *ch, const char *out_dir,
                                           btf_compress_stats *stats, btf_error *err);

/* btf_budget_compress whose writes call hook's write_hook (its other fields unused). */
btf_result btf_budget_compress_with(const btf *src, const btf_pca_options *pca, const btf_package_options *opt,
                                    const btf_package_channel *hook, const btf_budget *budget, const char *out,
                                    btf_budget_result *res, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
