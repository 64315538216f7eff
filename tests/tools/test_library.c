/* test_library.c - room tools, suite "library": `btf library build` (tools/cmd_library.c): one package per
 * source in parallel jobs, atomic writes, skipping what is up to date, failed
 * jobs that leave nothing behind, usage errors. Sources are generated
 * (gen:KIND:8) or a small DFMF file written by `btf gen`. */
#include <criterion/criterion.h>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>

#include "btf_cli.h"
#include "fixtures.h"

#include <cjson/cJSON.h>

static char g_dir[256], g_lib[320];

static void setup(void)
{
    cr_assert(fx_tmpdir(g_dir, sizeof g_dir));
    snprintf(g_lib, sizeof g_lib, "%s/lib", g_dir);
}

static void teardown(void)
{
    fx_rmtree(g_dir);
}

TestSuite(library, .init = setup, .fini = teardown, .timeout = 120);

/* `btf library build ARGS... --out g_lib --quiet`; returns the exit code. */
static int build(const char *const *args)
{
    char *argv[32] = {"library", "build"};
    int argc = 2;
    for (int i = 0; args[i] && argc < 28; i++)
        argv[argc++] = (char *)args[i];
    argv[argc++] = "--out";
    argv[argc++] = g_lib;
    argv[argc++] = "--quiet";
    argv[argc] = NULL;
    return cmd_library(argc, argv);
}

/* Runs a command in a child process: this test process must never run OpenMP
 * code itself, since cmd_library forks its jobs (libgomp does not survive a fork
 * after it started threads). Returns the exit code. */
static int run_forked(int (*cmd)(int, char **), int argc, char **argv)
{
    fflush(stdout);
    pid_t pid = fork();
    cr_assert_geq(pid, 0);
    if (pid == 0)
        _exit(cmd(argc, argv));
    int status = 0;
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Inode and mtime of LIB/name/manifest.json (0 if missing): changes when the package is rewritten. */
static long long identity(const char *name)
{
    char p[600];
    struct stat st;
    snprintf(p, sizeof p, "%s/%s/manifest.json", g_lib, name);
    if (stat(p, &st) != 0)
        return 0;
    return (long long)st.st_ino * 1000003 + st.st_mtim.tv_nsec + st.st_mtim.tv_sec;
}

/* LIB/name/manifest.json parsed (read as JSON: no codec code, which may use OpenMP); cJSON_Delete it. */
static cJSON *manifest_of(const char *name)
{
    char p[600], *text = NULL;
    snprintf(p, sizeof p, "%s/%s/manifest.json", g_lib, name);
    cr_assert_eq(btf_fs_read(p, 1 << 22, &text, NULL, NULL), BTF_OK, "%s", p);
    cJSON *j = cJSON_Parse(text);
    free(text);
    cr_assert_not_null(j);
    return j;
}

/* Chunks listed by the package's manifest, whose name must be the package's. */
static int chunks_of(const char *name)
{
    cJSON *j = manifest_of(name);
    cr_expect_str_eq(cJSON_GetStringValue(cJSON_GetObjectItem(j, "name")), name);
    int n = cJSON_GetArraySize(cJSON_GetObjectItem(j, "chunks"));
    cJSON_Delete(j);
    return n;
}

/* Entries of LIB whose name contains part (".tmp-" leftovers). */
static int entries_with(const char *part)
{
    DIR *d = opendir(g_lib);
    cr_assert_not_null(d);
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        n += strstr(e->d_name, part) != NULL;
    closedir(d);
    return n;
}

/* The tests of what is rebuilt compress with --plain (the equal-noise steps, the
 * fastest): whether a package is up to date does not depend on how it is quantised,
 * and the default's steps, levels and budgets are the test after them. */
Test(library, builds_every_source_in_parallel_and_skips_what_is_up_to_date)
{
    const char *two[] = {"gen:knit:8", "tile=gen:tiles:8", "-j", "2", "--components", "4", "--plain", NULL};
    cr_assert_eq(build(two), 0);
    cr_expect_eq(chunks_of("gen-knit-8"), 4);
    cr_expect_eq(chunks_of("tile"), 4);
    long long a = identity("gen-knit-8"), b = identity("tile");
    cr_assert(a && b);
    cr_expect_eq(entries_with(".tmp-"), 0);
    /* the same sources and settings: nothing is rewritten */
    cr_assert_eq(build(two), 0);
    cr_expect_eq(identity("gen-knit-8"), a, "an up-to-date package was rebuilt");
    cr_expect_eq(identity("tile"), b);
    /* other settings: rebuilt */
    const char *more[] = {"gen:knit:8", "tile=gen:tiles:8", "-j", "2", "--components", "3", "--plain", NULL};
    cr_assert_eq(build(more), 0);
    cr_expect_neq(identity("gen-knit-8"), a, "new settings did not rebuild");
    cr_expect_eq(chunks_of("gen-knit-8"), 3);
    cr_expect_eq(chunks_of("tile"), 3);
    /* a package replaced behind the tool's back is not the one the stamp describes */
    long long t = identity("tile");
    char out[400];
    snprintf(out, sizeof out, "%s/tile", g_lib);
    char *cargv[] = {"compress", "gen:tiles:8", out, "--components", "3", "--plain", "--quiet", NULL};
    cr_assert_eq(run_forked(cmd_compress, 7, cargv), 0);
    long long t2 = identity("tile");
    cr_assert_neq(t2, t);
    cr_assert_eq(build(more), 0);
    cr_expect_neq(identity("tile"), t2, "a package the stamp does not describe was kept");
    /* --force rebuilds anyway */
    a = identity("gen-knit-8");
    const char *force[] = {"gen:knit:8", "--components", "3", "--plain", "--force", NULL};
    cr_assert_eq(build(force), 0);
    cr_expect_neq(identity("gen-knit-8"), a);
}

Test(library, a_changed_source_file_is_rebuilt)
{
    char src[400];
    snprintf(src, sizeof src, "%s/knit.btf", g_dir);
    char *gargv[] = {"gen", "knit", src, "--size", "8", "--format", "btf", NULL};
    cr_assert_eq(run_forked(cmd_gen, 7, gargv), 0);
    const char *args[] = {src, "--components", "3", "--plain", NULL};
    cr_assert_eq(build(args), 0);
    long long a = identity("knit");
    cr_assert(a, "knit.btf builds the package 'knit'");
    cr_assert_eq(build(args), 0);
    cr_expect_eq(identity("knit"), a);
    struct timespec ts[2] = {{time(NULL) + 100, 0}, {time(NULL) + 100, 0}};
    cr_assert_eq(utimensat(AT_FDCWD, src, ts, 0), 0);
    cr_assert_eq(build(args), 0);
    cr_expect_neq(identity("knit"), a, "a newer source did not rebuild");
}

Test(library, a_failed_job_leaves_nothing_and_the_others_go_on)
{
    const char *args[] = {"gen:nosuch:8", "gen:knit:8", "missing=/nonexistent/source.btf", "-j", "3",
                          "--components", "3", "--plain", NULL};
    cr_expect_eq(build(args), 1, "failures make exit status 1");
    cr_expect_eq(chunks_of("gen-knit-8"), 3);
    cr_expect_eq(identity("gen-nosuch-8"), 0);
    cr_expect_eq(identity("missing"), 0);
    cr_expect_eq(entries_with("nosuch"), 0, "something of the failed job is left");
    cr_expect_eq(entries_with("missing"), 0);
    cr_expect_eq(entries_with(".tmp-"), 0);
    char p[600];
    snprintf(p, sizeof p, "%s/.build/missing.json", g_lib);
    cr_expect_neq(access(p, F_OK), 0, "a failed job wrote a stamp");
}

Test(library, usage_errors_exit_2)
{
    char *none[] = {"library", NULL};
    cr_expect_eq(cmd_library(1, none), 2);
    char *nosub[] = {"library", "rebuild", NULL};
    cr_expect_eq(cmd_library(2, nosub), 2);
    char *noout[] = {"library", "build", "gen:knit:8", NULL};
    cr_expect_eq(cmd_library(3, noout), 2);
    char *nosrc[] = {"library", "build", "--out", g_lib, NULL};
    cr_expect_eq(cmd_library(4, nosrc), 2);
    const char *j0[] = {"gen:knit:8", "-j", "0", NULL};
    cr_expect_eq(build(j0), 2);
    const char *dup[] = {"a=gen:knit:8", "a=gen:tiles:8", NULL};
    cr_expect_eq(build(dup), 2);
    const char *bad[] = {".hidden=gen:knit:8", NULL};
    cr_expect_eq(build(bad), 2);
    const char *tmp[] = {"x.tmp-1=gen:knit:8", NULL};
    cr_expect_eq(build(tmp), 2);
    cr_expect_eq(identity("a"), 0, "nothing is built after a usage error");
    char *help[] = {"library", "build", "--help", NULL};
    cr_expect_eq(cmd_library(3, help), 0);
}

/* "version" of LIB/name/manifest.json. */
static int version_of(const char *name)
{
    cJSON *j = manifest_of(name);
    int v = (int)cJSON_GetNumberValue(cJSON_GetObjectItem(j, "version"));
    cJSON_Delete(j);
    return v;
}

/* Rate-distortion steps by default: version 4 with levels, 3 without; --plain gives
 * versions 2 and 1; levels, --plain and a budget are part of the settings. */
Test(library, levels_plain_and_budgets_are_part_of_the_settings)
{
    const char *two[] = {"gen:knit:8", "--components", "3", "--levels", "2", NULL};
    cr_assert_eq(build(two), 0);
    cr_expect_eq(version_of("gen-knit-8"), 4);
    cr_expect_eq(entries_with(".tmp-"), 0, "the v1 temporary is gone");
    long long a = identity("gen-knit-8");
    cr_assert_eq(build(two), 0);
    cr_expect_eq(identity("gen-knit-8"), a);
    const char *one[] = {"gen:knit:8", "--components", "3", NULL};
    cr_assert_eq(build(one), 0);
    cr_expect_eq(version_of("gen-knit-8"), 3, "dropping --levels did not rebuild");
    const char *plain2[] = {"gen:knit:8", "--components", "3", "--levels", "2", "--plain", NULL};
    cr_assert_eq(build(plain2), 0);
    cr_expect_eq(version_of("gen-knit-8"), 2);
    const char *plain[] = {"gen:knit:8", "--components", "3", "--plain", NULL};
    cr_assert_eq(build(plain), 0);
    cr_expect_eq(version_of("gen-knit-8"), 1);
    const char *budget[] = {"gen:knit:8", "--k", "3", "--max-error", "4", NULL};
    cr_assert_eq(build(budget), 0);
    cr_expect_eq(version_of("gen-knit-8"), 3);
    cJSON *j = manifest_of("gen-knit-8");
    cr_expect(cJSON_IsObject(cJSON_GetObjectItem(j, "budget")), "a budget's record in the manifest");
    cJSON_Delete(j);
    const char *both[] = {"gen:knit:8", "--max-error", "4", "--max-bytes", "100000", NULL};
    cr_expect_eq(build(both), 2);
}

/* --sampling reaches the jobs: an image directory over a direction list (names fit no
 * built-in set) builds, its manifest lists the directions, and a sampling change rebuilds. */
Test(library, sampling_reaches_directory_sources)
{
    char set[400], img[400], spec[420];
    snprintf(set, sizeof set, "%s/list.json", g_dir);
    snprintf(img, sizeof img, "%s/img", g_dir);
    fx_write_text(set, "{\"directions\": [{\"theta\": 0, \"phi\": 0}, {\"theta\": 33, \"phi\": 10},"
                       " {\"theta\": 35, \"phi\": 130}, {\"theta\": 37, \"phi\": 250}, {\"theta\": 70, \"phi\": 70},"
                       " {\"theta\": 72, \"phi\": 190}, {\"theta\": 74, \"phi\": 310}]}");
    char *gen[] = {"gen", "knit", img, "--size", "4", "--sampling", set, NULL};
    cr_assert_eq(run_forked(cmd_gen, 7, gen), 0);
    snprintf(spec, sizeof spec, "goni=%s", img);
    const char *none[] = {spec, "--components", "2", NULL};
    cr_expect_neq(build(none), 0, "names of no built-in set accepted without --sampling");
    const char *with[] = {spec, "--components", "2", "--sampling", set, NULL};
    cr_assert_eq(build(with), 0);
    cJSON *j = manifest_of("goni");
    cJSON *dirs = cJSON_GetObjectItem(cJSON_GetObjectItem(j, "lights"), "directions");
    cr_expect_eq(cJSON_GetArraySize(dirs), 7);
    cr_expect(cJSON_IsArray(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "views"), "triangles")));
    cJSON_Delete(j);
    long long a = identity("goni");
    cr_assert_eq(build(with), 0);
    cr_expect_eq(identity("goni"), a, "an up-to-date package was rebuilt");
}

/* Width and height of an 8-bit RGB PNG from its IHDR (read as bytes: no codec code,
 * which may use OpenMP); 0, or -1 when path is no such PNG. */
static int png_rgb_size(const char *path, int *w, int *h)
{
    char *b = NULL;
    size_t n = 0;
    if (btf_fs_read(path, 1 << 20, &b, &n, NULL) != BTF_OK)
        return -1;
    const unsigned char *u = (const unsigned char *)b;
    int ok = n > 26 && !memcmp(b, "\x89PNG\r\n\x1a\n", 8) && !memcmp(b + 12, "IHDR", 4) && u[24] == 8 && u[25] == 2;
    *w = ok ? (u[16] << 24 | u[17] << 16 | u[18] << 8 | u[19]) : 0;
    *h = ok ? (u[20] << 24 | u[21] << 16 | u[22] << 8 | u[23]) : 0;
    free(b);
    return ok ? 0 : -1;
}

/* LIB/name has an 8x8 RGB thumbnail.png that no chunk of its manifest lists. */
static void expect_thumbnail(const char *name)
{
    char p[600];
    int w = 0, h = 0;
    snprintf(p, sizeof p, "%s/%s/thumbnail.png", g_lib, name);
    cr_expect_eq(png_rgb_size(p, &w, &h), 0, "%s is missing or no 8-bit RGB PNG", p);
    cr_expect(w == 8 && h == 8, "%s: %dx%d", p, w, h);
    cJSON *j = manifest_of(name), *c;
    cJSON_ArrayForEach(c, cJSON_GetObjectItem(j, "chunks")) {
        cJSON *f;
        cJSON_ArrayForEach(f, cJSON_GetObjectItem(c, "files"))
            cr_expect_str_neq(cJSON_GetStringValue(f), "thumbnail.png", "a chunk lists the thumbnail");
    }
    cJSON_Delete(j);
}

/* The thumbnail is part of every package built; a rebuild replaces a package that
 * has one (the writer owns it); a stamp from before thumbnails rebuilds. */
Test(library, every_package_gets_a_thumbnail_that_rebuilds_keep)
{
    const char *one[] = {"gen:knit:8", "--components", "3", NULL};
    const char *force[] = {"gen:knit:8", "--components", "3", "--force", NULL};
    cr_assert_eq(build(one), 0);
    expect_thumbnail("gen-knit-8");
    long long a = identity("gen-knit-8");
    cr_assert_eq(build(force), 0, "a package with a thumbnail was not replaced");
    long long b = identity("gen-knit-8");
    cr_expect_neq(b, a);
    expect_thumbnail("gen-knit-8");
    char stamp[600], *text = NULL;
    snprintf(stamp, sizeof stamp, "%s/.build/gen-knit-8.json", g_lib);
    cr_assert_eq(btf_fs_read(stamp, 1 << 16, &text, NULL, NULL), BTF_OK);
    char *line = strstr(text, " \"thumbnail\": ");
    cr_assert_not_null(line, "the stamp does not record the thumbnail: %s", text);
    memmove(line, strchr(line, '\n') + 1, strlen(strchr(line, '\n') + 1) + 1); /* a stamp of an older btf */
    cr_assert_eq(btf_fs_write_atomic(stamp, text, strlen(text), NULL), BTF_OK);
    free(text);
    cr_assert_eq(build(one), 0);
    cr_expect_neq(identity("gen-knit-8"), b, "a package built before thumbnails is not rebuilt");
    expect_thumbnail("gen-knit-8");
    cr_expect_eq(entries_with(".tmp-"), 0);
}
