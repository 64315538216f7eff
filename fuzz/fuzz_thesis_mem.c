/* fuzz_thesis_mem.c - libFuzzer target for the thesis package reader without the
 * disk (btf_thesis_read_with over a btf_fs_mem, codec/input/btf_thesis.c):
 * fuzz_thesis.c's package, inputs (first byte: which file, the rest its bytes, PNG
 * checksums repaired) and contracts, the package held in memory (loaded once). */
#include "fuzz_pkg.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static fuzz_mem m;
    if (size < 1)
        return 0;
    if (!m.mem.n)
        fuzz_mem_load(fuzz_thesis_dir(), &m);
    fuzz_swap s = fuzz_mem_put(&m, fuzz_thesis_file(data[0]), data + 1, size - 1);
    fuzz_thesis_check("mem/thesis", &m.files);
    fuzz_mem_restore(&s);
    return 0;
}
