/* btf_sample.h - the texel subsample on which the compressor measures CIELab
 * (doc/package-format.md section 9.1): one texel of each stride x stride cell, at an
 * offset hashed from the cell, so that a periodic pattern does not alias with it.
 *
 *     int s = btf_sample_stride(W, H, 256);
 *     for (int sy = 0; sy < (H + s - 1) / s; sy++)
 *         for (int sx = 0; sx < (W + s - 1) / s; sx++) {
 *             int x, y;
 *             btf_sample_texel(s, W, H, sx, sy, &x, &y);
 *         }
 */
#ifndef BTF_SAMPLE_H
#define BTF_SAMPLE_H

/* Smallest stride s with ceil(W/s) * ceil(H/s) <= max_texels. */
int btf_sample_stride(int W, int H, int max_texels);
/* The texel (*x, *y) of cell (sx, sy) of a W x H material sampled at stride: the same
 * on every call, within the material. */
void btf_sample_texel(int stride, int W, int H, int sx, int sy, int *x, int *y);

#endif
