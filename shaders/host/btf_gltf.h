/* btf_gltf.h - glTF 2.0 models for `btf render --model`: every triangle primitive
 * of the model's scene, node transforms applied, as render meshes in world units,
 * each with its glTF material's name and base colour.
 *
 *     btf_gltf *m = NULL;
 *     if (btf_gltf_load("chair.glb", &m, &err) != BTF_OK) puts(err.msg);
 *     for (int i = 0; i < m->n_parts; i++)
 *         draw(m->parts[i].material, &m->parts[i].mesh);   // world-space triangles
 *     btf_gltf_free(m);
 *
 * Read through tinygltf (btf_gltf.cpp, the one C++ file of this room), then
 * checked here before anything is trusted: every accessor's type, component type,
 * count, offset and stride against its buffer view and buffer, every index against
 * its vertex count, finite positions, the limits below (doc/client.md "Models"
 * lists them). Primitives must be triangles (mode 4); sparse accessors and
 * Draco/meshopt compression are refused. Texture images are never decoded.
 *
 * World: glTF's +y up becomes the world's +z of shaders/host/btf_render.h (x' = x,
 * y' = -z, z' = y), so the model stands on the world's ground and its front (glTF
 * +z) faces the default camera (phi -90).
 *
 * Tangents: TANGENT when the primitive has it (w the handedness), else generated
 * by btf_gltf_tangents (the MikkTSpace convention, as glTF specifies it).
 * Normals: NORMAL, else flat face normals (glTF's rule). A primitive without
 * TEXCOORD_0 loads (uv 0) with has_uv = 0: it can be drawn in its base colour,
 * not with a BTF.
 */
#ifndef BTF_GLTF_H
#define BTF_GLTF_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"
#include "btf_render.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_GLTF_MAX_FILE_BYTES (256ll << 20) /* a .glb, .gltf or external buffer */
#define BTF_GLTF_MAX_VERTICES 4000000         /* all parts, after node instancing */
#define BTF_GLTF_MAX_TRIANGLES 4000000        /* all parts, after node instancing */
#define BTF_GLTF_MAX_PARTS 4096               /* drawn primitives, after instancing */
#define BTF_GLTF_MAX_DEPTH 64                 /* node hierarchy depth */
#define BTF_GLTF_MAX_NODE_VISITS 65536        /* node instances in the scene (shared children count each time) */
#define BTF_GLTF_NAME_MAX 64                  /* material name, including NUL */

/* One drawn primitive (a glTF primitive under one node); owned by its btf_gltf. */
typedef struct btf_gltf_part {
    char material[BTF_GLTF_NAME_MAX]; /* the glTF material's name; "" when none or unnamed */
    int material_index;                /* index into the glTF's materials, -1 when none */
    float base_color[4];               /* pbrMetallicRoughness.baseColorFactor (linear RGBA) */
    int has_uv;                        /* 1: TEXCOORD_0 given */
    int tangents_given;                /* 1: TANGENT from the file; 0: generated */
    btf_render_mesh mesh;              /* world space; tangent w = handedness */
} btf_gltf_part;

/* A loaded model; heap struct owned by the caller (btf_gltf_free). */
typedef struct btf_gltf {
    int n_parts;
    btf_gltf_part *parts;
    float min[3], max[3]; /* world-space bounds of every vertex */
} btf_gltf;

/* Loads a .glb, or a .gltf with its buffers (files beside it or data URIs). */
btf_result btf_gltf_load(const char *path, btf_gltf **out, btf_error *err);
/* The same from bytes in memory (a .glb, or a .gltf whose buffers are data URIs);
 * name appears in error messages. */
btf_result btf_gltf_load_memory(const uint8_t *data, size_t size, const char *name, btf_gltf **out,
                                 btf_error *err);
void btf_gltf_free(btf_gltf *m);

/* Tangents of an indexed triangle mesh by the MikkTSpace convention as glTF reads it
 * (w * cross(normal, tangent) towards decreasing v): per triangle the direction of
 * increasing u in the surface (and of v, for the handedness),
 * projected into each corner's tangent plane and summed weighted by the corner's
 * angle over the triangles that share a vertex and a handedness; a vertex whose
 * triangles disagree on handedness is split. Reads positions, normals and uvs of
 * the interleaved vertices (BTF_RENDER_VERTEX_FLOATS each), writes their tangents
 * (xyz unit, w = +1 or -1). May grow the mesh (new vertices appended, indices
 * rewritten): BTF_ERR_NOMEM when that cannot be had. */
btf_result btf_gltf_tangents(btf_render_mesh *m, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
