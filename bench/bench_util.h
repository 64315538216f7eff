/* bench_util.h - clocks and start-up shared by the benchmark programs (header only). */
#ifndef BENCH_UTIL_H
#define BENCH_UTIL_H

#include "btf_fs.h"
#include "btf_package.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

/* Monotonic wall clock in seconds. */
static inline double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* CPU seconds (user + system, all threads) of this process so far: comparable
 * when other work shares the machine, unlike wall times. */
static inline double cpu_s(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

/* The start of a bench that runs `btf`: $BUILD/btf (BUILD default "build") into btf
 * (600 bytes) and a new directory "/tmp/bench_NAME.XXXXXX" into tmp (64 bytes); 0, with
 * a message on stderr, when btf is missing or the directory cannot be made. */
static inline int bench_btf_and_tmp(const char *name, char btf[600], char tmp[64])
{
    const char *build = getenv("BUILD") ? getenv("BUILD") : "build";
    snprintf(btf, 600, "%s/btf", build);
    snprintf(tmp, 64, "/tmp/bench_%s.XXXXXX", name);
    if (access(btf, X_OK) == 0 && mkdtemp(tmp))
        return 1;
    fprintf(stderr, "bench_%s: %s is missing (run 'make build') or no temporary directory\n", name, btf);
    return 0;
}

/* A package's bytes as a page fetches them: its manifest (in dir) and every chunk's
 * files (p read from dir). */
static inline long long bench_package_bytes(const char *dir, const btf_package *p)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    long long n = btf_fs_size(path);
    for (int i = 0; i < p->n_chunks; i++)
        n += p->chunk[i].bytes;
    return n;
}

/* x rounded to a half float's 11 significant bits (a network's parameters as a page
 * would receive them; the range they use, no overflow handling). */
static inline float bench_half_round(float x)
{
    int e;
    float m = frexpf(x, &e);
    return ldexpf(rintf(ldexpf(m, 11)), e - 11);
}

/* The small nonlinear decoder's direction inputs (bench_nn.c, and the shader bench's
 * network): l.xy, v.xy and the half vector's x, y, from the unit light l and view v. */
static inline void bench_nn_features(const float l[3], const float v[3], float f[6])
{
    float h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    float n = sqrtf(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    f[0] = l[0], f[1] = l[1], f[2] = v[0], f[3] = v[1];
    f[4] = n > 0 ? h[0] / n : 0, f[5] = n > 0 ? h[1] / n : 0;
}

#endif
