/* btf_lossy.c - lossy WebP or AVIF by one name (btf_lossy.h). */
#include "btf_lossy.h"
#include "btf_avif.h"
#include "btf_common.h"
#include "btf_webp.h"

/* Coarse to fine. WebP: the qualities measured in doc/performance.md section 11.
 * AVIF: AV1 quantisers spanning about the same errors on component atlases (quantiser
 * 4 about quality 100's error, 56 about quality 0's; section 11, "AVIF"). */
static const int btf__webp_ladder[BTF_LOSSY_LADDER] = {0, 10, 20, 35, 50, 60, 70, 78, 85, 90, 94, 97, 100};
static const int btf__avif_ladder[BTF_LOSSY_LADDER] = {56, 48, 42, 36, 31, 27, 23, 19, 16, 13, 10, 7, 4};
/* The same with more rungs where a coarse spatial level lands (WebP qualities 2-20 on
 * generated tiles at 128x128, where quality 0 to 10 doubled a file's bytes). */
static const int btf__webp_fine[BTF_LOSSY_FINE] = {0,  2,  4,  6,  8,  10, 13, 16, 20, 25, 30,
                                                   35, 42, 50, 60, 70, 78, 85, 90, 94, 97, 100};
static const int btf__avif_fine[BTF_LOSSY_FINE] = {63, 61, 59, 57, 56, 54, 52, 50, 48, 45, 42,
                                                   39, 36, 31, 27, 23, 19, 16, 13, 10, 7,  4};

int btf_lossy_codec_of(const uint8_t *data, size_t n)
{
    return btf_webp_is_lossy(data, n) ? BTF_LOSSY_WEBP : btf_avif_is_avif(data, n) ? BTF_LOSSY_AVIF : BTF_LOSSY_NONE;
}

const char *btf_lossy_ext(int codec)
{
    return codec == BTF_LOSSY_AVIF ? ".avif" : ".webp";
}

const char *btf_lossy_name(int codec)
{
    return codec == BTF_LOSSY_AVIF ? "avif" : "webp";
}

int btf_lossy_max_level(int codec)
{
    return codec == BTF_LOSSY_AVIF ? BTF_AVIF_MAX_QUANTIZER : 100;
}

int btf_lossy_ladder(int codec, int i)
{
    i = i < 0 ? 0 : i >= BTF_LOSSY_LADDER ? BTF_LOSSY_LADDER - 1 : i;
    return codec == BTF_LOSSY_AVIF ? btf__avif_ladder[i] : btf__webp_ladder[i];
}

int btf_lossy_fine(int codec, int i)
{
    i = i < 0 ? 0 : i >= BTF_LOSSY_FINE ? BTF_LOSSY_FINE - 1 : i;
    return codec == BTF_LOSSY_AVIF ? btf__avif_fine[i] : btf__webp_fine[i];
}

btf_result btf_lossy_encode(int codec, const uint8_t *grey, int w, int h, int level, uint8_t **out, size_t *n,
                            btf_error *err)
{
    if (codec == BTF_LOSSY_AVIF)
        return btf_avif_encode_grey(grey, w, h, level, out, n, err);
    return btf_webp_encode_grey_lossy(grey, w, h, level, out, n, err);
}

btf_result btf_lossy_decode(const uint8_t *data, size_t n, const char *what, int w, int h, uint8_t *grey,
                            btf_error *err)
{
    if (btf_lossy_codec_of(data, n) == BTF_LOSSY_AVIF)
        return btf_avif_decode_grey(data, n, what, w, h, grey, err);
    return btf_webp_decode_grey(data, n, what, w, h, grey, err);
}
