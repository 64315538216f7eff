/* btf_base64.c - standard base64 encoder and strict decoder. */
#include "btf_base64.h"

#include <stdlib.h>
#include <string.h>

static const char btf__b64_alphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

char *btf_base64_encode(const uint8_t *d, size_t n)
{
    const char *A = btf__b64_alphabet;
    char *o = malloc((n + 2) / 3 * 4 + 1), *q = o;
    for (size_t i = 0; o && i < n; i += 3) {
        unsigned v = (unsigned)d[i] << 16 | (i + 1 < n ? (unsigned)d[i + 1] << 8 : 0) | (i + 2 < n ? d[i + 2] : 0);
        *q++ = A[v >> 18 & 63], *q++ = A[v >> 12 & 63];
        *q++ = i + 1 < n ? A[v >> 6 & 63] : '=';
        *q++ = i + 2 < n ? A[v & 63] : '=';
    }
    if (o)
        *q = 0;
    return o;
}

int btf_base64_decode(const char *s, uint8_t *out, size_t n)
{
    const char *A = btf__b64_alphabet;
    size_t len = s ? strlen(s) : 0, k = 0;
    if (!s || len != (n + 2) / 3 * 4)
        return 0;
    for (size_t i = 0; i < len; i += 4) {
        unsigned v = 0;
        int pad = 0;
        for (int j = 0; j < 4; j++) {
            const char *q = s[i + j] ? strchr(A, s[i + j]) : NULL;
            if (s[i + j] == '=' && i + 4 == len && j >= 2)
                pad++, q = A;
            else if (!q || pad)
                return 0;
            v = v << 6 | (unsigned)(q - A);
        }
        for (int j = 0; j < 3 - pad; j++) {
            if (k == n)
                return 0; /* more bytes than asked for */
            out[k++] = (uint8_t)(v >> (16 - 8 * j));
        }
    }
    return k == n;
}
