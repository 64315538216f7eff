/* test_publish.c - room tools, suite "publish": `btf library publish LIB OUT` (tools/cmd_library.c,
 * which runs `btfd --publish`, server/btfd_publish.c): the folder a static host serves
 * (OUT/materials.json, OUT/materials/NAME/thumbnail.png, OUT/materials/NAME/ETAG/FILE, the
 * client's scripts), byte for byte the library's files; a second run writes nothing; a
 * package rebuilt under a new etag leaves the old etag's files where an older list finds
 * them. Packages are built by `btf library build gen:KIND:8` in a child process (this test
 * process runs no OpenMP code: cmd_library forks). */
#define _XOPEN_SOURCE 700
#include <criterion/criterion.h>

#include <ftw.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include "btf_cli.h"
#include "btf_fs.h"
#include "fixtures.h"

#include <cjson/cJSON.h>

static char g_dir[256], g_lib[320], g_out[320], g_client[320];

static void setup(void)
{
    cr_assert(fx_tmpdir(g_dir, sizeof g_dir));
    snprintf(g_lib, sizeof g_lib, "%s/lib", g_dir);
    snprintf(g_out, sizeof g_out, "%s/out", g_dir);
    snprintf(g_client, sizeof g_client, "%s/client", g_dir);
    cr_assert_eq(mkdir(g_client, 0755), 0);
    fx_put_text(g_client, "btf-viewer.js", "export const viewer = 1;\n");
    fx_put_text(g_client, "btf-model-ABC.js", "export const model = 1;\n");
    fx_put_text(g_client, "btf-viewer.js.gz", "(its gzipped copy)"); /* published as it is */
    fx_put_text(g_client, "index.html.gz", "(a page's)");             /* not published */
    fx_put_text(g_client, "index.html", "<!doctype html>\n"); /* a demo page: not published */
}

static void teardown(void)
{
    fx_rmtree(g_dir);
}

TestSuite(publish, .init = setup, .fini = teardown, .timeout = 120);

/* cmd_library(argv) in a child process; its exit code. */
static int run(const char *const *args)
{
    char *argv[16];
    int argc = 0;
    for (; args[argc] && argc < 15; argc++)
        argv[argc] = (char *)args[argc];
    argv[argc] = NULL;
    fflush(stdout);
    pid_t pid = fork();
    cr_assert_geq(pid, 0);
    if (pid == 0)
        _exit(cmd_library(argc, argv));
    int status = 0;
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static int build(const char *src, const char *components, int force)
{
    const char *a[] = {"library", "build", src, "--out", g_lib, "--components", components, "--quiet",
                       force ? "--force" : NULL, NULL};
    return run(a);
}

static int publish(void)
{
    const char *a[] = {"library", "publish", g_lib, g_out, "--client", g_client, NULL};
    return run(a);
}

static char *read_text(const char *path)
{
    char *t = NULL;
    cr_assert_eq(btf_fs_read(path, 1 << 24, &t, NULL, NULL), BTF_OK, "%s", path);
    return t;
}

/* 1 when the two files hold the same bytes. */
static int same_file(const char *a, const char *b)
{
    char *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    int same = btf_fs_read(a, 1 << 26, &x, &nx, NULL) == BTF_OK && btf_fs_read(b, 1 << 26, &y, &ny, NULL) == BTF_OK &&
               nx == ny && memcmp(x, y, nx) == 0;
    free(x);
    free(y);
    return same;
}

/* The entry of material name in OUT/materials.json (a copy; cJSON_Delete it). */
static cJSON *entry_of(const char *name)
{
    char p[400];
    snprintf(p, sizeof p, "%s/materials.json", g_out);
    char *t = read_text(p);
    cJSON *list = cJSON_Parse(t), *m, *out = NULL;
    free(t);
    cr_assert_not_null(list);
    cr_expect(cJSON_IsNumber(cJSON_GetObjectItem(list, "generation")));
    cJSON_ArrayForEach(m, cJSON_GetObjectItem(list, "materials"))
        if (!strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(m, "name")), name))
            out = cJSON_Duplicate(m, 1);
    cJSON_Delete(list);
    return out;
}

/* Every file the package LIB/name's manifest names, and the manifest itself, is at
 * OUT/materials/name/etag/ with the library's bytes; returns how many files. */
static int expect_package(const char *name, const char *etag)
{
    char lp[600], op[600];
    snprintf(lp, sizeof lp, "%s/%s/manifest.json", g_lib, name);
    snprintf(op, sizeof op, "%s/materials/%s/%s/manifest.json", g_out, name, etag);
    cr_expect(same_file(lp, op), "%s", op);
    char *t = read_text(lp);
    cJSON *man = cJSON_Parse(t), *c, *f;
    free(t);
    int n = 1;
    cJSON_ArrayForEach(c, cJSON_GetObjectItem(man, "chunks")) cJSON_ArrayForEach(f, cJSON_GetObjectItem(c, "files"))
    {
        snprintf(lp, sizeof lp, "%s/%s/%s", g_lib, name, f->valuestring);
        snprintf(op, sizeof op, "%s/materials/%s/%s/%s", g_out, name, etag, f->valuestring);
        cr_expect(same_file(lp, op), "%s", op);
        n++;
    }
    cJSON_Delete(man);
    return n;
}

/* Every file below OUT: its path, inode and mtime, concatenated (one walk at a time). */
static char g_walk[1 << 16];
static int walk_one(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)ftw;
    if (flag == FTW_F) {
        size_t n = strlen(g_walk);
        snprintf(g_walk + n, sizeof g_walk - n, "%s %llu %lld.%09ld\n", path, (unsigned long long)st->st_ino,
                 (long long)st->st_mtim.tv_sec, st->st_mtim.tv_nsec);
    }
    return 0;
}

static char *tree(void)
{
    g_walk[0] = 0;
    cr_assert_eq(nftw(g_out, walk_one, 16, FTW_PHYS), 0);
    return strdup(g_walk);
}

Test(publish, writes_the_list_the_packages_thumbnails_and_scripts)
{
    cr_assert_eq(build("gen:knit:8", "4", 0), 0);
    cr_assert_eq(build("tile=gen:tiles:8", "3", 0), 0);
    cr_assert_eq(publish(), 0);
    const char *names[] = {"gen-knit-8", "tile"};
    for (int i = 0; i < 2; i++) {
        cJSON *e = entry_of(names[i]);
        cr_assert_not_null(e, "%s is listed", names[i]);
        const char *etag = cJSON_GetStringValue(cJSON_GetObjectItem(e, "etag"));
        char files[300], p[600], q[600];
        snprintf(files, sizeof files, "/materials/%s/%s/", names[i], etag);
        cr_expect_str_eq(cJSON_GetStringValue(cJSON_GetObjectItem(e, "files")), files, "btfd's paths");
        int n = expect_package(names[i], etag);
        cr_expect_eq(n, cJSON_GetObjectItem(e, "chunks")->valueint * 2 + 1, "%s: %d files", names[i], n);
        snprintf(p, sizeof p, "%s/%s/thumbnail.png", g_lib, names[i]);
        snprintf(q, sizeof q, "%s/materials/%s/thumbnail.png", g_out, names[i]);
        cr_expect(same_file(p, q), "%s", q);
        snprintf(q, sizeof q, "%s/materials/%s/%s/thumbnail.png", g_out, names[i], etag);
        cr_expect(same_file(p, q), "%s", q);
        cJSON_Delete(e);
    }
    char p[600], q[600];
    snprintf(p, sizeof p, "%s/btf-viewer.js", g_client);
    snprintf(q, sizeof q, "%s/btf-viewer.js", g_out);
    cr_expect(same_file(p, q), "the bundle");
    snprintf(q, sizeof q, "%s/btf-model-ABC.js", g_out);
    cr_expect_geq(btf_fs_size(q), 1, "its model chunk");
    snprintf(p, sizeof p, "%s/btf-viewer.js.gz", g_client);
    snprintf(q, sizeof q, "%s/btf-viewer.js.gz", g_out);
    cr_expect(same_file(p, q), "the bundle's gzipped copy");
    snprintf(q, sizeof q, "%s/index.html", g_out);
    cr_expect_eq(btf_fs_size(q), -1, "no demo page");
    snprintf(q, sizeof q, "%s/index.html.gz", g_out);
    cr_expect_eq(btf_fs_size(q), -1, "nor its gzipped copy");
    char *t = tree();
    cr_expect_null(strstr(t, ".tmp-"), "no temporary file left");
    free(t);
}

Test(publish, a_second_run_over_the_same_library_writes_nothing)
{
    cr_assert_eq(build("gen:knit:8", "4", 0), 0);
    cr_assert_eq(publish(), 0);
    char *before = tree();
    cr_assert_eq(publish(), 0);
    char *after = tree();
    cr_expect_str_eq(after, before, "the same files, not rewritten (inode and mtime)");
    free(before);
    free(after);
}

Test(publish, a_rebuilt_package_keeps_the_old_etag_paths)
{
    cr_assert_eq(build("gen:knit:8", "4", 0), 0);
    cr_assert_eq(publish(), 0);
    cJSON *e = entry_of("gen-knit-8");
    char old[32];
    snprintf(old, sizeof old, "%s", cJSON_GetStringValue(cJSON_GetObjectItem(e, "etag")));
    cJSON_Delete(e);
    char oldlist[400], *list0 = NULL;
    snprintf(oldlist, sizeof oldlist, "%s/materials.json", g_out);
    list0 = read_text(oldlist);
    /* what an older list names: its manifest and one chunk file, kept to compare */
    char p[600], keep[600];
    snprintf(p, sizeof p, "%s/materials/gen-knit-8/%s/manifest.json", g_out, old);
    char *man0 = read_text(p);
    snprintf(keep, sizeof keep, "%s/manifest0.json", g_dir);
    fx_write_text(keep, man0);

    cr_assert_eq(build("gen:knit:8", "2", 1), 0); /* new settings: a new manifest, a new etag */
    cr_assert_eq(publish(), 0);
    e = entry_of("gen-knit-8");
    const char *etag = cJSON_GetStringValue(cJSON_GetObjectItem(e, "etag"));
    cr_assert_str_neq(etag, old, "the rebuilt package has a new etag");
    expect_package("gen-knit-8", etag);
    cr_expect(same_file(p, keep), "the old etag's manifest is still there, unchanged");
    char *man = read_text(p);
    cJSON *m = cJSON_Parse(man), *c, *f;
    cJSON_ArrayForEach(c, cJSON_GetObjectItem(m, "chunks")) cJSON_ArrayForEach(f, cJSON_GetObjectItem(c, "files"))
    {
        char q[600];
        snprintf(q, sizeof q, "%s/materials/gen-knit-8/%s/%s", g_out, old, f->valuestring);
        cr_expect_geq(btf_fs_size(q), 1, "the old list's file %s is still there", q);
    }
    cJSON_Delete(m);
    cJSON_Delete(e);
    char *list1 = read_text(oldlist);
    cr_expect_str_neq(list1, list0, "the list names the new etag");
    free(list0);
    free(list1);
    free(man);
    free(man0);
}

Test(publish, usage_errors_and_a_missing_library)
{
    const char *one[] = {"library", "publish", g_lib, NULL};
    cr_expect_eq(run(one), 2, "OUT missing");
    const char *bad[] = {"library", "publish", g_lib, g_out, "--bogus", NULL};
    cr_expect_eq(run(bad), 2);
    const char *missing[] = {"library", "publish", "/nonexistent/lib", g_out, "--client", g_client, NULL};
    cr_expect_eq(run(missing), 1, "a library that is not there");
}
