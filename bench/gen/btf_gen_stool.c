/* btf_gen_stool.c - the stool model as a .glb and as world-space surfaces from the
 * formulas (btf_gen_stool.h). */
#include "btf_gen_stool.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "btf_common.h"
#include "btf_fs.h"

#define PI 3.14159265358979323846
#define F BTF_GEN_STOOL_FLOATS
#define UV_UNIT 0.8        /* surface units per uv unit */
#define SEAT_R 0.4
#define SEAT_TOP 0.55
#define SEAT_LOW 0.43
#define LEG_R 0.035
#define LEG_OFF 0.26
#define ROOT_TURN_DEG 25.0
#define ROOT_SCALE 1.25
#define LEG_TILT_DEG 6.0
#define TOP_RINGS 6

/* One surface in its mesh's own space (glTF axes); arrays malloc'd. */
typedef struct stool_surface {
    float *v;
    int nv;
    unsigned *idx;
    int ni;
} stool_surface;

/* A quaternion (x, y, z, w) of angle deg about the unit axis. */
static void quat(const double axis[3], double deg, double q[4])
{
    double h = deg * PI / 360.0;
    for (int k = 0; k < 3; k++)
        q[k] = axis[k] * sin(h);
    q[3] = cos(h);
}

/* v rotated by unit quaternion q: v + 2w (q x v) + 2 q x (q x v). */
static void rotate(const double q[4], const double v[3], double out[3])
{
    double c[3] = {q[1] * v[2] - q[2] * v[1], q[2] * v[0] - q[0] * v[2], q[0] * v[1] - q[1] * v[0]};
    double cc[3] = {q[1] * c[2] - q[2] * c[1], q[2] * c[0] - q[0] * c[2], q[0] * c[1] - q[1] * c[0]};
    for (int k = 0; k < 3; k++)
        out[k] = v[k] + 2.0 * q[3] * c[k] + 2.0 * cc[k];
}

/* The tilt of leg i (signs of its x and z offsets), outwards at the foot. */
static void leg_pose(int i, double t[3], double q[4])
{
    double sx = (i & 1) ? 1.0 : -1.0, sz = (i & 2) ? 1.0 : -1.0;
    t[0] = sx * LEG_OFF, t[1] = 0.0, t[2] = sz * LEG_OFF;
    double axis[3] = {-sz / sqrt(2.0), 0.0, sx / sqrt(2.0)}; /* turns +y towards the centre: the foot out */
    quat(axis, LEG_TILT_DEG, q);
}

static void root_pose(double q[4])
{
    static const double up[3] = {0, 1, 0};
    quat(up, ROOT_TURN_DEG, q);
}

/* w of a frame: +1 when cross(n, t) points towards decreasing v (down = d(pos)/d(-v)). */
static float handedness(const double n[3], const double t[3], const double down[3])
{
    double c[3] = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]};
    return c[0] * down[0] + c[1] * down[1] + c[2] * down[2] >= 0.0 ? 1.0f : -1.0f;
}

static void put(float *v, const double p[3], const double n[3], const double t[3], float w, double u, double vv)
{
    for (int k = 0; k < 3; k++)
        v[k] = (float)p[k], v[3 + k] = (float)n[k], v[6 + k] = (float)t[k];
    v[9] = w, v[10] = (float)u, v[11] = (float)vv;
}

static int surface_alloc(stool_surface *s, int nv, int ni)
{
    s->v = malloc((size_t)nv * F * sizeof(float));
    s->idx = malloc((size_t)ni * sizeof(unsigned));
    s->nv = nv, s->ni = ni;
    return s->v && s->idx;
}

/* Two triangles per cell of a (cols+1) x (rows+1) vertex grid, row-major, facing
 * the side that cross(d/d col, d/d row) points to when flip = 0. */
static void grid_indices(unsigned *idx, int cols, int rows, int flip)
{
    int n = 0;
    for (int r = 0; r < rows; r++)
        for (int c = 0; c < cols; c++) {
            unsigned a = (unsigned)(r * (cols + 1) + c), b = a + 1, d = a + (unsigned)(cols + 1), e = d + 1;
            unsigned t[6] = {a, b, e, a, e, d};
            for (int k = 0; k < 6; k++)
                idx[n++] = t[flip && k % 3 ? (k % 3 == 1 ? k + 1 : k - 1) : k];
        }
}

/* The seat's top disc: rings around the centre, facing +y. */
static int top_surface(int S, stool_surface *s)
{
    if (!surface_alloc(s, (TOP_RINGS + 1) * (S + 1), TOP_RINGS * S * 6))
        return 0;
    static const double n[3] = {0, 1, 0}, t[3] = {1, 0, 0}, down[3] = {0, 0, -1};
    float w = handedness(n, t, down);
    for (int k = 0; k <= TOP_RINGS; k++)
        for (int j = 0; j <= S; j++) {
            double a = 2 * PI * j / S, r = SEAT_R * k / TOP_RINGS;
            double p[3] = {r * cos(a), SEAT_TOP, r * sin(a)};
            put(s->v + (size_t)(k * (S + 1) + j) * F, p, n, t, w, p[0] / UV_UNIT + 0.5, p[2] / UV_UNIT + 0.5);
        }
    grid_indices(s->idx, S, TOP_RINGS, 1); /* d/da x d/dr = -y: flipped to face +y */
    return 1;
}

/* An open tube of radius r around y from y0 to y1 (outwards), u along the angle. */
static int tube_surface(int S, double r, double y0, double y1, stool_surface *s)
{
    if (!surface_alloc(s, 2 * (S + 1), S * 6))
        return 0;
    static const double down[3] = {0, 1, 0}; /* v grows as y falls */
    for (int k = 0; k < 2; k++)
        for (int j = 0; j <= S; j++) {
            double a = 2 * PI * j / S, y = k ? y0 : y1;
            double p[3] = {r * cos(a), y, r * sin(a)}, n[3] = {cos(a), 0, sin(a)}, t[3] = {-sin(a), 0, cos(a)};
            put(s->v + (size_t)(k * (S + 1) + j) * F, p, n, t, handedness(n, t, down), a * r / UV_UNIT,
                (y1 - y) / UV_UNIT);
        }
    grid_indices(s->idx, S, 1, 0); /* d/da x d/dk: (-sin, 0, cos) x (0, -1, 0) = outwards */
    return 1;
}

static void surface_free(stool_surface *s)
{
    free(s->v), free(s->idx);
    s->v = NULL, s->idx = NULL;
}

/* The three surfaces (top, band, leg) for S segments. */
static btf_result surfaces(int S, stool_surface s[3], btf_error *err)
{
    memset(s, 0, 3 * sizeof *s);
    if (S < 3 || S > 120)
        return btf_fail(err, BTF_ERR_RANGE, "stool: %d segments (3..120)", S);
    if (top_surface(S, &s[0]) && tube_surface(S, SEAT_R, SEAT_LOW, SEAT_TOP, &s[1]) &&
        tube_surface(S, LEG_R, 0.0, SEAT_LOW, &s[2]))
        return BTF_OK;
    for (int i = 0; i < 3; i++)
        surface_free(&s[i]);
    return btf_fail(err, BTF_ERR_NOMEM, "stool: out of memory");
}

/* ---------------------------------------------------------------- world space */

/* s under the leg pose (leg >= 0) and the root, in world axes (x, -z, y). */
static btf_result world_part(const stool_surface *s, int leg, const char *material, btf_gen_stool_part *out,
                             btf_error *err)
{
    out->material = material;
    out->vertices = malloc((size_t)s->nv * F * sizeof(float));
    out->indices = malloc((size_t)s->ni * sizeof(unsigned));
    if (!out->vertices || !out->indices)
        return btf_fail(err, BTF_ERR_NOMEM, "stool: out of memory");
    out->n_vertices = s->nv, out->n_indices = s->ni;
    memcpy(out->indices, s->idx, (size_t)s->ni * sizeof(unsigned));
    double qr[4], ql[4] = {0, 0, 0, 1}, tl[3] = {0, 0, 0};
    root_pose(qr);
    if (leg >= 0)
        leg_pose(leg, tl, ql);
    for (int i = 0; i < s->nv; i++) {
        const float *a = s->v + (size_t)i * F;
        float *b = out->vertices + (size_t)i * F;
        double vec[3][3], w[3][3];
        for (int k = 0; k < 3; k++)
            vec[0][k] = a[k], vec[1][k] = a[3 + k], vec[2][k] = a[6 + k];
        for (int m = 0; m < 3; m++) {
            double x[3], y[3];
            rotate(ql, vec[m], x);
            if (m == 0)
                for (int k = 0; k < 3; k++)
                    x[k] += tl[k];
            rotate(qr, x, y);
            double sc = m == 0 ? ROOT_SCALE : 1.0;
            w[m][0] = sc * y[0], w[m][1] = -sc * y[2], w[m][2] = sc * y[1];
        }
        for (int k = 0; k < 3; k++)
            b[k] = (float)w[0][k], b[3 + k] = (float)w[1][k], b[6 + k] = (float)w[2][k];
        b[9] = a[9], b[10] = a[10], b[11] = a[11];
    }
    return BTF_OK;
}

btf_result btf_gen_stool_parts(int segments, btf_gen_stool_part parts[BTF_GEN_STOOL_PARTS], btf_error *err)
{
    memset(parts, 0, BTF_GEN_STOOL_PARTS * sizeof *parts);
    stool_surface s[3];
    btf_result r = surfaces(segments ? segments : 48, s, err);
    if (r == BTF_OK)
        r = world_part(&s[0], -1, "Seat", &parts[0], err);
    if (r == BTF_OK)
        r = world_part(&s[1], -1, "Trim", &parts[1], err);
    for (int i = 0; r == BTF_OK && i < 4; i++)
        r = world_part(&s[2], i, "Frame", &parts[2 + i], err);
    for (int i = 0; i < 3; i++)
        surface_free(&s[i]);
    if (r != BTF_OK)
        btf_gen_stool_free(parts);
    return r;
}

void btf_gen_stool_free(btf_gen_stool_part parts[BTF_GEN_STOOL_PARTS])
{
    for (int i = 0; i < BTF_GEN_STOOL_PARTS; i++) {
        free(parts[i].vertices), free(parts[i].indices);
        parts[i].vertices = NULL, parts[i].indices = NULL;
    }
}

/* ---------------------------------------------------------------- the .glb */

/* The binary chunk as it grows, and the JSON arrays that describe it. */
typedef struct glb_writer {
    uint8_t *bin;
    size_t n, cap;
    cJSON *views, *accessors;
} glb_writer;

/* Appends bytes (4-aligned) as one buffer view and one accessor; its index, -1 on OOM. */
static int glb_accessor(glb_writer *g, const void *data, size_t bytes, int count, int ctype, const char *type)
{
    size_t need = g->n + bytes + 4;
    if (need > g->cap) {
        size_t cap = need * 2;
        uint8_t *b = realloc(g->bin, cap);
        if (!b)
            return -1;
        g->bin = b, g->cap = cap;
    }
    memcpy(g->bin + g->n, data, bytes);
    cJSON *v = cJSON_CreateObject(), *a = cJSON_CreateObject();
    cJSON_AddNumberToObject(v, "buffer", 0);
    cJSON_AddNumberToObject(v, "byteOffset", (double)g->n);
    cJSON_AddNumberToObject(v, "byteLength", (double)bytes);
    cJSON_AddNumberToObject(a, "bufferView", cJSON_GetArraySize(g->views));
    cJSON_AddNumberToObject(a, "componentType", ctype);
    cJSON_AddNumberToObject(a, "count", count);
    cJSON_AddStringToObject(a, "type", type);
    cJSON_AddItemToArray(g->views, v);
    cJSON_AddItemToArray(g->accessors, a);
    g->n += bytes;
    while (g->n % 4)
        g->bin[g->n++] = 0;
    return cJSON_GetArraySize(g->accessors) - 1;
}

/* One attribute (components c at offset off of each vertex) as a float accessor. */
static int glb_attribute(glb_writer *g, const stool_surface *s, int off, int c, const char *type)
{
    float *a = malloc((size_t)s->nv * (size_t)c * sizeof(float));
    if (!a)
        return -1;
    for (int i = 0; i < s->nv; i++)
        memcpy(a + (size_t)i * c, s->v + (size_t)i * F + off, (size_t)c * sizeof(float));
    int k = glb_accessor(g, a, (size_t)s->nv * c * sizeof(float), s->nv, 5126, type);
    free(a);
    if (k >= 0 && off == 0) { /* POSITION's bounds, as glTF requires */
        cJSON *mn = cJSON_CreateArray(), *mx = cJSON_CreateArray();
        for (int d = 0; d < 3; d++) {
            float lo = INFINITY, hi = -INFINITY;
            for (int i = 0; i < s->nv; i++)
                lo = fminf(lo, s->v[(size_t)i * F + d]), hi = fmaxf(hi, s->v[(size_t)i * F + d]);
            cJSON_AddItemToArray(mn, cJSON_CreateNumber(lo));
            cJSON_AddItemToArray(mx, cJSON_CreateNumber(hi));
        }
        cJSON *acc = cJSON_GetArrayItem(g->accessors, k);
        cJSON_AddItemToObject(acc, "min", mn);
        cJSON_AddItemToObject(acc, "max", mx);
    }
    return k;
}

/* The indices of s as unsigned bytes (1), shorts (2) or ints (4). */
static int glb_indices(glb_writer *g, const stool_surface *s, int size)
{
    uint8_t *b = malloc((size_t)s->ni * (size_t)size);
    if (!b)
        return -1;
    for (int i = 0; i < s->ni; i++) {
        uint32_t x = s->idx[i];
        uint16_t h = (uint16_t)x;
        if (size == 1)
            b[i] = (uint8_t)x;
        else if (size == 2)
            memcpy(b + 2 * (size_t)i, &h, 2);
        else
            memcpy(b + 4 * (size_t)i, &x, 4);
    }
    int ctype = size == 1 ? 5121 : size == 2 ? 5123 : 5125;
    int k = glb_accessor(g, b, (size_t)s->ni * size, s->ni, ctype, "SCALAR");
    free(b);
    return k;
}

/* A primitive of s: its attributes (TANGENT when tangents), indices, material. */
static cJSON *glb_primitive(glb_writer *g, const stool_surface *s, int tangents, int index_size, int material)
{
    int pos = glb_attribute(g, s, 0, 3, "VEC3"), nrm = glb_attribute(g, s, 3, 3, "VEC3");
    int tan = tangents ? glb_attribute(g, s, 6, 4, "VEC4") : 0, uv = glb_attribute(g, s, 10, 2, "VEC2");
    int idx = glb_indices(g, s, index_size);
    if (pos < 0 || nrm < 0 || tan < 0 || uv < 0 || idx < 0)
        return NULL;
    cJSON *p = cJSON_CreateObject(), *at = cJSON_CreateObject();
    cJSON_AddNumberToObject(at, "POSITION", pos);
    cJSON_AddNumberToObject(at, "NORMAL", nrm);
    if (tangents)
        cJSON_AddNumberToObject(at, "TANGENT", tan);
    cJSON_AddNumberToObject(at, "TEXCOORD_0", uv);
    cJSON_AddItemToObject(p, "attributes", at);
    cJSON_AddNumberToObject(p, "indices", idx);
    cJSON_AddNumberToObject(p, "material", material);
    return p;
}

static cJSON *glb_numbers(const double *x, int n)
{
    cJSON *a = cJSON_CreateArray();
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(a, cJSON_CreateNumber(x[i]));
    return a;
}

static void glb_material(cJSON *mats, const char *name, double r, double g, double b)
{
    cJSON *m = cJSON_CreateObject(), *pbr = cJSON_CreateObject();
    double c[4] = {r, g, b, 1.0};
    cJSON_AddStringToObject(m, "name", name);
    cJSON_AddItemToObject(pbr, "baseColorFactor", glb_numbers(c, 4));
    cJSON_AddItemToObject(m, "pbrMetallicRoughness", pbr);
    cJSON_AddItemToArray(mats, m);
}

/* Nodes 0 "stool" (root), 1 "seat" (mesh 0), 2..5 "leg" (mesh 1). */
static cJSON *glb_nodes(void)
{
    cJSON *nodes = cJSON_CreateArray(), *root = cJSON_CreateObject(), *kids = cJSON_CreateArray();
    double q[4], t[3], s[3] = {ROOT_SCALE, ROOT_SCALE, ROOT_SCALE};
    root_pose(q);
    cJSON_AddStringToObject(root, "name", "stool");
    cJSON_AddItemToObject(root, "rotation", glb_numbers(q, 4));
    cJSON_AddItemToObject(root, "scale", glb_numbers(s, 3));
    for (int i = 1; i <= 5; i++)
        cJSON_AddItemToArray(kids, cJSON_CreateNumber(i));
    cJSON_AddItemToObject(root, "children", kids);
    cJSON_AddItemToArray(nodes, root);
    cJSON *seat = cJSON_CreateObject();
    cJSON_AddStringToObject(seat, "name", "seat");
    cJSON_AddNumberToObject(seat, "mesh", 0);
    cJSON_AddItemToArray(nodes, seat);
    for (int i = 0; i < 4; i++) {
        cJSON *leg = cJSON_CreateObject();
        leg_pose(i, t, q);
        cJSON_AddStringToObject(leg, "name", "leg");
        cJSON_AddNumberToObject(leg, "mesh", 1);
        cJSON_AddItemToObject(leg, "translation", glb_numbers(t, 3));
        cJSON_AddItemToObject(leg, "rotation", glb_numbers(q, 4));
        cJSON_AddItemToArray(nodes, leg);
    }
    return nodes;
}

/* The glTF JSON of the three surfaces, their bytes into g. */
static cJSON *glb_json(glb_writer *g, const stool_surface s[3])
{
    cJSON *doc = cJSON_CreateObject(), *asset = cJSON_CreateObject(), *meshes = cJSON_CreateArray();
    cJSON_AddStringToObject(asset, "version", "2.0");
    cJSON_AddStringToObject(asset, "generator", "btf gen-model (bench/gen/btf_gen_stool.c)");
    cJSON_AddItemToObject(doc, "asset", asset);
    cJSON *seat = cJSON_CreateObject(), *sp = cJSON_CreateArray(), *leg = cJSON_CreateObject(),
          *lp = cJSON_CreateArray();
    cJSON *p0 = glb_primitive(g, &s[0], 1, 2, 0), *p1 = glb_primitive(g, &s[1], 0, 4, 1),
          *p2 = glb_primitive(g, &s[2], 0, 1, 2);
    if (!p0 || !p1 || !p2) {
        cJSON_Delete(p0), cJSON_Delete(p1), cJSON_Delete(p2), cJSON_Delete(doc);
        cJSON_Delete(seat), cJSON_Delete(sp), cJSON_Delete(leg), cJSON_Delete(lp), cJSON_Delete(meshes);
        return NULL;
    }
    cJSON_AddItemToArray(sp, p0), cJSON_AddItemToArray(sp, p1), cJSON_AddItemToArray(lp, p2);
    cJSON_AddStringToObject(seat, "name", "seat"), cJSON_AddItemToObject(seat, "primitives", sp);
    cJSON_AddStringToObject(leg, "name", "leg"), cJSON_AddItemToObject(leg, "primitives", lp);
    cJSON_AddItemToArray(meshes, seat), cJSON_AddItemToArray(meshes, leg);
    cJSON_AddItemToObject(doc, "meshes", meshes);
    cJSON *mats = cJSON_CreateArray();
    glb_material(mats, "Seat", 0.8, 0.25, 0.2);
    glb_material(mats, "Trim", 0.2, 0.2, 0.25);
    glb_material(mats, "Frame", 0.6, 0.6, 0.62);
    cJSON_AddItemToObject(doc, "materials", mats);
    cJSON_AddItemToObject(doc, "nodes", glb_nodes());
    cJSON *scene = cJSON_CreateObject(), *scenes = cJSON_CreateArray(), *roots = cJSON_CreateArray();
    cJSON_AddItemToArray(roots, cJSON_CreateNumber(0));
    cJSON_AddItemToObject(scene, "nodes", roots);
    cJSON_AddItemToArray(scenes, scene);
    cJSON_AddItemToObject(doc, "scenes", scenes);
    cJSON_AddNumberToObject(doc, "scene", 0);
    cJSON *bufs = cJSON_CreateArray(), *buf = cJSON_CreateObject();
    cJSON_AddNumberToObject(buf, "byteLength", (double)g->n);
    cJSON_AddItemToArray(bufs, buf);
    cJSON_AddItemToObject(doc, "buffers", bufs);
    cJSON_AddItemToObject(doc, "bufferViews", g->views);
    cJSON_AddItemToObject(doc, "accessors", g->accessors);
    g->views = g->accessors = NULL; /* the document's now */
    return doc;
}

static void le32(uint8_t *p, uint32_t x)
{
    p[0] = (uint8_t)x, p[1] = (uint8_t)(x >> 8), p[2] = (uint8_t)(x >> 16), p[3] = (uint8_t)(x >> 24);
}

/* Header, JSON chunk (space-padded) and BIN chunk, into one malloc'd block. */
static uint8_t *glb_bytes(const char *json, const glb_writer *g, size_t *size)
{
    size_t jn = strlen(json), jp = (jn + 3) & ~(size_t)3, total = 12 + 8 + jp + 8 + g->n;
    uint8_t *b = malloc(total);
    if (!b)
        return NULL;
    memcpy(b, "glTF", 4), le32(b + 4, 2), le32(b + 8, (uint32_t)total);
    le32(b + 12, (uint32_t)jp), memcpy(b + 16, "JSON", 4);
    memcpy(b + 20, json, jn), memset(b + 20 + jn, ' ', jp - jn);
    le32(b + 20 + jp, (uint32_t)g->n), memcpy(b + 24 + jp, "BIN", 4), b[27 + jp] = 0;
    memcpy(b + 28 + jp, g->bin, g->n);
    *size = total;
    return b;
}

btf_result btf_gen_stool_write(const char *path, int segments, btf_error *err)
{
    stool_surface s[3];
    btf_result r = surfaces(segments ? segments : 48, s, err);
    if (r != BTF_OK)
        return r;
    glb_writer g = {NULL, 0, 0, cJSON_CreateArray(), cJSON_CreateArray()};
    cJSON *doc = g.views && g.accessors ? glb_json(&g, s) : NULL;
    char *json = doc ? cJSON_PrintUnformatted(doc) : NULL;
    size_t size = 0;
    uint8_t *bytes = json ? glb_bytes(json, &g, &size) : NULL;
    r = bytes ? btf_fs_write_atomic(path, bytes, size, err) : btf_fail(err, BTF_ERR_NOMEM, "stool: out of memory");
    free(bytes), free(json), free(g.bin);
    cJSON_Delete(doc), cJSON_Delete(g.views), cJSON_Delete(g.accessors);
    for (int i = 0; i < 3; i++)
        surface_free(&s[i]);
    return r;
}
