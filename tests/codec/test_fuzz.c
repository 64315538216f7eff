/* test_fuzz.c - room codec, suite "fuzz": every codec reader's saved fuzz corpus replays without a
 * contract breach and without a line on stderr (build/fuzz/replay_NAME, fuzz/build.mk), and each
 * regression input of a past finding is refused with a clear error before it can allocate. */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "btf_image.h"
#include "btf_io.h"
#include "btf_manifest.h"
#include "btf_thesis.h"
#include "fixtures.h"
#include "btf_input.h"

/* Caps this test process's address space at 1 GiB, so a reader that trusts a header
 * fails the test; not under AddressSanitizer, whose shadow memory needs more. */
static void cap_memory(void)
{
#ifndef __SANITIZE_ADDRESS__
    struct rlimit rl = {(rlim_t)1 << 30, (rlim_t)1 << 30};
    cr_assert_eq(setrlimit(RLIMIT_AS, &rl), 0);
#endif
}

/* Path under the repository (BTF_ROOT, exported by the Makefile, else the cwd). */
static void repo_path(char *buf, size_t n, const char *rel)
{
    const char *root = getenv("BTF_ROOT");
    snprintf(buf, n, "%s/%s", root ? root : ".", rel);
}

/* Runs BTF_BUILD/fuzz/replay_NAME over fuzz/corpus/NAME; returns the input count, -1 on failure. */
static int replay(const char *name)
{
    const char *build = getenv("BTF_BUILD");
    char bin[1024], corpus[1024], cmd[2200], out[4096] = {0};
    snprintf(bin, sizeof bin, "%s/fuzz/replay_%s", build ? build : "build", name);
    repo_path(corpus, sizeof corpus, "fuzz/corpus/");
    strncat(corpus, name, sizeof corpus - strlen(corpus) - 1);
    if (access(bin, X_OK) != 0)
        cr_skip_test("%s not built", bin);
    snprintf(cmd, sizeof cmd, "'%s' '%s' 2>&1", bin, corpus);
    FILE *p = popen(cmd, "r");
    cr_assert(p);
    size_t len = fread(out, 1, sizeof out - 1, p);
    out[len] = 0;
    int st = pclose(p);
    const char *at = strstr(out, "replay: ");
    cr_expect(WIFEXITED(st) && WEXITSTATUS(st) == 0, "%s failed:\n%s", name, out);
    cr_expect(at == out && len > 0 && strchr(out, '\n') == out + len - 1,
              "%s printed more than its count (a decoder's message on stderr?):\n%s", name, out);
    return at && WIFEXITED(st) && WEXITSTATUS(st) == 0 ? atoi(at + 8) : -1;
}

/* Files in fuzz/corpus/NAME. */
static int corpus_size(const char *name)
{
    char dir[1024], rel[256];
    snprintf(rel, sizeof rel, "fuzz/corpus/%s", name);
    repo_path(dir, sizeof dir, rel);
    return fx_count_files(dir);
}

Test(fuzz, every_corpus_replays)
{
    static const char *targets[] = {"dirset",     "dfmf",         "manifest",  "package", "package_mem", "thesis",
                                    "thesis_mem", "ubo2003_name", "roundtrip", "gltf",    "hdr"};
    for (size_t i = 0; i < sizeof targets / sizeof targets[0]; i++) {
        int want = corpus_size(targets[i]);
        cr_expect_gt(want, 0, "fuzz/corpus/%s is empty", targets[i]);
        cr_expect_eq(replay(targets[i]), want, "%s: not every input replayed", targets[i]);
    }
}

/* The 432-byte DFMF file that claims 16384 x 16384 texels with 0 components. */
Test(fuzz, dfmf_zero_components_is_refused_without_allocating)
{
    char path[1024];
    repo_path(path, sizeof path, "fuzz/corpus/dfmf/regress-k0-16384");
    cap_memory(); /* the old reader asked for several GiB */
    btf *b = NULL;
    btf_error err = {0};
    cr_expect_eq(btf_load_dfmf(path, NULL, &b, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_expect(strstr(err.msg, "0 components"), "%s", err.msg);
    repo_path(path, sizeof path, "fuzz/corpus/dfmf/regress-k0-4096");
    cr_expect_neq(btf_load_dfmf(path, NULL, &b, &err), BTF_OK, "a 4096x4096 claim with no data was accepted");
    cr_expect_null(b);
}

/* A 200-byte PNG whose header claims 32768 x 32768 RGBA (4 GiB decoded). */
Test(fuzz, png_header_larger_than_the_file_can_hold_is_refused)
{
    char in[1024], dir[64], path[128];
    repo_path(in, sizeof in, "fuzz/corpus/package/regress-png-header-32768");
    cr_assert(fx_tmpdir(dir, sizeof dir));
    FILE *f = fopen(in, "rb");
    cr_assert(f);
    unsigned char buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    snprintf(path, sizeof path, "%s/big.png", dir);
    fx_write(path, buf + 1, n - 1); /* the first byte picks the package file */
    cap_memory();
    int w, h, ch;
    uint8_t *px = NULL;
    btf_error err = {0};
    cr_expect_eq(btf_image_read_u8(path, &w, &h, &ch, &px, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_expect(strstr(err.msg, "cannot hold") || strstr(err.msg, "holds 4096 of"), "%s", err.msg);
    cr_expect_null(px);
    fx_rmtree(dir);
}

/* A manifest with "bytes": 1e300 or a block index of 1e10 never reaches a conversion. */
Test(fuzz, manifest_regressions_are_refused)
{
    static const char *names[] = {"regress-bytes-1e300", "regress-bytes-negative", "regress-block-index-1e10",
                                  "regress-bytes-sum-overflow"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char rel[256], path[1024], *text = NULL;
        snprintf(rel, sizeof rel, "fuzz/corpus/manifest/%s", names[i]);
        repo_path(path, sizeof path, rel);
        btf_error err = {0};
        cr_assert_eq(btf_fs_read(path, 1 << 20, &text, NULL, &err), BTF_OK, "%s", err.msg);
        btf_package p = {0};
        cr_expect_eq(btf_manifest_parse(text, names[i], &p, &err), BTF_ERR_FORMAT, "%s accepted", names[i]);
        btf_manifest_clear(&p);
        free(text);
    }
}

/* A thesis meta.json announcing 256 components of 8192^2 is refused before the
 * header's sizes are allocated, with the true reason. */
Test(fuzz, thesis_meta_announcing_gigabytes_is_refused_before_allocating)
{
    char in[1024], dir[64];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    repo_path(in, sizeof in, "fuzz/corpus/thesis/regress-meta-huge");
    char *text = NULL;
    size_t n = 0;
    btf_error err = {0};
    cr_assert_eq(btf_fs_read(in, 1 << 20, &text, &n, &err), BTF_OK, "%s", err.msg);
    char path[128];
    snprintf(path, sizeof path, "%s/meta.json", dir);
    cr_assert_eq(btf_fs_write_atomic(path, text + 1, n - 1, &err), BTF_OK);
    free(text);
    cap_memory();
    btf_thesis_pkg p;
    cr_expect_eq(btf_thesis_read(dir, &p, &err), BTF_ERR_MISSING, "%s", err.msg);
    cr_expect(strstr(err.msg, "R.png") || strstr(err.msg, "0.png"), "%s", err.msg);
    fx_rmtree(dir);
}
