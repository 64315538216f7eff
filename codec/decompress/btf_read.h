/* btf_read.h - what the package reader (btf_package_read.c) offers the level
 * builder and the decoder beyond btf_package.h: sampling one level's tile.
 */
#ifndef BTF_READ_H
#define BTF_READ_H

#include "btf_package.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Value of a level-l tile of w x h texels (w = W >> l) at level-0 texel (x, y):
 * bilinear (clamped to the tile) at the texel centre. */
float btf_package_level_sample(const float *tile, int l, int w, int h, int x, int y);

#ifdef __cplusplus
}
#endif
#endif
