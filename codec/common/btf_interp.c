/* btf_interp.c - angular interpolation over a ring direction set (thesis 4.4,
 * made continuous for any ring table).
 *
 * The exact algorithm, step by step, is in doc/data-model.md ("Angular
 * interpolation"); the GLSL in shaders/ must reproduce it operation by
 * operation. Everything here is float32 (no double), O(number of rings), and
 * never looks at more than 4 directions plus one per-ring theta comparison.
 *
 * In short: the sphere is covered by a triangulation whose edges are great-
 * circle arcs: consecutive directions of a ring are joined (the ring becomes a
 * convex spherical polygon), and the band between two rings is "zipped" by
 * walking both rings in phi order. The query P falls into exactly one
 * triangle; its weights are the tetrahedron volumes det(P, Pj, Pk) (thesis
 * 4.4.2), i.e. the coefficients of P in the basis of the triangle's vertices.
 * Shared edges give identical weights from both sides, so the result has no
 * seams. Inside the innermost ring polygon of a set without a pole direction,
 * and beyond the outermost ring polygon (down to and below the horizon), the
 * two ring neighbours are blended by the azimuth of P alone.
 */
#include "btf.h"
#include "btf_dirtab.h"
#include "btf_common.h"

#include <math.h>
#include <string.h>

#define BTF__DEG2RAD 0.017453292519943295f
/* Two "next" vertices whose phi differ by less than this (degrees) count as
 * aligned; they are then treated as "lower ring first" (see the doc). */
#define BTF__PHI_TIE_DEG 1e-3f
/* Longest walk through one band (see btf__band); enough while neighbouring
 * rings differ in count by a factor below ~14. */
#define BTF_INTERP_MAX_STEPS 16

/* 3-vector in the local frame (z = surface normal); value type. */
typedef struct btf__v3 {
    float x, y, z;
} btf__v3;

static btf__v3 btf__sub(btf__v3 a, btf__v3 b)
{
    btf__v3 r = {a.x - b.x, a.y - b.y, a.z - b.z};
    return r;
}

/* det(p, a, b) = p . (a x b), evaluated as p . ((a - p) x (b - p)): same value
 * in exact arithmetic, far less cancellation when a, b are close to p. */
static float btf__det(btf__v3 p, btf__v3 a, btf__v3 b)
{
    btf__v3 u = btf__sub(a, p), v = btf__sub(b, p);
    float cx = u.y * v.z - u.z * v.y;
    float cy = u.z * v.x - u.x * v.z;
    float cz = u.x * v.y - u.y * v.x;
    return p.x * cx + p.y * cy + p.z * cz;
}

static btf__v3 btf__dir(float theta_deg, float phi_deg)
{
    float t = theta_deg * BTF__DEG2RAD, p = phi_deg * BTF__DEG2RAD;
    float st = sinf(t);
    btf__v3 r = {st * cosf(p), st * sinf(p), cosf(t)};
    return r;
}

/* Unit vector and canonical index of vertex k (any integer) of ring r. */
static btf__v3 btf__vertex(const btf_dirset *d, int r, int k, int *idx)
{
    const btf_ring *g = &d->rings[r];
    int m = k % g->count;
    if (m < 0)
        m += g->count;
    *idx = d->ring_start[r] + m;
    return btf__dir(g->theta_deg, g->phi_offset_deg + (float)m * (360.0f / (float)g->count));
}

/* Index of the ring-r vertex at or before phi (unwrapped, may be < 0). */
static int btf__vertex_below(const btf_ring *g, float phi)
{
    return (int)floorf((phi - g->phi_offset_deg) / (360.0f / (float)g->count));
}

/* The two directions of ring r that bracket phi (0 <= phi < 360): lo at or
 * before phi, hi the next one counter-clockwise. Value type. */
typedef struct btf__pair {
    int lo, hi;       /* canonical indices */
    btf__v3 vlo, vhi; /* unit vectors */
} btf__pair;

static btf__pair btf__ring_pair(const btf_dirset *d, int r, float phi)
{
    int k = btf__vertex_below(&d->rings[r], phi);
    btf__pair q;
    q.vlo = btf__vertex(d, r, k, &q.lo);
    q.vhi = btf__vertex(d, r, k + 1, &q.hi);
    return q;
}

/* Weights of triangle (x, y, z) at p: max(0, det * orientation), normalised;
 * a degenerate triangle gives all weight to x. */
static btf_interp btf__tri(btf__v3 p, int ix, btf__v3 x, int iy, btf__v3 y, int iz, btf__v3 z)
{
    float vol = btf__det(x, y, z);
    float w0 = fmaxf(0.0f, btf__det(p, y, z) * vol);
    float w1 = fmaxf(0.0f, btf__det(p, z, x) * vol);
    float w2 = fmaxf(0.0f, btf__det(p, x, y) * vol);
    float s = w0 + w1 + w2;
    btf_interp r = {{ix, iy, iz}, {1.0f, 0.0f, 0.0f}};
    if (s > 1e-30f) {
        r.w[0] = w0 / s;
        r.w[1] = w1 / s;
        r.w[2] = w2 / s;
    }
    return r;
}

/* Cap (no pole direction) and beyond the outermost ring: blend the two ring
 * neighbours by azimuth only: w_lo ~ (P x hi).z, w_hi ~ (lo x P).z. */
static btf_interp btf__azimuth(btf__v3 p, const btf__pair *q)
{
    float w0 = fmaxf(0.0f, p.x * q->vhi.y - p.y * q->vhi.x);
    float w1 = fmaxf(0.0f, q->vlo.x * p.y - q->vlo.y * p.x);
    float s = w0 + w1;
    btf_interp r = {{q->lo, q->hi, q->lo}, {1.0f, 0.0f, 0.0f}};
    if (s > 1e-30f) {
        r.w[0] = w0 / s;
        r.w[1] = w1 / s;
    }
    return r;
}

/* phi of vertex k of ring r, unwrapped (k may be <0 or >= count). A ring of one
 * direction never "comes next" (it has no edge along the ring): phi + 720. */
static float btf__vertex_phi(const btf_ring *g, int k, float phi)
{
    return g->count == 1 ? phi + 720.0f : g->phi_offset_deg + (float)k * (360.0f / (float)g->count);
}

/* P between ring lo (inner) and ring lo+1 (outer): walk the zipper triangulation
 * of the band from the vertex pair current at phi until P lies left of the
 * walk's new cross edge (doc/data-model.md, step 5). */
static btf_interp btf__band(const btf_dirset *d, int lo, btf__v3 p, float phi)
{
    const btf_ring *gl = &d->rings[lo], *gu = &d->rings[lo + 1];
    int kl = btf__vertex_below(gl, phi), ku = btf__vertex_below(gu, phi);
    int il, iu, ix;
    btf__v3 vl = btf__vertex(d, lo, kl, &il), vu = btf__vertex(d, lo + 1, ku, &iu);
    btf_interp r = {{il, il, il}, {1.0f, 0.0f, 0.0f}};
    for (int s = 0; s < BTF_INTERP_MAX_STEPS; s++) {
        int lower_next = btf__vertex_phi(gl, kl + 1, phi) - btf__vertex_phi(gu, ku + 1, phi) <= BTF__PHI_TIE_DEG;
        btf__v3 x = lower_next ? btf__vertex(d, lo, kl + 1, &ix) : btf__vertex(d, lo + 1, ku + 1, &ix);
        r = btf__tri(p, il, vl, iu, vu, ix, x);
        /* the next cross edge runs from the new inner vertex to the new outer one;
         * det(P, inner, outer) > 0 means P lies beyond it (larger phi) */
        if (!(btf__det(p, lower_next ? x : vl, lower_next ? vu : x) > 0.0f))
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

/* The last list set this thread interpolated and its table (made on first use,
 * replaced when another list comes; reachable until the thread ends). */
static _Thread_local struct {
    int n;
    float list[BTF_MAX_LIST_DIRS][2];
    btf_dirtab *tab;
} btf__last_list;

void btf_interp_keep_list(const btf_dirset *d, btf_dirtab *t)
{
    btf_dirtab_free(btf__last_list.tab);
    btf__last_list.tab = t;
    btf__last_list.n = d->n_dirs;
    memcpy(btf__last_list.list, d->list, sizeof(float[2]) * (size_t)d->n_dirs);
}

/* A list set: through its table, kept for the next query on the same list. */
static btf_interp btf__list_interp(const btf_dirset *d, float theta_deg, float phi_deg)
{
    btf_interp none = {{0, 0, 0}, {1.0f, 0.0f, 0.0f}};
    size_t bytes = sizeof(float[2]) * (size_t)d->n_dirs;
    if (!btf__last_list.tab || btf__last_list.n != d->n_dirs || memcmp(btf__last_list.list, d->list, bytes) != 0) {
        btf_dirtab_free(btf__last_list.tab);
        btf__last_list.tab = NULL;
        if (btf_dirtab_build(d, &btf__last_list.tab, NULL) != BTF_OK)
            return none;
        btf__last_list.n = d->n_dirs;
        memcpy(btf__last_list.list, d->list, bytes);
    }
    float th = theta_deg == theta_deg ? fminf(fmaxf(theta_deg, 0.0f), 90.0f) * BTF__DEG2RAD : 0.0f;
    float ph = isfinite(phi_deg) ? phi_deg * BTF__DEG2RAD : 0.0f;
    float v[3] = {sinf(th) * cosf(ph), sinf(th) * sinf(ph), cosf(th)};
    return btf_dirtab_interp_vec(btf__last_list.tab, v);
}

btf_interp btf_dirset_interp(const btf_dirset *d, float theta_deg, float phi_deg)
{
    btf_interp none = {{0, 0, 0}, {1.0f, 0.0f, 0.0f}};
    if (d && btf_dirset_is_list(d))
        return btf__list_interp(d, theta_deg, phi_deg);
    if (!d || d->n_rings < 1 || d->n_rings > BTF_MAX_RINGS || d->n_dirs < 1)
        return none;
    /* 1. sanitise: NaN theta -> 0, clamp to [0, 90]; NaN/Inf phi -> 0, wrap to [0, 360) */
    float t = theta_deg == theta_deg ? fminf(fmaxf(theta_deg, 0.0f), 90.0f) : 0.0f;
    float phi = isfinite(phi_deg) ? phi_deg - 360.0f * floorf(phi_deg / 360.0f) : 0.0f;
    if (!(phi >= 0.0f && phi < 360.0f)) /* -1e-9 wraps to 360.0f; |phi| ~1e30 loses all digits */
        phi = 0.0f;
    btf__v3 p = btf__dir(t, phi);
    /* 2. candidate band from theta alone: last ring with theta_r <= t (-1 if none) */
    int lo = -1;
    for (int r = 0; r < d->n_rings; r++)
        if (d->rings[r].theta_deg <= t)
            lo = r;
    /* 3. the next ring's polygon edge may bulge past P: then P belongs one band out */
    if (lo + 1 < d->n_rings) {
        btf__pair q = btf__ring_pair(d, lo + 1, phi);
        if (!(btf__det(p, q.vlo, q.vhi) > 0.0f))
            lo++;
    }
    /* 4. inside the innermost polygon (no pole) or beyond the outermost one */
    if (lo < 0 || lo == d->n_rings - 1) {
        btf__pair q = btf__ring_pair(d, lo < 0 ? 0 : lo, phi);
        return btf__azimuth(p, &q);
    }
    /* 5. between two rings */
    return btf__band(d, lo, p, phi);
}

btf_interp btf_dirset_interp_vec(const btf_dirset *d, const float v[3])
{
    /* zero, NaN or Inf components: defined as the normal (theta 0) */
    if (!v || !isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
        return btf_dirset_interp(d, 0.0f, 0.0f);
    float m = fmaxf(fabsf(v[0]), fmaxf(fabsf(v[1]), fabsf(v[2])));
    if (!(m > 0.0f))
        return btf_dirset_interp(d, 0.0f, 0.0f);
    float x = v[0] / m, y = v[1] / m, z = v[2] / m; /* scaled: no overflow below */
    float theta = atan2f(sqrtf(x * x + y * y), z) / BTF__DEG2RAD; /* accurate near 0 too */
    float phi = (x == 0.0f && y == 0.0f) ? 0.0f : atan2f(y, x) / BTF__DEG2RAD;
    return btf_dirset_interp(d, theta, phi);
}
