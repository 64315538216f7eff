/* fuzz_pkg.h - what the package and thesis targets share (header only): the small
 * valid packages an input starts from (made once per process in the scratch
 * directory), which file an input's first byte replaces, and the contracts a read
 * keeps. Used by the disk targets (fuzz_package.c, fuzz_thesis.c), which write the
 * input into the package's directory, and by their in-memory twins
 * (fuzz_package_mem.c, fuzz_thesis_mem.c), which put it in a fuzz_mem and read
 * through btf_files: the same readers and checks without a file system. */
#ifndef BTF_FUZZ_PKG_H
#define BTF_FUZZ_PKG_H

#include <math.h>
#include <sys/stat.h>

#include "btf_common.h"
#include "btf_decode.h"
#include "btf_fs.h"
#include "btf_image.h"
#include "btf_gen.h"
#include "btf_lod.h"
#include "btf_lossy.h"
#include "btf_package.h"
#include "btf_thesis.h"
#include "btf_wtz.h"
#include "fuzz_util.h"

/* ---------------------------------------------------------------- packages */

/* The packages (v1, v2, v4, v3 with lossy WebP textures allowed, and va: v3 with AVIF
 * textures allowed) every package input starts from; made once per process. */
typedef struct fuzz_pkgs {
    char v1[300], v2[300], v4[300], v3[300], va[300];
    char residual[64]; /* v4's residual level file, or "manifest.json" when the writer kept none */
    char avif[64];     /* va's first AVIF texture file */
    char wt3[64];      /* v3's weights file of component 0: wt-00.z, wt-00.pz or wt-00.webp, as the writer chose */
    char wta[64];      /* va's: wt-00.webp (fuzz__webp_weights) */
    char w84[64];      /* v4's 8-bit weights of component 0: wt-00-8.webp, or wt-00-8.png, as the writer chose */
} fuzz_pkgs;

/* va: v3 with tex-00 as an AVIF of its decoded atlas (quantiser 20) and component 0's
 * weights as wt-00.webp (fuzz__webp_weights), under those names in the manifest; a
 * package this tiny never gets either from the writer (lossy does not win on a 32 x 32
 * atlas, nor an image on 5 x 5 weights), and any coding is allowed for any file. */
static inline btf_result fuzz__avif_package(fuzz_pkgs *p, btf_error *err)
{
    char from[400], to[400], *man = NULL;
    uint8_t *px = NULL, *f = NULL;
    size_t n = 0, mn = 0;
    int w = 0, h = 0;
    snprintf(from, sizeof from, "%s/tex-00.webp", p->v3);
    btf_result r = mkdir(p->va, 0700) == 0 ? BTF_OK : btf_fail(err, BTF_ERR_IO, "%s: cannot make", p->va);
    if (r == BTF_OK)
        r = btf_image_read_grey(from, &w, &h, &px, err);
    if (r == BTF_OK)
        r = btf_lossy_encode(BTF_LOSSY_AVIF, px, w, h, 20, &f, &n, err);
    snprintf(to, sizeof to, "%s/tex-00.avif", p->va);
    if (r == BTF_OK)
        r = btf_fs_write_atomic(to, f, n, err);
    const char *copy[7] = {"tex-01.webp", "wt-00.z", "wt-01.z", "wt-00.pz", "wt-01.pz", "wt-00.webp", "wt-01.webp"};
    for (int i = 0; r == BTF_OK && i < 7; i++) {
        char *data = NULL;
        snprintf(from, sizeof from, "%s/%s", p->v3, copy[i]);
        if (i > 0 && btf_fs_size(from) < 0)
            continue; /* each component has one of its three weights codings */
        snprintf(to, sizeof to, "%s/%s", p->va, copy[i]);
        r = btf_fs_read(from, (size_t)1 << 24, &data, &n, err);
        if (r == BTF_OK)
            r = btf_fs_write_atomic(to, data, n, err);
        free(data);
    }
    snprintf(from, sizeof from, "%s/manifest.json", p->v3);
    snprintf(to, sizeof to, "%s/manifest.json", p->va);
    if (r == BTF_OK)
        r = btf_fs_read(from, (size_t)1 << 24, &man, &mn, err);
    char *at = r == BTF_OK ? strstr(man, "tex-00.webp") : NULL;
    if (at)
        memcpy(at, "tex-00.avif", 11);
    if (r == BTF_OK)
        r = at ? btf_fs_write_atomic(to, man, mn, err) : btf_fail(err, BTF_ERR_FORMAT, "v3 names no tex-00.webp");
    free(px), free(f), free(man);
    return r;
}

/* Component 0's weights of the package dir replaced by a wt-00.webp of the same size
 * (codes 0..255 in a pattern, so the package stays valid) under that name in its
 * manifest. */
static inline btf_result fuzz__webp_weights(const char *dir, btf_error *err)
{
    btf_package *p = NULL;
    btf_result r = btf_package_read(dir, 0, &p, err);
    if (r != BTF_OK)
        return r;
    int V = p->views.n_dirs, L = p->lights.n_dirs;
    char was[BTF_PACKAGE_NAME_MAX], path[400], *man = NULL;
    snprintf(was, sizeof was, "%s", p->chunk[0].files[1]);
    btf_package_free(p);
    size_t n = (size_t)V * L * 3, nf = 0, mn = 0;
    uint16_t *q = malloc(n * sizeof *q);
    uint8_t *f = NULL;
    for (size_t i = 0; q && i < n; i++)
        q[i] = (uint16_t)((i * 37u + i / 3) & 255u);
    r = q ? btf_wtz_encode_webp(q, V, L, &f, &nf, err) : btf_fail(err, BTF_ERR_NOMEM, "fuzz: out of memory");
    snprintf(path, sizeof path, "%s/wt-00.webp", dir);
    if (r == BTF_OK)
        r = btf_fs_write_atomic(path, f, nf, err);
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    if (r == BTF_OK)
        r = btf_fs_read(path, (size_t)1 << 24, &man, &mn, err);
    char *at = r == BTF_OK && strncmp(was, "wt-00.", 6) == 0 ? strstr(man, was) : NULL;
    if (r == BTF_OK && !at)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s names no weights file of component 0", path);
    if (r == BTF_OK) { /* "wt-00.pz" or "wt-00.z" -> "wt-00.webp": the text grows by up to 2 */
        size_t head = (size_t)(at - man), tail = mn - head - strlen(was);
        char *text = malloc(mn + 8);
        r = text ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "fuzz: out of memory");
        if (text) {
            memcpy(text, man, head), memcpy(text + head, "wt-00.webp", 10), memcpy(text + head + 10, at + strlen(was), tail);
            r = btf_fs_write_atomic(path, text, head + 10 + tail, err);
            free(text);
        }
        snprintf(path, sizeof path, "%s/%s", dir, was);
        if (r == BTF_OK && strcmp(was, "wt-00.webp") != 0)
            unlink(path); /* the copy of v3's file this one replaces */
    }
    free(q), free(f), free(man);
    return r;
}

static inline void fuzz__pkgs_make(fuzz_pkgs *p)
{
    btf_ring r[2] = {{0.0f, 1, 0.0f}, {45.0f, 4, 0.0f}};
    btf_dirset d;
    btf_error err = {{0}};
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_TILES);
    btf *b = NULL;
    btf_pca_options po = {0};
    po.k = 2, po.components = 2;
    btf_lod_options lo = {0}, lr = {0};
    lo.levels = lr.levels = 2;
    lr.residual = 1;
    btf_package_options ro = {0};
    ro.rd = 1, ro.lossy = BTF_LOSSY_WEBP;
    if (btf_dirset_make(r, 2, &d, &err) != BTF_OK || btf_gen_create(&gp, 16, 16, &d, &d, BTF_U8, &b, &err) != BTF_OK ||
        btf_package_compress(b, &po, NULL, p->v1, NULL, &err) != BTF_OK ||
        btf_lod_build(p->v1, p->v2, &lo, NULL, &err) != BTF_OK || btf_lod_build(p->v1, p->v4, &lr, NULL, &err) != BTF_OK ||
        btf_package_compress(b, &po, &ro, p->v3, NULL, &err) != BTF_OK || fuzz__avif_package(p, &err) != BTF_OK ||
        fuzz__webp_weights(p->va, &err) != BTF_OK) {
        fprintf(stderr, "fuzz: package setup failed: %s\n", err.msg);
        abort();
    }
    btf_free(b);
}

static inline const fuzz_pkgs *fuzz_packages(void)
{
    static fuzz_pkgs p;
    if (p.v1[0])
        return &p;
    snprintf(p.v1, sizeof p.v1, "%s/v1", fuzz_dir());
    snprintf(p.v2, sizeof p.v2, "%s/v2", fuzz_dir());
    snprintf(p.v4, sizeof p.v4, "%s/v4", fuzz_dir());
    snprintf(p.v3, sizeof p.v3, "%s/v3", fuzz_dir());
    snprintf(p.va, sizeof p.va, "%s/va", fuzz_dir());
    fuzz__pkgs_make(&p);
    snprintf(p.residual, sizeof p.residual, "manifest.json");
    char path[400];
    for (int j = 0; j < 4 && !strcmp(p.residual, "manifest.json"); j++) {
        const char *ext = j < 2 ? "webp" : "png"; /* a lossless WebP where the writer found it smaller */
        snprintf(path, sizeof path, "%s/tex-%02d-d0.%s", p.v4, j % 2, ext);
        if (btf_fs_size(path) > 0)
            snprintf(p.residual, sizeof p.residual, "tex-%02d-d0.%s", j % 2, ext);
    }
    for (int j = 0; j < 2 && !p.avif[0]; j++) {
        snprintf(path, sizeof path, "%s/tex-%02d.avif", p.va, j);
        if (btf_fs_size(path) > 0)
            snprintf(p.avif, sizeof p.avif, "tex-%02d.avif", j);
    }
    static const char *const wt_ext[3] = {".webp", ".pz", ".z"};
    for (int j = 0; j < 3; j++) { /* the coding the writer chose for component 0 */
        snprintf(p.wt3, sizeof p.wt3, "wt-00%s", wt_ext[j]);
        snprintf(path, sizeof path, "%s/%s", p.v3, p.wt3);
        if (btf_fs_size(path) > 0)
            break;
    }
    snprintf(p.w84, sizeof p.w84, "wt-00-8.webp");
    snprintf(path, sizeof path, "%s/%s", p.v4, p.w84);
    if (btf_fs_size(path) < 0)
        snprintf(p.w84, sizeof p.w84, "wt-00-8.png");
    snprintf(p.wta, sizeof p.wta, "wt-00.webp");
    snprintf(path, sizeof path, "%s/%s", p.va, p.wta);
    if (!p.avif[0] || btf_fs_size(path) <= 0) {
        fprintf(stderr, "fuzz: the AVIF package has no AVIF texture or no wt-00.webp (the setup no longer covers them)\n");
        abort();
    }
    return &p;
}

/* The file an input replaces (first byte below 0xf8, modulo 6: 0 texture PNG, 1
 * weights .bin, 2 manifest.json of v1, 3 an 8-bit weights PNG of v2, 4 the manifest
 * and 5 a residual level of v4; 0xf8, 0xf9: v3's WebP texture tex-00.webp, lossy
 * or lossless, 32 x 32; 0xfa: v3's weights of component 0, wt-00.pz or wt-00.z; 0xfb:
 * va's, wt-00.webp; 0xfd: v4's 8-bit weights of component 0, wt-00-8.webp (or .png);
 * 0xfc, 0xfe, 0xff: va's AVIF texture); *pkg gets 1, 2, 3, 4 or 5. */
static inline const char *fuzz_package_file(const fuzz_pkgs *pk, uint8_t first, int *pkg)
{
    const char *names[6] = {"tex-00.png", "wt-00.bin", "manifest.json", "wt-00-8.png", "manifest.json", pk->residual};
    if (first == 0xfd) {
        *pkg = 4;
        return pk->w84;
    }
    if (first >= 0xfb) {
        *pkg = 5;
        return first == 0xfb ? pk->wta : pk->avif;
    }
    if (first >= 0xf8) {
        *pkg = 3;
        return first == 0xfa ? pk->wt3 : "tex-00.webp";
    }
    int which = first % 6;
    *pkg = which >= 4 ? 4 : which == 3 ? 2 : 1;
    return names[which];
}

/* Reads the package dir through files (NULL: the disk) and checks what an accepted
 * package promises (finite decoded values) or a refused one (no package, one line). */
static inline void fuzz_package_check(const char *dir, const btf_files *files)
{
    btf_package *p = NULL;
    btf_error err = {{0}};
    if (btf_package_read_with(dir, -1, files, &p, &err) != BTF_OK) {
        FUZZ_CHECK(p == NULL && err.msg[0] != 0 && !strchr(err.msg, '\n'));
        return;
    }
    btf_decode_options o = {0};
    float l[3] = {0.1f, 0.2f, 1.0f}, v[3] = {-0.3f, 0.1f, 1.0f}, rgb[3];
    btf_decode(p, 0.4f, 0.7f, l, v, &o, rgb);
    FUZZ_CHECK(isfinite(rgb[0]) && isfinite(rgb[1]) && isfinite(rgb[2]));
    btf_package_free(p);
}

/* ---------------------------------------------------------------- thesis packages */

/* The thesis package every thesis input starts from (C 2, N 7, k 7, S 4); made once. */
static inline const char *fuzz_thesis_dir(void)
{
    static char dir[300];
    if (dir[0])
        return dir;
    snprintf(dir, sizeof dir, "%s/thesis", fuzz_dir());
    btf_thesis_pkg p;
    btf_error err = {{0}};
    if (btf_thesis_alloc(2, 7, 7, 4, &p, &err) != BTF_OK)
        abort();
    for (size_t i = 0; i < (size_t)p.nb * p.S * p.S * p.C; i++)
        p.L[i] = (float)((i * 37) % 200) / 100.0f - 1.0f;
    for (size_t i = 0; i < (size_t)p.nb * p.k * p.N * 3 * p.C; i++)
        p.V[i] = (float)((i * 53) % 200) / 100.0f - 1.0f;
    for (int i = 0; i < p.nb * p.C; i++)
        p.sigma[i] = 1.0f + (float)i;
    if (btf_thesis_write(dir, &p, &err) != BTF_OK) {
        fprintf(stderr, "fuzz: thesis setup failed: %s\n", err.msg);
        abort();
    }
    btf_thesis_free(&p);
    return dir;
}

/* The file a thesis input replaces (first byte: 0 meta.json, 1 R.png, 2 0.png). */
static inline const char *fuzz_thesis_file(uint8_t first)
{
    static const char *names[3] = {"meta.json", "R.png", "0.png"};
    return names[first % 3];
}

/* Reads the thesis package dir through files (NULL: the disk): an accepted one
 * must reconstruct to finite values, a refused one give a one-line message. */
static inline void fuzz_thesis_check(const char *dir, const btf_files *files)
{
    btf_thesis_pkg p;
    btf_error err = {{0}};
    if (btf_thesis_read_with(dir, files, &p, &err) != BTF_OK) {
        FUZZ_CHECK(p.L == NULL && err.msg[0] != 0 && !strchr(err.msg, '\n'));
        return;
    }
    btf_dirset d;
    btf_ring r[2] = {{0.0f, 1, 0.0f}, {45.0f, 6, 0.0f}};
    btf *b = NULL;
    if (p.N == 7 && btf_dirset_make(r, 2, &d, NULL) == BTF_OK &&
        btf_thesis_reconstruct(&p, &d, 0, 0, BTF_F32, &b, &err) == BTF_OK) {
        const float *f = b->data;
        FUZZ_CHECK(isfinite(f[0]));
        btf_free(b);
    }
    btf_thesis_free(&p);
}

#endif
