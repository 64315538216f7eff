/* cmd_compress.c - `btf compress IN OUT`: k-view block PCA into a package directory
 * (doc/package-format.md).
 *
 *     btf compress wool/ lib/wool --k 3 --components 8
 *     btf compress knit.btf lib/knit --k 9 --components 16 --bits 16 --grouping spatial
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_fs.h"
#include "btf_io.h"
#include "btf_source.h"
#include "btf_package.h"
#include "btf_budget.h"
#include "btf_lod.h"
#include "btf_lossy.h"
#include "btf_output.h"
#include "btf_common.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Parsed command line; stack value of cmd_compress, strings point into argv. */
typedef struct compress_opts {
    const char *in, *out, *name;
    btf_source_args src; /* --downsample, --sampling, --fill-missing */
    btf_pca_options pca;
    btf_package_options pkg;
    int quiet, json;
    int in_memory;     /* --in-memory: load the whole input first (the baseline of the view-by-view read) */
    int plain;         /* --plain: equal-noise steps (version 1, 2 or 4), not rate-distortion (version 3 or 4) */
    int lossless;      /* --lossless: no lossy WebP textures in a rate-distortion package */
    int avif;          /* --avif: lossy textures as AVIF, not lossy WebP */
    btf_budget budget; /* --max-bytes / --max-error (codec/include/btf_budget.h); both 0 = none */
    btf_lod_options lod; /* levels > 0: package version 2 (4 with residual) with spatial levels (codec/include/btf_lod.h) */
} compress_opts;

static void compress_usage(FILE *f)
{
    fprintf(f,
            "usage: btf compress IN OUT [--k K] [--components C] [--bits 8|16]\n"
            "                           [--grouping consecutive|spatial] [--center none|row]\n"
            "                           [--clipped fit|keep] [--rounding cut|keep]\n"
            "                           [--method auto|gram|randomized|svd] [--downsample F]\n"
            "                           [--name NAME] [--levels N] [--sampling S] [--fill-missing]\n"
            "                           [--max-bytes N | --max-error E] [--full-search] [--plain] [--lossless] [--avif]\n"
            "                           [--png] [--tex-noise X] [--linear] [--in-memory]\n"
            "                           [--no-thumbnail] [--quiet] [--json]\n"
            "\n"
            "Compresses a BTF (UBO2003 image directory, thesis package, .btf file, or gen:KIND[:SIZE[:SEED]]\n"
            "for a generated material) by PCA over\n"
            "blocks of K neighbouring views into the package directory OUT (written as\n"
            "OUT.tmp-PID, renamed when complete). Prints the error after each chunk.\n"
            "Image directories, .btf files and gen: inputs are read one block of K views at a\n"
            "time (memory: about 4 * texels * 3 * lights * K bytes, not the whole material).\n"
            "Options take their value as --k 3 or --k=3. On a terminal, stderr shows the\n"
            "blocks done, the time elapsed and an estimate of the time left.\n"
            "  --k K            views per block, 1..views (default 3; 1 = PCA-RF, all = PCA-BTF)\n"
            "  --components C   components per block, component 0 included (default 8)\n"
            "  --bits B         texture quantisation, 8 or 16 bits (default 8; weights are 16)\n"
            "  --grouping G     consecutive: K consecutive views in canonical order (default);\n"
            "                   spatial: a view and its K-1 nearest unassigned views\n"
            "  --center M       none: best rank-C blocks (default); row: thesis, component 0 = mean\n"
            "  --clipped M      fit: a sample stored at 0 or 255 may lie beyond it in the model\n"
            "                   (what a clipped capture or import hides; the display clips again)\n"
            "                   (default); keep: fitted as stored, as the thesis method does\n"
            "  --rounding M     cut: a block's components stop where what they leave is within\n"
            "                   4x the 8-bit rounding of its samples (default; not with --linear\n"
            "                   or --bits 16, which keep every component);\n"
            "                   keep: every component, as the thesis method does\n"
            "  --method M       PCA route (default auto: Gram up to 2048 columns, else randomized)\n"
            "  --downsample F   box-filter the input by F on load\n"
            "  --sampling S     direction set of an image-directory input: ubo2003, dome151 or a\n"
            "                   JSON file (default: the built-in set the file names fit)\n"
            "  --fill-missing   interpolate missing images of an image directory from each\n"
            "                   view's nearest lights, with a warning (default: refuse)\n"
            "  --name NAME      material name in the manifest (default: last element of OUT)\n"
            "  --levels N       N spatial levels (as `btf lod`): version 4, each level stored as a\n"
            "                   residual over the coarser one where smaller (with --plain: version 2)\n"
            "  --residual       with --plain --levels: version 4 (as `btf lod --residual`)\n"
            "  --max-bytes N    the least CIELab error within N bytes (manifest and chunk files):\n"
            "                   k (or --k) and the chunk count are chosen by compressing each k\n"
            "                   once with up to 16 components (or --components); the default ks\n"
            "                   walk from 9 up (27, 81, ... two blocks, every view) while each\n"
            "                   beats the best, else down (5, 3, 1) while each beats it, one that\n"
            "                   wins keeping all its components grown first (24, 36, ... while it\n"
            "                   wins); without it the best k again with 24, 36, 56, 64 while it\n"
            "                   keeps them all);\n"
            "                   the choice and every candidate are recorded in the manifest (\"budget\";\n"
            "                   the candidates are measured unwritten, their bytes estimated);\n"
            "                   a side of 128 texels or more is halved for the candidates (the\n"
            "                   centre window, texture bytes scaled), the winner compressed from\n"
            "                   the whole material\n"
            "  --max-error E    the fewest bytes whose CIELab error is <= E (as btf eval reports it):\n"
            "                   the same walk, then the winner's steps fitted to the fewest bytes\n"
            "                   that meet E (bisected) and its chunks counted over every texel\n"
            "                   (with --levels: the levels' bytes count too; the error is level 0's)\n"
            "  --full-search    with a budget: measure the candidates on the whole material,\n"
            "                   and every default k\n"
            "  --in-memory      load the whole input before compressing (the same package; the\n"
            "                   baseline the view-by-view read is measured against)\n"
            "  --no-thumbnail   write no thumbnail.png (default: the material seen head-on, decoded\n"
            "                   from every chunk, at most 128 pixels a side: the viewer's poster)\n"
            "  (default)        package version 3: texture and weight steps per component chosen\n"
            "                   by rate-distortion (equal slope) for the error of the equal-noise\n"
            "                   steps, weights deflated (wt-JJ.z); a component's texture a lossy\n"
            "                   WebP of its full-range codes where that costs fewer bytes for its\n"
            "                   error (8 bits, not with --png), its coarse levels too, each in\n"
            "                   the fewest bytes that keep the level's CIELab at or below level\n"
            "                   0's; its weights likewise a lossy WebP;\n"
            "                   with --levels version 4;\n"
            "                   with --bits 16 steps down to 1/65535 of a block's range (PNG\n"
            "                   textures, no --levels)\n"
            "  --plain          the equal-noise steps of every component, weights raw: version 1\n"
            "                   (2 or 4 with --levels)\n"
            "  --rd             the default (kept for scripts that name it)\n"
            "  --lossless       rate-distortion steps with lossless textures and weights only\n"
            "                   (no lossy WebP)\n"
            "  --avif           lossy textures as AVIF (AV1, 8-bit monochrome) instead of lossy\n"
            "                   WebP, where the same rate-distortion choice finds them cheaper for\n"
            "                   their error (readers: package-format.md section 4.1)\n"
            "  --png            every texture a PNG and the weights zlib streams: no WebP file\n"
            "                   (default: a lossless WebP; with levels each level the smaller of\n"
            "                   a PNG and a WebP; weights also as lossless WebP images)\n"
            "  --tex-noise X    RMS quantisation noise per component of the textures\n"
            "                   (0..255 scale, default 0.5; without --plain the total it amounts to)\n"
            "  --linear         a linear-light package (manifest \"encoding\": \"linear\"): the\n"
            "                   source's sRGB values are decoded to linear light (exact sRGB\n"
            "                   EOTF) before the PCA, so sums over light directions add radiance;\n"
            "                   lab is measured after encoding back to sRGB (--max-error means the\n"
            "                   same), rmse and rmse_float are on the linear 0..255 scale (btf eval\n"
            "                   gives the sRGB rmse); works with every other option\n"
            "  --quiet          print nothing on success\n"
            "  --json           print one JSON object on stdout instead of the text:\n"
            "                   path (OUT), bytes (all chunk files), chunks, seconds_load,\n"
            "                   seconds_pca, seconds_write, and chunk: one entry per chunk in\n"
            "                   stream order {index, component, level, bytes, cumulative, rmse,\n"
            "                   rmse_float, lab, psnr, delta_e76} (errors after chunks 0..index;\n"
            "                   with --levels rmse_float is left out, lab and delta_e76 are null)\n");
    btf_args_exit_codes(f);
}

static const btf_args_spec compress_spec = {
    "compress", "k:k components:C method:m downsample:d bits:b grouping:g center:c clipped:K rounding:U levels:l residual!D name:n sampling:s fill-missing!F max-bytes:B max-error:E full-search!S rd!R plain!A lossless!O avif!V png!P tex-noise:X linear!L in-memory!M no-thumbnail!T quiet!q json!j",
    compress_usage, 2};

/* One option or positional of `btf compress` (btf_args_fn). */
static int compress_option(void *ctx, const btf_args *a, int c, const char *v)
{
    static const char *const groupings[] = {"consecutive", "spatial"};
    static const char *const centers[] = {"none", "row"};
    static const char *const clipped[] = {"fit", "keep"};
    static const char *const rounding[] = {"cut", "keep"};
    compress_opts *o = ctx;
    btf_args_pca_dst pca = {&o->pca.k,      &o->pca.components,     &o->src.downsample,
                            &o->pca.method, BTF_PACKAGE_MAX_CHUNKS, &o->budget};
    int e = 0, rc = 0;
    switch (c) {
    case BTF_ARG_POS: *(a->npos ? &o->out : &o->in) = v; break;
    case 'b':
        rc = btf_arg_int(v, 8, 16, &o->pkg.bits) && o->pkg.bits % 8 == 0 ? 0 : btf_args_bad(a, v, "8 or 16");
        break;
    case 'g': rc = btf_args_enum(a, v, groupings, 2, &e), o->pca.grouping = (btf_grouping)(e + 1); break;
    case 'c': rc = btf_args_enum(a, v, centers, 2, &e), o->pca.center = (btf_center)(e + 1); break;
    case 'K': rc = btf_args_enum(a, v, clipped, 2, &e), o->pca.clipped = (btf_clipped)(e + 1); break;
    case 'U': rc = btf_args_enum(a, v, rounding, 2, &e), o->pca.rounding = (btf_rounding)(e + 1); break;
    case 'l': rc = btf_args_int(a, v, 1, BTF_LOD_MAX_LEVELS, &o->lod.levels); break;
    case 'D': o->lod.residual = 1; break;
    case 'n': o->name = v; break;
    case 's': o->src.sampling = v; break;
    case 'F': o->src.fill_missing = 1; break;
    case 'q': o->quiet = 1; break;
    case 'M': o->in_memory = 1; break;
    case 'T': o->pkg.thumbnail = 0; break;
    case 'R': o->pkg.rd = 1; break;
    case 'A': o->plain = 1; break;
    case 'O': o->lossless = 1; break;
    case 'V': o->avif = 1; break;
    case 'L': o->pkg.linear = 1; break;
    case 'S': o->budget.full_search = 1; break;
    case 'P': o->pkg.png_only = o->lod.png_only = 1; break;
    case 'X': {
        double x = 0.0;
        rc = btf_args_double(a, v, 0.01, 64.0, &x), o->pkg.tex_noise = (float)x;
        break;
    }
    case 'j': o->json = 1; break;
    case 'B': rc = btf_args_long(a, v, 1, (long)1 << 40, &o->budget.max_bytes); break;
    case 'E': rc = btf_args_double(a, v, 1e-6, 1e6, &o->budget.max_error); break;
    default: rc = btf_args_pca(a, c, v, &pca);
    }
    return rc;
}

/* 0 ok, 2 usage error (message printed), -1 help printed. */
static int compress_parse(int argc, char **argv, compress_opts *o)
{
    memset(o, 0, sizeof *o);
    o->pca.k = 3, o->pca.components = 8, o->pkg.bits = 8, o->pkg.thumbnail = BTF_PACKAGE_THUMBNAIL_SIDE;
    int rc = btf_args_parse(&compress_spec, argc, argv, compress_option, o);
    if (rc == 0 && o->pkg.rd && o->plain) {
        fprintf(stderr, "btf compress: --rd (the default) or --plain, not both\n");
        rc = 2;
    }
    o->pkg.rd = !o->plain; /* rate-distortion steps unless asked otherwise */
    /* lossy textures where they win, unless asked otherwise (with levels, a lossy
     * component's coarse levels are matched to level 0's error: btf_lod_build) */
    o->pkg.lossy = o->pkg.rd && !o->lossless && o->pkg.bits == 8 && !o->pkg.png_only
                       ? (o->avif ? BTF_LOSSY_AVIF : BTF_LOSSY_WEBP)
                       : BTF_LOSSY_NONE;
    if (rc == 0 && o->avif && !o->pkg.lossy) {
        fprintf(stderr, "btf compress: --avif needs lossy textures (not --plain, --lossless, --png or --bits 16)\n");
        rc = 2;
    }
    if (rc == 0 && o->pkg.rd && o->pkg.bits != 8 && o->lod.levels > 0) {
        fprintf(stderr, "btf compress: levels over 16-bit textures need --plain (version 2)\n");
        rc = 2;
    }
    if (rc == 0 && o->lod.residual && (o->lod.levels < 1 || o->pkg.bits != 8)) {
        fprintf(stderr, "btf compress: --residual needs --levels N and 8-bit textures\n");
        rc = 2;
    }
    o->pkg.name = o->name;
    return rc;
}

static void compress_report(const char *out)
{
    btf_package *p = NULL;
    btf_error err = {0};
    if (btf_package_read(out, 1, &p, &err) != BTF_OK) {
        fprintf(stderr, "btf compress: cannot re-read %s: %s\n", out, err.msg);
        return;
    }
    long long total = 0;
    if (p->linear)
        printf("linear light: rmse and rmse_float on the linear 0..255 scale, lab after encoding to sRGB\n");
    printf("chunk component      bytes   cumulative    rmse  rmse_float    lab\n");
    int has_float, has_lab; /* "-" where the manifest records no value */
    btf_output_recorded(p, &has_float, &has_lab);
    for (int i = 0; i < p->n_chunks; i++) {
        const btf_chunk_info *c = &p->chunk[i];
        char fl[32] = "-", lab[32] = "-";
        total += c->bytes;
        if (has_float)
            snprintf(fl, sizeof fl, "%.3f", c->rmse_float);
        if (has_lab)
            snprintf(lab, sizeof lab, "%.3f", c->lab);
        printf("%5d %9d %10lld %12lld %7.3f %11s %6s\n", i, c->component, c->bytes, total, c->rmse, fl, lab);
    }
    btf_package_free(p);
}

/* --json: the package as written plus the timings; 0 ok, 1 failure. */
static int compress_json(const char *out, const btf_compress_stats *st, double seconds_load)
{
    cJSON *o = btf_json_package("compress", out);
    if (!o)
        return 1;
    cJSON_AddNumberToObject(o, "seconds_load", seconds_load);
    cJSON_AddNumberToObject(o, "seconds_pca", st->seconds_pca);
    cJSON_AddNumberToObject(o, "seconds_write", st->seconds_write);
    return btf_json_print(o);
}

/* --max-bytes / --max-error: the k and chunk count chosen by measuring (codec/include/btf_budget.h). */
static btf_result compress_budget(const btf *src, compress_opts *o, btf_compress_stats *st, btf_error *err)
{
    btf_budget_result res;
    btf_result r = btf_lod_budget_compress(src, &o->pca, &o->pkg, &o->budget, &o->lod, o->out, &res, err);
    if (r != BTF_OK)
        return r;
    st->bytes = res.bytes, st->n_chunks = res.n_chunks, st->lab = res.lab, st->rmse = res.rmse;
    if (!o->quiet && !o->json) {
        for (int i = 0; i < res.n_candidates; i++)
            fprintf(stderr, "btf compress: k %-3d %2d of %2d chunks %10lld bytes  Lab %.3f%s%s\n", res.candidate[i].k,
                    res.candidate[i].n_chunks, res.candidate[i].components, res.candidate[i].bytes, res.candidate[i].lab,
                    res.candidate[i].rd_fit ? "  (rd steps fitted to the bytes)" : "",
                    res.candidate[i].center == BTF_CENTER_ROW ? "  (row centring)" : "");
        fprintf(stderr, "btf compress: chose k %d%s, %d chunks, %lld bytes, Lab %.3f%s\n", res.k,
                res.center == BTF_CENTER_ROW ? " (row centring)" : "", res.n_chunks, res.bytes, res.lab,
                res.met ? "" : " (the error target is not reached: the lowest error)");
    }
    return BTF_OK;
}

/* Compresses src (or, when src is NULL, the view source views) as o says, with the
 * progress line on a terminal. */
static btf_result compress_run(const btf *src, btf_views *views, compress_opts *o, btf_compress_stats *st,
                               btf_error *err)
{
    btf_progress pr;
    btf_progress_start(&pr, "compress", "blocks");
    o->pca.progress = btf_progress_update, o->pca.progress_ctx = &pr;
    btf_result r = !src ? btf_lod_compress_views(views, &o->pca, &o->pkg, &o->lod, o->out, st, err)
                   : o->budget.max_bytes > 0 || o->budget.max_error > 0
                       ? compress_budget(src, o, st, err)
                       : btf_lod_compress(src, &o->pca, &o->pkg, &o->lod, o->out, st, err);
    btf_progress_end(&pr);
    return r;
}

/* The command once its options are parsed; the exit code. The input is read view by
 * view (one block of views in memory, doc/input-formats.md section 5) unless a budget
 * compresses it several times, --in-memory asks, or it is only read whole. */
static int compress_main(void *opts)
{
    compress_opts *o = opts;
    btf_error err = {0};
    btf_source_input in;
    double t0 = btf_seconds();
    int whole = o->budget.max_bytes > 0 || o->budget.max_error > 0 || o->in_memory;
    btf_result r = btf_source_open("compress", o->in, &o->src, whole, &in, &err);
    double t1 = btf_seconds();
    btf_compress_stats st = {0};
    if (r == BTF_OK)
        r = compress_run(in.whole, &in.views, o, &st, &err);
    if (r == BTF_OK)
        btf_source_warn_views("compress", o->in, &in);
    btf_source_close(&in);
    if (r != BTF_OK) {
        fprintf(stderr, "btf compress: %s\n", err.msg);
        return 1;
    }
    if (o->json)
        return compress_json(o->out, &st, t1 - t0);
    if (!o->quiet) {
        printf("%s: %d chunks, %lld bytes; load %.2f s, PCA %.2f s, write %.2f s\n", o->out, st.n_chunks, st.bytes,
               t1 - t0, st.seconds_pca, st.seconds_write);
        compress_report(o->out);
    }
    return 0;
}

int cmd_compress(int argc, char **argv)
{
    compress_opts o;
    return btf_args_finish(compress_parse(argc, argv, &o), compress_main, &o);
}
