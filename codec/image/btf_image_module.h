/* btf_image_module.h - the seam between btf_image.c (in every program) and the
 * OpenImageIO module: btf_image_oiio.cpp built on its own as btf_image_oiio.so and
 * loaded on the first image call, so a program that reads no image never maps
 * OpenImageIO and the 260 libraries it links (about 0.4 s at every start).
 *
 * The module links OpenImageIO and nothing of this tree: it reaches the codec's own
 * checks, coders and files through the host table it is opened with, and answers with
 * the table of image functions (btf_image.h). Where btf_image.c looks for the file is
 * in btf_image.c and doc/cli.md ("Image files"). */
#ifndef BTF_IMAGE_MODULE_H
#define BTF_IMAGE_MODULE_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_IMAGE_MODULE_FILE "btf_image_oiio.so"
#define BTF_IMAGE_MODULE_ENTRY "btf_image_oiio_open"
/* Raised whenever either table below changes: a module built for another value is refused. */
#define BTF_IMAGE_MODULE_ABI 2

/* What the module may call in the program (btf_common.h, btf_fs.h, btf_png.h, btf_webp.h,
 * btf_avif.h, btf_lossy.h). Owned by btf_image.c: a constant that lives as long as the process. */
typedef struct btf_image_host {
    btf_result (*fail)(btf_error *err, btf_result code, const char *fmt, ...);
    btf_result (*fs_read_with)(const btf_files *files, const char *path, size_t max_bytes, char **out, size_t *size,
                               btf_error *err);
    long long (*fs_size)(const char *path);
    btf_result (*fs_commit_file)(const char *tmp, const char *path, btf_error *err);
    btf_result (*png_check)(const uint8_t *data, size_t n, const char *what, btf_error *err);
    btf_result (*png_check_header)(const uint8_t *data, size_t n, const char *what, btf_error *err);
    btf_result (*webp_check)(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err);
    btf_result (*webp_encode_grey)(const uint8_t *grey, int w, int h, uint8_t **out, size_t *n, btf_error *err);
    int (*avif_is_avif)(const uint8_t *data, size_t n);
    btf_result (*avif_check)(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err);
    int (*lossy_codec_of)(const uint8_t *data, size_t n);
    btf_result (*lossy_decode)(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                               btf_error *err);
} btf_image_host;

/* The image functions of btf_image.h that need OpenImageIO, with the same contracts
 * (btf_image_write and btf_image_write_unsynced are write_flags with flags 0 and
 * BTF_IMAGE_UNSYNCED). Owned by the module: a constant that lives while it is loaded
 * (it is never unloaded). */
typedef struct btf_image_api {
    btf_result (*info)(const char *path, int *w, int *h, int *channels, btf_error *err);
    btf_result (*info_with)(const btf_files *files, const char *path, int *w, int *h, int *channels, btf_error *err);
    btf_result (*read_u8)(const char *path, int *w, int *h, int *channels, uint8_t **pixels, btf_error *err);
    btf_result (*read_rgb_f32)(const char *path, int max_w, int max_h, int *w, int *h, float **rgb, btf_error *err);
    btf_result (*write_flags)(const char *path, int w, int h, int channels, int bits, const void *pixels, int flags,
                              btf_error *err);
    btf_result (*write_smallest)(const char *stem, int w, int h, const uint8_t *grey, int flags, const char **ext,
                                 long long *bytes, btf_error *err);
    btf_result (*read_grey)(const char *path, int *w, int *h, uint8_t **pixels, btf_error *err);
    btf_result (*read_with)(const btf_files *files, const char *path, int w, int h, int channels, int grey,
                            uint8_t **pixels, btf_error *err);
    btf_result (*encode)(const char *name, int w, int h, int channels, int bits, const void *pixels, int flags,
                         uint8_t **out, size_t *n, btf_error *err);
} btf_image_api;

/* The module's one exported function: its table for this host, or NULL when abi is
 * not BTF_IMAGE_MODULE_ABI. */
typedef const btf_image_api *(*btf_image_open_fn)(const btf_image_host *host, int abi);

#ifdef __cplusplus
}
#endif
#endif
