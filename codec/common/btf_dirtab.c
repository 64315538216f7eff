/* btf_dirtab.c - a ring direction set as explicit triangles plus a lookup table
 * (btf_dirtab.h). The triangles are exactly those of the ring algorithm in
 * btf_interp.c (doc/data-model.md, "Angular interpolation"), enumerated once;
 * the lookup is the one shaders/btf_dirs.glsl performs operation by operation. */
#include "btf_dirtab.h"
#include "btf_hull.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BTF__DEG2RAD 0.017453292519943295f
#define BTF__PHI_TIE_DEG 1e-3f /* as in btf_interp.c: aligned "next" vertices go inner first */
#define BTF__N BTF_DIRTAB_CELLS

/* A point held in three scalars: the walk below loads a triangle's vertices once and
 * computes on values, not through pointers (the same arithmetic, fewer loads; a
 * sanitizer build checks every load through a pointer). */
typedef struct btf__v3 {
    float x, y, z;
} btf__v3;

static btf__v3 btf__v3_of(const float a[3])
{
    btf__v3 r = {a[0], a[1], a[2]};
    return r;
}

/* det(p, a, b) = p . ((a - p) x (b - p)): the same expression as btf_interp.c and the GLSL. */
static float btf__det3v(btf__v3 p, btf__v3 a, btf__v3 b)
{
    float ux = a.x - p.x, uy = a.y - p.y, uz = a.z - p.z, vx = b.x - p.x, vy = b.y - p.y, vz = b.z - p.z;
    float cx = uy * vz - uz * vy;
    float cy = uz * vx - ux * vz;
    float cz = ux * vy - uy * vx;
    return p.x * cx + p.y * cy + p.z * cz;
}

static float btf__det3(const float p[3], const float a[3], const float b[3])
{
    return btf__det3v(btf__v3_of(p), btf__v3_of(a), btf__v3_of(b));
}

/* Triangles under construction; owned by btf_dirtab_build for its duration. */
typedef struct btf__tris {
    btf_dirtab *t;
    int cap;
} btf__tris;

static void btf__add(btf__tris *b, int a, int c, int d)
{
    btf_dirtab *t = b->t;
    if (t->n_tris >= b->cap || a == c || c == d || a == d)
        return;
    if (btf__det3(t->vert[a], t->vert[c], t->vert[d]) < 0.0f) { /* counter-clockwise from outside */
        int x = c;
        c = d;
        d = x;
    }
    int *r = t->tri[t->n_tris++];
    r[0] = a, r[1] = c, r[2] = d;
}

/* Canonical index of vertex k (any integer) of ring r. */
static int btf__ring_vertex(const btf_dirset *d, int r, int k)
{
    int n = d->rings[r].count, m = k % n;
    return d->ring_start[r] + (m < 0 ? m + n : m);
}

/* Unwrapped phi of vertex k of ring r; a ring of one direction never comes next. */
static float btf__ring_phi(const btf_ring *g, int k)
{
    return g->count == 1 ? 1e9f : g->phi_offset_deg + (float)k * (360.0f / (float)g->count);
}

/* The zipper between ring lo and lo + 1: both rings walked in phi order from phi 0,
 * the ring whose next vertex comes first (inner on a tie) advances, one triangle per
 * step, count_lo + count_hi triangles once around (the walk of btf_interp.c). */
static void btf__band(btf__tris *b, const btf_dirset *d, int lo)
{
    const btf_ring *gi = &d->rings[lo], *go = &d->rings[lo + 1];
    int ki = (int)floorf((0.0f - gi->phi_offset_deg) / (360.0f / (float)gi->count));
    int ko = (int)floorf((0.0f - go->phi_offset_deg) / (360.0f / (float)go->count));
    int steps_i = gi->count == 1 ? 0 : gi->count, steps_o = go->count == 1 ? 0 : go->count;
    for (int s = 0; s < steps_i + steps_o; s++) {
        int inner_next = btf__ring_phi(gi, ki + 1) - btf__ring_phi(go, ko + 1) <= BTF__PHI_TIE_DEG;
        int a = btf__ring_vertex(d, lo, ki), c = btf__ring_vertex(d, lo + 1, ko);
        int x = inner_next ? btf__ring_vertex(d, lo, ki + 1) : btf__ring_vertex(d, lo + 1, ko + 1);
        btf__add(b, a, c, x);
        if (inner_next)
            ki++;
        else
            ko++;
    }
}

/* Fan of ring r's polygon edges to a virtual pole. */
static void btf__fan(btf__tris *b, const btf_dirset *d, int r, int pole)
{
    for (int k = 0; k < d->rings[r].count && d->rings[r].count > 1; k++)
        btf__add(b, btf__ring_vertex(d, r, k), btf__ring_vertex(d, r, k + 1), pole);
}

/* One directed edge a -> c of triangle tri; a sorted array of them, by (a, c, tri),
 * finds the triangles holding an edge without comparing every pair of triangles.
 * Values in an array owned by the function that sorted it. */
typedef struct btf__edge {
    int a, c, tri;
} btf__edge;

static int btf__edge_cmp(const void *x, const void *y)
{
    const btf__edge *p = x, *q = y;
    return p->a != q->a ? (p->a > q->a) - (p->a < q->a)
           : p->c != q->c ? (p->c > q->c) - (p->c < q->c)
                          : (p->tri > q->tri) - (p->tri < q->tri);
}

/* The 3 n_tris directed edges of t's triangles (tri[k] -> tri[k + 1]), sorted; a new
 * array the caller frees, NULL when out of memory. */
static btf__edge *btf__edges(const btf_dirtab *t)
{
    btf__edge *e = malloc(sizeof(btf__edge) * 3 * (size_t)(t->n_tris > 0 ? t->n_tris : 1));
    if (!e)
        return NULL;
    for (int i = 0; i < t->n_tris; i++)
        for (int k = 0; k < 3; k++) {
            btf__edge x = {t->tri[i][k], t->tri[i][(k + 1) % 3], i};
            e[3 * i + k] = x;
        }
    qsort(e, 3 * (size_t)t->n_tris, sizeof *e, btf__edge_cmp);
    return e;
}

/* The smallest triangle other than skip holding the directed edge a -> c in the n
 * sorted edges e; -1 when none does. */
static int btf__edge_find(const btf__edge *e, int n, int a, int c, int skip)
{
    int lo = 0, hi = n; /* first edge not below (a, c) */
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (e[mid].a < a || (e[mid].a == a && e[mid].c < c))
            lo = mid + 1;
        else
            hi = mid;
    }
    for (; lo < n && e[lo].a == a && e[lo].c == c; lo++)
        if (e[lo].tri != skip)
            return e[lo].tri;
    return -1;
}

/* Neighbour across each edge: the first triangle holding the reversed edge. */
static btf_result btf__adjacency(btf_dirtab *t, btf_error *err)
{
    btf__edge *e = btf__edges(t);
    if (!e)
        return btf_fail(err, BTF_ERR_NOMEM, "dirtab: out of memory");
    for (int i = 0; i < t->n_tris; i++)
        for (int k = 0; k < 3; k++)
            t->adj[i][k] = btf__edge_find(e, 3 * t->n_tris, t->tri[i][(k + 2) % 3], t->tri[i][(k + 1) % 3], i);
    free(e);
    return BTF_OK;
}

/* One triangle as the walk reads it: its corners and the neighbours across the edges
 * opposite them, by value. The table build copies every triangle into an array of
 * these once and walks that (one load per step instead of one per coordinate). */
typedef struct btf__rec {
    btf__v3 x, y, z;
    int adj[3];
} btf__rec;

static btf__rec btf__rec_of(const btf_dirtab *t, int i)
{
    const int *v = t->tri[i], *a = t->adj[i];
    btf__rec r = {btf__v3_of(t->vert[v[0]]), btf__v3_of(t->vert[v[1]]), btf__v3_of(t->vert[v[2]]), {a[0], a[1], a[2]}};
    return r;
}

/* Triangle i: from recs when there is one, else from t. */
static btf__rec btf__rec_at(const btf_dirtab *t, const btf__rec *recs, int i)
{
    return recs ? recs[i] : btf__rec_of(t, i);
}

/* Barycentric volumes of p in triangle r, one per corner. */
typedef struct btf__vol {
    float w0, w1, w2;
} btf__vol;

static btf__vol btf__volumes(btf__rec r, btf__v3 p)
{
    btf__vol v = {btf__det3v(p, r.y, r.z), btf__det3v(p, r.z, r.x), btf__det3v(p, r.x, r.y)};
    return v;
}

/* The corner with the smallest volume (the first of equal ones). */
static int btf__vol_least(btf__vol v)
{
    return v.w0 <= v.w1 && v.w0 <= v.w2 ? 0 : v.w1 <= v.w2 ? 1 : 2;
}

static void btf__vol_put(btf__vol v, float w[3])
{
    w[0] = v.w0, w[1] = v.w1, w[2] = v.w2;
}

/* Volume v of corner k (0..2). */
static float btf__vol_at(btf__vol v, int k)
{
    return k == 0 ? v.w0 : k == 1 ? v.w1 : v.w2;
}

/* One step of the walk in triangle r: -1 when p is inside it (the smallest volume
 * >= 0), else the neighbour across the edge facing p (-1 too at a border). */
static int btf__step(btf__rec r, btf__vol v, int k)
{
    return btf__vol_at(v, k) >= 0.0f ? -1 : k == 0 ? r.adj[0] : k == 1 ? r.adj[1] : r.adj[2];
}

/* From triangle i, steps across the edge facing p until p is inside (all volumes
 * >= 0), a border is met or `steps` run out; returns the last triangle, its volumes
 * in w. */
static int btf__walk(const btf_dirtab *t, int i, btf__v3 p, int steps, float w[3])
{
    for (int s = 0;; s++) {
        btf__rec r = btf__rec_of(t, i);
        btf__vol v = btf__volumes(r, p);
        int next = btf__step(r, v, btf__vol_least(v));
        if (next < 0 || s >= steps) {
            btf__vol_put(v, w);
            return i;
        }
        i = next;
    }
}

/* Unit direction at the centre of cell (i, j) of the octahedral hemisphere map. */
static btf__v3 btf__cell_centre(int i, int j)
{
    float u = ((float)i + 0.5f) / (float)BTF__N * 2.0f - 1.0f, v = ((float)j + 0.5f) / (float)BTF__N * 2.0f - 1.0f;
    float a = 0.5f * (u + v), b = 0.5f * (u - v), z = 1.0f - fmaxf(fabsf(u), fabsf(v));
    float n = sqrtf(a * a + b * b + z * z);
    btf__v3 p = {a / n, b / n, z / n};
    return p;
}

#define BTF__CELL_STEPS (4 * BTF__N) /* longest walk from one cell's triangle to the next's */

/* What the cell walk reads and marks, made once per table (all NULL where there was
 * no memory: then the triangles come from t and every walk runs its steps). */
typedef struct btf__walker {
    btf__rec *recs; /* n_tris walk records */
    int *seen, *at; /* per triangle: the cell (+1) whose walk last entered it, at which step */
    int *path;      /* BTF__CELL_STEPS + 1: the triangle of each step of the current walk */
} btf__walker;

/* Each cell's triangle: walked from the previous cell's, else searched. Returns 1
 * when every cell centre lies in its cell's triangle (no volume below -1e-6: the
 * hemisphere is covered), else 0; with stop, at the first cell that does not (the
 * caller refuses the table, the other cells left unset).
 * A step depends on its triangle alone, so a walk that comes back to a triangle
 * goes round that loop until its steps run out (flat or folded triangles of a
 * degenerate ring set do this, in every cell): the walk goes straight to the
 * triangle it would end in, the same table at a fraction of the steps. */
static int btf__cells_from(btf_dirtab *t, const btf__walker *wk, int stop)
{
    const btf__rec *recs = wk->recs;
    int prev = 0, covered = 1;
    btf__rec r = btf__rec_at(t, recs, 0); /* triangle prev's, kept from cell to cell */
    for (int j = 0; j < BTF__N; j++)
        for (int i = 0; i < BTF__N; i++) {
            btf__v3 p = btf__cell_centre(i, j);
            int c = prev, k, cell = j * BTF__N + i + 1; /* btf__walk from prev, r following c */
            btf__vol v = btf__volumes(r, p);
            if (btf__vol_at(v, btf__vol_least(v)) >= 0.0f) { /* in the previous cell's triangle: most cells */
                t->cell[j * BTF__N + i] = c;
                continue;
            }
            for (int s = 0;; s++) {
                if (wk->seen && wk->seen[c] == cell) { /* round a loop: its triangle at the last step */
                    int s0 = wk->at[c];
                    c = wk->path[s0 + (BTF__CELL_STEPS - s0) % (s - s0)];
                    r = btf__rec_at(t, recs, c);
                    v = btf__volumes(r, p);
                    k = btf__vol_least(v);
                    break;
                }
                if (wk->seen)
                    wk->seen[c] = cell, wk->at[c] = s, wk->path[s] = c;
                v = btf__volumes(r, p);
                int next = btf__step(r, v, k = btf__vol_least(v));
                if (next < 0 || s >= BTF__CELL_STEPS)
                    break;
                r = btf__rec_at(t, recs, c = next);
            }
            float least = btf__vol_at(v, k); /* the smallest volume of the cell's triangle */
            for (int s = 0; s < t->n_tris && btf__vol_at(v, k) < 0.0f; s++) {
                btf__rec q = btf__rec_at(t, recs, s);
                v = btf__volumes(q, p);
                if (btf__vol_at(v, k = btf__vol_least(v)) >= 0.0f)
                    c = s, least = btf__vol_at(v, k), r = q;
            }
            t->cell[j * BTF__N + i] = prev = c;
            if (least < -1e-6f) {
                covered = 0;
                if (stop)
                    return 0;
            }
        }
    return covered;
}

/* btf__cells_from with a walker for t. */
static int btf__cells(btf_dirtab *t, int stop)
{
    size_t n = (size_t)t->n_tris;
    btf__walker w = {malloc(sizeof *w.recs * n), calloc(n, sizeof(int)), malloc(sizeof(int) * n),
                     malloc(sizeof(int) * (BTF__CELL_STEPS + 1))};
    if (!w.recs || !w.seen || !w.at || !w.path) {
        free(w.recs), free(w.seen), free(w.at), free(w.path);
        w.recs = NULL, w.seen = w.at = w.path = NULL;
    }
    for (size_t s = 0; w.recs && s < n; s++)
        w.recs[s] = btf__rec_of(t, (int)s);
    int covered = btf__cells_from(t, &w, stop);
    free(w.recs), free(w.seen), free(w.at), free(w.path);
    return covered;
}

static btf_dirtab *btf__alloc(int n_dirs, int nv, int cap)
{
    size_t bytes = sizeof(btf_dirtab) + (size_t)nv * sizeof(float[4]) + (size_t)cap * 2 * sizeof(int[3]) +
                   (size_t)BTF__N * BTF__N * sizeof(int) + (size_t)nv * sizeof(int);
    btf_dirtab *t = calloc(1, bytes);
    if (!t)
        return NULL;
    t->n_dirs = n_dirs;
    t->n_verts = nv;
    t->vert = (float(*)[4])(t + 1);
    t->tri = (int(*)[3])(t->vert + nv);
    t->adj = t->tri + cap;
    t->cell = (int *)(t->adj + cap);
    t->dir = t->cell + BTF__N * BTF__N;
    return t;
}

static btf_result btf__build_rings(const btf_dirset *d, btf_dirtab **out, btf_error *err)
{
    int cap = 2 * (d->n_dirs + 2); /* a sphere of V vertices has 2V - 4 triangles */
    btf_dirtab *t = btf__alloc(d->n_dirs, d->n_dirs + 2, cap);
    if (!t)
        return btf_fail(err, BTF_ERR_NOMEM, "dirtab: out of memory");
    for (int i = 0; i < d->n_dirs; i++) {
        btf_dirset_vector(d, i, t->vert[i]);
        t->vert[i][3] = 1.0f;
        t->dir[i] = i;
    }
    float pole[2][4] = {{0, 0, 1, 0}, {0, 0, -1, 0}};
    memcpy(t->vert[d->n_dirs], pole, sizeof pole);
    t->dir[d->n_dirs] = t->dir[d->n_dirs + 1] = -1;
    btf__tris b = {t, cap};
    if (d->rings[0].count > 1)
        btf__fan(&b, d, 0, d->n_dirs); /* cap inside a ring without a pole direction */
    for (int r = 0; r + 1 < d->n_rings; r++)
        btf__band(&b, d, r);
    btf__fan(&b, d, d->n_rings - 1, d->n_dirs + 1); /* beyond the outermost ring */
    if (btf__adjacency(t, err) != BTF_OK) {
        free(t);
        return BTF_ERR_NOMEM;
    }
    if (t->n_tris > 0)
        btf__cells(t, 0);
    *out = t;
    return BTF_OK;
}

btf_result btf_dirtab_build(const btf_dirset *d, btf_dirtab **out, btf_error *err)
{
    if (!d || !out)
        return btf_fail(err, BTF_ERR_ARG, "dirtab: NULL argument");
    *out = NULL;
    if (btf_dirset_is_list(d))
        return btf_dirtab_build_list(d, NULL, 0, out, err);
    if (d->n_rings < 1 || d->n_rings > BTF_MAX_RINGS || d->n_dirs < 1 || d->n_dirs > BTF_MAX_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "dirtab: invalid direction set (%d rings, %d directions)", d->n_rings,
                        d->n_dirs);
    return btf__build_rings(d, out, err);
}

/* ---------------------------------------------------------------- list sets */

#define BTF__MIRROR_MIN_Z 1e-6f  /* a direction this close to the horizon is not mirrored */
#define BTF__CONVEX_EPS 1e-5f    /* how far outside a triangle's plane a vertex may lie */

/* Unit vector of list vertex i (list numbering: n_dirs + j is the mirror image of j). */
static void btf__list_vertex(const btf_dirset *d, int i, float v[3])
{
    btf_dirset_vector(d, i % d->n_dirs, v);
    if (i >= d->n_dirs)
        v[2] = -v[2];
}

/* qhull's triangles of the directions and their mirror images, those holding a real
 * direction, in list numbering into a new array (*n_out of them). */
static btf_result btf__list_hull(const btf_dirset *d, int (**out)[3], int *n_out, btf_error *err)
{
    int n = d->n_dirs, np = 0, cap = 4 * (2 * n + 2);
    float(*pts)[3] = malloc(sizeof(float[3]) * (size_t)(2 * n));
    int *id = malloc(sizeof(int) * (size_t)(2 * n));
    int(*tris)[3] = malloc(sizeof(int[3]) * (size_t)cap);
    btf_result r = pts && id && tris ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "dirtab: out of memory");
    for (int i = 0; i < 2 * n && r == BTF_OK; i++) {
        btf__list_vertex(d, i, pts[np]);
        if (i < n || pts[np][2] < -BTF__MIRROR_MIN_Z)
            id[np++] = i;
    }
    int nt = 0, kept = 0;
    if (r == BTF_OK)
        r = btf_hull_triangles((const float(*)[3])pts, np, tris, cap, &nt, err);
    for (int i = 0; i < nt && r == BTF_OK; i++) {
        int a = id[tris[i][0]], b = id[tris[i][1]], c = id[tris[i][2]];
        if (a < n || b < n || c < n) {
            tris[kept][0] = a, tris[kept][1] = b, tris[kept][2] = c;
            kept++;
        }
    }
    free(pts);
    free(id);
    if (r != BTF_OK) {
        free(tris);
        return r;
    }
    *out = tris;
    *n_out = kept;
    return BTF_OK;
}

/* Checks one list triangle: indices, a mirror only of a direction above the horizon. */
static btf_result btf__list_tri_ok(const btf_dirset *d, const int tri[3], int i, btf_error *err)
{
    int n = d->n_dirs, real = 0;
    for (int k = 0; k < 3; k++) {
        if (tri[k] < 0 || tri[k] >= 2 * n)
            return btf_fail(err, BTF_ERR_RANGE, "dirtab: triangle %d: vertex %d outside 0..%d", i, tri[k], 2 * n - 1);
        float v[3];
        btf__list_vertex(d, tri[k], v);
        if (tri[k] >= n && !(v[2] < -BTF__MIRROR_MIN_Z))
            return btf_fail(err, BTF_ERR_FORMAT, "dirtab: triangle %d mirrors direction %d, which is on the horizon",
                            i, tri[k] - n);
        real += tri[k] < n;
    }
    if (!real)
        return btf_fail(err, BTF_ERR_FORMAT, "dirtab: triangle %d holds no measured direction", i);
    return BTF_OK;
}

/* Vertices in table numbering: the directions, then each mirror image used (map[i]). */
static int btf__list_vertices(const btf_dirset *d, const int (*tris)[3], int n_tris, int *map)
{
    int n = d->n_dirs, nv = n;
    for (int i = 0; i < 2 * n; i++)
        map[i] = i < n ? i : -1;
    for (int i = 0; i < n_tris; i++)
        for (int k = 0; k < 3; k++)
            if (map[tris[i][k]] < 0)
                map[tris[i][k]] = nv++;
    return nv;
}

/* The plane of triangle i: its first corner a, its normal n and |n| (double). */
typedef struct btf__plane {
    btf__v3 a;
    double nx, ny, nz, len;
} btf__plane;

static btf__plane btf__plane_of(const btf_dirtab *t, int i)
{
    btf__v3 a = btf__v3_of(t->vert[t->tri[i][0]]), b = btf__v3_of(t->vert[t->tri[i][1]]),
            c = btf__v3_of(t->vert[t->tri[i][2]]);
    double u[3] = {b.x - a.x, b.y - a.y, b.z - a.z}, w[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
    btf__plane e = {a, u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0], 0.0};
    e.len = sqrt(e.nx * e.nx + e.ny * e.ny + e.nz * e.nz);
    return e;
}

/* 1 when point p lies more than BTF__CONVEX_EPS outside plane e. */
static int btf__outside(btf__plane e, btf__v3 p)
{
    double h = e.nx * (p.x - e.a.x) + e.ny * (p.y - e.a.y) + e.nz * (p.z - e.a.z);
    return h > BTF__CONVEX_EPS * e.len;
}

/* The first triangle before i holding one of i's directed edges, -1 when none does
 * (e: the sorted edges of all n_tris triangles). */
static int btf__shared_edge(const btf_dirtab *t, const btf__edge *e, int i)
{
    int first = -1;
    for (int k = 0; k < 3; k++) {
        int j = btf__edge_find(e, 3 * t->n_tris, t->tri[i][k], t->tri[i][(k + 1) % 3], -1);
        if (j >= 0 && j < i && (first < 0 || j < first))
            first = j;
    }
    return first;
}

/* Orientation, each directed edge once, and convexity (what makes the walk and the
 * interpolation well defined whoever wrote the triangles). */
static btf_result btf__list_shape_ok(const btf_dirtab *t, btf_error *err)
{
    btf__edge *e = btf__edges(t);
    if (!e)
        return btf_fail(err, BTF_ERR_NOMEM, "dirtab: out of memory");
    btf_result r = BTF_OK;
    for (int i = 0; i < t->n_tris && r == BTF_OK; i++) {
        const int *a = t->tri[i];
        int j = -1;
        if (!(btf__det3(t->vert[a[0]], t->vert[a[1]], t->vert[a[2]]) > 0.0f))
            r = btf_fail(err, BTF_ERR_FORMAT, "dirtab: triangle %d is flat or clockwise seen from outside", i);
        btf__plane pl = btf__plane_of(t, i);
        for (int v = 0; v < t->n_verts && r == BTF_OK; v++)
            if (btf__outside(pl, btf__v3_of(t->vert[v])))
                r = btf_fail(err, BTF_ERR_FORMAT, "dirtab: triangle %d is not on the convex hull (vertex %d outside)",
                             i, v);
        if (r == BTF_OK && (j = btf__shared_edge(t, e, i)) >= 0)
            r = btf_fail(err, BTF_ERR_FORMAT, "dirtab: triangles %d and %d share an edge the same way", j, i);
    }
    free(e);
    return r;
}

/* Every edge touching a measured direction has a neighbour: the kept triangles end only
 * between mirror images, below the horizon (no hole a file could cut). */
static btf_result btf__list_closed(const btf_dirtab *t, btf_error *err)
{
    for (int i = 0; i < t->n_tris; i++)
        for (int e = 0; e < 3; e++) {
            int a = t->tri[i][(e + 1) % 3], b = t->tri[i][(e + 2) % 3];
            if (t->adj[i][e] < 0 && (a < t->n_dirs || b < t->n_dirs))
                return btf_fail(err, BTF_ERR_FORMAT,
                                "dirtab: triangle %d's edge %d-%d has no neighbour: the triangles do not cover the "
                                "hemisphere", i, a, b);
        }
    return BTF_OK;
}

/* The table of checked list-numbered triangles. */
static btf_result btf__list_table(const btf_dirset *d, const int (*tris)[3], int n_tris, btf_dirtab **out,
                                  btf_error *err)
{
    int n = d->n_dirs, *map = malloc(sizeof(int) * (size_t)(2 * n));
    if (!map)
        return btf_fail(err, BTF_ERR_NOMEM, "dirtab: out of memory");
    int nv = btf__list_vertices(d, tris, n_tris, map);
    btf_dirtab *t = btf__alloc(n, nv, n_tris);
    if (!t) {
        free(map);
        return btf_fail(err, BTF_ERR_NOMEM, "dirtab: out of memory");
    }
    for (int i = 0; i < 2 * n; i++)
        if (map[i] >= 0) {
            btf__list_vertex(d, i, t->vert[map[i]]);
            t->vert[map[i]][3] = 1.0f;
            t->dir[map[i]] = i % n;
        }
    for (int i = 0; i < n_tris; i++)
        for (int k = 0; k < 3; k++)
            t->tri[i][k] = map[tris[i][k]];
    t->n_tris = n_tris;
    free(map);
    btf_result r = btf__list_shape_ok(t, err);
    if (r == BTF_OK)
        r = btf__adjacency(t, err);
    if (r == BTF_OK)
        r = btf__list_closed(t, err);
    if (r == BTF_OK && !btf__cells(t, 1))
        r = btf_fail(err, BTF_ERR_FORMAT, "dirtab: the triangles do not cover the upper hemisphere");
    if (r != BTF_OK) {
        free(t);
        return r;
    }
    *out = t;
    return BTF_OK;
}

btf_result btf_dirtab_build_list(const btf_dirset *d, const int (*tris)[3], int n_tris, btf_dirtab **out,
                                 btf_error *err)
{
    if (!d || !out || (!tris && n_tris))
        return btf_fail(err, BTF_ERR_ARG, "dirtab: NULL argument");
    *out = NULL;
    if (!btf_dirset_is_list(d) || d->n_dirs < 3 || d->n_dirs > BTF_MAX_LIST_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "dirtab: not a list set of 3..%d directions", BTF_MAX_LIST_DIRS);
    int(*own)[3] = NULL;
    if (!tris) {
        btf_result r = btf__list_hull(d, &own, &n_tris, err);
        if (r != BTF_OK)
            return r;
        tris = (const int(*)[3])own;
    }
    btf_result r = BTF_OK;
    if (n_tris < 1 || n_tris > 4 * (2 * d->n_dirs + 2))
        r = btf_fail(err, BTF_ERR_RANGE, "dirtab: %d triangles for %d directions", n_tris, d->n_dirs);
    for (int i = 0; i < n_tris && r == BTF_OK; i++)
        r = btf__list_tri_ok(d, tris[i], i, err);
    if (r == BTF_OK)
        r = btf__list_table(d, tris, n_tris, out, err);
    free(own);
    return r;
}

int btf_dirtab_list_tris(const btf_dirtab *t, int (*out)[3], int cap)
{
    if (!t || t->n_verts < 1 || t->dir[t->n_verts - 1] < 0)
        return 0; /* a ring table ends with its virtual poles */
    for (int i = 0; i < t->n_tris && i < cap; i++)
        for (int k = 0; k < 3; k++) {
            int v = t->tri[i][k];
            out[i][k] = v < t->n_dirs ? v : t->n_dirs + t->dir[v];
        }
    return t->n_tris;
}

void btf_dirtab_free(btf_dirtab *t) { free(t); }

int btf_dirtab_cell_of(const float v[3])
{
    float z = fmaxf(v[2], 0.0f), s = fabsf(v[0]) + fabsf(v[1]) + z;
    float a = s > 0.0f ? v[0] / s : 0.0f, b = s > 0.0f ? v[1] / s : 0.0f;
    int i = (int)floorf((a + b + 1.0f) * 0.5f * (float)BTF__N), j = (int)floorf((a - b + 1.0f) * 0.5f * (float)BTF__N);
    i = i < 0 ? 0 : i >= BTF__N ? BTF__N - 1 : i;
    j = j < 0 ? 0 : j >= BTF__N ? BTF__N - 1 : j;
    return j * BTF__N + i;
}

/* The query as a unit vector: NaN, Inf or zero -> the normal; below the horizon ->
 * the horizon at the same azimuth (straight down: phi 0), as btf_dirset_interp_vec. */
static void btf__query(const float v[3], float p[3])
{
    float m = fmaxf(fabsf(v[0]), fmaxf(fabsf(v[1]), fabsf(v[2])));
    if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]) || !(m > 0.0f)) {
        p[0] = p[1] = 0.0f, p[2] = 1.0f;
        return;
    }
    float x = v[0] / m, y = v[1] / m, z = fmaxf(v[2] / m, 0.0f);
    if (x == 0.0f && y == 0.0f && z == 0.0f)
        x = 1.0f;
    float n = sqrtf(x * x + y * y + z * z);
    p[0] = x / n, p[1] = y / n, p[2] = z / n;
}

btf_interp btf_dirtab_interp_vec(const btf_dirtab *t, const float v[3])
{
    btf_interp r = {{0, 0, 0}, {1.0f, 0.0f, 0.0f}};
    if (!t || !v || t->n_tris < 1)
        return r;
    float p[3], w[3];
    btf__query(v, p);
    int i = btf__walk(t, t->cell[btf_dirtab_cell_of(p)], btf__v3_of(p), BTF_DIRTAB_MAX_STEPS, w);
    int first = -1;
    float s = 0.0f;
    for (int k = 0; k < 3; k++) {
        int vk = t->tri[i][k];
        w[k] = fmaxf(w[k], 0.0f) * t->vert[vk][3]; /* a virtual pole's weight is dropped */
        s += w[k];
        if (first < 0 && t->vert[vk][3] > 0.0f)
            first = vk;
    }
    for (int k = 0; k < 3; k++) {
        int vk = t->tri[i][k];
        r.idx[k] = t->dir[t->vert[vk][3] > 0.0f ? vk : first];
        r.w[k] = s > 1e-30f ? w[k] / s : (vk == first ? 1.0f : 0.0f);
    }
    if (!(s > 1e-30f)) /* a query at a virtual pole: all weight to the first real vertex */
        r.w[0] = 1.0f, r.w[1] = r.w[2] = 0.0f, r.idx[0] = t->dir[first];
    return r;
}
