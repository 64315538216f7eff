// btf_dirs.glsl - angular interpolation over a ring direction set: the GLSL twin of
// btf_dirset_interp (codec/btf_interp.c; algorithm in doc/data-model.md). It follows
// the C operation by operation, in float, so both give the same 3 directions and
// weights (tested to 1e-4 in tests/test_gl.c on both headless backends).
//
// A direction set is a ring table in a uniform struct, one vec4 per ring:
//   rings[r] = (theta_deg, count, phi_offset_deg, canonical index of the ring's first direction)
// with rings in ascending theta (as btf_dirset keeps them), n_rings <= BTF_MAX_RINGS.
// Any set (UBO2003's 81 directions, the 151-direction dome, a JSON table) works
// without new shader code.
//
// Public:  btf_interp btf_dirs_interp(btf_dirset d, float theta_deg, float phi_deg)
//          btf_interp btf_dirs_interp_vec(btf_dirset d, vec3 v)   (local frame, z = normal)
// Unused weight slots are 0 and repeat a valid index.

#ifndef BTF_MAX_RINGS
#define BTF_MAX_RINGS 32
#endif

#define BTF_DEG2RAD 0.017453292519943295
#define BTF_PHI_TIE_DEG 1e-3
// Longest walk through one band (btf_dirs_band); enough while neighbouring rings
// differ in count by a factor below ~14. Same value as BTF_INTERP_MAX_STEPS in C.
#define BTF_INTERP_MAX_STEPS 16

struct btf_dirset {
    vec4 rings[BTF_MAX_RINGS];
    int n_rings;
};

struct btf_interp {
    ivec3 idx;
    vec3 w;
};

// Two directions of one ring bracketing phi: lo at or before phi, hi the next one.
struct btf_dirs_pair {
    int lo;
    int hi;
    vec3 vlo;
    vec3 vhi;
};

// (floor(a / n), a - n * floor(a / n)) for n > 0 and |a| < 2^24: the quotient in
// float (GPU division may be off by one ulp, the two corrections fix that), because
// integer division runs one lane at a time on CPU rasterizers (llvmpipe), and GLSL ES
// leaves % of negative operands undefined. Used by btf_decode.glsl too.
ivec2 btf_divmod(int a, int n)
{
    int q = int(floor(float(a) / float(n)));
    int m = a - n * q;
    q -= m < 0 ? 1 : 0;
    m += m < 0 ? n : 0;
    q += m >= n ? 1 : 0;
    m -= m >= n ? n : 0;
    return ivec2(q, clamp(m, 0, n - 1)); // in range even where |a| >= 2^24 is inexact
}

vec3 btf_dirs_vec(float theta_deg, float phi_deg)
{
    float t = theta_deg * BTF_DEG2RAD, p = phi_deg * BTF_DEG2RAD;
    float st = sin(t);
    return vec3(st * cos(p), st * sin(p), cos(t));
}

// det(p, a, b) = p . (a x b), evaluated as p . ((a - p) x (b - p)) (less cancellation).
float btf_dirs_det(vec3 p, vec3 a, vec3 b)
{
    vec3 u = a - p, v = b - p;
    float cx = u.y * v.z - u.z * v.y;
    float cy = u.z * v.x - u.x * v.z;
    float cz = u.x * v.y - u.y * v.x;
    return p.x * cx + p.y * cy + p.z * cz;
}

// Unit vector and canonical index of vertex k (any integer) of ring r.
vec3 btf_dirs_vertex(btf_dirset d, int r, int k, out int idx)
{
    vec4 g = d.rings[r];
    int n = int(g.y);
    int m = btf_divmod(k, n).y;
    idx = int(g.w) + m;
    return btf_dirs_vec(g.x, g.z + float(m) * (360.0 / float(n)));
}

// Index of the ring's vertex at or before phi (unwrapped, may be < 0).
int btf_dirs_vertex_below(vec4 g, float phi)
{
    return int(floor((phi - g.z) / (360.0 / float(int(g.y)))));
}

// phi of vertex k, unwrapped; a ring of one direction never "comes next": phi + 720.
float btf_dirs_vertex_phi(vec4 g, int k, float phi)
{
    int n = int(g.y);
    return n == 1 ? phi + 720.0 : g.z + float(k) * (360.0 / float(n));
}

btf_dirs_pair btf_dirs_ring_pair(btf_dirset d, int r, float phi)
{
    int k = btf_dirs_vertex_below(d.rings[r], phi);
    btf_dirs_pair q;
    q.vlo = btf_dirs_vertex(d, r, k, q.lo);
    q.vhi = btf_dirs_vertex(d, r, k + 1, q.hi);
    return q;
}

// Weights of triangle (x, y, z) at p; a degenerate triangle gives all weight to x.
btf_interp btf_dirs_tri(vec3 p, int ix, vec3 x, int iy, vec3 y, int iz, vec3 z)
{
    float vol = btf_dirs_det(x, y, z);
    float w0 = max(0.0, btf_dirs_det(p, y, z) * vol);
    float w1 = max(0.0, btf_dirs_det(p, z, x) * vol);
    float w2 = max(0.0, btf_dirs_det(p, x, y) * vol);
    float s = w0 + w1 + w2;
    btf_interp r;
    r.idx = ivec3(ix, iy, iz);
    r.w = s > 1e-30 ? vec3(w0, w1, w2) / s : vec3(1.0, 0.0, 0.0);
    return r;
}

// Inside the innermost ring (no pole) and beyond the outermost: blend by azimuth only.
btf_interp btf_dirs_azimuth(vec3 p, btf_dirs_pair q)
{
    float w0 = max(0.0, p.x * q.vhi.y - p.y * q.vhi.x);
    float w1 = max(0.0, q.vlo.x * p.y - q.vlo.y * p.x);
    float s = w0 + w1;
    btf_interp r;
    r.idx = ivec3(q.lo, q.hi, q.lo);
    r.w = s > 1e-30 ? vec3(w0, w1, 0.0) / s : vec3(1.0, 0.0, 0.0);
    return r;
}

// P between ring lo (inner) and lo + 1 (outer), whose vertex pairs current at phi are
// qi and qo: walk the band's zipper triangulation from those vertices until P lies
// left of the walk's new cross edge. One vertex per step (the ring and index are
// chosen first): CPU rasterizers such as llvmpipe run both sides of every branch.
btf_interp btf_dirs_band(btf_dirset d, int lo, vec3 p, float phi, btf_dirs_pair qi, btf_dirs_pair qo)
{
    vec4 g_in = d.rings[lo], g_out = d.rings[lo + 1];
    int kl = btf_dirs_vertex_below(g_in, phi), ku = btf_dirs_vertex_below(g_out, phi);
    int il = qi.lo, iu = qo.lo, ix;
    vec3 vl = qi.vlo, vu = qo.vlo;
    btf_interp r;
    r.idx = ivec3(il);
    r.w = vec3(1.0, 0.0, 0.0);
    for (int s = 0; s < BTF_INTERP_MAX_STEPS; s++) {
        bool lower_next =
            btf_dirs_vertex_phi(g_in, kl + 1, phi) - btf_dirs_vertex_phi(g_out, ku + 1, phi) <= BTF_PHI_TIE_DEG;
        vec3 x = btf_dirs_vertex(d, lower_next ? lo : lo + 1, lower_next ? kl + 1 : ku + 1, ix);
        r = btf_dirs_tri(p, il, vl, iu, vu, ix, x);
        // the next cross edge runs from the new inner vertex to the new outer one;
        // det(P, inner, outer) > 0 means P lies beyond it (larger phi)
        if (!(btf_dirs_det(p, lower_next ? x : vl, lower_next ? vu : x) > 0.0))
            return r;
        if (lower_next) {
            kl++;
            il = ix;
            vl = x;
        } else {
            ku++;
            iu = ix;
            vu = x;
        }
    }
    return r;
}

btf_interp btf_dirs_interp(btf_dirset d, float theta_deg, float phi_deg)
{
    // 1. sanitise: NaN theta -> 0, clamp to [0, 90]; NaN/Inf phi -> 0, wrap to [0, 360)
    float t = theta_deg == theta_deg ? min(max(theta_deg, 0.0), 90.0) : 0.0;
    float phi = (isnan(phi_deg) || isinf(phi_deg)) ? 0.0 : phi_deg - 360.0 * floor(phi_deg / 360.0);
    if (!(phi < 360.0))
        phi = 0.0;
    vec3 p = btf_dirs_vec(t, phi);
    // 2. candidate band from theta alone: last ring with theta <= t (-1 if none)
    int lo = -1;
    for (int r = 0; r < BTF_MAX_RINGS; r++) {
        if (r >= d.n_rings)
            break;
        if (d.rings[r].x <= t)
            lo = r;
    }
    // 3. the next ring's polygon edge may bulge past P: then P belongs one band out.
    // qa = vertex pair of ring lo + 1 at phi (of the last ring when there is none).
    int n = d.n_rings;
    btf_dirs_pair qa = btf_dirs_ring_pair(d, min(lo + 1, n - 1), phi);
    bool moved = lo + 1 < n && !(btf_dirs_det(p, qa.vlo, qa.vhi) > 0.0);
    // the other pair the cases below need: ring lo + 2 when P moved out, else ring lo
    btf_dirs_pair qb = btf_dirs_ring_pair(d, clamp(moved ? lo + 2 : lo, 0, n - 1), phi);
    if (moved)
        lo++;
    // 4. inside the innermost polygon (no pole) or beyond the outermost one
    // (no ?: on structs: WebGL forbids it)
    btf_dirs_pair qi = qb, qo = qa; // inner ring lo, outer ring lo + 1
    if (moved) {
        qi = qa;
        qo = qb;
    }
    if (lo < 0)
        return btf_dirs_azimuth(p, qa);
    if (lo == n - 1)
        return btf_dirs_azimuth(p, qi);
    // 5. between two rings
    return btf_dirs_band(d, lo, p, phi, qi, qo);
}

btf_interp btf_dirs_interp_vec(btf_dirset d, vec3 v)
{
    // NaN or Inf components, or the zero vector: defined as the normal (theta 0)
    if (any(isnan(v)) || any(isinf(v)))
        return btf_dirs_interp(d, 0.0, 0.0);
    float m = max(abs(v.x), max(abs(v.y), abs(v.z)));
    if (!(m > 0.0))
        return btf_dirs_interp(d, 0.0, 0.0);
    vec3 s = v / m; // scaled: no overflow below
    // atan, not acos(z): accurate near the pole (GPU acos is also coarse: 1.6e-4 rad on llvmpipe)
    float theta = atan(sqrt(s.x * s.x + s.y * s.y), s.z) / BTF_DEG2RAD;
    float phi = (s.x == 0.0 && s.y == 0.0) ? 0.0 : atan(s.y, s.x) / BTF_DEG2RAD;
    return btf_dirs_interp(d, theta, phi);
}
