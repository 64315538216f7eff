/* cmd_chart.c - `btf chart MATERIAL...`: every method setting on every material,
 * CSV files and gnuplot charts (bench/eval/btf_chart.h).
 *
 *     btf chart gen:knit:64 gen:stone:64 wool/ --size 64 --out doc/figures   # wool/: a thesis package
 *     btf chart gen:tiles:16 --quick --no-shader --out /tmp/c
 */
#include "btf_chart.h"
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_source.h"
#include "btf_common.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Parsed command line; stack value of cmd_chart, strings point into argv. */
typedef struct chart_opts {
    const char *out;
    int size, stream_size;
    int no_plot, csv_only_plot;
    btf_chart_options o;
    int n_inputs;
    const char **inputs; /* n_inputs positionals (calloc'd, argc entries) */
} chart_opts;

static void chart_usage(FILE *f)
{
    fprintf(f, "usage: btf chart MATERIAL... [--out DIR] [--size N] [--stream-size N] [--quick]\n"
               "                 [--no-shader] [--no-stream] [--no-plot] [--threads N]\n"
               "       btf chart --plot-only [--out DIR]\n"
               "\n"
               "Runs every method setting of the registry (bench/eval/btf_method.h) on each MATERIAL\n"
               "(gen:KIND[:SIZE[:SEED]] or anything btf_load_any reads) and writes\n"
               "  DIR/chart-speed-accuracy.csv   per material and setting (plus \"mean\" rows): encode\n"
               "                                 time, bytes, CIELab error over the whole BTF, decode\n"
               "                                 cost, shader ms/frame (PCA), Pareto fronts\n"
               "  DIR/chart-streaming.csv        error vs bytes received: project package (k3 C8)\n"
               "                                 and the thesis-format export of the same source\n"
               "  DIR/chart-compress-time.csv    encode seconds, one column per material\n"
               "  DIR/chart-*.svg, DIR/chart-*.png   the charts (gnuplot)\n"
               "  --out DIR      output directory (default .; created if missing)\n"
               "  --size N       materials at N x N texels (thesis packages reconstructed at N,\n"
               "                 gen:KIND without a size generated at N, others box-filtered)\n"
               "  --stream-size N  the streaming comparison at N x N texels instead (the\n"
               "                 share of weights in the bytes shrinks as textures grow)\n"
               "  --quick        a reduced set of settings\n"
               "  --no-shader    do not time the shader (no GL needed)\n"
               "  --no-stream    skip the streaming comparison\n"
               "  --no-plot      CSV files only\n"
               "  --plot-only    redraw the charts from DIR's CSV files\n"
               "  --threads N    threads for the error sums (default: OMP_NUM_THREADS or all cores)\n");
    btf_args_exit_codes(f);
}

/* One option or positional of `btf chart` (btf_args_fn). */
static int chart_option(void *ctx, const btf_args *a, int c, const char *v)
{
    chart_opts *o = ctx;
    switch (c) {
    case BTF_ARG_POS: o->inputs[o->n_inputs++] = v; break;
    case 'o': o->out = v; break;
    case 's': return btf_args_int(a, v, 1, BTF_MAX_SIDE, &o->size);
    case 'S': return btf_args_int(a, v, 1, BTF_MAX_SIDE, &o->stream_size);
    case 't': return btf_args_int(a, v, 1, 16, &o->o.threads);
    case 'q': o->o.quick = 1; break;
    case 'G': o->o.shader = 0; break;
    case 'T': o->o.no_stream = 1; break;
    case 'P': o->no_plot = 1; break;
    case 'p': o->csv_only_plot = 1; break;
    }
    return 0;
}

/* 0 ok, 2 usage error, -1 help printed. */
static int chart_parse(int argc, char **argv, chart_opts *c)
{
    static const btf_args_spec spec = {"chart",
                                       "out:o size:s stream-size:S threads:t "
                                       "quick!q no-shader!G no-stream!T no-plot!P plot-only!p",
                                       chart_usage, -1};
    memset(c, 0, sizeof *c);
    c->out = ".";
    c->o.shader = 1;
    c->o.log = stderr;
    c->inputs = calloc((size_t)argc, sizeof *c->inputs);
    if (!c->inputs)
        return 2;
    int rc = btf_args_parse(&spec, argc, argv, chart_option, c);
    if (rc == 0 && c->n_inputs == 0 && !c->csv_only_plot) {
        fprintf(stderr, "btf chart: no MATERIAL given\n");
        chart_usage(stderr);
        return 2;
    }
    return rc;
}

/* Row label of an input: the kind of gen:KIND..., else the last path element. */
static void chart_name(const char *spec, char *out, size_t n)
{
    const char *s = spec;
    if (!strncmp(spec, "gen:", 4)) {
        s = spec + 4;
    } else {
        size_t len = strlen(spec);
        while (len > 1 && spec[len - 1] == '/')
            len--;
        const char *slash = NULL;
        for (size_t i = 0; i < len; i++)
            if (spec[i] == '/')
                slash = spec + i;
        s = slash ? slash + 1 : spec;
        len = (size_t)(spec + len - s);
        snprintf(out, n, "%.*s", (int)len, s);
        return;
    }
    size_t len = strcspn(s, ":");
    snprintf(out, n, "%.*s", (int)len, s);
}

/* Loads spec at the requested size (0 = native). */
static btf_result chart_load(const char *spec, int size, btf **out, btf_error *err)
{
    btf_load_options lo = {0};
    char gen[128];
    if (size > 0 && !strncmp(spec, "gen:", 4) && !strchr(spec + 4, ':')) {
        snprintf(gen, sizeof gen, "%s:%d", spec, size);
        spec = gen;
    } else if (size > 0) {
        lo.width = lo.height = size; /* honoured by the thesis import */
    }
    btf *b = NULL;
    btf_result r = btf_source_load(spec, &lo, &b, err);
    if (r != BTF_OK || size <= 0 || (b->width == size && b->height == size)) {
        *out = b;
        return r;
    }
    if (b->width != b->height || b->width < size || b->width % size) {
        int w = b->width, h = b->height;
        btf_free(b);
        *out = NULL;
        return btf_fail(err, BTF_ERR_ARG, "%s: %dx%d texels cannot be box-filtered to %dx%d", spec, w, h, size, size);
    }
    btf *small = NULL;
    r = btf_downsample(b, b->width / size, &small, err);
    btf_free(b);
    *out = small;
    return r;
}

static int chart_run(chart_opts *c)
{
    btf_error err = {{0}};
    btf_chart *ch = NULL;
    if (mkdir(c->out, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "btf chart: cannot create %s\n", c->out);
        return 1;
    }
    if (c->csv_only_plot) {
        if (btf_chart_plot(c->out, c->out, &err) != BTF_OK) {
            fprintf(stderr, "btf chart: %s\n", err.msg);
            return 1;
        }
        return 0;
    }
    if (btf_chart_create(&ch, &err) != BTF_OK) {
        fprintf(stderr, "btf chart: %s\n", err.msg);
        return 1;
    }
    int rc = 0;
    int split = c->stream_size > 0 && c->stream_size != c->size && !c->o.no_stream;
    for (int i = 0; i < c->n_inputs && rc == 0; i++) {
        char name[BTF_CHART_NAME];
        chart_name(c->inputs[i], name, sizeof name);
        for (int pass = 0; pass < 1 + split && rc == 0; pass++) {
            btf_chart_options o = c->o; /* pass 1: streaming rows at --stream-size */
            o.no_stream |= split && pass == 0;
            o.no_methods = pass == 1;
            btf *src = NULL;
            if (chart_load(c->inputs[i], pass ? c->stream_size : c->size, &src, &err) != BTF_OK ||
                btf_chart_add_material(ch, name, src, &o, &err) != BTF_OK) {
                fprintf(stderr, "btf chart: %s: %s\n", c->inputs[i], err.msg);
                rc = 1;
            }
            btf_free(src);
        }
    }
    if (rc == 0 && (btf_chart_finish(ch, &err) != BTF_OK || btf_chart_write_csv(ch, c->out, &err) != BTF_OK ||
                    (!c->no_plot && btf_chart_plot(c->out, c->out, &err) != BTF_OK))) {
        fprintf(stderr, "btf chart: %s\n", err.msg);
        rc = 1;
    }
    if (rc == 0)
        fprintf(stderr, "btf chart: wrote %s/chart-*.csv%s\n", c->out, c->no_plot ? "" : ", .svg, .png");
    btf_chart_free(ch);
    return rc;
}

int cmd_chart(int argc, char **argv)
{
    chart_opts c;
    int p = chart_parse(argc, argv, &c);
    int rc = p == 0 ? chart_run(&c) : p < 0 ? 0 : 2;
    free(c.inputs);
    return rc;
}
