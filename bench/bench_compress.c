/* bench_compress.c - compressor numbers, printed as `name value unit` lines:
 *
 *   a. full-size thesis wool (256x256, 81x81): btf_package_compress at k = 3, C = 8
 *      from loaded data and from a UBO2003 JPEG directory (written once into
 *      $BENCH_TMP, image decode included): wall time, peak RSS; the same first
 *      BENCH_SVD_BLOCKS blocks through full sgesdd and through the default route,
 *      extrapolated to all blocks, and their ratio;
 *   b. error versus size, k in {1,3,9,27,81} x C in {2,4,8,16,32}, 64x64 texels:
 *      thesis wool (box-filtered) and generated knit and tiles;
 *   c. equal bytes: the project's package (k = 3, 8 bits, the longest chunk prefix
 *      whose files + manifest fit in the thesis package's bytes) against
 *      btf_export_thesis (k = 3, C = 8, thesis and fit scaling) of the same generated
 *      material at BENCH_EQ_SIDE (default 128; 256 = full size), both decoded in
 *      float and compared with the source over every sample; also the package with
 *      full-range 8-bit textures (tex_noise < 0, the earlier writer) as a baseline.
 *
 * Each stage runs in a forked child (own peak RSS). Environment: BTF_SHARED,
 * BENCH_TMP (default /tmp/btf-bench-compress), BENCH_SVD_BLOCKS (default 2),
 * BENCH_EQ_SIDE, BENCH_ONLY (full, sweep or equal: one part). Run through bench/run.sh (make bench); progress goes to stderr.
 */
#include "btf.h"
#include "btf_export.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "btf_pca.h"
#include "btf_thesis.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_util.h"
#include "btf_input.h"
#include "btf_blocks.h"

static char g_tmp[1024], g_wool[1024];

static int env_int(const char *name, int def)
{
    const char *s = getenv(name);
    return s && atoi(s) > 0 ? atoi(s) : def;
}

/* Runs stage() in a child; prints NAME_peak_rss after it. Returns its exit status. */
static int run_stage(const char *name, int (*stage)(void))
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0)
        return 1;
    if (pid == 0) {
        int rc = stage();
        fflush(stdout);
        _exit(rc);
    }
    int status = 0;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) < 0)
        return 1;
    int rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (rc == 0)
        printf("%s_peak_rss %.1f MiB\n", name, (double)ru.ru_maxrss / 1024.0);
    else
        fprintf(stderr, "bench: stage %s failed (status %d)\n", name, rc);
    return rc;
}

static int fail(const char *what, const btf_error *err)
{
    fprintf(stderr, "bench: %s: %s\n", what, err->msg);
    return 1;
}

static int load_wool(int side, btf **out)
{
    btf_load_options o = {0};
    o.width = o.height = side;
    btf_error err = {0};
    return btf_import_thesis(g_wool, &o, out, &err) == BTF_OK ? 0 : fail("wool", &err);
}

/* ------------------------------------------------------------ (a) full size */

static int stage_jpeg_dir(void)
{
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/wool-jpg", g_tmp);
    struct stat st;
    if (stat(dir, &st) == 0)
        return 0;
    btf *b = NULL;
    if (load_wool(0, &b))
        return 1;
    btf_error err = {0};
    double t0 = now_s();
    char tmp[1200];
    snprintf(tmp, sizeof tmp, "%s.tmp", dir);
    mkdir(tmp, 0755);
    int rc = btf_save_ubo2003_dir(b, tmp, "wool", "jpg", &err) == BTF_OK && rename(tmp, dir) == 0 ? 0 : 1;
    if (rc)
        fail("writing the JPEG directory", &err);
    else
        printf("wool_jpeg_dir_write_time %.2f s\n", now_s() - t0);
    btf_free(b);
    return rc;
}

static int compress_full(const btf *b, const char *tag, double t_load, double t_start)
{
    char out[1100];
    snprintf(out, sizeof out, "%s/wool-%s.pkg", g_tmp, tag);
    btf_pca_options po = {0};
    po.k = 3, po.components = 8;
    btf_compress_stats st = {0};
    btf_error err = {0};
    double t0 = now_s(), c0 = cpu_s();
    if (btf_package_compress(b, &po, NULL, out, &st, &err) != BTF_OK)
        return fail("compress", &err);
    double t1 = now_s();
    printf("full_%s_compress_cpu %.2f s\n", tag, cpu_s() - c0);
    printf("full_%s_total_cpu %.2f s\n", tag, cpu_s());
    double la[1];
    if (getloadavg(la, 1) == 1)
        printf("full_%s_loadavg_1min %.2f count\n", tag, la[0]);
    printf("full_%s_load_time %.2f s\n", tag, t_load);
    printf("full_%s_compress_time %.2f s\n", tag, t1 - t0);
    printf("full_%s_compress_pca_time %.2f s\n", tag, st.seconds_pca);
    printf("full_%s_compress_write_time %.2f s\n", tag, st.seconds_write);
    printf("full_%s_total_time %.2f s\n", tag, t1 - t_start);
    printf("full_%s_total_vs_target_30s %.3f ratio\n", tag, (t1 - t_start) / 30.0);
    printf("full_%s_bytes %lld bytes\n", tag, st.bytes);
    printf("full_%s_rmse %.4f 0..255\n", tag, st.rmse);
    printf("full_%s_lab %.4f CIELab\n", tag, st.lab);
    return 0;
}

static int stage_full_loaded(void)
{
    double t0 = now_s();
    btf *b = NULL;
    if (load_wool(0, &b))
        return 1;
    int rc = compress_full(b, "loaded", now_s() - t0, now_s());
    btf_free(b);
    return rc;
}

static int stage_full_images(void)
{
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/wool-jpg", g_tmp);
    double t0 = now_s();
    btf *b = NULL;
    btf_error err = {0};
    if (btf_load_any(dir, NULL, &b, &err) != BTF_OK)
        return fail(dir, &err);
    int rc = compress_full(b, "images", now_s() - t0, t0);
    btf_free(b);
    return rc;
}

/* The first n blocks through the default route and through full sgesdd. */
static int stage_svd(void)
{
    btf *b = NULL;
    if (load_wool(0, &b))
        return 1;
    btf_blocks *bl = NULL;
    btf_error err = {0};
    if (btf_blocks_group(&b->views, 3, BTF_GROUP_CONSECUTIVE, &bl, &err) != BTF_OK)
        return fail("blocks", &err);
    int n = env_int("BENCH_SVD_BLOCKS", 2), rows = b->width * b->height;
    n = n > bl->n_blocks ? bl->n_blocks : n;
    float *A = malloc(sizeof(float) * (size_t)rows * 3 * 81 * 3);
    double t[2] = {0, 0}, dev = 0.0;
    for (int i = 0; A && i < n; i++) {
        int cols = btf_blocks_cols(b, bl, i);
        if (btf_pca_block_matrix(b, bl, i, A, &err) != BTF_OK)
            return fail("block matrix", &err);
        btf_pca_block res[2];
        for (int m = 0; m < 2; m++) {
            double t0 = now_s();
            if (btf_pca_block_compute(A, rows, cols, 8, m ? BTF_PCA_SVD : BTF_PCA_AUTO, BTF_CENTER_NONE, &res[m],
                                      &err) != BTF_OK)
                return fail("PCA", &err);
            t[m] += now_s() - t0;
        }
        for (int j = 0; j < 8; j++) {
            double d = res[0].sigma[j] / res[1].sigma[j] - 1.0;
            dev = fabs(d) > dev ? fabs(d) : dev;
        }
        btf_pca_block_clear(&res[0]);
        btf_pca_block_clear(&res[1]);
    }
    printf("svd_blocks_measured %d count\n", n);
    printf("svd_default_route_per_block %.3f s\n", t[0] / n);
    printf("svd_sgesdd_per_block %.3f s\n", t[1] / n);
    printf("svd_sgesdd_all_blocks_extrapolated %.1f s\n", t[1] / n * bl->n_blocks);
    printf("svd_default_all_blocks_extrapolated %.1f s\n", t[0] / n * bl->n_blocks);
    printf("svd_speedup_default_vs_sgesdd %.1f ratio\n", t[1] / t[0]);
    printf("svd_top8_sigma_max_rel_diff %.2e ratio\n", dev);
    free(A);
    btf_blocks_free(bl);
    btf_free(b);
    return 0;
}

/* ------------------------------------------------------------ (b) sweep */

static int sweep_one(const char *mat, const btf *src)
{
    static const int ks[] = {1, 3, 9, 27, 81}, cs[] = {2, 4, 8, 16, 32};
    for (int a = 0; a < 5; a++)
        for (int c = 0; c < 5; c++) {
            char out[1100];
            snprintf(out, sizeof out, "%s/sweep-%s.pkg", g_tmp, mat);
            btf_pca_options po = {0};
            po.k = ks[a], po.components = cs[c];
            btf_compress_stats st = {0};
            btf_error err = {0};
            double t0 = now_s();
            if (btf_package_compress(src, &po, NULL, out, &st, &err) != BTF_OK)
                return fail("sweep compress", &err);
            printf("sweep_%s_k%d_c%d_bytes %lld bytes\n", mat, ks[a], cs[c], st.bytes);
            printf("sweep_%s_k%d_c%d_rmse %.4f 0..255\n", mat, ks[a], cs[c], st.rmse);
            printf("sweep_%s_k%d_c%d_rmse_float %.4f 0..255\n", mat, ks[a], cs[c], st.rmse_float);
            printf("sweep_%s_k%d_c%d_lab %.4f CIELab_subsample\n", mat, ks[a], cs[c], st.lab);
            printf("sweep_%s_k%d_c%d_time %.2f s\n", mat, ks[a], cs[c], now_s() - t0);
            fflush(stdout);
        }
    return 0;
}

static int gen(btf_gen_kind kind, int side, btf **out)
{
    btf_gen_params p = btf_gen_defaults(kind);
    btf_dirset d = btf_dirset_ubo2003();
    btf_error err = {0};
    return btf_gen_create(&p, side, side, &d, &d, BTF_U8, out, &err) == BTF_OK ? 0 : fail("gen", &err);
}

static int stage_sweep(void)
{
    btf *b = NULL;
    int rc = 0;
    if (!load_wool(64, &b))
        rc |= sweep_one("wool", b);
    btf_free(b), b = NULL;
    for (int k = 0; k < 2 && !rc; k++) {
        btf_gen_kind kind = k ? BTF_GEN_TILES : BTF_GEN_KNIT;
        if ((rc = gen(kind, 64, &b)) == 0)
            rc = sweep_one(btf_gen_kind_name(kind), b);
        btf_free(b), b = NULL;
    }
    return rc;
}

/* ------------------------------------------------------------ (c) equal bytes */

static int lab_of(const btf *src, btf *dec, btf_metrics *m)
{
    btf_error err = {0};
    btf_result r = btf_compare(src, dec, NULL, m, &err);
    btf_free(dec);
    return r == BTF_OK ? 0 : fail("compare", &err);
}

static int thesis_error(const btf *src, const char *dir, btf_metrics *m)
{
    btf_thesis_pkg p;
    btf *dec = NULL;
    btf_error err = {0};
    if (btf_thesis_read(dir, &p, &err) != BTF_OK)
        return fail(dir, &err);
    btf_result r = btf_thesis_reconstruct(&p, &src->views, src->width, src->height, BTF_F32, &dec, &err);
    btf_thesis_free(&p);
    return r == BTF_OK ? lab_of(src, dec, m) : fail("thesis reconstruct", &err);
}

/* Longest chunk prefix of the package at dir within budget bytes (chunk files +
 * manifest), its bytes and its error against src. */
static int package_at_bytes(const btf *src, const char *dir, long long budget, int *n, long long *bytes,
                            btf_metrics *m)
{
    btf_package *p = NULL;
    btf_error err = {0};
    char man[1200];
    snprintf(man, sizeof man, "%s/manifest.json", dir);
    struct stat st;
    if (stat(man, &st) != 0 || btf_package_read(dir, 0, &p, &err) != BTF_OK)
        return fail(dir, &err);
    long long acc = st.st_size;
    *n = 0;
    while (*n < p->n_chunks && acc + p->chunk[*n].bytes <= budget)
        acc += p->chunk[(*n)++].bytes;
    *bytes = acc;
    btf *dec = NULL;
    btf_result r = *n > 0 ? btf_package_reconstruct(p, *n, &dec, &err) : BTF_ERR_RANGE;
    btf_package_free(p);
    if (r != BTF_OK)
        return fail("package prefix (does the first chunk fit?)", &err);
    return lab_of(src, dec, m);
}

static int equal_one(btf_gen_kind kind, int side)
{
    const char *mat = btf_gen_kind_name(kind);
    btf *src = NULL;
    if (gen(kind, side, &src))
        return 1;
    char dir[1100];
    btf_error err = {0};
    btf_metrics mt[2], mp[2];
    long long tbytes[2];
    for (int s = 0; s < 2; s++) {
        btf_export_options eo = {3, 8, s ? BTF_THESIS_SCALE_FIT : BTF_THESIS_SCALE_THESIS, 0};
        btf_export_stats es;
        snprintf(dir, sizeof dir, "%s/eq-%s-thesis-%d", g_tmp, mat, s);
        if (btf_export_thesis(src, &eo, dir, &es, &err) != BTF_OK)
            return fail("export-thesis", &err);
        tbytes[s] = es.bytes;
        if (thesis_error(src, dir, &mt[s]))
            return 1;
        const char *sn = btf_thesis_scale_name(eo.scale);
        printf("equal_%s_%d_thesis_%s_bytes %lld bytes\n", mat, side, sn, es.bytes);
        printf("equal_%s_%d_thesis_%s_rmse %.4f 0..255\n", mat, side, sn, mt[s].rmse);
        printf("equal_%s_%d_thesis_%s_lab %.4f CIELab\n", mat, side, sn, mt[s].lab_thesis);
    }
    for (int v = 0; v < 2; v++) { /* v = 0: full-range textures (earlier writer), 1: default */
        btf_pca_options po = {0};
        po.k = 3, po.components = 24;
        btf_package_options ko = {0};
        ko.tex_noise = v ? 0.0f : -1.0f;
        snprintf(dir, sizeof dir, "%s/eq-%s-pkg-%d", g_tmp, mat, v);
        if (btf_package_compress(src, &po, &ko, dir, NULL, &err) != BTF_OK)
            return fail("compress", &err);
        const char *vn = v ? "default" : "fullrange";
        for (int s = 0; s < 2; s++) {
            int n = 0;
            long long bytes = 0;
            if (package_at_bytes(src, dir, tbytes[s], &n, &bytes, &mp[v]))
                return 1;
            const char *sn = s ? "fit" : "thesis";
            printf("equal_%s_%d_pkg_%s_at_%s_bytes_chunks %d count\n", mat, side, vn, sn, n);
            printf("equal_%s_%d_pkg_%s_at_%s_bytes %lld bytes\n", mat, side, vn, sn, bytes);
            printf("equal_%s_%d_pkg_%s_at_%s_bytes_rmse %.4f 0..255\n", mat, side, vn, sn, mp[v].rmse);
            printf("equal_%s_%d_pkg_%s_at_%s_bytes_lab %.4f CIELab\n", mat, side, vn, sn, mp[v].lab_thesis);
            printf("equal_%s_%d_lab_ratio_pkg_%s_vs_thesis_%s %.3f ratio\n", mat, side, vn, sn,
                   mp[v].lab_thesis / mt[s].lab_thesis);
            fflush(stdout);
        }
    }
    btf_free(src);
    return 0;
}

static int stage_equal(void)
{
    int side = env_int("BENCH_EQ_SIDE", 128);
    return equal_one(BTF_GEN_KNIT, side) || equal_one(BTF_GEN_TILES, side);
}

int main(void)
{
    const char *root = getenv("BTF_SHARED"), *tmp = getenv("BENCH_TMP");
    snprintf(g_wool, sizeof g_wool, "%s/data/thesis-ubo2003/wool", root ? root : "../shared");
    snprintf(g_tmp, sizeof g_tmp, "%s", tmp ? tmp : "/tmp/btf-bench-compress");
    mkdir(g_tmp, 0755);
    struct stat st;
    const char *only = getenv("BENCH_ONLY"); /* full, sweep or equal: one part (for trials) */
    int have_wool = stat(g_wool, &st) == 0, rc = 0;
    if (!have_wool)
        fprintf(stderr, "bench: %s absent: full-size part and wool sweep skipped\n", g_wool);
    if (have_wool && (!only || !strcmp(only, "full"))) {
        fprintf(stderr, "bench: (a) full-size wool\n");
        rc |= run_stage("wool_jpeg_dir", stage_jpeg_dir);
        rc |= run_stage("full_loaded", stage_full_loaded);
        rc |= run_stage("full_images", stage_full_images);
        rc |= run_stage("svd", stage_svd);
    }
    if (!only || !strcmp(only, "sweep")) {
        fprintf(stderr, "bench: (b) sweep\n");
        rc |= run_stage("sweep", stage_sweep);
    }
    if (!only || !strcmp(only, "equal")) {
        fprintf(stderr, "bench: (c) equal bytes\n");
        rc |= run_stage("equal", stage_equal);
    }
    return rc ? 1 : 0;
}
