/* cmd_lod.c - `btf lod IN_PKG OUT_PKG`: adds spatial levels to a version-1 package
 * (doc/package-format.md section 9.2, codec/include/btf_lod.h).
 *
 *     btf lod lib/wool-v1 lib/wool --levels 4
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_lod.h"
#include "btf_output.h"
#include "btf_source.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parsed command line; stack value of cmd_lod, strings point into argv. */
typedef struct lod_opts {
    const char *in, *out;
    const char *source; /* --source SRC, or NULL */
    btf_lod_options lod;
    int quiet, json;
} lod_opts;

static void lod_usage(FILE *f)
{
    fprintf(f, "usage: btf lod IN_PKG OUT_PKG [--levels N] [--threshold T] [--residual] [--png]\n"
               "                              [--source SRC] [--no-thumbnail] [--quiet] [--json]\n"
               "\n"
               "Writes OUT_PKG (a different directory) as package version 2: the version-1\n"
               "package IN_PKG plus per-component mip levels, chunks ordered coarse first.\n"
               "  --levels N      levels including level 0, 1..%d (default: as many as keep\n"
               "                  tiles >= 8 texels, at most 4); W and H must divide by 2^(N-1)\n"
               "  --threshold T   visibility threshold (RMS on 0..255) of the chunk order (default %.1f)\n"
               "  --residual      version 4: every level but the coarsest stored as a residual over\n"
               "                  the next coarser one (doc/package-format.md section 4.4); 8 bits only\n"
               "  --png           with --residual: every texture a PNG (default: each the smaller\n"
               "                  of a PNG and a lossless WebP, doc/package-format.md section 4)\n"
               "  --source SRC    IN_PKG's source (anything `btf compress` reads): a lossy texture's\n"
               "                  coarse levels then take the fewest bytes at which each\n"
               "                  level's CIELab against SRC box-filtered to it stays at or below\n"
               "                  level 0's, as `btf compress --levels` does (default: the\n"
               "                  quality of its level 0; doc/package-format.md section 10.7)\n"
               "  --no-thumbnail  write no thumbnail.png (default: as `btf compress`, decoded from OUT_PKG)\n"
               "  --quiet         print nothing on success\n"
               "  --json          print one JSON object on stdout instead of the text: path\n"
               "                  (OUT_PKG), bytes, chunks, levels, bytes_v1 (IN_PKG's chunk files),\n"
               "                  first_chunk_bytes, and chunk: one entry per chunk in stream order\n"
               "                  {index, component, level, bytes, cumulative, rmse, rmse_float,\n"
               "                  lab, psnr, delta_e76} as the manifest records them (rmse_float\n"
               "                  not in version 4; lab and delta_e76 null: levels record neither)\n",
            BTF_LOD_MAX_LEVELS, BTF_LOD_THRESHOLD);
    btf_args_exit_codes(f);
}

/* One option or positional of `btf lod` (btf_args_fn). */
static int lod_option(void *ctx, const btf_args *a, int c, const char *v)
{
    lod_opts *o = ctx;
    char *end = NULL;
    switch (c) {
    case BTF_ARG_POS: *(a->npos ? &o->out : &o->in) = v; break;
    case 'l': return btf_args_int(a, v, 1, BTF_LOD_MAX_LEVELS, &o->lod.levels);
    case 't':
        errno = 0;
        o->lod.threshold = strtod(v, &end);
        if (errno || end == v || *end || !(o->lod.threshold > 0.0) || o->lod.threshold > 1e6)
            return btf_args_bad(a, v, "a number > 0 and <= 1e6");
        break;
    case 'r': o->lod.residual = 1; break;
    case 'P': o->lod.png_only = 1; break;
    case 's': o->source = v; break;
    case 'T': o->lod.thumbnail = 0; break;
    case 'q': o->quiet = 1; break;
    case 'j': o->json = 1; break;
    }
    return 0;
}

/* 0 ok, 2 usage error (message printed), -1 help printed. */
static int lod_parse(int argc, char **argv, lod_opts *o)
{
    static const btf_args_spec spec = {"lod", "levels:l threshold:t residual!r png!P source:s no-thumbnail!T quiet!q json!j", lod_usage, 2};
    memset(o, 0, sizeof *o);
    o->lod.thumbnail = BTF_PACKAGE_THUMBNAIL_SIDE;
    return btf_args_parse(&spec, argc, argv, lod_option, o);
}

/* --json: the package as written plus the level statistics; 0 ok, 1 failure. */
static int lod_json(const char *out, const btf_lod_stats *st)
{
    cJSON *o = btf_json_package("lod", out);
    if (!o)
        return 1;
    cJSON_AddNumberToObject(o, "levels", st->levels);
    cJSON_AddNumberToObject(o, "bytes_v1", (double)st->bytes_v1);
    cJSON_AddNumberToObject(o, "first_chunk_bytes", (double)st->first_chunk);
    return btf_json_print(o);
}

/* The command once its options are parsed; the exit code. */
static int lod_main(void *opts)
{
    lod_opts *o = opts;
    btf_lod_stats st = {0};
    btf_error err = {0};
    btf_source_input in = {0};
    btf_source_args sa = {0};
    btf_result r = o->source ? btf_source_open("lod", o->source, &sa, 0, &in, &err) : BTF_OK;
    o->lod.source = o->source && r == BTF_OK ? &in.views : NULL;
    if (r == BTF_OK)
        r = btf_lod_build(o->in, o->out, &o->lod, &st, &err);
    btf_source_close(&in);
    if (r != BTF_OK) {
        fprintf(stderr, "btf lod: %s\n", err.msg);
        return 1;
    }
    if (o->json)
        return lod_json(o->out, &st);
    if (!o->quiet)
        printf("%s: %d levels, %d chunks, %lld bytes (version 1: %lld), first chunk %lld bytes\n", o->out, st.levels,
               st.n_chunks, st.bytes, st.bytes_v1, st.first_chunk);
    return 0;
}

int cmd_lod(int argc, char **argv)
{
    lod_opts o;
    return btf_args_finish(lod_parse(argc, argv, &o), lod_main, &o);
}
