/* fuzz_package.c - libFuzzer target for the package reader's files on disk
 * (btf_package_read, codec/decompress/btf_package_read.c). Small valid packages
 * (v1, v2, v4, v3 with lossy WebP textures, va with AVIF ones) are made once (fuzz_pkg.h); each input replaces one of their files
 * in the directory (first byte: fuzz_package_file), with PNG checksums repaired so
 * mutations reach the decoder. An accepted package must decode to finite values;
 * the original file is put back after. fuzz_package_mem.c: the same without the disk. */
#include "fuzz_pkg.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const fuzz_pkgs *pk = fuzz_packages();
    int v;
    const char *name = fuzz_package_file(pk, data[0], &v);
    const char *dir = v == 5 ? pk->va : v == 4 ? pk->v4 : v == 3 ? pk->v3 : v == 2 ? pk->v2 : pk->v1;
    char path[4096], *orig = NULL;
    size_t n = 0;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (btf_fs_read(path, (size_t)1 << 24, &orig, &n, NULL) != BTF_OK)
        abort();
    fuzz_write_file(dir, name, data + 1, size - 1);
    fuzz_package_check(dir, NULL);
    fuzz_write(path, orig, n); /* the next input starts from the valid package again */
    free(orig);
    return 0;
}
