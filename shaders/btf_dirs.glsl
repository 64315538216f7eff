// btf_dirs.glsl - angular interpolation by direction table: the GLSL twin of
// btf_dirtab_interp_vec (codec/common/btf_dirtab.c; doc/data-model.md, "Direction tables"),
// operation by operation in float. Per query: one table texel, three vertex reads
// from a uniform block and three determinants; a step to a neighbouring triangle
// (one more texel) only where the cell's triangle does not contain the query.
// Cost does not depend on the number of rings or directions.
//
// Data (filled by the host, C: btf_gl_dirs_upload; browser: client/btf-gl.js):
//   btf_dirs_block   std140 uniform block, vec4 u_btf_verts[BTF_GL_MAX_VERTS]: the vertices
//                    of both sets (lights first, then views), each set followed by its
//                    two virtual poles (ring sets) or by the mirror images below the
//                    horizon its triangles use (list sets): xyz = unit vector, w =
//                    direction index + 1 within its set (a mirror image: the direction it
//                    mirrors; 0 = virtual pole: weight dropped, the others renormalised)
//   u_btf_dir_cells  RGBA32UI, 64 x 128: set s, cell (i, j) at texel (i, j + 64 s) = the
//                    texel of a triangle containing the cell centre (below)
//   u_btf_dir_tris   RGBA32UI, 1024 x rows: triangle t at (t & 1023, t >> 10) =
//                    (v0 | v1 << 16, v2, n0 | n1 << 16, n2): vertices (into u_btf_verts,
//                    counter-clockwise seen from outside) and the triangle across the
//                    edge opposite each vertex (0xFFFF: none)
//
// Public:  btf_interp btf_dirs_interp_vec(int set, vec3 v)   set 0 lights, 1 views;
//          v in the local frame (z = normal), any length; NaN/Inf/zero = the normal,
//          z < 0 = the horizon at the same azimuth. Unused weight slots are 0 and
//          repeat a valid index (and its block). blk: each direction's block (views;
//          0 for lights), so the decoder reads no vertex again.
//          vec3 btf_dirs_vec(float theta_deg, float phi_deg)

#ifndef BTF_GL_MAX_VERTS
#define BTF_GL_MAX_VERTS 1024
#endif
#define BTF_DEG2RAD 0.017453292519943295
#define BTF_DIRS_CELLS 64
#define BTF_DIRS_MAX_STEPS 8

layout(std140) uniform btf_dirs_block {
    vec4 u_btf_verts[BTF_GL_MAX_VERTS];
};
uniform highp usampler2D u_btf_dir_cells;
uniform highp usampler2D u_btf_dir_tris;

struct btf_interp {
    ivec3 idx; // direction indices within the set
    ivec3 blk; // view sets: each direction's block (bits 12.. of the vertex .w); lights: 0
    vec3 w;
};

vec3 btf_dirs_vec(float theta_deg, float phi_deg)
{
    float t = theta_deg * BTF_DEG2RAD, p = phi_deg * BTF_DEG2RAD;
    float st = sin(t);
    return vec3(st * cos(p), st * sin(p), cos(t));
}

// det(p, a, b) = p . ((a - p) x (b - p)) (less cancellation than p . (a x b)).
float btf_dirs_det(vec3 p, vec3 a, vec3 b)
{
    vec3 u = a - p, v = b - p;
    float cx = u.y * v.z - u.z * v.y;
    float cy = u.z * v.x - u.x * v.z;
    float cz = u.x * v.y - u.y * v.x;
    return p.x * cx + p.y * cy + p.z * cz;
}

// The query as a unit vector (btf__query in C).
vec3 btf_dirs_query(vec3 v)
{
    float m = max(abs(v.x), max(abs(v.y), abs(v.z)));
    if (any(isnan(v)) || any(isinf(v)) || !(m > 0.0))
        return vec3(0.0, 0.0, 1.0);
    vec3 s = vec3(v.xy / m, max(v.z / m, 0.0));
    if (s.x == 0.0 && s.y == 0.0 && s.z == 0.0)
        s.x = 1.0;
    return s / sqrt(dot(s, s));
}

// Cell of the octahedral map of the upper hemisphere (btf_dirtab_cell_of).
ivec2 btf_dirs_cell(vec3 p)
{
    float s = abs(p.x) + abs(p.y) + p.z;
    vec2 ab = s > 0.0 ? p.xy / s : vec2(0.0);
    vec2 uv = floor((vec2(ab.x + ab.y, ab.x - ab.y) + 1.0) * 0.5 * float(BTF_DIRS_CELLS));
    return clamp(ivec2(uv), 0, BTF_DIRS_CELLS - 1);
}

btf_interp btf_dirs_interp_vec(int set, vec3 v)
{
    vec3 p = btf_dirs_query(v);
    ivec2 c = btf_dirs_cell(p);
    uvec4 t = texelFetch(u_btf_dir_cells, ivec2(c.x, c.y + BTF_DIRS_CELLS * set), 0);
    vec3 w, real; // real: the vertices' .w, read once with their vectors
    for (int s = 0; s <= BTF_DIRS_MAX_STEPS; s++) {
        vec4 x = u_btf_verts[int(t.x & 0xFFFFu)], y = u_btf_verts[int(t.x >> 16)], z = u_btf_verts[int(t.y)];
        real = vec3(x.w, y.w, z.w);
        w = vec3(btf_dirs_det(p, y.xyz, z.xyz), btf_dirs_det(p, z.xyz, x.xyz), btf_dirs_det(p, x.xyz, y.xyz));
        int k = w.x <= w.y && w.x <= w.z ? 0 : w.y <= w.z ? 1 : 2;
        uint n = k == 0 ? t.z & 0xFFFFu : k == 1 ? t.z >> 16 : t.w;
        if (w[k] >= 0.0 || s == BTF_DIRS_MAX_STEPS || n == 0xFFFFu)
            break;
        t = texelFetch(u_btf_dir_tris, ivec2(int(n & 1023u), int(n >> 10)), 0);
    }
    ivec3 iw = ivec3(real), idx = (iw & 4095) - 1, blk = iw >> 12; // bits 12.. of a view vertex: its block
    bvec3 on = greaterThan(real, vec3(0.0)); // false: a virtual pole
    int k = on.x ? 0 : on.y ? 1 : 2;         // the first real vertex
    w = max(w, 0.0) * vec3(on);              // a virtual pole's weight is dropped
    float sum = w.x + w.y + w.z;
    btf_interp r;
    r.idx = ivec3(on.x ? idx.x : idx[k], on.y ? idx.y : idx[k], on.z ? idx.z : idx[k]);
    r.blk = ivec3(on.x ? blk.x : blk[k], on.y ? blk.y : blk[k], on.z ? blk.z : blk[k]);
    r.w = w / sum;
    if (!(sum > 1e-30)) { // a query at a virtual pole: all weight to the first real vertex
        r.idx.x = idx[k];
        r.blk.x = blk[k];
        r.w = vec3(1.0, 0.0, 0.0);
    }
    return r;
}
