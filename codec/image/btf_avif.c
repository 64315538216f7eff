/* btf_avif.c - AVIF for grey textures: libavif's encoder (libaom) and a strict parse
 * and Y-plane decode (btf_avif.h). */
#include "btf_avif.h"
#include "btf_common.h"

#include <avif/avif.h>
#include <stdlib.h>
#include <string.h>

/* libaom's effort through libavif (0 slowest .. 10 fastest): on component atlases 6
 * gives the bytes of 4 (within 0.2 %) at a quarter of its time, 8 5 % more bytes
 * (doc/performance.md section 11, "AVIF"). */
#define BTF_AVIF_SPEED 6
#define BTF_AVIF_MAX_SIDE 32768

int btf_avif_is_avif(const uint8_t *data, size_t n)
{
    return n >= 12 && !memcmp(data + 4, "ftyp", 4) && !memcmp(data + 8, "avif", 4);
}

/* A decoder over the n bytes, parsed (strict; no Exif or XMP kept) into *out, or
 * an error: a file that is not one 8-bit 4:0:0 full-range image without alpha is refused. */
static btf_result btf__parse(const uint8_t *data, size_t n, const char *what, avifDecoder **out, btf_error *err)
{
    *out = NULL;
    if (!btf_avif_is_avif(data, n))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not an AVIF file (no ftyp box of brand avif)", what);
    avifDecoder *d = avifDecoderCreate();
    if (!d)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", what);
    d->maxThreads = 1, d->ignoreExif = AVIF_TRUE, d->ignoreXMP = AVIF_TRUE, d->strictFlags = AVIF_STRICT_ENABLED;
    d->imageDimensionLimit = BTF_AVIF_MAX_SIDE, d->imageCountLimit = 1;
    avifResult ar = avifDecoderSetIOMemory(d, data, n);
    if (ar == AVIF_RESULT_OK)
        ar = avifDecoderParse(d);
    const avifImage *im = d->image;
    btf_result r = BTF_ERR_FORMAT;
    if (ar != AVIF_RESULT_OK)
        btf_fail(err, BTF_ERR_FORMAT, "%s: not a valid AVIF (%s%s%s)", what, avifResultToString(ar),
                 d->diag.error[0] ? ": " : "", d->diag.error);
    else if (d->imageCount != 1 || d->alphaPresent)
        btf_fail(err, BTF_ERR_FORMAT, "%s: AVIF of %d images%s (needs one, no alpha)", what, d->imageCount,
                 d->alphaPresent ? " with alpha" : "");
    else if (im->depth != 8 || im->yuvFormat != AVIF_PIXEL_FORMAT_YUV400 || im->yuvRange != AVIF_RANGE_FULL)
        btf_fail(err, BTF_ERR_FORMAT, "%s: AVIF of depth %u, format %s, %s range (needs 8-bit 4:0:0, full range)",
                 what, im->depth, avifPixelFormatToString(im->yuvFormat),
                 im->yuvRange == AVIF_RANGE_FULL ? "full" : "limited");
    else if (im->width < 1 || im->height < 1 || im->width > BTF_AVIF_MAX_SIDE || im->height > BTF_AVIF_MAX_SIDE)
        btf_fail(err, BTF_ERR_FORMAT, "%s: AVIF of %ux%u (each side 1..%d)", what, im->width, im->height,
                 BTF_AVIF_MAX_SIDE);
    else
        r = BTF_OK;
    if (r == BTF_OK)
        *out = d;
    else
        avifDecoderDestroy(d);
    return r;
}

btf_result btf_avif_check(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err)
{
    avifDecoder *d = NULL;
    btf_result r = btf__parse(data, n, what, &d, err);
    if (r != BTF_OK)
        return r;
    if (w)
        *w = (int)d->image->width;
    if (h)
        *h = (int)d->image->height;
    avifDecoderDestroy(d);
    return BTF_OK;
}

btf_result btf_avif_decode_grey(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                                btf_error *err)
{
    avifDecoder *d = NULL;
    btf_result r = btf__parse(data, n, what, &d, err);
    if (r != BTF_OK)
        return r;
    if ((int)d->image->width != w || (int)d->image->height != h)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: AVIF of %ux%u, expected %dx%d", what, d->image->width,
                     d->image->height, w, h);
    avifResult ar = r == BTF_OK ? avifDecoderNextImage(d) : AVIF_RESULT_OK;
    const avifImage *im = d->image;
    if (r == BTF_OK && ar != AVIF_RESULT_OK)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode AVIF data (%s)", what, avifResultToString(ar));
    else if (r == BTF_OK && ((int)im->width != w || (int)im->height != h || im->depth != 8 || !im->yuvPlanes[0]))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: AVIF frame of %ux%u, depth %u differs from its header", what,
                     im->width, im->height, im->depth);
    for (int y = 0; r == BTF_OK && y < h; y++)
        memcpy(grey + (size_t)y * (size_t)w, im->yuvPlanes[0] + (size_t)y * im->yuvRowBytes[0], (size_t)w);
    avifDecoderDestroy(d);
    return r;
}

btf_result btf_avif_encode_grey(const uint8_t *grey, int w, int h, int quantizer, uint8_t **out, size_t *n,
                                btf_error *err)
{
    *out = NULL, *n = 0;
    if (w < 1 || h < 1 || w > BTF_AVIF_MAX_SIDE || h > BTF_AVIF_MAX_SIDE)
        return btf_fail(err, BTF_ERR_ARG, "avif: %dx%d is outside 1..%d", w, h, BTF_AVIF_MAX_SIDE);
    if (quantizer < 0 || quantizer > BTF_AVIF_MAX_QUANTIZER)
        return btf_fail(err, BTF_ERR_ARG, "avif: quantizer %d is outside 0..%d", quantizer, BTF_AVIF_MAX_QUANTIZER);
    avifImage *im = avifImageCreate((uint32_t)w, (uint32_t)h, 8, AVIF_PIXEL_FORMAT_YUV400);
    avifEncoder *e = avifEncoderCreate();
    avifRWData o = AVIF_DATA_EMPTY;
    btf_result r = im && e ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "avif: out of memory (%dx%d)", w, h);
    if (r == BTF_OK) {
        im->yuvRange = AVIF_RANGE_FULL;
        if (avifImageAllocatePlanes(im, AVIF_PLANES_YUV) != AVIF_RESULT_OK || !im->yuvPlanes[0])
            r = btf_fail(err, BTF_ERR_NOMEM, "avif: out of memory (%dx%d)", w, h);
    }
    for (int y = 0; r == BTF_OK && y < h; y++)
        memcpy(im->yuvPlanes[0] + (size_t)y * im->yuvRowBytes[0], grey + (size_t)y * (size_t)w, (size_t)w);
    if (r == BTF_OK) {
        e->codecChoice = AVIF_CODEC_CHOICE_AOM, e->maxThreads = 1, e->speed = BTF_AVIF_SPEED;
        e->minQuantizer = e->maxQuantizer = quantizer;
        avifResult ar = avifEncoderWrite(e, im, &o);
        if (ar != AVIF_RESULT_OK)
            r = btf_fail(err, BTF_ERR_IO, "avif: encoding failed (%s)", avifResultToString(ar));
    }
    if (r == BTF_OK && (*out = malloc(o.size ? o.size : 1)) == NULL)
        r = btf_fail(err, BTF_ERR_NOMEM, "avif: out of memory");
    if (r == BTF_OK)
        memcpy(*out, o.data, o.size), *n = o.size;
    avifRWDataFree(&o);
    if (e)
        avifEncoderDestroy(e);
    if (im)
        avifImageDestroy(im);
    return r;
}
