/* btf_hull.c - convex hulls through qhull's reentrant library (btf_hull.h). */
#define _POSIX_C_SOURCE 200809L /* open_memstream: qhull's messages go to err, not stderr */
#include "btf_hull.h"
#include "btf_common.h"

#include <libqhull_r/qhull_ra.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define BTF__HULL_MAX_POINTS 8192
#define BTF__INSIDE_EPS 1e-6 /* the origin must be this far inside every facet's plane */

/* (b - a) x (c - a) . a > 0: counter-clockwise seen from outside (origin inside). */
static int btf__ccw(const float (*p)[3], const int t[3])
{
    const float *a = p[t[0]], *b = p[t[1]], *c = p[t[2]];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    return n[0] * a[0] + n[1] * a[1] + n[2] * a[2] > 0.0;
}

/* The facets of a finished hull into tris; fails when the origin is not inside. */
static btf_result btf__facets(qhT *qh, const float (*pts)[3], int (*tris)[3], int cap, int *n_tris, btf_error *err)
{
    facetT *facet;
    vertexT *vertex, **vertexp;
    int nt = 0;
    FORALLfacets {
        if (facet->offset > -BTF__INSIDE_EPS)
            return btf_fail(err, BTF_ERR_RANGE,
                            "hull: the directions do not surround the normal (a facet passes %g from the centre)",
                            -facet->offset);
        if (nt >= cap)
            return btf_fail(err, BTF_ERR_RANGE, "hull: more than %d triangles", cap);
        int k = 0;
        FOREACHvertex_(facet->vertices) if (k < 3) tris[nt][k++] = qh_pointid(qh, vertex->point);
        if (k != 3)
            continue;
        if (!btf__ccw(pts, tris[nt])) {
            int x = tris[nt][1];
            tris[nt][1] = tris[nt][2];
            tris[nt][2] = x;
        }
        nt++;
    }
    *n_tris = nt;
    return BTF_OK;
}

btf_result btf_hull_triangles(const float (*pts)[3], int n, int (*tris)[3], int cap, int *n_tris, btf_error *err)
{
    if (!pts || !tris || !n_tris)
        return btf_fail(err, BTF_ERR_ARG, "hull: NULL argument");
    *n_tris = 0;
    if (n < 4 || n > BTF__HULL_MAX_POINTS)
        return btf_fail(err, BTF_ERR_RANGE, "hull: %d points, expected 4..%d", n, BTF__HULL_MAX_POINTS);
    coordT *xyz = malloc(sizeof(coordT) * 3 * (size_t)n);
    char *log = NULL;
    size_t log_len = 0;
    FILE *errfile = open_memstream(&log, &log_len);
    if (!xyz || !errfile) {
        free(xyz);
        if (errfile)
            fclose(errfile);
        free(log);
        return btf_fail(err, BTF_ERR_NOMEM, "hull: out of memory");
    }
    for (int i = 0; i < 3 * n; i++)
        xyz[i] = pts[i / 3][i % 3];
    qhT qh_qh, *qh = &qh_qh;
    qh_zero(qh, errfile);
    char cmd[] = "qhull Qt";
    int code = qh_new_qhull(qh, 3, n, xyz, False, cmd, NULL, errfile);
    btf_result r = BTF_OK;
    if (code != 0) {
        fflush(errfile);
        const char *m = log && log_len ? log : "";
        const char *nl = strchr(m, '\n');
        r = btf_fail(err, BTF_ERR_RANGE, "hull: qhull failed (code %d; the directions may be flat): %.*s", code,
                     nl ? (int)(nl - m) : (int)strlen(m), m);
    } else {
        r = btf__facets(qh, pts, tris, cap, n_tris, err);
    }
    int curlong = 0, totlong = 0;
    qh_freeqhull(qh, !qh_ALL);
    qh_memfreeshort(qh, &curlong, &totlong);
    fclose(errfile);
    free(log);
    free(xyz);
    return r;
}
