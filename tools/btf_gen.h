/* btf_gen.h - synthetic, physically plausible BTFs with known ground truth.
 *
 *     btf_gen_params p = btf_gen_defaults(BTF_GEN_KNIT);
 *     btf *m; btf_gen_create(&p, 64, 64, &lights, &views, BTF_U8, &m, &err);
 *     float rgb[3]; btf_gen_eval(&p, x, y, light_dir, view_dir, rgb);  // any direction
 *
 * Model: a tileable height field with self-shadowing (marched toward the light),
 * masking/parallax for grazing views (marched along the view ray), spatially
 * varying albedo, Lambert diffuse plus a specular lobe of spatially varying
 * roughness; values include the cos(theta_light) factor like measured images.
 */
#ifndef BTF_GEN_H
#define BTF_GEN_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_gen_kind { BTF_GEN_KNIT = 0, BTF_GEN_TILES, BTF_GEN_STONE, BTF_GEN_KIND_COUNT } btf_gen_kind;

/* Generator parameters; plain value, zero-cost to copy. */
typedef struct btf_gen_params {
    btf_gen_kind kind;
    unsigned seed;
    float height_scale; /* relief depth in texel units */
    float spec_strength;
    float roughness_min, roughness_max;
} btf_gen_params;

btf_gen_params btf_gen_defaults(btf_gen_kind kind);
/* Parses "knit", "tiles", "stone"; -1 if unknown. */
int btf_gen_kind_from_name(const char *name);
const char *btf_gen_kind_name(btf_gen_kind kind);

/* Fills a new BTF of size w x h sampled at the given direction sets. */
btf_result btf_gen_create(const btf_gen_params *p, int w, int h, const btf_dirset *lights, const btf_dirset *views,
                          btf_storage storage, btf **out, btf_error *err);
/* Ground truth at texel (x, y) of a w x h material for unit local directions (z = normal). */
void btf_gen_eval(const btf_gen_params *p, int w, int h, int x, int y, const float light[3], const float view[3],
                  float rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
