/* cmd_eval.c - `btf eval REF TEST`: error metrics of TEST against REF.
 *
 *     btf eval wool/ wool_k3c8.btf
 *     btf eval ref.btf test.btf --pairs 0:0,40:12 --csv
 *
 * Both inputs go through btf_load_any (UBO2003 directory, thesis package,
 * `.btf`), must have the same size and direction sets, and are compared with
 * btf_compare: RGB MAE/RMSE (0..255), PSNR, CIELab MAE as the thesis computes
 * it and mean CIE76 Delta E (codec/btf_metrics.h).
 */
#include "btf_cli.h"
#include "btf_io.h"
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
    int csv;
    int downsample;
} eval_opts;

/* Explicit pair list from --pairs V:L,...; malloc'd arrays owned by the caller. */
typedef struct eval_pairs {
    int *views, *lights;
    int n;
} eval_pairs;

static void eval_usage(FILE *f)
{
    fprintf(f, "usage: btf eval REF TEST [--pairs all|measured|V:L[,V:L...]] [--csv] [--downsample N]\n"
               "\n"
               "Error of TEST against REF (anything btf_load_any reads; same size and\n"
               "direction sets). Values are treated as sRGB-encoded 8-bit, D65.\n"
               "  --pairs all        every (view, light) pair (default)\n"
               "  --pairs measured   the pairs measured in REF: the same as all for two BTFs\n"
               "                     (differs for packages, decodable between directions)\n"
               "  --pairs V:L,...    only these (view, light) canonical indices\n"
               "  --csv              print metric,value,unit rows\n"
               "  --downsample N     box-filter both inputs by N on load\n"
               "Metrics: rgb_mae, rgb_rmse (0..255 scale), psnr (dB; 999 = identical),\n"
               "lab_mae (thesis: mean of |dL|,|da|,|db| over pixels and channels),\n"
               "delta_e76 (mean CIE 1976 Delta E).\n");
}

/* 0 ok, 2 usage error, -1 help printed. */
static int eval_parse(int argc, char **argv, eval_opts *o)
{
    memset(o, 0, sizeof *o);
    o->pairs = "all";
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            eval_usage(stdout);
            return -1;
        } else if (!strcmp(a, "--csv")) {
            o->csv = 1;
        } else if (!strcmp(a, "--pairs") && i + 1 < argc) {
            o->pairs = argv[++i];
        } else if (!strcmp(a, "--downsample") && i + 1 < argc) {
            char *end;
            long v = strtol(argv[++i], &end, 10);
            if (*end || v < 1 || v > 64) {
                fprintf(stderr, "btf eval: --downsample wants an integer 1..64, got '%s'\n", argv[i]);
                return 2;
            }
            o->downsample = (int)v;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "btf eval: unknown or incomplete option '%s'\n", a);
            return 2;
        } else if (npos < 2) {
            *(npos++ ? &o->test_path : &o->ref_path) = a;
        } else {
            fprintf(stderr, "btf eval: unexpected argument '%s'\n", a);
            return 2;
        }
    }
    if (npos != 2) {
        eval_usage(stderr);
        return 2;
    }
    return 0;
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

/* Loads path into *out; 0 ok, 1 failure (message printed). */
static int eval_load(const char *path, const eval_opts *o, btf **out)
{
    btf_load_options lo = {0};
    lo.downsample = o->downsample;
    btf_error err = {0};
    btf_result r = btf_source_load(path, &lo, out, &err);
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

static void eval_print(const eval_opts *o, const btf_metrics *m, int n_pairs, int all_pairs)
{
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
    printf("test       %s\n", o->test_path);
    printf("pairs      %d of %d (view, light)\n", n_pairs, all_pairs);
    printf("pixels     %zu\n", m->pixels);
    printf("rgb_mae    %.4f  (0..255 scale)\n", m->mae);
    printf("rgb_rmse   %.4f  (0..255 scale)\n", m->rmse);
    printf("psnr       %.2f dB%s\n", m->psnr, m->psnr >= 999.0 ? "  (identical: sentinel 999)" : "");
    printf("lab_mae    %.4f  (CIELab, thesis: mean of |dL|,|da|,|db|)\n", m->lab_thesis);
    printf("delta_e76  %.4f  (CIELab, mean CIE 1976 Delta E)\n", m->delta_e76);
}

/* TEST is a BTF: load, compare over all pairs or the listed ones (pl->n > 0), print. */
static int eval_btf(const eval_opts *o, const eval_pairs *pl, const btf *ref)
{
    btf *test = NULL;
    int rc = eval_load(o->test_path, o, &test);
    if (rc == 0) {
        btf_pair_subset sub = {pl->views, pl->lights, pl->n};
        btf_metrics m;
        btf_error err = {0};
        btf_result r = btf_compare(ref, test, pl->n ? &sub : NULL, &m, &err);
        int total = ref->views.n_dirs * ref->lights.n_dirs;
        if (r == BTF_OK)
            eval_print(o, &m, pl->n ? pl->n : total, total);
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

/* Decode of the first n chunks of p (box-filtered like REF with --downsample) vs ref. */
static btf_result eval_package_prefix(const eval_opts *o, const eval_pairs *pl, const btf *ref,
                                      const btf_package *p, int n, btf_metrics *m, btf_error *err)
{
    btf *rec = NULL, *small = NULL;
    btf_result r = btf_package_reconstruct(p, n, &rec, err);
    if (r == BTF_OK && o->downsample > 1) {
        r = btf_downsample(rec, o->downsample, &small, err);
        btf_free(rec);
        rec = small;
    }
    btf_pair_subset sub = {pl->views, pl->lights, pl->n};
    if (r == BTF_OK)
        r = btf_compare(ref, rec, pl->n ? &sub : NULL, m, err);
    btf_free(rec);
    return r;
}

/* TEST is a package: metrics of the whole package, then the error curve versus
 * bytes received, one line per chunk (each prefix decoded at the measured pairs). */
static int eval_package(const eval_opts *o, const eval_pairs *pl, const btf *ref)
{
    btf_package *p = NULL;
    btf_error err = {0};
    btf_metrics m, last = {0};
    btf_result r = btf_package_read(o->test_path, 0, &p, &err);
    int total = ref->views.n_dirs * ref->lights.n_dirs;
    if (r == BTF_OK && o->csv)
        printf("chunk,component,cumulative_bytes,rgb_rmse,lab_mae,delta_e76\n");
    else if (r == BTF_OK)
        printf("chunk component cumulative_bytes  rgb_rmse  lab_mae  delta_e76\n");
    long long bytes = 0;
    for (int n = 1; r == BTF_OK && n <= p->n_chunks; n++) {
        r = eval_package_prefix(o, pl, ref, p, n, &m, &err);
        if (r != BTF_OK)
            break;
        bytes += p->chunk[n - 1].bytes;
        printf(o->csv ? "%d,%d,%lld,%.6f,%.6f,%.6f\n" : "%5d %9d %16lld %9.4f %8.4f %10.4f\n", n - 1,
               p->chunk[n - 1].component, bytes, m.rmse, m.lab_thesis, m.delta_e76);
        last = m;
    }
    if (r == BTF_OK) {
        printf(o->csv ? "\n" : "\npackage    %d chunks, %lld bytes\n", p->n_chunks, bytes);
        eval_print(o, &last, pl->n ? pl->n : total, total);
    } else {
        fprintf(stderr, "btf eval: %s vs %s: %s\n", o->ref_path, o->test_path, err.msg);
    }
    btf_package_free(p);
    return r == BTF_OK ? 0 : 1;
}

int cmd_eval(int argc, char **argv)
{
    eval_opts o;
    int rc = eval_parse(argc, argv, &o);
    if (rc)
        return rc < 0 ? 0 : rc;
    eval_pairs pl = {0};
    if (strcmp(o.pairs, "all") && strcmp(o.pairs, "measured"))
        rc = eval_parse_pairs(o.pairs, &pl);
    btf *ref = NULL;
    if (rc == 0)
        rc = eval_load(o.ref_path, &o, &ref);
    /* ---- PACKAGE EVALUATION (issue 3): TEST is a package directory ---- */
    if (rc == 0 && eval_is_package(o.test_path))
        rc = eval_package(&o, &pl, ref);
    else if (rc == 0)
        rc = eval_btf(&o, &pl, ref);
    btf_free(ref);
    free(pl.views);
    free(pl.lights);
    return rc;
}
