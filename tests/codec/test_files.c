/* test_files.c - room codec, suite "files": the readers' btf_files (btf.h). A package
 * (versions 1 at 8 and 16 bits, 2, 4 with WebP textures) and a thesis package read
 * from memory (btf_fs_mem_files) give what the disk gives, bit for bit; a truncated
 * or missing file gives the same error, code and message. */
#include <math.h>

#include "btf_decode.h"
#include "btf_thesis.h"
#include "fixtures.h"

/* A directory's files in memory: up to 40, each read with fx_read (malloc'd). One
 * per test, on its stack; mem_free releases the bytes. */
typedef struct mem_dir {
    btf_fs_mem_file file[40];
    char name[40][BTF_PACKAGE_NAME_MAX];
    btf_fs_mem mem;
    btf_files files;
} mem_dir;

/* Adds dir/name to m. */
static void mem_add(mem_dir *m, const char *dir, const char *name)
{
    char path[600];
    size_t n = 0;
    cr_assert_lt(m->mem.n, 40);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    snprintf(m->name[m->mem.n], BTF_PACKAGE_NAME_MAX, "%s", name);
    m->file[m->mem.n].data = fx_read(path, &n);
    m->file[m->mem.n].name = m->name[m->mem.n];
    m->file[m->mem.n++].size = n;
    m->mem.file = m->file;
    m->files = btf_fs_mem_files(&m->mem);
}

/* The package at dir in memory: manifest.json and every file its chunks list. */
static void mem_package(mem_dir *m, const char *dir)
{
    memset(m, 0, sizeof *m);
    btf_package *p = fx_package(dir, NULL, 0);
    mem_add(m, dir, "manifest.json");
    for (int i = 0; i < p->n_chunks; i++)
        for (int f = 0; f < p->chunk[i].n_files; f++)
            mem_add(m, dir, p->chunk[i].files[f]);
    btf_package_free(p);
}

static void mem_free(mem_dir *m)
{
    for (int i = 0; i < m->mem.n; i++)
        free((void *)m->file[i].data);
}

/* The entry of m named name. */
static btf_fs_mem_file *mem_file(mem_dir *m, const char *name)
{
    for (int i = 0; i < m->mem.n; i++)
        if (!strcmp(m->file[i].name, name))
            return &m->file[i];
    cr_assert_fail("%s is not in the package", name);
    return NULL;
}

/* a and b hold the same chunks, bit for bit, and decode to the same bits. */
static void expect_same_package(const btf_package *a, const btf_package *b)
{
    cr_assert_eq(a->n_loaded, b->n_loaded);
    cr_assert_eq(a->n_chunks, b->n_chunks);
    for (int i = 0; i < a->n_loaded; i++) {
        int l = a->chunk[i].level;
        size_t nt = (size_t)a->blocks->n_blocks * (a->width >> l) * (a->height >> l);
        size_t nw = (size_t)a->views.n_dirs * a->lights.n_dirs * 3;
        cr_expect_eq(memcmp(a->tex[i], b->tex[i], nt * sizeof(float)), 0, "chunk %d texels differ", i);
        cr_expect_eq(memcmp(a->wt[i], b->wt[i], nw * sizeof(float)), 0, "chunk %d weights differ", i);
    }
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_BILINEAR;
    for (int k = 0; k < 16; k++) {
        float l[3], v[3], ra[3], rb[3];
        fx_dirf(7.0 * k, 23.0 * k, l);
        fx_dirf(50.0 - 3.0 * k, 180.0 - 17.0 * k, v);
        btf_decode(a, 0.06f * k, 1.0f - 0.05f * k, l, v, &o, ra);
        btf_decode(b, 0.06f * k, 1.0f - 0.05f * k, l, v, &o, rb);
        cr_expect(isfinite(ra[0]) && isfinite(ra[1]) && isfinite(ra[2]));
        cr_expect_eq(memcmp(ra, rb, sizeof ra), 0, "decode %d: %g %g %g vs %g %g %g", k, ra[0], ra[1], ra[2], rb[0],
                     rb[1], rb[2]);
    }
}

/* Reads dir from the disk and from m (under the same name, so messages match):
 * both succeed with the same package, or fail with the same code and message;
 * want_ok 1: they succeed, 0: they fail, -1: either. */
static void expect_same_read(const char *dir, mem_dir *m, int n, int want_ok)
{
    btf_package *a = NULL, *b = NULL;
    btf_error ea = {{0}}, eb = {{0}};
    btf_result ra = btf_package_read_with(dir, n, NULL, &a, &ea), rb = btf_package_read_with(dir, n, &m->files, &b, &eb);
    cr_expect_eq(ra, rb, "disk %s (%s), memory %s (%s)", btf_result_string(ra), ea.msg, btf_result_string(rb), eb.msg);
    if (want_ok >= 0)
        cr_expect_eq(ra == BTF_OK, want_ok, "%s", ea.msg);
    if (ra == BTF_OK && rb == BTF_OK)
        expect_same_package(a, b);
    else
        cr_expect_str_eq(ea.msg, eb.msg);
    btf_package_free(a);
    btf_package_free(b);
}

/* Version 4 of the package at v1 into dir/v4 (lossless WebP textures where smaller). */
static void make_v4(const char *root, const char *v1)
{
    char v4[600];
    snprintf(v4, sizeof v4, "%s/v4", root);
    btf_lod_options lo = {0};
    lo.levels = 2, lo.residual = 1;
    btf_error err = {{0}};
    cr_assert_eq(btf_lod_build(v1, v4, &lo, NULL, &err), BTF_OK, "%s", err.msg);
}

Test(files, package_from_memory_decodes_as_from_disk)
{
    btf_dirset d = fx_dirs11();
    fx_levels_spec s = {BTF_GEN_KNIT, 16, BTF_U8, &d, 3, 4, 8, 2};
    char root[256], dir[600], v16[600];
    fx_levels(root, sizeof root, &s, NULL);
    snprintf(dir, sizeof dir, "%s/v1", root);
    make_v4(root, dir);
    snprintf(v16, sizeof v16, "%s/v16", root); /* version 1 at 16 bits: RGB textures */
    btf *src = fx_gen(BTF_GEN_STONE, 16, &d, BTF_U8);
    btf_pca_options po = {0};
    po.k = 2, po.components = 3;
    btf_package_options ko = {0};
    ko.bits = 16;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_compress(src, &po, &ko, v16, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(src);
    const char *subs[4] = {"v1", "v2", "v4", "v16"};
    int webp = 0;
    for (int i = 0; i < 4; i++) {
        mem_dir m;
        snprintf(dir, sizeof dir, "%s/%s", root, subs[i]);
        mem_package(&m, dir);
        for (int f = 0; f < m.mem.n; f++)
            webp += strstr(m.file[f].name, ".webp") != NULL;
        expect_same_read(dir, &m, 0, 1);
        expect_same_read(dir, &m, 1, 1);
        btf_package *a = fx_package(dir, NULL, 0), *b = NULL; /* memory only: no name looked up on disk */
        cr_expect_eq(btf_package_read_with("nowhere", -1, &m.files, &b, &err), BTF_OK, "%s", err.msg);
        if (b)
            expect_same_package(a, b);
        btf_package_free(a);
        btf_package_free(b);
        mem_free(&m);
    }
    cr_expect_gt(webp, 0, "no WebP texture in the version-4 package");
    fx_rmtree(root);
}

/* Every file of each package cut to half its size (in memory and on disk), then
 * removed: the same refusal from both, or (n < 0, a missing later chunk) the same
 * partial package. */
Test(files, truncated_or_missing_file_gives_the_same_error)
{
    btf_dirset d = fx_dirs7();
    fx_levels_spec s = {BTF_GEN_TILES, 16, BTF_U8, &d, 2, 3, 8, 2};
    char root[256], dir[600];
    fx_levels(root, sizeof root, &s, NULL);
    snprintf(dir, sizeof dir, "%s/v1", root);
    make_v4(root, dir);
    const char *subs[3] = {"v1", "v2", "v4"};
    for (int i = 0; i < 3; i++) {
        mem_dir m;
        snprintf(dir, sizeof dir, "%s/%s", root, subs[i]);
        mem_package(&m, dir);
        for (int f = 0; f < m.mem.n; f++) {
            btf_fs_mem_file *e = &m.file[f], keep = *e;
            e->size = keep.size / 2;
            fx_put(dir, e->name, keep.data, e->size);
            expect_same_read(dir, &m, 0, 0);
            e->name = "gone";
            char path[700];
            snprintf(path, sizeof path, "%s/%s", dir, keep.name);
            cr_assert_eq(unlink(path), 0);
            expect_same_read(dir, &m, 0, 0);
            expect_same_read(dir, &m, -1, -1); /* a later chunk's file: the chunks before it */
            *e = keep;
            fx_put(dir, e->name, e->data, e->size);
        }
        expect_same_read(dir, &m, 0, 1);
        mem_free(&m);
    }
    fx_rmtree(root);
}

/* A small thesis package (C 3, N 7, k 3, S 8) of random values on disk. */
static void make_thesis(const char *dir)
{
    btf_thesis_pkg p;
    uint32_t seed = 2024;
    cr_assert_eq(btf_thesis_alloc(3, 7, 3, 8, &p, NULL), BTF_OK);
    size_t nl = (size_t)p.nb * p.S * p.S * p.C, nv = (size_t)p.nb * p.k * p.N * 3 * p.C;
    for (size_t i = 0; i < nl + nv; i++)
        *(i < nl ? &p.L[i] : &p.V[i - nl]) = (float)(2.0 * fx_unit(fx_xorshift32(&seed)) - 1.0);
    for (int i = 0; i < p.nb * p.C; i++)
        p.sigma[i] = (float)(1.0 + 100.0 * fx_unit(fx_xorshift32(&seed)));
    btf_error err = {{0}};
    cr_assert_eq(btf_thesis_write(dir, &p, &err), BTF_OK, "%s", err.msg);
    btf_thesis_free(&p);
}

/* Reads the thesis package at dir from the disk and from m: the same arrays, or the same error. */
static void expect_same_thesis(const char *dir, mem_dir *m, int want_ok)
{
    btf_thesis_pkg a, b;
    btf_error ea = {{0}}, eb = {{0}};
    btf_result ra = btf_thesis_read_with(dir, NULL, &a, &ea), rb = btf_thesis_read_with(dir, &m->files, &b, &eb);
    cr_expect_eq(ra, rb, "disk %s (%s), memory %s (%s)", btf_result_string(ra), ea.msg, btf_result_string(rb), eb.msg);
    cr_expect_eq(ra == BTF_OK, want_ok, "%s", ea.msg);
    if (ra == BTF_OK && rb == BTF_OK) {
        cr_expect_eq(memcmp(a.L, b.L, (size_t)a.nb * a.S * a.S * a.C * sizeof(float)), 0);
        cr_expect_eq(memcmp(a.V, b.V, (size_t)a.nb * a.k * a.N * 3 * a.C * sizeof(float)), 0);
        cr_expect_eq(memcmp(a.sigma, b.sigma, (size_t)a.nb * a.C * sizeof(float)), 0);
    } else {
        cr_expect_str_eq(ea.msg, eb.msg);
    }
    btf_thesis_free(&a);
    btf_thesis_free(&b);
}

Test(files, thesis_from_memory_reads_as_from_disk)
{
    char root[256], dir[300];
    cr_assert(fx_tmpdir(root, sizeof root));
    snprintf(dir, sizeof dir, "%s/pkg", root);
    make_thesis(dir);
    mem_dir m;
    memset(&m, 0, sizeof m);
    const char *names[5] = {"meta.json", "R.png", "0.png", "1.png", "2.png"};
    for (int i = 0; i < 5; i++)
        mem_add(&m, dir, names[i]);
    expect_same_thesis(dir, &m, 1);
    for (int i = 0; i < 5; i++) {
        btf_fs_mem_file *e = mem_file(&m, names[i]), keep = *e;
        e->size = keep.size / 2;
        fx_put(dir, e->name, keep.data, e->size);
        expect_same_thesis(dir, &m, 0);
        *e = keep;
        fx_put(dir, e->name, e->data, e->size);
    }
    mem_free(&m);
    fx_rmtree(root);
}

/* btf_fs_mem_files refuses as btf_fs_read does: over max_bytes, missing. */
Test(files, memory_files_refuse_as_the_disk_does)
{
    char root[256], path[300];
    cr_assert(fx_tmpdir(root, sizeof root));
    fx_put_text(root, "a.txt", "0123456789");
    btf_fs_mem_file f = {"a.txt", "0123456789", 10};
    btf_fs_mem m = {&f, 1};
    btf_files files = btf_fs_mem_files(&m);
    char *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    btf_error ea = {{0}}, eb = {{0}};
    snprintf(path, sizeof path, "%s/a.txt", root);
    cr_expect_eq(btf_fs_read_with(NULL, path, 9, &a, &na, &ea), BTF_ERR_RANGE);
    cr_expect_eq(btf_fs_read_with(&files, path, 9, &b, &nb, &eb), BTF_ERR_RANGE);
    cr_expect_str_eq(ea.msg, eb.msg);
    cr_expect_null(b);
    cr_assert_eq(btf_fs_read_with(&files, path, 10, &b, &nb, &eb), BTF_OK);
    cr_expect(nb == 10 && !strcmp(b, "0123456789"), "%zu %s", nb, b); /* NUL-terminated, as from the disk */
    free(b);
    cr_expect_eq(btf_fs_size_with(&files, path), 10);
    snprintf(path, sizeof path, "%s/b.txt", root);
    cr_expect_eq(btf_fs_size_with(&files, path), -1);
    cr_expect_eq(btf_fs_read_with(NULL, path, 9, &a, &na, &ea), BTF_ERR_MISSING);
    cr_expect_eq(btf_fs_read_with(&files, path, 9, &b, &nb, &eb), BTF_ERR_MISSING);
    cr_expect_str_eq(ea.msg, eb.msg);
    fx_rmtree(root);
}
