/* btf_chart_plot.c - gnuplot charts from the CSV files btf_chart_write_csv writes
 * (btf_chart_plot in btf_chart.h). The CSVs are read back (so charts can be redrawn
 * from them alone), turned into gnuplot data blocks inside one script, and gnuplot
 * draws every chart twice: SVG and PNG (pngcairo). */
#include "btf_chart.h"
#include "btf_fs.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

/* A CSV file in memory: fields are pointers into text. Made by btf__csv_read, freed
 * by btf__csv_free. Fields never contain commas or quotes (the writer ensures it). */
typedef struct btf__csv {
    char *text;
    char ***row; /* n_rows (header = row 0) x n_cols */
    int n_rows, n_cols;
} btf__csv;

static void btf__csv_free(btf__csv *c)
{
    if (!c)
        return;
    for (int i = 0; i < c->n_rows; i++)
        free(c->row[i]);
    free(c->row), free(c->text);
    memset(c, 0, sizeof *c);
}

static btf_result btf__csv_read(const char *path, btf__csv *c, btf_error *err)
{
    memset(c, 0, sizeof *c);
    size_t n;
    btf_result rr = btf_fs_read(path, (size_t)64 << 20, &c->text, &n, err);
    if (rr != BTF_OK)
        return rr == BTF_ERR_MISSING ? BTF_ERR_IO : rr; /* a missing table is an I/O failure of the plot */
    int lines = 1;
    for (size_t i = 0; i < n; i++)
        lines += c->text[i] == '\n';
    c->row = calloc((size_t)lines, sizeof *c->row);
    if (!c->row) {
        btf__csv_free(c);
        return btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory reading %s", path);
    }
    for (char *s = c->text, *nl; s && *s; s = nl ? nl + 1 : NULL) {
        nl = strchr(s, '\n');
        if (nl)
            *nl = 0;
        int cols = 1;
        for (char *p = s; *p; p++)
            cols += *p == ',';
        if (c->n_rows == 0)
            c->n_cols = cols;
        if (cols != c->n_cols) {
            int line = c->n_rows + 1;
            btf__csv_free(c);
            return btf_fail(err, BTF_ERR_FORMAT, "chart: %s line %d: %d fields, header has %d", path, line, cols,
                            c->n_cols);
        }
        char **r = malloc((size_t)cols * sizeof *r);
        if (!r) {
            btf__csv_free(c);
            return btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory reading %s", path);
        }
        c->row[c->n_rows++] = r;
        for (int k = 0; k < cols; k++) {
            r[k] = s;
            s = strchr(s, ',');
            if (s)
                *s++ = 0;
        }
        s = r[cols - 1] + strlen(r[cols - 1]);
    }
    if (c->n_rows < 1) {
        btf__csv_free(c);
        return btf_fail(err, BTF_ERR_FORMAT, "chart: %s is empty", path);
    }
    return BTF_OK;
}

static int btf__csv_col(const btf__csv *c, const char *name)
{
    for (int k = 0; k < c->n_cols; k++)
        if (!strcmp(c->row[0][k], name))
            return k;
    return -1;
}

static double btf__csv_num(const btf__csv *c, int row, int col)
{
    if (col < 0 || !c->row[row][col][0])
        return NAN;
    char *end;
    double v = strtod(c->row[row][col], &end);
    return *end ? NAN : v;
}

/* Distinct values of column col in rows where column fcol equals fval (fcol < 0:
 * all rows), in order of appearance; at most max. */
static int btf__csv_distinct(const btf__csv *c, int col, int fcol, const char *fval, const char **out, int max)
{
    int n = 0;
    for (int i = 1; i < c->n_rows && col >= 0; i++) {
        if (fcol >= 0 && strcmp(c->row[i][fcol], fval))
            continue;
        int seen = 0;
        for (int j = 0; j < n; j++)
            seen |= !strcmp(out[j], c->row[i][col]);
        if (!seen && n < max)
            out[n++] = c->row[i][col];
    }
    return n;
}

/* ---------------------------------------------------------------- speed vs accuracy */

#define BTF__PLOT_MAX 256

/* Data block $NAME with "x y label" lines of rows of material mat and family fam
 * (fam NULL: the Pareto front flagged in column pcol, sorted by x). */
static int btf__plot_block(FILE *f, const btf__csv *c, const char *name, const char *mat, const char *fam,
                           int xcol, int pcol, double xscale)
{
    int cm = btf__csv_col(c, "material"), cf = btf__csv_col(c, "family"), cy = btf__csv_col(c, "lab");
    int cl = btf__csv_col(c, "label"), cok = btf__csv_col(c, "ok");
    int idx[BTF__PLOT_MAX], n = 0;
    for (int i = 1; i < c->n_rows && n < BTF__PLOT_MAX; i++) {
        if (strcmp(c->row[i][cm], mat) || btf__csv_num(c, i, cok) != 1.0)
            continue;
        if (fam ? strcmp(c->row[i][cf], fam) != 0 : btf__csv_num(c, i, pcol) != 1.0)
            continue;
        if (!isfinite(btf__csv_num(c, i, xcol)) || !isfinite(btf__csv_num(c, i, cy)))
            continue;
        idx[n++] = i;
    }
    for (int a = 1; !fam && a < n; a++) /* front: by ascending x */
        for (int b = a; b > 0 && btf__csv_num(c, idx[b - 1], xcol) > btf__csv_num(c, idx[b], xcol); b--) {
            int t = idx[b];
            idx[b] = idx[b - 1], idx[b - 1] = t;
        }
    fprintf(f, "$%s << EOD\n", name);
    for (int a = 0; a < n; a++) { /* 4th column: label height, alternating above and below */
        double y = btf__csv_num(c, idx[a], cy);
        fprintf(f, "%.6g %.6g \"%s\" %.6g\n", btf__csv_num(c, idx[a], xcol) * xscale, y, c->row[idx[a]][cl],
                y * (a % 2 ? 0.86 : 1.14));
    }
    fprintf(f, "EOD\n");
    return n;
}

/* One panel: a line per family plus the front. Data blocks are named PREFIX_i and PREFIX_front. */
static void btf__plot_panel(FILE *f, const btf__csv *c, const char *mat, const char **fams, int nf,
                            const char *prefix, const char *xcol_name, const char *pareto_name, double xscale,
                            const char *xlabel, const char *title)
{
    int xcol = btf__csv_col(c, xcol_name), pcol = btf__csv_col(c, pareto_name);
    int have[BTF__PLOT_MAX], any = 0;
    char name[64];
    for (int i = 0; i < nf; i++) {
        snprintf(name, sizeof name, "%s_%d", prefix, i);
        have[i] = btf__plot_block(f, c, name, mat, fams[i], xcol, pcol, xscale);
        any += have[i];
    }
    snprintf(name, sizeof name, "%s_front", prefix);
    int nfront = btf__plot_block(f, c, name, mat, NULL, xcol, pcol, xscale);
    fprintf(f, "set title \"%s\"\nset xlabel \"%s\"\nset logscale x\n", title, xlabel);
    if (!any) {
        fprintf(f, "set label 1 \"not measured\" at graph 0.5, graph 0.5 center\n"
                   "plot [1:10][1:10] NaN notitle\nunset label 1\n");
        return;
    }
    fprintf(f, "plot ");
    for (int i = 0; i < nf; i++)
        if (have[i])
            fprintf(f, "$%s_%d using 1:2 with linespoints ls %d title \"%s\", ", prefix, i, i + 1, fams[i]);
    if (nfront)
        fprintf(f, "$%s_front using 1:2 with lines ls 100 title \"Pareto front\", "
                   "$%s_front using 1:2 with points ls 101 notitle, "
                   "$%s_front using 1:4:3 with labels offset char 0.8,0 left font \",9\" notitle",
                prefix, prefix, prefix);
    else
        fprintf(f, "NaN notitle");
    fprintf(f, "\n");
}

static const char *const btf__plot_colours[10] = {"#1b9e77", "#d95f02", "#7570b3", "#e7298a", "#66a61e",
                                                   "#e6ab02", "#a6761d", "#666666", "#1f78b4", "#b2182b"};

static void btf__plot_styles(FILE *f)
{
    for (int i = 0; i < 40; i++)
        fprintf(f, "set style line %d lc rgb \"%s\" lw 2 pt %d ps 1.2 dt %d\n", i + 1, btf__plot_colours[i % 10],
                (i % 7) + 1, i < 10 ? 1 : 2);
    fprintf(f, "set style line 100 lc rgb \"black\" lw 1.5 dt 3\n"
               "set style line 101 lc rgb \"black\" pt 6 ps 2.4 lw 1.5\n");
}

/* ---------------------------------------------------------------- script */

/* Data block $name of one streaming curve: (KiB, CIELab) of material mat's rows of
 * the format, in CSV order; mat NULL gives an empty block. Returns the points written. */
static int btf__plot_curve(FILE *f, const btf__csv *st, const char *name, const char *mat, const char *format)
{
    int sm = btf__csv_col(st, "material"), sfm = btf__csv_col(st, "format"), sb = btf__csv_col(st, "bytes");
    int sl = btf__csv_col(st, "lab"), n = 0;
    fprintf(f, "$%s << EOD\n", name);
    for (int r = 1; mat && r < st->n_rows; r++)
        if (!strcmp(st->row[r][sm], mat) && !strcmp(st->row[r][sfm], format) && isfinite(btf__csv_num(st, r, sl))) {
            fprintf(f, "%.6g %.6g\n", btf__csv_num(st, r, sb) / 1024.0, btf__csv_num(st, r, sl));
            n++;
        }
    fprintf(f, "EOD\n");
    return n;
}

/* The k figure: per material a panel with the package and its float PCA optimum at
 * k = 1, 3 and every view (rows package-k1, float-k1, ...); an empty panel when a
 * run has no such rows (quick runs). */
static void btf__plot_stream_k(FILE *f, const btf__csv *st, const char *const *smats, int nsm, const char *out_dir,
                               const char *term, const char *ext)
{
    static const char *const formats[6] = {"package-k1", "float-k1", "package", "float", "package-kall", "float-kall"};
    static const char *const titles[6] = {"k1 package", "k1 float optimum", "k3 package", "k3 float optimum",
                                          "k all package", "k all float optimum"};
    int cols = nsm < 1 ? 1 : nsm;
    fprintf(f, "set terminal %s size %d,520 font \"DejaVu Sans,11\" background rgb \"white\"\n", term, 80 + 420 * cols);
    fprintf(f, "set output \"%s/chart-streaming-k.%s\"\n", out_dir, ext);
    fprintf(f, "set multiplot layout 1,%d title \"Error after each chunk (C = 1..8) at k = 1, 3 and every view: "
               "package (solid) and the float PCA optimum of the same k at the package's bytes (dash-dot)\"\n", cols);
    fprintf(f, "set xlabel \"bytes received (KiB)\"\nset ylabel \"CIELab error (whole BTF)\"\n"
               "set logscale x\nset logscale y\nset grid\nset key top right font \",8\"\n");
    for (int i = 0; i < nsm || i == 0; i++) {
        int any = 0;
        for (int k = 0; k < 6; k++) {
            char name[32];
            snprintf(name, sizeof name, "k_%d_%d", i, k);
            any += btf__plot_curve(f, st, name, i < nsm ? smats[i] : NULL, formats[k]);
        }
        fprintf(f, "set title \"%s\"\n", i < nsm ? smats[i] : "no materials");
        if (!any) {
            fprintf(f, "plot [1:10][1:10] NaN notitle\n");
            continue;
        }
        fprintf(f, "plot ");
        for (int k = 0; k < 6; k++)
            fprintf(f, "$k_%d_%d using 1:2 with linespoints lc rgb \"%s\" lw %d dt %d pt %d ps 1.0 title \"%s\", ", i, k,
                    btf__plot_colours[k / 2], k % 2 ? 1 : 2, k % 2 ? 4 : 1, k % 2 ? 6 : 7, titles[k]);
        fprintf(f, "NaN notitle\n");
    }
    fprintf(f, "unset multiplot\nunset output\nunset logscale\nunset title\n");
}

/* Writes the data blocks and plot commands of all three charts for one terminal. */
static btf_result btf__plot_script(FILE *f, const btf__csv *sa, const btf__csv *st, const btf__csv *ct,
                                   const char *out_dir, const char *term, const char *ext, btf_error *err)
{
    (void)err;
    const char *mats[BTF__PLOT_MAX], *fams[BTF__PLOT_MAX], *sfams[BTF__PLOT_MAX];
    int cm = btf__csv_col(sa, "material"), cf = btf__csv_col(sa, "family"), csh = btf__csv_col(sa, "shader_ms");
    int nm = btf__csv_distinct(sa, cm, -1, NULL, mats, BTF__PLOT_MAX);
    const char *mat = nm ? mats[nm - 1] : "mean";
    for (int i = 0; i < nm; i++)
        if (!strcmp(mats[i], "mean"))
            mat = "mean";
    int nf = btf__csv_distinct(sa, cf, cm, mat, fams, BTF__PLOT_MAX);
    int nsf = 0; /* families with a shader time */
    for (int i = 0; i < nf; i++)
        for (int r = 1; r < sa->n_rows; r++)
            if (!strcmp(sa->row[r][cf], fams[i]) && isfinite(btf__csv_num(sa, r, csh))) {
                sfams[nsf++] = fams[i];
                break;
            }
    int n_real = nm - (strcmp(mat, "mean") == 0);
    btf__plot_styles(f);
    fprintf(f, "set terminal %s size 1650,560 font \"DejaVu Sans,11\" background rgb \"white\"\n", term);
    fprintf(f, "set output \"%s/chart-speed-accuracy.%s\"\n", out_dir, ext);
    fprintf(f, "set grid\nset key top right font \",9\"\nset logscale y\n"
               "set offsets 0, graph 0.2, 0, 0\n"); /* room for the labels on the right */
    if (strcmp(mat, "mean"))
        fprintf(f, "set multiplot layout 1,3 title \"Speed vs accuracy: %s", mat);
    else
        fprintf(f, "set multiplot layout 1,3 title \"Speed vs accuracy: mean over %d material%s", n_real,
                n_real == 1 ? "" : "s");
    fprintf(f, "; y = CIELab error (thesis MAE, whole BTF, measured directions); circles: Pareto front\"\n");
    fprintf(f, "set ylabel \"CIELab error\"\n");
    btf__plot_panel(f, sa, mat, fams, nf, "cost", "cost", "pareto_cost", 1.0,
                    "decode cost per fragment: texture fetches + ALU ops (cost model)", "error vs decode cost");
    /* shader panel: front recomputed among the timed settings is not in the CSV; show lines only */
    fprintf(f, "unset ylabel\n");
    btf__plot_panel(f, sa, mat, sfams, nsf, "shader", "shader_ms", "no_such_column", 1.0,
                    "shader ms/frame, 1280x720, headless llvmpipe", "error vs shader time (PCA package)");
    btf__plot_panel(f, sa, mat, fams, nf, "bytes", "bytes", "pareto_bytes", 1.0 / 1024.0, "model size (KiB)",
                    "error vs bytes");
    fprintf(f, "unset multiplot\nunset output\nunset logscale\nunset label\nset offsets 0, 0, 0, 0\n");

    /* streaming */
    int sm = btf__csv_col(st, "material");
    const char *smats[BTF__PLOT_MAX];
    int nsm = btf__csv_distinct(st, sm, -1, NULL, smats, BTF__PLOT_MAX);
    static const char *const formats[4] = {"package", "thesis", "levels", "float"};
    fprintf(f, "set terminal %s size 1000,640 font \"DejaVu Sans,11\" background rgb \"white\"\n", term);
    fprintf(f, "set output \"%s/chart-streaming.%s\"\n", out_dir, ext);
    fprintf(f, "set title \"Streaming, error after each chunk (k3 C8): package (solid), thesis format (dashed), "
               "package with residual levels (dotted), float PCA optimum at the package's bytes (dash-dot)\"\n"
               "set xlabel \"bytes received (KiB)\"\nset ylabel \"CIELab error (whole BTF)\"\n"
               "set logscale x\nset logscale y\nset grid\nset key top right font \",9\"\n");
    int any = 0;
    for (int i = 0; i < nsm; i++)
        for (int k = 0; k < 4; k++) {
            char name[32];
            snprintf(name, sizeof name, "s_%d_%d", i, k);
            any += btf__plot_curve(f, st, name, smats[i], formats[k]);
        }
    if (!any)
        fprintf(f, "plot [1:10][1:10] NaN notitle\n");
    else {
        fprintf(f, "plot ");
        for (int i = 0; i < nsm; i++)
            for (int k = 0; k < 4; k++)
                fprintf(f, "$s_%d_%d using 1:2 with linespoints lc rgb \"%s\" lw %d dt %d pt %d ps 1.1 "
                           "title \"%s %s\", ",
                        i, k, btf__plot_colours[i % 10], k == 3 ? 1 : 2, k + 1, k == 3 ? 1 : k == 2 ? 6 : k ? 4 : 7,
                        smats[i], formats[k]);
        fprintf(f, "NaN notitle\n");
    }
    fprintf(f, "unset output\nunset logscale\n");
    btf__plot_stream_k(f, st, smats, nsm, out_dir, term, ext);

    /* compression time: clustered bars, one cluster per setting, one bar per material */
    fprintf(f, "set terminal %s size 1500,600 font \"DejaVu Sans,11\" background rgb \"white\"\n", term);
    fprintf(f, "set output \"%s/chart-compress-time.%s\"\n", out_dir, ext);
    fprintf(f, "set title \"Compression (encode) time per method setting\"\nset xlabel \"\"\n"
               "set ylabel \"seconds (log)\"\nset logscale y\nset grid ytics\n"
               "set style data histograms\nset style histogram clustered gap 1\n"
               "set style fill solid 0.85 border -1\nset boxwidth 0.9\n"
               "set xtics rotate by -40 left font \",9\"\nset key top left font \",9\"\n");
    fprintf(f, "$t << EOD\n");
    for (int r = 0; r < ct->n_rows; r++) { /* names quoted, numbers bare, empty = NaN */
        for (int k = 0; k < ct->n_cols; k++) {
            const char *v = ct->row[r][k];
            if (r == 0 || k < 2)
                fprintf(f, "%s\"%s\"", k ? " " : "", v);
            else
                fprintf(f, " %s", isfinite(btf__csv_num(ct, r, k)) ? v : "NaN");
        }
        fprintf(f, "\n");
    }
    fprintf(f, "EOD\n");
    int bars = 0; /* one bar per material; the mean column stays in the CSV only */
    fprintf(f, "plot ");
    for (int k = 2; k < ct->n_cols; k++)
        if (strcmp(ct->row[0][k], "mean"))
            fprintf(f, "%s$t using %d:xtic(1) title columnhead ls %d", bars++ ? ", " : "", k + 1, (k - 2) % 10 + 1);
    fprintf(f, "%s\n", bars ? "" : "[0:1][1:10] NaN notitle");
    fprintf(f, "unset output\nreset\n");
    return BTF_OK;
}

static int btf__plot_safe_path(const char *s)
{
    for (; *s; s++)
        if (*s == '"' || *s == '\\' || *s == '\n' || *s == '`')
            return 0;
    return 1;
}

btf_result btf_chart_plot(const char *csv_dir, const char *out_dir, btf_error *err)
{
    if (!csv_dir || !out_dir)
        return btf_fail(err, BTF_ERR_ARG, "chart: NULL directory");
    if (!btf__plot_safe_path(out_dir))
        return btf_fail(err, BTF_ERR_ARG, "chart: output directory %s has a quote or backslash", out_dir);
    char path[4096];
    btf__csv sa = {0}, st = {0}, ct = {0};
    snprintf(path, sizeof path, "%s/chart-speed-accuracy.csv", csv_dir);
    btf_result r = btf__csv_read(path, &sa, err);
    snprintf(path, sizeof path, "%s/chart-streaming.csv", csv_dir);
    if (r == BTF_OK)
        r = btf__csv_read(path, &st, err);
    snprintf(path, sizeof path, "%s/chart-compress-time.csv", csv_dir);
    if (r == BTF_OK)
        r = btf__csv_read(path, &ct, err);
    static const char *const need[] = {"material", "family", "label", "ok", "lab", "cost", "bytes", "shader_ms",
                                       "pareto_cost", "pareto_bytes"};
    for (size_t i = 0; r == BTF_OK && i < sizeof need / sizeof need[0]; i++)
        if (btf__csv_col(&sa, need[i]) < 0)
            r = btf_fail(err, BTF_ERR_FORMAT, "chart: chart-speed-accuracy.csv has no column %s", need[i]);
    if (r == BTF_OK && (btf__csv_col(&st, "material") < 0 || btf__csv_col(&st, "bytes") < 0 ||
                        btf__csv_col(&st, "lab") < 0 || btf__csv_col(&st, "format") < 0))
        r = btf_fail(err, BTF_ERR_FORMAT, "chart: chart-streaming.csv lacks material/format/bytes/lab");
    char script[4200];
    snprintf(script, sizeof script, "%s/.chart-%d.gp", out_dir, (int)getpid());
    FILE *f = r == BTF_OK ? fopen(script, "w") : NULL;
    if (r == BTF_OK && !f)
        r = btf_fail(err, BTF_ERR_IO, "chart: cannot write %s", script);
    if (r == BTF_OK)
        r = btf__plot_script(f, &sa, &st, &ct, out_dir, "svg dynamic", "svg", err);
    if (r == BTF_OK)
        r = btf__plot_script(f, &sa, &st, &ct, out_dir, "pngcairo", "png", err);
    if (f && fclose(f) != 0 && r == BTF_OK)
        r = btf_fail(err, BTF_ERR_IO, "chart: cannot write %s", script);
    if (r == BTF_OK) {
        pid_t pid = fork();
        if (pid == 0) {
            execlp("gnuplot", "gnuplot", script, (char *)NULL);
            _exit(127);
        }
        int status = 0;
        if (pid < 0 || waitpid(pid, &status, 0) < 0)
            r = btf_fail(err, BTF_ERR_IO, "chart: cannot start gnuplot");
        else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
            r = btf_fail(err, BTF_ERR_IO, "chart: gnuplot failed (exit %d) on %s%s",
                         WIFEXITED(status) ? WEXITSTATUS(status) : -1, script,
                         WIFEXITED(status) && WEXITSTATUS(status) == 127 ? " (is gnuplot installed?)" : "");
    }
    if (f && !getenv("BTF_CHART_KEEP_SCRIPT")) /* kept for debugging gnuplot */
        unlink(script);
    btf__csv_free(&sa), btf__csv_free(&st), btf__csv_free(&ct);
    return r;
}
