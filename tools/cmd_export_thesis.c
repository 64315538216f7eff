/* cmd_export_thesis.c - `btf export-thesis IN OUT`: the project's k-view PCA written
 * in the thesis's package format (codec/input/btf_thesis.h; bench/eval/btf_export.h), the
 * baseline for comparisons at equal bytes.
 *
 *     btf export-thesis knit/ out/knit-thesis --k 3 --components 8
 *     btf eval knit/ out/knit-thesis        # thesis packages load like any BTF
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_export.h"
#include "btf_io.h"
#include "btf_source.h"
#include "btf_metrics.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parsed command line; stack value of cmd_export_thesis, strings point into argv. */
typedef struct export_opts {
    const char *in, *out;
    btf_source_args src; /* --downsample, --sampling, --fill-missing */
    btf_export_options ex;
    int quiet, eval;
} export_opts;

static void export_usage(FILE *f)
{
    fprintf(f,
            "usage: btf export-thesis IN OUT [--k K] [--components C] [--scale thesis|fit]\n"
            "                                [--method auto|gram|randomized|svd] [--downsample F]\n"
            "                                [--sampling S] [--fill-missing] [--eval] [--quiet]\n"
            "\n"
            "Writes IN (anything the loaders read) as a thesis package OUT (meta.json, J.png,\n"
            "R.png; codec/input/btf_thesis.h): K consecutive views per block, component 0 = the\n"
            "texel mean, components 1..C-1 = row-centred PCA, 8-bit U and V, sigma in 0.1 steps.\n"
            "Needs the same light and view directions and a square texture of even side.\n"
            "  --k K            views per block, 1..views (default 3)\n"
            "  --components C   components including the mean, 1..%d (default 8)\n"
            "  --scale thesis   U scaled by 10, V as is: the published files' quantisation (default)\n"
            "  --scale fit      per block and component scales minimising the quantisation error\n"
            "  --method M       PCA route (default auto)\n"
            "  --downsample F   box-filter the input by F on load\n"
            "  --sampling S     direction set of an image-directory input: ubo2003, dome151 or JSON\n"
            "  --fill-missing   interpolate missing images of an image directory, with a warning\n"
            "  --eval           read OUT back and print its error against IN\n"
            "  --quiet          no summary line\n",
            BTF_THESIS_MAX_C);
    btf_args_exit_codes(f);
}

static const btf_args_spec export_spec = {
    "export-thesis", "k:k components:C method:m downsample:d scale:s sampling:S fill-missing!F quiet!q eval!e", export_usage, 2};

/* One option or positional of `btf export-thesis` (btf_args_fn). */
static int export_option(void *ctx, const btf_args *a, int c, const char *v)
{
    static const char *const scales[] = {"thesis", "fit"};
    export_opts *o = ctx;
    int e = 0, rc = 0;
    if (c == BTF_ARG_POS) {
        *(a->npos ? &o->out : &o->in) = v;
    } else if (c == 'S') {
        o->src.sampling = v;
    } else if (c == 'F') {
        o->src.fill_missing = 1;
    } else if (c == 's') {
        rc = btf_args_enum(a, v, scales, 2, &e), o->ex.scale = (btf_thesis_scale)(e + 1);
    } else if (c == 'q' || c == 'e') {
        *(c == 'q' ? &o->quiet : &o->eval) = 1;
    } else {
        btf_args_pca_dst pca = {&o->ex.k, &o->ex.components, &o->src.downsample, &o->ex.method, BTF_THESIS_MAX_C, NULL};
        rc = btf_args_pca(a, c, v, &pca);
    }
    return rc;
}

/* 0 ok, 2 usage error (message printed), -1 help printed. */
static int export_parse(int argc, char **argv, export_opts *o)
{
    memset(o, 0, sizeof *o);
    o->ex.k = 3, o->ex.components = 8;
    return btf_args_parse(&export_spec, argc, argv, export_option, o);
}

/* Reads OUT back (unclamped float decode) and prints its error against src; 0 ok, 1 failure. */
static int export_eval(const char *out, const btf *src)
{
    btf_thesis_pkg p;
    btf_error err = {0};
    btf *dec = NULL;
    btf_metrics m;
    btf_result r = btf_thesis_read(out, &p, &err);
    if (r == BTF_OK) {
        r = btf_thesis_reconstruct(&p, &src->views, src->width, src->height, BTF_F32, &dec, &err);
        btf_thesis_free(&p);
    }
    if (r == BTF_OK)
        r = btf_compare(src, dec, NULL, &m, &err);
    btf_free(dec);
    if (r != BTF_OK) {
        fprintf(stderr, "btf export-thesis: evaluating %s: %s\n", out, err.msg);
        return 1;
    }
    printf("error vs source: rgb_rmse %.4f, psnr %.2f dB, lab_mae %.4f, delta_e76 %.4f\n", m.rmse, m.psnr,
           m.lab_thesis, m.delta_e76);
    return 0;
}

/* The command once its options are parsed; the exit code. */
static int export_thesis_main(void *opts)
{
    export_opts *o = opts;
    int rc = 0;
    btf_error err = {0};
    btf *src = NULL;
    if (btf_source_load_args("export-thesis", o->in, &o->src, &src, &err) != BTF_OK) {
        fprintf(stderr, "btf export-thesis: %s\n", err.msg);
        return 1;
    }
    btf_export_stats st = {0};
    if (btf_export_thesis(src, &o->ex, o->out, &st, &err) != BTF_OK) {
        fprintf(stderr, "btf export-thesis: %s\n", err.msg);
        btf_free(src);
        return 1;
    }
    if (!o->quiet)
        printf("%s: thesis package, k %d, C %d, scale %s, %lld bytes; PCA %.2f s, write %.2f s\n", o->out, o->ex.k,
               o->ex.components, btf_thesis_scale_name(o->ex.scale), st.bytes, st.seconds_pca, st.seconds_write);
    if (o->eval)
        rc = export_eval(o->out, src);
    btf_free(src);
    return rc;
}

int cmd_export_thesis(int argc, char **argv)
{
    export_opts o;
    return btf_args_finish(export_parse(argc, argv, &o), export_thesis_main, &o);
}
