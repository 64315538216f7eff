/* bench_dirlist.c - direction lists (doc/data-model.md 2.1, 3.4.1) against the ring
 * fast path, in one process: the time to build a list's table (qhull hull plus the
 * reader's checks) for 151..1024 directions, and the cost per interpolation query of
 * the dome's 151 directions as a list against the same directions as rings (CPU
 * seconds; the ratio is the figure to quote). Output: `name value unit` lines.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "bench_util.h"
#include "btf.h"
#include "btf_dirtab.h"

static unsigned rng = 4711u;
static double urand(void) /* xorshift32 in [0, 1) */
{
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return (double)(rng >> 8) / 16777216.0;
}

/* n directions uniform by area down to 85 degrees. */
static int random_list(int n, btf_dirset *d)
{
    static float dirs[BTF_MAX_LIST_DIRS][2];
    for (int tries = 0; tries < 20; tries++) {
        for (int i = 0; i < n; i++) {
            dirs[i][0] = (float)(acos(1.0 - urand() * (1.0 - cos(85.0 * 0.017453292519943295))) * 57.29577951308232);
            dirs[i][1] = (float)(360.0 * urand());
        }
        if (btf_dirset_make_list((const float(*)[2])dirs, n, d, NULL) == BTF_OK)
            return 0;
    }
    return -1;
}

/* CPU seconds per query of n_q random queries through table t; sink keeps them live. */
static double per_query(const btf_dirtab *t, int n_q, double *sink)
{
    double t0 = cpu_s();
    for (int q = 0; q < n_q; q++) {
        float v[3] = {(float)(urand() * 2 - 1), (float)(urand() * 2 - 1), (float)urand()};
        btf_interp in = btf_dirtab_interp_vec(t, v);
        *sink += in.w[0] + in.idx[1];
    }
    return (cpu_s() - t0) / n_q;
}

int main(void)
{
    static btf_dirset d;
    const int sizes[4] = {151, 300, 600, 1024};
    for (int k = 0; k < 4; k++) {
        if (random_list(sizes[k], &d) != 0)
            return 1;
        btf_dirtab *t = NULL;
        double t0 = cpu_s();
        int reps = sizes[k] > 600 ? 1 : 3;
        for (int r = 0; r < reps; r++) {
            btf_dirtab_free(t);
            if (btf_dirtab_build(&d, &t, NULL) != BTF_OK)
                return 1;
        }
        printf("list_table_build_%d %.4f s (%d triangles, %d vertices with mirror images)\n", sizes[k],
               (cpu_s() - t0) / reps, t->n_tris, t->n_verts);
        btf_dirtab_free(t);
    }
    btf_dirset ring = btf_dirset_dome151();
    float dirs[151][2];
    for (int i = 0; i < 151; i++)
        btf_dirset_angles(&ring, i, &dirs[i][0], &dirs[i][1]);
    if (btf_dirset_make_list((const float(*)[2])dirs, 151, &d, NULL) != BTF_OK)
        return 1;
    btf_dirtab *tr = NULL, *tl = NULL;
    if (btf_dirtab_build(&ring, &tr, NULL) != BTF_OK || btf_dirtab_build(&d, &tl, NULL) != BTF_OK)
        return 1;
    double sink = 0, qr = 0, ql = 0;
    for (int round = 0; round < 3; round++) { /* interleaved: the machine's load hits both */
        qr += per_query(tr, 1000000, &sink);
        ql += per_query(tl, 1000000, &sink);
    }
    printf("dome151_ring_query %.1f ns\n", qr / 3 * 1e9);
    printf("dome151_list_query %.1f ns\n", ql / 3 * 1e9);
    printf("dome151_list_over_ring %.3f ratio\n", ql / qr);
    printf("sink %g\n", sink > 0 ? 1.0 : 0.0);
    btf_dirtab_free(tr);
    btf_dirtab_free(tl);
    return 0;
}
