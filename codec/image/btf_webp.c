/* btf_webp.c - WebP for grey textures: libwebp's lossless and lossy encoders, a
 * RIFF/VP8L/VP8 check, the grey decode (btf_webp.h). */
#include "btf_webp.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>
#include <webp/decode.h>
#include <webp/encode.h>

/* libwebp's lossless effort preset (0..9): on component atlases 3 makes files
 * nearly as small as 9's at a small part of the time, and 6 is no smaller than 3
 * (doc/package-format.md section 11.2). */
#define BTF_WEBP_LEVEL 3
/* The lossy encoder's effort (libwebp's method 0..6): 6 gives the fewest bytes at a
 * given error on component atlases (doc/performance.md section 11). */
#define BTF_WEBP_LOSSY_METHOD 6

static uint32_t btf__le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

int btf_webp_is_webp(const uint8_t *data, size_t n)
{
    return n >= 12 && !memcmp(data, "RIFF", 4) && !memcmp(data + 8, "WEBP", 4);
}

int btf_webp_is_lossy(const uint8_t *data, size_t n)
{
    return n >= 16 && btf_webp_is_webp(data, n) && !memcmp(data + 12, "VP8 ", 4);
}

/* The VP8L chunk's header (data holds a whole simple-format file of n bytes). */
static btf_result btf__check_vp8l(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err)
{
    uint32_t chunk = btf__le32(data + 16);
    if (chunk < 5 || (unsigned long long)chunk + 20 + (chunk & 1) != n)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8L chunk of %u bytes does not fill the file", what, chunk);
    uint32_t bits = btf__le32(data + 21);
    if (data[20] != 0x2f || bits >> 29 != 0)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: bad VP8L signature or version", what);
    *w = (int)(bits & 0x3fff) + 1;
    *h = (int)((bits >> 14) & 0x3fff) + 1;
    return BTF_OK;
}

/* The VP8 chunk's frame header: a shown key frame, version 0..3, the start code, no
 * scaling, a first partition inside the chunk (doc/package-format.md section 4.1). */
static btf_result btf__check_vp8(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err)
{
    uint32_t chunk = btf__le32(data + 16);
    if (n < 30 || chunk < 10 || (unsigned long long)chunk + 20 + (chunk & 1) != n)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8 chunk of %u bytes does not fill the file", what, chunk);
    const uint8_t *f = data + 20;
    uint32_t tag = (uint32_t)f[0] | (uint32_t)f[1] << 8 | (uint32_t)f[2] << 16;
    if (tag & 1)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8 frame is not a key frame", what);
    if (((tag >> 1) & 7) > 3 || !((tag >> 4) & 1))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8 frame of version %u, shown %u (needs 0..3, shown)", what,
                        (tag >> 1) & 7, (tag >> 4) & 1);
    if (f[3] != 0x9d || f[4] != 0x01 || f[5] != 0x2a)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: bad VP8 start code", what);
    unsigned ws = (unsigned)f[6] | (unsigned)f[7] << 8, hs = (unsigned)f[8] | (unsigned)f[9] << 8;
    if ((ws >> 14) || (hs >> 14) || !(ws & 0x3fff) || !(hs & 0x3fff))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8 frame of %ux%u with scaling %u/%u (needs 1.. and none)", what,
                        ws & 0x3fff, hs & 0x3fff, ws >> 14, hs >> 14);
    if ((tag >> 5) > chunk - 10)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8 first partition of %u bytes overruns its %u-byte chunk", what,
                        tag >> 5, chunk);
    *w = (int)(ws & 0x3fff), *h = (int)(hs & 0x3fff);
    return BTF_OK;
}

btf_result btf_webp_check(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err)
{
    if (!btf_webp_is_webp(data, n))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a WebP file (no RIFF/WEBP signature)", what);
    if (n < 25)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: WebP file of %zu bytes is truncated", what, n);
    uint32_t riff = btf__le32(data + 4);
    if ((unsigned long long)riff + 8 != n)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: RIFF size %u does not match the file's %zu bytes", what, riff, n);
    int iw = 0, ih = 0;
    btf_result r;
    if (!memcmp(data + 12, "VP8L", 4))
        r = btf__check_vp8l(data, n, what, &iw, &ih, err);
    else if (!memcmp(data + 12, "VP8 ", 4))
        r = btf__check_vp8(data, n, what, &iw, &ih, err);
    else
        return btf_fail(err, BTF_ERR_FORMAT,
                        "%s: WebP chunk '%.4s' is not a simple lossless (VP8L) or lossy (VP8) image "
                        "(no alpha, animation or extended files)",
                        what, (const char *)data + 12);
    if (r == BTF_OK && w)
        *w = iw;
    if (r == BTF_OK && h)
        *h = ih;
    return r;
}

/* The encoded picture into *out (malloc'd copy of the memory writer's bytes). */
static btf_result btf__encode(const WebPConfig *cfg, WebPPicture *pic, uint8_t **out, size_t *n, btf_error *err)
{
    WebPMemoryWriter mw;
    WebPMemoryWriterInit(&mw);
    pic->writer = WebPMemoryWrite, pic->custom_ptr = &mw;
    int ok = WebPEncode(cfg, pic);
    int code = pic->error_code;
    WebPPictureFree(pic);
    if (ok && (*out = malloc(mw.size ? mw.size : 1)) != NULL) {
        memcpy(*out, mw.mem, mw.size);
        *n = mw.size;
    }
    WebPMemoryWriterClear(&mw);
    if (!ok)
        return btf_fail(err, BTF_ERR_IO, "webp: encoding failed (libwebp error %d)", code);
    return *out ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "webp: out of memory");
}

static btf_result btf__check_size(int w, int h, btf_error *err)
{
    if (w < 1 || h < 1 || w > WEBP_MAX_DIMENSION || h > WEBP_MAX_DIMENSION)
        return btf_fail(err, BTF_ERR_ARG, "webp: %dx%d is outside 1..%d", w, h, WEBP_MAX_DIMENSION);
    return BTF_OK;
}

/* w x h pixels of ch bytes (1: grey, written as R = G = B; 3: RGB) as an opaque
 * lossless WebP, every sample kept (exact), into *out (malloc'd, *n bytes). */
static btf_result btf__encode_lossless(const uint8_t *px, int ch, int w, int h, uint8_t **out, size_t *n,
                                       btf_error *err)
{
    *out = NULL, *n = 0;
    btf_result r = btf__check_size(w, h, err);
    if (r != BTF_OK)
        return r;
    WebPConfig cfg;
    WebPPicture pic;
    if (!WebPConfigInit(&cfg) || !WebPConfigLosslessPreset(&cfg, BTF_WEBP_LEVEL) || !WebPPictureInit(&pic))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "webp: libwebp version mismatch");
    cfg.exact = 1;
    pic.use_argb = 1, pic.width = w, pic.height = h;
    if (!WebPPictureAlloc(&pic))
        return btf_fail(err, BTF_ERR_NOMEM, "webp: out of memory (%dx%d)", w, h);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const uint8_t *p = px + ((size_t)y * w + x) * (size_t)ch;
            uint32_t r8 = p[0], g8 = p[ch == 3 ? 1 : 0], b8 = p[ch == 3 ? 2 : 0];
            pic.argb[(size_t)y * pic.argb_stride + x] = 0xff000000u | r8 << 16 | g8 << 8 | b8;
        }
    return btf__encode(&cfg, &pic, out, n, err);
}

btf_result btf_webp_encode_grey(const uint8_t *grey, int w, int h, uint8_t **out, size_t *n, btf_error *err)
{
    return btf__encode_lossless(grey, 1, w, h, out, n, err);
}

btf_result btf_webp_encode_rgb(const uint8_t *rgb, int w, int h, uint8_t **out, size_t *n, btf_error *err)
{
    return btf__encode_lossless(rgb, 3, w, h, out, n, err);
}

int btf_webp_r_of_y(int y)
{
    int v = ((y * 19077) >> 8) + ((128 * 26149) >> 8) - 14234;
    return (v & ~16383) == 0 ? v >> 6 : v < 0 ? 0 : 255;
}

int btf_webp_y_of_q(int q)
{
    int best = 0;
    for (int y = 1; y < 256; y++)
        if (abs(btf_webp_r_of_y(y) - q) < abs(btf_webp_r_of_y(best) - q))
            best = y;
    return best;
}

/* The lossy encoder's settings for w x h data at quality 0..100 into cfg, pic
 * initialised (nothing allocated): method 6, no spatial noise shaping and no
 * deblocking filter, both aimed at the eye, where these images are data. */
static btf_result btf__lossy_setup(int w, int h, int quality, WebPConfig *cfg, WebPPicture *pic, btf_error *err)
{
    btf_result r = btf__check_size(w, h, err);
    if (r != BTF_OK)
        return r;
    if (quality < 0 || quality > 100)
        return btf_fail(err, BTF_ERR_ARG, "webp: quality %d is outside 0..100", quality);
    if (!WebPConfigInit(cfg) || !WebPPictureInit(pic))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "webp: libwebp version mismatch");
    cfg->quality = (float)quality, cfg->method = BTF_WEBP_LOSSY_METHOD;
    cfg->sns_strength = 0, cfg->filter_strength = 0;
    pic->use_argb = 0, pic->width = w, pic->height = h;
    return BTF_OK;
}

btf_result btf_webp_encode_grey_lossy(const uint8_t *grey, int w, int h, int quality, uint8_t **out, size_t *n,
                                      btf_error *err)
{
    WebPConfig cfg;
    WebPPicture pic;
    *out = NULL, *n = 0;
    btf_result r = btf__lossy_setup(w, h, quality, &cfg, &pic, err);
    if (r != BTF_OK)
        return r;
    pic.colorspace = WEBP_YUV420;
    if (!WebPPictureAlloc(&pic))
        return btf_fail(err, BTF_ERR_NOMEM, "webp: out of memory (%dx%d)", w, h);
    uint8_t tab[256];
    for (int q = 0; q < 256; q++)
        tab[q] = (uint8_t)btf_webp_y_of_q(q);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            pic.y[(size_t)y * pic.y_stride + x] = tab[grey[(size_t)y * w + x]];
    for (int y = 0; y < (h + 1) / 2; y++) {
        memset(pic.u + (size_t)y * pic.uv_stride, 128, (size_t)(w + 1) / 2);
        memset(pic.v + (size_t)y * pic.uv_stride, 128, (size_t)(w + 1) / 2);
    }
    return btf__encode(&cfg, &pic, out, n, err);
}

btf_result btf_webp_encode_rgb_lossy(const uint8_t *rgb, int w, int h, int quality, uint8_t **out, size_t *n,
                                     btf_error *err)
{
    WebPConfig cfg;
    WebPPicture pic;
    *out = NULL, *n = 0;
    btf_result r = btf__lossy_setup(w, h, quality, &cfg, &pic, err);
    if (r != BTF_OK)
        return r;
    if (!WebPPictureImportRGB(&pic, rgb, 3 * w)) {
        WebPPictureFree(&pic);
        return btf_fail(err, BTF_ERR_NOMEM, "webp: out of memory (%dx%d)", w, h);
    }
    return btf__encode(&cfg, &pic, out, n, err);
}

/* A WebP that btf_webp_check accepts and whose header says w x h, decoded into *px
 * (malloc'd; the caller frees it): RGB for a lossy file (*ch 3), RGBA for a lossless
 * one (*ch 4); nothing allocated before the check and the size pass. */
static btf_result btf__decode_px(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t **px,
                                 int *ch, btf_error *err)
{
    int fw = 0, fh = 0;
    *px = NULL;
    btf_result r = btf_webp_check(data, n, what, &fw, &fh, err);
    if (r != BTF_OK)
        return r;
    if (fw != w || fh != h)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: WebP of %dx%d, expected %dx%d", what, fw, fh, w, h);
    int lossy = btf_webp_is_lossy(data, n);
    size_t np = (size_t)w * (size_t)h;
    *ch = lossy ? 3 : 4;
    if (!(*px = malloc(np * (size_t)*ch)))
        return btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate %dx%d pixels", what, w, h);
    uint8_t *got = lossy ? WebPDecodeRGBInto(data, n, *px, np * 3, w * 3) : WebPDecodeRGBAInto(data, n, *px, np * 4, w * 4);
    if (!got)
        free(*px), *px = NULL;
    return got ? BTF_OK : btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode WebP data", what);
}

btf_result btf_webp_decode_grey(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                                btf_error *err)
{
    uint8_t *px = NULL;
    int ch = 0;
    btf_result r = btf__decode_px(data, n, what, w, h, &px, &ch, err);
    for (size_t i = 0; r == BTF_OK && i < (size_t)w * (size_t)h; i++) {
        const uint8_t *p = px + i * (size_t)ch;
        if (ch == 4 && (p[1] != p[0] || p[2] != p[0] || p[3] != 255))
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: not a grey image (channels differ at pixel %zu)", what, i);
        grey[i] = p[0];
    }
    free(px);
    return r;
}

btf_result btf_webp_decode_rgb(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *rgb,
                               btf_error *err)
{
    uint8_t *px = NULL;
    int ch = 0;
    btf_result r = btf__decode_px(data, n, what, w, h, &px, &ch, err);
    if (r == BTF_OK && ch == 3)
        memcpy(rgb, px, (size_t)w * (size_t)h * 3);
    for (size_t i = 0; r == BTF_OK && ch == 4 && i < (size_t)w * (size_t)h; i++) {
        if (px[4 * i + 3] != 255)
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: pixel %zu is not opaque (alpha %u)", what, i, px[4 * i + 3]);
        memcpy(rgb + 3 * i, px + 4 * i, 3);
    }
    free(px);
    return r;
}
