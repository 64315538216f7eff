/* test_model.c - suite "model": glTF models in the GL host (shaders/host/btf_gltf.h,
 * btf_scene.h, `btf render --model`).
 *
 * The stool of bench/gen/btf_gen_stool.h is written as a .glb and read back: every
 * part must equal the surfaces the generator computes from its formulas in world
 * space (not through glTF's matrices). Rendered with two packages bound and one
 * part in its base colour, on both backends, every pixel is checked against a CPU
 * ray cast of those formula surfaces shaded with btf_decode (and the flat rule).
 * Hostile variants of the file are refused with a message naming the fault. */
#include <cjson/cJSON.h>
#include <math.h>

#include "btf_color.h"
#include "btf_decode.h"
#include "btf_env.h"
#include "btf_gen_stool.h"
#include "btf_gltf.h"
#include "btf_scene.h"
#include "fixtures.h"

#define SEG 24 /* stool segments: tangents of the generated kind deviate by at most half of one */

/* ---------------------------------------------------------------- loading */

static double dot3(const float *a, const float *b) { return (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2]; }

/* The stool written into a fresh tmp (path = tmp/stool.glb); when m, read back
 * into *m, and when ref, its formula surfaces into ref. */
static void stool(char tmp[256], char path[300], btf_gltf **m, btf_gen_stool_part *ref)
{
    cr_assert(fx_tmpdir(tmp, 256));
    snprintf(path, 300, "%s/stool.glb", tmp);
    btf_error err = {{0}};
    cr_assert_eq(btf_gen_stool_write(path, SEG, &err), BTF_OK, "%s", err.msg);
    if (m)
        cr_assert_eq(btf_gltf_load(path, m, &err), BTF_OK, "%s", err.msg);
    if (ref)
        cr_assert_eq(btf_gen_stool_parts(SEG, ref, &err), BTF_OK, "%s", err.msg);
}

Test(model, stool_loads_as_its_formulas)
{
    char tmp[256], path[300];
    btf_gltf *m = NULL;
    btf_gen_stool_part ref[BTF_GEN_STOOL_PARTS];
    stool(tmp, path, &m, ref);
    cr_assert_eq(m->n_parts, BTF_GEN_STOOL_PARTS);
    /* generated tangents: the mean of the faces' u directions around a vertex, exact on
     * a tube's inner vertices, half a segment off at the seam (one face only) */
    double worst_deg = 0, max_dev = 180.0 / SEG + 0.01;
    for (int i = 0; i < m->n_parts; i++) {
        const btf_gltf_part *p = &m->parts[i];
        const btf_gen_stool_part *r = &ref[i];
        cr_assert_str_eq(p->material, r->material, "part %d", i);
        cr_assert(p->has_uv);
        cr_assert_eq(p->tangents_given, i == 0, "part %d: only the seat top carries TANGENT", i);
        cr_assert_eq(p->mesh.n_vertices, r->n_vertices, "part %d (one handedness: no vertex split)", i);
        cr_assert_eq(p->mesh.n_indices, r->n_indices, "part %d", i);
        cr_assert_eq(memcmp(p->mesh.indices, r->indices, (size_t)r->n_indices * sizeof(unsigned)), 0,
                     "part %d: triangles (and their winding) differ", i);
        for (int v = 0; v < r->n_vertices; v++) {
            const float *a = p->mesh.vertices + (size_t)v * BTF_RENDER_VERTEX_FLOATS;
            const float *b = r->vertices + (size_t)v * BTF_GEN_STOOL_FLOATS;
            for (int c = 0; c < 3; c++) /* float32 positions through two transforms: 1e-5 of a ~1 unit model */
                cr_assert(fabsf(a[c] - b[c]) < 1e-5f, "part %d vertex %d: position %g, formula %g", i, v, a[c], b[c]);
            cr_assert(dot3(a + 3, b + 3) > 1 - 1e-6, "part %d vertex %d: normal", i, v);
            cr_assert(a[10] == b[10] && a[11] == b[11], "part %d vertex %d: uv", i, v);
            cr_assert_eq(a[9], b[9], "part %d vertex %d: handedness %g, formula %g", i, v, a[9], b[9]);
            double dev = acos(fmin(1.0, dot3(a + 6, b + 6))) * 180 / M_PI;
            worst_deg = fmax(worst_deg, dev);
            cr_assert_leq(dev, i == 0 ? 1e-3 : max_dev, "part %d vertex %d: tangent %.3f degrees off", i, v, dev);
        }
    }
    cr_assert_gt(worst_deg, 0.0, "the generated tangents were never tested off the formula");
    cr_log_info("model: generated tangents at most %.3f degrees from the formulas (bound %.3f)", worst_deg, max_dev);
    /* bounds: the formula vertices' */
    for (int c = 0; c < 3; c++) {
        float lo = INFINITY, hi = -INFINITY;
        for (int i = 0; i < BTF_GEN_STOOL_PARTS; i++)
            for (int v = 0; v < ref[i].n_vertices; v++)
                lo = fminf(lo, ref[i].vertices[v * BTF_GEN_STOOL_FLOATS + c]),
                hi = fmaxf(hi, ref[i].vertices[v * BTF_GEN_STOOL_FLOATS + c]);
        cr_assert(fabsf(m->min[c] - lo) < 1e-5f && fabsf(m->max[c] - hi) < 1e-5f, "bounds axis %d", c);
    }
    cr_assert_lt(m->min[2], 0.01f, "the stool stands on z = 0 (glTF +y up is +z)");
    btf_gen_stool_free(ref);
    btf_gltf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* A tangent-less mirrored quad: the generated frame follows the uvs, the mirror
 * turns the winding and flips the handedness (w). */
Test(model, tangents_follow_uv_and_mirror)
{
    /* quad in the xy plane, normal +z, u along +x, v along -y (image rows downwards):
     * the frame of shaders/btf_render.vert with w = +1 */
    float v[4][BTF_RENDER_VERTEX_FLOATS] = {{0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1},
                                            {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1},
                                            {1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0},
                                            {0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0}};
    unsigned idx[6] = {0, 1, 2, 0, 2, 3};
    btf_render_mesh m = {malloc(sizeof v), 4, malloc(sizeof idx), 6};
    memcpy(m.vertices, v, sizeof v), memcpy(m.indices, idx, sizeof idx);
    btf_error err = {{0}};
    cr_assert_eq(btf_gltf_tangents(&m, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(m.n_vertices, 4);
    for (int i = 0; i < 4; i++) {
        const float *q = m.vertices + i * BTF_RENDER_VERTEX_FLOATS;
        cr_assert(fabsf(q[6] - 1) < 1e-6f && fabsf(q[7]) < 1e-6f && fabsf(q[8]) < 1e-6f, "vertex %d tangent", i);
        cr_assert_eq(q[9], 1.0f, "vertex %d: cross(n, t) = +y, towards v = 0", i);
    }
    /* u mirrored on the first triangle only (vertex 1 at u = -1): the vertices both
     * triangles share (0 and 2) split, one copy per handedness */
    m.vertices[1 * BTF_RENDER_VERTEX_FLOATS + 10] = -1;
    cr_assert_eq(btf_gltf_tangents(&m, &err), BTF_OK, "%s", err.msg);
    int minus = 0;
    for (int i = 0; i < m.n_vertices; i++)
        minus += m.vertices[i * BTF_RENDER_VERTEX_FLOATS + 9] < 0;
    cr_assert_eq(m.n_vertices, 6, "the vertices both triangles share were not split by handedness");
    cr_assert_gt(minus, 0);
    free(m.vertices), free(m.indices);
}

/* ---------------------------------------------------------------- hostile files */

/* The .glb's JSON as a document and its BIN chunk (pointers into the file). */
typedef struct glb {
    uint8_t *bytes;
    size_t n;
    cJSON *json;
    uint8_t *bin;
    size_t bin_n;
} glb;

static uint32_t rd32(const uint8_t *p) { return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24; }

static glb glb_open(const char *path)
{
    glb g = {0};
    g.bytes = (uint8_t *)fx_read(path, &g.n);
    cr_assert(g.bytes && g.n > 28);
    uint32_t jn = rd32(g.bytes + 12);
    char *text = strndup((const char *)g.bytes + 20, jn);
    g.json = cJSON_Parse(text);
    free(text);
    cr_assert(g.json);
    g.bin = g.bytes + 28 + jn, g.bin_n = rd32(g.bytes + 20 + jn);
    return g;
}

/* The file with g's JSON (as edited) and BIN (as patched), loaded from memory. */
static btf_result glb_load(const glb *g, btf_error *err)
{
    char *json = cJSON_PrintUnformatted(g->json);
    size_t jn = strlen(json), jp = (jn + 3) & ~(size_t)3, total = 28 + jp + g->bin_n;
    uint8_t *b = malloc(total);
    memcpy(b, g->bytes, 12);
    uint32_t h[2] = {(uint32_t)total, (uint32_t)jp};
    memcpy(b + 8, &h[0], 4), memcpy(b + 12, &h[1], 4), memcpy(b + 16, "JSON", 4);
    memcpy(b + 20, json, jn), memset(b + 20 + jn, ' ', jp - jn);
    memcpy(b + 20 + jp, g->bin - 8, 8 + g->bin_n);
    btf_gltf *m = (btf_gltf *)1;
    btf_result r = btf_gltf_load_memory(b, total, "hostile.glb", &m, err);
    cr_assert(r != BTF_OK || m, "");
    if (r == BTF_OK)
        btf_gltf_free(m);
    else
        cr_assert_null(m, "a failed load left a model");
    free(json), free(b);
    return r;
}

static cJSON *at(cJSON *o, const char *key, int i) { return cJSON_GetArrayItem(cJSON_GetObjectItem(o, key), i); }

static void set_num(cJSON *o, const char *key, double v) { cJSON_ReplaceItemInObject(o, key, cJSON_CreateNumber(v)); }

/* The byte offset in BIN of accessor a's first element. */
static size_t acc_offset(const glb *g, int a)
{
    cJSON *acc = at(g->json, "accessors", a);
    cJSON *bv = at(g->json, "bufferViews", cJSON_GetObjectItem(acc, "bufferView")->valueint);
    cJSON *off = cJSON_GetObjectItem(bv, "byteOffset");
    return off ? (size_t)off->valuedouble : 0;
}

static void expect_refused(const char *path, void (*edit)(glb *), const char *needle, const char *what)
{
    glb g = glb_open(path);
    edit(&g);
    btf_error err = {{0}};
    btf_result r = glb_load(&g, &err);
    cr_expect_neq(r, BTF_OK, "%s: loaded", what);
    cr_expect(strstr(err.msg, needle), "%s: message \"%s\" lacks \"%s\"", what, err.msg, needle);
    cJSON_Delete(g.json);
    free(g.bytes);
}

static void e_index(glb *g) /* the legs' u8 indices: one beyond the tube's vertices */
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 1), "primitives"), 0);
    g->bin[acc_offset(g, cJSON_GetObjectItem(p, "indices")->valueint) + 4] = 255;
}
static void e_count(glb *g) /* the leg's POSITION reads past its view */
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 1), "primitives"), 0);
    int pos = cJSON_GetObjectItem(cJSON_GetObjectItem(p, "attributes"), "POSITION")->valueint;
    cJSON *a = at(g->json, "accessors", pos);
    set_num(a, "count", cJSON_GetObjectItem(a, "count")->valuedouble + 1000);
    /* the other attributes agree with it: only the bounds can fail */
    cJSON *attrs = cJSON_GetObjectItem(p, "attributes"), *it;
    cJSON_ArrayForEach(it, attrs) set_num(at(g->json, "accessors", it->valueint), "count",
                                          cJSON_GetObjectItem(a, "count")->valuedouble);
}
static void e_mode(glb *g)
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 0), "primitives"), 0);
    cJSON_AddNumberToObject(p, "mode", 0);
}
static void e_sparse(glb *g)
{
    cJSON *a = at(g->json, "accessors", 0);
    cJSON_AddItemToObject(a, "sparse", cJSON_Parse("{\"count\":1,\"indices\":{\"bufferView\":0,\"componentType\":5125},"
                                                   "\"values\":{\"bufferView\":0}}"));
}
static void e_required(glb *g)
{
    cJSON_AddItemToObject(g->json, "extensionsRequired", cJSON_Parse("[\"KHR_draco_mesh_compression\"]"));
    cJSON_AddItemToObject(g->json, "extensionsUsed", cJSON_Parse("[\"KHR_draco_mesh_compression\"]"));
}
static void e_cycle(glb *g) { cJSON_AddItemToObject(at(g->json, "nodes", 1), "children", cJSON_Parse("[0]")); }
static void e_position(glb *g)
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 0), "primitives"), 1);
    cJSON_DeleteItemFromObject(cJSON_GetObjectItem(p, "attributes"), "POSITION");
}
static void e_view(glb *g) { set_num(at(g->json, "bufferViews", 2), "byteOffset", 1e7); }
static void e_float_index(glb *g)
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 0), "primitives"), 0);
    set_num(at(g->json, "accessors", cJSON_GetObjectItem(p, "indices")->valueint), "componentType", 5126);
}
static void e_nan(glb *g)
{
    float nan = NAN;
    memcpy(g->bin + acc_offset(g, 0) + 4, &nan, 4);
}
static void e_attributes(glb *g)
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 0), "primitives"), 1);
    cJSON_DeleteItemFromObject(p, "attributes");
}
static void e_accessor(glb *g)
{
    cJSON *p = cJSON_GetArrayItem(cJSON_GetObjectItem(at(g->json, "meshes", 0), "primitives"), 1);
    set_num(cJSON_GetObjectItem(p, "attributes"), "NORMAL", 9999);
}

Test(model, hostile_glb_refused)
{
    char tmp[256], path[300];
    stool(tmp, path, NULL, NULL);
    btf_error err = {{0}};
    glb g = glb_open(path); /* the round trip itself loads: each case below fails by its edit alone */
    cr_assert_eq(glb_load(&g, &err), BTF_OK, "%s", err.msg);
    cJSON_Delete(g.json);
    free(g.bytes);
    static const struct {
        void (*edit)(glb *);
        const char *needle, *what;
    } cases[] = {{e_index, "out of bounds", "index beyond the vertices"},
                 {e_count, "past its buffer view", "accessor past its view"},
                 {e_mode, "primitive mode 0", "points instead of triangles"},
                 {e_sparse, "sparse", "sparse accessor"},
                 {e_required, "KHR_draco_mesh_compression", "required extension"},
                 {e_cycle, "deeper than", "node cycle"},
                 {e_position, "no POSITION", "primitive without POSITION"},
                 {e_view, "buffer", "buffer view beyond its buffer"},
                 {e_float_index, "not unsigned integer", "float indices"},
                 {e_nan, "not finite", "NaN position"},
                 {e_accessor, "does not exist", "missing accessor"},
                 {e_attributes, "no \"attributes\"", "primitive without attributes"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_refused(path, cases[i].edit, cases[i].needle, cases[i].what);
    /* truncations: every cut refused, none read past the bytes (ASan) */
    size_t n = 0;
    uint8_t *b = (uint8_t *)fx_read(path, &n);
    size_t cuts[] = {0, 3, 12, 20, 100, n / 2, n - 1};
    b[4] = 1; /* the header's version */
    btf_gltf *m1 = NULL;
    cr_expect_neq(btf_gltf_load_memory(b, n, "v1.glb", &m1, &err), BTF_OK, "a version-1 .glb loaded");
    cr_expect(strstr(err.msg, "version 1"), "%s", err.msg);
    b[4] = 2;
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        btf_gltf *m = NULL;
        cr_expect_neq(btf_gltf_load_memory(b, cuts[i], "cut.glb", &m, &err), BTF_OK, "cut at %zu loaded", cuts[i]);
        cr_expect_null(m);
    }
    free(b);
    /* a .gltf whose buffer lies outside its folder */
    fx_put_text(tmp, "out.gltf", "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"uri\":\"../x.bin\",\"byteLength\":4}]}");
    char gl[400];
    snprintf(gl, sizeof gl, "%s/out.gltf", tmp);
    btf_gltf *m = NULL;
    cr_expect_neq(btf_gltf_load(gl, &m, &err), BTF_OK);
    cr_expect(strstr(err.msg, "x.bin"), "%s", err.msg);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* ---------------------------------------------------------------- rendering */

#define MW 64 /* render size */
#define MH 48

/* Nearest hit of the ray through pixel (px, py) (py = 0 the bottom row) on the
 * formula surfaces: part index (-1 none), the interpolated vertex (12 floats) and
 * the distance to the nearest triangle edge in barycentric units (*edge). */
static int ray_cast(const fx_cam *c, int px, int py, const btf_gen_stool_part *parts, float *out, double *edge)
{
    double d[3];
    fx_cam_ray(c, px, py, MW, MH, d);
    double best = INFINITY;
    int hit = -1;
    for (int pi = 0; pi < BTF_GEN_STOOL_PARTS; pi++)
        for (int t = 0; t < parts[pi].n_indices; t += 3) {
            const float *v[3];
            for (int k = 0; k < 3; k++)
                v[k] = parts[pi].vertices + (size_t)parts[pi].indices[t + k] * BTF_GEN_STOOL_FLOATS;
            double e1[3], e2[3], s[3], p[3], q[3];
            for (int k = 0; k < 3; k++)
                e1[k] = v[1][k] - v[0][k], e2[k] = v[2][k] - v[0][k], s[k] = c->eye[k] - v[0][k];
            p[0] = d[1] * e2[2] - d[2] * e2[1], p[1] = d[2] * e2[0] - d[0] * e2[2], p[2] = d[0] * e2[1] - d[1] * e2[0];
            double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
            if (fabs(det) < 1e-14)
                continue;
            double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
            q[0] = s[1] * e1[2] - s[2] * e1[1], q[1] = s[2] * e1[0] - s[0] * e1[2], q[2] = s[0] * e1[1] - s[1] * e1[0];
            double w = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
            double dist = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
            if (u < 0 || w < 0 || u + w > 1 || dist <= 0 || dist >= best)
                continue;
            best = dist, hit = pi;
            double b[3] = {1 - u - w, u, w};
            *edge = fmin(b[0], fmin(b[1], b[2]));
            for (int f = 0; f < BTF_GEN_STOOL_FLOATS; f++)
                out[f] = (float)(b[0] * v[0][f] + b[1] * v[1][f] + b[2] * v[2][f]);
            out[9] = v[0][9];
        }
    return hit;
}

static float srgb(float c) { return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1 / 2.4f) - 0.055f; }

/* What the shaders compute at a hit: btf_decode in the hit's frame for a bound part
 * (shaders/btf_render.frag), the flat rule for the others (shaders/btf_flat.frag). */
static void shade(const btf_package *pkg, float repeat, const float *h, const float *base, const fx_cam *c,
                  const float light[3], float rgb[3])
{
    double n[3], t[3], b[3], nl = 0, td = 0, tl = 0;
    for (int k = 0; k < 3; k++)
        nl += (double)h[3 + k] * h[3 + k];
    for (int k = 0; k < 3; k++)
        n[k] = h[3 + k] / sqrt(nl), td += h[6 + k] * n[k];
    for (int k = 0; k < 3; k++)
        t[k] = h[6 + k] - td * n[k], tl += t[k] * t[k];
    for (int k = 0; k < 3; k++)
        t[k] /= sqrt(tl);
    b[0] = (n[1] * t[2] - n[2] * t[1]) * h[9], b[1] = (n[2] * t[0] - n[0] * t[2]) * h[9],
    b[2] = (n[0] * t[1] - n[1] * t[0]) * h[9];
    if (!pkg) {
        double ndl = fmax(0.0, n[0] * light[0] + n[1] * light[1] + n[2] * light[2]);
        for (int k = 0; k < 3; k++)
            rgb[k] = srgb(fminf(1.0f, (float)(base[k] * (BTF_SCENE_FLAT_AMBIENT + (1 - BTF_SCENE_FLAT_AMBIENT) * ndl))));
        return;
    }
    float l[3], v[3];
    double V[3];
    for (int k = 0; k < 3; k++)
        V[k] = c->eye[k] - h[k];
    for (int k = 0; k < 3; k++) {
        const double *axis = k == 0 ? t : k == 1 ? b : n;
        l[k] = (float)(light[0] * axis[0] + light[1] * axis[1] + light[2] * axis[2]);
        v[k] = (float)(V[0] * axis[0] + V[1] * axis[1] + V[2] * axis[2]);
    }
    btf_decode_options o = {.filter = BTF_FILTER_BILINEAR, .wrap = 1};
    btf_decode(pkg, h[10] * repeat, h[11] * repeat, l, v, &o, rgb);
    for (int k = 0; k < 3; k++)
        rgb[k] = fminf(1.0f, fmaxf(0.0f, rgb[k]));
}

/* Two packages of generated materials in tmp (tiles for the seat, knit for the frame). */
static void make_packages(const char *tmp, char dirs[2][400], btf_package *pkg[2])
{
    static const btf_gen_kind kinds[2] = {BTF_GEN_TILES, BTF_GEN_KNIT};
    btf_dirset d = fx_dirs19();
    for (int i = 0; i < 2; i++) {
        btf *m = fx_gen(kinds[i], 16, &d, BTF_F32);
        btf_pca_options po = {.k = 3, .components = 4};
        snprintf(dirs[i], 400, "%s/pkg%d", tmp, i);
        btf_error err = {{0}};
        cr_assert_eq(btf_package_compress(m, &po, NULL, dirs[i], NULL, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(btf_package_read(dirs[i], 0, &pkg[i], &err), BTF_OK, "%s", err.msg);
        btf_free(m);
    }
}

/* The stool with Seat and Frame bound, Trim in its base colour, on backend be, into
 * a float target; returns the RGBA pixels (malloc'd, GL row order). */
static float *render_stool(btf_gl_backend be, const btf_gltf *m, const btf_scene_binding *b, const btf_render_params *p)
{
    btf_gl *gl = fx_gl_open(be);
    btf_scene *s = NULL;
    btf_gl_target *t = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_scene_create(gl, m, b, 2, &s, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_target_create(gl, MW, MH, BTF_GL_RGBA32F, 1, &t, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_scene_draw(s, p, t, &err), BTF_OK, "%s", err.msg);
    float *px = malloc(MW * MH * 4 * sizeof(float));
    cr_assert_eq(btf_gl_target_read(gl, t, 0, px, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_free(gl, t);
    btf_scene_free(s);
    btf_gl_free(gl);
    return px;
}

/* Coverage and colour of one render against the ray cast: pixels whose ray passes
 * within 2% (barycentric) of a triangle edge are skipped (silhouettes and part
 * borders, where a pixel centre may fall either side); of the others, coverage must
 * agree everywhere and colour within 2/255 on 99% (the quantised package read
 * through two filters and a renormalised frame) and within 0.1 everywhere. */
static void check_render(const float *px, const btf_gen_stool_part *ref, btf_package *pkg[2], const btf_gltf *m,
                         const btf_render_params *p, const char *what)
{
    fx_cam c = fx_cam_make(p);
    double ld[3];
    float light[3];
    fx_dir(p->light_theta, p->light_phi, ld);
    for (int k = 0; k < 3; k++)
        light[k] = (float)ld[k];
    int covered = 0, checked = 0, close = 0, per_part[3] = {0, 0, 0};
    double worst = 0;
    for (int py = 0; py < MH; py++)
        for (int qx = 0; qx < MW; qx++) {
            float h[BTF_GEN_STOOL_FLOATS];
            double edge = 1;
            int part = ray_cast(&c, qx, py, ref, h, &edge);
            const float *o = px + (size_t)(py * MW + qx) * 4;
            int bg = o[0] == p->background[0] && o[1] == p->background[1] && o[2] == p->background[2];
            if (edge < 0.02)
                continue;
            cr_assert_eq(part < 0, bg, "%s pixel (%d,%d): ray cast %s, render %s", what, qx, py,
                         part < 0 ? "misses" : "hits", bg ? "background" : "drawn");
            if (part < 0)
                continue;
            covered++;
            int bind = !strcmp(ref[part].material, "Seat") ? 0 : !strcmp(ref[part].material, "Frame") ? 1 : -1;
            float e[3];
            shade(bind >= 0 ? pkg[bind] : NULL, bind == 1 ? 3.0f : 1.0f, h, m->parts[part].base_color, &c, light, e);
            double d = 0;
            for (int k = 0; k < 3; k++)
                d = fmax(d, fabs(o[k] - e[k]));
            worst = fmax(worst, d);
            close += d <= 2.0 / 255;
            checked++;
            per_part[bind + 1]++;
            cr_assert_leq(d, 0.1, "%s pixel (%d,%d) part %d: render (%.3f %.3f %.3f), expected (%.3f %.3f %.3f)", what,
                          qx, py, part, o[0], o[1], o[2], e[0], e[1], e[2]);
        }
    cr_log_info("%s: %d pixels checked, %.2f%% within 2/255, worst %.4f", what, checked, 100.0 * close / checked, worst);
    cr_assert_gt(per_part[0], 20, "%s: too few pixels of the unbound part", what);
    cr_assert_gt(per_part[1], 100, "%s: too few pixels of the seat", what);
    cr_assert_gt(per_part[2], 20, "%s: too few pixels of the legs", what);
    cr_assert_geq(close, 0.99 * checked, "%s: %d of %d pixels within 2/255", what, close, checked);
    (void)covered;
}

Test(model, render_matches_ray_cast_both_backends, .timeout = 120)
{
    char tmp[256], path[300], dirs[2][400];
    btf_gltf *m = NULL;
    btf_gen_stool_part ref[BTF_GEN_STOOL_PARTS];
    stool(tmp, path, &m, ref);
    btf_package *pkg[2];
    make_packages(tmp, dirs, pkg);
    btf_scene_binding b[2] = {{"Seat", dirs[0], 1.0f}, {"Frame", dirs[1], 3.0f}};
    btf_render_params p = btf_render_defaults(BTF_RENDER_SPHERE);
    p.width = MW, p.height = MH, p.horizon_fade = 0, p.light_theta = 40, p.light_phi = -60;
    btf_scene_frame(m, &p);
    float *px[2];
    static const btf_gl_backend be[2] = {BTF_GL_EGL, BTF_GL_OSMESA};
    for (int i = 0; i < 2; i++) {
        px[i] = render_stool(be[i], m, b, &p);
        check_render(px[i], ref, pkg, m, &p, btf_gl_backend_name(be[i]));
    }
    /* the two backends: the same pixels within one 8-bit step nearly everywhere */
    int same = 0;
    for (int i = 0; i < MW * MH; i++) {
        double d = 0;
        for (int k = 0; k < 3; k++)
            d = fmax(d, fabs(px[0][4 * i + k] - px[1][4 * i + k]));
        same += d <= 1.0 / 255;
    }
    cr_assert_geq(same, 0.995 * MW * MH, "EGL and OSMesa differ by more than 1/255 on %d pixels", MW * MH - same);
    free(px[0]), free(px[1]);
    btf_package_free(pkg[0]), btf_package_free(pkg[1]);
    btf_gen_stool_free(ref);
    btf_gltf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* The hit's frame (shaders/btf_render.frag's: normal, tangent made orthogonal to it,
 * b = n x t w) and uv times repeat, as an fx_surface seen from eye. */
static fx_surface surface_of(const float *h, float repeat, const double eye[3])
{
    fx_surface s;
    double nl = 0, td = 0, tl = 0, vl = 0;
    for (int k = 0; k < 3; k++)
        nl += (double)h[3 + k] * h[3 + k];
    for (int k = 0; k < 3; k++)
        s.n[k] = h[3 + k] / sqrt(nl), td += h[6 + k] * s.n[k];
    for (int k = 0; k < 3; k++)
        s.t[k] = h[6 + k] - td * s.n[k], tl += s.t[k] * s.t[k];
    for (int k = 0; k < 3; k++)
        s.t[k] /= sqrt(tl), s.v[k] = eye[k] - h[k], vl += s.v[k] * s.v[k];
    s.b[0] = (s.n[1] * s.t[2] - s.n[2] * s.t[1]) * h[9], s.b[1] = (s.n[2] * s.t[0] - s.n[0] * s.t[2]) * h[9];
    s.b[2] = (s.n[0] * s.t[1] - s.n[1] * s.t[0]) * h[9];
    for (int k = 0; k < 3; k++)
        s.v[k] /= sqrt(vl);
    s.uv[0] = h[10] * repeat, s.uv[1] = h[11] * repeat;
    return s;
}

/* (1/pi) * integral of the quadratic's channel c times max(0, n.d) over the sphere
 * (20000 Fibonacci points): the irradiance of a Lambertian surface over pi. */
static double lambert(const btf_env_quad *q, int c, const double n[3])
{
    const int N = 20000;
    double sum = 0;
    for (int i = 0; i < N; i++) {
        double z = 1.0 - (2.0 * i + 1.0) / N, r = sqrt(1.0 - z * z), ph = i * M_PI * (3.0 - sqrt(5.0));
        double d[3] = {r * cos(ph), r * sin(ph), z}, nd = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
        if (nd > 0)
            sum += fx_quad_eval(q, c, d) * nd;
    }
    return sum * 4.0 * M_PI / N / M_PI;
}

/* The stool under the built-in studio turned 30 degrees, no point light, exposure 0.5,
 * no tone curve, both backends: every bound pixel (clear of triangle edges) against
 * the light sum of the environment's quadratic over the measured light cells in the
 * ray cast's frame (doc/lighting.md; the shader sums sRGB-encoded values of these
 * packages, then decodes), and every unbound pixel against Lambert under that
 * quadratic integrated numerically here: within 2/255 on 99% and 0.05 everywhere,
 * as the point light's check above (a renormalised, interpolated frame on a
 * 24-segment mesh). */
Test(model, environment_light_matches_the_light_sum, .timeout = 180)
{
    char tmp[256], path[300], dirs[2][400];
    btf_gltf *m = NULL;
    btf_gen_stool_part ref[BTF_GEN_STOOL_PARTS];
    stool(tmp, path, &m, ref);
    btf_package *pkg[2];
    make_packages(tmp, dirs, pkg);
    btf_scene_binding b[2] = {{"Seat", dirs[0], 1.0f}, {"Frame", dirs[1], 3.0f}};
    btf_env *envs[2] = {NULL, NULL};
    btf_error err = {{0}};
    char sky[300];
    snprintf(sky, sizeof sky, "%s/sky.hdr", tmp);
    fx_write_sky(sky, 64, 32);
    cr_assert_eq(btf_env_load("studio", &envs[0], &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_env_load(sky, &envs[1], &err), BTF_OK, "%s", err.msg);
    fx_env_sum es[2] = {fx_env_sum_make(pkg[0]), fx_env_sum_make(pkg[1])};
    static const btf_gl_backend be[2] = {BTF_GL_EGL, BTF_GL_OSMESA};
    for (int run = 0; run < 4; run++) { /* studio, sky; turned 30 and 200 degrees; backends alternate */
    const btf_env *env = envs[run / 2];
    double rot = run % 2 ? 200 : 30;
    btf_render_params p = btf_render_defaults(BTF_RENDER_SPHERE);
    p.width = MW, p.height = MH, p.env = env, p.env_rotation = (float)rot, p.no_point_light = 1;
    p.exposure = 0.5f, p.tone_mapping = BTF_TONE_NONE;
    btf_scene_frame(m, &p);
    btf_env_quad q;
    btf_env_quadratic(env, rot, &q);
    fx_cam c = fx_cam_make(&p);
    {
        int i = run % 2;
        float *px = render_stool(be[i], m, b, &p);
        int checked = 0, close = 0, flat = 0;
        double worst = 0;
        for (int py = 0; py < MH; py++)
            for (int qx = 0; qx < MW; qx++) {
                float h[BTF_GEN_STOOL_FLOATS];
                double edge = 1;
                int part = ray_cast(&c, qx, py, ref, h, &edge);
                if (edge < 0.02 || part < 0)
                    continue;
                int bind = !strcmp(ref[part].material, "Seat") ? 0 : !strcmp(ref[part].material, "Frame") ? 1 : -1;
                fx_surface at = surface_of(h, bind == 1 ? 3.0f : 1.0f, c.eye);
                fx_light_sums ls;
                if (bind >= 0)
                    fx_env_sums(&es[bind], pkg[bind], env, rot, &q, 1, &at, &ls);
                else /* unbound: Lambert under the quadratic, integrated here */
                    for (int k = 0; k < 3; k++)
                        ls.l2[k] = m->parts[part].base_color[k] * lambert(&q, k, at.n);
                const float *o = px + (size_t)(py * MW + qx) * 4;
                double d = 0;
                for (int k = 0; k < 3; k++)
                    d = fmax(d, fabs(o[k] - btf_color_srgb_encode(fmin(fmax(0.5 * ls.l2[k], 0), 1))));
                flat += bind < 0;
                worst = fmax(worst, d);
                close += d <= 2.0 / 255;
                checked++;
                cr_assert_leq(d, 0.05, "%s pixel (%d,%d) part %d: off the light sum by %.4f", btf_gl_backend_name(be[i]),
                              qx, py, part, d);
            }
        cr_log_info("%s %s %g deg: %d pixels (%d unbound), %.2f%% within 2/255, worst %.4f", btf_gl_backend_name(be[i]),
                    run / 2 ? "sky" : "studio", rot, checked, flat, 100.0 * close / checked, worst);
        cr_assert_gt(checked - flat, 300, "too few bound pixels: %d", checked - flat);
        cr_assert_gt(flat, 20, "too few unbound pixels: %d", flat);
        cr_assert_geq(close, 0.99 * checked, "%d of %d pixels within 2/255", close, checked);
        free(px);
    }
    }
    fx_env_sum_free(&es[0]), fx_env_sum_free(&es[1]);
    btf_env_free(envs[0]), btf_env_free(envs[1]);
    btf_package_free(pkg[0]), btf_package_free(pkg[1]);
    btf_gen_stool_free(ref);
    btf_gltf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* A binding's package stays readable while its scene lives: a levelled package
 * (repacked on every bind) drawn through btf_scene_png, both backends. */
Test(model, levelled_packages_draw_in_a_scene)
{
    char tmp[256], path[300], pkg[400], out[400];
    btf_gltf *m = NULL;
    stool(tmp, path, &m, NULL);
    btf_dirset d = fx_dirs19();
    btf *src = fx_gen(BTF_GEN_STONE, 16, &d, BTF_U8);
    btf_pca_options po = {.k = 3, .components = 4};
    btf_lod_options lo = {.levels = 3};
    snprintf(pkg, sizeof pkg, "%s/stone", tmp);
    btf_error err = {{0}};
    cr_assert_eq(btf_lod_compress(src, &po, NULL, &lo, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(src);
    btf_scene_binding b[1] = {{"*", pkg, 2.0f}};
    btf_render_params p = btf_render_defaults(BTF_RENDER_SPHERE);
    p.width = 48, p.height = 40;
    btf_scene_frame(m, &p);
    static const btf_gl_backend be[2] = {BTF_GL_EGL, BTF_GL_OSMESA};
    for (int i = 0; i < 2; i++) {
        snprintf(out, sizeof out, "%s/%d.png", tmp, i);
        cr_assert_eq(btf_scene_png(m, b, 1, &p, be[i], out, &err), BTF_OK, "%s", err.msg);
        size_t n = 0;
        char *png = fx_read(out, &n);
        cr_assert(png && n > 100, "%s: no PNG written", btf_gl_backend_name(be[i]));
        free(png);
    }
    btf_gltf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}
