/* btf_hull.h - the convex hull of a point set in 3-D as triangles (qhull, option Qt):
 * the one place the codec calls qhull.
 *
 *     int (*tris)[3] = malloc(sizeof(int[3]) * (size_t)(2 * n));
 *     int nt = 0;
 *     if (btf_hull_triangles(pts, n, tris, 2 * n, &nt, &err) != BTF_OK) ...;
 */
#ifndef BTF_HULL_H
#define BTF_HULL_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Triangulates the convex hull of pts[0..n-1] (4 <= n <= 8192) into at most cap
 * triangles of point indices, each counter-clockwise seen from outside. Fails
 * (BTF_ERR_RANGE, naming the cause) when the points are flat or the origin is not
 * strictly inside the hull; qhull's own message, if any, is in err, never printed. */
btf_result btf_hull_triangles(const float (*pts)[3], int n, int (*tris)[3], int cap, int *n_tris, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
