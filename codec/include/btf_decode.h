/* btf_decode.h - the CPU reference decoder of a package (doc/package-format.md):
 * any light and view direction, any texture coordinate, every level.
 *
 *     btf_decode_options d = {0};  d.filter = BTF_FILTER_BILINEAR;
 *     float rgb[3];
 *     btf_decode(p, u, v, light_dir, view_dir, &d, rgb);
 */
#ifndef BTF_DECODE_H
#define BTF_DECODE_H

#include "btf_package.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_filter { BTF_FILTER_NEAREST = 0, BTF_FILTER_BILINEAR } btf_filter;

/* Decoder options; zero means default. Plain value. */
typedef struct btf_decode_options {
    btf_filter filter;
    int wrap;     /* 1: texel indices modulo the size (tiling); 0: clamp to the edge */
    int n_chunks; /* use the first n loaded chunks; 0 = all loaded */
    float lod;    /* version 2: level of detail (0 = finest; fractional = trilinear between levels) */
} btf_decode_options;

/* CPU reference decoder (doc/package-format.md section 6): texture coordinate (u, v)
 * in [0,1], light and view directions in the local frame (z = normal, need not be
 * unit). rgb is on the byte/255 scale, not clamped. Never NaN for finite input.
 * rgb is the package's own value: linear light for a linear package (p->linear,
 * manifest "encoding": "linear"), where sums over light directions are sums of
 * radiance; sRGB-encoded otherwise. btf_package_to_source (btf_package.h) puts it
 * on the source's scale for comparisons and images. */
void btf_decode(const btf_package *p, float u, float v, const float light[3], const float view[3],
                const btf_decode_options *opt, float rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
