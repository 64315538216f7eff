/* bench_foundation.c - foundation numbers, printed as `name value unit` lines:
 *
 *   1. full-size load of the thesis wool (btf_import_thesis at 256x256, 81x81
 *      directions): wall time and peak resident memory;
 *   2. generator speed (btf_gen_create, knit) at 64x64 and 256x256, 81x81 directions;
 *   3. a full-size btf_compare (81x81 directions, 256x256 texels, U8).
 *
 * Each stage runs in a forked child so its peak RSS (wait4 ru_maxrss) is its own.
 * Environment: BTF_SHARED (data root, default ../shared), BENCH_GEN256_MAX_S
 * (default 300: if the 64x64 run predicts more for 256x256, the 256x256 run
 * renders 81 lights x one 45-degree ring of 18 views and extrapolates).
 * Run through bench/run.sh (make bench); progress and skips go to stderr.
 */
#include "btf.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_metrics.h"

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

#define BENCH_SIDE 256

/* Runs stage() in a child; prints NAME_peak_rss and NAME_stage_cpu after it.
 * Returns the child's exit status. */
static int run_stage(const char *name, int (*stage)(void))
{
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid < 0) {
        perror("bench: fork");
        return 1;
    }
    if (pid == 0) {
        int rc = stage();
        fflush(stdout);
        _exit(rc);
    }
    int status = 0;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) < 0) {
        perror("bench: wait4");
        return 1;
    }
    int rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (rc == 0) {
        printf("%s_peak_rss %.1f MiB\n", name, (double)ru.ru_maxrss / 1024.0);
        /* CPU time of the whole stage (setup included): wall times above are only
         * meaningful on an otherwise idle machine, this one also under load. */
        printf("%s_stage_cpu %.3f s\n", name,
               (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec +
                   1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec));
    }
    else
        fprintf(stderr, "bench: stage %s failed (status %d)\n", name, rc);
    return rc;
}

static void wool_path(char *buf, size_t n)
{
    const char *root = getenv("BTF_SHARED");
    snprintf(buf, n, "%s/data/thesis-ubo2003/wool", root ? root : "../shared");
}

static int have_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

/* ---------------------------------------------------------------- 1. thesis load */

static int stage_thesis_load(void)
{
    char dir[4096];
    wool_path(dir, sizeof dir);
    btf_load_options o = {0};
    o.width = o.height = BENCH_SIDE;
    btf *b = NULL;
    btf_error err = {0};
    double t0 = now_s(), c0 = cpu_s();
    btf_result r = btf_import_thesis(dir, &o, &b, &err);
    double t = now_s() - t0, c = cpu_s() - c0;
    if (r != BTF_OK) {
        fprintf(stderr, "bench: %s: %s\n", dir, err.msg);
        return 1;
    }
    printf("thesis_load_wool_%d_time %.3f s\n", BENCH_SIDE, t);
    printf("thesis_load_wool_%d_cpu %.3f s\n", BENCH_SIDE, c);
    printf("thesis_load_wool_%d_samples %zu count\n", BENCH_SIDE, b->count);
    printf("thesis_load_wool_%d_data %.1f MiB\n", BENCH_SIDE,
           (double)b->count * (b->storage == BTF_U8 ? 1.0 : 4.0) / 1048576.0);
    btf_free(b);
    return 0;
}

/* ---------------------------------------------------------------- 2. generator */

/* Wall seconds of one btf_gen_create (CPU seconds into *cpu); -1 on failure. */
static double gen_time(int side, const btf_dirset *lights, const btf_dirset *views, double *cpu)
{
    btf_gen_params p = btf_gen_defaults(BTF_GEN_KNIT);
    btf *b = NULL;
    btf_error err = {0};
    double t0 = now_s(), c0 = cpu_s();
    btf_result r = btf_gen_create(&p, side, side, lights, views, BTF_U8, &b, &err);
    double t = now_s() - t0;
    *cpu = cpu_s() - c0;
    btf_free(b);
    if (r != BTF_OK) {
        fprintf(stderr, "bench: btf_gen_create %dx%d: %s\n", side, side, err.msg);
        return -1.0;
    }
    return t;
}

static void print_gen(int side, double t, double cpu, const char *how)
{
    double pix = (double)side * side * 81.0 * 81.0;
    printf("gen_knit_%d_time%s %.3f s\n", side, how, t);
    printf("gen_knit_%d_cpu%s %.3f s\n", side, how, cpu);
    printf("gen_knit_%d_rate%s %.2f Mpixel/s\n", side, how, pix / t * 1e-6);
}

static int stage_gen64(void)
{
    btf_dirset d = btf_dirset_ubo2003();
    double cpu, t = gen_time(64, &d, &d, &cpu);
    if (t < 0)
        return 1;
    print_gen(64, t, cpu, "");
    return 0;
}

static int stage_gen256(void)
{
    btf_dirset d = btf_dirset_ubo2003();
    const char *lim = getenv("BENCH_GEN256_MAX_S");
    double max_s = lim ? atof(lim) : 300.0;
    double cpu, t64 = gen_time(64, &d, &d, &cpu);
    if (t64 < 0)
        return 1;
    if (t64 * 16.0 <= max_s) {
        double t = gen_time(BENCH_SIDE, &d, &d, &cpu);
        if (t < 0)
            return 1;
        print_gen(BENCH_SIDE, t, cpu, "");
        return 0;
    }
    fprintf(stderr, "bench: 256x256 generation predicted %.0f s > %.0f s: one view ring, extrapolated\n",
            t64 * 16.0, max_s);
    btf_ring ring = {45.0f, 18, 0.0f};
    btf_dirset views;
    if (btf_dirset_make(&ring, 1, &views, NULL) != BTF_OK)
        return 1;
    double t = gen_time(BENCH_SIDE, &d, &views, &cpu);
    if (t < 0)
        return 1;
    print_gen(BENCH_SIDE, t * 81.0 / 18.0, cpu * 81.0 / 18.0, "_extrapolated");
    return 0;
}

/* ---------------------------------------------------------------- 3. compare */

/* Reference for the compare: the wool if present, else deterministic noise. */
static btf *compare_source(void)
{
    char dir[4096];
    wool_path(dir, sizeof dir);
    btf *b = NULL;
    btf_error err = {0};
    btf_load_options o = {0};
    o.width = o.height = BENCH_SIDE;
    o.storage = BTF_U8;
    if (have_dir(dir) && btf_import_thesis(dir, &o, &b, &err) == BTF_OK && b->storage == BTF_U8) {
        printf("compare_source_wool 1 flag\n");
        return b;
    }
    btf_free(b);
    b = NULL;
    btf_dirset d = btf_dirset_ubo2003();
    if (btf_create(BENCH_SIDE, BENCH_SIDE, &d, &d, BTF_U8, &b, &err) != BTF_OK) {
        fprintf(stderr, "bench: %s\n", err.msg);
        return NULL;
    }
    uint8_t *p = b->data;
    uint32_t s = 1;
    for (size_t i = 0; i < b->count; i++) {
        s = s * 1664525u + 1013904223u;
        p[i] = (uint8_t)(s >> 24);
    }
    printf("compare_source_wool 0 flag\n");
    return b;
}

static int stage_compare(void)
{
    btf *a = compare_source(), *b = NULL;
    btf_error err = {0};
    if (!a || btf_create(a->width, a->height, &a->lights, &a->views, BTF_U8, &b, &err) != BTF_OK) {
        fprintf(stderr, "bench: compare setup: %s\n", err.msg);
        btf_free(a);
        return 1;
    }
    const uint8_t *pa = a->data; /* test = reference + noise in -7..7, clamped */
    uint8_t *pb = b->data;
    uint32_t s = 2;
    for (size_t i = 0; i < a->count; i++) {
        s = s * 1664525u + 1013904223u;
        int v = pa[i] + (int)((s >> 20) % 15u) - 7;
        pb[i] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
    }
    btf_metrics m;
    double t0 = now_s(), c0 = cpu_s();
    btf_result r = btf_compare(a, b, NULL, &m, &err);
    double t = now_s() - t0, c = cpu_s() - c0;
    if (r == BTF_OK) {
        printf("compare_full_time %.3f s\n", t);
        printf("compare_full_cpu %.3f s\n", c);
        printf("compare_full_rate %.1f Mpixel/s\n", (double)m.pixels / t * 1e-6);
        printf("compare_full_pixels %zu count\n", m.pixels);
        printf("compare_full_rgb_mae %.4f 0..255\n", m.mae);
        printf("compare_full_lab_mae %.4f CIELab\n", m.lab_thesis);
        printf("compare_full_delta_e76 %.4f CIELab\n", m.delta_e76);
    } else {
        fprintf(stderr, "bench: btf_compare: %s\n", err.msg);
    }
    btf_free(a);
    btf_free(b);
    return r == BTF_OK ? 0 : 1;
}

int main(void)
{
    char dir[4096];
    wool_path(dir, sizeof dir);
    printf("cpus %ld count\n", sysconf(_SC_NPROCESSORS_ONLN));
    int failed = 0;
    if (have_dir(dir))
        failed |= run_stage("thesis_load_wool", stage_thesis_load);
    else
        fprintf(stderr, "bench: %s absent: thesis load skipped\n", dir);
    failed |= run_stage("gen_knit_64", stage_gen64);
    failed |= run_stage("gen_knit_256", stage_gen256);
    failed |= run_stage("compare_full", stage_compare);
    return failed ? 1 : 0;
}
