/* fuzz_package_mem.c - libFuzzer target for the package reader without the disk
 * (btf_package_read_with over a btf_fs_mem, codec/decompress/btf_package_read.c):
 * fuzz_package.c's packages, inputs (first byte: which file, the rest its bytes,
 * PNG checksums repaired) and contracts, the packages held in memory (loaded once)
 * and every file read through btf_files, so an input costs no file system call. */
#include "fuzz_pkg.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The packages v1, v2, v4, v3, va in memory, loaded on the first input. */
static fuzz_mem *fuzz_mem_packages(void)
{
    static fuzz_mem m[5];
    static int loaded;
    if (!loaded) {
        const fuzz_pkgs *pk = fuzz_packages();
        fuzz_mem_load(pk->v1, &m[0]), fuzz_mem_load(pk->v2, &m[1]), fuzz_mem_load(pk->v4, &m[2]);
        fuzz_mem_load(pk->v3, &m[3]), fuzz_mem_load(pk->va, &m[4]);
        loaded = 1;
    }
    return m;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    fuzz_mem *m = fuzz_mem_packages();
    int v;
    const char *name = fuzz_package_file(fuzz_packages(), data[0], &v);
    static const int slot[6] = {0, 0, 1, 3, 2, 4}; /* by v: v1, v2, v3, v4, va */
    static const char *const dir[6] = {"mem/v1", "mem/v1", "mem/v2", "mem/v3", "mem/v4", "mem/va"};
    fuzz_mem *pkg = &m[slot[v]];
    fuzz_swap s = fuzz_mem_put(pkg, name, data + 1, size - 1);
    fuzz_package_check(dir[v], &pkg->files);
    fuzz_mem_restore(&s);
    return 0;
}
