/* btf_dirset_list.c - btf_dirset_make_list: a list set from {theta, phi} pairs,
 * checked by triangulating it (btf_dirtab.h). It sits above btf_dirset.c and
 * btf_dirtab.c both, since the triangulation reads the set's directions. */
#include "btf.h"
#include "btf_dirtab.h"
#include "btf_common.h"

#include <math.h>
#include <string.h>

#define BTF__PI 3.14159265358979323846
#define BTF__LIST_MIN_SEP_DEG 0.01 /* two listed directions closer than this are one */

/* Angle in degrees between list directions i and j (double, acos-free). */
static double btf__list_sep(const btf_dirset *d, int i, int j)
{
    float a[3], b[3];
    btf_dirset_vector(d, i, a);
    btf_dirset_vector(d, j, b);
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    double dot = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
    return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), dot) * (180.0 / BTF__PI);
}

btf_result btf_dirset_make_list(const float (*dirs)[2], int n, btf_dirset *out, btf_error *err)
{
    if (!dirs || !out)
        return btf_fail(err, BTF_ERR_ARG, "dirset: NULL argument");
    if (n < 3 || n > BTF_MAX_LIST_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "dirset: %d listed directions, expected 3..%d", n, BTF_MAX_LIST_DIRS);
    memset(out, 0, sizeof *out);
    for (int i = 0; i < n; i++) {
        float t = dirs[i][0], p = dirs[i][1];
        if (!isfinite(t) || !isfinite(p) || t < 0.0f || t > 90.0f || fabsf(p) > 1e6f)
            return btf_fail(err, BTF_ERR_RANGE, "dirset: direction %d (theta %g, phi %g) outside theta 0..90", i,
                            (double)t, (double)p);
        p = fmodf(p, 360.0f);
        out->list[i][0] = t;
        out->list[i][1] = t == 0.0f ? 0.0f : p < 0.0f ? p + 360.0f : p;
    }
    out->n_dirs = n;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++)
            if (btf__list_sep(out, i, j) < BTF__LIST_MIN_SEP_DEG)
                return btf_fail(err, BTF_ERR_FORMAT, "dirset: directions %d and %d coincide (theta %g, phi %g)", j, i,
                                (double)out->list[i][0], (double)out->list[i][1]);
    btf_dirtab *t = NULL;
    btf_error inner = {{0}};
    btf_result r = btf_dirtab_build(out, &t, &inner);
    if (r != BTF_OK)
        return btf_fail(err, r, "dirset: %d listed directions do not triangulate: %s", n, inner.msg);
    btf_interp_keep_list(out, t); /* the table the set's first interpolation needs */
    return BTF_OK;
}
