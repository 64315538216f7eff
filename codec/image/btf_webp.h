/* btf_webp.h - grey 8-bit images as lossless WebP (libwebp): the encoder the package
 * writers try beside PNG (doc/package-format.md section 4), and the structural check a
 * reader runs before a decoder sees the file. Decoding goes through btf_image (OpenImageIO).
 *
 *     uint8_t *file; size_t n;
 *     if (btf_webp_encode_grey(px, w, h, &file, &n, &err) == BTF_OK) { ...; free(file); }
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
/* BTF_OK when data (n bytes) is a simple-format lossless WebP the way the package
 * format allows it: the RIFF size is the file's, one "VP8L" chunk fills it (no
 * extended, animated or lossy file), its signature byte and version are right; *w,
 * *h (optional) its size from the header. BTF_ERR_FORMAT otherwise, naming what is
 * wrong; what names the file. */
btf_result btf_webp_check(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err);
/* Encodes w x h grey bytes (row 0 first) as a lossless WebP with R = G = B (WebP has
 * no grey mode) into *out (malloc'd, *n bytes; the caller frees it). */
btf_result btf_webp_encode_grey(const uint8_t *grey, int w, int h, uint8_t **out, size_t *n, btf_error *err);
#ifdef __cplusplus
}
#endif
#endif
