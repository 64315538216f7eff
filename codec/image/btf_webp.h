/* btf_webp.h - grey 8-bit images as WebP (libwebp): the lossless encoder the package
 * writers try beside PNG (and its RGB form for the weights files wt-JJ.webp), the
 * lossy encoder of rate-distortion packages
 * (doc/package-format.md sections 4.1 and 10.8), the structural check a reader runs
 * before a decoder sees a file, and the grey decode of either kind. Other decoding
 * goes through btf_image (OpenImageIO).
 *
 *     uint8_t *file; size_t n;
 *     if (btf_webp_encode_grey_lossy(px, w, h, 85, &file, &n, &err) == BTF_OK) {
 *         btf_webp_decode_grey(file, n, "atlas", w, h, back, &err);   // back: w*h bytes, R of the decode
 *         free(file);
 *     }
 *
 * Limitations: grey only (but the RGB pair for weights, lossless or lossy); a lossy file holds 220 grey levels (its Y plane's 16..235),
 * so a lossy round trip is never exact, and the decoded value of a lossy file is R of
 * libwebp's RGB decode (G differs from R by one on about 1% of the pixels). No
 * extended (VP8X) files: no alpha, animation or metadata.
 */
#ifndef BTF_WEBP_H
#define BTF_WEBP_H
#include <stddef.h>
#include <stdint.h>
#include "btf.h"
#ifdef __cplusplus
extern "C" {
#endif
/* 1 when the n bytes start like a WebP file ("RIFF", 4 bytes, "WEBP"). */
int btf_webp_is_webp(const uint8_t *data, size_t n);
/* 1 when a WebP file's first chunk is a lossy image ("VP8 "); meaningful after
 * btf_webp_check accepted it. */
int btf_webp_is_lossy(const uint8_t *data, size_t n);
/* BTF_OK when data (n bytes) is a simple-format WebP the way the package format allows
 * it: the RIFF size is the file's and one chunk fills it, either "VP8L" (lossless:
 * signature byte and version right) or "VP8 " (lossy: a shown key frame of version 0..3
 * with its start code, no scaling bits, a first partition inside the chunk); no
 * extended (VP8X: alpha, animation), no other chunk. *w, *h (optional) its size from
 * the header. BTF_ERR_FORMAT otherwise, naming what is wrong; what names the file. */
btf_result btf_webp_check(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err);
/* Encodes w x h grey bytes (row 0 first) as a lossless WebP with R = G = B (WebP has
 * no grey mode) into *out (malloc'd, *n bytes; the caller frees it). */
btf_result btf_webp_encode_grey(const uint8_t *grey, int w, int h, uint8_t **out, size_t *n, btf_error *err);
/* Encodes w x h grey bytes as a lossy WebP at quality 0..100 (libwebp: method 6, no
 * spatial noise shaping, no deblocking filter; each grey q written as the Y whose
 * decoded R is nearest, U = V = 128) into *out (malloc'd, *n bytes). */
btf_result btf_webp_encode_grey_lossy(const uint8_t *grey, int w, int h, int quality, uint8_t **out, size_t *n,
                                      btf_error *err);
/* Decodes a WebP that btf_webp_check accepts and whose header says w x h into grey
 * (the caller's w*h bytes): a lossless file must hold R = G = B with alpha 255 and
 * gives R; a lossy file gives R of libwebp's RGB decode. BTF_ERR_FORMAT (naming what)
 * for anything else, before anything is decoded when the check or the size fails. */
btf_result btf_webp_decode_grey(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                                btf_error *err);
/* Encodes w x h RGB bytes (3 per pixel, row 0 first) as an opaque lossless WebP
 * (every sample kept exactly) into *out (malloc'd, *n bytes; the caller frees it):
 * the weights files wt-JJ.webp (doc/package-format.md section 5.5). */
btf_result btf_webp_encode_rgb(const uint8_t *rgb, int w, int h, uint8_t **out, size_t *n, btf_error *err);
/* Encodes w x h RGB bytes as a lossy WebP at quality 0..100 (libwebp: method 6, no
 * spatial noise shaping, no deblocking filter; libwebp's RGB to YUV 4:2:0) into *out
 * (malloc'd, *n bytes): the lossy weights files wt-JJ.webp (doc/package-format.md
 * section 5.5). */
btf_result btf_webp_encode_rgb_lossy(const uint8_t *rgb, int w, int h, int quality, uint8_t **out, size_t *n,
                                     btf_error *err);
/* Decodes a WebP that btf_webp_check accepts and whose header says w x h into rgb
 * (the caller's 3*w*h bytes): a lossless file must have every pixel opaque; a lossy
 * one gives libwebp's RGB decode. BTF_ERR_FORMAT (naming what) for another size or a
 * lossless pixel with alpha below 255; the check and the size before anything is
 * decoded. */
btf_result btf_webp_decode_rgb(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *rgb,
                               btf_error *err);
/* libwebp's R of a decoded Y at U = V = 128 (its VP8YUVToR), 0..255. */
int btf_webp_r_of_y(int y);
/* The Y (0..255) whose btf_webp_r_of_y is nearest q (ties: the smaller Y); the lossy
 * encoder writes grey q as this Y. */
int btf_webp_y_of_q(int q);
#ifdef __cplusplus
}
#endif
#endif
