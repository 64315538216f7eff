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

/* Removes path and, for a directory, everything under it (no symlinks followed).
 * 0 on success or when path does not exist, -1 otherwise. */
static inline int test_rmtree(const char *path)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT ? 0 : -1;
    if (!S_ISDIR(st.st_mode))
        return unlink(path);
    DIR *d = opendir(path);
    if (!d)
        return -1;
    int rc = 0;
    struct dirent *e;
    char child[4096];
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
            int n = snprintf(child, sizeof child, "%s/%s", path, e->d_name);
            if (n < 0 || (size_t)n >= sizeof child || test_rmtree(child) != 0)
                rc = -1;
        }
    closedir(d);
    return rmdir(path) == 0 ? rc : -1;
}

#endif
