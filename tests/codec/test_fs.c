/* test_fs.c - room codec, suite "fs": the shared file helpers (codec/common/btf_fs.h),
 * base64 (codec/common/btf_base64.h), the manifest serializer
 * (codec/format/btf_manifest.h) and the writers' refusal to replace what they did not
 * write. */
#include <criterion/criterion.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "btf_base64.h"
#include "btf_fs.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_lod.h"
#include "btf_manifest.h"
#include "btf_package.h"
#include "fixtures.h"

static int exists(const char *dir, const char *name)
{
    char path[4300];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return lstat(path, &st) == 0;
}

/* Entries of dir whose name starts with prefix. */
static int count_prefix(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += !strncmp(e->d_name, prefix, strlen(prefix));
    if (d)
        closedir(d);
    return n;
}

static btf *knit(int size)
{
    return fx_material(BTF_GEN_KNIT, size, NULL, 0);
}

static btf_result compress(const btf *b, const char *out, btf_error *err)
{
    btf_pca_options po = {0};
    po.k = 1, po.components = 3;
    return btf_package_compress(b, &po, NULL, out, NULL, err);
}

Test(fs, base64_round_trips_every_length_and_rejects_bad_text)
{
    uint8_t in[64], back[64];
    for (int i = 0; i < 64; i++)
        in[i] = (uint8_t)(i * 37 + 11);
    for (size_t n = 0; n <= sizeof in; n++) {
        char *s = btf_base64_encode(in, n);
        cr_assert(s);
        cr_expect_eq(strlen(s), (n + 2) / 3 * 4);
        cr_expect(btf_base64_decode(s, back, n), "length %zu", n);
        cr_expect(!memcmp(in, back, n), "length %zu", n);
        if (n > 0)
            cr_expect(!btf_base64_decode(s, back, n - 1), "length %zu accepted as %zu", n, n - 1);
        free(s);
    }
    char *s = btf_base64_encode((const uint8_t *)"Man", 3); /* the textbook example */
    cr_expect_str_eq(s, "TWFu");
    free(s);
    cr_expect(!btf_base64_decode("TW=u", back, 3), "padding inside");
    cr_expect(!btf_base64_decode("TW*u", back, 3), "bad character");
}

Test(fs, read_is_bounded_and_write_is_atomic)
{
    char dir[64], path[128], *text = NULL;
    size_t n = 0;
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/a.txt", dir);
    cr_assert_eq(btf_fs_read(path, 10, &text, &n, &err), BTF_ERR_MISSING);
    cr_assert_eq(btf_fs_write_atomic(path, "hello world", 11, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(btf_fs_read(path, 10, &text, &n, &err), BTF_ERR_RANGE, "11 bytes read under a limit of 10");
    cr_expect(strstr(err.msg, "larger than"), "%s", err.msg);
    cr_expect_null(text);
    cr_assert_eq(btf_fs_read(path, 11, &text, &n, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(n, 11);
    cr_expect_str_eq(text, "hello world");
    free(text);
    cr_expect_eq(count_prefix(dir, "a.txt.tmp-"), 0, "a temporary file was left behind");
    /* a write into a missing directory fails and leaves the old file alone */
    snprintf(path, sizeof path, "%s/none/b.txt", dir);
    cr_expect_neq(btf_fs_write_atomic(path, "x", 1, &err), BTF_OK);
    cr_expect_eq(btf_fs_size(dir), -1, "a directory has no file size");
    fx_rmtree(dir);
}

Test(fs, rmtree_removes_nested_trees_without_following_links)
{
    char dir[64], sub[128], keep[64], link[160];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    cr_assert(fx_tmpdir(keep, sizeof keep));
    fx_put_text(keep, "precious", "x");
    snprintf(sub, sizeof sub, "%s/a/b/c", dir);
    char a[128];
    snprintf(a, sizeof a, "%s/a", dir), mkdir(a, 0755);
    snprintf(a, sizeof a, "%s/a/b", dir), mkdir(a, 0755);
    mkdir(sub, 0755);
    fx_put_text(sub, "f", "y");
    snprintf(link, sizeof link, "%s/a/to-keep", dir);
    cr_assert_eq(symlink(keep, link), 0);
    cr_expect_eq(btf_fs_rmtree(dir, &err), BTF_OK, "%s", err.msg);
    struct stat st;
    cr_expect_neq(lstat(dir, &st), 0, "the tree is still there");
    cr_expect(exists(keep, "precious"), "rmtree followed a link out of its tree");
    cr_expect_eq(btf_fs_rmtree(dir, &err), BTF_OK, "a missing tree is not an error");
    fx_rmtree(keep);
}

Test(fs, replace_dir_swaps_owned_trees_and_refuses_others)
{
    char dir[64], out[128], tmp[BTF_FS_PATH_MAX];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/out", dir);
    cr_assert_eq(btf_fs_temp_dir(out, tmp, sizeof tmp, NULL, NULL, &err), BTF_OK, "%s", err.msg);
    fx_put_text(tmp, "one", "1");
    cr_assert_eq(btf_fs_replace_dir(tmp, out, NULL, NULL, &err), BTF_OK, "%s", err.msg);
    cr_expect(exists(out, "one"));
    /* not owned: refused, nothing touched */
    cr_assert_eq(btf_fs_temp_dir(out, tmp, sizeof tmp, NULL, NULL, &err), BTF_OK, "%s", err.msg);
    fx_put_text(tmp, "two", "2");
    cr_expect_eq(btf_fs_replace_dir(tmp, out, NULL, NULL, &err), BTF_ERR_IO);
    cr_expect(strstr(err.msg, "not replaced"), "%s", err.msg);
    cr_expect(exists(out, "one") && !exists(out, "two"));
    btf_fs_rmtree(tmp, NULL);
    fx_rmtree(dir);
}

/* A folder that has a manifest.json but is not a package (a web app's, say): the
 * writer refuses it and deletes nothing in it, at once and after the work. */
Test(fs, compress_never_replaces_a_folder_that_is_not_its_package)
{
    char dir[64], out[128], sub[160];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/webapp", dir);
    mkdir(out, 0755);
    fx_put_text(out, "manifest.json", "{\"name\": \"my web app\", \"start_url\": \"/\"}");
    fx_put_text(out, "notes.txt", "keep me");
    snprintf(sub, sizeof sub, "%s/assets", out);
    mkdir(sub, 0755);
    fx_put_text(sub, "logo.svg", "<svg/>");
    btf *b = knit(8);
    cr_expect_eq(compress(b, out, &err), BTF_ERR_IO);
    cr_expect(strstr(err.msg, "not replaced"), "%s", err.msg);
    cr_expect(exists(out, "notes.txt") && exists(out, "manifest.json") && exists(sub, "logo.svg"));
    cr_expect_eq(count_prefix(dir, "webapp."), 0, "a temporary or .old directory was left behind");
    /* a real package of ours with a stray file in it is not ours either */
    snprintf(out, sizeof out, "%s/pkg", dir);
    cr_assert_eq(compress(b, out, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(compress(b, out, &err), BTF_OK, "replacing our own package: %s", err.msg);
    fx_put_text(out, "mine.txt", "a user's file");
    cr_expect_eq(compress(b, out, &err), BTF_ERR_IO);
    cr_expect(exists(out, "mine.txt"));
    btf_free(b);
    fx_rmtree(dir);
}

/* A write that fails half-way (file size limit, like a full disk) leaves the
 * previous package intact and no temporary directory. */
Test(fs, a_write_failing_half_way_leaves_the_old_package)
{
    char dir[64], out[128];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/pkg", dir);
    btf *small = knit(8), *big = knit(32);
    cr_assert_eq(compress(small, out, &err), BTF_OK, "%s", err.msg);
    pid_t pid = fork();
    if (pid == 0) {
        struct rlimit rl = {2000, 2000}; /* bytes per file: the big package's files are larger */
        signal(SIGXFSZ, SIG_IGN);
        setrlimit(RLIMIT_FSIZE, &rl);
        _exit(compress(big, out, &err) == BTF_OK ? 0 : 3);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    cr_expect(WIFEXITED(status) && WEXITSTATUS(status) == 3, "the limited write did not fail (status %d)", status);
    btf_package *p = NULL;
    cr_expect_eq(btf_package_read(out, 0, &p, &err), BTF_OK, "old package damaged: %s", err.msg);
    if (p)
        cr_expect_eq(p->width, 8, "the package is not the old one");
    btf_package_free(p);
    cr_expect_eq(count_prefix(dir, "pkg."), 0, "a temporary directory was left behind");
    btf_free(small), btf_free(big);
    fx_rmtree(dir);
}

/* A killed writer's temporary directory is removed by the next run. */
Test(fs, the_next_run_cleans_a_killed_writers_temporary)
{
    char dir[64], out[128], stale[160];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/pkg", dir);
    pid_t pid = fork();
    if (pid == 0)
        _exit(0);
    waitpid(pid, NULL, 0); /* a pid that is no longer running */
    snprintf(stale, sizeof stale, "%s.tmp-%ld", out, (long)pid);
    mkdir(stale, 0755);
    fx_put_text(stale, "tex-00.png", "half");
    btf *b = knit(8);
    cr_assert_eq(compress(b, out, &err), BTF_OK, "%s", err.msg);
    struct stat st;
    cr_expect_neq(lstat(stale, &st), 0, "the killed writer's %s is still there", stale);
    cr_expect_eq(count_prefix(dir, "pkg."), 0);
    btf_free(b);
    fx_rmtree(dir);
}

/* Parse -> print -> parse gives the same package, for both versions. */
static void round_trip(const char *pkg)
{
    char path[4300], *text = NULL;
    btf_error err = {0};
    snprintf(path, sizeof path, "%s/manifest.json", pkg);
    cr_assert_eq(btf_fs_read(path, BTF_MANIFEST_MAX_BYTES, &text, NULL, &err), BTF_OK, "%s", err.msg);
    btf_package a = {0}, b = {0};
    cr_assert_eq(btf_manifest_parse(text, path, &a, &err), BTF_OK, "%s", err.msg);
    char *again = btf_manifest_print(&a, &err);
    cr_assert(again);
    cr_assert_eq(btf_manifest_parse(again, "printed", &b, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(a.version, b.version);
    cr_expect_eq(a.n_chunks, b.n_chunks);
    cr_expect_eq(a.n_levels, b.n_levels);
    cr_expect_eq(a.lab_stride, b.lab_stride);
    for (int i = 0; i < a.n_chunks && i < b.n_chunks; i++) {
        cr_expect_eq(a.chunk[i].component, b.chunk[i].component);
        cr_expect_eq(a.chunk[i].level, b.chunk[i].level);
        cr_expect_eq(a.chunk[i].bytes, b.chunk[i].bytes);
        cr_expect_eq(a.chunk[i].n_files, b.chunk[i].n_files);
        cr_expect_eq(a.chunk[i].wt8_step, b.chunk[i].wt8_step);
        for (int k = 0; k < 2 * a.blocks->n_blocks; k++)
            cr_expect_eq(a.chunk[i].tex_range[k], b.chunk[i].tex_range[k], "chunk %d range %d", i, k);
    }
    free(text), free(again);
    btf_manifest_clear(&a), btf_manifest_clear(&b);
}

Test(fs, manifest_print_round_trips_both_versions)
{
    char dir[64], v1[128], v2[128];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(v1, sizeof v1, "%s/v1", dir);
    snprintf(v2, sizeof v2, "%s/v2", dir);
    btf *b = knit(16);
    cr_assert_eq(compress(b, v1, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_lod_build(v1, v2, NULL, NULL, &err), BTF_OK, "%s", err.msg);
    round_trip(v1);
    round_trip(v2);
    btf_free(b);
    fx_rmtree(dir);
}

/* Numbers of a manifest are range-checked before they are converted. */
Test(fs, manifest_numbers_out_of_range_are_refused)
{
    char dir[64], pkg[128], path[200], *text = NULL;
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    btf *b = knit(8);
    cr_assert_eq(compress(b, pkg, &err), BTF_OK, "%s", err.msg);
    snprintf(path, sizeof path, "%s/manifest.json", pkg);
    cr_assert_eq(btf_fs_read(path, BTF_MANIFEST_MAX_BYTES, &text, NULL, &err), BTF_OK);
    const char *bad[][2] = {{"\"bytes\":", "\"bytes\": 1e300, \"x\":"},
                            {"\"bytes\":", "\"bytes\": -5, \"x\":"},
                            {"\"rmse\":", "\"rmse\": 1e400, \"x\":"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char *at = strstr(text, bad[i][0]);
        cr_assert(at);
        size_t pre = (size_t)(at - text), n = strlen(text) + strlen(bad[i][1]) + 1;
        char *mod = malloc(n);
        snprintf(mod, n, "%.*s%s%s", (int)pre, text, bad[i][1], at + strlen(bad[i][0]));
        btf_package p = {0};
        cr_expect_eq(btf_manifest_parse(mod, "mod", &p, &err), BTF_ERR_FORMAT, "accepted: %s", bad[i][1]);
        btf_manifest_clear(&p);
        free(mod);
    }
    /* a block index far outside the view count */
    char *blocks = strstr(text, "\"blocks\"");
    cr_assert(blocks);
    char *digit = strpbrk(blocks, "0123456789");
    size_t n = strlen(text) + 16;
    char *mod = malloc(n);
    snprintf(mod, n, "%.*s1e10%s", (int)(digit - text), text, digit + 1);
    btf_package p = {0};
    cr_expect_eq(btf_manifest_parse(mod, "mod", &p, &err), BTF_ERR_FORMAT, "block index 1e10 accepted");
    btf_manifest_clear(&p);
    free(mod), free(text);
    btf_free(b);
    fx_rmtree(dir);
}

/* The .btf writer replaces a .btf file, never another file at that path. */
Test(fs, dfmf_writer_never_overwrites_a_file_that_is_not_a_btf)
{
    char dir[64], path[128];
    btf_error err = {0};
    cr_assert(fx_tmpdir(dir, sizeof dir));
    fx_put_text(dir, "thesis.btf", "my thesis, not a BTF");
    snprintf(path, sizeof path, "%s/thesis.btf", dir);
    btf *b = knit(4);
    cr_expect_eq(btf_save_dfmf(b, path, 2, &err), BTF_ERR_IO);
    cr_expect(strstr(err.msg, "not replaced"), "%s", err.msg);
    cr_expect_eq(btf_fs_size(path), 20, "the user's file changed");
    snprintf(path, sizeof path, "%s/a.btf", dir);
    cr_assert_eq(btf_save_dfmf(b, path, 2, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(btf_save_dfmf(b, path, 2, &err), BTF_OK, "replacing its own .btf: %s", err.msg);
    btf_free(b);
    fx_rmtree(dir);
}
