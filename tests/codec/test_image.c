/* test_image.c - room codec, suite "image": the image writer's PNG filter choice
 * (BTF_IMAGE_PNG_SMALLEST, codec/image/btf_image.h), checked against the writer's own
 * default encoding of the same pixels and against the pixels themselves; filter Up
 * on every row (BTF_IMAGE_PNG_UP) read back from the file's rows; lossless
 * WebP (codec/image/btf_webp.h): grey round trips, the smaller-of-two writer, and damaged
 * or non-grey files refused with one clear error; lossy WebP: R of libwebp's own RGB
 * decode, the q -> Y table, and malformed, extended (alpha, animation) or wrongly
 * sized files refused. */
#include <criterion/criterion.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "btf_avif.h"
#include "btf_webp.h"
#include "fixtures.h"

#include <avif/avif.h>
#include <math.h>
#include <webp/decode.h>
#include <webp/encode.h>
#include <zlib.h>

/* One image written both ways: the smallest choice decodes to the same samples, is no
 * larger than the default (adaptive) encoding, and leaves no temporary file. */
static long long check_one(const char *dir, int w, int h, int ch, int bits, const void *px, long long *adaptive)
{
    char a[600], s[600];
    btf_error err = {0};
    snprintf(a, sizeof a, "%s/a.png", dir);
    snprintf(s, sizeof s, "%s/s.png", dir);
    cr_assert_eq(btf_image_write(a, w, h, ch, bits, px, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_image_write_flags(s, w, h, ch, bits, px, BTF_IMAGE_PNG_SMALLEST, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(fx_count_files(dir), 2, "temporary files left in %s", dir);
    size_t n = (size_t)w * h * ch;
    if (bits == 8) {
        uint8_t *back = NULL;
        int bw, bh, bc;
        cr_assert_eq(btf_image_read_u8(s, &bw, &bh, &bc, &back, &err), BTF_OK, "%s", err.msg);
        cr_assert(bw == w && bh == h && bc == ch);
        cr_assert_eq(memcmp(back, px, n), 0, "%dx%d: the smallest choice decodes to other samples", w, h);
        free(back);
    }
    *adaptive = btf_fs_size(a);
    long long sz = btf_fs_size(s);
    remove(a);
    remove(s);
    return sz;
}

Test(image, smallest_png_filter_choice)
{
    char dir[256];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 99;
    /* sizes with the whole image judged (<= 128 rows) and with the middle strip */
    int sizes[3][2] = {{40, 30}, {96, 128}, {300, 260}};
    for (int k = 0; k < 3; k++) {
        int w = sizes[k][0], h = sizes[k][1];
        uint8_t *px = malloc((size_t)w * h);
        /* columns that vary, rows that repeat them with a little noise (Up's case),
         * then noise (None's case) */
        for (int kind = 0; kind < 2; kind++) {
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    px[y * w + x] = (uint8_t)(kind == 0 ? (x * 37 % 200) + fx_lcg(&seed) % 3 : fx_lcg(&seed) & 255);
            long long adaptive, s = check_one(dir, w, h, 1, 8, px, &adaptive);
            cr_assert(s > 0 && s <= adaptive, "%dx%d kind %d: %lld bytes, adaptive %lld", w, h, kind, s, adaptive);
        }
        free(px);
    }
    /* more channels and 16 bits go through the same choice */
    int w = 64, h = 200;
    uint16_t *p16 = malloc((size_t)w * h * 2 * sizeof *p16);
    for (int i = 0; i < w * h * 2; i++)
        p16[i] = (uint16_t)((i % (2 * w)) * 300 + fx_lcg(&seed) % 5);
    long long adaptive, s = check_one(dir, w, h, 2, 16, p16, &adaptive);
    cr_assert(s > 0 && s <= adaptive, "16-bit: %lld bytes, adaptive %lld", s, adaptive);
    free(p16);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* w x h grey bytes: a ramp with noise (kind 0, where PNG's filters and WebP's
 * predictors both work) or pure noise (kind 1). */
static uint8_t *grey_image(int w, int h, int kind, unsigned *seed)
{
    uint8_t *px = malloc((size_t)w * h);
    cr_assert_not_null(px);
    for (int i = 0; i < w * h; i++)
        px[i] = (uint8_t)(kind == 0 ? (i % w) * 3 + (i / w) + fx_lcg(seed) % 4 : fx_lcg(seed) & 255);
    return px;
}

/* The filter type byte of every row of an 8-bit grey PNG of width w and height h,
 * read here from its IDAT chunks (PNG: 8-byte signature, then length, type, data,
 * CRC per chunk; the inflated data is h rows of a filter byte and w samples). */
static void png_row_filters(const char *path, int w, int h, uint8_t *filters)
{
    FILE *f = fopen(path, "rb");
    cr_assert_not_null(f);
    static uint8_t file[1 << 20], idat[1 << 20];
    size_t n = fread(file, 1, sizeof file, f), ni = 0;
    fclose(f);
    for (size_t i = 8; i + 12 <= n;) {
        size_t len = (size_t)file[i] << 24 | (size_t)file[i + 1] << 16 | (size_t)file[i + 2] << 8 | file[i + 3];
        cr_assert(i + 12 + len <= n);
        if (!memcmp(file + i + 4, "IDAT", 4)) {
            memcpy(idat + ni, file + i + 8, len);
            ni += len;
        }
        i += 12 + len;
    }
    uLongf raw_n = (uLongf)(w + 1) * h;
    uint8_t *raw = malloc(raw_n);
    cr_assert_eq(uncompress(raw, &raw_n, idat, ni), Z_OK);
    cr_assert_eq(raw_n, (uLongf)(w + 1) * h);
    for (int y = 0; y < h; y++)
        filters[y] = raw[(size_t)y * (w + 1)];
    free(raw);
}

Test(image, png_filter_up_on_every_row)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/u.png", dir);
    unsigned seed = 7;
    int w = 50, h = 40;
    uint8_t px[50 * 40], filters[40], *back = NULL;
    for (int i = 0; i < w * h; i++)
        px[i] = (uint8_t)(fx_lcg(&seed) & 255); /* noise: the adaptive choice would pick None */
    btf_error err = {0};
    cr_assert_eq(btf_image_write_flags(path, w, h, 1, 8, px, BTF_IMAGE_PNG_UP | BTF_IMAGE_UNSYNCED, &err), BTF_OK, "%s",
                 err.msg);
    png_row_filters(path, w, h, filters);
    for (int y = 0; y < h; y++)
        cr_assert_eq(filters[y], 2, "row %d has filter type %d, not Up (2)", y, filters[y]);
    int bw, bh, bc;
    cr_assert_eq(btf_image_read_u8(path, &bw, &bh, &bc, &back, &err), BTF_OK, "%s", err.msg);
    cr_assert(bw == w && bh == h && bc == 1 && !memcmp(back, px, sizeof px));
    free(back);
    cr_assert_eq(fx_rmtree(dir), 0);
}

Test(image, webp_grey_round_trip)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 4711;
    int sizes[3][2] = {{1, 1}, {37, 5}, {256, 192}};
    for (int k = 0; k < 3; k++)
        for (int kind = 0; kind < 2; kind++) {
            int w = sizes[k][0], h = sizes[k][1], bw, bh, bc;
            uint8_t *px = grey_image(w, h, kind, &seed), *back = NULL;
            btf_error err = {0};
            snprintf(path, sizeof path, "%s/g.webp", dir);
            cr_assert_eq(btf_image_write_flags(path, w, h, 1, 8, px, 0, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(fx_count_files(dir), 1, "temporary files left in %s", dir);
            /* OpenImageIO decodes it as RGB; the grey reader gives the bytes back */
            cr_assert_eq(btf_image_info(path, &bw, &bh, &bc, &err), BTF_OK, "%s", err.msg);
            cr_assert(bw == w && bh == h && bc >= 3, "%dx%dx%d", bw, bh, bc);
            cr_assert_eq(btf_image_read_grey(path, &bw, &bh, &back, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(memcmp(back, px, (size_t)w * h), 0, "%dx%d kind %d: WebP is not lossless", w, h, kind);
            free(back), free(px);
            remove(path);
        }
    /* only 8-bit grey is written as WebP */
    uint8_t rgb[12] = {0};
    btf_error err = {0};
    cr_assert_eq(btf_image_write_flags(path, 2, 2, 3, 8, rgb, 0, &err), BTF_ERR_UNSUPPORTED);
    cr_assert_eq(fx_count_files(dir), 0);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* btf_image_write_smallest keeps the smaller file, only that one, with its size. */
Test(image, webp_or_png_smallest)
{
    char dir[256], stem[600], path[640];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 815;
    int seen_webp = 0;
    for (int kind = 0; kind < 2; kind++) {
        int w = 200, h = 150;
        uint8_t *px = grey_image(w, h, kind, &seed), *back = NULL, *webp = NULL;
        btf_error err = {0};
        const char *ext = NULL;
        long long bytes = -1;
        snprintf(stem, sizeof stem, "%s/t%d", dir, kind);
        cr_assert_eq(btf_image_write_smallest(stem, w, h, px, BTF_IMAGE_PNG_SMALLEST, &ext, &bytes, &err), BTF_OK, "%s",
                     err.msg);
        snprintf(path, sizeof path, "%s%s", stem, ext);
        cr_assert_eq(btf_fs_size(path), bytes);
        cr_assert_eq(fx_count_files(dir), kind + 1, "the losing file or a temporary was left");
        /* independent sizes: the PNG alone, the WebP of the same pixels in memory */
        char png[640];
        snprintf(png, sizeof png, "%s/png-only", dir);
        const char *pext = NULL;
        long long pbytes = -1;
        cr_assert_eq(btf_image_write_smallest(png, w, h, px, BTF_IMAGE_PNG_SMALLEST | BTF_IMAGE_NO_WEBP, &pext, &pbytes,
                                              &err), BTF_OK, "%s", err.msg);
        cr_assert_str_eq(pext, ".png");
        size_t nw = 0;
        cr_assert_eq(btf_webp_encode_grey(px, w, h, &webp, &nw, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(bytes, (long long)nw < pbytes ? (long long)nw : pbytes, "kept %lld of PNG %lld / WebP %zu", bytes,
                     pbytes, nw);
        cr_assert_str_eq(ext, (long long)nw < pbytes ? ".webp" : ".png");
        seen_webp += !strcmp(ext, ".webp");
        snprintf(png + strlen(png), sizeof png - strlen(png), ".png");
        remove(png);
        int bw, bh;
        cr_assert_eq(btf_image_read_grey(path, &bw, &bh, &back, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(memcmp(back, px, (size_t)w * h), 0);
        free(back), free(px), free(webp);
    }
    cr_assert_geq(seen_webp, 1, "WebP won on neither image: the test no longer covers it");
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Writes n bytes to dir/name, returns the path in buf. */
static const char *put(const char *dir, const char *name, const uint8_t *d, size_t n, char *buf, size_t bn)
{
    snprintf(buf, bn, "%s/%s", dir, name);
    btf_error err = {0};
    cr_assert_eq(btf_fs_write_atomic(buf, d, n, &err), BTF_OK, "%s", err.msg);
    return buf;
}

Test(image, webp_damaged_or_not_grey_refused)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 5;
    uint8_t *px = grey_image(64, 48, 0, &seed), *f = NULL, *g = NULL;
    size_t n = 0;
    btf_error err = {0};
    cr_assert_eq(btf_webp_encode_grey(px, 64, 48, &f, &n, &err), BTF_OK, "%s", err.msg);
    int w = 0, h = 0, bw, bh;
    cr_assert_eq(btf_webp_check(f, n, "ok", &w, &h, &err), BTF_OK, "%s", err.msg);
    cr_assert(w == 64 && h == 48);
    g = malloc(n);
    /* cut short, a RIFF size that lies, a lossy chunk (the VP8L bytes are no VP8 key
     * frame), a bad signature byte */
    const char *want[4] = {"RIFF size", "RIFF size", "not a key frame", "signature"};
    for (int k = 0; k < 4; k++) {
        memcpy(g, f, n);
        size_t m = k == 0 ? n - 7 : n;
        if (k == 1)
            g[4] ^= 0x10;
        if (k == 2)
            memcpy(g + 12, "VP8 ", 4);
        if (k == 3)
            g[20] = 0x2e;
        put(dir, "bad.webp", g, m, path, sizeof path);
        uint8_t *back = NULL;
        err.msg[0] = 0;
        cr_assert_eq(btf_image_read_grey(path, &bw, &bh, &back, &err), BTF_ERR_FORMAT, "case %d", k);
        cr_assert_not_null(strstr(err.msg, want[k]), "case %d: %s", k, err.msg);
        cr_assert_null(back);
    }
    /* a well-formed lossless WebP whose channels differ is no grey texture */
    uint8_t rgb[16 * 8 * 3];
    for (size_t i = 0; i < sizeof rgb; i++)
        rgb[i] = (uint8_t)(i * 7);
    uint8_t *out = NULL;
    size_t no = WebPEncodeLosslessRGB(rgb, 16, 8, 16 * 3, &out);
    cr_assert_gt(no, 0);
    put(dir, "rgb.webp", out, no, path, sizeof path);
    WebPFree(out);
    uint8_t *back = NULL;
    cr_assert_eq(btf_image_read_grey(path, &bw, &bh, &back, &err), BTF_ERR_FORMAT);
    cr_assert_not_null(strstr(err.msg, "not a grey image"), "%s", err.msg);
    free(px), free(f), free(g);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Both file readers (btf_image_read_grey, btf_image_read_with as a w x h grey texture)
 * give exactly back's w*h bytes for the file at path. */
static void file_reads_as(const char *path, int w, int h, const uint8_t *back)
{
    uint8_t *g = NULL, *gw = NULL;
    int bw = 0, bh = 0;
    btf_error err = {0};
    cr_assert_eq(btf_image_read_grey(path, &bw, &bh, &g, &err), BTF_OK, "%s", err.msg);
    cr_assert(bw == w && bh == h && !memcmp(g, back, (size_t)w * h));
    cr_assert_eq(btf_image_read_with(NULL, path, w, h, 1, 1, &gw, &err), BTF_OK, "%s", err.msg);
    cr_assert(!memcmp(gw, back, (size_t)w * h));
    free(g), free(gw);
}

/* A lossy grey WebP decodes to R of libwebp's own RGB decode (WebPDecodeRGB, called
 * here directly), through btf_webp_decode_grey and through the file readers; at
 * quality 100 it stays within the mapping's and VP8's finest quantiser's error. */
Test(image, lossy_webp_is_r_of_the_rgb_decode)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 11;
    int w = 96, h = 64;
    uint8_t *px = grey_image(w, h, 0, &seed), *f = NULL, *back = malloc((size_t)w * h);
    for (int q = 0; q < 256; q++) /* the table: every code within one level (Y 16..235 covers 0..255) */
        cr_assert_leq(abs(btf_webp_r_of_y(btf_webp_y_of_q(q)) - q), 1, "q %d", q);
    int quality[2] = {30, 100};
    for (int k = 0; k < 2; k++) {
        size_t n = 0;
        btf_error err = {0};
        cr_assert_eq(btf_webp_encode_grey_lossy(px, w, h, quality[k], &f, &n, &err), BTF_OK, "%s", err.msg);
        int fw = 0, fh = 0;
        cr_assert_eq(btf_webp_check(f, n, "lossy", &fw, &fh, &err), BTF_OK, "%s", err.msg);
        cr_assert(fw == w && fh == h && btf_webp_is_lossy(f, n));
        cr_assert_eq(btf_webp_decode_grey(f, n, "lossy", w, h, back, &err), BTF_OK, "%s", err.msg);
        int dw = 0, dh = 0;
        uint8_t *rgb = WebPDecodeRGB(f, n, &dw, &dh);
        cr_assert(rgb && dw == w && dh == h);
        double e2 = 0.0;
        for (int i = 0; i < w * h; i++) {
            cr_assert_eq(back[i], rgb[3 * i], "pixel %d", i);
            e2 += ((double)back[i] - px[i]) * ((double)back[i] - px[i]);
        }
        WebPFree(rgb);
        /* the format's rule for what this encoder writes: chroma 128 everywhere, so the
         * value is VP8YUVToR(Y, 128) of the decoded Y plane alone */
        uint8_t *u = NULL, *v = NULL;
        int ys = 0, uvs = 0;
        uint8_t *yp = WebPDecodeYUV(f, n, &dw, &dh, &u, &v, &ys, &uvs);
        cr_assert_not_null(yp);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                cr_assert(u[(y / 2) * uvs + x / 2] == 128 && v[(y / 2) * uvs + x / 2] == 128, "chroma at %d,%d", x, y);
                cr_assert_eq(btf_webp_r_of_y(yp[y * ys + x]), back[y * w + x], "texel %d,%d", x, y);
            }
        WebPFree(yp);
        /* quality 100: the table's 0.4 RMS plus VP8's finest quantiser (about one level)
         * is under 1.5; a decode that lost the table's offset (Y taken as q) would
         * miss by 16 levels or more near black */
        if (quality[k] == 100)
            cr_assert_lt(sqrt(e2 / (w * h)), 1.5, "RMS %.3f at quality 100", sqrt(e2 / (w * h)));
        put(dir, "lossy.webp", f, n, path, sizeof path);
        file_reads_as(path, w, h, back);
        free(f);
    }
    free(px), free(back);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Reads path as a w x h grey texture and expects BTF_ERR_FORMAT naming want. */
static void refused(const char *path, int w, int h, const char *want, const char *what)
{
    btf_error err = {0};
    uint8_t *px = NULL;
    cr_assert_eq(btf_image_read_with(NULL, path, w, h, 1, 1, &px, &err), BTF_ERR_FORMAT, "%s", what);
    cr_assert_null(px, "%s", what);
    cr_assert_not_null(strstr(err.msg, want), "%s: %s", what, err.msg);
}

/* A lossy file the format does not allow is refused with a clear message before it
 * is decoded: cut short, not a key frame, a bad start code, scaling bits, a first
 * partition past its chunk, the wrong size, alpha (an extended file), animation,
 * and any lossy file where a reader wants colour. */
Test(image, lossy_webp_malformed_refused)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 12;
    int w = 64, h = 48;
    uint8_t *px = grey_image(w, h, 0, &seed), *f = NULL;
    size_t n = 0;
    btf_error err = {0};
    cr_assert_eq(btf_webp_encode_grey_lossy(px, w, h, 60, &f, &n, &err), BTF_OK, "%s", err.msg);
    uint8_t *g = malloc(n);
    struct { size_t at; uint8_t or_, and_; size_t cut; const char *want; } c[] = {
        {0, 0, 0xff, 7, "RIFF size"},           /* truncated */
        {20, 1, 0xff, 0, "not a key frame"},    /* frame tag bit 0: an inter frame */
        {23, 0, 0, 0, "start code"},            /* 0x9d -> 0 */
        {27, 0x40, 0xff, 0, "scaling"},         /* width's scale bits */
        {22, 0xff, 0xff, 0, "first partition"}, /* partition size bits 19..23 all set */
    };
    for (size_t k = 0; k < sizeof c / sizeof c[0]; k++) {
        memcpy(g, f, n);
        g[c[k].at] = (uint8_t)((g[c[k].at] | c[k].or_) & c[k].and_);
        put(dir, "bad.webp", g, n - c[k].cut, path, sizeof path);
        refused(path, w, h, c[k].want, c[k].want);
    }
    put(dir, "ok.webp", f, n, path, sizeof path);
    refused(path, w + 16, h, "expected", "wrong size");
    uint8_t *rgb = NULL;
    cr_assert_eq(btf_image_read_with(NULL, path, w, h, 3, 0, &rgb, &err), BTF_ERR_FORMAT);
    cr_assert_not_null(strstr(err.msg, "only as a grey texture"), "%s", err.msg);
    cr_assert_null(rgb);
    /* alpha: libwebp writes a lossy image with alpha as an extended file (VP8X, ALPH, VP8) */
    uint8_t *rgba = malloc((size_t)w * h * 4), *out = NULL;
    for (int i = 0; i < w * h; i++)
        rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = px[i], rgba[4 * i + 3] = (uint8_t)(i % 200);
    size_t na = WebPEncodeRGBA(rgba, w, h, 4 * w, 75.0f, &out);
    cr_assert_gt(na, 30);
    put(dir, "alpha.webp", out, na, path, sizeof path);
    WebPFree(out);
    refused(path, w, h, "'VP8X'", "alpha");
    /* animation: an extended header with the animation flag and an ANIM chunk */
    uint8_t anim[44] = "RIFF\0\0\0\0WEBPVP8X\x0a\0\0\0\x02\0\0\0";
    anim[24] = (uint8_t)(w - 1), anim[27] = (uint8_t)(h - 1);
    memcpy(anim + 30, "ANIM\x06\0\0\0", 8);
    anim[4] = sizeof anim - 8;
    put(dir, "anim.webp", anim, sizeof anim, path, sizeof path);
    refused(path, w, h, "'VP8X'", "animation");
    free(px), free(f), free(g), free(rgba);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* An AVIF made here with libavif itself (not btf_avif): w x h, depth bits, format fmt,
 * range, every sample of every plane from px (8 bits) or px * 4 (10 bits); *n bytes,
 * malloc'd. */
static uint8_t *avif_made(const uint8_t *px, int w, int h, int depth, avifPixelFormat fmt, avifRange range,
                          size_t *n)
{
    avifImage *im = avifImageCreate((uint32_t)w, (uint32_t)h, (uint32_t)depth, fmt);
    cr_assert_not_null(im);
    im->yuvRange = range;
    cr_assert_eq(avifImageAllocatePlanes(im, AVIF_PLANES_YUV), AVIF_RESULT_OK);
    for (int c = 0; c < (fmt == AVIF_PIXEL_FORMAT_YUV400 ? 1 : 3); c++) {
        int pw = c ? (w + 1) / 2 : w, ph = c ? (h + 1) / 2 : h;
        for (int y = 0; y < ph; y++)
            for (int x = 0; x < pw; x++) {
                uint8_t v = c ? 128 : px[y * w + x];
                if (depth > 8)
                    ((uint16_t *)(im->yuvPlanes[c] + (size_t)y * im->yuvRowBytes[c]))[x] = (uint16_t)(v * 4);
                else
                    im->yuvPlanes[c][(size_t)y * im->yuvRowBytes[c] + x] = v;
            }
    }
    avifEncoder *e = avifEncoderCreate();
    e->minQuantizer = e->maxQuantizer = 10, e->speed = 8;
    avifRWData o = AVIF_DATA_EMPTY;
    cr_assert_eq(avifEncoderWrite(e, im, &o), AVIF_RESULT_OK);
    uint8_t *f = malloc(o.size);
    memcpy(f, o.data, o.size), *n = o.size;
    avifRWDataFree(&o), avifEncoderDestroy(e), avifImageDestroy(im);
    return f;
}

/* A grey AVIF decodes to its Y plane: through btf_avif_decode_grey and both file
 * readers, equal to libavif's own decode (avifDecoderReadMemory, called here) and to
 * R = G = B of libavif's RGB conversion, the rule a browser's decode follows for a
 * full-range monochrome file (doc/package-format.md section 4.1); at quantiser 4 within
 * 1.5 levels RMS of the source (AV1's finest steps; a file read with limited range
 * would be off by up to 16 levels near black), and coarser at 40 (the quantiser is used). */
Test(image, avif_is_the_y_plane)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 21;
    int w = 96, h = 64, quant[2] = {4, 40};
    uint8_t *px = grey_image(w, h, 0, &seed), *back = malloc((size_t)w * h);
    double rms[2];
    for (int k = 0; k < 2; k++) {
        uint8_t *f = NULL;
        size_t n = 0;
        btf_error err = {0};
        cr_assert_eq(btf_avif_encode_grey(px, w, h, quant[k], &f, &n, &err), BTF_OK, "%s", err.msg);
        int fw = 0, fh = 0;
        cr_assert(btf_avif_is_avif(f, n));
        cr_assert_eq(btf_avif_check(f, n, "avif", &fw, &fh, &err), BTF_OK, "%s", err.msg);
        cr_assert(fw == w && fh == h);
        cr_assert_eq(btf_avif_decode_grey(f, n, "avif", w, h, back, &err), BTF_OK, "%s", err.msg);
        avifDecoder *d = avifDecoderCreate();
        avifImage *im = avifImageCreateEmpty();
        cr_assert_eq(avifDecoderReadMemory(d, im, f, n), AVIF_RESULT_OK);
        cr_assert(im->yuvFormat == AVIF_PIXEL_FORMAT_YUV400 && im->depth == 8 && im->yuvRange == AVIF_RANGE_FULL);
        avifRGBImage rgb;
        avifRGBImageSetDefaults(&rgb, im);
        rgb.format = AVIF_RGB_FORMAT_RGB, rgb.depth = 8;
        avifRGBImageAllocatePixels(&rgb);
        cr_assert_eq(avifImageYUVToRGB(im, &rgb), AVIF_RESULT_OK);
        double e2 = 0.0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                uint8_t b = back[y * w + x], *c = rgb.pixels + (size_t)y * rgb.rowBytes + 3 * x;
                cr_assert_eq(b, im->yuvPlanes[0][(size_t)y * im->yuvRowBytes[0] + x], "Y at %d,%d", x, y);
                cr_assert(c[0] == b && c[1] == b && c[2] == b, "RGB %d %d %d vs %d at %d,%d", c[0], c[1], c[2], b, x, y);
                e2 += ((double)b - px[y * w + x]) * ((double)b - px[y * w + x]);
            }
        rms[k] = sqrt(e2 / (w * h));
        avifRGBImageFreePixels(&rgb), avifImageDestroy(im), avifDecoderDestroy(d);
        put(dir, "t.avif", f, n, path, sizeof path);
        file_reads_as(path, w, h, back);
        free(f);
    }
    cr_assert_lt(rms[0], 1.5, "RMS %.3f at quantiser 4", rms[0]);
    cr_assert_gt(rms[1], rms[0], "RMS %.3f at 40, %.3f at 4", rms[1], rms[0]);
    free(px), free(back);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* An AVIF the format does not allow is refused with a clear message before any pixel
 * is decoded: cut short, another brand, colour (4:2:0), 10 bits, limited range, the
 * wrong size, and any AVIF where a reader wants colour. */
Test(image, avif_malformed_refused)
{
    char dir[256], path[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    unsigned seed = 22;
    int w = 64, h = 48;
    uint8_t *px = grey_image(w, h, 0, &seed), *f = NULL;
    size_t n = 0;
    btf_error err = {0};
    cr_assert_eq(btf_avif_encode_grey(px, w, h, 20, &f, &n, &err), BTF_OK, "%s", err.msg);
    put(dir, "cut.avif", f, n * 2 / 3, path, sizeof path);
    refused(path, w, h, "not a valid AVIF", "truncated");
    f[11] = 's'; /* the major brand "avis": an image sequence */
    put(dir, "avis.avif", f, n, path, sizeof path);
    refused(path, w, h, "not an AVIF", "brand");
    f[11] = 'f';
    put(dir, "ok.avif", f, n, path, sizeof path);
    refused(path, w + 16, h, "expected", "wrong size");
    uint8_t *rgb = NULL;
    cr_assert_eq(btf_image_read_with(NULL, path, w, h, 3, 0, &rgb, &err), BTF_ERR_FORMAT);
    cr_assert_not_null(strstr(err.msg, "only as a grey texture"), "%s", err.msg);
    cr_assert_null(rgb);
    struct { int depth; avifPixelFormat fmt; avifRange range; const char *want; } c[] = {
        {8, AVIF_PIXEL_FORMAT_YUV420, AVIF_RANGE_FULL, "format YUV420"},
        {10, AVIF_PIXEL_FORMAT_YUV400, AVIF_RANGE_FULL, "depth 10"},
        {8, AVIF_PIXEL_FORMAT_YUV400, AVIF_RANGE_LIMITED, "limited range"},
    };
    for (size_t k = 0; k < sizeof c / sizeof c[0]; k++) {
        size_t m = 0;
        uint8_t *g = avif_made(px, w, h, c[k].depth, c[k].fmt, c[k].range, &m);
        put(dir, "bad.avif", g, m, path, sizeof path);
        refused(path, w, h, c[k].want, c[k].want);
        free(g);
    }
    free(px), free(f);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* 1 when a mapping of this process names `name` (/proc/self/maps). */
static int mapped(const char *name)
{
    FILE *f = fopen("/proc/self/maps", "r");
    cr_assert_not_null(f);
    char line[4096];
    int hit = 0;
    while (!hit && fgets(line, sizeof line, f))
        hit = strstr(line, name) != NULL;
    fclose(f);
    return hit;
}

/* OpenImageIO (and the libraries it links) is mapped on the first image call, not at
 * start (codec/image/btf_image_module.h): a program that reads no image starts without it.
 * A sanitizer build links the module at start (the Makefile's IMAGE_AT_START, which
 * defines BTF_IMAGE_AT_START here): only the second half holds there. */
#ifdef BTF_IMAGE_AT_START
#define IMAGE_AT_START 1
#else
#define IMAGE_AT_START 0
#endif
Test(image, openimageio_is_mapped_on_the_first_image_call)
{
    cr_assert(IMAGE_AT_START || !mapped("libOpenImageIO"), "OpenImageIO is mapped before any image call");
    cr_assert(IMAGE_AT_START || !mapped("btf_image_oiio.so"));
    char dir[256], p[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(p, sizeof p, "%s/a.png", dir);
    uint8_t px[12] = {0, 50, 100, 150, 200, 250, 1, 2, 3, 4, 5, 6};
    btf_error err = {0};
    cr_assert_eq(btf_image_write(p, 2, 2, 3, 8, px, &err), BTF_OK, "%s", err.msg);
    int w, h, ch;
    cr_assert_eq(btf_image_info(p, &w, &h, &ch, &err), BTF_OK, "%s", err.msg);
    cr_assert(w == 2 && h == 2 && ch == 3);
    cr_assert(mapped("btf_image_oiio.so") && mapped("libOpenImageIO"), "the module is loaded by the first call");
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* A module that cannot be loaded: every image call fails with BTF_ERR_IO naming what
 * was tried, and nothing is written. */
Test(image, a_missing_module_is_a_clear_error)
{
    cr_assert_eq(setenv("BTF_IMAGE_MODULE", "/nonexistent/btf_image_oiio.so", 1), 0);
    char dir[256], p[600];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(p, sizeof p, "%s/a.png", dir);
    uint8_t px[4] = {1, 2, 3, 4};
    btf_error err = {0};
    cr_assert_eq(btf_image_write(p, 2, 2, 1, 8, px, &err), BTF_ERR_IO);
    cr_assert(strstr(err.msg, "OpenImageIO module") && strstr(err.msg, "/nonexistent/btf_image_oiio.so") &&
                  strstr(err.msg, "BTF_IMAGE_MODULE"),
              "%s", err.msg);
    cr_assert_eq(fx_count_files(dir), 0, "a file was written");
    int w, h, ch;
    err.msg[0] = 0;
    cr_assert_eq(btf_image_info(p, &w, &h, &ch, &err), BTF_ERR_IO);
    cr_assert(strstr(err.msg, "/nonexistent/btf_image_oiio.so"), "%s", err.msg);
    cr_assert(IMAGE_AT_START || !mapped("libOpenImageIO"));
    cr_assert_eq(fx_rmtree(dir), 0);
}
