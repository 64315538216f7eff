/* btf_png.h - structural check of a PNG file before it reaches the decoder, so a
 * damaged or hostile file gets one clear error instead of a decoder message on
 * stderr: signature, chunk framing and checksums, IHDR, the zlib stream's size
 * and the row filter bytes.
 *
 *     if (btf_png_check(bytes, n, "tex-00.png", &err) != BTF_OK) puts(err.msg);
 */
#ifndef BTF_PNG_H
#define BTF_PNG_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 1 when the n bytes start with the PNG signature. */
int btf_png_is_png(const uint8_t *data, size_t n);

/* BTF_OK when data (n bytes) is a well-formed PNG: every chunk complete with a
 * valid CRC and a letter type, IHDR first and valid, at most one PLTE (1 to 256
 * entries, in a colour image, before IDAT; required for palette images), no
 * unknown critical chunk, IEND last, and the IDAT stream
 * inflating to exactly the image's filtered size (Adam7 passes counted for
 * interlaced images) with filter bytes 0..4 (checked for non-interlaced images).
 * BTF_ERR_FORMAT otherwise, naming what is wrong; what names the file. */
btf_result btf_png_check(const uint8_t *data, size_t n, const char *what, btf_error *err);

/* The same without inflating the image data (framing, CRCs, IHDR, chunk order),
 * for readers that only want the image size: the decoder still reads every chunk
 * before the image data when it opens a file. */
btf_result btf_png_check_header(const uint8_t *data, size_t n, const char *what, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
