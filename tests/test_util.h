/* test_util.h - small helpers shared by the Criterion tests (header only). */
#ifndef BTF_TEST_UTIL_H
#define BTF_TEST_UTIL_H

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_fs.h"

/* Path under ../shared (BTF_SHARED, exported by the Makefile) into buf; 1 if it exists. */
static inline int test_shared_path(char *buf, size_t n, const char *rel)
{
    const char *root = getenv("BTF_SHARED");
    snprintf(buf, n, "%s/%s", root ? root : "../shared", rel);
    struct stat st;
    return stat(buf, &st) == 0;
}

/* Fresh empty temporary directory (mkdtemp) into buf; 1 on success. */
static inline int test_tmpdir(char *buf, size_t n)
{
    snprintf(buf, n, "/tmp/btftest-XXXXXX");
    return mkdtemp(buf) != NULL;
}

/* Entries of dir whose names do not start with '.'; 0 when dir cannot be opened. */
static inline int test_count_files(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += e->d_name[0] != '.';
    if (d)
        closedir(d);
    return n;
}

/* 1 if dir_a/name and dir_b/name both exist and hold the same bytes. */
static inline int test_same_file(const char *dir_a, const char *dir_b, const char *name)
{
    char pa[1024], pb[1024];
    snprintf(pa, sizeof pa, "%s/%s", dir_a, name);
    snprintf(pb, sizeof pb, "%s/%s", dir_b, name);
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    int same = fa && fb;
    for (int ca = 0; same && ca != EOF;) {
        ca = fgetc(fa);
        same = ca == fgetc(fb);
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

/* Removes path and, for a directory, everything under it (no symlinks followed).
 * 0 on success or when path does not exist, -1 otherwise. */
static inline int test_rmtree(const char *path)
{
    return btf_fs_rmtree(path, NULL) == BTF_OK ? 0 : -1;
}

#endif
