/* btf_gltf_tangent.c - tangents of a triangle mesh by the MikkTSpace convention
 * (btf_gltf.h, btf_gltf_tangents): the tangent follows increasing u and
 * w * cross(normal, tangent) decreasing v (towards image row 0: glTF's bitangent,
 * the BTF's local y of shaders/btf_render.vert). On glTF's uvs (v along image rows)
 * that is MikkTSpace's sign negated, as glTF readers apply it. */
#include "btf_gltf.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "btf_common.h"

#define F BTF_RENDER_VERTEX_FLOATS
#define BTF__UV_AREA_MIN 1e-20 /* |2 x uv area| below this: no u direction (a degenerate triangle) */

/* Per triangle the handedness w (0 when degenerate in uv) and the unit direction of
 * increasing u in its plane. With r twice the signed uv area, the bitangent towards
 * increasing v is w * cross(n, t) for w = sign(r) (MikkTSpace); towards decreasing
 * v, the one wanted here, w = -sign(r). */
static int btf__face(const float *v, const unsigned *t, double tu[3])
{
    const float *a = v + (size_t)t[0] * F, *b = v + (size_t)t[1] * F, *c = v + (size_t)t[2] * F;
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++)
        e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
    double du1 = (double)b[10] - a[10], dv1 = (double)b[11] - a[11];
    double du2 = (double)c[10] - a[10], dv2 = (double)c[11] - a[11];
    double r = du1 * dv2 - du2 * dv1;
    if (fabs(r) < BTF__UV_AREA_MIN)
        return 0;
    double l = 0;
    for (int k = 0; k < 3; k++) {
        tu[k] = (e1[k] * dv2 - e2[k] * dv1) / r;
        l += tu[k] * tu[k];
    }
    l = sqrt(l);
    if (!(l > 0) || !isfinite(l))
        return 0;
    for (int k = 0; k < 3; k++)
        tu[k] /= l;
    return r > 0 ? -1 : 1;
}

/* Angle at corner k of triangle t (radians). */
static double btf__corner_angle(const float *v, const unsigned *t, int k)
{
    const float *p = v + (size_t)t[k] * F, *q = v + (size_t)t[(k + 1) % 3] * F, *s = v + (size_t)t[(k + 2) % 3] * F;
    double a[3], b[3], d = 0, la = 0, lb = 0;
    for (int c = 0; c < 3; c++) {
        a[c] = (double)q[c] - p[c], b[c] = (double)s[c] - p[c];
        d += a[c] * b[c], la += a[c] * a[c], lb += b[c] * b[c];
    }
    if (!(la > 0) || !(lb > 0))
        return 0.0;
    double cs = d / sqrt(la * lb);
    return acos(cs > 1 ? 1 : cs < -1 ? -1 : cs);
}

/* Any unit vector orthogonal to unit n (for a vertex no triangle gave a u direction). */
static void btf__any_tangent(const float n[3], double t[3])
{
    double a[3] = {fabsf(n[0]) < 0.9f ? 1.0 : 0.0, fabsf(n[0]) < 0.9f ? 0.0 : 1.0, 0.0};
    double d = a[0] * n[0] + a[1] * n[1];
    double l = 0;
    for (int k = 0; k < 3; k++) {
        t[k] = a[k] - d * n[k];
        l += t[k] * t[k];
    }
    l = sqrt(l);
    for (int k = 0; k < 3; k++)
        t[k] /= l;
}

/* The vertex of (original vertex i, handedness slot s) in the grown mesh, made on first use. */
static unsigned btf__slot(int *slot, unsigned i, int s, int *n_new, int n_old)
{
    int *x = &slot[2 * (size_t)i + s];
    if (*x < 0)
        *x = slot[2 * (size_t)i + (1 - s)] < 0 ? (int)i : n_old + (*n_new)++;
    return (unsigned)*x;
}

btf_result btf_gltf_tangents(btf_render_mesh *m, btf_error *err)
{
    int nv = m->n_vertices, ni = m->n_indices, nt = ni / 3;
    int *slot = malloc((size_t)nv * 2 * sizeof(int));
    signed char *hand = malloc((size_t)nt + 1);
    double *tu = malloc(((size_t)nt * 3 + 1) * sizeof(double));
    if (!slot || !hand || !tu) {
        free(slot), free(hand), free(tu);
        return btf_fail(err, BTF_ERR_NOMEM, "tangents: out of memory (%d vertices)", nv);
    }
    for (int i = 0; i < 2 * nv; i++)
        slot[i] = -1;
    int n_new = 0;
    /* handedness per triangle; each corner's vertex gets the slot of its handedness
     * (a degenerate triangle joins whichever slot its vertex already has) */
    for (int t = 0; t < nt; t++)
        hand[t] = (signed char)btf__face(m->vertices, m->indices + 3 * t, tu + 3 * t);
    for (int pass = 0; pass < 2; pass++)
        for (int t = 0; t < nt; t++) {
            if ((hand[t] == 0) != (pass == 1))
                continue;
            for (int k = 0; k < 3; k++) {
                unsigned i = m->indices[3 * t + k];
                int s = hand[t] < 0;
                if (hand[t] == 0 && slot[2 * (size_t)i] < 0 && slot[2 * (size_t)i + 1] >= 0)
                    s = 1;
                m->indices[3 * t + k] = btf__slot(slot, i, s, &n_new, nv);
            }
        }
    float *v = m->vertices;
    if (n_new > 0) {
        v = realloc(m->vertices, ((size_t)nv + n_new) * F * sizeof(float));
        if (!v) {
            free(slot), free(hand), free(tu);
            return btf_fail(err, BTF_ERR_NOMEM, "tangents: out of memory (%d vertices)", nv + n_new);
        }
        for (int i = 0; i < nv; i++)
            for (int s = 0; s < 2; s++)
                if (slot[2 * (size_t)i + s] >= nv)
                    memcpy(v + (size_t)slot[2 * (size_t)i + s] * F, v + (size_t)i * F, F * sizeof(float));
        m->vertices = v, m->n_vertices = nv + n_new;
    }
    int n = m->n_vertices;
    double *acc = calloc((size_t)n * 3 + 1, sizeof(double));
    signed char *w = malloc((size_t)n + 1);
    if (!acc || !w) {
        free(slot), free(hand), free(tu), free(acc), free(w);
        return btf_fail(err, BTF_ERR_NOMEM, "tangents: out of memory (%d vertices)", n);
    }
    memset(w, 1, (size_t)n);
    for (int t = 0; t < nt; t++) {
        if (hand[t] == 0)
            continue;
        for (int k = 0; k < 3; k++) {
            unsigned i = m->indices[3 * t + k];
            const float *nv3 = v + (size_t)i * F + 3;
            const double *d = tu + 3 * t;
            double dn = d[0] * nv3[0] + d[1] * nv3[1] + d[2] * nv3[2], p[3], l = 0;
            for (int c = 0; c < 3; c++) {
                p[c] = d[c] - dn * nv3[c];
                l += p[c] * p[c];
            }
            if (!(l > 1e-24))
                continue;
            double a = btf__corner_angle(v, m->indices + 3 * t, k) / sqrt(l);
            for (int c = 0; c < 3; c++)
                acc[3 * (size_t)i + c] += a * p[c];
            w[i] = hand[t];
        }
    }
    for (int i = 0; i < n; i++) {
        float *q = v + (size_t)i * F;
        double *a = acc + 3 * (size_t)i, dn = a[0] * q[3] + a[1] * q[4] + a[2] * q[5], l = 0;
        for (int c = 0; c < 3; c++) {
            a[c] -= dn * q[3 + c];
            l += a[c] * a[c];
        }
        if (l > 1e-24)
            for (int c = 0; c < 3; c++)
                a[c] /= sqrt(l);
        else
            btf__any_tangent(q + 3, a);
        for (int c = 0; c < 3; c++)
            q[6 + c] = (float)a[c];
        q[9] = (float)w[i];
    }
    free(slot), free(hand), free(tu), free(acc), free(w);
    return BTF_OK;
}
