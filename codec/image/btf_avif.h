/* btf_avif.h - grey 8-bit images as AVIF (libavif; AV1 through libaom to encode, any
 * AV1 decoder libavif has to decode): the second lossy texture encoding of
 * rate-distortion packages (doc/package-format.md sections 4.1 and 10.8), the check a
 * reader runs before the AV1 decoder sees a file, and the grey decode.
 *
 *     uint8_t *file; size_t n;
 *     if (btf_avif_encode_grey(px, w, h, 24, &file, &n, &err) == BTF_OK) {
 *         btf_avif_decode_grey(file, n, "atlas", w, h, back, &err);   // back: w*h bytes, the Y plane
 *         free(file);
 *     }
 *
 * The file is one still AV1 image, 8-bit, YUV 4:0:0 (monochrome), full range, no
 * alpha: its value is the decoded Y sample, all 256 levels (a browser's RGB decode
 * gives R = G = B = Y). Lossy at every quantiser but 0; AV1 decoding is exact, so every
 * conforming decoder gives the same Y.
 */
#ifndef BTF_AVIF_H
#define BTF_AVIF_H
#include <stddef.h>
#include <stdint.h>
#include "btf.h"
#ifdef __cplusplus
extern "C" {
#endif
#define BTF_AVIF_MAX_QUANTIZER 63 /* AV1's quantiser index range is 0 (finest) .. 63 */

/* 1 when the n bytes start like an AVIF file: an ISO-BMFF "ftyp" box whose major
 * brand is "avif" (the box size is not checked here). */
int btf_avif_is_avif(const uint8_t *data, size_t n);
/* BTF_OK when data (n bytes) parses (libavif, strict, no pixels decoded) as the
 * package format allows an AVIF: one image, 8-bit, 4:0:0, full range, no alpha, each
 * side 1..32768; *w, *h (optional) its size. BTF_ERR_FORMAT otherwise, naming what is
 * wrong; what names the file. */
btf_result btf_avif_check(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err);
/* Encodes w x h grey bytes (row 0 first) as that AVIF at AV1 quantiser 0..63 (libaom,
 * one thread, speed BTF_AVIF_SPEED) into *out (malloc'd, *n bytes; the caller frees it). */
btf_result btf_avif_encode_grey(const uint8_t *grey, int w, int h, int quantizer, uint8_t **out, size_t *n,
                                btf_error *err);
/* Decodes an AVIF that btf_avif_check accepts and whose size is w x h into grey (the
 * caller's w*h bytes, the Y plane). BTF_ERR_FORMAT (naming what) for anything else,
 * before any pixel is decoded when the check or the size fails. */
btf_result btf_avif_decode_grey(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                                btf_error *err);
#ifdef __cplusplus
}
#endif
#endif
