/* btf_io.h - loading any measured BTF (one dispatcher over every input format,
 * doc/input-formats.md) and writing the formats the tools export.
 *
 *     btf_load_options o = {0};        // zero means defaults
 *     o.downsample = 4;                // 256x256 images -> 64x64 BTF
 *     btf *m; btf_error err;
 *     if (btf_load_any("wool/", &o, &m, &err) != BTF_OK) puts(err.msg);  // images, .btf or thesis package
 *
 * Every loader checks sizes and counts before allocating and returns an error
 * naming the offending file on bad input; none prints or aborts.
 */
#ifndef BTF_IO_H
#define BTF_IO_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Image samples at the 8-bit maximum (255: clipped highlights), counted by the image
 * directory readers; the caller's value, filled when btf_load_options.report is set. */
typedef struct btf_load_report {
    long long n_samples;        /* colour samples read from the image files */
    long long n_saturated;      /* of them at 255 */
    int n_images_clipped;       /* images with at least BTF_LOAD_CLIPPED_SHARE of their samples at 255 */
    long long worst_saturated;  /* samples at 255 in worst_file, the image with the most */
    long long worst_samples;    /* colour samples of worst_file */
    char worst_file[1024];
} btf_load_report;

/* An image is "clipped" when at least this share of its samples are 255: 10%. */
#define BTF_LOAD_CLIPPED_SHARE 0.10

/* Options for loaders; zero means default. Plain value. */
typedef struct btf_load_options {
    int downsample;     /* integer box-filter factor on load, 0/1 = none */
    int width, height;  /* requested output size where a loader can resample (thesis import); 0 = native */
    btf_storage storage;/* 0 = loader's natural storage */
    const btf_dirset *sampling; /* expected direction set; NULL = UBO2003 */
    int fill_missing;   /* image directories: a missing (light, view) image is interpolated from the
                         * view's nearest present lights instead of failing the load */
    int *n_filled;      /* optional out: how many images were interpolated (warn the user when > 0) */
    btf_load_report *report; /* optional out: saturated samples of image directories (warn when clipped) */
} btf_load_options;

/* Writes a UBO2003 image directory (doc/input-formats.md section 1): one PNG (or .jpg, by ext) per (light, view) pair, flat layout, name prefix given. */
btf_result btf_save_ubo2003_dir(const btf *b, const char *dir, const char *prefix, const char *ext,
                                btf_error *err);

/* Writes b as a DFMF08FC file with `components` factors per channel (RGB colour model,
 * float32 scalars); components = 0 means full rank (exact up to float rounding). */
btf_result btf_save_dfmf(const btf *b, const char *path, int components, btf_error *err);

/* What kind of input a path is; btf_load_any and btf_views_open dispatch on it. */
typedef enum btf_input_kind { BTF_INPUT_DFMF = 1, BTF_INPUT_THESIS, BTF_INPUT_IMAGES } btf_input_kind;
/* A .btf file, a thesis package directory (meta.json) or an image directory; a
 * package directory (manifest.json), another file or a missing path is an error. */
btf_result btf_input_kind_of(const char *path, btf_input_kind *kind, btf_error *err);
/* Loads anything the loaders read: a directory (UBO2003 images or thesis package,
 * told apart by meta.json) or a `.btf` file. */
btf_result btf_load_any(const char *path, const btf_load_options *opt, btf **out, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
