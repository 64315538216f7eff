// btf_image_oiio.cpp - the one C++ file: OpenImageIO behind the C API of btf_image.h,
// built on its own as the module btf_image_oiio.so (btf_image_module.h), which
// btf_image.c loads on the first image call. It calls the codec only through the
// host table it is opened with (H below): the names of those functions are macros here.
#include "btf_image.h"
#include "btf_image_module.h"
#include "btf_fs.h"
#include "btf_png.h"
#include "btf_avif.h"
#include "btf_lossy.h"
#include "btf_webp.h"
#include "btf_common.h"

#include <OpenImageIO/filesystem.h>
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

static const btf_image_host *H; // the program's table, set once by btf_image_oiio_open
#define btf_fail H->fail
#define btf_fs_read_with H->fs_read_with
#define btf_fs_size H->fs_size
#define btf_fs_commit_file H->fs_commit_file
#define btf_png_check H->png_check
#define btf_png_check_header H->png_check_header
#define btf_webp_check H->webp_check
#define btf_webp_encode_grey H->webp_encode_grey
#define btf_avif_is_avif H->avif_is_avif
#define btf_avif_check H->avif_check
#define btf_lossy_codec_of H->lossy_codec_of
#define btf_lossy_decode H->lossy_decode

static const int kMaxSide = 1 << 15;
static const size_t kMaxFileBytes = (size_t)1 << 30; // a larger PNG, WebP or AVIF is refused unread

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

// One image being read: its name in messages and, for a PNG, a WebP or an AVIF, its
// bytes (read from the file, or the caller's), which OpenImageIO (an AVIF: libavif)
// decodes from memory; a file of another format OpenImageIO opens by name. A stack value of one read,
// owning the bytes it read and the memory reader; declared before the ImageInput
// that reads through it.
struct source {
    const char *what = nullptr;
    const uint8_t *data = nullptr;
    size_t n = 0;
    const char *format = nullptr; // "png", "webp" or "avif" once checked; nullptr: another format, from the file
    char *file = nullptr;         // the bytes read from the file (malloc'd)
    std::unique_ptr<Filesystem::IOMemReader> mem;
    ~source() { free(file); }
};

// 1 when the name ends in ext (".png"), ignoring case.
static int has_ext(const char *name, const char *ext)
{
    size_t len = strlen(name), e = strlen(ext);
    return len > e && !strcasecmp(name + len - e, ext);
}

// "png", "webp" or "avif" by the first n bytes or by the name; nullptr for another format.
static const char *own_format(const uint8_t *head, size_t n, const char *name)
{
    if ((n >= 4 && !memcmp(head, "\x89PNG", 4)) || has_ext(name, ".png"))
        return "png";
    if ((n >= 4 && !memcmp(head, "RIFF", 4)) || has_ext(name, ".webp"))
        return "webp";
    return btf_avif_is_avif(head, n) || has_ext(name, ".avif") ? "avif" : nullptr;
}

// 1 for a file read as grey through btf_webp or btf_avif, not OpenImageIO: a lossy
// WebP or an AVIF (checked in s).
static int lossy_file(const source &s)
{
    return s.format && btf_lossy_codec_of(s.data, s.n) != BTF_LOSSY_NONE;
}

// A PNG must pass btf_png_check before OpenImageIO sees it (no decoder messages on
// stderr, one clear error), a WebP btf_webp_check, an AVIF btf_avif_check; a ".png"
// holding another format is refused as not a PNG.
static btf_result check_bytes(source &s, int header_only, btf_error *err)
{
    s.format = own_format(s.data, s.n, s.what);
    if (!s.format)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a PNG, WebP or AVIF image", s.what);
    if (!strcmp(s.format, "webp"))
        return btf_webp_check(s.data, s.n, s.what, nullptr, nullptr, err);
    if (!strcmp(s.format, "avif"))
        return btf_avif_check(s.data, s.n, s.what, nullptr, nullptr, err);
    return header_only ? btf_png_check_header(s.data, s.n, s.what, err) : btf_png_check(s.data, s.n, s.what, err);
}

// The bytes of the PNG, WebP or AVIF at path, read through files (NULL: the disk), into s
// and checked (the header only, or the whole file).
static btf_result load_with(const btf_files *files, const char *path, int header_only, source &s, btf_error *err)
{
    s.what = path;
    btf_result r = btf_fs_read_with(files, path, kMaxFileBytes, &s.file, &s.n, err);
    s.data = (const uint8_t *)s.file;
    return r == BTF_OK ? check_bytes(s, header_only, err) : r;
}

// The file at path into s: a PNG, WebP or AVIF (by its magic or its name) read and checked,
// any other format left for OpenImageIO to open by name.
static btf_result load_file(const char *path, int header_only, source &s, btf_error *err)
{
    uint8_t head[12];
    s.what = path;
    FILE *f = std::fopen(path, "rb");
    if (!f)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot open image", path);
    size_t n = std::fread(head, 1, sizeof head, f);
    std::fclose(f);
    if (!own_format(head, n, path))
        return BTF_OK;
    btf_result r = load_with(nullptr, path, header_only, s, err);
    return r == BTF_ERR_MISSING ? BTF_ERR_IO : r; // gone since it was opened
}

// Opens s for reading with alpha left unassociated: the checked bytes through a
// memory reader, another format by name; NULL with *r and err set on failure.
static std::unique_ptr<ImageInput> open_input(source &s, btf_result *r, btf_error *err)
{
    ImageSpec config, spec;
    config.attribute("oiio:UnassociatedAlpha", 1);
    if (s.format && !strcmp(s.format, "avif")) {
        *r = btf_fail(err, BTF_ERR_FORMAT, "%s: an AVIF is read only as a grey texture", s.what);
        return nullptr;
    }
    if (!s.format) {
        auto in = ImageInput::open(s.what, &config);
        if (!in)
            *r = btf_fail(err, BTF_ERR_IO, "%s: cannot open image (%s)", s.what, one_line(OIIO::geterror()).c_str());
        return in;
    }
    s.mem.reset(new Filesystem::IOMemReader(s.data, s.n));
    Filesystem::IOProxy *proxy = s.mem.get(); // OpenImageIO 2.4 takes it from the configuration only
    config.attribute("oiio:ioproxy", TypeDesc::PTR, &proxy);
    auto in = ImageInput::create(s.format, false, &config);
    if (in && in->open(s.what, spec, config))
        return in;
    std::string e = one_line(in ? in->geterror() : OIIO::geterror());
    *r = btf_fail(err, BTF_ERR_IO, "%s: cannot open image (%s)", s.what, e.c_str());
    return nullptr;
}

// The header of s: size and channel count (an AVIF: grey, from its own check).
static btf_result info(source &s, int *w, int *h, int *channels, btf_error *err)
{
    btf_result r = BTF_OK;
    if (s.format && !strcmp(s.format, "avif")) {
        *channels = 1;
        return btf_avif_check(s.data, s.n, s.what, w, h, err);
    }
    auto in = open_input(s, &r, err);
    if (!in)
        return r;
    const ImageSpec &sp = in->spec();
    *w = sp.width;
    *h = sp.height;
    *channels = sp.nchannels;
    in->close();
    return BTF_OK;
}

static btf_result oiio_info(const char *path, int *w, int *h, int *channels, btf_error *err)
{
    source s;
    btf_result r = load_file(path, 1, s, err);
    return r == BTF_OK ? info(s, w, h, channels, err) : r;
}

static btf_result oiio_info_with(const btf_files *files, const char *path, int *w, int *h, int *channels,
                                          btf_error *err)
{
    source s;
    btf_result r = load_with(files, path, 1, s, err);
    return r == BTF_OK ? info(s, w, h, channels, err) : r;
}

// open_input for the pixels, then a 2-D image of 1..4 channels, each side 1..max_side;
// NULL with *r and err set otherwise.
static std::unique_ptr<ImageInput> open_image(source &s, int max_side, btf_result *r, btf_error *err)
{
    auto in = open_input(s, r, err);
    if (!in)
        return in;
    const ImageSpec &sp = in->spec();
    if (sp.width < 1 || sp.height < 1 || sp.width > max_side || sp.height > max_side || sp.nchannels < 1 ||
        sp.nchannels > 4 || sp.depth != 1) {
        *r = btf_fail(err, BTF_ERR_FORMAT, "%s: unsupported image %dx%dx%d (depth %d; at most %d per side)", s.what,
                      sp.width, sp.height, sp.nchannels, sp.depth, max_side);
        return nullptr;
    }
    return in;
}

// A PNG or WebP whose header claims more pixels than its bytes can hold (the ratios of
// btf_image.h) is refused before the pixels are allocated.
static btf_result check_ratio(const source &s, const char *format, const ImageSpec &sp, size_t n, btf_error *err)
{
    long long file = (long long)s.n; // a PNG or WebP is always read into memory (load_file)
    if (!strcmp(format, "webp") && (double)n > (double)file * BTF_IMAGE_MAX_PNG_RATIO && n > BTF_IMAGE_MAX_WEBP_FLOOR)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: a %lld-byte WebP claims %dx%dx%d pixels (over %dx its size and %d MiB)",
                        s.what, file, sp.width, sp.height, sp.nchannels, BTF_IMAGE_MAX_PNG_RATIO,
                        BTF_IMAGE_MAX_WEBP_FLOOR >> 20);
    if (!strcmp(format, "png") && (double)n > (double)file * BTF_IMAGE_MAX_PNG_RATIO)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: a %lld-byte PNG cannot hold %dx%dx%d pixels (deflate expands at most %dx)",
                        s.what, file, sp.width, sp.height, sp.nchannels, BTF_IMAGE_MAX_PNG_RATIO);
    return BTF_OK;
}

// All pixels as 8-bit samples into buf: a scanline image row by row (read_image
// would take a buffer of 64 MB whatever the image's size), a tiled one whole.
static bool read_pixels(ImageInput *in, const ImageSpec &sp, uint8_t *buf)
{
    if (sp.tile_width)
        return in->read_image(0, 0, 0, sp.nchannels, TypeDesc::UINT8, buf);
    size_t row = (size_t)sp.width * (size_t)sp.nchannels;
    for (int y = 0; y < sp.height; y++)
        if (!in->read_scanline(sp.y + y, sp.z, TypeDesc::UINT8, buf + (size_t)y * row))
            return false;
    return true;
}

// The pixels of s, opened as in, as 8-bit samples (malloc'd into *pixels).
static btf_result decode(ImageInput *in, const source &s, int *w, int *h, int *channels, uint8_t **pixels,
                         btf_error *err)
{
    const ImageSpec &sp = in->spec();
    size_t n = (size_t)sp.width * (size_t)sp.height * (size_t)sp.nchannels;
    btf_result r = check_ratio(s, in->format_name(), sp, n, err);
    if (r != BTF_OK)
        return r;
    uint8_t *buf = (uint8_t *)malloc(n);
    if (!buf)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate %zu bytes", s.what, n);
    if (!read_pixels(in, sp, buf)) {
        std::string e = one_line(in->geterror());
        free(buf);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: cannot decode image (%s)", s.what, e.c_str());
    }
    in->close();
    *w = sp.width;
    *h = sp.height;
    *channels = sp.nchannels;
    *pixels = buf;
    return BTF_OK;
}

// The pixels of s as 8-bit samples (malloc'd into *pixels).
static btf_result read_u8(source &s, int *w, int *h, int *channels, uint8_t **pixels, btf_error *err)
{
    btf_result r = BTF_OK;
    auto in = open_image(s, kMaxSide, &r, err);
    return in ? decode(in.get(), s, w, h, channels, pixels, err) : r;
}

static btf_result oiio_read_u8(const char *path, int *w, int *h, int *channels, uint8_t **pixels,
                                        btf_error *err)
{
    source s;
    *pixels = nullptr;
    btf_result r = load_file(path, 0, s, err);
    return r == BTF_OK ? read_u8(s, w, h, channels, pixels, err) : r;
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

static btf_result oiio_read_rgb_f32(const char *path, int max_w, int max_h, int *w, int *h, float **rgb,
                                             btf_error *err)
{
    *rgb = nullptr;
    if (max_w < 1 || max_h < 1)
        return btf_fail(err, BTF_ERR_ARG, "%s: bound %dx%d", path, max_w, max_h);
    source src;
    btf_result r = load_file(path, 0, src, err);
    auto in = r == BTF_OK ? open_image(src, BTF_IMAGE_MAX_F32_SIDE, &r, err) : nullptr;
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

// Encodes pixels into the file tmp, or with mem into *mem instead (nothing on disk;
// the format still from tmp's extension); png_filter: libpng's filter mask (0 = its
// adaptive default), for PNG files only.
static btf_result encode_image(const std::string &tmp, const char *path, int w, int h, int channels, int bits,
                               const void *pixels, int png_filter, std::vector<unsigned char> *mem, btf_error *err)
{
    std::unique_ptr<Filesystem::IOVecOutput> proxy; // outlives out, which writes into it until closed
    auto out = ImageOutput::create(tmp);
    if (!out)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: no writer for this extension", path);
    if (mem) {
        mem->clear(); // the proxy writes from offset 0 and keeps whatever lies beyond
        proxy.reset(new Filesystem::IOVecOutput(*mem));
        if (!out->supports("ioproxy") || !out->set_ioproxy(proxy.get()))
            return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: this format cannot be encoded in memory", path);
    }
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
        if (!mem)
            std::remove(tmp.c_str());
        return btf_fail(err, BTF_ERR_IO, "%s: write failed (%s)", path, e.c_str());
    }
    return BTF_OK;
}

// With BTF_IMAGE_PNG_SMALLEST: the filter choice that deflates smallest among libpng's
// per-row adaptive one and filter None, Up or Average on every row, judged on the
// image's middle 64 rows (the whole image when it has at most 128), then the whole
// image in tmp (or *mem) with that choice. Up wins on most component atlases, Average on some,
// None on residuals; Sub and Paeth did not win on the materials measured
// (doc/package-format.md section 11.2). The strip's choice is nearly always the
// whole image's; it can lose a little to the adaptive choice, where comparing both
// on the whole image would cost a second full encoding. The trials are encoded in
// memory; when the strip is the whole image the smallest is written as it is.
static btf_result encode_smallest_png(const std::string &tmp, const char *path, int w, int h, int channels,
                                      int bits, const void *pixels, std::vector<unsigned char> *mem, btf_error *err)
{
    static const int filters[4] = {0, 0x08, 0x20, 0x40}; // adaptive, None, Up, Average (libpng's masks)
    const int strip = 64;
    int sh = h <= 2 * strip ? h : strip, y0 = h <= 2 * strip ? 0 : h / 2 - strip / 2;
    const unsigned char *rows = (const unsigned char *)pixels + (size_t)y0 * w * channels * (bits / 8);
    std::vector<unsigned char> best, cand;
    int pick = 0;
    btf_result r = BTF_OK;
    for (int i = 0; r == BTF_OK && i < 4; i++) {
        r = encode_image(tmp, path, w, sh, channels, bits, rows, filters[i], &cand, err);
        if (r == BTF_OK && (i == 0 || cand.size() < best.size())) // the first of equal sizes
            best.swap(cand), pick = i;
    }
    if (r != BTF_OK || sh != h)
        return r == BTF_OK ? encode_image(tmp, path, w, h, channels, bits, pixels, filters[pick], mem, err) : r;
    if (!mem)
        return write_bytes(tmp, path, best.data(), best.size(), err);
    mem->swap(best);
    return BTF_OK;
}

// WebP (grey 8-bit only) through libwebp: OpenImageIO 2.4's WebP writer imports the
// pixels through YUV, so its "lossless" files do not give the same bytes back.
static btf_result encode_webp(const std::string &tmp, const char *path, int w, int h, int channels, int bits,
                              const void *pixels, std::vector<unsigned char> *mem, btf_error *err)
{
    if (channels != 1 || bits != 8)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: WebP is written for 8-bit grey images only", path);
    uint8_t *buf = nullptr;
    size_t n = 0;
    btf_result r = btf_webp_encode_grey((const uint8_t *)pixels, w, h, &buf, &n, err);
    if (r == BTF_OK && mem)
        mem->assign(buf, buf + n);
    else if (r == BTF_OK)
        r = write_bytes(tmp, path, buf, n, err);
    free(buf);
    return r;
}

// ".EXT" of path (empty without one).
static std::string ext_of(const char *path)
{
    std::string p(path);
    size_t dot = p.find_last_of('.');
    return dot == std::string::npos ? std::string() : p.substr(dot);
}

// "PATH.tmp-PID.EXT" for path, the extension kept last so OpenImageIO picks the
// format from the temp name; ext gets ".EXT" (empty without one).
static std::string temp_path(const char *path, std::string *ext)
{
    *ext = ext_of(path);
    return std::string(path) + ".tmp-" + std::to_string((long)getpid()) + *ext;
}

// Encodes into tmp, or with mem into *mem (nothing on disk), as path's extension
// says (PNG with the flags' filter choice).
static btf_result encode_any(const std::string &tmp, const std::string &ext, const char *path, int w, int h,
                             int channels, int bits, const void *pixels, int flags, std::vector<unsigned char> *mem,
                             btf_error *err)
{
    int png = ext == ".png" || ext == ".PNG";
    if (ext == ".webp" || ext == ".WEBP")
        return encode_webp(tmp, path, w, h, channels, bits, pixels, mem, err);
    if (png && (flags & BTF_IMAGE_PNG_SMALLEST))
        return encode_smallest_png(tmp, path, w, h, channels, bits, pixels, mem, err);
    int filter = !png ? 0 : (flags & BTF_IMAGE_PNG_UNFILTERED) ? 0x08 : (flags & BTF_IMAGE_PNG_UP) ? 0x20 : 0;
    return encode_image(tmp, path, w, h, channels, bits, pixels, filter, mem, err);
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
    btf_result r = encode_any(tmp, ext, path, w, h, channels, bits, pixels, flags, nullptr, err);
    return r == BTF_OK ? commit(tmp, path, flags, err) : r;
}

// The bytes write_image would put in a file called name, into *out (malloc'd, *n).
static btf_result oiio_encode(const char *name, int w, int h, int channels, int bits, const void *pixels, int flags,
                              uint8_t **out, size_t *n, btf_error *err)
{
    *out = nullptr, *n = 0;
    if (bad_params(w, h, channels, bits))
        return btf_fail(err, BTF_ERR_ARG, "%s: bad image parameters %dx%dx%d/%d", name, w, h, channels, bits);
    std::vector<unsigned char> mem;
    btf_result r = encode_any(name, ext_of(name), name, w, h, channels, bits, pixels, flags, &mem, err);
    if (r == BTF_OK && !(*out = (uint8_t *)malloc(mem.size() + 1)))
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    if (r == BTF_OK)
        memcpy(*out, mem.data(), mem.size()), *n = mem.size();
    return r;
}

static btf_result oiio_write_smallest(const char *stem, int w, int h, const uint8_t *grey, int flags,
                                               const char **ext, long long *bytes, btf_error *err)
{
    std::string png = std::string(stem) + ".png", webp = std::string(stem) + ".webp", pext, wext;
    *ext = ".png", *bytes = -1;
    if (bad_params(w, h, 1, 8))
        return btf_fail(err, BTF_ERR_ARG, "%s: bad image parameters %dx%d", png.c_str(), w, h);
    std::string ptmp = temp_path(png.c_str(), &pext), wtmp = temp_path(webp.c_str(), &wext);
    btf_result r = encode_any(ptmp, pext, png.c_str(), w, h, 1, 8, grey, flags, nullptr, err);
    long long pn = r == BTF_OK ? btf_fs_size(ptmp.c_str()) : -1, wn = -1;
    if (r == BTF_OK && !(flags & BTF_IMAGE_NO_WEBP)) {
        r = encode_webp(wtmp, webp.c_str(), w, h, 1, 8, grey, nullptr, err);
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

// Pixels of ch channels (w x h) to one grey byte each, in place: one channel as it
// is, or three or four whose R, G and B agree (alpha 255); anything else is freed.
static btf_result to_grey(const char *what, int w, int h, int ch, uint8_t **pixels, btf_error *err)
{
    uint8_t *px = *pixels;
    size_t n = (size_t)w * (size_t)h;
    for (size_t i = 0; ch != 1 && i < n; i++) {
        const uint8_t *p = px + i * (size_t)ch;
        if (ch < 3 || p[1] != p[0] || p[2] != p[0] || (ch == 4 && p[3] != 255)) {
            free(px);
            *pixels = nullptr;
            return btf_fail(err, BTF_ERR_FORMAT, "%s: not a grey image (%d channels that differ at pixel %zu)", what,
                            ch, i);
        }
        px[i] = p[0];
    }
    return BTF_OK;
}

// The header size of a lossy WebP or an AVIF (checked in s) and its name in messages.
static btf_result lossy_size(const source &s, int *w, int *h, const char **kind, btf_error *err)
{
    int avif = !strcmp(s.format, "avif");
    *kind = avif ? "AVIF" : "lossy WebP";
    return avif ? btf_avif_check(s.data, s.n, s.what, w, h, err) : btf_webp_check(s.data, s.n, s.what, w, h, err);
}

// A lossy WebP or an AVIF (checked in s) as grey: R of libwebp's RGB decode
// (btf_webp_decode_grey), an AVIF's Y plane (btf_avif_decode_grey), its header size in
// *w, *h; refused before allocating when the header claims more pixels than the
// ratios of btf_image.h allow.
static btf_result lossy_grey(const source &s, int *w, int *h, uint8_t **pixels, btf_error *err)
{
    int fw = 0, fh = 0;
    const char *kind = nullptr;
    btf_result r = lossy_size(s, &fw, &fh, &kind, err);
    size_t n = (size_t)fw * (size_t)fh * 3;
    if (r == BTF_OK && (double)n > (double)s.n * BTF_IMAGE_MAX_PNG_RATIO && n > BTF_IMAGE_MAX_WEBP_FLOOR)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: a %zu-byte %s claims %dx%d pixels (over %dx its size and %d MiB)",
                     s.what, s.n, kind, fw, fh, BTF_IMAGE_MAX_PNG_RATIO, BTF_IMAGE_MAX_WEBP_FLOOR >> 20);
    uint8_t *px = r == BTF_OK ? (uint8_t *)malloc((size_t)fw * (size_t)fh) : nullptr;
    if (r == BTF_OK && !px)
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate %dx%d pixels", s.what, fw, fh);
    if (r == BTF_OK)
        r = btf_lossy_decode(s.data, s.n, s.what, fw, fh, px, err);
    if (r != BTF_OK) {
        free(px);
        return r;
    }
    *w = fw, *h = fh, *pixels = px;
    return BTF_OK;
}

static btf_result oiio_read_grey(const char *path, int *w, int *h, uint8_t **pixels, btf_error *err)
{
    source s;
    int ch = 0;
    *pixels = nullptr;
    btf_result r = load_file(path, 0, s, err);
    if (r == BTF_OK && lossy_file(s))
        return lossy_grey(s, w, h, pixels, err);
    r = r == BTF_OK ? read_u8(s, w, h, &ch, pixels, err) : r;
    return r == BTF_OK ? to_grey(path, *w, *h, ch, pixels, err) : r;
}

// btf_image_read_with for a lossy WebP or an AVIF (checked in s): only as one grey
// channel of the expected size, compared before anything is allocated.
static btf_result read_lossy_with(const source &s, int w, int h, int channels, int grey, uint8_t **pixels,
                                  btf_error *err)
{
    int fw = 0, fh = 0;
    const char *kind = !strcmp(s.format, "avif") ? "an AVIF" : "a lossy WebP";
    if (!grey || channels != 1)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s is read only as a grey texture", s.what, kind);
    btf_result r = lossy_size(s, &fw, &fh, &kind, err);
    if (r == BTF_OK && (fw != w || fh != h))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: %dx%d with 1 channels, expected %dx%d with 1", s.what, fw, fh, w, h);
    return r == BTF_OK ? lossy_grey(s, &fw, &fh, pixels, err) : r;
}

static btf_result oiio_read_with(const btf_files *files, const char *path, int w, int h, int channels,
                                          int grey, uint8_t **pixels, btf_error *err)
{
    source s;
    *pixels = nullptr;
    btf_result r = load_with(files, path, 1, s, err); // the header first: no decode of a wrong size
    if (r == BTF_OK && lossy_file(s))
        return read_lossy_with(s, w, h, channels, grey, pixels, err);
    auto in = r == BTF_OK ? open_image(s, kMaxSide, &r, err) : nullptr;
    if (!in)
        return r;
    const ImageSpec &sp = in->spec();
    grey = grey && channels == 1;
    int ch = grey && sp.nchannels >= 3 ? 1 : sp.nchannels, iw, ih;
    if (sp.width != w || sp.height != h || ch != channels)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %dx%d with %d channels, expected %dx%d with %d", path, sp.width,
                        sp.height, ch, w, h, channels);
    if ((r = check_bytes(s, 0, err)) == BTF_OK) // then the whole file, before the decoder sees its data
        r = decode(in.get(), s, &iw, &ih, &ch, pixels, err);
    return r == BTF_OK && grey ? to_grey(path, w, h, ch, pixels, err) : r;
}

static btf_result oiio_write_flags(const char *path, int w, int h, int channels, int bits, const void *pixels,
                                   int flags, btf_error *err)
{
    return write_image(path, w, h, channels, bits, pixels, flags, err);
}

extern "C" __attribute__((visibility("default"))) const btf_image_api *btf_image_oiio_open(const btf_image_host *host,
                                                                                            int abi)
{
    static const btf_image_api api = {oiio_info,        oiio_info_with,      oiio_read_u8,   oiio_read_rgb_f32,
                                      oiio_write_flags, oiio_write_smallest, oiio_read_grey, oiio_read_with,
                                      oiio_encode};
    if (abi != BTF_IMAGE_MODULE_ABI || !host)
        return nullptr;
    H = host;
    return &api;
}
