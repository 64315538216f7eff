/* btf_lossy.h - the lossy texture encodings of rate-distortion packages, one entry
 * point for their writers and readers: lossy WebP (btf_webp.h) and AVIF
 * (btf_avif.h), each at a ladder of BTF_LOSSY_LADDER levels from coarse to fine
 * (doc/package-format.md sections 4.1 and 10.8).
 *
 *     uint8_t *file; size_t n;
 *     int level = btf_lossy_ladder(BTF_LOSSY_AVIF, 9);         // an AV1 quantiser
 *     if (btf_lossy_encode(BTF_LOSSY_AVIF, px, w, h, level, &file, &n, &err) == BTF_OK) {
 *         btf_lossy_decode(file, n, "atlas", w, h, back, &err);  // as every reader decodes it
 *         free(file);
 *     }
 */
#ifndef BTF_LOSSY_H
#define BTF_LOSSY_H
#include <stddef.h>
#include <stdint.h>
#include "btf.h"
#ifdef __cplusplus
extern "C" {
#endif
#define BTF_LOSSY_NONE 0
#define BTF_LOSSY_WEBP 1 /* level: libwebp quality 0..100 */
#define BTF_LOSSY_AVIF 2 /* level: AV1 quantiser 0..63 (0 finest) */
#define BTF_LOSSY_LADDER 13
#define BTF_LOSSY_FINE 22 /* rungs of the fine ladder (btf_lossy_fine) */

/* The encoding of the file whose first n bytes these are: BTF_LOSSY_WEBP for a lossy
 * WebP, BTF_LOSSY_AVIF for an AVIF, else BTF_LOSSY_NONE (a PNG or lossless WebP). */
int btf_lossy_codec_of(const uint8_t *data, size_t n);
/* The file extension of codec's files: ".webp" or ".avif" (static strings). */
const char *btf_lossy_ext(int codec);
/* The name of codec in messages and manifests: "webp" or "avif" (static strings). */
const char *btf_lossy_name(int codec);
/* The largest level codec takes: 100 (a WebP quality), 63 (an AV1 quantiser); the least is 0. */
int btf_lossy_max_level(int codec);
/* Level i (0 coarsest .. BTF_LOSSY_LADDER - 1 finest) of codec's ladder. */
int btf_lossy_ladder(int codec, int i);
/* Rung i (0 coarsest .. BTF_LOSSY_FINE - 1 finest) of codec's fine ladder: every rung of
 * btf_lossy_ladder and more between its coarsest ones, and below them for AVIF (the
 * coarse spatial levels' choice, doc/package-format.md section 10.7). */
int btf_lossy_fine(int codec, int i);
/* w x h grey bytes as a file of codec at level (btf_webp_encode_grey_lossy,
 * btf_avif_encode_grey) into *out (malloc'd, *n bytes). */
btf_result btf_lossy_encode(int codec, const uint8_t *grey, int w, int h, int level, uint8_t **out, size_t *n,
                            btf_error *err);
/* A lossy WebP or an AVIF (by its bytes) of w x h decoded into grey (w*h bytes) as
 * every reader decodes it (btf_webp_decode_grey, btf_avif_decode_grey). */
btf_result btf_lossy_decode(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                            btf_error *err);
#ifdef __cplusplus
}
#endif
#endif
