/* btf_dirtab.h - a direction set as an explicit spherical triangulation with a
 * lookup table: angular interpolation in O(1) (one table read, one triangle test,
 * rarely a step or two to a neighbour), the layout the GPU decoder reads
 * (shaders/btf_dirs.glsl; doc/data-model.md, "Direction tables").
 *
 *     btf_dirtab *t = NULL;
 *     if (btf_dirtab_build(&set, &t, &err) != BTF_OK) ...;
 *     float v[3] = {0.3f, 0.1f, 0.9f};
 *     btf_interp in = btf_dirtab_interp_vec(t, v);   // same triangles as btf_dirset_interp
 *     btf_dirtab_free(t);
 *
 * Ring sets: vertices 0..n_dirs-1 are the set's directions (canonical order); two
 * virtual vertices follow, the north pole (n_dirs) and the south pole (n_dirs + 1):
 * a virtual vertex's weight is dropped and the real weights renormalised, which is
 * exactly the azimuth blend the ring algorithm uses inside a ring without a pole
 * direction and beyond the outermost ring. Every triangle is the ring algorithm's
 * (zipper bands, caps).
 * List sets: the triangles are the convex hull (qhull) of the directions and their
 * mirror images (x, y, -z), those with at least one real direction; vertices
 * 0..n_dirs-1 are the directions, then the mirror images the triangles use, whose
 * weight goes to the direction they mirror. Continuous by construction, defined
 * between the outermost directions and the horizon, and below it.
 * Triangles are counter-clockwise seen from outside.
 */
#ifndef BTF_DIRTAB_H
#define BTF_DIRTAB_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_DIRTAB_CELLS 64     /* the lookup table is CELLS x CELLS over the upper hemisphere */
#define BTF_DIRTAB_MAX_STEPS 8  /* longest walk from a cell's triangle to the query's */

/* Triangulated direction set plus lookup table. Made by btf_dirtab_build (one
 * allocation), freed by btf_dirtab_free; immutable in between. */
typedef struct btf_dirtab {
    int n_dirs;      /* real directions */
    int n_verts;     /* rings: n_dirs + 2 (the virtual poles); lists: n_dirs + mirror images */
    int n_tris;
    float (*vert)[4];/* n_verts: unit x, y, z; w = 1 weighted, 0 virtual */
    int *dir;        /* n_verts: the direction a vertex's weight goes to, -1 virtual */
    int (*tri)[3];   /* n_tris: vertex indices, counter-clockwise from outside */
    int (*adj)[3];   /* n_tris: triangle across the edge opposite vertex i, -1 none */
    int *cell;       /* CELLS x CELLS: a triangle containing the cell's centre direction */
} btf_dirtab;

/* Triangulates d (zipper bands between rings, a cap inside a ring without a pole
 * direction, a fan to the south pole beyond the outermost ring) and fills the table. */
btf_result btf_dirtab_build(const btf_dirset *d, btf_dirtab **out, btf_error *err);
void btf_dirtab_free(btf_dirtab *t);

/* A list set's table from given triangles in list numbering (index i < n_dirs: direction
 * i; n_dirs + i: the mirror image of direction i), e.g. read from a package manifest.
 * Checks what a hostile file could break: indices, orientation, each directed edge
 * once, convexity (no vertex outside a triangle's plane), every table cell covered. */
btf_result btf_dirtab_build_list(const btf_dirset *d, const int (*tris)[3], int n_tris, btf_dirtab **out,
                                 btf_error *err);
/* A list set's triangles in list numbering into out[0..cap-1]; returns the count
 * (which may exceed cap: then only cap are written), 0 for a ring set. */
int btf_dirtab_list_tris(const btf_dirtab *t, int (*out)[3], int cap);

/* Table cell of a direction (any length; z < 0 is taken as z = 0): the octahedral
 * map of the upper hemisphere, u = a + b, v = a - b with (a, b) = (x, y) / (|x| + |y| + z),
 * cell (floor((u + 1) / 2 * CELLS), floor((v + 1) / 2 * CELLS)) clamped; returns y * CELLS + x. */
int btf_dirtab_cell_of(const float v[3]);

/* Interpolation of a direction vector in the local frame (z = normal, need not be
 * unit; NaN, Inf or zero = the normal; z < 0 = the horizon at the same azimuth). */
btf_interp btf_dirtab_interp_vec(const btf_dirtab *t, const float v[3]);

#ifdef __cplusplus
}
#endif
#endif
