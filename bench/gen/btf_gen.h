/* btf_gen.h - synthetic, physically plausible BTFs with known ground truth.
 *
 *     btf_gen_params p = btf_gen_defaults(BTF_GEN_KNIT);
 *     btf *m; btf_gen_create(&p, 64, 64, &lights, &views, BTF_U8, &m, &err);
 *     float rgb[3]; btf_gen_eval(&p, 64, 64, x, y, light_dir, view_dir, rgb);  // any direction
 *
 * Model: a tileable height field with self-shadowing (marched toward the light),
 * masking/parallax for grazing views (marched along the view ray), spatially
 * varying albedo, Lambert diffuse plus a specular lobe of spatially varying
 * roughness; values include the cos(theta_light) factor like measured images.
 *
 * Details (what a user of the ground truth may rely on):
 * - Frame: local directions with z = surface normal, x = +column, y = towards
 *   image row 0 (doc/input-formats.md section 1). The pattern is defined on the unit square
 *   and tiles (texel x wraps modulo w), so a 256x256 material looks like a 64x64
 *   one at 4x the resolution; height_scale is in texels of a 64x64 material and
 *   scales with sqrt(w*h)/64.
 * - Rectification plane = the base (lowest point) of the relief, as for a sample
 *   lying on a plate: at grazing views, raised parts appear shifted away from the
 *   viewer by height * tan(theta_view) (tan capped at 8, i.e. 82.9 deg), and hide
 *   what lies behind them (masking).
 * - Shading (linear): vis * (albedo * max(n.l, 0) + specular) + 0.1 * albedo * l_z,
 *   specular = ks * (e + 8) / 8 * max(n.h, 0)^e * (1 + 2 (1 - v.h)^5) * max(n.l, 0)
 *   (normalised Blinn-Phong, e = 2 / roughness^2 - 2); vis = soft shadow from a
 *   march along the light azimuth; n, albedo, e, ks, vis are bilinearly
 *   interpolated at the visible point found by marching the view ray.
 * - Output = sRGB-encoded (IEC 61966-2-1 curve) clamp(linear, 0, 1): 0..1 floats,
 *   the byte/255 scale of btf_get. Stored U8 samples are round(255 * value).
 * - Any direction is accepted: non-unit vectors are normalised; a light with
 *   z <= 0 (or NaN/zero) gives black; a view below the horizon is clamped to the
 *   horizon at its azimuth (NaN/zero view = the normal). Output is continuous in
 *   both directions and never NaN.
 *
 * Limitations: btf_gen_eval rebuilds the material's fields on every call
 * (about w*h work); for many evaluations use btf_gen_model_create once.
 */
#ifndef BTF_GEN_H
#define BTF_GEN_H

#include "btf.h"
#include "btf_views.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_gen_kind { BTF_GEN_KNIT = 0, BTF_GEN_TILES, BTF_GEN_STONE, BTF_GEN_KIND_COUNT } btf_gen_kind;

/* Generator parameters; plain value, zero-cost to copy. */
typedef struct btf_gen_params {
    btf_gen_kind kind;
    unsigned seed;
    float height_scale; /* relief depth in texels of a 64x64 material (scaled with size), 0..64 */
    float spec_strength;/* specular weight ks of the shiniest texels, 0..10 */
    float roughness_min, roughness_max; /* Blinn-Phong roughness range, 0.02..1 */
    int repeats;        /* pattern periods across the material (stitches, tiles, noise base); 0 = kind default */
} btf_gen_params;

btf_gen_params btf_gen_defaults(btf_gen_kind kind);
/* Parses "knit", "tiles", "stone"; -1 if unknown. */
int btf_gen_kind_from_name(const char *name);
const char *btf_gen_kind_name(btf_gen_kind kind);

/* Checks a parameter set; BTF_ERR_ARG/BTF_ERR_RANGE naming the bad field. */
btf_result btf_gen_check_params(const btf_gen_params *p, btf_error *err);

/* Fills a new BTF of size w x h sampled at the given direction sets (uses all cores). */
btf_result btf_gen_create(const btf_gen_params *p, int w, int h, const btf_dirset *lights, const btf_dirset *views,
                          btf_storage storage, btf **out, btf_error *err);
/* The same material as a view source (codec/include/btf_views.h): each fill renders one view
 * (the samples btf_gen_create stores as BTF_U8, bit for bit), so a full-size
 * material (151 x 151 directions at 400 x 400 texels) needs one view's images and
 * the shadow table (4 * lights * w * h bytes) in memory, never the material. */
btf_result btf_gen_views_open(const btf_gen_params *p, int w, int h, const btf_dirset *lights, const btf_dirset *views,
                              btf_views *out, btf_error *err);
/* Ground truth at texel (x, y) of a w x h material for local directions (z = normal);
 * equals what btf_gen_create stores (F32) at measured directions. Black on bad params. */
void btf_gen_eval(const btf_gen_params *p, int w, int h, int x, int y, const float light[3], const float view[3],
                  float rgb[3]);

/* Precomputed fields (height, normals, albedo, roughness) of one material; created by
 * btf_gen_model_create, owned by the caller, released with btf_gen_model_free. */
typedef struct btf_gen_model btf_gen_model;

btf_result btf_gen_model_create(const btf_gen_params *p, int w, int h, btf_gen_model **out, btf_error *err);
void btf_gen_model_free(btf_gen_model *m);
/* Same value as btf_gen_eval, without rebuilding the fields; thread-safe (read only). */
void btf_gen_model_eval(const btf_gen_model *m, int x, int y, const float light[3], const float view[3],
                        float rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
