/* btf_wtz.c - the weights codings wt-JJ.z and wt-JJ.pz (zlib, doc/package-format.md
 * sections 9.3 and 5.4) and wt-JJ.webp (a lossless RGB image, section 5.5). */
#include "btf_wtz.h"
#include "btf_common.h"
#include "btf_webp.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* zlib's level for the weights. 9 spends its time on the long runs of coarsely
 * quantised weights: on tiles at 128x128 (k 9, 24 components) level 6 made the
 * files 1.4% larger and the allocation's weight ladders about twice as fast. */
#define BTF_WTZ_LEVEL 6

size_t btf_wtz_max_bytes(int V, int L)
{
    return 2 * (size_t)V * L * 3 + 1024;
}

void btf_wtz_prev_views(const int *block_of_view, int V, int *prev)
{
    for (int v = 0; v < V; v++) {
        prev[v] = -1;
        for (int u = v - 1; u >= 0 && prev[v] < 0; u--)
            if (block_of_view[u] == block_of_view[v])
                prev[v] = u;
    }
}

/* The prediction of q[(v*L + l)*3 + c] from values before it (mod 65536): the
 * previous light of view v, plus with a predecessor u the change from u's previous
 * light to its light l (u's light 0 alone at l = 0). */
static unsigned btf__wtz_pred(const uint16_t *q, int L, int v, int u, int l, int c)
{
    const uint16_t *a = q + (size_t)v * L * 3, *b = u >= 0 ? q + (size_t)u * L * 3 : NULL;
    if (!b)
        return l > 0 ? a[(l - 1) * 3 + c] : 0u;
    if (l == 0)
        return b[c];
    return (unsigned)a[(l - 1) * 3 + c] + b[l * 3 + c] - b[(l - 1) * 3 + c];
}

static uint16_t btf__zigzag(unsigned e)
{
    int d = (int16_t)(uint16_t)e; /* wrapped to -32768..32767 */
    return (uint16_t)((unsigned)(d * 2) ^ (unsigned)(d < 0 ? -1 : 0));
}

/* The zigzag codes of q (n = V*L*3) into zz: prev NULL, differences along the
 * lights (wt-JJ.z); else the prediction's residuals, channels 0 and 2 less
 * channel 1's (wt-JJ.pz). */
static void btf__wtz_codes(const uint16_t *q, int V, int L, const int *prev, uint16_t *zz)
{
    for (int v = 0; v < V; v++)
        for (int l = 0; l < L; l++) {
            size_t i = ((size_t)v * L + l) * 3;
            unsigned r[3];
            for (int c = 0; c < 3; c++)
                r[c] = q[i + c] - btf__wtz_pred(q, L, v, prev ? prev[v] : -1, l, c);
            for (int c = 0; c < 3; c++)
                zz[i + c] = btf__zigzag(prev && c != 1 ? r[c] - r[1] : r[c]);
        }
}

/* The inverse of btf__wtz_codes: q from the codes zz. */
static void btf__wtz_rebuild(const uint16_t *zz, int V, int L, const int *prev, uint16_t *q)
{
    for (int v = 0; v < V; v++)
        for (int l = 0; l < L; l++) {
            size_t i = ((size_t)v * L + l) * 3;
            unsigned r[3];
            for (int c = 0; c < 3; c++)
                r[c] = ((unsigned)zz[i + c] >> 1) ^ (0u - ((unsigned)zz[i + c] & 1u));
            for (int c = 0; c < 3; c++)
                q[i + c] = (uint16_t)(btf__wtz_pred(q, L, v, prev ? prev[v] : -1, l, c) + r[c] +
                                      (prev && c != 1 ? r[1] : 0u));
        }
}

btf_result btf_wtz_encode(const uint16_t *q, int V, int L, uint8_t **out, size_t *len, btf_error *err)
{
    return btf_wtz_encode_pred(q, V, L, NULL, out, len, err);
}

btf_result btf_wtz_encode_pred(const uint16_t *q, int V, int L, const int *prev, uint8_t **out, size_t *len,
                               btf_error *err)
{
    size_t n = (size_t)V * L * 3;
    uLong bound = compressBound((uLong)(2 * n));
    uint8_t *raw = malloc(2 * n), *z = malloc(bound);
    uint16_t *zz = malloc(n * sizeof *zz);
    *out = NULL, *len = 0;
    if (!raw || !z || !zz) {
        free(raw), free(z), free(zz);
        return btf_fail(err, BTF_ERR_NOMEM, "weights: out of memory");
    }
    btf__wtz_codes(q, V, L, prev, zz);
    for (size_t i = 0; i < n; i++)
        raw[i] = (uint8_t)(zz[i] & 255u), raw[n + i] = (uint8_t)(zz[i] >> 8);
    free(zz);
    uLongf zl = bound;
    int zr = compress2(z, &zl, raw, (uLong)(2 * n), BTF_WTZ_LEVEL);
    free(raw);
    if (zr != Z_OK) {
        free(z);
        return btf_fail(err, BTF_ERR_NOMEM, "weights: zlib compress failed (%d)", zr);
    }
    *out = z, *len = (size_t)zl;
    return BTF_OK;
}

int btf_wtz_fits_webp(const uint16_t *q, int V, int L)
{
    size_t n = (size_t)V * L * 3;
    for (size_t i = 0; i < n; i++)
        if (q[i] > 255)
            return 0;
    return 1;
}

btf_result btf_wtz_encode_webp(const uint16_t *q, int V, int L, uint8_t **out, size_t *len, btf_error *err)
{
    size_t n = (size_t)V * L * 3;
    *out = NULL, *len = 0;
    if (!btf_wtz_fits_webp(q, V, L))
        return btf_fail(err, BTF_ERR_RANGE, "weights: a code above 255 has no wt-JJ.webp");
    uint8_t *rgb = malloc(n ? n : 1);
    if (!rgb)
        return btf_fail(err, BTF_ERR_NOMEM, "weights: out of memory");
    for (size_t i = 0; i < n; i++) /* index (v*L + l)*3 + c is pixel (l, v)'s sample c */
        rgb[i] = (uint8_t)q[i];
    btf_result r = btf_webp_encode_rgb(rgb, L, V, out, len, err);
    free(rgb);
    return r;
}

btf_result btf_wtz_decode_webp(const uint8_t *data, size_t len, int V, int L, uint16_t *q, const char *name,
                               btf_error *err)
{
    size_t n = (size_t)V * L * 3;
    if (len < 1 || len > btf_wtz_max_bytes(V, L))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %zu bytes, expected 1..%zu", name, len, btf_wtz_max_bytes(V, L));
    uint8_t *rgb = malloc(n);
    if (!rgb)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    btf_result r = btf_webp_decode_rgb(data, len, name, L, V, rgb, err);
    for (size_t i = 0; r == BTF_OK && i < n; i++)
        q[i] = rgb[i];
    free(rgb);
    return r;
}

const char *btf_wtz_ext(int kind)
{
    return kind == BTF_WTZ_WEBP ? ".webp" : kind == BTF_WTZ_PZ ? ".pz" : ".z";
}

int btf_wtz_kind_of(const char *name)
{
    size_t n = strlen(name);
    if (strncmp(name, "wt-", 3))
        return -1;
    if (n > 5 && !strcmp(name + n - 5, ".webp"))
        return BTF_WTZ_WEBP;
    if (n > 3 && !strcmp(name + n - 3, ".pz"))
        return BTF_WTZ_PZ;
    return n > 2 && !strcmp(name + n - 2, ".z") && !(n > 4 && !strcmp(name + n - 4, "-r.z")) ? BTF_WTZ_Z : -1;
}

btf_result btf_wtz_decode_kind(int kind, const uint8_t *data, size_t len, int V, int L, const int *prev,
                               uint16_t *q, const char *name, btf_error *err)
{
    if (kind == BTF_WTZ_WEBP)
        return btf_wtz_decode_webp(data, len, V, L, q, name, err);
    return btf_wtz_decode_pred(data, len, V, L, kind == BTF_WTZ_PZ ? prev : NULL, q, name, err);
}

/* *out (*len bytes, coding *kind) replaced by b (nb bytes, coding k) when b is smaller;
 * whichever is not kept is freed. */
static void btf__wtz_keep_smaller(uint8_t **out, size_t *len, int *kind, uint8_t *b, size_t nb, int k)
{
    if (b && nb < *len) {
        free(*out);
        *out = b, *len = nb, *kind = k;
    } else {
        free(b);
    }
}

btf_result btf_wtz_encode_smaller(const uint16_t *q, int V, int L, const int *prev, int webp, uint8_t **out,
                                  size_t *len, int *kind, btf_error *err)
{
    uint8_t *b = NULL;
    size_t nb = 0;
    *kind = BTF_WTZ_Z;
    btf_result r = btf_wtz_encode(q, V, L, out, len, err);
    if (r == BTF_OK && (r = btf_wtz_encode_pred(q, V, L, prev, &b, &nb, err)) == BTF_OK)
        btf__wtz_keep_smaller(out, len, kind, b, nb, BTF_WTZ_PZ);
    b = NULL;
    if (r == BTF_OK && webp && btf_wtz_fits_webp(q, V, L) && (r = btf_wtz_encode_webp(q, V, L, &b, &nb, err)) == BTF_OK)
        btf__wtz_keep_smaller(out, len, kind, b, nb, BTF_WTZ_WEBP);
    if (r != BTF_OK)
        free(*out), *out = NULL, *len = 0;
    return r;
}

btf_result btf_wtz_decode(const uint8_t *z, size_t len, int V, int L, uint16_t *q, const char *name,
                          btf_error *err)
{
    return btf_wtz_decode_pred(z, len, V, L, NULL, q, name, err);
}

btf_result btf_wtz_decode_pred(const uint8_t *z, size_t len, int V, int L, const int *prev, uint16_t *q,
                               const char *name, btf_error *err)
{
    size_t n = (size_t)V * L * 3;
    if (len < 1 || len > btf_wtz_max_bytes(V, L))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %zu bytes, expected 1..%zu", name, len, btf_wtz_max_bytes(V, L));
    uint8_t *raw = malloc(2 * n + 1); /* one spare byte: a longer stream is seen, not cut */
    if (!raw)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    z_stream s = {0};
    int zr = inflateInit(&s);
    if (zr == Z_OK) {
        s.next_in = (Bytef *)z, s.avail_in = (uInt)len;
        s.next_out = raw, s.avail_out = (uInt)(2 * n + 1);
        zr = inflate(&s, Z_FINISH);
        inflateEnd(&s);
    }
    size_t got = 2 * n + 1 - s.avail_out;
    btf_result r = BTF_OK;
    if (zr != Z_STREAM_END)
        r = got > 2 * n ? btf_fail(err, BTF_ERR_FORMAT, "%s: inflates to more than %zu bytes", name, 2 * n)
                        : btf_fail(err, BTF_ERR_FORMAT, "%s: not a complete zlib stream (%s)", name,
                                   s.msg ? s.msg : "truncated");
    else if (got != 2 * n)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: inflates to %zu bytes, expected %zu", name, got, 2 * n);
    else if (s.avail_in != 0)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: %u bytes after the zlib stream", name, s.avail_in);
    uint16_t *zz = r == BTF_OK ? malloc(n * sizeof *zz) : NULL;
    if (r == BTF_OK && !zz)
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    for (size_t i = 0; r == BTF_OK && i < n; i++)
        zz[i] = (uint16_t)((unsigned)raw[i] | ((unsigned)raw[n + i] << 8));
    if (r == BTF_OK)
        btf__wtz_rebuild(zz, V, L, prev, q);
    free(zz), free(raw);
    return r;
}
