/* bench_lod.c - scene-driven budgets (doc/performance.md section 6, "Budgets"), printed as `name value unit` lines.
 *
 * A generated knit, BENCH_LOD_SIDE (default 128) texels square, UBO2003 81 x 81
 * directions, k = 3, C = 8, compressed and given 4 spatial levels (btf_lod_build).
 * For each scene btf_lod_select (threshold BTF_LOD_THRESHOLD) gives the chunk prefix;
 * printed: its bytes, the bytes of the whole package ("send everything"), and the
 * RMSE (0..255) at the displayed level against the whole package at that level,
 * over every measured (view, light) pair and every texel of that level.
 * Scenes (device pixels across the surface, times the material repeats across it):
 * close-up 1920 px x 1; thumbnail 300 px x 8 (a gallery sphere tiles the material);
 * grid of 12 thumbnails 200 px x 8; phone 1080 px x 2. First frame: manifest + chunk 0.
 * The same scenes again for version 4 (btf_lod_build with residual levels, section 12 of
 * doc/package-format.md), prefixed v4_: bytes and the display RMSE against the complete
 * version-2 package (version 4 rebuilds its levels exactly, so the same as version 2's).
 * Environment: BENCH_TMP (default /tmp/btf-bench-lod), BENCH_LOD_SIDE, BENCH_LOD_THRESHOLD
 * (visibility threshold of the build and the selection, default BTF_LOD_THRESHOLD).
 */
#include "btf.h"
#include "btf_gen.h"
#include "btf_lod.h"
#include "btf_package.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

static float bilin(const float *t, int w, int h, float fx, float fy)
{
    float x0f = floorf(fx), y0f = floorf(fy), ax = fx - x0f, ay = fy - y0f;
    int x0 = (int)x0f, y0 = (int)y0f;
    int xa = x0 < 0 ? 0 : x0 >= w ? w - 1 : x0, xb = x0 + 1 >= w ? w - 1 : x0 + 1 < 0 ? 0 : x0 + 1;
    int ya = y0 < 0 ? 0 : y0 >= h ? h - 1 : y0, yb = y0 + 1 >= h ? h - 1 : y0 + 1 < 0 ? 0 : y0 + 1;
    return (1 - ay) * ((1 - ax) * t[ya * w + xa] + ax * t[ya * w + xb]) + ay * ((1 - ax) * t[yb * w + xa] + ax * t[yb * w + xb]);
}

/* Texel of component c at level ld from the chunks < n (finest loaded level >= ld, upsampled); 0 if absent. */
static float texel(const btf_package *p, int n, int c, int ld, int b, int x, int y)
{
    int j = btf_package_chunk_at(p, n, c, ld);
    if (j < 0)
        return 0.0f;
    int g = p->chunk[j].level, w = p->width >> g, h = p->height >> g;
    const float *t = p->tex[j] + (size_t)b * w * h;
    if (g == ld)
        return t[y * w + x];
    float s = (float)(1 << (g - ld));
    return bilin(t, w, h, ((float)x + 0.5f) / s - 0.5f, ((float)y + 0.5f) / s - 0.5f);
}

/* RMSE at level ld of the prefix package q (read with only its budget, so with the
 * 8-bit coarse weights where those came first) against the whole package p at level ld. */
static double display_error(const btf_package *p, const btf_package *q, int ld)
{
    int w = p->width >> ld, h = p->height >> ld, V = p->views.n_dirs, L = p->lights.n_dirs, C = p->n_comp;
    double e = 0.0;
    float *tf = malloc((size_t)C * sizeof(float)), *tq = malloc((size_t)C * sizeof(float));
    const float **wf = malloc((size_t)C * sizeof *wf), **wq = malloc((size_t)C * sizeof *wq);
    for (int c = 0; c < C; c++) {
        int jf = btf_package_chunk_at(p, 0, c, 0), jq = btf_package_chunk_at(q, 0, c, ld);
        wf[c] = jf >= 0 ? p->wt[jf] : NULL;
        wq[c] = jq >= 0 ? q->wt[jq] : NULL;
    }
    for (int v = 0; v < V; v++) {
        int b = p->blocks->block_of_view[v];
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                for (int c = 0; c < C; c++)
                    tf[c] = texel(p, 0, c, ld, b, x, y), tq[c] = texel(q, 0, c, ld, b, x, y);
                for (int k = 0; k < L * 3; k++) {
                    float s = 0.0f;
                    for (int c = 0; c < C; c++)
                        s += (wf[c] ? tf[c] * wf[c][(size_t)v * L * 3 + k] : 0.0f) -
                             (wq[c] ? tq[c] * wq[c][(size_t)v * L * 3 + k] : 0.0f);
                    e += (double)s * s;
                }
            }
    }
    free(tf), free(tq), free(wf), free(wq);
    return 255.0 * sqrt(e / ((double)V * L * 3 * w * h));
}

int main(void)
{
    const char *tmp = getenv("BENCH_TMP") ? getenv("BENCH_TMP") : "/tmp/btf-bench-lod";
    int side = getenv("BENCH_LOD_SIDE") ? atoi(getenv("BENCH_LOD_SIDE")) : 128;
    char v1[1024], v2[1024], v4[1024], man[1100], man4[1100];
    mkdir(tmp, 0755);
    snprintf(v1, sizeof v1, "%s/knit-v1", tmp);
    snprintf(v2, sizeof v2, "%s/knit", tmp);
    snprintf(v4, sizeof v4, "%s/knit-v4", tmp);
    btf_dirset d = btf_dirset_ubo2003();
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf *src = NULL;
    btf_error err = {0};
    fprintf(stderr, "bench_lod: generating %dx%d knit\n", side, side);
    if (btf_gen_create(&gp, side, side, &d, &d, BTF_U8, &src, &err) != BTF_OK)
        return fprintf(stderr, "%s\n", err.msg), 1;
    btf_pca_options po = {0};
    po.k = 3, po.components = 8;
    btf_package_options ko = {0};
    if (btf_package_compress(src, &po, &ko, v1, NULL, &err) != BTF_OK)
        return fprintf(stderr, "%s\n", err.msg), 1;
    btf_free(src);
    btf_lod_options lo = {0};
    lo.levels = 4;
    double thr = getenv("BENCH_LOD_THRESHOLD") ? atof(getenv("BENCH_LOD_THRESHOLD")) : BTF_LOD_THRESHOLD;
    lo.threshold = thr;
    printf("threshold %.2f rmse\n", thr);
    btf_lod_stats st;
    clock_t t0 = clock();
    if (btf_lod_build(v1, v2, &lo, &st, &err) != BTF_OK)
        return fprintf(stderr, "%s\n", err.msg), 1;
    printf("lod_build_cpu %.2f s\n", (double)(clock() - t0) / CLOCKS_PER_SEC);
    btf_lod_stats st4;
    lo.residual = 1;
    if (btf_lod_build(v1, v4, &lo, &st4, &err) != BTF_OK)
        return fprintf(stderr, "%s\n", err.msg), 1;
    btf_package *p = NULL;
    if (btf_package_read(v2, 0, &p, &err) != BTF_OK)
        return fprintf(stderr, "%s\n", err.msg), 1;
    struct stat ms;
    snprintf(man, sizeof man, "%s/manifest.json", v2);
    long long mbytes = stat(man, &ms) == 0 ? (long long)ms.st_size : 0;
    snprintf(man4, sizeof man4, "%s/manifest.json", v4);
    long long mbytes4 = stat(man4, &ms) == 0 ? (long long)ms.st_size : 0;
    printf("package_v4_bytes %lld B\nv2_overhead %.1f %%\nv4_overhead %.1f %%\n", st4.bytes,
           100.0 * (double)(st.bytes - st.bytes_v1) / (double)st.bytes_v1,
           100.0 * (double)(st4.bytes - st4.bytes_v1) / (double)st4.bytes_v1);
    printf("v4_manifest_bytes %lld B\nv4_first_chunk_bytes %lld B\nv4_first_frame_bytes %lld B\n", mbytes4,
           st4.first_chunk, st4.first_chunk + mbytes4);
    printf("package_v1_bytes %lld B\npackage_v2_bytes %lld B\nchunks %d\nlevels %d\n", st.bytes_v1, st.bytes,
           st.n_chunks, st.levels);
    printf("manifest_bytes %lld B\nfirst_chunk_bytes %lld B\nfirst_frame_bytes %lld B\n", mbytes, st.first_chunk,
           st.first_chunk + mbytes);
    struct { const char *name; double px, repeat; int count; } sc[] = {
        {"closeup", 1920, 1, 1}, {"thumbnail", 300, 8, 1}, {"grid12", 200, 8, 12}, {"phone", 1080, 2, 1}};
    for (size_t i = 0; i < sizeof sc / sizeof sc[0]; i++) {
        btf_lod_view v = {btf_lod_footprint(p->width, sc[i].repeat, sc[i].px), thr};
        btf_lod_selection s;
        btf_lod_select(p, &v, &s, NULL);
        btf_package *q = NULL;
        if (btf_package_read(v2, s.limit, &q, &err) != BTF_OK)
            return fprintf(stderr, "%s\n", err.msg), 1;
        double e = display_error(p, q, s.level);
        btf_package_free(q);
        long long all = st.bytes_v1 * sc[i].count, got = (s.bytes + mbytes) * sc[i].count;
        printf("%s_texels_per_pixel %.3f\n%s_level %d\n%s_chunks %d of %d\n", sc[i].name, v.texels_per_pixel,
               sc[i].name, s.level, sc[i].name, s.limit, p->n_chunks);
        printf("%s_bytes %lld B\n%s_bytes_everything %lld B\n%s_fraction %.3f\n%s_display_rmse %.3f rmse\n",
               sc[i].name, got, sc[i].name, all, sc[i].name, (double)got / (double)all, sc[i].name, e);
        btf_package *p4 = NULL, *q4 = NULL;
        btf_lod_selection s4;
        if (btf_package_read(v4, 0, &p4, &err) != BTF_OK)
            return fprintf(stderr, "%s\n", err.msg), 1;
        btf_lod_select(p4, &v, &s4, NULL);
        if (btf_package_read(v4, s4.limit, &q4, &err) != BTF_OK)
            return fprintf(stderr, "%s\n", err.msg), 1;
        double e4 = display_error(p, q4, s4.level);
        long long got4 = (s4.bytes + mbytes4) * sc[i].count;
        printf("v4_%s_chunks %d of %d\nv4_%s_bytes %lld B\nv4_%s_fraction %.3f\nv4_%s_display_rmse %.3f rmse\n",
               sc[i].name, s4.limit, p4->n_chunks, sc[i].name, got4, sc[i].name, (double)got4 / (double)all, sc[i].name,
               e4);
        btf_package_free(p4);
        btf_package_free(q4);
        fflush(stdout);
    }
    btf_package_free(p);
    return 0;
}
