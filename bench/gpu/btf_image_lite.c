/* btf_image_lite.c - btf_image.h for the self-contained GPU bench folder (make
 * bench-gpu): reads PNG through libpng's simplified API and WebP through libwebp,
 * nothing else, so the folder carries a few small libraries instead of
 * OpenImageIO's closure. The bench only reads packages made beforehand; every
 * writer here answers BTF_ERR_UNSUPPORTED. The product links codec/image/btf_image.cpp. */
#include "btf_image.h"
#include "btf_common.h"
#include "btf_fs.h"
#include "btf_png.h"
#include "btf_webp.h"

#include <png.h>
#include <stdlib.h>
#include <string.h>
#include <webp/decode.h>

/* The file's bytes (malloc'd; read through files, NULL: the disk) after the
 * structural checks of btf_png / btf_webp. */
static btf_result lite_load(const btf_files *files, const char *path, uint8_t **data, size_t *n, int *webp,
                            btf_error *err)
{
    char *d = NULL;
    btf_result r = btf_fs_read_with(files, path, (size_t)1 << 30, &d, n, err);
    if (r != BTF_OK)
        return r;
    *webp = btf_webp_is_webp((const uint8_t *)d, *n);
    if (!*webp && !btf_png_is_png((const uint8_t *)d, *n))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: neither PNG nor WebP (this build reads only those)", path);
    else
        r = *webp ? btf_webp_check((const uint8_t *)d, *n, path, NULL, NULL, err)
                  : btf_png_check((const uint8_t *)d, *n, path, err);
    if (r != BTF_OK) {
        free(d);
        return r;
    }
    *data = (uint8_t *)d;
    return BTF_OK;
}

static btf_result lite_png(const char *path, const uint8_t *d, size_t n, int *w, int *h, int *ch, uint8_t **px,
                           btf_error *err)
{
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_memory(&img, d, n))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s", path, img.message);
    int c = img.format & PNG_FORMAT_FLAG_COLOR ? 3 : 1;
    img.format = c == 3 ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
    size_t bytes = PNG_IMAGE_SIZE(img);
    *px = malloc(bytes);
    if (!*px || !png_image_finish_read(&img, NULL, *px, 0, NULL)) {
        free(*px), *px = NULL;
        png_image_free(&img);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode (%s)", path, img.message);
    }
    *w = (int)img.width, *h = (int)img.height, *ch = c;
    return BTF_OK;
}

/* The pixels of the PNG or WebP at path, read through files. */
static btf_result lite_read(const btf_files *files, const char *path, int *w, int *h, int *channels, uint8_t **pixels,
                            btf_error *err)
{
    uint8_t *d = NULL;
    size_t n = 0;
    int webp = 0;
    *pixels = NULL;
    btf_result r = lite_load(files, path, &d, &n, &webp, err);
    if (r != BTF_OK)
        return r;
    if (webp) {
        *pixels = WebPDecodeRGB(d, n, w, h);
        *channels = 3;
        if (!*pixels)
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode the WebP image", path);
        for (size_t i = 0; *pixels && btf_webp_is_lossy(d, n) && i < (size_t)*w * (size_t)*h; i++)
            (*pixels)[3 * i + 1] = (*pixels)[3 * i + 2] = (*pixels)[3 * i]; /* a lossy texture is its R (package-format.md 4.1) */
    } else {
        r = lite_png(path, d, n, w, h, channels, pixels, err);
    }
    free(d);
    return r;
}

btf_result btf_image_read_u8(const char *path, int *w, int *h, int *channels, uint8_t **pixels, btf_error *err)
{
    btf_result r = lite_read(NULL, path, w, h, channels, pixels, err);
    return r == BTF_ERR_MISSING ? BTF_ERR_IO : r;
}

btf_result btf_image_info(const char *path, int *w, int *h, int *channels, btf_error *err)
{
    uint8_t *px = NULL;
    btf_result r = btf_image_read_u8(path, w, h, channels, &px, err);
    free(px);
    return r;
}

/* Pixels of ch channels (w x h) to one grey byte each, in place. */
static btf_result lite_grey(const char *path, int w, int h, int ch, uint8_t **pixels, btf_error *err)
{
    if (ch == 1)
        return BTF_OK;
    size_t n = (size_t)w * (size_t)h;
    uint8_t *px = *pixels;
    for (size_t i = 0; i < n; i++) {
        const uint8_t *p = px + i * 3;
        if (p[1] != p[0] || p[2] != p[0]) {
            free(px), *pixels = NULL;
            return btf_fail(err, BTF_ERR_FORMAT, "%s: not a grey image", path);
        }
        px[i] = p[0];
    }
    return BTF_OK;
}

btf_result btf_image_read_grey(const char *path, int *w, int *h, uint8_t **pixels, btf_error *err)
{
    int ch = 0;
    btf_result r = btf_image_read_u8(path, w, h, &ch, pixels, err);
    return r == BTF_OK ? lite_grey(path, *w, *h, ch, pixels, err) : r;
}

btf_result btf_image_info_with(const btf_files *files, const char *path, int *w, int *h, int *channels,
                               btf_error *err)
{
    uint8_t *px = NULL;
    btf_result r = lite_read(files, path, w, h, channels, &px, err);
    free(px);
    return r;
}

btf_result btf_image_read_with(const btf_files *files, const char *path, int w, int h, int channels, int grey,
                               uint8_t **pixels, btf_error *err)
{
    int iw = 0, ih = 0, ch = 0;
    btf_result r = lite_read(files, path, &iw, &ih, &ch, pixels, err); /* decodes first: a bench of made packages */
    if (r == BTF_OK && grey && channels == 1)
        r = lite_grey(path, iw, ih, ch, pixels, err), ch = 1;
    if (r == BTF_OK && (iw != w || ih != h || ch != channels)) {
        free(*pixels), *pixels = NULL;
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: %dx%d with %d channels, expected %dx%d with %d", path, iw, ih, ch, w, h,
                     channels);
    }
    return r;
}

btf_result btf_image_read_rgb_f32(const char *path, int max_w, int max_h, int *w, int *h, float **rgb, btf_error *err)
{
    (void)max_w, (void)max_h, (void)w, (void)h, (void)rgb;
    return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: this build reads no HDR images", path);
}

static btf_result lite_no_writer(const char *path, btf_error *err)
{
    return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: this build writes no images", path);
}

btf_result btf_image_write(const char *path, int w, int h, int channels, int bits, const void *pixels, btf_error *err)
{
    (void)w, (void)h, (void)channels, (void)bits, (void)pixels;
    return lite_no_writer(path, err);
}

btf_result btf_image_write_unsynced(const char *path, int w, int h, int channels, int bits, const void *pixels,
                                    btf_error *err)
{
    (void)w, (void)h, (void)channels, (void)bits, (void)pixels;
    return lite_no_writer(path, err);
}

btf_result btf_image_write_flags(const char *path, int w, int h, int channels, int bits, const void *pixels, int flags,
                                 btf_error *err)
{
    (void)w, (void)h, (void)channels, (void)bits, (void)pixels, (void)flags;
    return lite_no_writer(path, err);
}

btf_result btf_image_write_smallest(const char *stem, int w, int h, const uint8_t *grey, int flags, const char **ext,
                                    long long *bytes, btf_error *err)
{
    (void)w, (void)h, (void)grey, (void)flags, (void)ext, (void)bytes;
    return lite_no_writer(stem, err);
}
