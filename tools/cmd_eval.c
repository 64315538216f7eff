/* cmd_eval.c - `btf eval REF TEST`: error metrics of TEST against REF.
 *
 *     btf eval wool/ wool_k3c8.btf
 *     btf eval ref.btf test.btf --pairs 0:0,40:12 --csv
 *
 * Both inputs go through btf_load_any (UBO2003 directory, thesis package,
 * `.btf`), must have the same size and direction sets, and are compared with
 * btf_compare: RGB MAE/RMSE (0..255), PSNR, CIELab MAE as the thesis computes
 * it and mean CIE76 Delta E (codec/include/btf_metrics.h).
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_io.h"
#include "btf_output.h"
#include "btf_source.h"
#include "btf_metrics.h"
#include "btf_package.h"

#include <sys/stat.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parsed command line; stack value of cmd_eval, strings point into argv. */
typedef struct eval_opts {
    const char *ref_path, *test_path;
    const char *pairs; /* "all", "measured" or "V:L[,V:L...]" */
    btf_source_args src; /* --downsample, --sampling, --fill-missing (both inputs) */
    int csv, json;
    int no_curve; /* --no-curve: the whole package only, not every prefix */
    int displayed; /* --displayed: TEST's values as the 8-bit codes a display stores */
} eval_opts;

/* Explicit pair list from --pairs V:L,...; malloc'd arrays owned by the caller. */
typedef struct eval_pairs {
    int *views, *lights;
    int n;
} eval_pairs;

static void eval_usage(FILE *f)
{
    fprintf(f, "usage: btf eval REF TEST [--pairs all|measured|V:L[,V:L...]] [--csv | --json]\n"
               "                [--downsample N] [--sampling S] [--fill-missing] [--no-curve]\n"
               "                [--displayed]\n"
               "\n"
               "Error of TEST against REF (anything btf_load_any reads; same size and\n"
               "direction sets). Values are treated as sRGB-encoded 8-bit, D65. TEST is\n"
               "measured as decoded (floats; a thesis package's reconstruction too, at REF's\n"
               "size, not rounded as its import stores it). When TEST is\n"
               "a package directory, also the error after each chunk (the curve versus bytes),\n"
               "every prefix in one pass a tile of texels at a time (memory: REF and the\n"
               "package's files; with --pairs or --downsample, a whole decode per prefix).\n"
               "  --pairs all        every (view, light) pair (default)\n"
               "  --pairs measured   the pairs measured in REF: the same as all for two BTFs\n"
               "                     (differs for packages, decodable between directions)\n"
               "  --pairs V:L,...    only these (view, light) canonical indices\n"
               "  --csv              print metric,value,unit rows\n"
               "  --json             print one JSON object on stdout instead: ref, test, path\n"
               "                     (= TEST), pairs, pairs_total, pixels and the metrics below;\n"
               "                     for a package also bytes, chunks and chunk: one entry per\n"
               "                     chunk {index, component, cumulative_bytes, rgb_rmse,\n"
               "                     lab_mae, delta_e76} (the error after chunks 0..index)\n"
               "  --downsample N     box-filter both inputs by N on load\n"
               "  --sampling S       direction set of image-directory inputs: ubo2003, dome151 or a\n"
               "                     JSON file (default: the built-in set the file names fit)\n"
               "  --fill-missing     interpolate missing images of image directories, with a warning\n"
               "  --no-curve         a package: only the metrics of all its chunks (the curve's\n"
               "                     pass for one prefix instead of C: about half the time;\n"
               "                     with --json, chunk holds the last entry only)\n"
               "  --displayed        TEST's values rounded to the 8-bit codes a page's canvas\n"
               "                     shows (clamped to 0..1, then to 1/255 steps) before they\n"
               "                     are measured: the error a viewer sees\n"
               "Metrics: rgb_mae, rgb_rmse (0..255 scale), psnr (dB; 999 = identical),\n"
               "lab_mae (thesis: mean of |dL|,|da|,|db| over pixels and channels),\n"
               "delta_e76 (mean CIE 1976 Delta E).\n");
    btf_args_exit_codes(f);
}

/* One option or positional of `btf eval` (btf_args_fn). */
static int eval_option(void *ctx, const btf_args *a, int c, const char *v)
{
    eval_opts *o = ctx;
    switch (c) {
    case BTF_ARG_POS: *(a->npos ? &o->test_path : &o->ref_path) = v; break;
    case 'p': o->pairs = v; break;
    case 's': o->src.sampling = v; break;
    case 'F': o->src.fill_missing = 1; break;
    case 'c': o->csv = 1; break;
    case 'j': o->json = 1; break;
    case 'n': o->no_curve = 1; break;
    case 'D': o->displayed = 1; break;
    case 'd': return btf_args_int(a, v, 1, 64, &o->src.downsample);
    }
    return 0;
}

/* 0 ok, 2 usage error, -1 help printed. */
static int eval_parse(int argc, char **argv, eval_opts *o)
{
    static const btf_args_spec spec = {"eval", "pairs:p downsample:d sampling:s fill-missing!F csv!c json!j no-curve!n displayed!D", eval_usage, 2};
    memset(o, 0, sizeof *o);
    o->pairs = "all";
    int rc = btf_args_parse(&spec, argc, argv, eval_option, o);
    if (rc == 0 && o->csv && o->json) {
        fprintf(stderr, "btf eval: --csv and --json exclude each other\n");
        return 2;
    }
    return rc;
}

/* Parses "V:L,V:L"; 0 ok, 2 on a syntax error (message printed). */
static int eval_parse_pairs(const char *spec, eval_pairs *p)
{
    int n = 1;
    for (const char *s = spec; *s; s++)
        n += *s == ',';
    p->views = malloc((size_t)n * sizeof *p->views);
    p->lights = malloc((size_t)n * sizeof *p->lights);
    p->n = 0;
    if (!p->views || !p->lights) {
        fprintf(stderr, "btf eval: out of memory for %d pairs\n", n);
        return 1;
    }
    const char *s = spec;
    for (int i = 0; i < n; i++) {
        char *end;
        long v = strtol(s, &end, 10);
        if (end == s || *end != ':')
            goto bad;
        s = end + 1;
        long l = strtol(s, &end, 10);
        if (end == s || (*end != ',' && *end) || v < -1000000 || v > 1000000 || l < -1000000 || l > 1000000)
            goto bad;
        p->views[i] = (int)v;
        p->lights[i] = (int)l;
        p->n++;
        s = *end ? end + 1 : end;
    }
    return 0;
bad:
    fprintf(stderr, "btf eval: --pairs: expected all, measured or V:L[,V:L...], got '%s'\n", spec);
    return 2;
}

/* Loads path into *out (ref: NULL, or the reference TEST is read against: a thesis
 * package is then reconstructed at its size, in floats, not rounded to the 8-bit
 * samples its import stores); 0 ok, 1 failure (message printed). */
static int eval_load(const char *path, const eval_opts *o, const btf *ref, btf **out)
{
    btf_error err = {0};
    btf_source_args a = o->src;
    btf_input_kind kind;
    if (ref && btf_input_kind_of(path, &kind, &err) == BTF_OK && kind == BTF_INPUT_THESIS)
        a.storage = BTF_F32, a.width = ref->width, a.height = ref->height;
    btf_result r = btf_source_load_args("eval", path, &a, out, &err);
    if (r == BTF_OK)
        r = btf_check_finite(*out, &err);
    if (r != BTF_OK) {
        if (strstr(err.msg, path)) /* loaders name the file themselves */
            fprintf(stderr, "btf eval: %s (%s)\n", err.msg, btf_result_string(r));
        else
            fprintf(stderr, "btf eval: %s: %s (%s)\n", path, err.msg, btf_result_string(r));
        btf_free(*out);
        *out = NULL;
        return 1;
    }
    return 0;
}

/* The metrics as JSON fields of j. */
static void eval_json_metrics(cJSON *j, const btf_metrics *m, int n_pairs, int all_pairs)
{
    cJSON_AddNumberToObject(j, "pairs", n_pairs);
    cJSON_AddNumberToObject(j, "pairs_total", all_pairs);
    cJSON_AddNumberToObject(j, "pixels", (double)m->pixels);
    cJSON_AddNumberToObject(j, "rgb_mae", m->mae);
    cJSON_AddNumberToObject(j, "rgb_rmse", m->rmse);
    cJSON_AddNumberToObject(j, "psnr", m->psnr);
    cJSON_AddNumberToObject(j, "lab_mae", m->lab_thesis);
    cJSON_AddNumberToObject(j, "delta_e76", m->delta_e76);
}

/* The metrics: into j (--json), as CSV rows or as text. */
static void eval_print(const eval_opts *o, cJSON *j, const btf_metrics *m, int n_pairs, int all_pairs)
{
    if (j) {
        eval_json_metrics(j, m, n_pairs, all_pairs);
        return;
    }
    if (o->csv) {
        printf("metric,value,unit\n");
        printf("pairs,%d,count\n", n_pairs);
        printf("pixels,%zu,count\n", m->pixels);
        printf("rgb_mae,%.6f,0..255\n", m->mae);
        printf("rgb_rmse,%.6f,0..255\n", m->rmse);
        printf("psnr,%.4f,dB\n", m->psnr);
        printf("lab_mae,%.6f,CIELab\n", m->lab_thesis);
        printf("delta_e76,%.6f,CIELab\n", m->delta_e76);
        return;
    }
    printf("ref        %s\n", o->ref_path);
    printf("test       %s%s\n", o->test_path, o->displayed ? "  (as displayed: 8-bit codes)" : "");
    printf("pairs      %d of %d (view, light)\n", n_pairs, all_pairs);
    printf("pixels     %zu\n", m->pixels);
    printf("rgb_mae    %.4f  (0..255 scale)\n", m->mae);
    printf("rgb_rmse   %.4f  (0..255 scale)\n", m->rmse);
    printf("psnr       %.2f dB%s\n", m->psnr, m->psnr >= 999.0 ? "  (identical: sentinel 999)" : "");
    printf("lab_mae    %.4f  (CIELab, thesis: mean of |dL|,|da|,|db|)\n", m->lab_thesis);
    printf("delta_e76  %.4f  (CIELab, mean CIE 1976 Delta E)\n", m->delta_e76);
}

/* --displayed: b's values as the 8-bit codes a display stores (a BTF_U8 holds
 * nothing else). */
static void eval_displayed(btf *b)
{
    if (b->storage == BTF_F32)
        btf_metrics_displayed(b->data, b->count);
}

/* TEST is a BTF: load, compare over all pairs or the listed ones (pl->n > 0), print. */
static int eval_btf(const eval_opts *o, const eval_pairs *pl, const btf *ref, cJSON *j)
{
    btf *test = NULL;
    int rc = eval_load(o->test_path, o, ref, &test);
    if (rc == 0 && o->displayed)
        eval_displayed(test);
    if (rc == 0) {
        btf_pair_subset sub = {pl->views, pl->lights, pl->n};
        btf_metrics m;
        btf_error err = {0};
        btf_result r = btf_compare(ref, test, pl->n ? &sub : NULL, &m, &err);
        int total = ref->views.n_dirs * ref->lights.n_dirs;
        if (r == BTF_OK)
            eval_print(o, j, &m, pl->n ? pl->n : total, total);
        else {
            fprintf(stderr, "btf eval: %s vs %s: %s\n", o->ref_path, o->test_path, err.msg);
            rc = 1;
        }
    }
    btf_free(test);
    return rc;
}

/* 1 if path is a package directory (doc/package-format.md: it has manifest.json). */
static int eval_is_package(const char *path)
{
    char buf[4200];
    struct stat st;
    int n = snprintf(buf, sizeof buf, "%s/manifest.json", path);
    return n > 0 && (size_t)n < sizeof buf && stat(buf, &st) == 0 && S_ISREG(st.st_mode);
}

/* Decodes of the first ns[0..count) chunks of p (box-filtered like REF with
 * --downsample) vs ref, into m: every pair a tile of texels at a time, the prefixes
 * in one pass (btf_package_compare_prefixes: the same numbers as whole decodes, none
 * in memory, 5 GB each at 256x256); with --pairs or --downsample each decoded whole. */
static btf_result eval_package_prefixes(const eval_opts *o, const eval_pairs *pl, const btf *ref,
                                        const btf_package *p, const int *ns, int count, btf_metrics *m,
                                        btf_error *err)
{
    btf_compare_options co = {.displayed = o->displayed};
    if (!pl->n && o->src.downsample <= 1)
        return btf_package_compare_with(p, ns, count, ref, &co, m, err);
    btf_result r = BTF_OK;
    for (int i = 0; r == BTF_OK && i < count; i++) {
        btf *rec = NULL, *small = NULL;
        r = btf_package_reconstruct(p, ns[i], &rec, err);
        if (r == BTF_OK && o->src.downsample > 1) {
            r = btf_downsample(rec, o->src.downsample, &small, err);
            btf_free(rec);
            rec = small;
        }
        if (r == BTF_OK && o->displayed)
            eval_displayed(rec);
        btf_pair_subset sub = {pl->views, pl->lights, pl->n};
        if (r == BTF_OK)
            r = btf_compare(ref, rec, pl->n ? &sub : NULL, &m[i], err);
        btf_free(rec);
    }
    return r;
}

/* One point of the error curve: an entry of list (--json), a CSV row or a text line. */
static void eval_chunk_out(const eval_opts *o, cJSON *list, int i, int component, long long bytes,
                           const btf_metrics *m)
{
    if (!list) {
        printf(o->csv ? "%d,%d,%lld,%.6f,%.6f,%.6f\n" : "%5d %9d %16lld %9.4f %8.4f %10.4f\n", i, component,
               bytes, m->rmse, m->lab_thesis, m->delta_e76);
        return;
    }
    cJSON *c = cJSON_CreateObject();
    cJSON_AddNumberToObject(c, "index", i);
    cJSON_AddNumberToObject(c, "component", component);
    cJSON_AddNumberToObject(c, "cumulative_bytes", (double)bytes);
    cJSON_AddNumberToObject(c, "rgb_rmse", m->rmse);
    cJSON_AddNumberToObject(c, "lab_mae", m->lab_thesis);
    cJSON_AddNumberToObject(c, "delta_e76", m->delta_e76);
    cJSON_AddItemToArray(list, c);
}

/* The error after each chunk of p (each prefix decoded at the measured pairs; with
 * --no-curve the whole package only) into list or on stdout; the last metrics into
 * *last, the bytes of all chunks into *bytes. */
static btf_result eval_curve(const eval_opts *o, const eval_pairs *pl, const btf *ref, const btf_package *p,
                             cJSON *list, btf_metrics *last, long long *bytes, btf_error *err)
{
    btf_progress pr;
    btf_progress_start(&pr, "eval", "chunks");
    btf_result r = BTF_OK;
    int first = o->no_curve ? p->n_chunks : 1; /* the prefixes measured: first..n_chunks */
    for (int n = 1; n < first; n++)
        *bytes += p->chunk[n - 1].bytes;
    for (int n0 = first; r == BTF_OK && n0 <= p->n_chunks; n0 += BTF_PACKAGE_COMPARE_MAX) {
        int ns[BTF_PACKAGE_COMPARE_MAX], count = 0;
        btf_metrics m[BTF_PACKAGE_COMPARE_MAX];
        for (int n = n0; n <= p->n_chunks && count < BTF_PACKAGE_COMPARE_MAX; n++)
            ns[count++] = n;
        r = eval_package_prefixes(o, pl, ref, p, ns, count, m, err);
        for (int i = 0; r == BTF_OK && i < count; i++) {
            *bytes += p->chunk[ns[i] - 1].bytes;
            eval_chunk_out(o, list, ns[i] - 1, p->chunk[ns[i] - 1].component, *bytes, &m[i]);
            *last = m[i];
        }
        btf_progress_update(&pr, n0 + count - 1, p->n_chunks);
    }
    btf_progress_end(&pr);
    return r;
}

/* TEST is a package: the error curve versus bytes received, then the metrics of the
 * whole package; into j with --json. */
static int eval_package(const eval_opts *o, const eval_pairs *pl, const btf *ref, cJSON *j)
{
    btf_package *p = NULL;
    btf_error err = {0};
    btf_metrics last = {0};
    btf_result r = btf_package_read(o->test_path, 0, &p, &err);
    int total = ref->views.n_dirs * ref->lights.n_dirs;
    if (r == BTF_OK && !j)
        printf(o->csv ? "chunk,component,cumulative_bytes,rgb_rmse,lab_mae,delta_e76\n"
                      : "chunk component cumulative_bytes  rgb_rmse  lab_mae  delta_e76\n");
    long long bytes = 0;
    cJSON *list = j ? cJSON_AddArrayToObject(j, "chunk") : NULL;
    if (r == BTF_OK)
        r = eval_curve(o, pl, ref, p, list, &last, &bytes, &err);
    if (r == BTF_OK && j) {
        cJSON_AddNumberToObject(j, "bytes", (double)bytes);
        cJSON_AddNumberToObject(j, "chunks", p->n_chunks);
    } else if (r == BTF_OK) {
        printf(o->csv ? "\n" : "\npackage    %d chunks, %lld bytes\n", p->n_chunks, bytes);
    }
    if (r == BTF_OK)
        eval_print(o, j, &last, pl->n ? pl->n : total, total);
    else
        fprintf(stderr, "btf eval: %s vs %s: %s\n", o->ref_path, o->test_path, err.msg);
    btf_package_free(p);
    return r == BTF_OK ? 0 : 1;
}

/* --json: the object naming the inputs (the metrics follow); NULL otherwise. */
static cJSON *eval_json_start(const eval_opts *o)
{
    if (!o->json)
        return NULL;
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "ref", o->ref_path);
    cJSON_AddStringToObject(j, "test", o->test_path);
    cJSON_AddStringToObject(j, "path", o->test_path);
    cJSON_AddBoolToObject(j, "displayed", o->displayed);
    return j;
}

/* The command once its options are parsed; the exit code. */
static int eval_main(void *opts)
{
    eval_opts *o = opts;
    int rc = 0;
    eval_pairs pl = {0};
    if (strcmp(o->pairs, "all") && strcmp(o->pairs, "measured"))
        rc = eval_parse_pairs(o->pairs, &pl);
    btf *ref = NULL;
    if (rc == 0)
        rc = eval_load(o->ref_path, o, NULL, &ref);
    cJSON *j = eval_json_start(o);
    if (rc == 0 && eval_is_package(o->test_path)) /* TEST is a package directory */
        rc = eval_package(o, &pl, ref, j);
    else if (rc == 0)
        rc = eval_btf(o, &pl, ref, j);
    if (j && rc == 0)
        rc = btf_json_print(j);
    else
        cJSON_Delete(j);
    btf_free(ref);
    free(pl.views);
    free(pl.lights);
    return rc;
}

int cmd_eval(int argc, char **argv)
{
    eval_opts o;
    return btf_args_finish(eval_parse(argc, argv, &o), eval_main, &o);
}
