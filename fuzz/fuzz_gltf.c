/* fuzz_gltf.c - libFuzzer target for the glTF reader (btf_gltf_load_memory,
 * shaders/host/btf_gltf.cpp): an accepted model keeps every promise of btf_gltf.h
 * (parts and sizes within the limits, every index inside its part, finite unit
 * normals and tangents, w = +-1, bounds around every vertex); a refused one says why. */
#include <math.h>

#include "btf_gltf.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_part(const btf_gltf *m, const btf_gltf_part *p)
{
    FUZZ_CHECK(p->mesh.n_vertices >= 1 && p->mesh.n_vertices <= BTF_GLTF_MAX_VERTICES);
    FUZZ_CHECK(p->mesh.n_indices % 3 == 0 && p->mesh.n_indices / 3 <= BTF_GLTF_MAX_TRIANGLES);
    FUZZ_CHECK(memchr(p->material, 0, sizeof p->material) != NULL);
    for (int i = 0; i < p->mesh.n_indices; i++)
        FUZZ_CHECK(p->mesh.indices[i] < (unsigned)p->mesh.n_vertices);
    for (int v = 0; v < p->mesh.n_vertices; v++) {
        const float *q = p->mesh.vertices + (size_t)v * BTF_RENDER_VERTEX_FLOATS;
        for (int k = 0; k < BTF_RENDER_VERTEX_FLOATS; k++)
            FUZZ_CHECK(isfinite(q[k]));
        for (int k = 0; k < 3; k++)
            FUZZ_CHECK(q[k] >= m->min[k] && q[k] <= m->max[k]);
        double n = q[3] * q[3] + q[4] * q[4] + q[5] * q[5], t = q[6] * q[6] + q[7] * q[7] + q[8] * q[8];
        FUZZ_CHECK(fabs(n - 1) < 1e-3 && fabs(t - 1) < 1e-3);
        FUZZ_CHECK(q[9] == 1.0f || q[9] == -1.0f);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    btf_gltf *m = NULL;
    btf_error err = {{0}};
    if (btf_gltf_load_memory(data, size, "fuzz.glb", &m, &err) == BTF_OK) {
        FUZZ_CHECK(m && m->n_parts >= 1 && m->n_parts <= BTF_GLTF_MAX_PARTS);
        for (int i = 0; i < m->n_parts; i++)
            check_part(m, &m->parts[i]);
    } else {
        FUZZ_CHECK(m == NULL && err.msg[0] != 0);
    }
    btf_gltf_free(m);
    return 0;
}
