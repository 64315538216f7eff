/* btf_thesis.h - the 2015 thesis's published package format (doc/input-formats.md section 3).
 *
 *     btf_thesis_pkg p = {0};
 *     btf_error err;
 *     if (btf_thesis_read("data/wool", &p, &err) != BTF_OK) puts(err.msg);
 *     float rgb[3];
 *     btf_thesis_decode_pixel(&p, view, light, x, y, rgb);   // unclamped
 *     btf_thesis_free(&p);
 *
 * A package is a directory: meta.json (all values strings), j.png for the
 * C components (j = 0..C-1) and R.png (weights V and singular values sigma).
 * The in-memory form below holds the dequantised values exactly as the
 * reconstruction formula uses them:
 *
 *     I[view][light][y][x][c] = sum_j L[b][y][x][j] * sigma[b][j] * V[view][light][c][j],
 *     b = view / k.
 *
 * Writing a package (btf_thesis_write) from your own PCA: allocate with
 * btf_thesis_alloc, fill L with the block mean in component 0 and the U columns
 * scaled so |L| <= 1 (the thesis scales U by 10) in components 1..C-1, sigma with
 * the singular values divided by that same scale (sigma[b][0] = 1), V with the
 * right singular vectors (|V| <= 1, V[..][0] = 1). The writer quantises every L and
 * V value to a byte as round((v + 1) * 255 / 2) (values outside [-1, 1] are an
 * error) and sigma to 0.1 steps as two "digit pairs" hi, lo (sigma = 10*hi + 0.1*lo,
 * lo <= 99), so sigma must lie in [0, 2559.9].
 *
 * Generalisation: the thesis uses C a multiple of 4. Here any C >= 1 is accepted;
 * R.png then holds ceil(C/4) pixels per (view, light, colour) and ceil(C/2) sigma
 * pixels per block, unused channels zero. For C % 4 == 0 this is exactly the
 * thesis layout.
 *
 * Not done here: no PCA (see the compressor), no colour conversion, no clamping
 * (the decoded values are the format's own; about 1% lie outside [0, 1]).
 */
#ifndef BTF_THESIS_H
#define BTF_THESIS_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Limits accepted when reading meta.json (guards allocations). */
#define BTF_THESIS_MAX_C 256
#define BTF_THESIS_MAX_S 8192

/* One package in memory. Filled by btf_thesis_read or btf_thesis_alloc, owned by
 * the caller (usually on the stack), released with btf_thesis_free; the arrays
 * live until then. */
typedef struct btf_thesis_pkg {
    int C;        /* components, including the mean as component 0 (numComp) */
    int N;        /* light directions = view directions (numDirections) */
    int k;        /* views per block (blockSize) */
    int S;        /* texture side in texels, even (imageSize) */
    int nb;       /* blocks = ceil(N / k); views are padded to nb*k slots */
    int r_size;   /* side of R.png (RSize); 0 on write = smallest power of two that fits */
    int tex_size; /* texSize from meta.json (client atlas side); 0 on write = computed */
    float *L;     /* nb*S*S*C: L[((b*S + y)*S + x)*C + j], component j of texel (x, y), block b */
    float *V;     /* nb*k*N*3*C: V[((slot*N + light)*3 + c)*C + j], slot = view (0..nb*k-1) */
    float *sigma; /* nb*C: sigma[b*C + j] */
} btf_thesis_pkg;

/* Fills p's sizes and allocates zeroed L, V, sigma (nb computed from N and k). */
btf_result btf_thesis_alloc(int C, int N, int k, int S, btf_thesis_pkg *p, btf_error *err);
/* Frees the arrays and zeroes p; accepts NULL and a zeroed struct. */
void btf_thesis_free(btf_thesis_pkg *p);

/* Reads and validates a package directory (meta.json numbers, PNG sizes). */
btf_result btf_thesis_read(const char *dir, btf_thesis_pkg *p, btf_error *err);
/* The same with every file read through files (btf.h; NULL: the disk), e.g. a package
 * held in memory (btf_fs_mem_files): dir only names the files, "DIR/meta.json", ... */
btf_result btf_thesis_read_with(const char *dir, const btf_files *files, btf_thesis_pkg *p, btf_error *err);

/* Writes p into dir (created; its parent must exist; an existing dir is replaced)
 * through a temporary sibling directory renamed into place. */
btf_result btf_thesis_write(const char *dir, const btf_thesis_pkg *p, btf_error *err);
/* 1 when dir holds a thesis package and nothing else (meta.json, R.png, N.png):
 * one this writer may replace. ctx unused (a btf_fs_owned_fn, codec/common/btf_fs.h). */
int btf_thesis_owns_dir(const char *dir, void *ctx);

/* Decodes one unclamped RGB value (view, light < N; x, y < S) by the formula above. */
void btf_thesis_decode_pixel(const btf_thesis_pkg *p, int view, int light, int x, int y, float rgb[3]);

/* Decodes one full (view, light) image, S*S*3 floats, unclamped, [y][x][c]. */
void btf_thesis_decode_image(const btf_thesis_pkg *p, int view, int light, float *out);

/* Reconstructs the BTF from a package in memory: the same as btf_import_thesis
 * after btf_thesis_read (dirs: NULL = chosen from N, UBO2003 for 81, dome for 151). */
btf_result btf_thesis_reconstruct(const btf_thesis_pkg *p, const btf_dirset *dirs, int width, int height,
                                  btf_storage storage, btf **out, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
