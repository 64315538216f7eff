/* btf_input.h - what the readers of measured BTFs (btf_ubo2003.c, btf_dfmf.c,
 * btf_thesis.c) offer the one dispatcher, btf_input.c, and the tests: each
 * format's own entry points. A program outside the codec opens any input with
 * btf_load_any or btf_views_open (btf_io.h, btf_views.h).
 */
#ifndef BTF_INPUT_H
#define BTF_INPUT_H

#include "btf_io.h"
#include "btf_views.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Angles tl, pl, tv, pv (whole degrees, 0..999) of a UBO2003 image file name
 * (basename): 1 if it is a .png/.jpg/.jpeg whose stem ends in the angle pattern
 * "tlTTT_plPPP_tvTTT_pvPPP" (doc/input-formats.md section 1), 0 otherwise. */
int btf_ubo2003_name_angles(const char *name, int a[4]);

/* Adds one image's counts (path, samples, of them at 255) to rep. */
void btf_load_report_add(btf_load_report *rep, const char *path, long long samples, long long saturated);

/* UBO2003 image directory (doc/input-formats.md section 1): files named ..._tlTTT_plPPP_tvTTT_pvPPP.{jpg,png}
 * or "tvTTT_pvPPP/NNNNN tlTTT plPPP tvTTT pvPPP.jpg"; every (light, view) image exactly once. */
btf_result btf_load_ubo2003_dir(const char *dir, const btf_load_options *opt, btf **out, btf_error *err);

/* The thesis's published package (doc/input-formats.md section 3): full reconstruction.
 * opt->width/height choose the output size (box filter for divisors of 256, area-weighted otherwise). */
btf_result btf_import_thesis(const char *dir, const btf_load_options *opt, btf **out, btf_error *err);

/* UBO2014 DFMF08FC `.btf` file (doc/input-formats.md section 2): decoded to float RGB. */
btf_result btf_load_dfmf(const char *path, const btf_load_options *opt, btf **out, btf_error *err);

/* Each reader as a view source (btf_views_open dispatches to them). */
btf_result btf_views_open_ubo2003(const char *dir, const btf_load_options *opt, btf_views *out, btf_error *err);
btf_result btf_views_open_dfmf(const char *path, const btf_load_options *opt, btf_views *out, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
