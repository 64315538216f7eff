/* fuzz_util.h - shared pieces of the codec fuzz targets (header only): a scratch
 * directory per process, whole-file writes, and PNG checksum repair so mutated
 * PNGs reach the decoder instead of stopping at a CRC mismatch. */
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

/* Writes data to dir/name, repairing PNG checksums first. */
static inline void fuzz_write_file(const char *dir, const char *name, const uint8_t *data, size_t n)
{
    char path[1024];
    uint8_t *copy = malloc(n + 1);
    if (!copy)
        abort();
    memcpy(copy, data, n);
    fuzz_fix_png_crcs(copy, n);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    fuzz_write(path, copy, n);
    free(copy);
}

#endif
