/* btf_wtz.c - wt-JJ.z weights coding (doc/package-format.md section 9.3). */
#include "btf_wtz.h"
#include "btf_common.h"

#include <stdlib.h>
#include <zlib.h>

/* zlib's level for the weights. 9 spends its time on the long runs of coarsely
 * quantised weights: on tiles at 128x128 (k 9, 24 components) level 6 made the
 * files 1.4% larger and the allocation's weight ladders about twice as fast. */
#define BTF_WTZ_LEVEL 6

size_t btf_wtz_max_bytes(int V, int L)
{
    return 2 * (size_t)V * L * 3 + 1024;
}

btf_result btf_wtz_encode(const uint16_t *q, int V, int L, uint8_t **out, size_t *len, btf_error *err)
{
    size_t n = (size_t)V * L * 3;
    uLong bound = compressBound((uLong)(2 * n));
    uint8_t *raw = malloc(2 * n), *z = malloc(bound);
    *out = NULL, *len = 0;
    if (!raw || !z) {
        free(raw), free(z);
        return btf_fail(err, BTF_ERR_NOMEM, "weights: out of memory");
    }
    for (size_t i = 0; i < n; i++) {
        size_t l = (i / 3) % (size_t)L;
        int d = (int16_t)(uint16_t)(q[i] - (l > 0 ? q[i - 3] : 0)); /* wrapped to -32768..32767 */
        uint16_t zz = (uint16_t)((unsigned)(d * 2) ^ (unsigned)(d < 0 ? -1 : 0));
        raw[i] = (uint8_t)(zz & 255u);
        raw[n + i] = (uint8_t)(zz >> 8);
    }
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

btf_result btf_wtz_decode(const uint8_t *z, size_t len, int V, int L, uint16_t *q, const char *name,
                          btf_error *err)
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
    for (size_t i = 0; r == BTF_OK && i < n; i++) {
        unsigned zz = (unsigned)raw[i] | ((unsigned)raw[n + i] << 8);
        unsigned d = (zz >> 1) ^ (0u - (zz & 1u));
        size_t l = (i / 3) % (size_t)L;
        q[i] = (uint16_t)((l > 0 ? q[i - 3] : 0u) + d);
    }
    free(raw);
    return r;
}
