// btf_image.cpp - the one C++ file: OpenImageIO behind the C API of btf_image.h.
#include "btf_image.h"
#include "btf_fs.h"
#include "btf_png.h"
#include "btf_webp.h"
#include "btf_common.h"

#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>
#include <algorithm>
#include <strings.h>
#include <unistd.h>

using namespace OIIO;

static const int kMaxSide = 1 << 15;

// OpenImageIO's message on one line (its errors may span several).
static std::string one_line(std::string e)
{
    for (char &c : e)
        if (c == '\n' || c == '\r')
            c = ' ';
    while (!e.empty() && e.back() == ' ')
        e.pop_back();
    return e;
}

// A PNG must pass btf_png_check before OpenImageIO sees it (no decoder messages on
// stderr, one clear error); other formats go straight to OpenImageIO.
static btf_result check_file(const char *path, int header_only, btf_error *err)
{
    uint8_t head[8];
    size_t n = 0;
    FILE *f = std::fopen(path, "rb");
    if (!f)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot open image", path);
    n = std::fread(head, 1, sizeof head, f);
    std::fclose(f);
    size_t len = strlen(path);
    int png = (n >= 4 && !memcmp(head, "\x89PNG", 4)) || (len > 4 && !strcasecmp(path + len - 4, ".png"));
    int webp = (n >= 4 && !memcmp(head, "RIFF", 4)) || (len > 5 && !strcasecmp(path + len - 5, ".webp"));
    if (!png && !webp) /* PNG or WebP by its magic or its name: checked; others go to OIIO */
        return BTF_OK;
    char *data = nullptr;
    btf_result r = btf_fs_read(path, (size_t)1 << 30, &data, &n, err);
    if (r == BTF_OK && webp && !png)
        r = btf_webp_check((const uint8_t *)data, n, path, nullptr, nullptr, err);
    else if (r == BTF_OK)
        r = header_only ? btf_png_check_header((const uint8_t *)data, n, path, err)
                        : btf_png_check((const uint8_t *)data, n, path, err);
    free(data);
    return r == BTF_ERR_MISSING ? BTF_ERR_IO : r;
}

// Opens path for reading with alpha left unassociated, after check_file (the header
// alone when only the size is wanted); NULL with *r and err set on failure.
static std::unique_ptr<ImageInput> open_input(const char *path, int header_only, btf_result *r, btf_error *err)
{
    if ((*r = check_file(path, header_only, err)) != BTF_OK)
        return nullptr;
    ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = ImageInput::open(path, &config);
    if (!in)
        *r = btf_fail(err, BTF_ERR_IO, "%s: cannot open image (%s)", path, one_line(OIIO::geterror()).c_str());
    return in;
}

extern "C" btf_result btf_image_info(const char *path, int *w, int *h, int *channels, btf_error *err)
{
    btf_result r = BTF_OK;
    auto in = open_input(path, 1, &r, err);
    if (!in)
        return r;
    const ImageSpec &s = in->spec();
    *w = s.width;
    *h = s.height;
    *channels = s.nchannels;
    in->close();
    return BTF_OK;
}

// open_input for the pixels, then a 2-D image of 1..4 channels, each side 1..max_side;
// NULL with *r and err set otherwise.
static std::unique_ptr<ImageInput> open_image(const char *path, int max_side, btf_result *r, btf_error *err)
{
    auto in = open_input(path, 0, r, err);
    if (!in)
        return in;
    const ImageSpec &s = in->spec();
    if (s.width < 1 || s.height < 1 || s.width > max_side || s.height > max_side || s.nchannels < 1 ||
        s.nchannels > 4 || s.depth != 1) {
        *r = btf_fail(err, BTF_ERR_FORMAT, "%s: unsupported image %dx%dx%d (depth %d; at most %d per side)", path,
                      s.width, s.height, s.nchannels, s.depth, max_side);
        return nullptr;
    }
    return in;
}

extern "C" btf_result btf_image_read_u8(const char *path, int *w, int *h, int *channels, uint8_t **pixels,
                                        btf_error *err)
{
    *pixels = nullptr;
    btf_result r = BTF_OK;
    auto in = open_image(path, kMaxSide, &r, err);
    if (!in)
        return r;
    const ImageSpec &s = in->spec();
    size_t n = (size_t)s.width * (size_t)s.height * (size_t)s.nchannels;
    long long file = btf_fs_size(path);
    if (!strcmp(in->format_name(), "webp") && (double)n > (double)file * BTF_IMAGE_MAX_PNG_RATIO &&
        n > BTF_IMAGE_MAX_WEBP_FLOOR)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: a %lld-byte WebP claims %dx%dx%d pixels (over %dx its size and %d MiB)",
                        path, file, s.width, s.height, s.nchannels, BTF_IMAGE_MAX_PNG_RATIO,
                        BTF_IMAGE_MAX_WEBP_FLOOR >> 20);
    if (!strcmp(in->format_name(), "png") && (double)n > (double)file * BTF_IMAGE_MAX_PNG_RATIO)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: a %lld-byte PNG cannot hold %dx%dx%d pixels (deflate expands at most %dx)",
                        path, file, s.width, s.height, s.nchannels, BTF_IMAGE_MAX_PNG_RATIO);
    uint8_t *buf = (uint8_t *)malloc(n);
    if (!buf)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate %zu bytes", path, n);
    if (!in->read_image(0, 0, 0, s.nchannels, TypeDesc::UINT8, buf)) {
        std::string e = one_line(in->geterror());
        free(buf);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode image (%s)", path, e.c_str());
    }
    in->close();
    *w = s.width;
    *h = s.height;
    *channels = s.nchannels;
    *pixels = buf;
    return BTF_OK;
}

// Adds row y of a w-pixel image (ch channels, float) into the reduced rows of acc
// (ow pixels, RGB, plus a count per pixel) at box factor f; 0, or -1 with the first
// bad sample's column in *bad.
static int add_row(const float *row, int w, int ch, int f, double *acc, int *bad)
{
    for (int x = 0; x < w; x++) {
        const float *p = row + (size_t)x * ch;
        double *o = acc + (size_t)(x / f) * 4;
        for (int c = 0; c < 3; c++) {
            float v = p[ch >= 3 ? c : 0];
            if (!(v >= 0.0f) || v > 3.0e38f) {
                *bad = x;
                return -1;
            }
            o[c] += v;
        }
        o[3] += 1.0;
    }
    return 0;
}

extern "C" btf_result btf_image_read_rgb_f32(const char *path, int max_w, int max_h, int *w, int *h, float **rgb,
                                             btf_error *err)
{
    *rgb = nullptr;
    if (max_w < 1 || max_h < 1)
        return btf_fail(err, BTF_ERR_ARG, "%s: bound %dx%d", path, max_w, max_h);
    btf_result r = BTF_OK;
    auto in = open_image(path, BTF_IMAGE_MAX_F32_SIDE, &r, err);
    if (!in)
        return r;
    const ImageSpec &s = in->spec();
    int f = 1;
    while ((s.width + f - 1) / f > max_w || (s.height + f - 1) / f > max_h)
        f++;
    int ow = (s.width + f - 1) / f, oh = (s.height + f - 1) / f;
    std::vector<float> row((size_t)s.width * s.nchannels);
    std::vector<double> acc((size_t)ow * 4);
    float *out = (float *)malloc((size_t)ow * oh * 3 * sizeof(float));
    if (!out)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    for (int y = 0; y < s.height && r == BTF_OK; y++) {
        int bad = 0;
        if (!in->read_scanline(y, 0, TypeDesc::FLOAT, row.data()))
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode row %d (%s)", path, y, one_line(in->geterror()).c_str());
        else if (add_row(row.data(), s.width, s.nchannels, f, acc.data(), &bad))
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: pixel (%d, %d) is negative or not finite", path, bad, y);
        if (r != BTF_OK || ((y + 1) % f && y + 1 < s.height))
            continue;
        for (int x = 0; x < ow; x++) /* a reduced row is complete */
            for (int c = 0; c < 3; c++)
                out[((size_t)(y / f) * ow + x) * 3 + c] = (float)(acc[(size_t)x * 4 + c] / acc[(size_t)x * 4 + 3]);
        std::fill(acc.begin(), acc.end(), 0.0);
    }
    in->close();
    if (r != BTF_OK) {
        free(out);
        return r;
    }
    *w = ow, *h = oh, *rgb = out;
    return BTF_OK;
}

// Encodes pixels into the file tmp; png_filter: libpng's filter mask (0 = its adaptive
// default), for PNG files only.
static btf_result encode_image(const std::string &tmp, const char *path, int w, int h, int channels, int bits,
                               const void *pixels, int png_filter, btf_error *err)
{
    auto out = ImageOutput::create(tmp);
    if (!out)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: no writer for this extension", path);
    ImageSpec spec(w, h, channels, bits == 8 ? TypeDesc::UINT8 : TypeDesc::UINT16);
    spec.attribute("oiio:UnassociatedAlpha", 1);
    spec.attribute("png:compressionLevel", 9); // PNG: deflate level 9 (the writer's default is 6)
    if (png_filter)
        spec.attribute("png:filter", png_filter);
    if (!out->open(tmp, spec))
        return btf_fail(err, BTF_ERR_IO, "%s: cannot create (%s)", tmp.c_str(), one_line(out->geterror()).c_str());
    bool ok = out->write_image(bits == 8 ? TypeDesc::UINT8 : TypeDesc::UINT16, pixels);
    ok = out->close() && ok;
    if (!ok) {
        std::string e = one_line(out->geterror());
        std::remove(tmp.c_str());
        return btf_fail(err, BTF_ERR_IO, "%s: write failed (%s)", path, e.c_str());
    }
    return BTF_OK;
}

// With BTF_IMAGE_PNG_SMALLEST: the filter choice that deflates smallest among libpng's
// per-row adaptive one and filter None, Up or Average on every row, judged on the
// image's middle 64 rows (the whole image when it has at most 128), then the whole
// image in tmp with that choice. Up wins on most component atlases, Average on some,
// None on residuals; Sub and Paeth did not win on the materials measured
// (doc/package-format.md section 11.2). The strip's choice is nearly always the
// whole image's; it can lose a little to the adaptive choice, where comparing both
// on the whole image would cost a second full encoding.
static btf_result encode_smallest_png(const std::string &tmp, const std::string &ext, const char *path, int w, int h,
                                      int channels, int bits, const void *pixels, btf_error *err)
{
    static const int filters[4] = {0, 0x08, 0x20, 0x40}; // adaptive, None, Up, Average (libpng's masks)
    const int strip = 64;
    int sh = h <= 2 * strip ? h : strip, y0 = h <= 2 * strip ? 0 : h / 2 - strip / 2;
    const unsigned char *rows = (const unsigned char *)pixels + (size_t)y0 * w * channels * (bits / 8);
    std::string cand = tmp + ".f" + ext;
    long long best = -1;
    int pick = 0;
    btf_result r = BTF_OK;
    for (int i = 0; r == BTF_OK && i < 4; i++) {
        r = encode_image(cand, path, w, sh, channels, bits, rows, filters[i], err);
        long long n = r == BTF_OK ? btf_fs_size(cand.c_str()) : -1;
        if (n >= 0 && (best < 0 || n < best)) {
            best = n, pick = i;
            if (sh == h && std::rename(cand.c_str(), tmp.c_str()) != 0) // the strip is the image: keep it
                r = btf_fail(err, BTF_ERR_IO, "%s: cannot rename temporary file", path);
        }
    }
    std::remove(cand.c_str());
    if (r == BTF_OK && sh != h)
        r = encode_image(tmp, path, w, h, channels, bits, pixels, filters[pick], err);
    if (r != BTF_OK)
        std::remove(tmp.c_str());
    return r;
}

// Bytes into the new file tmp (stdio; the caller syncs and renames).
static btf_result write_bytes(const std::string &tmp, const char *path, const uint8_t *data, size_t n, btf_error *err)
{
    FILE *f = std::fopen(tmp.c_str(), "wb");
    if (!f)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot create", tmp.c_str());
    bool ok = std::fwrite(data, 1, n, f) == n;
    ok = std::fclose(f) == 0 && ok;
    if (!ok) {
        std::remove(tmp.c_str());
        return btf_fail(err, BTF_ERR_IO, "%s: write failed", path);
    }
    return BTF_OK;
}

// WebP (grey 8-bit only) through libwebp: OpenImageIO 2.4's WebP writer imports the
// pixels through YUV, so its "lossless" files do not give the same bytes back.
static btf_result encode_webp(const std::string &tmp, const char *path, int w, int h, int channels, int bits,
                              const void *pixels, btf_error *err)
{
    if (channels != 1 || bits != 8)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: WebP is written for 8-bit grey images only", path);
    uint8_t *buf = nullptr;
    size_t n = 0;
    btf_result r = btf_webp_encode_grey((const uint8_t *)pixels, w, h, &buf, &n, err);
    if (r == BTF_OK)
        r = write_bytes(tmp, path, buf, n, err);
    free(buf);
    return r;
}

// "PATH.tmp-PID.EXT" for path, the extension kept last so OpenImageIO picks the
// format from the temp name; ext gets ".EXT" (empty without one).
static std::string temp_path(const char *path, std::string *ext)
{
    std::string p(path);
    size_t dot = p.find_last_of('.');
    *ext = dot == std::string::npos ? std::string() : p.substr(dot);
    return p + ".tmp-" + std::to_string((long)getpid()) + *ext;
}

// Encodes into tmp as path's extension says (PNG with the flags' filter choice).
static btf_result encode_any(const std::string &tmp, const std::string &ext, const char *path, int w, int h,
                             int channels, int bits, const void *pixels, int flags, btf_error *err)
{
    int png = ext == ".png" || ext == ".PNG";
    if (ext == ".webp" || ext == ".WEBP")
        return encode_webp(tmp, path, w, h, channels, bits, pixels, err);
    if (png && (flags & BTF_IMAGE_PNG_SMALLEST))
        return encode_smallest_png(tmp, ext, path, w, h, channels, bits, pixels, err);
    int filter = !png ? 0 : (flags & BTF_IMAGE_PNG_UNFILTERED) ? 0x08 : (flags & BTF_IMAGE_PNG_UP) ? 0x20 : 0;
    return encode_image(tmp, path, w, h, channels, bits, pixels, filter, err);
}

// tmp into place at path: fsync of the file and the directory unless BTF_IMAGE_UNSYNCED.
static btf_result commit(const std::string &tmp, const char *path, int flags, btf_error *err)
{
    if (!(flags & BTF_IMAGE_UNSYNCED))
        return btf_fs_commit_file(tmp.c_str(), path, err); // fsync, rename, fsync of the directory
    if (std::rename(tmp.c_str(), path) != 0) {
        std::remove(tmp.c_str());
        return btf_fail(err, BTF_ERR_IO, "%s: cannot rename temporary file", path);
    }
    return BTF_OK;
}

static int bad_params(int w, int h, int channels, int bits)
{
    return w < 1 || h < 1 || w > kMaxSide || h > kMaxSide || channels < 1 || channels > 4 || (bits != 8 && bits != 16);
}

// Writes through "PATH.tmp-PID.EXT" and renames.
static btf_result write_image(const char *path, int w, int h, int channels, int bits, const void *pixels, int flags,
                              btf_error *err)
{
    if (bad_params(w, h, channels, bits))
        return btf_fail(err, BTF_ERR_ARG, "%s: bad image parameters %dx%dx%d/%d", path, w, h, channels, bits);
    std::string ext, tmp = temp_path(path, &ext);
    btf_result r = encode_any(tmp, ext, path, w, h, channels, bits, pixels, flags, err);
    return r == BTF_OK ? commit(tmp, path, flags, err) : r;
}

extern "C" btf_result btf_image_write_smallest(const char *stem, int w, int h, const uint8_t *grey, int flags,
                                               const char **ext, long long *bytes, btf_error *err)
{
    std::string png = std::string(stem) + ".png", webp = std::string(stem) + ".webp", pext, wext;
    *ext = ".png", *bytes = -1;
    if (bad_params(w, h, 1, 8))
        return btf_fail(err, BTF_ERR_ARG, "%s: bad image parameters %dx%d", png.c_str(), w, h);
    std::string ptmp = temp_path(png.c_str(), &pext), wtmp = temp_path(webp.c_str(), &wext);
    btf_result r = encode_any(ptmp, pext, png.c_str(), w, h, 1, 8, grey, flags, err);
    long long pn = r == BTF_OK ? btf_fs_size(ptmp.c_str()) : -1, wn = -1;
    if (r == BTF_OK && !(flags & BTF_IMAGE_NO_WEBP)) {
        r = encode_webp(wtmp, webp.c_str(), w, h, 1, 8, grey, err);
        wn = r == BTF_OK ? btf_fs_size(wtmp.c_str()) : -1;
    }
    if (r == BTF_OK && (pn < 0 || ((flags & BTF_IMAGE_NO_WEBP) == 0 && wn < 0)))
        r = btf_fail(err, BTF_ERR_IO, "%s: encoded file vanished", stem);
    int use_webp = r == BTF_OK && wn >= 0 && wn < pn;
    std::remove((use_webp ? ptmp : wtmp).c_str());
    if (r != BTF_OK) {
        std::remove(ptmp.c_str());
        return r;
    }
    *ext = use_webp ? ".webp" : ".png", *bytes = use_webp ? wn : pn;
    return use_webp ? commit(wtmp, webp.c_str(), flags, err) : commit(ptmp, png.c_str(), flags, err);
}

extern "C" btf_result btf_image_read_grey(const char *path, int *w, int *h, uint8_t **pixels, btf_error *err)
{
    int ch = 0;
    btf_result r = btf_image_read_u8(path, w, h, &ch, pixels, err);
    if (r != BTF_OK || ch == 1)
        return r;
    uint8_t *px = *pixels;
    size_t n = (size_t)*w * (size_t)*h;
    for (size_t i = 0; i < n; i++) {
        const uint8_t *p = px + i * (size_t)ch;
        if (ch < 3 || p[1] != p[0] || p[2] != p[0] || (ch == 4 && p[3] != 255)) {
            free(px);
            *pixels = nullptr;
            return btf_fail(err, BTF_ERR_FORMAT, "%s: not a grey image (%d channels that differ at pixel %zu)", path,
                            ch, i);
        }
        px[i] = p[0];
    }
    return BTF_OK;
}

extern "C" btf_result btf_image_write(const char *path, int w, int h, int channels, int bits, const void *pixels,
                                      btf_error *err)
{
    return write_image(path, w, h, channels, bits, pixels, 0, err);
}

extern "C" btf_result btf_image_write_flags(const char *path, int w, int h, int channels, int bits, const void *pixels,
                                            int flags, btf_error *err)
{
    return write_image(path, w, h, channels, bits, pixels, flags, err);
}

extern "C" btf_result btf_image_write_unsynced(const char *path, int w, int h, int channels, int bits,
                                               const void *pixels, btf_error *err)
{
    return write_image(path, w, h, channels, bits, pixels, BTF_IMAGE_UNSYNCED, err);
}
