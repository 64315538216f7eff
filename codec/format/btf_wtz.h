/* btf_wtz.h - the weights files wt-JJ.z (doc/package-format.md section 9.3) and
 * wt-JJ.pz (section 5.4): 16-bit quantised weights as zigzag residuals of a
 * prediction, in two byte planes, in one zlib stream. wt-JJ.z predicts from the
 * previous light; wt-JJ.pz also from the view before in the same block, and codes
 * channels 0 and 2 less channel 1's residual. And wt-JJ.webp (section 5.5): codes
 * that fit 8 bits as a lossless RGB image, lights across, views down.
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
/* The codings of version 3's 16-bit weights files, by the file's name: wt-JJ.z,
 * wt-JJ.pz and wt-JJ.webp. */
#define BTF_WTZ_Z 0
#define BTF_WTZ_PZ 1
#define BTF_WTZ_WEBP 2

/* 1 when every one of q's V*L*3 codes is at most 255: a wt-JJ.webp can hold them. */
int btf_wtz_fits_webp(const uint16_t *q, int V, int L);
/* wt-JJ.webp (doc/package-format.md section 5.5): q (V*L*3, every code <= 255, else
 * BTF_ERR_RANGE) as an opaque lossless RGB WebP of L x V pixels, pixel (l, v) holding
 * channels 0, 1, 2 of view v and light l, into *out (malloc'd, *len bytes). */
btf_result btf_wtz_encode_webp(const uint16_t *q, int V, int L, uint8_t **out, size_t *len, btf_error *err);
/* Reads a wt-JJ.webp of len bytes (at most btf_wtz_max_bytes) into q (V*L*3): L x V,
 * lossless with every pixel opaque, or lossy (its RGB decode: the codes of section
 * 5.5's lossy weights); BTF_ERR_FORMAT naming name otherwise. */
btf_result btf_wtz_decode_webp(const uint8_t *data, size_t len, int V, int L, uint16_t *q, const char *name,
                               btf_error *err);
/* The extension of coding kind's files: ".z", ".pz" or ".webp" (static strings). */
const char *btf_wtz_ext(int kind);
/* The coding of a weights file named name (wt-*.z but not wt-*-r.z, wt-*.pz,
 * wt-*.webp), -1 for any other name. */
int btf_wtz_kind_of(const char *name);
/* Decodes a file of coding kind (prev: the views' predecessors, for wt-JJ.pz). */
btf_result btf_wtz_decode_kind(int kind, const uint8_t *data, size_t len, int V, int L, const int *prev,
                               uint16_t *q, const char *name, btf_error *err);
/* q coded each way it can be (wt-JJ.z, wt-JJ.pz and, with webp and when every code is
 * at most 255, wt-JJ.webp), the smallest kept (ties: in that order) into *out
 * (malloc'd, *len bytes), its coding into *kind (BTF_WTZ_*). What the writers write
 * and the allocation counts (webp 0: a package of PNG files and zlib streams only). */
btf_result btf_wtz_encode_smaller(const uint16_t *q, int V, int L, const int *prev, int webp, uint8_t **out,
                                  size_t *len, int *kind, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
