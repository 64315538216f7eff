/* btf_color.h - sRGB transfer functions and CIELab, one copy for the metrics,
 * the method families and the generator.
 *
 *     float lab[3], rgb[3] = {0.5f, 0.25f, 1.0f};   // sRGB-encoded, 0..1
 *     btf_color_srgb_to_lab(rgb, lab);              // D65, L in 0..100
 *     double lin = btf_color_srgb_decode(0.5);      // 0.214...
 */
#ifndef BTF_COLOR_H
#define BTF_COLOR_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* sRGB-encoded value (0..1) to linear light; no clamping. */
double btf_color_srgb_decode(double v);
/* Linear light (0..1) to the sRGB encoding; no clamping. */
double btf_color_srgb_encode(double v);
/* btf_color_srgb_decode / btf_color_srgb_encode of n floats in place (the double
 * formulas rounded to float; no clamping: below 0 both follow the linear segment,
 * above 1 the power curve). encode_n gives 0 for NaN. */
void btf_color_srgb_decode_n(float *v, size_t n);
void btf_color_srgb_encode_n(float *v, size_t n);
/* sRGB (byte/255 scale, clamped to 0..1, NaN as 0) to CIELab (D65), in double precision. */
void btf_color_srgb_to_lab(const float rgb[3], float lab[3]);

#ifdef __cplusplus
}
#endif
#endif
