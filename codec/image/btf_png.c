/* btf_png.c - PNG structure check with zlib (framing, CRCs, IHDR, inflate size, filters). */
#include "btf_png.h"
#include "btf_common.h"

#include <string.h>
#include <zlib.h>

static const uint8_t btf__png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

/* libpng's default limit per side (PNG_USER_WIDTH_MAX): a larger IHDR is refused here
 * rather than by libpng, whose error goes to stderr. */
#define BTF__PNG_MAX_SIDE 1000000u

/* Parsed IHDR and what the IDAT stream must inflate to; stack value of one check. */
typedef struct btf__png {
    uint32_t w, h;
    int depth, color, interlace, has_plte;
    unsigned long long row_bytes, want; /* filtered row size (1 filter byte + data), total */
} btf__png;

static uint32_t btf__be32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

int btf_png_is_png(const uint8_t *data, size_t n)
{
    return n >= 8 && !memcmp(data, btf__png_sig, 8);
}

/* Samples per pixel of a valid (color type, bit depth) pair, else 0. */
static int btf__png_channels(int color, int depth)
{
    switch (color) {
    case 0: return depth == 1 || depth == 2 || depth == 4 || depth == 8 || depth == 16;
    case 3: return (depth == 1 || depth == 2 || depth == 4 || depth == 8) ? 1 : 0;
    case 2: return depth == 8 || depth == 16 ? 3 : 0;
    case 4: return depth == 8 || depth == 16 ? 2 : 0;
    case 6: return depth == 8 || depth == 16 ? 4 : 0;
    }
    return 0;
}

/* Filtered size of an Adam7-interlaced image: seven passes, each a sub-image
 * with one filter byte per row (empty passes have none). */
static unsigned long long btf__adam7_bytes(uint32_t w, uint32_t h, int bits_per_pixel)
{
    static const int x0[7] = {0, 4, 0, 2, 0, 1, 0}, y0[7] = {0, 0, 4, 0, 2, 0, 1};
    static const int dx[7] = {8, 8, 4, 4, 2, 2, 1}, dy[7] = {8, 8, 8, 4, 4, 2, 2};
    unsigned long long total = 0;
    for (int k = 0; k < 7; k++) {
        unsigned long long pw = w > (uint32_t)x0[k] ? (w - x0[k] + dx[k] - 1) / dx[k] : 0;
        unsigned long long ph = h > (uint32_t)y0[k] ? (h - y0[k] + dy[k] - 1) / dy[k] : 0;
        if (pw && ph)
            total += ph * (1 + (pw * bits_per_pixel + 7) / 8);
    }
    return total;
}

static btf_result btf__png_ihdr(const uint8_t *d, uint32_t len, btf__png *p, const char *what, btf_error *err)
{
    if (len != 13)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG IHDR has %u bytes, not 13", what, len);
    p->w = btf__be32(d), p->h = btf__be32(d + 4), p->depth = d[8], p->color = d[9], p->interlace = d[12];
    int ch = btf__png_channels(p->color, p->depth);
    if (p->w < 1 || p->h < 1 || p->w > BTF__PNG_MAX_SIDE || p->h > BTF__PNG_MAX_SIDE || !ch || d[10] || d[11] ||
        p->interlace > 1)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG IHDR is invalid (%ux%u, depth %d, colour type %d)", what, p->w,
                        p->h, p->depth, p->color);
    p->row_bytes = 1 + ((unsigned long long)p->w * ch * p->depth + 7) / 8;
    p->want = p->interlace ? btf__adam7_bytes(p->w, p->h, ch * p->depth) : p->row_bytes * p->h;
    return BTF_OK;
}

/* A PLTE chunk of len bytes as libpng accepts it: one, before the image data, in a
 * colour image, of 1..256 entries of 3 bytes (libpng's error on any other goes to stderr). */
static btf_result btf__png_plte(uint32_t len, btf__png *p, int idat, const char *what, btf_error *err)
{
    if (p->has_plte++ || idat)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG has a second PLTE chunk or one after the image data", what);
    if (p->color == 0 || p->color == 4)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG grey image with a PLTE chunk", what);
    if (len < 3 || len > 768 || len % 3)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG PLTE of %u bytes (3 per entry, 1 to 256 entries)", what, len);
    return BTF_OK;
}

/* Inflates the concatenated IDAT data, counting bytes and checking each row's filter byte. */
typedef struct btf__inflate {
    z_stream z;
    unsigned long long got;
    int bad_filter;
} btf__inflate;

static void btf__png_count(btf__inflate *s, const btf__png *p, const uint8_t *out, size_t n)
{
    if (!p->interlace) { /* the filter byte of every row that starts in this piece */
        unsigned long long r = (s->got + p->row_bytes - 1) / p->row_bytes * p->row_bytes;
        for (; r < s->got + n; r += p->row_bytes)
            s->bad_filter |= out[r - s->got] > 4;
    }
    s->got += n;
}

/* Feeds one IDAT chunk; 1 while the stream is fine. */
static int btf__png_feed(btf__inflate *s, const btf__png *p, const uint8_t *d, uint32_t len, int *done)
{
    uint8_t out[16384];
    s->z.next_in = (Bytef *)d, s->z.avail_in = len;
    while (s->z.avail_in > 0 && !*done) {
        s->z.next_out = out, s->z.avail_out = sizeof out;
        int rc = inflate(&s->z, Z_NO_FLUSH);
        btf__png_count(s, p, out, sizeof out - s->z.avail_out);
        if (rc == Z_STREAM_END)
            *done = 1;
        else if (rc != Z_OK || s->got > p->want)
            return 0;
    }
    return s->got <= p->want;
}

/* Walks the chunks; fills p and inflates the image data (s NULL: framing only). */
static btf_result btf__png_walk(const uint8_t *d, size_t n, btf__png *p, btf__inflate *s, const char *what,
                                btf_error *err)
{
    int seen_ihdr = 0, seen_iend = 0, idat = 0, z_done = 0;
    size_t at = 8;
    while (at < n && !seen_iend) {
        if (n - at < 12)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG is truncated at byte %zu", what, at);
        uint32_t len = btf__be32(d + at);
        const uint8_t *type = d + at + 4, *body = d + at + 8;
        if (len > 0x7fffffffu || len > n - at - 12)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG chunk at byte %zu runs past the end of the file", what, at);
        for (int i = 0; i < 4; i++)
            if (!((type[i] >= 'A' && type[i] <= 'Z') || (type[i] >= 'a' && type[i] <= 'z')))
                return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG chunk at byte %zu has an invalid type", what, at);
        if ((uint32_t)crc32(0L, type, len + 4) != btf__be32(body + len))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG chunk %.4s at byte %zu fails its CRC", what, type, at);
        if (!seen_ihdr && memcmp(type, "IHDR", 4))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG does not start with IHDR", what);
        btf_result r = BTF_OK;
        if (!memcmp(type, "IHDR", 4))
            r = seen_ihdr++ ? btf_fail(err, BTF_ERR_FORMAT, "%s: PNG has two IHDR chunks", what)
                            : btf__png_ihdr(body, len, p, what, err);
        else if (!memcmp(type, "PLTE", 4))
            r = btf__png_plte(len, p, idat, what, err);
        else if (!memcmp(type, "IDAT", 4)) {
            if (p->color == 3 && !p->has_plte)
                return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG palette image without PLTE before IDAT", what);
            idat = 1;
            if (s && (!btf__png_feed(s, p, body, len, &z_done) || s->bad_filter))
                return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG image data is damaged (zlib stream or row filters)",
                                what);
        } else if (!memcmp(type, "IEND", 4))
            seen_iend = 1;
        else if (type[0] >= 'A' && type[0] <= 'Z') /* a critical chunk this decoder does not know */
            return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG has an unknown critical chunk %.4s", what, type);
        if (r != BTF_OK)
            return r;
        at += 12 + (size_t)len;
    }
    if (!seen_iend || !idat)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG is truncated (no %s)", what, idat ? "IEND" : "image data");
    if (s && !z_done)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG image data is truncated (the zlib stream does not end)", what);
    if (s && s->got != p->want)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: PNG image data holds %llu of %llu bytes", what, s->got, p->want);
    return BTF_OK;
}

btf_result btf_png_check(const uint8_t *data, size_t n, const char *what, btf_error *err)
{
    if (!btf_png_is_png(data, n))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a PNG file", what);
    btf__png p;
    memset(&p, 0, sizeof p);
    btf__inflate s;
    memset(&s, 0, sizeof s);
    if (inflateInit(&s.z) != Z_OK)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: cannot start zlib", what);
    btf_result r = btf__png_walk(data, n, &p, &s, what, err);
    inflateEnd(&s.z);
    return r;
}

btf_result btf_png_check_header(const uint8_t *data, size_t n, const char *what, btf_error *err)
{
    btf__png p;
    memset(&p, 0, sizeof p);
    if (!btf_png_is_png(data, n))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a PNG file", what);
    return btf__png_walk(data, n, &p, NULL, what, err);
}
