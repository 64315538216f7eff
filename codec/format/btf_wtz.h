/* btf_wtz.h - the version-3 weights file wt-JJ.z (doc/package-format.md section 9.3):
 * 16-bit quantised weights as zigzag differences along the lights, in two byte
 * planes, in one zlib stream.
 *
 *     uint8_t *z; size_t nz;
 *     btf_wtz_encode(q, V, L, &z, &nz, &err);       // q: V*L*3 values, (v*L + l)*3 + c
 *     btf_wtz_decode(z, nz, V, L, q_back, "wt-00.z", &err);
 *     free(z);
 */
#ifndef BTF_WTZ_H
#define BTF_WTZ_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Largest file a reader accepts for V*L*3 weights: the raw size plus deflate's worst-case framing. */
size_t btf_wtz_max_bytes(int V, int L);
/* Encodes q (V*L*3) into a malloc'd zlib stream *out of *len bytes (owned by the caller). */
btf_result btf_wtz_encode(const uint16_t *q, int V, int L, uint8_t **out, size_t *len, btf_error *err);
/* Decodes z (len bytes) into q (V*L*3); the stream must inflate to exactly 2*V*L*3
 * bytes and end there. name labels the messages. */
btf_result btf_wtz_decode(const uint8_t *z, size_t len, int V, int L, uint16_t *q, const char *name,
                          btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
