/* test_cli.c - room tools, suite "cli": the `btf` command line as people use it: getopt_long forms
 * (`--k 3` and `--k=3`), `--version`, `--json` of compress, eval and lod, exit
 * codes and their place in every --help, the progress callback of the PCA loop. */
#include <criterion/criterion.h>
#include <cjson/cJSON.h>
#include <math.h>

#include "btf_cli.h"
#include "btf_input.h"
#include "btf_output.h"
#include "btf_package.h"
#include "btf_source.h"
#include "btf_version.h"
#include "fixtures.h"

/* Runs cmd with stdout (fd 1) or stderr (fd 2) captured into buf (NUL-terminated). */
static int run_captured(int (*cmd)(int, char **), int argc, char **argv, int fd, char *buf, size_t n)
{
    FILE *stream = fd == 1 ? stdout : stderr;
    fflush(stream);
    int saved = dup(fd);
    FILE *tmp = tmpfile();
    cr_assert(saved >= 0 && tmp);
    dup2(fileno(tmp), fd);
    int rc = cmd(argc, argv);
    fflush(stream);
    dup2(saved, fd);
    close(saved);
    rewind(tmp);
    size_t k = fread(buf, 1, n - 1, tmp);
    buf[k] = '\0';
    fclose(tmp);
    return rc;
}

static double num(const cJSON *o, const char *k)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    cr_assert(cJSON_IsNumber(v), "field %s missing or not a number", k);
    return v->valuedouble;
}

static const char *str(const cJSON *o, const char *k)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    cr_assert(cJSON_IsString(v), "field %s missing or not a string", k);
    return v->valuestring;
}

/* The whole of out must be one JSON object (trailing whitespace allowed). */
static cJSON *parse_only_object(const char *out)
{
    const char *end = NULL;
    cJSON *j = cJSON_ParseWithOpts(out, &end, 1);
    cr_assert(j && cJSON_IsObject(j), "stdout is not exactly one JSON object: %.300s", out);
    return j;
}

/* `btf compress gen:knit:16 DIR/NAME --k K --components 4 --name p --quiet` (a small package). */
static void compress_small(const char *dir, const char *name, const char *k)
{
    char out[400];
    snprintf(out, sizeof out, "%s/%s", dir, name);
    char *argv[] = {"compress", "gen:knit:16", out, "--k", (char *)k, "--components", "4", "--name", "p", "--quiet",
                    NULL};
    cr_assert_eq(cmd_compress(10, argv), 0, "compress %s", out);
}

Test(cli, k_with_equals_or_space_gives_the_same_package)
{
    char dir[256], a[400], b[400], c[400];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(a, sizeof a, "%s/a", dir);
    snprintf(b, sizeof b, "%s/b", dir);
    snprintf(c, sizeof c, "%s/c", dir);
    /* options after the positionals with '=', before them with a space */
    char *eq[] = {"compress", "gen:knit:16", a, "--k=2", "--components=4", "--name=p", "--quiet", NULL};
    char *sp[] = {"compress", "--k", "2", "--components", "4", "--name", "p", "--quiet", "gen:knit:16", b, NULL};
    cr_assert_eq(cmd_compress(7, eq), 0);
    cr_assert_eq(cmd_compress(10, sp), 0);
    compress_small(dir, "c", "3");
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(a, 1, &p, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(p->k, 2, "--k=2 gave k %d", p->k);
    cr_assert_eq(p->n_chunks, 4, "--components=4 gave %d chunks", p->n_chunks);
    cr_assert_str_eq(p->name, "p");
    for (int i = 0; i < p->n_chunks; i++)
        for (int f = 0; f < p->chunk[i].n_files; f++)
            cr_assert(fx_same_file(a, b, p->chunk[i].files[f]), "%s differs", p->chunk[i].files[f]);
    btf_package_free(p);
    cr_assert(fx_same_file(a, b, "manifest.json"), "manifests differ");
    cr_assert(!fx_same_file(a, c, "manifest.json"), "--k 3 wrote what --k=2 wrote");
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* --linear: a linear-light package, the same read view by view or loaded whole
 * (--in-memory), and with levels. */
Test(cli, compress_linear_marks_the_package)
{
    char dir[256], a[400], b[400], c[400];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(a, sizeof a, "%s/a", dir);
    snprintf(b, sizeof b, "%s/b", dir);
    snprintf(c, sizeof c, "%s/c", dir);
    char *views[] = {"compress", "gen:knit:16", a, "--components=4", "--name=p", "--linear", "--quiet", NULL};
    char *whole[] = {"compress", "gen:knit:16", b, "--components=4", "--name=p", "--linear", "--in-memory", "--quiet", NULL};
    char *levels[] = {"compress", "gen:knit:16", c, "--components=4", "--linear", "--levels=2", "--quiet", NULL};
    cr_assert_eq(cmd_compress(7, views), 0);
    cr_assert_eq(cmd_compress(8, whole), 0);
    cr_assert_eq(cmd_compress(7, levels), 0);
    cr_assert(fx_same_file(a, b, "manifest.json"), "view by view and in memory differ");
    const char *pkg[] = {a, c};
    for (int i = 0; i < 2; i++) {
        btf_package *p = NULL;
        btf_error err = {{0}};
        cr_assert_eq(btf_package_read(pkg[i], 1, &p, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(p->linear, 1, "%s", pkg[i]);
        btf_package_free(p);
    }
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* `btf --version` and `btfd --version`: the programs themselves (main is not in this binary). */
Test(cli, version_of_btf_and_btfd)
{
    const char *build = getenv("BTF_BUILD");
    const char *prog[] = {"btf", "btfd"};
    for (int i = 0; i < 2; i++) {
        char cmd[600], line[128] = "", want[64];
        snprintf(cmd, sizeof cmd, "'%s/%s' --version", build ? build : "build", prog[i]);
        FILE *f = popen(cmd, "r");
        cr_assert(f, "%s", cmd);
        size_t n = fread(line, 1, sizeof line - 1, f);
        line[n] = '\0';
        cr_assert_eq(pclose(f), 0, "%s failed", cmd);
        snprintf(want, sizeof want, "%s %s\n", prog[i], BTF_VERSION);
        cr_assert_str_eq(line, want);
    }
    char cmd[600], help[8192] = "";
    snprintf(cmd, sizeof cmd, "'%s/btf' --help", build ? build : "build");
    FILE *f = popen(cmd, "r");
    cr_assert(f);
    help[fread(help, 1, sizeof help - 1, f)] = '\0';
    cr_assert_eq(pclose(f), 0);
    cr_assert(strstr(help, "0 ok, 1 failure, 2 usage error"), "btf --help: %s", help);
}

/* Every `btf` command by name; static table, lives for the program. */
static const struct {
    const char *name;
    int (*run)(int, char **);
} commands[] = {
    {"chart", cmd_chart},   {"compress", cmd_compress},           {"eval", cmd_eval},
    {"export-thesis", cmd_export_thesis}, {"gen", cmd_gen},       {"import-thesis", cmd_import_thesis},
    {"library", cmd_library}, {"lod", cmd_lod},   {"render", cmd_render},
};

Test(cli, bad_option_exits_2_and_every_help_lists_exit_codes)
{
    char out[16384];
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++) {
        char *bad[] = {(char *)commands[i].name, "--no-such-option", "in", "out", NULL};
        cr_assert_eq(run_captured(commands[i].run, 4, bad, 2, out, sizeof out), 2, "%s", commands[i].name);
        cr_assert(strstr(out, "--no-such-option"), "btf %s does not name the option: %s", commands[i].name, out);
        char *help[] = {(char *)commands[i].name, "--help", NULL};
        cr_assert_eq(run_captured(commands[i].run, 2, help, 1, out, sizeof out), 0, "%s --help", commands[i].name);
        cr_assert(strstr(out, "Exit status: 0 ok, 1 failure, 2 usage error."), "btf %s --help: %s",
                  commands[i].name, out);
    }
    /* a value with '=' is checked like one after a space; a missing value is a usage error */
    char *eq[] = {"compress", "in", "out", "--k=0", NULL};
    cr_assert_eq(run_captured(cmd_compress, 4, eq, 2, out, sizeof out), 2);
    cr_assert(strstr(out, "--k 0: expected"), "%s", out);
    char *dangling[] = {"lod", "in", "out", "--levels", NULL};
    cr_assert_eq(run_captured(cmd_lod, 4, dangling, 2, out, sizeof out), 2);
    char *flag_value[] = {"eval", "a", "b", "--json=yes", NULL};
    cr_assert_eq(run_captured(cmd_eval, 4, flag_value, 2, out, sizeof out), 2);
    /* an enum names its choices: --rounding cut|keep */
    char *rounding[] = {"compress", "in", "out", "--rounding", "some", NULL};
    cr_assert_eq(run_captured(cmd_compress, 5, rounding, 2, out, sizeof out), 2);
    cr_assert(strstr(out, "cut") && strstr(out, "keep"), "%s", out);
}

Test(cli, compress_json_describes_the_package)
{
    char dir[256], pkg[400], out[65536];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    char *argv[] = {"compress", "gen:knit:16", pkg, "--components=4", "--json", NULL};
    cr_assert_eq(run_captured(cmd_compress, 5, argv, 1, out, sizeof out), 0);
    cJSON *j = parse_only_object(out);
    cr_assert_str_eq(str(j, "path"), pkg);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq((int)num(j, "chunks"), p->n_chunks);
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(j, "chunk");
    cr_assert_eq(cJSON_GetArraySize(list), p->n_chunks);
    long long total = 0;
    for (int i = 0; i < p->n_chunks; i++) {
        const cJSON *c = cJSON_GetArrayItem(list, i);
        total += p->chunk[i].bytes;
        cr_assert_eq((int)num(c, "index"), i);
        cr_assert_eq((int)num(c, "component"), p->chunk[i].component);
        cr_assert_eq((long long)num(c, "bytes"), p->chunk[i].bytes);
        cr_assert_eq((long long)num(c, "cumulative"), total);
        cr_assert_float_eq(num(c, "rmse"), p->chunk[i].rmse, 1e-9);
        cr_assert_float_eq(num(c, "lab"), p->chunk[i].lab, 1e-9);
        cr_assert(num(c, "rmse_float") > 0);
    }
    cr_assert_eq((long long)num(j, "bytes"), total);
    cr_assert(num(j, "seconds_pca") >= 0 && num(j, "seconds_write") >= 0 && num(j, "seconds_load") >= 0);
    btf_package_free(p);
    cJSON_Delete(j);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* The decode of p's first n chunks (n <= 0: all): in floats, or (displayed) as a
 * page's canvas stores it, each decoded value through a BTF_U8 (btf_set rounds as an
 * 8-bit image writer does). */
static btf *prefix_decode(const btf_package *p, int n, int displayed)
{
    btf *rec = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_reconstruct(p, n, &rec, &err), BTF_OK, "%s", err.msg);
    if (!displayed)
        return rec;
    btf *u8 = fx_convert(rec, BTF_U8);
    btf_free(rec);
    return u8;
}

Test(cli, eval_json_has_the_error_curve)
{
    char dir[256], pkg[400], out[65536];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    compress_small(dir, "p", "3");
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    char *argv[] = {"eval", "--json", "gen:knit:16", pkg, NULL};
    cr_assert_eq(run_captured(cmd_eval, 4, argv, 1, out, sizeof out), 0);
    cJSON *j = parse_only_object(out);
    cr_assert_str_eq(str(j, "path"), pkg);
    cr_assert_str_eq(str(j, "ref"), "gen:knit:16");
    cr_assert_eq((int)num(j, "chunks"), 4);
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(j, "chunk");
    cr_assert_eq(cJSON_GetArraySize(list), 4);
    /* each point (decoded a tile of texels at a time) is btf_compare of that prefix's
     * whole decode, to the sums' order (1e-9) */
    btf *src = NULL;
    btf_package *p = NULL;
    btf_error err = {{0}};
    btf_load_options lo = {0};
    cr_assert_eq(btf_source_load("gen:knit:16", &lo, &src, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    for (int n = 1; n <= 4; n++) {
        btf *rec = prefix_decode(p, n, 0);
        btf_metrics m;
        cr_assert_eq(btf_compare(src, rec, NULL, &m, &err), BTF_OK, "%s", err.msg);
        const cJSON *c = cJSON_GetArrayItem(list, n - 1);
        cr_assert_float_eq(num(c, "rgb_rmse"), m.rmse, 1e-9 * m.rmse, "chunk %d", n - 1);
        cr_assert_float_eq(num(c, "lab_mae"), m.lab_thesis, 1e-9 * m.lab_thesis, "chunk %d", n - 1);
        cr_assert_float_eq(num(c, "delta_e76"), m.delta_e76, 1e-9 * m.delta_e76, "chunk %d", n - 1);
        btf_free(rec);
    }
    btf_package_free(p);
    btf_free(src);
    double prev = 1e9;
    for (int i = 0; i < 4; i++) {
        const cJSON *c = cJSON_GetArrayItem(list, i);
        cr_assert_eq((int)num(c, "index"), i);
        cr_assert_lt(num(c, "rgb_rmse"), prev, "chunk %d does not lower the error", i);
        prev = num(c, "rgb_rmse");
        cr_assert(num(c, "lab_mae") > 0 && num(c, "delta_e76") > 0);
    }
    const cJSON *last = cJSON_GetArrayItem(list, 3);
    cr_assert_eq(num(last, "cumulative_bytes"), num(j, "bytes"));
    cr_assert_float_eq(num(j, "rgb_rmse"), num(last, "rgb_rmse"), 1e-12);
    cr_assert_eq((int)num(j, "pairs"), 81 * 81);
    cr_assert(num(j, "psnr") > 0 && num(j, "pixels") > 0);
    /* --no-curve: the same whole-package metrics and bytes, one entry (the last) */
    char *whole[] = {"eval", "--json", "--no-curve", "gen:knit:16", pkg, NULL};
    cr_assert_eq(run_captured(cmd_eval, 5, whole, 1, out, sizeof out), 0);
    cJSON *w = parse_only_object(out);
    const cJSON *wl = cJSON_GetObjectItemCaseSensitive(w, "chunk");
    cr_assert_eq(cJSON_GetArraySize(wl), 1);
    cr_assert_eq((int)num(cJSON_GetArrayItem(wl, 0), "index"), 3);
    cr_assert_eq(num(w, "bytes"), num(j, "bytes"));
    cr_assert_eq((int)num(w, "chunks"), 4);
    cr_assert_float_eq(num(w, "rgb_rmse"), num(j, "rgb_rmse"), 1e-12);
    cr_assert_float_eq(num(w, "lab_mae"), num(j, "lab_mae"), 1e-12);
    cJSON_Delete(w);
    cJSON_Delete(j);
    char *both[] = {"eval", "--json", "--csv", "gen:knit:16", pkg, NULL};
    cr_assert_eq(run_captured(cmd_eval, 5, both, 2, out, sizeof out), 2, "--json with --csv");
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* --displayed: every prefix (a tile of texels at a time, levelled or not) and the
 * --pairs route (whole decodes) measure what btf_compare finds against the decode
 * stored as 8-bit codes, computed here by another route; and the displayed error is
 * not the decoded floats' (the rounding changes what is measured). */
Test(cli, eval_displayed_measures_the_8_bit_codes_a_page_shows)
{
    char dir[256], pkg[400], lev[400], out[65536];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    compress_small(dir, "p", "3");
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    snprintf(lev, sizeof lev, "%s/lev", dir);
    char *lv[] = {"lod", pkg, lev, "--levels", "2", "--quiet", NULL};
    cr_assert_eq(run_captured(cmd_lod, 6, lv, 2, out, sizeof out), 0);
    btf *src = NULL;
    btf_error err = {{0}};
    btf_load_options lo = {0};
    cr_assert_eq(btf_source_load("gen:knit:16", &lo, &src, &err), BTF_OK, "%s", err.msg);
    const char *pkgs[] = {pkg, lev};
    for (int k = 0; k < 2; k++) {
        char *argv[] = {"eval", "--json", "--displayed", "gen:knit:16", (char *)pkgs[k], NULL};
        cr_assert_eq(run_captured(cmd_eval, 5, argv, 1, out, sizeof out), 0);
        cJSON *j = parse_only_object(out);
        cr_assert(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "displayed")));
        const cJSON *list = cJSON_GetObjectItemCaseSensitive(j, "chunk");
        btf_package *p = NULL;
        cr_assert_eq(btf_package_read(pkgs[k], 0, &p, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(cJSON_GetArraySize(list), p->n_chunks);
        for (int n = 1; n <= p->n_chunks; n++) {
            btf *u8 = prefix_decode(p, n, 1);
            btf_metrics m, f;
            cr_assert_eq(btf_compare(src, u8, NULL, &m, &err), BTF_OK, "%s", err.msg);
            const cJSON *c = cJSON_GetArrayItem(list, n - 1);
            cr_assert_float_eq(num(c, "lab_mae"), m.lab_thesis, 1e-9 * m.lab_thesis, "%s chunk %d", pkgs[k], n - 1);
            /* two BTF_U8 are compared in whole codes; the decode's codes as floats carry
             * float32's 6e-8 of a value: 1e-6 of an RMSE */
            cr_assert_float_eq(num(c, "rgb_rmse"), m.rmse, 1e-6 * m.rmse, "%s chunk %d", pkgs[k], n - 1);
            cr_assert_eq(btf_package_compare(p, n, src, &f, &err), BTF_OK, "%s", err.msg);
            cr_assert(fabs(f.lab_thesis - m.lab_thesis) > 1e-6 * m.lab_thesis, "rounding changed nothing");
            btf_free(u8);
        }
        /* --pairs: each prefix decoded whole, then rounded */
        char *pairs[] = {"eval", "--json", "--no-curve", "--displayed", "--pairs", "0:0,40:12,80:3",
                         "gen:knit:16", (char *)pkgs[k], NULL};
        cr_assert_eq(run_captured(cmd_eval, 8, pairs, 1, out, sizeof out), 0);
        cJSON *w = parse_only_object(out);
        btf *u8 = prefix_decode(p, 0, 1);
        int vs[] = {0, 40, 80}, ls[] = {0, 12, 3};
        btf_pair_subset sub = {vs, ls, 3};
        btf_metrics m;
        cr_assert_eq(btf_compare(src, u8, &sub, &m, &err), BTF_OK, "%s", err.msg);
        cr_assert_float_eq(num(w, "lab_mae"), m.lab_thesis, 1e-9 * m.lab_thesis, "%s, three pairs", pkgs[k]);
        btf_free(u8);
        btf_package_free(p);
        cJSON_Delete(w);
        cJSON_Delete(j);
    }
    btf_free(src);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* A thesis package as TEST is measured as its reconstruction in floats, as a
 * package's decode is (not rounded to the bytes its import stores), at REF's size;
 * with --displayed as those bytes. Each computed here from btf_import_thesis. */
Test(cli, eval_reads_a_thesis_package_as_floats)
{
    char dir[256], th[400], out[65536];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(th, sizeof th, "%s/th", dir);
    char *ex[] = {"export-thesis", "gen:knit:16", th, "--k", "3", "--components", "4", NULL};
    cr_assert_eq(run_captured(cmd_export_thesis, 7, ex, 1, out, sizeof out), 0);
    btf *src = NULL, *f32 = NULL, *u8 = NULL;
    btf_error err = {{0}};
    btf_load_options lo = {0};
    cr_assert_eq(btf_source_load("gen:knit:16", &lo, &src, &err), BTF_OK, "%s", err.msg);
    lo.storage = BTF_F32;
    cr_assert_eq(btf_import_thesis(th, &lo, &f32, &err), BTF_OK, "%s", err.msg);
    lo.storage = BTF_U8;
    cr_assert_eq(btf_import_thesis(th, &lo, &u8, &err), BTF_OK, "%s", err.msg);
    btf_metrics mf, mu;
    cr_assert_eq(btf_compare(src, f32, NULL, &mf, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_compare(src, u8, NULL, &mu, &err), BTF_OK, "%s", err.msg);
    cr_assert(fabs(mf.lab_thesis - mu.lab_thesis) > 1e-6 * mu.lab_thesis, "the import's rounding changed nothing");
    const btf_metrics *want[] = {&mf, &mu};
    for (int d = 0; d < 2; d++) {
        char *argv[] = {"eval", "--json", "gen:knit:16", th, d ? "--displayed" : NULL, NULL};
        cr_assert_eq(run_captured(cmd_eval, 4 + d, argv, 1, out, sizeof out), 0);
        cJSON *j = parse_only_object(out);
        cr_assert_float_eq(num(j, "lab_mae"), want[d]->lab_thesis, 1e-9 * want[d]->lab_thesis, "displayed %d", d);
        cr_assert_float_eq(num(j, "rgb_rmse"), want[d]->rmse, 1e-6 * want[d]->rmse, "displayed %d", d);
        cJSON_Delete(j);
    }
    btf_free(src), btf_free(f32), btf_free(u8);
    /* against a smaller reference: reconstructed at its size */
    lo = (btf_load_options){0};
    cr_assert_eq(btf_source_load("gen:knit:8", &lo, &src, &err), BTF_OK, "%s", err.msg);
    lo.storage = BTF_F32, lo.width = lo.height = 8;
    cr_assert_eq(btf_import_thesis(th, &lo, &f32, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_compare(src, f32, NULL, &mf, &err), BTF_OK, "%s", err.msg);
    char *small[] = {"eval", "--json", "gen:knit:8", th, NULL};
    cr_assert_eq(run_captured(cmd_eval, 4, small, 1, out, sizeof out), 0);
    cJSON *j = parse_only_object(out);
    cr_assert_float_eq(num(j, "lab_mae"), mf.lab_thesis, 1e-9 * mf.lab_thesis);
    cJSON_Delete(j);
    btf_free(src), btf_free(f32);
    cr_assert_eq(fx_rmtree(dir), 0);
}

Test(cli, lod_json_lists_the_levels)
{
    char dir[256], in[400], pkg[400], out[65536];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    compress_small(dir, "v1", "3");
    snprintf(in, sizeof in, "%s/v1", dir);
    snprintf(pkg, sizeof pkg, "%s/v2", dir);
    char *argv[] = {"lod", in, pkg, "--levels=2", "--json", NULL};
    cr_assert_eq(run_captured(cmd_lod, 5, argv, 1, out, sizeof out), 0);
    cJSON *j = parse_only_object(out);
    cr_assert_str_eq(str(j, "path"), pkg);
    cr_assert_eq((int)num(j, "levels"), 2);
    cr_assert_eq((int)num(j, "chunks"), 8, "4 components x 2 levels");
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(j, "chunk");
    cr_assert_eq(cJSON_GetArraySize(list), 8);
    int coarse = 0;
    long long total = 0;
    for (int i = 0; i < 8; i++) {
        const cJSON *c = cJSON_GetArrayItem(list, i);
        coarse += num(c, "level") == 1;
        total += (long long)num(c, "bytes");
        cr_assert_eq((long long)num(c, "cumulative"), total);
        cr_assert(num(c, "rmse") > 0);
    }
    cr_assert_eq(coarse, 4);
    cr_assert_eq((long long)num(j, "bytes"), total);
    cr_assert(num(j, "bytes_v1") > 0 && num(j, "first_chunk_bytes") > 0);
    cJSON_Delete(j);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* `btf lod --source`: a source of another size is refused with a clear message and
 * nothing written; the package's own source builds the levels as `btf compress
 * --levels` does (the same chunk files). */
Test(cli, lod_source_is_checked_and_builds_as_compress)
{
    char dir[256], in[400], pkg[400], ref[400], out[4096];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    compress_small(dir, "v3", "3");
    snprintf(in, sizeof in, "%s/v3", dir);
    snprintf(pkg, sizeof pkg, "%s/lv", dir);
    snprintf(ref, sizeof ref, "%s/cl", dir);
    char *bad[] = {"lod", in, pkg, "--levels", "2", "--source", "gen:knit:8", "--quiet", NULL};
    cr_assert_eq(run_captured(cmd_lod, 8, bad, 2, out, sizeof out), 1);
    cr_assert(strstr(out, "not the package's size"), "stderr: %s", out);
    cr_assert_lt(btf_fs_size(pkg), 0, "nothing written");
    char *good[] = {"lod", in, pkg, "--levels", "2", "--source", "gen:knit:16", "--no-thumbnail", "--quiet", NULL};
    cr_assert_eq(cmd_lod(9, good), 0);
    char *cl[] = {"compress", "gen:knit:16", ref, "--k", "3", "--components", "4", "--name", "p", "--levels", "2",
                  "--no-thumbnail", "--quiet", NULL};
    cr_assert_eq(cmd_compress(13, cl), 0);
    btf_package *a = fx_package(dir, "lv", 0), *b = fx_package(dir, "cl", 0);
    cr_assert_eq(a->n_chunks, b->n_chunks);
    for (int i = 0; i < a->n_chunks; i++)
        for (int f = 0; f < a->chunk[i].n_files; f++)
            cr_expect(fx_same_file(pkg, ref, a->chunk[i].files[f]), "%s differs", a->chunk[i].files[f]);
    btf_package_free(a), btf_package_free(b);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* The compress report prints "-" for what the manifest does not record (rmse_float in
 * version 4, lab with levels), a number for what it does. */
Test(cli, compress_report_marks_values_the_manifest_lacks)
{
    char dir[256], a[400], b[400], out[16384];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(a, sizeof a, "%s/a", dir), snprintf(b, sizeof b, "%s/b", dir);
    char *v3[] = {"compress", "gen:knit:16", a, "--k", "3", "--components", "4", "--no-thumbnail", NULL};
    char *v4[] = {"compress", "gen:knit:16", b, "--k", "3", "--components", "4", "--levels", "2", "--no-thumbnail", NULL};
    cr_assert_eq(run_captured(cmd_compress, 8, v3, 1, out, sizeof out), 0);
    const char *row = strstr(out, "\n    0 ");
    cr_assert_not_null(row, "%s", out);
    cr_assert_null(strstr(out, " -"), "version 3 records every value: %s", out);
    cr_assert_eq(run_captured(cmd_compress, 10, v4, 1, out, sizeof out), 0);
    row = strstr(out, "\n    0 ");
    cr_assert_not_null(row, "%s", out);
    const char *eol = strchr(row + 1, '\n');
    cr_assert(eol && eol - row > 8 && !strncmp(eol - 8, "-      -", 8), "version 4 row: %.*s", (int)(eol ? eol - row : 40), row);
    /* --json gives null where the text prints "-", a number where the manifest has one */
    char *j3[] = {"compress", "gen:knit:16", a, "--k", "3", "--components", "4", "--no-thumbnail", "--json", NULL};
    char *j4[] = {"compress", "gen:knit:16", b, "--k", "3", "--components", "4", "--levels", "2", "--no-thumbnail",
                  "--json", NULL};
    cr_assert_eq(run_captured(cmd_compress, 9, j3, 1, out, sizeof out), 0);
    cJSON *o = cJSON_Parse(out);
    cJSON *c0 = cJSON_GetArrayItem(cJSON_GetObjectItem(o, "chunk"), 0);
    cr_assert(cJSON_IsNumber(cJSON_GetObjectItem(c0, "lab")) && cJSON_GetObjectItem(c0, "lab")->valuedouble > 0.0,
              "%s", out);
    cr_assert(cJSON_IsNumber(cJSON_GetObjectItem(c0, "delta_e76")), "%s", out);
    cJSON_Delete(o);
    cr_assert_eq(run_captured(cmd_compress, 11, j4, 1, out, sizeof out), 0);
    o = cJSON_Parse(out);
    c0 = cJSON_GetArrayItem(cJSON_GetObjectItem(o, "chunk"), 0);
    cr_assert(cJSON_IsNull(cJSON_GetObjectItem(c0, "lab")) && cJSON_IsNull(cJSON_GetObjectItem(c0, "delta_e76")), "%s",
              out);
    cr_assert_null(cJSON_GetObjectItem(c0, "rmse_float"), "%s", out);
    cr_assert(cJSON_IsNumber(cJSON_GetObjectItem(c0, "rmse")), "%s", out);
    cJSON_Delete(o);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Counts the callback's calls; stack value of the test. */
typedef struct progress_count {
    int calls, last_done, total, ordered;
} progress_count;

static void count_progress(void *ctx, int done, int total)
{
    progress_count *c = ctx;
    c->ordered &= done == c->last_done + 1;
    c->calls++, c->last_done = done, c->total = total;
}

/* The PCA options' progress callback reaches the PCA loop through btf_package_compress. */
Test(cli, progress_callback_once_per_block)
{
    btf *src = NULL;
    btf_error err = {{0}};
    btf_load_options lo = {0};
    cr_assert_eq(btf_source_load("gen:tiles:8", &lo, &src, &err), BTF_OK, "%s", err.msg);
    char dir[256], pkg[400];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    progress_count n = {0, 0, 0, 1};
    btf_pca_options po = {.k = 3, .components = 2, .progress = count_progress, .progress_ctx = &n};
    cr_assert_eq(btf_package_compress(src, &po, NULL, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    int blocks = (src->views.n_dirs + 2) / 3;
    cr_assert_eq(n.calls, blocks, "%d calls for %d blocks", n.calls, blocks);
    cr_assert(n.ordered && n.last_done == blocks && n.total == blocks);
    btf_free(src);
    cr_assert_eq(fx_rmtree(dir), 0);
    char line[160];
    btf_progress_format(line, sizeof line, "compress", "blocks", 3, 12, 1.5);
    cr_assert_str_eq(line, "btf compress: 3/12 blocks, 1.5 s elapsed, about 4.5 s left");
    btf_progress_format(line, sizeof line, "compress", "blocks", 12, 12, 6.0);
    cr_assert_str_eq(line, "btf compress: 12/12 blocks, 6.0 s elapsed");
}
