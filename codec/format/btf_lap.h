/* btf_lap.h - the residual levels of package version 4 (doc/package-format.md
 * section 12): a finer level's atlas coded as a residual over the next coarser one,
 * with a per-level linear predictor fitted by least squares.
 *
 *     btf_lap_pred pr = btf_lap_pred_fit(fine, coarse, aw, ah, tw, th);
 *     btf_lap_encode(fine, coarse, aw, ah, tw, th, &pr, res, &err);  // the residual PNG's bytes
 *     btf_lap_decode(res, coarse, aw, ah, tw, th, &pr, back, &err);  // back == fine
 *
 * Atlases are aw x ah bytes (aw, ah even) in tiles of tw x th texels (tw, th even);
 * coarse is the (aw/2) x (ah/2) atlas of the next coarser level, each of its texels
 * the rounded mean of the 2x2 cell above it.
 */
#ifndef BTF_LAP_H
#define BTF_LAP_H

#include <stdint.h>

#include "btf_package.h" /* btf_lap_pred */

#ifdef __cplusplus
extern "C" {
#endif

/* The predictor of a residual level whose chunk lists none: p + floor((eL + eU) / 4). */
btf_lap_pred btf_lap_pred_default(void);

/* The least-squares predictor of fine over coarse, rounded to integers within
 * BTF_LAP_PRED_MAX; the default one where the fit is degenerate or out of memory. */
btf_lap_pred btf_lap_pred_fit(const uint8_t *fine, const uint8_t *coarse, int aw, int ah, int tw, int th);

/* The residual of fine: texel (x, y) with x or y even stores (q - pred + 128) mod
 * 256; (odd x, odd y) the cell's (q0 + q1 + q2 + q3 - 4 coarse + 128) mod 256.
 * BTF_ERR_NOMEM when the prediction scratch (2 bytes a texel) cannot be had. */
btf_result btf_lap_encode(const uint8_t *fine, const uint8_t *coarse, int aw, int ah, int tw, int th,
                          const btf_lap_pred *pred, uint8_t *res, btf_error *err);

/* Inverts btf_lap_encode exactly (raster order), for any residual bytes. */
btf_result btf_lap_decode(const uint8_t *res, const uint8_t *coarse, int aw, int ah, int tw, int th,
                          const btf_lap_pred *pred, uint8_t *fine, btf_error *err);

#ifdef __cplusplus
}
#endif

#endif
