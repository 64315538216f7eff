/* fuzz_thesis.c - libFuzzer target for the thesis package reader on disk
 * (btf_thesis_read, codec/input/btf_thesis.c). A small valid package is written
 * once (fuzz_pkg.h); each input replaces one of its files in the directory (first
 * byte: 0 meta.json, 1 R.png, 2 0.png), PNG checksums repaired. Accepted packages
 * must reconstruct to finite values. fuzz_thesis_mem.c: the same without the disk. */
#include "fuzz_pkg.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const char *dir = fuzz_thesis_dir(), *name = fuzz_thesis_file(data[0]);
    char path[1024], *orig = NULL;
    size_t n = 0;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (btf_fs_read(path, (size_t)1 << 24, &orig, &n, NULL) != BTF_OK)
        abort();
    fuzz_write_file(dir, name, data + 1, size - 1);
    fuzz_thesis_check(dir, NULL);
    fuzz_write(path, orig, n);
    free(orig);
    return 0;
}
