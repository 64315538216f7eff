/* fuzz_util.h - shared pieces of the codec fuzz targets (header only): a scratch
 * directory per process, whole-file writes, PNG checksum repair so mutated PNGs
 * reach the decoder instead of stopping at a CRC mismatch, and a directory held in
 * memory for the in-memory targets (fuzz_mem: a reader's btf_files). */
#ifndef BTF_FUZZ_UTIL_H
#define BTF_FUZZ_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "btf.h"
#include "btf_fs.h"

/* A contract breach: abort, so libFuzzer and the replay both report it. */
#define FUZZ_CHECK(cond)                                                                   \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            fprintf(stderr, "fuzz: contract broken: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
            abort();                                                                       \
        }                                                                                  \
    } while (0)

static char fuzz__dir[256];

static void fuzz__remove_dir(void)
{
    btf_fs_rmtree(fuzz__dir, NULL);
}

/* This process's scratch directory ($TMPDIR or /tmp), made on first use; removed at exit. */
static inline const char *fuzz_dir(void)
{
    char *dir = fuzz__dir;
    if (!dir[0]) {
        const char *t = getenv("TMPDIR");
        snprintf(dir, sizeof fuzz__dir, "%s/btf-fuzz-XXXXXX", t && *t ? t : "/tmp");
        if (!mkdtemp(dir))
            abort();
        if (!getenv("FUZZ_KEEP_DIR")) /* set it to keep the scratch files (seed making) */
            atexit(fuzz__remove_dir);
    }
    return dir;
}

/* Writes n bytes to path (truncating); aborts on failure (the harness, not the target, broke). */
static inline void fuzz_write(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f || (n && fwrite(data, 1, n, f) != n) || fclose(f) != 0)
        abort();
}

/* Rewrites the CRC of every complete chunk of a PNG in place (length, type, data, crc). */
static inline void fuzz_fix_png_crcs(uint8_t *p, size_t n)
{
    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (n < 8 || memcmp(p, sig, 8) != 0)
        return;
    for (size_t at = 8; at + 12 <= n;) {
        uint32_t len = (uint32_t)p[at] << 24 | (uint32_t)p[at + 1] << 16 | (uint32_t)p[at + 2] << 8 | p[at + 3];
        if (len > n - at - 12)
            return;
        uint32_t crc = (uint32_t)crc32(0L, p + at + 4, (uInt)(len + 4));
        uint8_t *c = p + at + 8 + len;
        c[0] = (uint8_t)(crc >> 24), c[1] = (uint8_t)(crc >> 16), c[2] = (uint8_t)(crc >> 8), c[3] = (uint8_t)crc;
        at += 12 + (size_t)len;
    }
}

/* A copy of n bytes (malloc'd, the caller frees it) with PNG checksums repaired. */
static inline uint8_t *fuzz_png_copy(const uint8_t *data, size_t n)
{
    uint8_t *copy = malloc(n + 1);
    if (!copy)
        abort();
    if (n)
        memcpy(copy, data, n);
    fuzz_fix_png_crcs(copy, n);
    return copy;
}

/* Writes data to dir/name, repairing PNG checksums first. */
static inline void fuzz_write_file(const char *dir, const char *name, const uint8_t *data, size_t n)
{
    char path[4096];
    uint8_t *copy = fuzz_png_copy(data, n);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    fuzz_write(path, copy, n);
    free(copy);
}

/* ---------------------------------------------------------------- a directory in memory */

#define FUZZ_MEM_FILES 64

/* A directory's files held in memory and served to a reader as a btf_files
 * (btf_fs_mem_files). One per package, static, loaded once: the names and bytes
 * (malloc'd) live for the process. */
typedef struct fuzz_mem {
    const char *dir; /* the directory it was loaded from (while loading) */
    btf_fs_mem_file file[FUZZ_MEM_FILES];
    btf_fs_mem mem;
    btf_files files;
} fuzz_mem;

/* btf_fs_all_entries callback: a regular file of the directory into the fuzz_mem ctx. */
static inline int fuzz__mem_add(const char *name, const struct stat *st, void *ctx)
{
    fuzz_mem *m = ctx;
    char path[1024], *data = NULL;
    size_t n = 0;
    if (!S_ISREG(st->st_mode))
        return 1;
    snprintf(path, sizeof path, "%s/%s", m->dir, name);
    if (m->mem.n >= FUZZ_MEM_FILES || btf_fs_read(path, (size_t)1 << 24, &data, &n, NULL) != BTF_OK)
        abort();
    btf_fs_mem_file f = {strdup(name), data, n};
    m->file[m->mem.n++] = f;
    return 1;
}

/* Loads every file of dir into m (once; aborts when it cannot). */
static inline void fuzz_mem_load(const char *dir, fuzz_mem *m)
{
    memset(m, 0, sizeof *m);
    m->dir = dir;
    m->mem.file = m->file;
    if (!btf_fs_all_entries(dir, fuzz__mem_add, m))
        abort();
    m->files = btf_fs_mem_files(&m->mem);
}

/* One input's bytes standing in for one file of a fuzz_mem; a stack value of one input. */
typedef struct fuzz_swap {
    btf_fs_mem_file *at, keep;
    uint8_t *copy; /* the input's bytes, PNG checksums repaired (malloc'd) */
} fuzz_swap;

/* Puts the n bytes of data (PNG checksums repaired) in place of m's file name. */
static inline fuzz_swap fuzz_mem_put(fuzz_mem *m, const char *name, const uint8_t *data, size_t n)
{
    fuzz_swap s = {NULL, {NULL, NULL, 0}, NULL};
    for (int i = 0; i < m->mem.n && !s.at; i++)
        if (!strcmp(m->file[i].name, name))
            s.at = &m->file[i];
    if (!s.at)
        abort();
    s.keep = *s.at;
    s.copy = fuzz_png_copy(data, n);
    s.at->data = s.copy, s.at->size = n;
    return s;
}

/* Puts the original file back. */
static inline void fuzz_mem_restore(fuzz_swap *s)
{
    *s->at = s->keep;
    free(s->copy);
}

#endif
