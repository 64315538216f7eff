/* btf_dirset.c - direction sets as rings or explicit lists: ring construction, built-ins,
 * lookups (a list set is built and checked in btf_dirset_list.c). */
#include "btf.h"
#include "btf_common.h"

#include <math.h>
#include <string.h>

#define BTF__PI 3.14159265358979323846

btf_result btf_dirset_make(const btf_ring *rings, int n_rings, btf_dirset *out, btf_error *err)
{
    if (!rings || !out)
        return btf_fail(err, BTF_ERR_ARG, "dirset: NULL argument");
    if (n_rings < 1 || n_rings > BTF_MAX_RINGS)
        return btf_fail(err, BTF_ERR_RANGE, "dirset: %d rings, expected 1..%d", n_rings, BTF_MAX_RINGS);
    memset(out, 0, sizeof *out);
    int total = 0;
    for (int r = 0; r < n_rings; r++) {
        const btf_ring *g = &rings[r];
        if (!isfinite(g->theta_deg) || !isfinite(g->phi_offset_deg) || g->theta_deg < 0.0f || g->theta_deg > 90.0f)
            return btf_fail(err, BTF_ERR_RANGE, "dirset: ring %d theta %g outside 0..90", r, (double)g->theta_deg);
        if (g->count < 1 || g->count > BTF_MAX_DIRS)
            return btf_fail(err, BTF_ERR_RANGE, "dirset: ring %d count %d invalid", r, g->count);
        if (r > 0 && !(g->theta_deg > rings[r - 1].theta_deg))
            return btf_fail(err, BTF_ERR_FORMAT, "dirset: ring thetas must ascend (ring %d)", r);
        if (g->theta_deg == 0.0f && g->count != 1)
            return btf_fail(err, BTF_ERR_FORMAT, "dirset: the pole ring must hold exactly 1 direction");
        if (total + g->count > BTF_MAX_DIRS)
            return btf_fail(err, BTF_ERR_RANGE, "dirset: more than %d directions", BTF_MAX_DIRS);
        out->rings[r] = *g;
        out->rings[r].phi_offset_deg = fmodf(g->phi_offset_deg, 360.0f);
        if (out->rings[r].phi_offset_deg < 0.0f)
            out->rings[r].phi_offset_deg += 360.0f;
        out->ring_start[r] = total;
        total += g->count;
    }
    out->n_rings = n_rings;
    out->n_dirs = total;
    return BTF_OK;
}

btf_dirset btf_dirset_ubo2003(void)
{
    static const btf_ring r[6] = {{0, 1, 0}, {15, 6, 0}, {30, 12, 0}, {45, 18, 0}, {60, 20, 0}, {75, 24, 0}};
    btf_dirset d;
    btf_dirset_make(r, 6, &d, NULL);
    return d;
}

btf_dirset btf_dirset_dome151(void)
{
    static const btf_ring r[10] = {{0, 1, 0},       {11, 6, 15},     {23.5f, 12, 0}, {30, 12, 15},
                                   {37.5f, 12, 0},  {45, 18, 0},     {52.5f, 18, 7.5f}, {60, 24, 0},
                                   {67.5f, 24, 7.5f}, {75, 24, 0}};
    btf_dirset d;
    btf_dirset_make(r, 10, &d, NULL);
    return d;
}

static int btf__ring_of(const btf_dirset *d, int i)
{
    int r = 0;
    while (r + 1 < d->n_rings && d->ring_start[r + 1] <= i)
        r++;
    return r;
}

void btf_dirset_angles(const btf_dirset *d, int i, float *theta_deg, float *phi_deg)
{
    if (btf_dirset_is_list(d)) {
        *theta_deg = d->list[i][0];
        *phi_deg = d->list[i][1];
        return;
    }
    int r = btf__ring_of(d, i);
    const btf_ring *g = &d->rings[r];
    *theta_deg = g->theta_deg;
    float p = g->phi_offset_deg + (float)(i - d->ring_start[r]) * (360.0f / (float)g->count);
    *phi_deg = p >= 360.0f ? p - 360.0f : p;
}

void btf_dirset_vector(const btf_dirset *d, int i, float v[3])
{
    float t, p;
    btf_dirset_angles(d, i, &t, &p);
    double tr = t * (BTF__PI / 180.0), pr = p * (BTF__PI / 180.0);
    v[0] = (float)(sin(tr) * cos(pr));
    v[1] = (float)(sin(tr) * sin(pr));
    v[2] = (float)cos(tr);
}

int btf_dirset_find(const btf_dirset *d, float theta_deg, float phi_deg, float tol_deg)
{
    for (int i = 0; i < d->n_dirs; i++) {
        float t, p;
        btf_dirset_angles(d, i, &t, &p);
        if (fabsf(t - theta_deg) > tol_deg)
            continue;
        if (t == 0.0f)
            return i; /* the pole has every phi */
        float dp = fmodf(fabsf(p - phi_deg), 360.0f);
        if (dp > 180.0f)
            dp = 360.0f - dp;
        if (dp <= tol_deg)
            return i;
    }
    return -1;
}

float btf_dirset_max_theta(const btf_dirset *d)
{
    if (!btf_dirset_is_list(d))
        return d->n_rings > 0 ? d->rings[d->n_rings - 1].theta_deg : 0.0f;
    float m = 0.0f;
    for (int i = 0; i < d->n_dirs; i++)
        m = fmaxf(m, d->list[i][0]);
    return m;
}

int btf_dirset_equal(const btf_dirset *a, const btf_dirset *b)
{
    if (a->n_rings != b->n_rings || a->n_dirs != b->n_dirs)
        return 0;
    for (int i = 0; i < a->n_dirs && btf_dirset_is_list(a); i++)
        if (fabsf(a->list[i][0] - b->list[i][0]) > 1e-4f || fabsf(a->list[i][1] - b->list[i][1]) > 1e-4f)
            return 0;
    for (int r = 0; r < a->n_rings; r++)
        if (a->rings[r].count != b->rings[r].count || fabsf(a->rings[r].theta_deg - b->rings[r].theta_deg) > 1e-4f ||
            fabsf(a->rings[r].phi_offset_deg - b->rings[r].phi_offset_deg) > 1e-4f)
            return 0;
    return 1;
}
