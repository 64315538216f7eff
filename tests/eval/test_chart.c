/* test_chart.c - room eval, suite "chart": `btf chart` (bench/eval/btf_chart.h, tools/cmd_chart.c).
 *
 * Tiny inputs (8x8 texels, 11 directions) so the whole registry runs in about a
 * second. Checked against independent computations in this file: the Pareto
 * marking against a brute-force definition (random sets with ties, duplicates and
 * NaN, and the CSV's own rows); the CSV's error column against btf_compare of a
 * reconstruction built here; the "mean" rows against averages of the per-material
 * rows; the streaming rows (bytes growing, the manifest's numbers equal to the
 * whole-BTF recomputation); the compression-time table against the main CSV.
 * Bad inputs: NaN source, NULL arguments, missing/corrupt CSV files, CLI usage.
 * Rendering (gnuplot) is checked once for six non-empty files with the right
 * magic, skipped when gnuplot is absent.
 */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_chart.h"
#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_metrics.h"
#include "fixtures.h"

#define SIDE 8

/* ---------------------------------------------------------------- helpers */

/* KIND at SIDE x SIDE texels, 8-bit, on fx_dirs11. */
static btf *tiny_material(btf_gen_kind kind)
{
    btf_dirset d = fx_dirs11();
    return fx_gen(kind, SIDE, &d, BTF_U8);
}

/* A CSV file split into fields (no quoting: the writer never emits commas in fields). */
typedef struct csv {
    int rows, cols;
    char cell[512][32][160];
} csv;

static csv *csv_load(const char *dir, const char *name)
{
    char path[4096], line[8192];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "r");
    cr_assert(f, "cannot open %s", path);
    csv *c = calloc(1, sizeof *c);
    cr_assert(c);
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = 0;
        cr_assert_lt(c->rows, 512);
        int k = 0;
        char *s = line;
        for (;;) {
            char *comma = strchr(s, ',');
            size_t n = comma ? (size_t)(comma - s) : strlen(s);
            cr_assert_lt(k, 32);
            cr_assert_lt(n, 160);
            memcpy(c->cell[c->rows][k], s, n);
            c->cell[c->rows][k][n] = 0;
            k++;
            if (!comma)
                break;
            s = comma + 1;
        }
        if (c->rows == 0)
            c->cols = k;
        cr_assert_eq(k, c->cols, "%s line %d: %d fields, header %d", name, c->rows + 1, k, c->cols);
        c->rows++;
    }
    fclose(f);
    return c;
}

static int col(const csv *c, const char *name)
{
    for (int k = 0; k < c->cols; k++)
        if (!strcmp(c->cell[0][k], name))
            return k;
    cr_assert_fail("no column %s", name);
    return -1;
}

static double num(const csv *c, int r, const char *name)
{
    const char *s = c->cell[r][col(c, name)];
    if (!*s)
        return NAN;
    char *end;
    double v = strtod(s, &end);
    cr_assert(!*end, "row %d column %s: '%s' is not a number", r, name, s);
    return v;
}

static const char *str(const csv *c, int r, const char *name)
{
    return c->cell[r][col(c, name)];
}

/* The definition, quadratic: i is on the front when nothing dominates it. */
static int brute_front(const double *x, const double *y, int n, int i)
{
    if (!isfinite(x[i]) || !isfinite(y[i]))
        return 0;
    for (int j = 0; j < n; j++) {
        if (!isfinite(x[j]) || !isfinite(y[j]))
            continue;
        if (x[j] <= x[i] && y[j] <= y[i] && (x[j] < x[i] || y[j] < y[i]))
            return 0;
    }
    return 1;
}

static void rm_dir_files(const char *dir)
{
    static const char *const names[] = {"chart-speed-accuracy.csv", "chart-streaming.csv", "chart-compress-time.csv",
                                        "chart-speed-accuracy.svg", "chart-streaming.svg",  "chart-compress-time.svg",
                                        "chart-speed-accuracy.png", "chart-streaming.png",  "chart-compress-time.png",
                                        "chart-streaming-k.svg",    "chart-streaming-k.png"};
    char path[4096];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        unlink(path);
    }
    rmdir(dir);
}

/* One chart over two tiny materials, written once for the CSV tests. */
static char g_dir[256];
static int g_made;

static const char *chart_dir(void)
{
    if (g_made)
        return g_dir;
    cr_assert(fx_tmpdir(g_dir, sizeof g_dir));
    btf_chart *c = NULL;
    btf_error err;
    cr_assert_eq(btf_chart_create(&c, &err), BTF_OK);
    btf_chart_options o = {0};
    o.threads = 2;
    o.verify_stream = 1;
    btf *a = tiny_material(BTF_GEN_TILES), *b = tiny_material(BTF_GEN_STONE);
    cr_assert_eq(btf_chart_add_material(c, "tiles", a, &o, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_chart_add_material(c, "stone", b, &o, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_chart_finish(c, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_chart_write_csv(c, g_dir, &err), BTF_OK, "%s", err.msg);
    btf_chart_free(c);
    btf_free(a);
    btf_free(b);
    g_made = 1;
    return g_dir;
}

static void chart_cleanup(void)
{
    if (g_made)
        rm_dir_files(g_dir);
    g_made = 0;
}

/* ---------------------------------------------------------------- Pareto */

Test(chart, pareto_matches_brute_force)
{
    srand(7);
    for (int trial = 0; trial < 2000; trial++) {
        int n = rand() % 24;
        double x[24], y[24];
        int front[24];
        for (int i = 0; i < n; i++) {
            /* few distinct values: many ties and exact duplicates */
            x[i] = rand() % 6, y[i] = rand() % 6;
            if (rand() % 15 == 0)
                x[i] = NAN;
            if (rand() % 15 == 0)
                y[i] = INFINITY;
            if (i > 0 && rand() % 8 == 0)
                x[i] = x[i - 1], y[i] = y[i - 1];
        }
        btf_chart_pareto(x, y, n, front);
        for (int i = 0; i < n; i++)
            cr_assert_eq(front[i], brute_front(x, y, n, i), "trial %d point %d (%g, %g)", trial, i, x[i], y[i]);
    }
}

Test(chart, pareto_simple_cases)
{
    /* a staircase (all on the front), one dominated point, one tied duplicate */
    double x[5] = {1, 2, 3, 2.5, 3}, y[5] = {5, 3, 1, 4, 1};
    int f[5];
    btf_chart_pareto(x, y, 5, f);
    cr_assert(f[0] && f[1] && f[2] && !f[3] && f[4]);
    btf_chart_pareto(x, y, 0, f); /* no points: no crash */
}

/* ---------------------------------------------------------------- the CSV */

static void check_csv_complete(const char *dir)
{
    csv *c = csv_load(dir, "chart-speed-accuracy.csv");
    static const char *const cols[] = {"material", "label",     "family",   "method",   "k",        "components",
                                       "ok",       "encode_s",  "lab",      "bytes",    "fetches",  "flops",
                                       "cost",     "shader_ms", "pareto_cost", "pareto_bytes", "note"};
    for (size_t i = 0; i < sizeof cols / sizeof cols[0]; i++)
        col(c, cols[i]);
    const btf_method_setting *set;
    int n = btf_method_registry(&set);
    static const char *const mats[] = {"tiles", "stone", "mean"};
    cr_assert_eq(c->rows - 1, 3 * n, "rows %d, expected 3 x %d settings", c->rows - 1, n);
    for (int m = 0; m < 3; m++)
        for (int s = 0; s < n; s++) {
            int found = 0;
            for (int r = 1; r < c->rows; r++) {
                if (strcmp(str(c, r, "material"), mats[m]) || strcmp(str(c, r, "label"), set[s].label))
                    continue;
                found++;
                cr_assert_str_eq(str(c, r, "family"), set[s].family);
                cr_assert_str_eq(str(c, r, "method"), set[s].method->name);
                cr_assert_eq(num(c, r, "ok"), 1.0, "%s %s: %s", mats[m], set[s].label, str(c, r, "note"));
                double lab = num(c, r, "lab");
                cr_assert(isfinite(lab) && lab >= 0.0 && lab < 100.0, "%s %s lab %g", mats[m], set[s].label, lab);
                cr_assert_gt(num(c, r, "bytes"), 0.0);
                cr_assert_geq(num(c, r, "encode_s"), 0.0);
                cr_assert_gt(num(c, r, "fetches"), 0.0);
                cr_assert_eq(num(c, r, "cost"), num(c, r, "fetches") + num(c, r, "flops"));
                cr_assert(isnan(num(c, r, "shader_ms")), "shader not asked for, yet timed");
            }
            cr_assert_eq(found, 1, "%s %s: %d rows", mats[m], set[s].label, found);
        }
    free(c);
}

static void check_mean_rows_are_averages(const char *dir)
{
    csv *c = csv_load(dir, "chart-speed-accuracy.csv");
    static const char *const fields[] = {"lab", "bytes", "encode_s", "cost", "rmse"};
    for (int r = 1; r < c->rows; r++) {
        if (strcmp(str(c, r, "material"), "mean"))
            continue;
        for (size_t f = 0; f < sizeof fields / sizeof fields[0]; f++) {
            double sum = 0.0;
            int cnt = 0;
            for (int q = 1; q < c->rows; q++)
                if (strcmp(str(c, q, "material"), "mean") && !strcmp(str(c, q, "label"), str(c, r, "label")))
                    sum += num(c, q, fields[f]), cnt++;
            cr_assert_eq(cnt, 2);
            /* the CSV prints 6 significant digits: relative 1e-5 */
            double want = sum / cnt, got = num(c, r, fields[f]);
            cr_assert(fabs(got - want) <= 1e-5 * fabs(want) + 1e-9, "%s %s: %g vs mean %g", str(c, r, "label"),
                      fields[f], got, want);
        }
    }
    free(c);
}

static void check_pareto_columns_match_brute_force(const char *dir)
{
    csv *c = csv_load(dir, "chart-speed-accuracy.csv");
    static const char *const mats[] = {"tiles", "stone", "mean"};
    for (int m = 0; m < 3; m++) {
        double x[64], b[64], y[64];
        int row[64], n = 0, on_cost = 0;
        for (int r = 1; r < c->rows; r++)
            if (!strcmp(str(c, r, "material"), mats[m])) {
                cr_assert_lt(n, 64);
                row[n] = r, x[n] = num(c, r, "cost"), b[n] = num(c, r, "bytes"), y[n] = num(c, r, "lab");
                n++;
            }
        for (int i = 0; i < n; i++) {
            cr_assert_eq(num(c, row[i], "pareto_cost"), (double)brute_front(x, y, n, i), "%s %s", mats[m],
                         str(c, row[i], "label"));
            cr_assert_eq(num(c, row[i], "pareto_bytes"), (double)brute_front(b, y, n, i), "%s %s", mats[m],
                         str(c, row[i], "label"));
            on_cost += brute_front(x, y, n, i);
        }
        cr_assert_geq(on_cost, 1, "a non-empty set has a front");
    }
    free(c);
}

/* The error column equals btf_compare of a reconstruction decoded here (phong is
 * deterministic: a fixed exponent grid and exact least squares). */
static void check_error_column_matches_btf_compare(const char *dir)
{
    csv *c = csv_load(dir, "chart-speed-accuracy.csv");
    btf *src = tiny_material(BTF_GEN_TILES), *rec = NULL;
    btf_error err;
    btf_model *m = NULL;
    cr_assert_eq(btf_model_encode(&btf_method_phong, src, NULL, &m, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_create(SIDE, SIDE, &src->lights, &src->views, BTF_F32, &rec, &err), BTF_OK);
    for (int v = 0; v < src->views.n_dirs; v++)
        for (int l = 0; l < src->lights.n_dirs; l++) {
            float lv[3], vv[3], rgb[3];
            btf_dirset_vector(&src->lights, l, lv);
            btf_dirset_vector(&src->views, v, vv);
            for (int y = 0; y < SIDE; y++)
                for (int x = 0; x < SIDE; x++) {
                    btf_model_decode(m, x, y, lv, vv, rgb);
                    for (int k = 0; k < 3; k++)
                        btf_set(rec, v, l, x, y, k, rgb[k]);
                }
        }
    btf_metrics met;
    cr_assert_eq(btf_compare(src, rec, NULL, &met, &err), BTF_OK, "%s", err.msg);
    int hit = 0;
    for (int r = 1; r < c->rows; r++)
        if (!strcmp(str(c, r, "material"), "tiles") && !strcmp(str(c, r, "label"), "phong")) {
            hit = 1;
            /* 6 printed digits; summation order differs (threads): 1e-5 relative */
            cr_assert(fabs(num(c, r, "lab") - met.lab_thesis) <= 1e-5 * met.lab_thesis + 1e-9, "csv %g vs %g",
                      num(c, r, "lab"), met.lab_thesis);
            cr_assert_eq(num(c, r, "bytes"), (double)btf_model_bytes(m));
        }
    cr_assert(hit);
    btf_model_free(m);
    btf_free(rec);
    btf_free(src);
    free(c);
}

static void check_streaming_rows_consistent(const char *dir)
{
    csv *c = csv_load(dir, "chart-streaming.csv");
    static const char *const mats[] = {"tiles", "stone"}, *const fmts[] = {"package", "thesis"};
    for (int m = 0; m < 2; m++)
        for (int f = 0; f < 2; f++) {
            int steps = 0;
            double prev_bytes = 0.0, first_lab = 0.0, last_lab = 0.0;
            for (int r = 1; r < c->rows; r++) {
                if (strcmp(str(c, r, "material"), mats[m]) || strcmp(str(c, r, "format"), fmts[f]))
                    continue;
                steps++;
                cr_assert_eq(num(c, r, "step"), (double)steps, "%s %s: steps in order", mats[m], fmts[f]);
                double bytes = num(c, r, "bytes"), lab = num(c, r, "lab");
                cr_assert_gt(bytes, prev_bytes, "%s %s step %d: bytes grow", mats[m], fmts[f], steps);
                cr_assert(isfinite(lab) && lab >= 0.0);
                if (f == 0) {
                    /* manifest error over every texel = the recomputation: same metric,
                     * float sums in another order (1e-4 relative) */
                    double man = num(c, r, "lab_manifest");
                    cr_assert(fabs(man - lab) <= 1e-4 * lab + 1e-6, "%s step %d manifest %g vs %g", mats[m],
                              steps, man, lab);
                } else {
                    cr_assert(isnan(num(c, r, "lab_manifest")));
                }
                if (steps == 1)
                    first_lab = lab;
                prev_bytes = bytes, last_lab = lab;
            }
            cr_assert_eq(steps, 8, "%s %s: %d steps, expected C = 8", mats[m], fmts[f], steps);
            /* all 8 components beat the first one alone (not asserted step by step:
             * on an 8x8 material the 8-bit noise of a minor component can outweigh it) */
            cr_assert_lt(last_lab, first_lab, "%s %s: %g after all, %g after the first", mats[m], fmts[f], last_lab,
                         first_lab);
        }
    /* the float PCA optimum at k = 3, 1 and every view: one row per package step at the
     * package's bytes, an error falling with C and, with every component, not above the
     * quantised package's (quantisation adds noise; 5% for the MAE's ordering on an 8x8
     * material) */
    static const char *const pkgs[3] = {"package", "package-k1", "package-kall"},
                             *const floats[3] = {"float", "float-k1", "float-kall"};
    for (int m = 0; m < 6; m++) {
        const char *fpkg = pkgs[m / 2], *ffl = floats[m / 2];
        int steps = 0;
        double first = 0.0, last = 0.0, pkg_last = 0.0;
        for (int r = 1; r < c->rows; r++) {
            if (strcmp(str(c, r, "material"), mats[m % 2]))
                continue;
            if (!strcmp(str(c, r, "format"), fpkg))
                pkg_last = num(c, r, "lab");
            if (strcmp(str(c, r, "format"), ffl))
                continue;
            steps++;
            int same = 0;
            for (int q = 1; q < c->rows; q++)
                same += !strcmp(str(c, q, "material"), mats[m % 2]) && !strcmp(str(c, q, "format"), fpkg) &&
                        num(c, q, "step") == (double)steps && num(c, q, "bytes") == num(c, r, "bytes");
            cr_assert_eq(same, 1, "%s %s step %d: not at the package's bytes", mats[m % 2], ffl, steps);
            last = num(c, r, "lab");
            first = steps == 1 ? last : first;
            cr_assert(isfinite(last) && last >= 0.0 && isnan(num(c, r, "lab_manifest")));
        }
        cr_assert_eq(steps, 8, "%s %s: %d steps", mats[m % 2], ffl, steps);
        cr_assert_lt(last, first, "%s %s: %g after 8, %g after 1", mats[m % 2], ffl, last, first);
        cr_assert_leq(last, 1.05 * pkg_last, "%s: %s %g above the quantised package %g", mats[m % 2], ffl, last,
                      pkg_last);
    }
    free(c);
}

static void check_compress_time_table_matches(const char *dir)
{
    csv *t = csv_load(dir, "chart-compress-time.csv");
    csv *c = csv_load(dir, "chart-speed-accuracy.csv");
    cr_assert_str_eq(t->cell[0][0], "label");
    cr_assert_str_eq(t->cell[0][2], "tiles");
    cr_assert_str_eq(t->cell[0][3], "stone");
    cr_assert_str_eq(t->cell[0][4], "mean");
    cr_assert_eq(t->rows - 1, btf_method_registry(NULL));
    for (int r = 1; r < c->rows; r++) {
        int k = col(t, str(c, r, "material")), hit = 0;
        for (int q = 1; q < t->rows; q++)
            if (!strcmp(t->cell[q][0], str(c, r, "label"))) {
                hit++;
                cr_assert_eq(num(t, q, t->cell[0][k]), num(c, r, "encode_s"));
            }
        cr_assert_eq(hit, 1);
    }
    free(t);
    free(c);
}

/* ---------------------------------------------------------------- options, bad input */

Test(chart, quick_subset_and_shader_timing)
{
    btf *src = tiny_material(BTF_GEN_KNIT);
    btf_chart *c = NULL;
    btf_error err;
    cr_assert_eq(btf_chart_create(&c, &err), BTF_OK);
    btf_chart_options o = {0};
    o.quick = 1, o.no_stream = 1, o.shader = 1;
    o.shader_width = 64, o.shader_height = 32, o.shader_frames = 1; /* small: seconds matter */
    cr_assert_eq(btf_chart_add_material(c, "knit", src, &o, &err), BTF_OK, "%s", err.msg);
    const btf_method_setting *set;
    int n = btf_method_registry(&set), want = 0;
    for (int i = 0; i < n; i++)
        want += btf_chart_setting_quick(&set[i]);
    cr_assert(want > 3 && want < n);
    cr_assert_eq(c->n_rows, want);
    cr_assert_eq(c->n_stream, 0);
    for (int i = 0; i < c->n_rows; i++) {
        const btf_chart_row *r = &c->rows[i];
        int pca = !strcmp(r->method, "pca") || !strcmp(r->method, "pca-q");
        cr_assert(r->ok, "%s: %s", r->label, r->note);
        if (pca) /* needs the headless GL of the shader tests */
            cr_assert(isfinite(r->shader_ms) && r->shader_ms > 0.0, "%s: shader_ms %g (%s)", r->label, r->shader_ms,
                      r->note);
        else
            cr_assert(isnan(r->shader_ms));
    }
    btf_chart_free(c);
    btf_free(src);
}

Test(chart, bad_inputs)
{
    btf_error err;
    btf_chart *c = NULL;
    cr_assert_eq(btf_chart_create(NULL, &err), BTF_ERR_ARG);
    cr_assert_eq(btf_chart_create(&c, &err), BTF_OK);
    cr_assert_eq(btf_chart_add_material(c, "x", NULL, NULL, &err), BTF_ERR_ARG);
    cr_assert_eq(btf_chart_add_material(NULL, "x", NULL, NULL, &err), BTF_ERR_ARG);
    cr_assert_eq(btf_chart_finish(NULL, &err), BTF_ERR_ARG);
    /* a NaN sample: refused before any method runs, the sample named */
    btf_dirset d = fx_dirs11();
    btf *b = NULL;
    cr_assert_eq(btf_create(4, 4, &d, &d, BTF_F32, &b, &err), BTF_OK);
    ((float *)b->data)[17] = NAN;
    cr_assert_eq(btf_chart_add_material(c, "nan", b, NULL, &err), BTF_ERR_NUMERIC);
    cr_assert(strlen(err.msg) > 0);
    cr_assert_eq(c->n_rows, 0);
    /* nothing added: finish and CSV still work (empty tables) */
    cr_assert_eq(btf_chart_finish(c, &err), BTF_OK);
    cr_assert_eq(btf_chart_write_csv(c, "/nonexistent-dir-btf", &err), BTF_ERR_IO);
    cr_assert(strstr(err.msg, "/nonexistent-dir-btf"));
    btf_free(b);
    btf_chart_free(c);
    btf_chart_free(NULL);
}

Test(chart, plot_bad_csv)
{
    char dir[256], path[512];
    btf_error err;
    cr_assert(fx_tmpdir(dir, sizeof dir));
    cr_assert_eq(btf_chart_plot(dir, dir, &err), BTF_ERR_IO, "missing CSV");
    cr_assert(strstr(err.msg, "chart-speed-accuracy.csv"), "%s", err.msg);
    snprintf(path, sizeof path, "%s/chart-speed-accuracy.csv", dir);
    fx_write_text(path, "material,label\nknit,phong,extra\n"); /* ragged */
    cr_assert_eq(btf_chart_plot(dir, dir, &err), BTF_ERR_FORMAT);
    cr_assert(strstr(err.msg, "line 2"), "%s", err.msg);
    fx_write_text(path, "material,label\nknit,phong\n"); /* columns missing */
    fx_put_text(dir, "chart-streaming.csv", "material,format,bytes,lab\n");
    fx_put_text(dir, "chart-compress-time.csv", "label,family\n");
    cr_assert_eq(btf_chart_plot(dir, dir, &err), BTF_ERR_FORMAT);
    cr_assert(strstr(err.msg, "no column"), "%s", err.msg);
    cr_assert_eq(btf_chart_plot(dir, "/tmp/has\"quote", &err), BTF_ERR_ARG);
    rm_dir_files(dir);
}

static void check_plot_writes_svg_and_png(const char *dir)
{
    if (system("command -v gnuplot >/dev/null 2>&1") != 0)
        return; /* gnuplot not installed: rendering not checked */
    btf_error err;
    cr_assert_eq(btf_chart_plot(dir, dir, &err), BTF_OK, "%s", err.msg);
    static const char *const names[] = {"speed-accuracy", "streaming", "compress-time", "streaming-k"};
    for (int i = 0; i < 4; i++) {
        char path[4096];
        unsigned char head[8] = {0};
        snprintf(path, sizeof path, "%s/chart-%s.png", dir, names[i]);
        FILE *f = fopen(path, "rb");
        cr_assert(f, "%s missing", path);
        cr_assert_eq(fread(head, 1, 8, f), 8u);
        fclose(f);
        cr_assert(!memcmp(head, "\x89PNG\r\n\x1a\n", 8), "%s is not a PNG", path);
        snprintf(path, sizeof path, "%s/chart-%s.svg", dir, names[i]);
        f = fopen(path, "r");
        cr_assert(f, "%s missing", path);
        char text[4096] = {0};
        size_t n = fread(text, 1, sizeof text - 1, f);
        fclose(f);
        cr_assert(n > 100 && strstr(text, "<svg"), "%s is not an SVG", path);
    }
}

Test(chart, cli_usage_and_run)
{
    char *none[] = {"chart", NULL};
    char *bad_size[] = {"chart", "gen:knit:8", "--size", "0", NULL};
    char *bad_opt[] = {"chart", "gen:knit:8", "--bogus", NULL};
    char *missing[] = {"chart", "/nonexistent/material", "--no-plot", "--out", "/tmp", NULL};
    cr_assert_eq(cmd_chart(1, none), 2);
    cr_assert_eq(cmd_chart(4, bad_size), 2);
    cr_assert_eq(cmd_chart(3, bad_opt), 2);
    cr_assert_eq(cmd_chart(5, missing), 1);
    char dir[256], file[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    /* a tiny material as a .btf file (11 directions: fast); --size 4 box-filters it */
    btf *b = tiny_material(BTF_GEN_TILES);
    btf_error err;
    snprintf(file, sizeof file, "%s/tiny.btf", dir);
    cr_assert_eq(btf_save_dfmf(b, file, 0, &err), BTF_OK, "%s", err.msg);
    btf_free(b);
    char *run[] = {"chart", file, "--size", "4", "--quick", "--no-shader", "--no-stream", "--no-plot",
                   "--out", dir, NULL};
    cr_assert_eq(cmd_chart(10, run), 0);
    char *too_big[] = {"chart", file, "--size", "16", "--no-plot", "--out", dir, NULL};
    cr_assert_eq(cmd_chart(7, too_big), 1, "8x8 cannot be box-filtered to 16x16");
    csv *c = csv_load(dir, "chart-speed-accuracy.csv");
    int quick = 0;
    const btf_method_setting *set;
    int n = btf_method_registry(&set);
    for (int i = 0; i < n; i++)
        quick += btf_chart_setting_quick(&set[i]);
    cr_assert_eq(c->rows - 1, 2 * quick, "one material plus its mean rows");
    cr_assert_str_eq(str(c, 1, "material"), "tiny.btf");
    free(c);
    unlink(file);
    rm_dir_files(dir);
}

/* One chart over two tiny materials, checked from every side (one generation: each
 * Criterion test runs in its own process). */
Test(chart, written_chart_is_complete_and_consistent, .fini = chart_cleanup)
{
    const char *dir = chart_dir();
    check_csv_complete(dir);
    check_mean_rows_are_averages(dir);
    check_pareto_columns_match_brute_force(dir);
    check_error_column_matches_btf_compare(dir);
    check_streaming_rows_consistent(dir);
    check_compress_time_table_matches(dir);
    check_plot_writes_svg_and_png(dir);
}
