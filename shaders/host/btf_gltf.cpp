// btf_gltf.cpp - glTF 2.0 models through tinygltf (btf_gltf.h): parse, check every
// count, offset and index before it is trusted, then bake each primitive under each
// node of the scene into a world-space render mesh.
#include "btf_gltf.h"

#include <tiny_gltf.h>

#include <cjson/cJSON.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <string>
#include <sys/stat.h>
#include <vector>

#include "btf_common.h"
#include "btf_fs.h"

namespace {

// The loading of one model: the parsed glTF, what has been made of it so far, and
// the error; lives for one btf_gltf_load call.
struct Loader {
    const tinygltf::Model &g;
    const char *name;
    btf_error *err;
    std::vector<btf_gltf_part> parts;
    long long vertices = 0, triangles = 0, visits = 0;
    btf_result r = BTF_OK;

    Loader(const tinygltf::Model &model, const char *n, btf_error *e) : g(model), name(n), err(e) {}
    ~Loader()
    {
        for (btf_gltf_part &p : parts)
            free(p.mesh.vertices), free(p.mesh.indices);
    }
    // Records the first failure (a btf_fail message naming the model) and returns false.
    bool fail(btf_result code, const char *fmt, ...) __attribute__((format(printf, 3, 4)))
    {
        if (r == BTF_OK) {
            char msg[400];
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(msg, sizeof msg, fmt, ap);
            va_end(ap);
            r = btf_fail(err, code, "%s: %s", name, msg);
        }
        return false;
    }
};

// A primitive's vertex data in its own (object) space, before any node transform:
// interleaved BTF_RENDER_VERTEX_FLOATS per vertex, triangles as indices.
struct Geometry {
    std::vector<float> v;
    std::vector<unsigned> idx;
    int has_uv = 0, has_tangent = 0;
};

// Image payloads are never decoded: a BTF model needs none of them.
bool skip_image(tinygltf::Image *, const int, std::string *, std::string *, int, int, const unsigned char *, int,
                void *)
{
    return true;
}

// The folder external buffers must lie in (the .gltf's own), for the file callbacks.
struct Folder {
    std::string dir;
};

std::string keep_path(const std::string &path, void *) { return path; }

bool file_exists(const std::string &path, void *)
{
    struct stat st;
    return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

// Reads an external buffer: only a regular file beside the .gltf (no "..", no other
// folder), of at most BTF_GLTF_MAX_FILE_BYTES, its size checked before reading.
bool read_file(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *user)
{
    const Folder *f = static_cast<const Folder *>(user);
    const std::string d = f->dir + "/";
    if (path.compare(0, d.size(), d) != 0 || path.find("..") != std::string::npos ||
        path.find('/', d.size()) != std::string::npos) {
        *err = "buffer " + path + " does not lie beside the .gltf";
        return false;
    }
    struct stat st;
    if (stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) {
        *err = "buffer " + path + " is missing";
        return false;
    }
    if (st.st_size > BTF_GLTF_MAX_FILE_BYTES) {
        *err = "buffer " + path + " is larger than the model limit";
        return false;
    }
    FILE *fp = fopen(path.c_str(), "rb");
    if (!fp) {
        *err = "cannot open buffer " + path;
        return false;
    }
    out->resize((size_t)st.st_size);
    size_t got = st.st_size ? fread(out->data(), 1, out->size(), fp) : 0;
    fclose(fp);
    if (got != out->size()) {
        *err = "cannot read buffer " + path;
        return false;
    }
    return true;
}

int components_of(int type)
{
    switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    default: return 0;
    }
}

int component_bytes(int ct)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

// The bytes of accessor a, checked: its view and buffer exist, every element lies
// inside both, no sparse storage, count <= max_count. *base the first element,
// *stride the distance between elements, *esize one element's bytes.
bool accessor_bytes(Loader &L, int a, const char *what, size_t max_count, const unsigned char **base,
                    size_t *stride, size_t *esize)
{
    const tinygltf::Model &g = L.g;
    if (a < 0 || (size_t)a >= g.accessors.size())
        return L.fail(BTF_ERR_FORMAT, "%s: accessor %d does not exist", what, a);
    const tinygltf::Accessor &acc = g.accessors[a];
    if (acc.sparse.isSparse)
        return L.fail(BTF_ERR_UNSUPPORTED, "%s: accessor %d is sparse (not supported)", what, a);
    int nc = components_of(acc.type), cb = component_bytes(acc.componentType);
    if (nc == 0 || cb == 0)
        return L.fail(BTF_ERR_FORMAT, "%s: accessor %d has an unknown type", what, a);
    if (acc.count == 0 || acc.count > max_count)
        return L.fail(BTF_ERR_RANGE, "%s: accessor %d has %zu elements (1..%zu)", what, a, acc.count, max_count);
    if (acc.bufferView < 0 || (size_t)acc.bufferView >= g.bufferViews.size())
        return L.fail(BTF_ERR_FORMAT, "%s: accessor %d has no buffer view", what, a);
    const tinygltf::BufferView &bv = g.bufferViews[acc.bufferView];
    if (bv.buffer < 0 || (size_t)bv.buffer >= g.buffers.size())
        return L.fail(BTF_ERR_FORMAT, "%s: buffer view %d has no buffer", what, acc.bufferView);
    const std::vector<unsigned char> &buf = g.buffers[bv.buffer].data;
    if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset)
        return L.fail(BTF_ERR_RANGE, "%s: buffer view %d lies outside its buffer", what, acc.bufferView);
    size_t es = (size_t)nc * (size_t)cb, st = bv.byteStride ? bv.byteStride : es;
    if (st < es || st > 252)
        return L.fail(BTF_ERR_FORMAT, "%s: buffer view %d has stride %zu for %zu-byte elements", what,
                      acc.bufferView, st, es);
    // last byte needed: byteOffset + stride * (count - 1) + es, count <= max_count keeps it in size_t
    if (acc.byteOffset > bv.byteLength || (acc.count - 1) * st + es > bv.byteLength - acc.byteOffset)
        return L.fail(BTF_ERR_RANGE, "%s: accessor %d reads past its buffer view", what, a);
    *base = buf.data() + bv.byteOffset + acc.byteOffset;
    *stride = st, *esize = es;
    return true;
}

// One component of an element as a float: floats as they are, normalized integers
// mapped to 0..1 (unsigned) or -1..1 (signed), as glTF specifies.
float component(const unsigned char *p, int ct, bool normalized)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float f;
        memcpy(&f, p, 4);
        return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0f : p[0];
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
        float f = (float)(signed char)p[0];
        return normalized ? fmaxf(f / 127.0f, -1.0f) : f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t s;
        memcpy(&s, p, 2);
        return normalized ? s / 65535.0f : s;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t s;
        memcpy(&s, p, 2);
        return normalized ? fmaxf(s / 32767.0f, -1.0f) : s;
    }
    default: return 0.0f;
    }
}

// Attribute accessor a into v (n vertices of BTF_RENDER_VERTEX_FLOATS) at float
// offset off: type must be `type`; float components, or (normalized_ok) normalized
// unsigned bytes and shorts. Every value finite.
bool read_attribute(Loader &L, int a, const char *what, int type, bool normalized_ok, size_t n, float *v, int off)
{
    if (a < 0 || (size_t)a >= L.g.accessors.size())
        return L.fail(BTF_ERR_FORMAT, "%s: accessor %d does not exist", what, a);
    const tinygltf::Accessor &acc = L.g.accessors[a];
    bool norm_int = normalized_ok && acc.normalized &&
                    (acc.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                     acc.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    if (acc.type != type || (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !norm_int))
        return L.fail(BTF_ERR_FORMAT, "%s: accessor %d has the wrong type or component type", what, a);
    if (acc.count != n)
        return L.fail(BTF_ERR_FORMAT, "%s: accessor %d has %zu elements, POSITION %zu", what, a, acc.count, n);
    const unsigned char *base;
    size_t stride, es;
    if (!accessor_bytes(L, a, what, n, &base, &stride, &es))
        return false;
    int nc = components_of(type), cb = component_bytes(acc.componentType);
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < nc; c++) {
            float x = component(base + i * stride + (size_t)c * cb, acc.componentType, acc.normalized);
            if (!std::isfinite(x))
                return L.fail(BTF_ERR_NUMERIC, "%s: accessor %d element %zu is not finite", what, a, i);
            v[i * BTF_RENDER_VERTEX_FLOATS + off + c] = x;
        }
    return true;
}

// Triangle indices of primitive p (or 0..n-1 without indices), each < n.
bool read_indices(Loader &L, const tinygltf::Primitive &p, size_t n, std::vector<unsigned> &idx)
{
    if (p.indices < 0) {
        if (n % 3)
            return L.fail(BTF_ERR_FORMAT, "a primitive without indices has %zu vertices (not triangles)", n);
        idx.resize(n);
        for (size_t i = 0; i < n; i++)
            idx[i] = (unsigned)i;
        return true;
    }
    if ((size_t)p.indices >= L.g.accessors.size())
        return L.fail(BTF_ERR_FORMAT, "indices: accessor %d does not exist", p.indices);
    const tinygltf::Accessor &acc = L.g.accessors[p.indices];
    int ct = acc.componentType;
    if (acc.type != TINYGLTF_TYPE_SCALAR ||
        (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
        return L.fail(BTF_ERR_FORMAT, "indices: accessor %d is not unsigned integer scalars", p.indices);
    const unsigned char *base;
    size_t stride, es;
    if (!accessor_bytes(L, p.indices, "indices", 3 * (size_t)BTF_GLTF_MAX_TRIANGLES, &base, &stride, &es))
        return false;
    if (acc.count % 3)
        return L.fail(BTF_ERR_FORMAT, "indices: accessor %d has %zu indices (not triangles)", p.indices, acc.count);
    idx.resize(acc.count);
    for (size_t i = 0; i < acc.count; i++) {
        const unsigned char *q = base + i * stride;
        uint32_t k = 0;
        if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE)
            k = q[0];
        else if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
            uint16_t s;
            memcpy(&s, q, 2);
            k = s;
        } else
            memcpy(&k, q, 4);
        if (k >= n)
            return L.fail(BTF_ERR_RANGE, "indices: index %u at %zu is out of bounds (%zu vertices)", k, i, n);
        idx[i] = k;
    }
    return true;
}

// Flat normals: every triangle its own three vertices, each with the face normal.
void flat_normals(Geometry &geo)
{
    const int F = BTF_RENDER_VERTEX_FLOATS;
    std::vector<float> out(geo.idx.size() * F);
    for (size_t t = 0; t + 2 < geo.idx.size(); t += 3) {
        const float *a = &geo.v[geo.idx[t] * F], *b = &geo.v[geo.idx[t + 1] * F], *c = &geo.v[geo.idx[t + 2] * F];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int k = 0; k < 3; k++) {
            float *o = &out[(t + k) * F];
            memcpy(o, &geo.v[geo.idx[t + k] * F], F * sizeof(float));
            for (int c2 = 0; c2 < 3; c2++)
                o[3 + c2] = l > 0 ? (float)(n[c2] / l) : (c2 == 2 ? 1.0f : 0.0f);
        }
    }
    geo.v.swap(out);
    for (size_t i = 0; i < geo.idx.size(); i++)
        geo.idx[i] = (unsigned)i;
}

int attribute(const tinygltf::Primitive &p, const char *key)
{
    auto it = p.attributes.find(key);
    return it == p.attributes.end() ? -1 : it->second;
}

// Tangents of geo by btf_gltf_tangents, which may grow the arrays (a malloc'd
// copy, then taken back).
bool generate_tangents(Loader &L, Geometry &geo)
{
    const int F = BTF_RENDER_VERTEX_FLOATS;
    btf_render_mesh m = {(float *)malloc(geo.v.size() * sizeof(float)), (int)(geo.v.size() / F),
                         (unsigned *)malloc(geo.idx.size() * sizeof(unsigned)), (int)geo.idx.size()};
    btf_result r = BTF_OK;
    if (!m.vertices || !m.indices) {
        r = btf_fail(L.err, BTF_ERR_NOMEM, "%s: out of memory (tangents)", L.name);
    } else {
        memcpy(m.vertices, geo.v.data(), geo.v.size() * sizeof(float));
        memcpy(m.indices, geo.idx.data(), geo.idx.size() * sizeof(unsigned));
        r = btf_gltf_tangents(&m, L.err);
    }
    if (r == BTF_OK) {
        geo.v.assign(m.vertices, m.vertices + (size_t)m.n_vertices * F);
        geo.idx.assign(m.indices, m.indices + m.n_indices);
    }
    free(m.vertices), free(m.indices);
    if (r != BTF_OK)
        L.r = r;
    return r == BTF_OK;
}

// Primitive p of mesh mi in object space, checked; tangents generated when absent.
bool load_geometry(Loader &L, const tinygltf::Primitive &p, int mi, Geometry &geo)
{
    if (p.mode != TINYGLTF_MODE_TRIANGLES && p.mode != -1)
        return L.fail(BTF_ERR_UNSUPPORTED, "mesh %d: primitive mode %d (only triangles, mode 4)", mi, p.mode);
    if (!p.extensions.empty())
        return L.fail(BTF_ERR_UNSUPPORTED, "mesh %d: primitive extension %s (not supported)", mi,
                      p.extensions.begin()->first.c_str());
    int pos = attribute(p, "POSITION");
    if (pos < 0)
        return L.fail(BTF_ERR_FORMAT, "mesh %d: a primitive has no POSITION", mi);
    if ((size_t)pos >= L.g.accessors.size())
        return L.fail(BTF_ERR_FORMAT, "mesh %d: POSITION accessor %d does not exist", mi, pos);
    size_t n = L.g.accessors[pos].count;
    if (n == 0 || n > (size_t)BTF_GLTF_MAX_VERTICES)
        return L.fail(BTF_ERR_RANGE, "mesh %d: %zu vertices (1..%d)", mi, n, BTF_GLTF_MAX_VERTICES);
    const int F = BTF_RENDER_VERTEX_FLOATS;
    geo.v.assign(n * F, 0.0f);
    if (!read_attribute(L, pos, "POSITION", TINYGLTF_TYPE_VEC3, false, n, geo.v.data(), 0))
        return false;
    int nrm = attribute(p, "NORMAL"), tan = attribute(p, "TANGENT"), uv = attribute(p, "TEXCOORD_0");
    if (nrm >= 0 && !read_attribute(L, nrm, "NORMAL", TINYGLTF_TYPE_VEC3, false, n, geo.v.data(), 3))
        return false;
    if (tan >= 0 && nrm >= 0 && !read_attribute(L, tan, "TANGENT", TINYGLTF_TYPE_VEC4, false, n, geo.v.data(), 6))
        return false;
    if (uv >= 0 && !read_attribute(L, uv, "TEXCOORD_0", TINYGLTF_TYPE_VEC2, true, n, geo.v.data(), 10))
        return false;
    if (!read_indices(L, p, n, geo.idx))
        return false;
    geo.has_uv = uv >= 0;
    geo.has_tangent = tan >= 0 && nrm >= 0; // without NORMAL, glTF says TANGENT is ignored
    if (nrm < 0)
        flat_normals(geo);
    for (size_t i = 0; i < geo.v.size() / F; i++) { // unit normals (a file's may not be)
        float *q = &geo.v[i * F + 3];
        double l = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        for (int c = 0; c < 3; c++)
            q[c] = l > 0 ? (float)(q[c] / l) : (c == 2 ? 1.0f : 0.0f);
    }
    return geo.has_tangent || geo.idx.empty() || generate_tangents(L, geo);
}

// ---------------------------------------------------------------- transforms

// The node's local matrix (column-major): its matrix, else T * R * S.
bool local_matrix(Loader &L, const tinygltf::Node &nd, int ni, double m[16])
{
    if (nd.matrix.size() == 16) {
        for (int i = 0; i < 16; i++)
            m[i] = nd.matrix[i];
    } else {
        double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
        if (nd.translation.size() == 3)
            t[0] = nd.translation[0], t[1] = nd.translation[1], t[2] = nd.translation[2];
        if (nd.rotation.size() == 4)
            q[0] = nd.rotation[0], q[1] = nd.rotation[1], q[2] = nd.rotation[2], q[3] = nd.rotation[3];
        if (nd.scale.size() == 3)
            s[0] = nd.scale[0], s[1] = nd.scale[1], s[2] = nd.scale[2];
        double ql = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (!(ql > 0))
            return L.fail(BTF_ERR_FORMAT, "node %d: zero rotation quaternion", ni);
        double x = q[0] / ql, y = q[1] / ql, z = q[2] / ql, w = q[3] / ql;
        double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                       2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                       2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
        for (int col = 0; col < 3; col++)
            for (int row = 0; row < 3; row++)
                m[col * 4 + row] = r[col * 3 + row] * s[col];
        m[3] = m[7] = m[11] = 0, m[12] = t[0], m[13] = t[1], m[14] = t[2], m[15] = 1;
    }
    for (int i = 0; i < 16; i++)
        if (!std::isfinite(m[i]))
            return L.fail(BTF_ERR_NUMERIC, "node %d: its transform is not finite", ni);
    return true;
}

// Upper 3x3 of m, its determinant, and the inverse transpose (for normals).
double normal_matrix(const double m[16], double nm[9])
{
    double a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], i = m[10];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    // cofactor matrix = det * inverse transpose; the scale does not matter once normalised
    double co[9] = {e * i - f * h, -(d * i - f * g), d * h - e * g, -(b * i - c * h), a * i - c * g,
                    -(a * h - b * g), b * f - c * e, -(a * f - c * d), a * e - b * d};
    // co is row-major cofactors C[r][c]; as column-major nm: nm[col*3+row] = C[row][col]
    for (int row = 0; row < 3; row++)
        for (int col = 0; col < 3; col++)
            nm[col * 3 + row] = det < 0 ? -co[row * 3 + col] : co[row * 3 + col];
    return det;
}

void xform3(const double m3[9], const float *v, double out[3], int stride4, const double *tr)
{
    for (int r = 0; r < 3; r++) {
        out[r] = tr ? tr[r] : 0.0;
        for (int c = 0; c < 3; c++)
            out[r] += (stride4 ? m3[c * 4 + r] : m3[c * 3 + r]) * v[c];
    }
}

void unit(double v[3], float *dst, const float fallback[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    bool ok = l > 0 && std::isfinite(l);
    for (int c = 0; c < 3; c++)
        dst[c] = ok ? (float)(v[c] / l) : fallback[c];
}

// One drawn part: geo under world matrix m, its material's name and colour.
bool add_part(Loader &L, const Geometry &geo, const tinygltf::Primitive &p, const double m[16])
{
    const int F = BTF_RENDER_VERTEX_FLOATS;
    size_t nv = geo.v.size() / F, ni = geo.idx.size();
    if ((long long)L.parts.size() >= BTF_GLTF_MAX_PARTS)
        return L.fail(BTF_ERR_RANGE, "more than %d drawn primitives", BTF_GLTF_MAX_PARTS);
    if (L.vertices + (long long)nv > BTF_GLTF_MAX_VERTICES || L.triangles + (long long)(ni / 3) > BTF_GLTF_MAX_TRIANGLES)
        return L.fail(BTF_ERR_RANGE, "more than %d vertices or %d triangles in the scene", BTF_GLTF_MAX_VERTICES,
                      BTF_GLTF_MAX_TRIANGLES);
    btf_gltf_part part;
    memset(&part, 0, sizeof part);
    part.mesh.vertices = (float *)malloc(nv * F * sizeof(float));
    part.mesh.indices = (unsigned *)malloc(ni * sizeof(unsigned));
    if (!part.mesh.vertices || !part.mesh.indices) {
        free(part.mesh.vertices), free(part.mesh.indices);
        return L.fail(BTF_ERR_NOMEM, "out of memory (%zu vertices)", nv);
    }
    part.mesh.n_vertices = (int)nv, part.mesh.n_indices = (int)ni;
    double nm[9];
    double det = normal_matrix(m, nm);
    static const float up[3] = {0, 0, 1}, ux[3] = {1, 0, 0};
    for (size_t i = 0; i < nv; i++) {
        const float *s = &geo.v[i * F];
        float *d = &part.mesh.vertices[i * F];
        double x[3];
        xform3(m, s, x, 1, m + 12);
        for (int c = 0; c < 3; c++)
            d[c] = (float)x[c];
        xform3(nm, s + 3, x, 0, NULL);
        unit(x, d + 3, up);
        xform3(m, s + 6, x, 1, NULL);
        unit(x, d + 6, ux);
        d[9] = (s[9] < 0 ? -1.0f : 1.0f) * (det < 0 ? -1.0f : 1.0f);
        d[10] = s[10], d[11] = s[11];
        for (int c = 0; c < BTF_RENDER_VERTEX_FLOATS; c++)
            if (!std::isfinite(d[c])) {
                free(part.mesh.vertices), free(part.mesh.indices);
                return L.fail(BTF_ERR_NUMERIC, "a vertex is not finite under its node's transform (%zu)", i);
            }
    }
    for (size_t t = 0; t < ni; t += 3) { // a mirroring transform turns the triangles over
        part.mesh.indices[t] = geo.idx[t];
        part.mesh.indices[t + 1] = geo.idx[det < 0 ? t + 2 : t + 1];
        part.mesh.indices[t + 2] = geo.idx[det < 0 ? t + 1 : t + 2];
    }
    part.material_index = p.material >= 0 && (size_t)p.material < L.g.materials.size() ? p.material : -1;
    part.base_color[0] = part.base_color[1] = part.base_color[2] = part.base_color[3] = 1.0f;
    if (part.material_index >= 0) {
        const tinygltf::Material &mt = L.g.materials[part.material_index];
        snprintf(part.material, sizeof part.material, "%s", mt.name.c_str());
        const std::vector<double> &bc = mt.pbrMetallicRoughness.baseColorFactor;
        for (size_t c = 0; c < 4 && c < bc.size(); c++)
            part.base_color[c] = std::isfinite(bc[c]) ? (float)fmin(fmax(bc[c], 0.0), 1.0) : 1.0f;
    }
    part.has_uv = geo.has_uv, part.tangents_given = geo.has_tangent;
    L.parts.push_back(part);
    L.vertices += (long long)nv, L.triangles += (long long)(ni / 3);
    return true;
}

// The parts of node ni and its children under parent matrix pm.
bool visit(Loader &L, int ni, const double pm[16], int depth, std::vector<std::vector<Geometry>> &geos)
{
    if (ni < 0 || (size_t)ni >= L.g.nodes.size())
        return L.fail(BTF_ERR_FORMAT, "node %d does not exist", ni);
    if (depth > BTF_GLTF_MAX_DEPTH)
        return L.fail(BTF_ERR_RANGE, "the node hierarchy is deeper than %d (or a cycle)", BTF_GLTF_MAX_DEPTH);
    if (++L.visits > BTF_GLTF_MAX_NODE_VISITS)
        return L.fail(BTF_ERR_RANGE, "more than %d node instances in the scene", BTF_GLTF_MAX_NODE_VISITS);
    const tinygltf::Node &nd = L.g.nodes[ni];
    double lm[16], m[16];
    if (!local_matrix(L, nd, ni, lm))
        return false;
    btf_render_mat4_mul(pm, lm, m);
    if (nd.mesh >= 0) {
        if ((size_t)nd.mesh >= L.g.meshes.size())
            return L.fail(BTF_ERR_FORMAT, "node %d: mesh %d does not exist", ni, nd.mesh);
        const tinygltf::Mesh &mesh = L.g.meshes[nd.mesh];
        std::vector<Geometry> &gs = geos[nd.mesh];
        if (gs.empty() && !mesh.primitives.empty()) { // each mesh's geometry once, however many nodes use it
            gs.resize(mesh.primitives.size());
            for (size_t k = 0; k < mesh.primitives.size(); k++) {
                if (!load_geometry(L, mesh.primitives[k], nd.mesh, gs[k]))
                    return false;
            }
        }
        for (size_t k = 0; k < mesh.primitives.size(); k++)
            if (!add_part(L, gs[k], mesh.primitives[k], m))
                return false;
    }
    for (int c : nd.children)
        if (!visit(L, c, m, depth + 1, geos))
            return false;
    return true;
}

// The nodes drawn: the default scene's (or the first scene's) roots; without scenes,
// every node that is nobody's child.
std::vector<int> roots(const tinygltf::Model &g)
{
    if (!g.scenes.empty()) {
        size_t s = g.defaultScene >= 0 && (size_t)g.defaultScene < g.scenes.size() ? (size_t)g.defaultScene : 0;
        return g.scenes[s].nodes;
    }
    std::vector<char> child(g.nodes.size(), 0);
    for (const tinygltf::Node &n : g.nodes)
        for (int c : n.children)
            if (c >= 0 && (size_t)c < g.nodes.size())
                child[c] = 1;
    std::vector<int> r;
    for (size_t i = 0; i < g.nodes.size(); i++)
        if (!child[i])
            r.push_back((int)i);
    return r;
}

btf_result bake(const tinygltf::Model &g, const char *name, btf_gltf **out, btf_error *err)
{
    for (const std::string &e : g.extensionsRequired)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: required extension %s is not supported", name, e.c_str());
    Loader L(g, name, err);
    std::vector<std::vector<Geometry>> geos(g.meshes.size());
    // glTF's +y up becomes the world's +z (its front, +z, faces the world's -y: the
    // default camera): x' = x, y' = -z, z' = y
    static const double up[16] = {1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1};
    for (int n : roots(g))
        if (!visit(L, n, up, 0, geos))
            return L.r;
    if (L.parts.empty())
        return btf_fail(err, BTF_ERR_FORMAT, "%s: the scene draws no triangles", name);
    btf_gltf *m = (btf_gltf *)calloc(1, sizeof *m);
    btf_gltf_part *parts = (btf_gltf_part *)malloc(L.parts.size() * sizeof *parts);
    if (!m || !parts) {
        free(m), free(parts);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    }
    memcpy(parts, L.parts.data(), L.parts.size() * sizeof *parts);
    m->parts = parts, m->n_parts = (int)L.parts.size();
    L.parts.clear(); // the model owns the meshes now
    for (int c = 0; c < 3; c++)
        m->min[c] = INFINITY, m->max[c] = -INFINITY;
    for (int i = 0; i < m->n_parts; i++)
        for (int v = 0; v < parts[i].mesh.n_vertices; v++)
            for (int c = 0; c < 3; c++) {
                float x = parts[i].mesh.vertices[v * BTF_RENDER_VERTEX_FLOATS + c];
                m->min[c] = fminf(m->min[c], x), m->max[c] = fmaxf(m->max[c], x);
            }
    *out = m;
    return BTF_OK;
}

// tinygltf's parse of bytes (binary when they start "glTF"); false with its message.
bool parse(tinygltf::Model &g, const uint8_t *data, size_t size, const std::string &dir, std::string &msg)
{
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(skip_image, nullptr);
    Folder folder{dir};
    tinygltf::FsCallbacks fs = {file_exists, keep_path, read_file, nullptr, &folder};
    loader.SetFsCallbacks(fs);
    std::string warn;
    if (size >= 4 && memcmp(data, "glTF", 4) == 0)
        return loader.LoadBinaryFromMemory(&g, &msg, &warn, data, (unsigned int)size, dir);
    return loader.LoadASCIIFromString(&g, &msg, &warn, (const char *)data, (unsigned int)size, dir);
}

// tinygltf drops a primitive without "attributes" silently; the browser's loader
// refuses it, and so does this one: true when the JSON (a .glb's first chunk, or
// the whole .gltf) has such a primitive. JSON that does not parse is tinygltf's to refuse.
bool primitive_without_attributes(const uint8_t *data, size_t size)
{
    const char *text = (const char *)data;
    size_t n = size;
    if (size >= 20 && memcmp(data, "glTF", 4) == 0) {
        uint32_t jn = (uint32_t)data[12] | (uint32_t)data[13] << 8 | (uint32_t)data[14] << 16 | (uint32_t)data[15] << 24;
        if (jn > size - 20)
            return false;
        text = (const char *)data + 20, n = jn;
    }
    cJSON *doc = cJSON_ParseWithLength(text, n);
    bool bad = false;
    const cJSON *mesh, *prim;
    cJSON_ArrayForEach(mesh, cJSON_GetObjectItemCaseSensitive(doc, "meshes"))
        cJSON_ArrayForEach(prim, cJSON_GetObjectItemCaseSensitive(mesh, "primitives"))
            bad |= !cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(prim, "attributes"));
    cJSON_Delete(doc);
    return bad;
}

btf_result load_bytes(const uint8_t *data, size_t size, const char *name, const std::string &dir, btf_gltf **out,
                      btf_error *err)
{
    if (size > (size_t)BTF_GLTF_MAX_FILE_BYTES)
        return btf_fail(err, BTF_ERR_RANGE, "%s: larger than %lld bytes", name, (long long)BTF_GLTF_MAX_FILE_BYTES);
    if (size < 4)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a glTF file (%zu bytes)", name, size);
    if (memcmp(data, "glTF", 4) == 0) { /* a .glb: version 2 and a length within the bytes (tinygltf checks neither) */
        uint32_t version = size >= 12 ? (uint32_t)data[4] | (uint32_t)data[5] << 8 | (uint32_t)data[6] << 16 |
                                            (uint32_t)data[7] << 24
                                      : 0;
        if (version != 2)
            return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: binary glTF version %u (only 2)", name, version);
    }
    if (primitive_without_attributes(data, size))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: a mesh primitive has no \"attributes\"", name);
    tinygltf::Model g;
    std::string msg;
    bool ok = false;
    try {
        ok = parse(g, data, size, dir, msg);
    } catch (const std::exception &e) {
        msg = e.what();
    }
    if (!ok) {
        for (char &c : msg)
            if (c == '\n')
                c = ' ';
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a valid glTF: %s", name, msg.empty() ? "parse failed" : msg.c_str());
    }
    try {
        return bake(g, name, out, err);
    } catch (const std::bad_alloc &) {
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    }
}

} // namespace

extern "C" btf_result btf_gltf_load_memory(const uint8_t *data, size_t size, const char *name, btf_gltf **out,
                                            btf_error *err)
{
    if (!out || (!data && size))
        return btf_fail(err, BTF_ERR_ARG, "model: bad arguments");
    *out = NULL;
    // no folder: a .gltf in memory can only use data URIs
    return load_bytes(data, size, name ? name : "model", "/nonexistent-btf-model-dir", out, err);
}

extern "C" btf_result btf_gltf_load(const char *path, btf_gltf **out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "model: bad arguments");
    *out = NULL;
    char *text = NULL;
    size_t size = 0;
    btf_result r = btf_fs_read(path, (size_t)BTF_GLTF_MAX_FILE_BYTES, &text, &size, err);
    if (r != BTF_OK)
        return r;
    std::string p(path), dir = ".";
    size_t slash = p.rfind('/');
    if (slash != std::string::npos)
        dir = slash == 0 ? "/" : p.substr(0, slash);
    r = load_bytes((const uint8_t *)text, size, path, dir, out, err);
    free(text);
    return r;
}

extern "C" void btf_gltf_free(btf_gltf *m)
{
    if (!m)
        return;
    for (int i = 0; i < m->n_parts; i++)
        free(m->parts[i].mesh.vertices), free(m->parts[i].mesh.indices);
    free(m->parts);
    free(m);
}
