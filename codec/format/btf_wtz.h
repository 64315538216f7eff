/* btf_wtz.h - the weights files wt-JJ.z (doc/package-format.md section 9.3) and
 * wt-JJ.pz (section 5.4): 16-bit quantised weights as zigzag residuals of a
 * prediction, in two byte planes, in one zlib stream. wt-JJ.z predicts from the
 * previous light; wt-JJ.pz also from the view before in the same block, and codes
 * channels 0 and 2 less channel 1's residual.
 *
 *     uint8_t *z; size_t nz;
 *     btf_wtz_encode(q, V, L, &z, &nz, &err);       // q: V*L*3 values, (v*L + l)*3 + c
 *     btf_wtz_decode(z, nz, V, L, q_back, "wt-00.z", &err);
 *     free(z);
 *
 *     int prev[V];                                   // wt-JJ.pz: each view's predecessor
 *     btf_wtz_prev_views(blocks->block_of_view, V, prev);
 *     btf_wtz_encode_pred(q, V, L, prev, &z, &nz, &err);
 *     btf_wtz_decode_pred(z, nz, V, L, prev, q_back, "wt-00.pz", &err);
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

/* prev[v] (V ints) = the largest view index below v in v's block, -1 when there is none. */
void btf_wtz_prev_views(const int *block_of_view, int V, int *prev);
/* As btf_wtz_encode and btf_wtz_decode, with prev (btf_wtz_prev_views) the coding of
 * wt-JJ.pz; prev NULL is wt-JJ.z's. */
btf_result btf_wtz_encode_pred(const uint16_t *q, int V, int L, const int *prev, uint8_t **out, size_t *len,
                               btf_error *err);
btf_result btf_wtz_decode_pred(const uint8_t *z, size_t len, int V, int L, const int *prev, uint16_t *q,
                               const char *name, btf_error *err);
/* q coded both ways, the smaller kept (ties: wt-JJ.z) into *out (malloc'd, *len bytes);
 * *pred = 1 when it is wt-JJ.pz's coding. What the writers write and the allocation counts. */
btf_result btf_wtz_encode_smaller(const uint16_t *q, int V, int L, const int *prev, uint8_t **out, size_t *len,
                                  int *pred, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
