/* bench_lap.c - package version 4 (residual levels, doc/package-format.md section 4.4)
 * against version 2 (independent mips) and version 1 (no levels), and its streaming
 * order against the thesis format (issue 14, items 4 and 5); `name value unit` lines.
 *
 * Per material (generated knit and tiles at 64x64 with seeds no test uses, and the
 * thesis wool reconstructed at 64x64 when $BTF_SHARED has it): version 1 (k = 3,
 * C = 8), versions 2 and 4 made from it (4 levels, btf_lod_build), and the thesis
 * format of the same source (btf_export_thesis, k = 3, C = 8). Printed:
 *   lap_MAT_v1_bytes, _v2_bytes, _v4_bytes (every file, manifest included; version 4
 *   as written by default, each texture file the smaller of PNG and lossless WebP),
 *   _v4png_bytes (version 4 with PNG only), _v1best_bytes (version 1 with each
 *   texture counted at the smaller of its PNG and the lossless WebP of its pixels:
 *   the level-less package at the same file coding) and the overheads of v2, v4png
 *   and v4 over v1 and of v4 over v1best in percent;
 *   at 10, 25, 50 and 100% of the version-4 package's bytes B (manifest included):
 *   lap_MAT_F_v4_lab = the CIELab error (the thesis's, over every texel and measured
 *   pair, as btf eval) of the longest prefix of its chunk order within F% of B,
 *   decoded at level 0 (each component at its finest loaded level, upsampled as
 *   btf_decode does, with the most precise weights loaded); lap_MAT_F_thesis_lab = the
 *   thesis format's error after the files that fit in the same bytes in its own order
 *   (meta.json + R.png + 0.png, then 1.png, ...); lap_MAT_F_v1_lab = version 1's
 *   (no levels) the same way. -1 = nothing renders within those bytes.
 * Environment: BENCH_TMP (default /tmp/btf-bench-lap), BTF_SHARED, BENCH_LAP_SIDE (64),
 * BENCH_LAP_ONLY (knit, tiles or wool: that material alone, e.g. the wool at 256).
 */
#include "btf.h"
#include "btf_export.h"
#include "btf_gen.h"
#include "btf_image.h"
#include "btf_lod.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "btf_thesis.h"
#include "btf_webp.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static long long file_bytes(const char *dir, const char *name)
{
    char path[2200];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return stat(path, &st) == 0 ? (long long)st.st_size : 0;
}

/* dir_bytes with every tex-* file counted at the smaller of its size and the
 * lossless WebP of its grey pixels (codec/image/btf_webp.h). */
static long long dir_bytes_best(const char *dir)
{
    DIR *d = opendir(dir);
    long long n = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        if (e->d_name[0] == '.')
            continue;
        long long b = file_bytes(dir, e->d_name);
        char path[2200];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        int w, h;
        uint8_t *px = NULL, *webp = NULL;
        size_t nw = 0;
        btf_error err = {0};
        if (!strncmp(e->d_name, "tex-", 4) && btf_image_read_grey(path, &w, &h, &px, &err) == BTF_OK &&
            btf_webp_encode_grey(px, w, h, &webp, &nw, &err) == BTF_OK && (long long)nw < b)
            b = (long long)nw;
        free(px), free(webp);
        n += b;
    }
    if (d)
        closedir(d);
    return n;
}

static long long dir_bytes(const char *dir)
{
    DIR *d = opendir(dir);
    long long n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        if (e->d_name[0] != '.')
            n += file_bytes(dir, e->d_name);
    if (d)
        closedir(d);
    return n;
}

/* CIELab error of the package's first n chunks at level 0 against src, every pair. */
static double package_lab(const btf *src, const char *dir, int n)
{
    btf_package *p = NULL;
    btf_error err = {0};
    if (btf_package_read(dir, n, &p, &err) != BTF_OK) {
        fprintf(stderr, "bench_lap: %s\n", err.msg);
        exit(1);
    }
    int W = p->width, H = p->height, nb = p->blocks->n_blocks, C = p->n_comp, V = p->views.n_dirs, L = p->lights.n_dirs;
    size_t N = (size_t)W * H;
    float *T = calloc((size_t)C * nb * N, sizeof(float)), *ref = malloc(3 * N * sizeof(float));
    float *dec = malloc(3 * N * sizeof(float));
    const float **wt = calloc((size_t)C, sizeof *wt);
    for (int c = 0; c < C; c++) {
        int j = btf_package_chunk_at(p, n, c, 0);
        if (j < 0)
            continue;
        wt[c] = p->wt[j];
        for (int b = 0; b < nb; b++)
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++)
                    T[((size_t)c * nb + b) * N + (size_t)y * W + x] =
                        p->n_levels > 1 ? btf_package_texel(p, j, b, x, y) : p->tex[j][(size_t)b * N + (size_t)y * W + x];
    }
    btf_metrics_acc acc = {0};
    for (int v = 0; v < V; v++) {
        int b = p->blocks->block_of_view[v];
        for (int l = 0; l < L; l++) {
            btf_get_image(src, v, l, ref);
            memset(dec, 0, 3 * N * sizeof(float));
            for (int c = 0; c < C; c++) {
                if (!wt[c])
                    continue;
                const float *t = T + ((size_t)c * nb + b) * N, *w = wt[c] + ((size_t)v * L + l) * 3;
                for (size_t i = 0; i < N; i++)
                    dec[3 * i] += t[i] * w[0], dec[3 * i + 1] += t[i] * w[1], dec[3 * i + 2] += t[i] * w[2];
            }
            btf_metrics_add(&acc, ref, dec, N);
        }
    }
    btf_metrics m;
    btf_metrics_finish(&acc, &m);
    free(T), free(ref), free(dec), free(wt);
    btf_package_free(p);
    return m.lab_thesis;
}

/* Longest chunk prefix of the package within max bytes (manifest included); 0 if none. */
static int prefix_within(const char *dir, long long max)
{
    btf_package *p = NULL;
    btf_error err = {0};
    if (btf_package_read(dir, 1, &p, &err) != BTF_OK)
        return 0;
    long long b = file_bytes(dir, "manifest.json");
    int n = 0;
    while (n < p->n_chunks && b + p->chunk[n].bytes <= max)
        b += p->chunk[n++].bytes;
    btf_package_free(p);
    return n;
}

/* The thesis format's CIELab error after its files within max bytes (-1: not even the first component). */
static double thesis_lab(const btf *src, const char *dir, long long max)
{
    btf_thesis_pkg p = {0};
    btf_error err = {0};
    if (btf_thesis_read(dir, &p, &err) != BTF_OK) {
        fprintf(stderr, "bench_lap: %s\n", err.msg);
        exit(1);
    }
    long long b = file_bytes(dir, "meta.json") + file_bytes(dir, "R.png");
    int got = 0;
    char f[32];
    for (int j = 0; j < p.C; j++) {
        snprintf(f, sizeof f, "%d.png", j);
        if (b + file_bytes(dir, f) > max)
            break;
        b += file_bytes(dir, f), got = j + 1;
    }
    double lab = -1.0;
    if (got > 0) {
        for (int k = 0; k < p.nb; k++)
            for (int i = got; i < p.C; i++)
                p.sigma[k * p.C + i] = 0.0f; /* components not received */
        size_t N = (size_t)src->width * src->height;
        float *ref = malloc(3 * N * sizeof(float)), *dec = malloc(3 * N * sizeof(float));
        btf_metrics_acc acc = {0};
        for (int v = 0; v < src->views.n_dirs; v++)
            for (int l = 0; l < src->lights.n_dirs; l++) {
                btf_get_image(src, v, l, ref);
                btf_thesis_decode_image(&p, v, l, dec);
                btf_metrics_add(&acc, ref, dec, N);
            }
        btf_metrics m;
        btf_metrics_finish(&acc, &m);
        lab = m.lab_thesis;
        free(ref), free(dec);
    }
    btf_thesis_free(&p);
    return lab;
}

static void die(const btf_error *e)
{
    fprintf(stderr, "bench_lap: %s\n", e->msg);
    exit(1);
}

static void material(const char *name, const btf *src, const char *tmp)
{
    char v1[1200], v2[1200], v4[1200], v4p[1200], th[1200];
    snprintf(v1, sizeof v1, "%s/%s-v1", tmp, name);
    snprintf(v2, sizeof v2, "%s/%s-v2", tmp, name);
    snprintf(v4, sizeof v4, "%s/%s-v4", tmp, name);
    snprintf(v4p, sizeof v4p, "%s/%s-v4png", tmp, name);
    snprintf(th, sizeof th, "%s/%s-thesis", tmp, name);
    btf_error err = {0};
    btf_pca_options po = {0};
    po.k = 3, po.components = 8;
    btf_package_options ko = {0};
    if (btf_package_compress(src, &po, &ko, v1, NULL, &err) != BTF_OK)
        die(&err);
    btf_lod_options lo = {0};
    lo.levels = 4;
    if (btf_lod_build(v1, v2, &lo, NULL, &err) != BTF_OK)
        die(&err);
    lo.residual = 1;
    if (btf_lod_build(v1, v4, &lo, NULL, &err) != BTF_OK)
        die(&err);
    lo.png_only = 1;
    if (btf_lod_build(v1, v4p, &lo, NULL, &err) != BTF_OK)
        die(&err);
    btf_export_options eo = {0};
    eo.k = 3, eo.components = 8;
    if (btf_export_thesis(src, &eo, th, NULL, &err) != BTF_OK)
        die(&err);
    long long b1 = dir_bytes(v1), b2 = dir_bytes(v2), b4 = dir_bytes(v4), bt = dir_bytes(th);
    printf("lap_%s_v1_bytes %lld B\nlap_%s_v2_bytes %lld B\nlap_%s_v4_bytes %lld B\nlap_%s_thesis_bytes %lld B\n", name,
           b1, name, b2, name, b4, name, bt);
    long long b4p = dir_bytes(v4p), b1b = dir_bytes_best(v1);
    printf("lap_%s_v4png_bytes %lld B\nlap_%s_v1best_bytes %lld B\n", name, b4p, name, b1b);
    printf("lap_%s_v2_overhead %.1f %%\nlap_%s_v4png_overhead %.1f %%\nlap_%s_v4_overhead %.1f %%\n", name,
           100.0 * (b2 - b1) / b1, name, 100.0 * (b4p - b1) / b1, name, 100.0 * (b4 - b1) / b1);
    printf("lap_%s_v4_over_v1best %.1f %%\n", name, 100.0 * (b4 - b1b) / b1b);
    printf("# %s: share of B | bytes | v4 chunks / Lab | thesis Lab | v1 chunks / Lab\n", name);
    const int pct[4] = {10, 25, 50, 100};
    for (int i = 0; i < 4; i++) {
        long long max = b4 * pct[i] / 100;
        int n4 = prefix_within(v4, max), n1 = prefix_within(v1, max);
        double l4 = n4 ? package_lab(src, v4, n4) : -1.0, l1 = n1 ? package_lab(src, v1, n1) : -1.0;
        double lt = thesis_lab(src, th, max);
        printf("lap_%s_%d_bytes %lld B\nlap_%s_%d_v4_chunks %d\nlap_%s_%d_v4_lab %.4f lab\n", name, pct[i], max, name,
               pct[i], n4, name, pct[i], l4);
        printf("lap_%s_%d_thesis_lab %.4f lab\nlap_%s_%d_v1_lab %.4f lab\n", name, pct[i], lt, name, pct[i], l1);
        printf("# %s %3d%% | %lld | %d / %.3f | %.3f | %d / %.3f\n", name, pct[i], max, n4, l4, lt, n1, l1);
        fflush(stdout);
    }
}

int main(void)
{
    const char *tmp = getenv("BENCH_TMP") ? getenv("BENCH_TMP") : "/tmp/btf-bench-lap";
    int side = getenv("BENCH_LAP_SIDE") ? atoi(getenv("BENCH_LAP_SIDE")) : 64;
    mkdir(tmp, 0755);
    btf_dirset d = btf_dirset_ubo2003();
    btf_error err = {0};
    struct { const char *name; btf_gen_kind kind; unsigned seed; } gen[] = {
        {"knit", BTF_GEN_KNIT, 4343}, {"tiles", BTF_GEN_TILES, 4344}};
    const char *only = getenv("BENCH_LAP_ONLY");
    for (size_t i = 0; i < sizeof gen / sizeof gen[0]; i++) {
        if (only && strcmp(only, gen[i].name))
            continue;
        btf_gen_params gp = btf_gen_defaults(gen[i].kind);
        gp.seed = gen[i].seed;
        btf *src = NULL;
        fprintf(stderr, "bench_lap: %s %dx%d\n", gen[i].name, side, side);
        if (btf_gen_create(&gp, side, side, &d, &d, BTF_U8, &src, &err) != BTF_OK)
            die(&err);
        material(gen[i].name, src, tmp);
        btf_free(src);
    }
    const char *shared = getenv("BTF_SHARED");
    char wool[1200];
    snprintf(wool, sizeof wool, "%s/data/thesis-ubo2003/wool", shared ? shared : "../shared");
    btf_thesis_pkg tp = {0};
    if (only && strcmp(only, "wool"))
        return 0;
    if (btf_thesis_read(wool, &tp, &err) == BTF_OK) {
        btf *src = NULL;
        fprintf(stderr, "bench_lap: thesis wool at %dx%d\n", side, side);
        if (btf_thesis_reconstruct(&tp, NULL, side, side, BTF_F32, &src, &err) != BTF_OK)
            die(&err);
        btf_thesis_free(&tp);
        material("wool", src, tmp);
        btf_free(src);
    } else {
        printf("# thesis wool not found (%s): skipped\n", err.msg);
    }
    return 0;
}
