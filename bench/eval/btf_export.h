/* btf_export.h - export of a BTF into the thesis's package format (doc/input-formats.md
 * section 3), the baseline the project's own package is compared with.
 *
 *     btf_export_options o = {0};  o.k = 3; o.components = 8;   // zero = 3, 8, thesis scaling
 *     btf_export_stats st;
 *     if (btf_export_thesis(src, &o, "out/wool-thesis", &st, &err) != BTF_OK) puts(err.msg);
 *     // read back: btf_thesis_read / btf_import_thesis (codec/input/btf_thesis.h, btf_io.h)
 *
 * Model: the project's k-view block PCA (codec/include/btf_pca.h) in the thesis's layout:
 * k consecutive views per block (block b = views k*b .. k*b+k-1, the last block
 * padded to k view slots with zero weights), component 0 = the texel's mean over
 * the block (L0 = mean, sigma0 = 1, V0 = 1), components 1..C-1 = the top C-1
 * principal components of the row-centred block. A component with left singular
 * vector U (unit), singular value s and right singular vector V (unit) is stored as
 *
 *     L = a*U,  V' = c*V,  sigma' = s / (a*c)      (so L * sigma' * V' = s*U*V)
 *
 * with per-(block, component) scales a, c >= 0 chosen by `scale`:
 * - BTF_THESIS_SCALE_THESIS (default): what the published files do: a = 10
 *   (U scaled by 10), c = 1; a is lowered to 1/max|U| where 10*U would leave
 *   [-1, 1] (small textures), and c raised up to 1/max|V| where sigma' would
 *   exceed the format's 2559.9.
 * - BTF_THESIS_SCALE_FIT: the best the format allows: a <= 1/max|U|, c <= 1/max|V|
 *   on a grid of quarter octaves, minimising the predicted squared quantisation
 *   error  s^2 h^2/3 (rows/a^2 + cols/c^2) + (a c (sigma'q - sigma'))^2  (h = 1/255,
 *   sigma'q = sigma' rounded to 0.1). A stronger baseline than the thesis's own.
 *
 * Quantisation bound (what a reader of the written package decodes): every L and V
 * byte is within h = 1/255 of the exported float, every sigma within s = 0.05, so
 * at any sample the thesis decoder's value differs from the float PCA
 * reconstruction sum_j L_j sigma_j V_j by at most
 *     sum_j (|L_j| + h)(sigma_j + s)(|V_j| + h) - |L_j| sigma_j |V_j|
 * (btf_export_thesis_bound), plus float rounding.
 *
 * Requirements: lights and views the same direction set (the format has one N), a
 * square texture of even side, 1 <= k <= N, 1 <= C <= the smallest block's rank
 * limit and <= BTF_THESIS_MAX_C, finite data with block means in [0, 1].
 * Not done here: the project's own package (btf_package.h); sampling other than
 * what btf_thesis_reconstruct infers from N (81 = UBO2003, 151 = dome) must be
 * passed to the reader.
 */
#ifndef BTF_EXPORT_H
#define BTF_EXPORT_H

#include "btf.h"
#include "btf_pca.h"
#include "btf_thesis.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_thesis_scale {
    BTF_THESIS_SCALE_DEFAULT = 0, /* = BTF_THESIS_SCALE_THESIS */
    BTF_THESIS_SCALE_THESIS,      /* U * 10, V as is (the published files) */
    BTF_THESIS_SCALE_FIT          /* per block and component, least predicted error */
} btf_thesis_scale;

/* Options; zero means default. Plain value. */
typedef struct btf_export_options {
    int k;                   /* views per block; 0 = 3 */
    int components;          /* C including the mean; 0 = 8 */
    btf_thesis_scale scale;
    btf_pca_method method;   /* PCA route (btf_pca.h); 0 = auto */
} btf_export_options;

/* Summary of an export (optional output). Plain value. */
typedef struct btf_export_stats {
    double seconds_pca;   /* block matrices, PCA, scaling */
    double seconds_write; /* quantisation and files */
    long long bytes;      /* all files of the written package */
} btf_export_stats;

const char *btf_thesis_scale_name(btf_thesis_scale s);

/* PCA + scaling into an unquantised package (floats; btf_thesis_write quantises).
 * out is filled by btf_thesis_alloc: the caller frees it with btf_thesis_free. */
btf_result btf_export_thesis_model(const btf *src, const btf_export_options *opt, btf_thesis_pkg *out,
                                   btf_error *err);

/* btf_export_thesis_model + btf_thesis_write into dir (written as a temporary
 * sibling and renamed; an existing thesis package at dir is replaced only once the
 * new one is complete). */
btf_result btf_export_thesis(const btf *src, const btf_export_options *opt, const char *dir,
                             btf_export_stats *stats, btf_error *err);

/* The documented bound (above) at one sample of an unquantised package p, the
 * largest over the three colour channels. */
float btf_export_thesis_bound(const btf_thesis_pkg *p, int view, int light, int x, int y);

/* Bytes of the plain files directly inside dir (a package's size); -1 if unreadable. */
long long btf_dir_bytes(const char *dir);

#ifdef __cplusplus
}
#endif
#endif
