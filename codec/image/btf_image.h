/* btf_image.h - image files through OpenImageIO (the only C++ in the codec).
 *
 *     uint8_t *px; int w, h, ch;
 *     if (btf_image_read_u8("a.png", &w, &h, &ch, &px, &err) == BTF_OK) { ...; free(px); }
 *
 * Reads any format OpenImageIO reads (PNG, JPEG, WebP, ...) as 8-bit, interleaved,
 * row 0 first, with alpha left unassociated (never premultiplied). A PNG or WebP is
 * read into memory, checked (btf_png_check, btf_webp_check) and decoded from there.
 * Writes go to "<path>.tmp-<pid>", are fsynced and renamed into place on success.
 */
#ifndef BTF_IMAGE_H
#define BTF_IMAGE_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Decoded bytes per PNG file byte, at most: deflate cannot expand further (about
 * 1032:1), so a PNG whose header claims more pixels is refused before allocating. */
#define BTF_IMAGE_MAX_PNG_RATIO 1100
/* A lossless WebP may decode to more than that ratio (a flat atlas is a few dozen
 * bytes); it is refused only when it would also decode to more than this many bytes. */
#define BTF_IMAGE_MAX_WEBP_FLOOR (64 << 20)

/* Reads an image; *pixels is malloc'd (w*h*ch bytes), caller frees. A PNG whose
 * header claims more than BTF_IMAGE_MAX_PNG_RATIO bytes per file byte is refused. */
btf_result btf_image_read_u8(const char *path, int *w, int *h, int *channels, uint8_t **pixels, btf_error *err);
/* Reads only the header: size and channel count. */
btf_result btf_image_info(const char *path, int *w, int *h, int *channels, btf_error *err);
/* Writes w*h*channels samples, bits 8 (uint8_t) or 16 (uint16_t), format from the extension. */
btf_result btf_image_write(const char *path, int w, int h, int channels, int bits, const void *pixels,
                           btf_error *err);
/* The same without the fsyncs, for writers of many files into one directory that
 * sync the directory once at the end (image directories: one fsync per image
 * would cost ten times the encoding). */
btf_result btf_image_write_unsynced(const char *path, int w, int h, int channels, int bits, const void *pixels,
                                    btf_error *err);
/* btf_image_write with flags: BTF_IMAGE_UNSYNCED (as btf_image_write_unsynced),
 * BTF_IMAGE_PNG_UNFILTERED (PNG rows stored with filter type None: smaller for data
 * without spatial correlation, such as prediction residuals) and
 * BTF_IMAGE_PNG_SMALLEST (of libpng's per-row adaptive filter choice and filter
 * None, Up or Average on every row, the one that deflates the image's middle rows
 * smallest: smaller texture atlases for a longer encoding, doc/package-format.md
 * section 11.2)
 * and BTF_IMAGE_PNG_UP (filter Up on every row: the usual winner of that choice, at
 * one encoding). Other formats ignore the PNG flags. */
#define BTF_IMAGE_UNSYNCED 1
#define BTF_IMAGE_PNG_UNFILTERED 2
#define BTF_IMAGE_PNG_SMALLEST 4
#define BTF_IMAGE_NO_WEBP 8
#define BTF_IMAGE_PNG_UP 16
btf_result btf_image_write_flags(const char *path, int w, int h, int channels, int bits, const void *pixels, int flags,
                                 btf_error *err);
/* The bytes btf_image_write_flags would write to a file called name (its extension
 * picks the format; the flags' PNG choices, the sync flag ignored) into *out, a new
 * malloc'd buffer of *n bytes the caller frees; nothing touches the disk. */
btf_result btf_image_encode(const char *name, int w, int h, int channels, int bits, const void *pixels, int flags,
                            uint8_t **out, size_t *n, btf_error *err);
/* An 8-bit grey image as STEM.png (with flags' PNG choices) or, when it is smaller,
 * STEM.webp, lossless (doc/package-format.md section 4; never with BTF_IMAGE_NO_WEBP);
 * *ext gets ".png" or ".webp" (static strings), *bytes the file's size. Only the
 * chosen file is left. */
btf_result btf_image_write_smallest(const char *stem, int w, int h, const uint8_t *grey, int flags, const char **ext,
                                    long long *bytes, btf_error *err);
/* Reads an image as grey (malloc'd w*h bytes, caller frees): one channel as it is,
 * or three or four whose R, G and B agree (alpha 255), as a lossless grey WebP holds
 * them, or R of a lossy WebP's RGB decode (btf_webp_decode_grey); any other image is
 * BTF_ERR_FORMAT. */
btf_result btf_image_read_grey(const char *path, int *w, int *h, uint8_t **pixels, btf_error *err);

/* For readers of a directory (packages, thesis packages): the PNG or WebP at path read
 * through files (btf.h; NULL: the disk) and decoded from memory, as the readers above
 * decode these formats. Any other format is BTF_ERR_FORMAT; a missing file BTF_ERR_MISSING.
 * btf_image_info_with: the header only. btf_image_read_with: the pixels (malloc'd) of
 * an image whose header says w x h with channels channels, else BTF_ERR_FORMAT before
 * anything is decoded; with grey and channels 1, three or four channels of one grey
 * (a grey WebP) count as one and are read as one, and a lossy WebP is read as R of its
 * RGB decode (btf_image_read_grey); a lossy WebP is refused for anything else. */
btf_result btf_image_info_with(const btf_files *files, const char *path, int *w, int *h, int *channels,
                               btf_error *err);
btf_result btf_image_read_with(const btf_files *files, const char *path, int w, int h, int channels, int grey,
                               uint8_t **pixels, btf_error *err);

/* The largest side btf_image_read_rgb_f32 accepts. */
#define BTF_IMAGE_MAX_F32_SIDE 65536
/* Reads an image as linear float RGB (a grey image: R = G = B; alpha dropped), box-
 * averaged by the smallest integer factor that makes it at most max_w x max_h while
 * it is read, one row at a time (memory: the result plus two rows). For HDR images
 * (Radiance .hdr, OpenEXR); 8-bit formats read as OpenImageIO converts them. A
 * negative or non-finite sample is BTF_ERR_FORMAT naming its pixel. *rgb is malloc'd
 * (*w * *h * 3 floats), caller frees. */
btf_result btf_image_read_rgb_f32(const char *path, int max_w, int max_h, int *w, int *h, float **rgb,
                                  btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
