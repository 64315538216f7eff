/* test_dirlist.c - room codec, suite "dirlist": explicit direction lists
 * (codec/include/btf_dirtab.h): the qhull triangulation, its table lookup against a
 * brute-force search, continuity, the horizon, bad lists, the manifest's triangles
 * (hostile ones too), and list order, also through `btf gen`/`compress`/`eval` and
 * `btf import-thesis`. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf.h"
#include "btf_dirtab.h"
#include "btf_io.h"
#include "btf_package.h"
#include "fixtures.h"
#include "btf_input.h"

#define D2R 0.017453292519943295

static unsigned rng = 1u;
static double urand(void) /* xorshift32 in [0, 1) */
{
    return fx_unit(fx_xorshift32(&rng));
}

/* n random directions, uniform by area up to theta_max, seeded; retried until the
 * list triangulates (a few random points may all sit on one side of the normal). */
static btf_dirset random_list(int n, double theta_max, unsigned seed)
{
    static float dirs[BTF_MAX_LIST_DIRS][2];
    btf_dirset d;
    rng = seed;
    for (int tries = 0; tries < 50; tries++) {
        double zmin = cos(theta_max * D2R);
        for (int i = 0; i < n; i++) {
            dirs[i][0] = (float)(acos(zmin + (1.0 - zmin) * urand()) / D2R);
            dirs[i][1] = (float)(360.0 * urand());
        }
        if (btf_dirset_make_list((const float(*)[2])dirs, n, &d, NULL) == BTF_OK)
            return d;
    }
    cr_assert_fail("no random list of %d directions triangulated", n);
    return d;
}

/* The UBO2014 dome's 151 directions, phi rotated by rot degrees, in a shuffled order
 * (perm[i] = the dome's canonical index of list entry i). */
static btf_dirset dome_list(float rot, unsigned seed, int perm[151])
{
    btf_dirset dome = btf_dirset_dome151();
    static float dirs[151][2];
    for (int i = 0; i < 151; i++)
        perm[i] = i;
    rng = seed;
    for (int i = 150; i > 0; i--) {
        int j = (int)(urand() * (i + 1)), x = perm[i];
        perm[i] = perm[j], perm[j] = x;
    }
    for (int i = 0; i < 151; i++) {
        btf_dirset_angles(&dome, perm[i], &dirs[i][0], &dirs[i][1]);
        dirs[i][1] += rot;
    }
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_make_list((const float(*)[2])dirs, 151, &d, &err), BTF_OK, "%s", err.msg);
    return d;
}

static void vec_d(const float *f, double v[3]) { v[0] = f[0], v[1] = f[1], v[2] = f[2]; }

/* Independent hull check in double: every point (directions and mirror images of
 * those above the horizon) is inside or on the plane of every triangle. */
static void check_hull(const btf_dirset *d, const btf_dirtab *t, const char *what)
{
    for (int i = 0; i < t->n_tris; i++) {
        double a[3], b[3], c[3];
        vec_d(t->vert[t->tri[i][0]], a), vec_d(t->vert[t->tri[i][1]], b), vec_d(t->vert[t->tri[i][2]], c);
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        cr_assert(n[0] * a[0] + n[1] * a[1] + n[2] * a[2] > 0, "%s: triangle %d faces inwards", what, i);
        for (int k = 0; k < 2 * d->n_dirs; k++) {
            float th, ph;
            btf_dirset_angles(d, k % d->n_dirs, &th, &ph);
            double p[3] = {sin(th * D2R) * cos(ph * D2R), sin(th * D2R) * sin(ph * D2R), cos(th * D2R)};
            if (k >= d->n_dirs && !(p[2] > 1e-6))
                continue;
            if (k >= d->n_dirs)
                p[2] = -p[2];
            double h = (n[0] * (p[0] - a[0]) + n[1] * (p[1] - a[1]) + n[2] * (p[2] - a[2])) / len;
            cr_assert(h < 2e-5, "%s: point %d lies %g outside triangle %d's plane: not the convex hull", what, k, h, i);
        }
    }
}

/* Per-direction weights by brute force in double: the triangle whose cone holds p
 * (Cramer's rule, all coefficients >= -1e-9), coefficients normalised. */
static int brute_weights(const btf_dirtab *t, const double p[3], double *wd)
{
    for (int i = 0; i < t->n_tris; i++) {
        double m[3][3];
        for (int k = 0; k < 3; k++)
            vec_d(t->vert[t->tri[i][k]], m[k]);
        double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        double c[3];
        for (int k = 0; k < 3; k++) { /* replace row k by p */
            double r[3][3];
            memcpy(r, m, sizeof r);
            memcpy(r[k], p, sizeof r[k]);
            c[k] = (r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
                    r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0])) / det;
        }
        if (c[0] < -1e-9 || c[1] < -1e-9 || c[2] < -1e-9)
            continue;
        double s = c[0] + c[1] + c[2];
        for (int k = 0; k < 3; k++)
            wd[t->dir[t->tri[i][k]]] += c[k] / s;
        return 1;
    }
    return 0;
}

/* Random queries (some below the horizon, on it, at the pole): the table's weights
 * per direction equal the brute-force search's within 2e-4 (float32 determinants of
 * unit vectors err by ~1e-7 relative; random lists have triangles of aspect up to
 * ~100, which amplify that to ~1e-5; 2e-4 leaves room yet catches a wrong triangle,
 * whose weights differ by O(0.1)). */
static void check_lookup(const btf_dirset *d, const btf_dirtab *t, int n_queries, const char *what)
{
    double *wd = calloc((size_t)d->n_dirs, sizeof(double)), *wt = calloc((size_t)d->n_dirs, sizeof(double));
    for (int q = 0; q < n_queries; q++) {
        float v[3];
        if (q < 4) {
            float fixed[4][3] = {{0, 0, 1}, {1, 0, 0}, {0.3f, -0.4f, 0}, {0.2f, 0.1f, -0.7f}};
            memcpy(v, fixed[q], sizeof v);
        } else {
            v[0] = (float)(urand() * 2 - 1), v[1] = (float)(urand() * 2 - 1), v[2] = (float)(urand() * 1.3 - 0.3);
        }
        btf_interp in = btf_dirtab_interp_vec(t, v);
        double s = 0, p[3] = {v[0], v[1], v[2] > 0 ? v[2] : 0};
        double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        p[0] /= len, p[1] /= len, p[2] /= len;
        memset(wd, 0, sizeof(double) * (size_t)d->n_dirs);
        memset(wt, 0, sizeof(double) * (size_t)d->n_dirs);
        cr_assert(brute_weights(t, p, wd), "%s: query %d (%g %g %g) in no triangle: the hemisphere is not covered",
                  what, q, p[0], p[1], p[2]);
        for (int k = 0; k < 3; k++) {
            cr_assert(in.idx[k] >= 0 && in.idx[k] < d->n_dirs && in.w[k] >= 0 && isfinite(in.w[k]), "%s: bad slot", what);
            wt[in.idx[k]] += in.w[k];
            s += in.w[k];
        }
        cr_assert(fabs(s - 1.0) < 1e-5, "%s: weights sum to %g", what, s);
        for (int i = 0; i < d->n_dirs; i++)
            cr_assert(fabs(wt[i] - wd[i]) < 2e-4, "%s: query %d (%g %g %g): direction %d weight %g, brute force %g", what,
                      q, p[0], p[1], p[2], i, wt[i], wd[i]);
    }
    free(wd);
    free(wt);
}

Test(dirlist, random_lists_are_hulls_and_lookups_match_brute_force)
{
    const int sizes[5] = {8, 40, 151, 400, 1024};
    for (int k = 0; k < 5; k++) {
        btf_dirset d = random_list(sizes[k], k % 2 ? 88.0 : 70.0, 9001u + (unsigned)k);
        btf_dirtab *t = NULL;
        btf_error err = {{0}};
        cr_assert_eq(btf_dirtab_build(&d, &t, &err), BTF_OK, "%s", err.msg);
        char what[64];
        snprintf(what, sizeof what, "%d random directions", sizes[k]);
        check_hull(&d, t, what);
        check_lookup(&d, t, sizes[k] > 400 ? 300 : 1500, what);
        btf_dirtab_free(t);
    }
}

Test(dirlist, exact_at_listed_directions_and_below_horizon)
{
    int perm[151];
    btf_dirset d = dome_list(17.0f, 77u, perm);
    btf_dirtab *t = NULL;
    cr_assert_eq(btf_dirtab_build(&d, &t, NULL), BTF_OK);
    for (int i = 0; i < d.n_dirs; i++) {
        float v[3];
        btf_dirset_vector(&d, i, v);
        btf_interp in = btf_dirtab_interp_vec(t, v);
        double w = 0;
        for (int k = 0; k < 3; k++)
            w += in.idx[k] == i ? in.w[k] : 0.0;
        cr_assert(w > 1.0 - 1e-5, "listed direction %d gets weight %g", i, w);
    }
    for (int q = 0; q < 200; q++) { /* below the horizon = the horizon at the same azimuth */
        float a = (float)(urand() * 6.2831853), lo[3] = {cosf(a), sinf(a), -(float)urand() * 3}, hz[3] = {cosf(a), sinf(a), 0};
        btf_interp x = btf_dirtab_interp_vec(t, lo), y = btf_dirtab_interp_vec(t, hz);
        for (int k = 0; k < 3; k++) { /* per direction: equal up to the rounding of the rescaled query */
            double wx = 0, wy = 0;
            for (int j = 0; j < 3; j++)
                wx += x.idx[j] == x.idx[k] ? x.w[j] : 0.0, wy += y.idx[j] == x.idx[k] ? y.w[j] : 0.0;
            cr_assert(fabs(wx - wy) < 1e-5, "below the horizon differs from the horizon at azimuth %g", (double)a);
        }
    }
    btf_dirtab_free(t);
}

/* f at the interpolated direction: sum of weights times a smooth f of the listed directions. */
static double interp_f(const btf_dirtab *t, const btf_dirset *d, double th, double ph)
{
    float v[3] = {(float)(sin(th * D2R) * cos(ph * D2R)), (float)(sin(th * D2R) * sin(ph * D2R)), (float)cos(th * D2R)};
    btf_interp in = btf_dirtab_interp_vec(t, v);
    double s = 0;
    for (int k = 0; k < 3; k++) {
        float a[3];
        btf_dirset_vector(d, in.idx[k], a);
        s += in.w[k] * (0.5 + 0.3 * a[0] - 0.2 * a[1] + 0.4 * a[2] * a[2] + 0.3 * a[0] * a[1]);
    }
    return s;
}

/* Steps of 0.004 degrees along theta lines (0.05..92, through the horizon) and phi
 * lines (across the wrap): a jump of 1e-3 anywhere is a seam (the bound; a
 * continuous piecewise-linear interpolant of this f changes by at most |grad f| <=
 * 1.12 times the mesh amplification times 7e-5 rad per step). */
static void continuity(const btf_dirset *d, const char *what)
{
    btf_dirtab *t = NULL;
    cr_assert_eq(btf_dirtab_build(d, &t, NULL), BTF_OK);
    const double h = 0.004;
    for (int k = 0; k < 24; k++) {
        double ph = 15.0 * k + 0.37, prev = interp_f(t, d, 0.05, ph);
        for (double th = 0.05 + h; th <= 92.0; th += h) {
            double v = interp_f(t, d, th, ph);
            cr_assert(fabs(v - prev) < 1e-3, "%s: jump %g at theta %g, phi %g", what, fabs(v - prev), th, ph);
            prev = v;
        }
    }
    const double ths[6] = {3.0, 33.3, 61.0, 80.0, 86.5, 89.99};
    for (int k = 0; k < 6; k++) {
        double prev = interp_f(t, d, ths[k], -2.0);
        for (double ph = -2.0 + h; ph <= 362.0; ph += h) {
            double v = interp_f(t, d, ths[k], ph);
            cr_assert(fabs(v - prev) < 1e-3, "%s: jump %g at theta %g, phi %g", what, fabs(v - prev), ths[k], ph);
            prev = v;
        }
    }
    btf_dirtab_free(t);
}

Test(dirlist, continuous_through_the_horizon, .timeout = 120)
{
    int perm[151];
    btf_dirset dome = dome_list(17.0f, 78u, perm);
    continuity(&dome, "rotated dome list");
    static float spiral[300][2]; /* a jittered Fibonacci spiral down to 80 degrees */
    rng = 31u;
    for (int i = 0; i < 300; i++) {
        double z = 1.0 - (i + 0.5) / 300.0 * (1.0 - cos(80.0 * D2R));
        spiral[i][0] = (float)(acos(z) / D2R + (urand() - 0.5) * 0.6);
        spiral[i][0] = spiral[i][0] < 0 ? 0 : spiral[i][0];
        spiral[i][1] = (float)fmod(i * 137.50776 + (urand() - 0.5) * 2.0, 360.0);
    }
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_make_list((const float(*)[2])spiral, 300, &d, &err), BTF_OK, "%s", err.msg);
    continuity(&d, "spiral list");
}

/* The scanner can fail: a table with one triangle's corner moved to a neighbour's
 * vertex (overlap on one side, a gap on the other) has seams. */
Test(dirlist, continuity_scan_detects_a_wrong_table)
{
    int perm[151];
    btf_dirset d = dome_list(0.0f, 79u, perm);
    btf_dirtab *t = NULL;
    cr_assert_eq(btf_dirtab_build(&d, &t, NULL), BTF_OK);
    int nb = t->adj[5][0], far = 0;
    for (int k = 0; k < 3; k++)
        if (t->tri[nb][k] != t->tri[5][1] && t->tri[nb][k] != t->tri[5][2])
            far = t->tri[nb][k];
    t->tri[5][1] = far; /* triangle 5 now folds over its neighbour */
    double worst = 0;
    for (int k = 0; k < 72; k++)
        for (int j = 0; j < 2; j++) {
            double ph = 5.0 * k, prev = interp_f(t, &d, 0.05, ph);
            for (double th = 0.05 + 0.004; th <= 90.0; th += 0.004) {
                double v = interp_f(t, &d, th, ph);
                worst = fmax(worst, fabs(v - prev));
                prev = v;
            }
        }
    cr_expect(worst >= 1e-3, "a broken table scanned smooth (worst jump %g)", worst);
    btf_dirtab_free(t);
}

/* JSON text -> the load result and message. */
static btf_result parse(const char *json, btf_error *err)
{
    btf_dirset d;
    return btf_dirset_parse_json(json, strlen(json), "t.json", &d, err);
}

Test(dirlist, bad_lists_get_clear_errors)
{
    static const struct {
        const char *json, *msg;
    } bad[] = {
        {"{\"directions\": [{\"theta\": 10, \"phi\": 0}, {\"theta\": 10, \"phi\": 120}]}", "3..1024"},
        {"{\"directions\": [{\"theta\": 95, \"phi\": 0}, {\"theta\": 10, \"phi\": 120}, {\"theta\": 10, \"phi\": 240}]}",
         "theta 95"},
        {"{\"directions\": [{\"theta\": 30, \"phi\": 0}, {\"theta\": 30, \"phi\": 360}, {\"theta\": 30, \"phi\": 120},"
         " {\"theta\": 30, \"phi\": 240}]}",
         "coincide"},
        {"{\"directions\": [{\"theta\": 30, \"phi\": 0}, {\"theta\": 30, \"ph\": 90}, {\"theta\": 30, \"phi\": 240}]}",
         "unknown key \"ph\""},
        {"{\"directions\": [{\"theta\": 30, \"phi\": 0}, {\"theta\": 30}, {\"theta\": 30, \"phi\": 240}]}",
         "missing key \"phi\""},
        {"{\"directions\": [{\"theta\": 30, \"phi\": 0}, {\"theta\": 40, \"phi\": 50}, {\"theta\": 60, \"phi\": 80},"
         " {\"theta\": 50, \"phi\": 20}]}",
         "surround the normal"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0}], \"directions\": []}", "not both"},
        {"{\"directions\": {\"theta\": 3}}", "must be an array"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        btf_error err = {{0}};
        cr_expect_neq(parse(bad[i].json, &err), BTF_OK, "case %zu accepted", i);
        cr_expect(strstr(err.msg, bad[i].msg) != NULL, "case %zu: \"%s\" lacks \"%s\"", i, err.msg, bad[i].msg);
    }
    btf_error err = {{0}};
    cr_expect_eq(parse("{\"directions\": [{\"theta\": 30, \"phi\": 0}, {\"theta\": 30, \"phi\": 120},"
                       " {\"theta\": 30, \"phi\": 240}]}",
                       &err),
                 BTF_OK, "three directions around the normal: %s", err.msg);
}

/* ------------------------------------------------------------ packages and commands */

/* A list set as the JSON the commands read. */
static void write_list(const char *path, const btf_dirset *d)
{
    FILE *f = fopen(path, "w");
    cr_assert(f != NULL);
    fputs("{\"directions\": [", f);
    for (int i = 0; i < d->n_dirs; i++) {
        float t, p;
        btf_dirset_angles(d, i, &t, &p);
        fprintf(f, "%s{\"theta\": %.9g, \"phi\": %.9g}", i ? ", " : "", (double)t, (double)p);
    }
    fputs("]}\n", f);
    fclose(f);
}

int cmd_gen(int argc, char **argv);
int cmd_compress(int argc, char **argv);
int cmd_eval(int argc, char **argv);

/* The dome's directions in a shuffled order, rotated 23 degrees in phi (names then
 * carry no built-in set): gen -> compress -> eval through the commands, the package
 * reads back with its triangles, and the decoder's error matches eval's. */
Test(dirlist, commands_round_trip_a_rotated_permuted_dome, .timeout = 300)
{
    char dir[64], set[128], img[128], pkg[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(set, sizeof set, "%s/set.json", dir);
    snprintf(img, sizeof img, "%s/img", dir);
    snprintf(pkg, sizeof pkg, "%s/pkg", dir);
    int perm[151];
    btf_dirset d = dome_list(23.0f, 4711u, perm);
    write_list(set, &d);
    char *gen[] = {"gen", "stone", img, "--size", "4", "--sampling", set, "--format", "png", "--seed", "8128", NULL};
    cr_assert_eq(cmd_gen(11, gen), 0);
    char *comp[] = {"compress", img, pkg, "--sampling", set, "--k", "3", "--components", "4", "--quiet", NULL};
    cr_assert_eq(cmd_compress(10, comp), 0);
    char *ev[] = {"eval", img, pkg, "--sampling", set, "--csv", NULL};
    cr_expect_eq(cmd_eval(6, ev), 0);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    cr_expect(btf_dirset_equal(&p->lights, &d) && btf_dirset_equal(&p->views, &d), "the list came back changed");
    btf_dirtab *q = NULL;
    cr_assert_eq(btf_dirtab_build(&d, &q, NULL), BTF_OK);
    cr_expect_eq(p->dirtab[1]->n_tris, q->n_tris, "the manifest's triangles are not qhull's");
    cr_expect(!memcmp(p->dirtab[1]->tri, q->tri, sizeof(int[3]) * (size_t)q->n_tris));
    btf_dirtab_free(q);
    btf_package_free(p);
    fx_rmtree(dir);
}

/* Index order as listed: a material generated over the dome in a shuffled list has,
 * at list entries (i, j), the samples the ring dome has at (perm[i], perm[j]); its
 * k = 1 package (PCA per view, invariant to the order of the lights) has the
 * same RMSE as the ring package's. */
Test(dirlist, list_order_is_kept)
{
    int perm[151];
    btf_dirset list = dome_list(0.0f, 5150u, perm), ring = btf_dirset_dome151();
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_TILES);
    gp.seed = 60061;
    btf *a = NULL, *b = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gen_create(&gp, 4, 4, &ring, &ring, BTF_U8, &a, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gen_create(&gp, 4, 4, &list, &list, BTF_U8, &b, &err), BTF_OK, "%s", err.msg);
    int diff = 0;
    for (int v = 0; v < 151; v += 7)
        for (int l = 0; l < 151; l++)
            for (int c = 0; c < 3; c++)
                diff += fabsf(btf_get(b, v, l, 1, 2, c) - btf_get(a, perm[v], perm[l], 1, 2, c)) > 1.5f / 255.0f;
    cr_expect_eq(diff, 0, "%d samples are not where the list says", diff);
    btf_free(a);
    btf_free(b);
}

/* A manifest's triangles come from a file: every way of breaking them (in a package
 * the library compressed on a random list) is refused with a message, and the
 * untouched package still reads. */
Test(dirlist, hostile_manifest_triangles_are_refused)
{
    char dir[64], pkg[128], man[160];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(pkg, sizeof pkg, "%s/pkg", dir);
    snprintf(man, sizeof man, "%s/manifest.json", pkg);
    btf_dirset d = random_list(24, 80.0, 424242u);
    btf *src = fx_gen(BTF_GEN_KNIT, 4, &d, BTF_U8);
    btf_pca_options po = {0};
    po.k = 1, po.components = 2;
    btf_package_options ko = {0};
    btf_error cerr = {{0}};
    cr_assert_eq(btf_package_compress(src, &po, &ko, pkg, NULL, &cerr), BTF_OK, "%s", cerr.msg);
    btf_free(src);
    char *good = fx_read(man, NULL);
    cr_assert(good != NULL, "cannot read %s", man);
    char *tris = strstr(strstr(good, "\"views\""), "\"triangles\"");
    cr_assert(tris != NULL, "no triangles in the views' entry");
    char *open = strchr(tris, '[');
    long at = open - good;
    /* edits on the views' triangle list, just after '[' */
    static const struct {
        const char *insert, *msg;
    } bad[] = {
        {"999, 0, 1, ", "triangle vertex"},  /* index out of range */
        {"-1, 0, 1, ", "triangle vertex"},   /* negative */
        {"0.5, 0, 1, ", "triangle vertex"},  /* not an integer */
        {"0, 1, 2, ", ""},                   /* an extra triangle: clockwise, off the hull or an edge twice */
        {"1, 0, ", "vertex triples"},        /* not a multiple of 3 */
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        size_t n = strlen(good) + strlen(bad[i].insert) + 1;
        char *m = malloc(n);
        snprintf(m, n, "%.*s%s%s", (int)(at + 1), good, bad[i].insert, good + at + 1);
        fx_write_text(man, m);
        free(m);
        btf_package *p = NULL;
        btf_error err = {{0}};
        cr_expect_neq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "edit %zu accepted", i);
        cr_expect(strstr(err.msg, bad[i].msg) != NULL && strstr(err.msg, "views") != NULL, "edit %zu: \"%s\"", i,
                  err.msg);
        btf_package_free(p);
    }
    /* the first triangle dropped: a hole in the hemisphere */
    char *end = strchr(open, ']'), *third = open + 1;
    for (int commas = 0; commas < 3 && third < end; third++)
        commas += *third == ',';
    size_t n = strlen(good) + 1;
    char *m = malloc(n);
    snprintf(m, n, "%.*s%s", (int)(at + 1), good, third);
    fx_write_text(man, m);
    free(m);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_expect_neq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "a triangle short accepted");
    cr_expect(strstr(err.msg, "cover") != NULL || strstr(err.msg, "hull") != NULL, "hole: \"%s\"", err.msg);
    btf_package_read_options ro = {0}; /* no_dirtab skips the reader's tables, not the manifest's */
    ro.no_dirtab = 1;
    cr_expect_neq(btf_package_read_opts(pkg, 0, NULL, &ro, &p, &err), BTF_OK, "no_dirtab: a triangle short accepted");
    fx_write_text(man, good);
    cr_expect_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    btf_package_free(p);
    cr_expect_eq(btf_package_read_opts(pkg, 0, NULL, &ro, &p, &err), BTF_OK, "%s", err.msg);
    cr_expect(p && p->dirtab[0] && p->dirtab[1], "no_dirtab: a list set's tables from the manifest's triangles");
    btf_package_free(p);
    free(good);
    fx_rmtree(dir);
}

/* A DFMF .btf of a list set stores its directions in list order; they are no rings,
 * so the reader makes the same list (float radians in the file: 1e-4 degrees). */
Test(dirlist, dfmf_keeps_a_list)
{
    btf_dirset d = random_list(30, 85.0, 1717u);
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf *a = NULL, *b = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gen_create(&gp, 4, 4, &d, &d, BTF_U8, &a, &err), BTF_OK, "%s", err.msg);
    char dir[64], path[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/m.btf", dir);
    cr_assert_eq(btf_save_dfmf(a, path, 0, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_load_any(path, NULL, &b, &err), BTF_OK, "%s", err.msg);
    cr_expect(btf_dirset_is_list(&b->lights) && btf_dirset_equal(&b->lights, &d) && btf_dirset_equal(&b->views, &d),
              "the list came back as %d rings", b->lights.n_rings);
    btf_free(a);
    btf_free(b);
    fx_rmtree(dir);
}

int cmd_import_thesis(int argc, char **argv);

/* import-thesis --sampling: a package's index i is the listed direction i. The thesis
 * wool's 81 directions named in a shuffled list: same data by index as the default
 * import, but written out as images each lands at its listed direction, so a loader
 * of the ring set finds list entry i at canonical perm[i]. */
Test(dirlist, import_thesis_takes_a_list_order)
{
    char wool[512];
    if (!fx_shared_path(wool, sizeof wool, "data/thesis-ubo2003/wool"))
        cr_skip_test("shared thesis data absent");
    btf_dirset ubo = btf_dirset_ubo2003();
    static float dirs[81][2];
    int perm[81];
    for (int i = 0; i < 81; i++)
        perm[i] = i;
    rng = 8080u;
    for (int i = 80; i > 0; i--) {
        int j = (int)(urand() * (i + 1)), x = perm[i];
        perm[i] = perm[j], perm[j] = x;
    }
    for (int i = 0; i < 81; i++)
        btf_dirset_angles(&ubo, perm[i], &dirs[i][0], &dirs[i][1]);
    btf_dirset list;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_make_list((const float(*)[2])dirs, 81, &list, &err), BTF_OK, "%s", err.msg);
    btf_load_options o = {0};
    o.width = o.height = 4;
    btf *a = NULL, *b = NULL, *c = NULL;
    cr_assert_eq(btf_import_thesis(wool, &o, &a, &err), BTF_OK, "%s", err.msg);
    o.sampling = &list;
    cr_assert_eq(btf_import_thesis(wool, &o, &b, &err), BTF_OK, "%s", err.msg);
    cr_expect(btf_dirset_equal(&b->lights, &list) && btf_dirset_equal(&b->views, &list));
    cr_expect(!memcmp(a->data, b->data, a->count), "the package's data changed with its labels");
    char dir[64], img[128], set[128], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    cr_assert_eq(btf_save_ubo2003_dir(b, img, "wool", "png", &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_load_ubo2003_dir(img, NULL, &c, &err), BTF_OK, "%s", err.msg);
    int diff = 0;
    for (int v = 0; v < 81; v += 5)
        for (int l = 0; l < 81; l++)
            diff += btf_get(c, perm[v], perm[l], 3, 2, 1) != btf_get(b, v, l, 3, 2, 1);
    cr_expect_eq(diff, 0, "%d samples not at their listed direction", diff);
    btf_free(a);
    btf_free(b);
    btf_free(c);
    /* the command: --sampling with the list file, and a file of the wrong size refused */
    snprintf(set, sizeof set, "%s/order.json", dir);
    snprintf(out, sizeof out, "%s/wool.btf", dir);
    write_list(set, &list);
    char *ok[] = {"import-thesis", wool, out, "--size", "4", "--sampling", set, NULL};
    cr_expect_eq(cmd_import_thesis(7, ok), 0);
    char *bad[] = {"import-thesis", wool, out, "--size", "4", "--sampling", "dome151", NULL};
    cr_expect_eq(cmd_import_thesis(7, bad), 1, "151 directions accepted for an 81-direction package");
    fx_rmtree(dir);
}

/* btf_dirset_interp(_vec) on list sets: the table's result, also when two lists
 * take turns (the per-thread table is replaced, never mixed up). */
Test(dirlist, dirset_interp_uses_the_right_table)
{
    btf_dirset a = random_list(50, 80.0, 2024u), b = random_list(70, 85.0, 2025u);
    btf_dirtab *ta = NULL, *tb = NULL;
    cr_assert_eq(btf_dirtab_build(&a, &ta, NULL), BTF_OK);
    cr_assert_eq(btf_dirtab_build(&b, &tb, NULL), BTF_OK);
    for (int q = 0; q < 400; q++) {
        const btf_dirset *d = q % 3 ? &a : &b;
        const btf_dirtab *t = q % 3 ? ta : tb;
        float th = (float)(urand() * 89.0), ph = (float)(urand() * 360.0);
        float v[3] = {sinf(th * (float)D2R) * cosf(ph * (float)D2R), sinf(th * (float)D2R) * sinf(ph * (float)D2R),
                      cosf(th * (float)D2R)};
        btf_interp x = btf_dirset_interp(d, th, ph), y = btf_dirtab_interp_vec(t, v);
        for (int k = 0; k < 3; k++) {
            double wx = 0, wy = 0;
            for (int j = 0; j < 3; j++)
                wx += x.idx[j] == y.idx[k] ? x.w[j] : 0.0, wy += y.idx[j] == y.idx[k] ? y.w[j] : 0.0;
            cr_assert(fabs(wx - wy) < 1e-5, "query %d: %g vs %g", q, wx, wy);
        }
    }
    btf_dirtab_free(ta);
    btf_dirtab_free(tb);
}
