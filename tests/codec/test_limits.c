/* test_limits.c - room codec, suite "limits": every limit of doc/package-format.md section 8
 * (and the file-size limits of the other readers) tried at the limit, where it
 * must pass, and at the limit plus one, where it must be refused with an error. */
#include <criterion/criterion.h>
#include <cjson/cJSON.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_fs.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_lod.h"
#include "btf_manifest.h"
#include "btf_package.h"
#include "btf_thesis.h"
#include "fixtures.h"

/* A manifest of a generated package (v1, or v2 with 2 levels), parsed with cJSON; lives for one test. */
static cJSON *base_manifest(int version)
{
    char dir[64], v1[128], v2[128], path[200], *text = NULL;
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(v1, sizeof v1, "%s/v1", dir);
    snprintf(v2, sizeof v2, "%s/v2", dir);
    static const btf_ring r[2] = {{0.0f, 1, 0.0f}, {45.0f, 4, 0.0f}};
    btf_error err = {0};
    btf *b = fx_material(BTF_GEN_KNIT, 16, r, 2);
    btf_pca_options po = {0};
    po.k = 2, po.components = 2;
    cr_assert_eq(btf_package_compress(b, &po, NULL, v1, NULL, &err), BTF_OK, "%s", err.msg);
    btf_lod_options lo = {0};
    lo.levels = 2;
    cr_assert_eq(btf_lod_build(v1, v2, &lo, NULL, &err), BTF_OK, "%s", err.msg);
    snprintf(path, sizeof path, "%s/manifest.json", version == 2 ? v2 : v1);
    cr_assert_eq(btf_fs_read(path, 1 << 20, &text, NULL, &err), BTF_OK);
    cJSON *m = cJSON_Parse(text);
    free(text);
    btf_free(b);
    fx_rmtree(dir);
    cr_assert(m);
    return m;
}

/* btf_manifest_parse of m's text. */
static btf_result parse(const cJSON *m, btf_error *err)
{
    char *text = cJSON_PrintUnformatted(m);
    btf_package p = {0};
    btf_result r = btf_manifest_parse(text, "limits", &p, err);
    btf_manifest_clear(&p);
    free(text);
    return r;
}

/* Sets key of obj to x; the manifest must parse when ok, else be refused. */
static void try_number(cJSON *m, cJSON *obj, const char *key, double x, int ok)
{
    cJSON_ReplaceItemInObjectCaseSensitive(obj, key, cJSON_CreateNumber(x));
    btf_error err = {0};
    btf_result r = parse(m, &err);
    if (ok)
        cr_expect_eq(r, BTF_OK, "%s = %.17g refused: %s", key, x, err.msg);
    else
        cr_expect_neq(r, BTF_OK, "%s = %.17g accepted", key, x);
}

static cJSON *chunk0(cJSON *m)
{
    return cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(m, "chunks"), 0);
}

Test(limits, manifest_sizes_and_counts)
{
    cJSON *m = base_manifest(1);
    try_number(m, m, "width", 16, 1);
    try_number(m, m, "width", BTF_MAX_SIDE + 1, 0); /* also no longer the atlas tile width */
    try_number(m, m, "width", 16, 1);
    try_number(m, m, "components", BTF_PACKAGE_MAX_CHUNKS, 1);
    try_number(m, m, "components", BTF_PACKAGE_MAX_CHUNKS + 1, 0);
    try_number(m, m, "components", 2, 1);
    try_number(m, m, "bits", 9, 0);
    try_number(m, m, "bits", 8, 1);
    cJSON *c = chunk0(m);
    try_number(m, c, "bytes", (double)BTF_MANIFEST_MAX_CHUNK_BYTES, 1);
    try_number(m, c, "bytes", (double)BTF_MANIFEST_MAX_CHUNK_BYTES + 1, 0);
    try_number(m, c, "bytes", -1, 0);
    try_number(m, c, "bytes", 100.5, 0);
    try_number(m, c, "bytes", 100, 1);
    try_number(m, c, "rmse", 1e9, 1);
    try_number(m, c, "rmse", 1.000001e9, 0);
    try_number(m, c, "rmse", 1, 1);
    try_number(m, c, "component", 1, 1);
    try_number(m, c, "component", 2, 0); /* components - 1 is the last */
    try_number(m, c, "component", 0, 1);
    cJSON *at = cJSON_GetObjectItemCaseSensitive(m, "atlas");
    int cols = cJSON_GetObjectItemCaseSensitive(at, "cols")->valueint;
    try_number(m, at, "cols", 4097, 0);
    try_number(m, at, "cols", cols, 1);
    cJSON_Delete(m);
}

Test(limits, manifest_blocks_files_and_rings)
{
    cJSON *m = base_manifest(1);
    cJSON *blocks = cJSON_GetObjectItemCaseSensitive(m, "blocks"), *b0 = cJSON_GetArrayItem(blocks, 0);
    int v0 = cJSON_GetArrayItem(b0, 0)->valueint;
    cJSON_ReplaceItemInArray(b0, 0, cJSON_CreateNumber(5)); /* V = 5 views: 0..4 */
    btf_error err = {0};
    cr_expect_neq(parse(m, &err), BTF_OK, "block entry V accepted");
    cJSON_ReplaceItemInArray(b0, 0, cJSON_CreateNumber(v0));
    cr_expect_eq(parse(m, &err), BTF_OK, "%s", err.msg);
    /* file names: 63 characters pass, 64 do not; 8 files pass, 9 do not */
    cJSON *files = cJSON_GetObjectItemCaseSensitive(chunk0(m), "files");
    char name[80];
    memset(name, 'a', 63), name[63] = 0;
    cJSON_AddItemToArray(files, cJSON_CreateString(name));
    cr_expect_eq(parse(m, &err), BTF_OK, "a 63-character name refused: %s", err.msg);
    cJSON_DeleteItemFromArray(files, cJSON_GetArraySize(files) - 1);
    memset(name, 'a', 64), name[64] = 0;
    cJSON_AddItemToArray(files, cJSON_CreateString(name));
    cr_expect_neq(parse(m, &err), BTF_OK, "a 64-character name accepted");
    cJSON_DeleteItemFromArray(files, cJSON_GetArraySize(files) - 1);
    while (cJSON_GetArraySize(files) < BTF_PACKAGE_MAX_FILES)
        cJSON_AddItemToArray(files, cJSON_CreateString("extra.png"));
    cr_expect_eq(parse(m, &err), BTF_OK, "%d files refused: %s", BTF_PACKAGE_MAX_FILES, err.msg);
    cJSON_AddItemToArray(files, cJSON_CreateString("extra.png"));
    cr_expect_neq(parse(m, &err), BTF_OK, "%d files accepted", BTF_PACKAGE_MAX_FILES + 1);
    /* a ring count above the direction limit */
    cJSON *ring = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(m, "lights"), "rings"), 1);
    try_number(m, ring, "count", BTF_MAX_DIRS + 1, 0);
    cJSON_Delete(m);
}

Test(limits, manifest_levels_and_chunk_count)
{
    cJSON *m = base_manifest(2);
    btf_error err = {0};
    cr_assert_eq(parse(m, &err), BTF_OK, "%s", err.msg);
    cJSON *c = chunk0(m);
    try_number(m, c, "level", 1, 1);
    try_number(m, c, "level", 2, 0); /* levels - 1 is the coarsest */
    try_number(m, c, "level", 0, 1);
    try_number(m, m, "levels", 16, 0);
    try_number(m, m, "levels", 2, 1);
    cJSON_Delete(m);
    /* 1024 chunks pass, 1025 do not */
    m = base_manifest(1);
    cJSON *chunks = cJSON_GetObjectItemCaseSensitive(m, "chunks");
    cJSON_ReplaceItemInObjectCaseSensitive(m, "components", cJSON_CreateNumber(BTF_PACKAGE_MAX_CHUNKS));
    for (int i = cJSON_GetArraySize(chunks); i < BTF_PACKAGE_MAX_CHUNKS + 1; i++) {
        cJSON *e = cJSON_Duplicate(cJSON_GetArrayItem(chunks, 0), 1);
        cJSON_ReplaceItemInObjectCaseSensitive(e, "id", cJSON_CreateNumber(i));
        cJSON_AddItemToArray(chunks, e);
    }
    cr_expect_neq(parse(m, &err), BTF_OK, "%d chunks accepted", BTF_PACKAGE_MAX_CHUNKS + 1);
    cJSON_DeleteItemFromArray(chunks, BTF_PACKAGE_MAX_CHUNKS);
    cr_expect_eq(parse(m, &err), BTF_OK, "%d chunks refused: %s", BTF_PACKAGE_MAX_CHUNKS, err.msg);
    cJSON_Delete(m);
}

/* A sparse file of n bytes at dir/name. */
static void sparse(const char *dir, const char *name, off_t n, char *path, size_t len)
{
    snprintf(path, len, "%s/%s", dir, name);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    cr_assert(fd >= 0);
    cr_assert_eq(ftruncate(fd, n), 0);
    close(fd);
}

/* Whole-file limits: refused from the file size, before anything is read. */
Test(limits, file_sizes_are_refused_before_reading)
{
    char dir[64], path[200];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf_error err = {0};
    char *text = NULL;
    sparse(dir, "manifest.json", (off_t)BTF_MANIFEST_MAX_BYTES + 1, path, sizeof path);
    btf_package *p = NULL;
    cr_expect_eq(btf_package_read(dir, 0, &p, &err), BTF_ERR_RANGE, "%s", err.msg);
    cr_expect(strstr(err.msg, "larger than"), "%s", err.msg);
    sparse(dir, "set.json", (1 << 20) + 1, path, sizeof path);
    btf_dirset d;
    cr_expect_eq(btf_dirset_load_json(path, &d, &err), BTF_ERR_RANGE, "%s", err.msg);
    sparse(dir, "meta.json", (1 << 20) + 1, path, sizeof path);
    btf_thesis_pkg tp;
    cr_expect_eq(btf_thesis_read(dir, &tp, &err), BTF_ERR_RANGE, "%s", err.msg);
    cr_expect_eq(btf_fs_read(path, 1 << 20, &text, NULL, &err), BTF_ERR_RANGE);
    cr_expect_null(text);
    sparse(dir, "ok.json", 1 << 20, path, sizeof path);
    cr_expect_eq(btf_fs_read(path, 1 << 20, &text, NULL, &err), BTF_OK, "the limit itself refused: %s", err.msg);
    free(text);
    fx_rmtree(dir);
}

/* The weights file must have exactly 2 x V x L x 3 bytes. */
Test(limits, weight_file_size_is_exact)
{
    char dir[64], pkg[128], path[200];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(pkg, sizeof pkg, "%s/p", dir);
    static const btf_ring r[2] = {{0.0f, 1, 0.0f}, {45.0f, 4, 0.0f}};
    btf_error err = {0};
    btf *b = fx_material(BTF_GEN_KNIT, 8, r, 2);
    btf_pca_options po = {0};
    po.k = 1, po.components = 1;
    cr_assert_eq(btf_package_compress(b, &po, NULL, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    snprintf(path, sizeof path, "%s/wt-00.bin", pkg);
    long long n = btf_fs_size(path);
    cr_assert_eq(n, 2 * 5 * 5 * 3);
    cr_assert_eq(truncate(path, n + 1), 0);
    btf_package *p = NULL;
    cr_expect_eq(btf_package_read(pkg, 0, &p, &err), BTF_ERR_FORMAT, "one byte too many accepted");
    cr_assert_eq(truncate(path, n), 0);
    cr_expect_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    btf_package_free(p);
    btf_free(b);
    fx_rmtree(dir);
}
