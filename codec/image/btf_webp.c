/* btf_webp.c - lossless WebP for grey textures: libwebp's encoder, a RIFF/VP8L check. */
#include "btf_webp.h"
#include "btf_common.h"

#include <stdlib.h>
#include <string.h>
#include <webp/encode.h>

/* libwebp's lossless effort preset (0..9): on component atlases 3 makes files
 * nearly as small as 9's at a small part of the time, and 6 is no smaller than 3
 * (doc/package-format.md section 11.2). */
#define BTF_WEBP_LEVEL 3

static uint32_t btf__le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

int btf_webp_is_webp(const uint8_t *data, size_t n)
{
    return n >= 12 && !memcmp(data, "RIFF", 4) && !memcmp(data + 8, "WEBP", 4);
}

btf_result btf_webp_check(const uint8_t *data, size_t n, const char *what, int *w, int *h, btf_error *err)
{
    if (!btf_webp_is_webp(data, n))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a WebP file (no RIFF/WEBP signature)", what);
    if (n < 25)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: WebP file of %zu bytes is truncated", what, n);
    uint32_t riff = btf__le32(data + 4), chunk = btf__le32(data + 16);
    if ((unsigned long long)riff + 8 != n)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: RIFF size %u does not match the file's %zu bytes", what, riff, n);
    if (memcmp(data + 12, "VP8L", 4))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: WebP chunk '%.4s' is not a lossless image (VP8L)", what,
                        (const char *)data + 12);
    if (chunk < 5 || (unsigned long long)chunk + 20 + (chunk & 1) != n)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: VP8L chunk of %u bytes does not fill the file", what, chunk);
    uint32_t bits = btf__le32(data + 21);
    if (data[20] != 0x2f || bits >> 29 != 0)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: bad VP8L signature or version", what);
    if (w)
        *w = (int)(bits & 0x3fff) + 1;
    if (h)
        *h = (int)((bits >> 14) & 0x3fff) + 1;
    return BTF_OK;
}

btf_result btf_webp_encode_grey(const uint8_t *grey, int w, int h, uint8_t **out, size_t *n, btf_error *err)
{
    *out = NULL, *n = 0;
    if (w < 1 || h < 1 || w > WEBP_MAX_DIMENSION || h > WEBP_MAX_DIMENSION)
        return btf_fail(err, BTF_ERR_ARG, "webp: %dx%d is outside 1..%d", w, h, WEBP_MAX_DIMENSION);
    WebPConfig cfg;
    WebPPicture pic;
    WebPMemoryWriter mw;
    if (!WebPConfigInit(&cfg) || !WebPConfigLosslessPreset(&cfg, BTF_WEBP_LEVEL) || !WebPPictureInit(&pic))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "webp: libwebp version mismatch");
    cfg.exact = 1;
    pic.use_argb = 1, pic.width = w, pic.height = h;
    if (!WebPPictureAlloc(&pic))
        return btf_fail(err, BTF_ERR_NOMEM, "webp: out of memory (%dx%d)", w, h);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            uint32_t g = grey[(size_t)y * w + x];
            pic.argb[(size_t)y * pic.argb_stride + x] = 0xff000000u | g << 16 | g << 8 | g;
        }
    WebPMemoryWriterInit(&mw);
    pic.writer = WebPMemoryWrite, pic.custom_ptr = &mw;
    int ok = WebPEncode(&cfg, &pic);
    int code = pic.error_code;
    WebPPictureFree(&pic);
    if (ok && (*out = malloc(mw.size ? mw.size : 1)) != NULL) {
        memcpy(*out, mw.mem, mw.size);
        *n = mw.size;
    }
    WebPMemoryWriterClear(&mw);
    if (!ok)
        return btf_fail(err, BTF_ERR_IO, "webp: encoding failed (libwebp error %d)", code);
    return *out ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "webp: out of memory");
}
