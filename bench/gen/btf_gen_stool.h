/* btf_gen_stool.h - a small glTF 2.0 product with known geometry: a stool of three
 * materials, written as a .glb for the tests and the demo, and the same surfaces
 * in world space straight from their formulas (the tests' independent reference).
 *
 *     btf_gen_stool_write("stool.glb", 0, &err);
 *     btf_gen_stool_part parts[BTF_GEN_STOOL_PARTS];
 *     btf_gen_stool_parts(0, parts, &err);     // world space, z up, as btf_gltf_load
 *     ...
 *     btf_gen_stool_free(parts);
 *
 * The model (glTF units, +y up; 1 uv unit = 0.8 units of surface, the seat's width):
 *   mesh 0 "seat": primitive 0, material "Seat": the top disc, radius 0.4 at y 0.55,
 *            uv = (x / 0.8 + 0.5, z / 0.8 + 0.5), NORMAL and TANGENT given, u16 indices;
 *          primitive 1, material "Trim": the side band, y 0.43..0.55, u = angle * 0.4 /
 *            0.8, v = (0.55 - y) / 0.8, no TANGENT, u32 indices.
 *   mesh 1 "leg": material "Frame": an open tube of radius 0.035 along y 0..0.43,
 *            u = angle * 0.035 / 0.8, v = (0.43 - y) / 0.8, no TANGENT, u8 indices.
 *   nodes: "stool" (rotation 25 degrees about +y) with children "seat" (translation
 *   y 0) and four "leg" nodes (translation (+-0.26, 0, +-0.26), each tilted 6 degrees
 *   outwards): one mesh drawn four times under non-identity transforms.
 * Angles run from +x towards +z: position (r cos a, y, r sin a).
 */
#ifndef BTF_GEN_STOOL_H
#define BTF_GEN_STOOL_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_GEN_STOOL_PARTS 6 /* drawn primitives: top, band, four legs */
#define BTF_GEN_STOOL_FLOATS 12 /* per vertex: position 3, normal 3, tangent 4, uv 2 */

/* One drawn primitive in world space (z up: glTF's (x, y, z) is (x, -z, y) here),
 * tangents from the formulas (w = the glTF handedness). Arrays malloc'd, freed by
 * btf_gen_stool_free. */
typedef struct btf_gen_stool_part {
    const char *material; /* "Seat", "Trim" or "Frame" (static) */
    float *vertices;      /* n_vertices * BTF_GEN_STOOL_FLOATS */
    int n_vertices;
    unsigned *indices;    /* n_indices, triangles */
    int n_indices;
} btf_gen_stool_part;

/* segments: subdivisions around; 0 = 48 (at most 120: the legs' u8 indices). */
btf_result btf_gen_stool_write(const char *path, int segments, btf_error *err);
btf_result btf_gen_stool_parts(int segments, btf_gen_stool_part parts[BTF_GEN_STOOL_PARTS], btf_error *err);
void btf_gen_stool_free(btf_gen_stool_part parts[BTF_GEN_STOOL_PARTS]);

#ifdef __cplusplus
}
#endif
#endif
