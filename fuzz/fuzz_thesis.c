/* fuzz_thesis.c - libFuzzer target for the thesis package reader (btf_thesis_read,
 * codec/input/btf_thesis.c). A small valid package is written once; each input
 * replaces one of its files (first byte: 0 meta.json, 1 R.png, 2 0.png), PNG
 * checksums repaired. Accepted packages must stay in range and reconstruct. */
#include <math.h>

#include "btf_fs.h"
#include "btf_thesis.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *fuzz_thesis_dir(void)
{
    static char dir[300];
    if (dir[0])
        return dir;
    snprintf(dir, sizeof dir, "%s/thesis", fuzz_dir());
    btf_thesis_pkg p;
    btf_error err = {{0}};
    if (btf_thesis_alloc(2, 7, 7, 4, &p, &err) != BTF_OK)
        abort();
    for (size_t i = 0; i < (size_t)p.nb * p.S * p.S * p.C; i++)
        p.L[i] = (float)((i * 37) % 200) / 100.0f - 1.0f;
    for (size_t i = 0; i < (size_t)p.nb * p.k * p.N * 3 * p.C; i++)
        p.V[i] = (float)((i * 53) % 200) / 100.0f - 1.0f;
    for (int i = 0; i < p.nb * p.C; i++)
        p.sigma[i] = 1.0f + (float)i;
    if (btf_thesis_write(dir, &p, &err) != BTF_OK) {
        fprintf(stderr, "fuzz_thesis: setup failed: %s\n", err.msg);
        abort();
    }
    btf_thesis_free(&p);
    return dir;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const char *dir = fuzz_thesis_dir();
    static const char *names[3] = {"meta.json", "R.png", "0.png"};
    int which = data[0] % 3;
    char path[1024], *orig = NULL;
    size_t n = 0;
    snprintf(path, sizeof path, "%s/%s", dir, names[which]);
    if (btf_fs_read(path, (size_t)1 << 24, &orig, &n, NULL) != BTF_OK)
        abort();
    fuzz_write_file(dir, names[which], data + 1, size - 1);
    btf_thesis_pkg p;
    btf_error err = {{0}};
    if (btf_thesis_read(dir, &p, &err) == BTF_OK) {
        btf_dirset d;
        btf_ring r[2] = {{0.0f, 1, 0.0f}, {45.0f, 6, 0.0f}};
        btf *b = NULL;
        if (p.N == 7 && btf_dirset_make(r, 2, &d, NULL) == BTF_OK &&
            btf_thesis_reconstruct(&p, &d, 0, 0, BTF_F32, &b, &err) == BTF_OK) {
            const float *f = b->data;
            FUZZ_CHECK(isfinite(f[0]));
            btf_free(b);
        }
        btf_thesis_free(&p);
    } else {
        FUZZ_CHECK(err.msg[0] != 0 && !strchr(err.msg, '\n'));
    }
    fuzz_write(path, orig, n);
    free(orig);
    return 0;
}
