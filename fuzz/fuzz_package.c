/* fuzz_package.c - libFuzzer target for the package reader's files
 * (btf_package_read, codec/decompress/btf_package_read.c). A small valid package is made
 * once; each input replaces one of its files (first byte: 0 texture PNG, 1
 * weights .bin, 2 manifest.json, 3 an 8-bit weights PNG of a version-2 package,
 * 4 the manifest and 5 a residual level of a version-4 package: a lossless WebP,
 * as the writer keeps it where smaller, or a PNG), with PNG checksums repaired so mutations reach the decoder. An accepted
 * package must decode to finite values; the original file is put back after. */
#include <math.h>

#include "btf_fs.h"
#include "btf_gen.h"
#include "btf_lod.h"
#include "btf_package.h"
#include "fuzz_util.h"
#include "btf_decode.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The packages (v1, v2, v4) every input starts from; made once per process. */
typedef struct fuzz_pkgs {
    char v1[300], v2[300], v4[300];
    char residual[64]; /* v4's residual level file, or "manifest.json" when the writer kept none */
} fuzz_pkgs;

static const fuzz_pkgs *fuzz_packages(void)
{
    static fuzz_pkgs p;
    if (p.v1[0])
        return &p;
    btf_ring r[2] = {{0.0f, 1, 0.0f}, {45.0f, 4, 0.0f}};
    btf_dirset d;
    btf_error err = {{0}};
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_TILES);
    btf *b = NULL;
    snprintf(p.v1, sizeof p.v1, "%s/v1", fuzz_dir());
    snprintf(p.v2, sizeof p.v2, "%s/v2", fuzz_dir());
    snprintf(p.v4, sizeof p.v4, "%s/v4", fuzz_dir());
    btf_pca_options po = {0};
    po.k = 2, po.components = 2;
    btf_lod_options lo = {0};
    lo.levels = 2;
    if (btf_dirset_make(r, 2, &d, &err) != BTF_OK || btf_gen_create(&gp, 16, 16, &d, &d, BTF_U8, &b, &err) != BTF_OK ||
        btf_package_compress(b, &po, NULL, p.v1, NULL, &err) != BTF_OK ||
        btf_lod_build(p.v1, p.v2, &lo, NULL, &err) != BTF_OK) {
        fprintf(stderr, "fuzz_package: setup failed: %s\n", err.msg);
        abort();
    }
    lo.residual = 1;
    if (btf_lod_build(p.v1, p.v4, &lo, NULL, &err) != BTF_OK) {
        fprintf(stderr, "fuzz_package: setup failed: %s\n", err.msg);
        abort();
    }
    btf_free(b);
    snprintf(p.residual, sizeof p.residual, "manifest.json");
    char path[400];
    for (int j = 0; j < 4 && !strcmp(p.residual, "manifest.json"); j++) {
        const char *ext = j < 2 ? "webp" : "png"; /* a lossless WebP where the writer found it smaller */
        snprintf(path, sizeof path, "%s/tex-%02d-d0.%s", p.v4, j % 2, ext);
        if (btf_fs_size(path) > 0)
            snprintf(p.residual, sizeof p.residual, "tex-%02d-d0.%s", j % 2, ext);
    }
    return &p;
}

/* Reads dir and checks what an accepted package promises. */
static void check_read(const char *dir)
{
    btf_package *p = NULL;
    btf_error err = {{0}};
    if (btf_package_read(dir, -1, &p, &err) != BTF_OK) {
        FUZZ_CHECK(p == NULL && err.msg[0] != 0 && !strchr(err.msg, '\n'));
        return;
    }
    btf_decode_options o = {0};
    float l[3] = {0.1f, 0.2f, 1.0f}, v[3] = {-0.3f, 0.1f, 1.0f}, rgb[3];
    btf_decode(p, 0.4f, 0.7f, l, v, &o, rgb);
    FUZZ_CHECK(isfinite(rgb[0]) && isfinite(rgb[1]) && isfinite(rgb[2]));
    btf_package_free(p);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const fuzz_pkgs *pk = fuzz_packages();
    const char *names[6] = {"tex-00.png", "wt-00.bin", "manifest.json", "wt-00-8.png", "manifest.json", pk->residual};
    int which = data[0] % 6;
    const char *dir = which >= 4 ? pk->v4 : which == 3 ? pk->v2 : pk->v1;
    char path[1024], *orig = NULL;
    size_t n = 0;
    snprintf(path, sizeof path, "%s/%s", dir, names[which]);
    if (btf_fs_read(path, (size_t)1 << 24, &orig, &n, NULL) != BTF_OK)
        abort();
    fuzz_write_file(dir, names[which], data + 1, size - 1);
    check_read(dir);
    fuzz_write(path, orig, n); /* the next input starts from the valid package again */
    free(orig);
    return 0;
}
