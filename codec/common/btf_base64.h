/* btf_base64.h - standard base64 (RFC 4648 alphabet, '=' padding, no line breaks).
 *
 *     char *s = btf_base64_encode(bytes, 16);        // malloc'd, NUL-terminated
 *     uint8_t back[16];
 *     int ok = btf_base64_decode(s, back, 16);       // 1: exactly 16 bytes decoded
 *     free(s);
 */
#ifndef BTF_BASE64_H
#define BTF_BASE64_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Base64 of n bytes as a new string (free it); NULL when out of memory. */
char *btf_base64_encode(const uint8_t *data, size_t n);
/* Decodes s into exactly n bytes; 0 when s is not the base64 of n bytes. */
int btf_base64_decode(const char *s, uint8_t *out, size_t n);

#ifdef __cplusplus
}
#endif
#endif
