/* test_interp.c - room codec, suites "interp" and "dirset_json": angular
 * interpolation (codec/common/btf_interp.c) and the JSON ring-table loader.
 *
 * Independent references used here: a smooth test function f evaluated
 * directly at the query direction, double-precision geometry (triple products,
 * azimuth formulas) written in this file, and a brute-force scan over every
 * measured direction. Nothing compares against stored outputs of the code. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf.h"
#include "btf_dirtab.h"
#include "fixtures.h"

#define D2R 0.017453292519943295

/* ------------------------------------------------------------------ helpers */

/* Test sets: the two built-ins, an irregular table (odd counts, arbitrary
 * offsets, uneven theta) and one without a pole direction but with a horizon
 * ring. n_sets is fixed; sets[] filled by make_sets. */
enum { N_SETS = 4 };
static void make_sets(btf_dirset sets[N_SETS])
{
    static const btf_ring odd[5] = {{0, 1, 0}, {10, 5, 17}, {25, 11, 3}, {40, 7, 50}, {70, 16, 2}};
    static const btf_ring nopole[3] = {{15, 6, 0}, {40, 12, 7}, {90, 16, 11.25f}};
    sets[0] = btf_dirset_ubo2003();
    sets[1] = btf_dirset_dome151();
    cr_assert_eq(btf_dirset_make(odd, 5, &sets[2], NULL), BTF_OK);
    cr_assert_eq(btf_dirset_make(nopole, 3, &sets[3], NULL), BTF_OK);
}

static void dir_d(double t_deg, double p_deg, double v[3])
{
    v[0] = sin(t_deg * D2R) * cos(p_deg * D2R);
    v[1] = sin(t_deg * D2R) * sin(p_deg * D2R);
    v[2] = cos(t_deg * D2R);
}

/* Measured direction i in double precision (independent of the library's float path). */
static void meas_d(const btf_dirset *d, int i, double v[3])
{
    float t, p;
    btf_dirset_angles(d, i, &t, &p);
    dir_d(t, p, v);
}

/* Smooth test function on the sphere; |grad f| <= 1.12 on the unit sphere
 * (grad = (0.3 + 0.3y, -0.2 + 0.3x, 0.8z)). */
static double f_smooth(const double v[3])
{
    return 0.5 + 0.3 * v[0] - 0.2 * v[1] + 0.4 * v[2] * v[2] + 0.3 * v[0] * v[1];
}

/* f at the measured directions of the last set seen (each Criterion test runs
 * in its own process, so this cache is per test). */
static const btf_dirset *cache_set;
static btf_dirset cache_copy;
static double cache_f[BTF_MAX_DIRS];

static double f_measured(const btf_dirset *d, int i)
{
    if (cache_set != d || memcmp(&cache_copy, d, sizeof *d) != 0) {
        for (int k = 0; k < d->n_dirs; k++) {
            double v[3];
            meas_d(d, k, v);
            cache_f[k] = f_smooth(v);
        }
        cache_set = d;
        cache_copy = *d;
    }
    return cache_f[i];
}

/* The table of the set under test when a test checks btf_dirtab instead of the ring walk. */
static btf_dirtab *use_tab;

/* Interpolated value of f at (t, p): sum of weights times f at the measured directions. */
static double interp_value(const btf_dirset *d, double t, double p)
{
    float v[3] = {(float)(sin(t * D2R) * cos(p * D2R)), (float)(sin(t * D2R) * sin(p * D2R)), (float)cos(t * D2R)};
    btf_interp r = use_tab ? btf_dirtab_interp_vec(use_tab, v) : btf_dirset_interp(d, (float)t, (float)p);
    return r.w[0] * f_measured(d, r.idx[0]) + r.w[1] * f_measured(d, r.idx[1]) + r.w[2] * f_measured(d, r.idx[2]);
}

/* Negative control for the seam scanner: value of the nearest measured direction. */
static double nearest_value(const btf_dirset *d, double t, double p)
{
    double q[3], v[3], best = -2;
    int bi = 0;
    dir_d(t, p, q);
    for (int i = 0; i < d->n_dirs; i++) {
        meas_d(d, i, v);
        double c = q[0] * v[0] + q[1] * v[1] + q[2] * v[2];
        if (c > best) {
            best = c;
            bi = i;
        }
    }
    meas_d(d, bi, v);
    return f_smooth(v);
}

static double weight_of(const btf_interp *r, int i)
{
    double w = 0;
    for (int k = 0; k < 3; k++)
        if (r->idx[k] == i)
            w += r->w[k];
    return w;
}

static void assert_valid(const btf_dirset *d, btf_interp r, const char *what)
{
    double s = 0;
    for (int k = 0; k < 3; k++) {
        cr_assert(r.idx[k] >= 0 && r.idx[k] < d->n_dirs, "%s: index %d out of range", what, r.idx[k]);
        cr_assert(isfinite(r.w[k]) && r.w[k] >= 0.0f && r.w[k] <= 1.0f, "%s: weight %g", what, (double)r.w[k]);
        s += r.w[k];
    }
    /* three float32 divisions by the same sum: error a few ulp of 1 */
    cr_assert(fabs(s - 1.0) < 1e-6, "%s: weights sum to %.9f", what, s);
}

static double det_d(const double a[3], const double b[3], const double c[3])
{
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
           a[2] * (b[0] * c[1] - b[1] * c[0]);
}

static unsigned rng_state = 12345u;
static double urand(void)
{
    return fx_unit(fx_lcg_nr(&rng_state));
}

/* Uniform random direction with theta in [0, tmax] (degrees) into t, p. */
static void rand_dir(double tmax, double *t, double *p)
{
    double c = 1.0 - (1.0 - cos(tmax * D2R)) * urand();
    *t = acos(c) / D2R;
    *p = 360.0 * urand();
}

/* Smallest polar angle of ring r's great-circle polygon (midpoint of an edge). */
static double ring_inner_theta(const btf_ring *g)
{
    if (g->count < 3 || g->theta_deg >= 90.0f)
        return g->theta_deg;
    return atan(tan(g->theta_deg * D2R) * cos(M_PI / g->count)) / D2R;
}

/* ------------------------------------------------------------------ interp */

Test(interp, weights_valid_everywhere)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    char what[96];
    for (int s = 0; s < N_SETS; s++)
        for (int n = 0; n < 20000; n++) {
            double t = -20.0 + 220.0 * urand(), p = -800.0 + 1600.0 * urand();
            snprintf(what, sizeof what, "set %d theta %.4f phi %.4f", s, t, p);
            assert_valid(&sets[s], btf_dirset_interp(&sets[s], (float)t, (float)p), what);
        }
}

Test(interp, exact_at_measured_directions)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    for (int s = 0; s < N_SETS; s++) {
        const btf_dirset *d = &sets[s];
        for (int i = 0; i < d->n_dirs; i++) {
            float t, p, v[3];
            btf_dirset_angles(d, i, &t, &p);
            btf_interp r = btf_dirset_interp(d, t, p);
            /* float32 directions: off-vertex weights are rounding noise ~1e-7 */
            cr_assert(weight_of(&r, i) > 1.0 - 1e-5, "set %d dir %d (%g, %g): weight %.8f", s, i, (double)t,
                      (double)p, weight_of(&r, i));
            btf_dirset_vector(d, i, v);
            r = btf_dirset_interp_vec(d, v);
            cr_assert(weight_of(&r, i) > 1.0 - 1e-5, "set %d dir %d by vector: weight %.8f", s, i, weight_of(&r, i));
            /* the same direction given with phi + 360 and phi - 360 */
            r = btf_dirset_interp(d, t, p + 360.0f);
            cr_assert(weight_of(&r, i) > 1.0 - 1e-5, "set %d dir %d at phi+360", s, i);
            r = btf_dirset_interp(d, t, p - 360.0f);
            cr_assert(weight_of(&r, i) > 1.0 - 1e-5, "set %d dir %d at phi-360", s, i);
        }
    }
}

/* Inside the measured range the weights are the tetrahedron volumes: the
 * weighted sum of the three directions is parallel to P (an independent double
 * check), and the triangle holds no other measured direction (brute force). */
Test(interp, barycentric_and_empty_triangle)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    for (int s = 0; s < 3; s++) { /* sets with a pole: the whole inner region is triangulated */
        const btf_dirset *d = &sets[s];
        double tmax = ring_inner_theta(&d->rings[d->n_rings - 1]) - 1e-3;
        for (int n = 0; n < 3000; n++) {
            double t, p, P[3], V[3][3], sum[3] = {0, 0, 0};
            rand_dir(tmax, &t, &p);
            dir_d(t, p, P);
            btf_interp r = btf_dirset_interp(d, (float)t, (float)p);
            for (int k = 0; k < 3; k++) {
                meas_d(d, r.idx[k], V[k]);
                for (int c = 0; c < 3; c++)
                    sum[c] += r.w[k] * V[k][c];
            }
            double cx = sum[1] * P[2] - sum[2] * P[1], cy = sum[2] * P[0] - sum[0] * P[2],
                   cz = sum[0] * P[1] - sum[1] * P[0];
            double sin_err = sqrt(cx * cx + cy * cy + cz * cz) / sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
            /* float32 vectors and determinants: ~1e-6 rad; 1e-4 rad still far below a wrong triangle (> 1e-2) */
            cr_assert(sin_err < 1e-4, "set %d (%.4f, %.4f): weighted sum off P by %.3g rad", s, t, p, sin_err);
            double vol = det_d(V[0], V[1], V[2]);
            if (fabs(vol) < 1e-12)
                continue; /* P exactly on a vertex: nothing to check */
            for (int i = 0; i < d->n_dirs; i++) {
                if (i == r.idx[0] || i == r.idx[1] || i == r.idx[2])
                    continue;
                double Q[3];
                meas_d(d, i, Q);
                double a = det_d(Q, V[1], V[2]) * vol, b = det_d(Q, V[2], V[0]) * vol, c = det_d(Q, V[0], V[1]) * vol;
                double eps = 1e-9 * fabs(vol);
                int inside = a > eps && b > eps && c > eps && Q[0] * sum[0] + Q[1] * sum[1] + Q[2] * sum[2] > 0;
                cr_assert(!inside, "set %d (%.4f, %.4f): direction %d lies inside the chosen triangle", s, t, p, i);
            }
        }
    }
}

Test(interp, pole)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    for (int s = 0; s < 3; s++) {
        for (double p = -30; p < 400; p += 7.3) {
            btf_interp r = btf_dirset_interp(&sets[s], 0.0f, (float)p);
            cr_assert(weight_of(&r, 0) > 1.0 - 1e-6, "set %d pole at phi %g: %.8f", s, p, weight_of(&r, 0));
            /* just off the pole the pole keeps almost all weight: 0.01 deg of a >= 10 deg ring spacing */
            r = btf_dirset_interp(&sets[s], 0.01f, (float)p);
            cr_assert(weight_of(&r, 0) > 0.998, "set %d near pole phi %g: %.6f", s, p, weight_of(&r, 0));
        }
        float up[3] = {0, 0, 5}, tilt[3] = {1e-9f, -1e-9f, 1};
        btf_interp r = btf_dirset_interp_vec(&sets[s], up);
        cr_assert(weight_of(&r, 0) > 1.0 - 1e-6);
        r = btf_dirset_interp_vec(&sets[s], tilt);
        cr_assert(weight_of(&r, 0) > 1.0 - 1e-6);
    }
}

/* Beyond the outermost ring polygon (and below the horizon, clamped): the two
 * outer-ring neighbours of phi, weighted by azimuth only:
 * w_C : w_D = sin(phi_D - phi) : sin(phi - phi_C), computed here in double. */
Test(interp, beyond_outer_ring_and_below_horizon)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    const double thetas[] = {75.001, 76, 80, 89.9, 90, 95, 120, 180, 1e9};
    for (int s = 0; s < 3; s++) {
        const btf_dirset *d = &sets[s];
        const btf_ring *g = &d->rings[d->n_rings - 1];
        int start = d->ring_start[d->n_rings - 1];
        double step = 360.0 / g->count;
        for (int n = 0; n < 500; n++) {
            double p = 360.0 * urand();
            double u = (p - g->phi_offset_deg) / step;
            int k = (int)floor(u);
            double pc = g->phi_offset_deg + k * step, pd = pc + step;
            double wc = sin((pd - p) * D2R), wd = sin((p - pc) * D2R);
            int ic = start + ((k % g->count) + g->count) % g->count;
            int id = start + (((k + 1) % g->count) + g->count) % g->count;
            for (size_t j = 0; j < sizeof thetas / sizeof thetas[0]; j++) {
                double t = thetas[j] + (g->theta_deg - 75.0f);
                btf_interp r = btf_dirset_interp(d, (float)t, (float)p);
                /* float32 angles and sines: ~1e-6 */
                cr_assert(fabs(weight_of(&r, ic) - wc / (wc + wd)) < 1e-5 && fabs(weight_of(&r, id) - wd / (wc + wd)) < 1e-5,
                          "set %d theta %g phi %g: weights %g %g, expected %g %g", s, t, p, weight_of(&r, ic),
                          weight_of(&r, id), wc / (wc + wd), wd / (wc + wd));
            }
        }
    }
}

Test(interp, phi_wrap)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    for (int s = 0; s < N_SETS; s++)
        for (double t = 0.5; t < 95; t += 2.5) {
            double a = interp_value(&sets[s], t, 359.99), b = interp_value(&sets[s], t, 0.0);
            double c = interp_value(&sets[s], t, -0.01), e = interp_value(&sets[s], t, 360.0);
            /* 0.01 deg apart: |grad| <= 5 (see continuity) gives <= 1e-3 */
            cr_assert(fabs(a - b) < 1e-3, "set %d theta %g: f(359.99) %g vs f(0) %g", s, t, a, b);
            cr_assert(fabs(a - c) < 1e-5, "set %d theta %g: phi -0.01 differs from 359.99", s, t);
            cr_assert(fabs(b - e) < 1e-5, "set %d theta %g: phi 360 differs from 0", s, t);
            cr_assert(fabs(interp_value(&sets[s], t, 725.0) - interp_value(&sets[s], t, 5.0)) < 1e-5);
        }
}

Test(interp, edge_inputs_finite)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    const float thetas[] = {0, 74.9f, 75, 80, 89.9f, 90, 95, -5, 180, 1e30f, NAN, INFINITY, -INFINITY};
    const float phis[] = {359.99f, 0, -0.0f, 360, -1e-9f, 1e30f, -1e30f, NAN, INFINITY, -INFINITY};
    char what[96];
    for (int s = 0; s < N_SETS; s++) {
        for (size_t i = 0; i < sizeof thetas / sizeof *thetas; i++)
            for (size_t j = 0; j < sizeof phis / sizeof *phis; j++) {
                snprintf(what, sizeof what, "set %d theta %g phi %g", s, (double)thetas[i], (double)phis[j]);
                assert_valid(&sets[s], btf_dirset_interp(&sets[s], thetas[i], phis[j]), what);
            }
        const float vecs[][3] = {{0, 0, 0}, {NAN, 0, 1}, {INFINITY, 0, 0}, {0, 0, -1}, {1, 0, 0}, {1e30f, 1e30f, 1e30f},
                                 {1e-30f, 0, 1e-30f}, {-1, -1, -1}, {0, 1e-38f, 0}};
        for (size_t i = 0; i < sizeof vecs / sizeof *vecs; i++) {
            snprintf(what, sizeof what, "set %d vector %zu", s, i);
            assert_valid(&sets[s], btf_dirset_interp_vec(&sets[s], vecs[i]), what);
        }
        assert_valid(&sets[s], btf_dirset_interp_vec(&sets[s], NULL), "NULL vector");
    }
    /* NaN means the normal; below the horizon equals the horizon at the same phi */
    btf_dirset d = sets[0];
    btf_interp a = btf_dirset_interp(&d, NAN, 0), b = btf_dirset_interp(&d, 0, 0);
    cr_assert(weight_of(&a, 0) == weight_of(&b, 0));
    for (double p = 0; p < 360; p += 11.7) {
        double h = interp_value(&d, 90.0, p);
        cr_assert(fabs(interp_value(&d, 95.0, p) - h) < 1e-7 && fabs(interp_value(&d, 180.0, p) - h) < 1e-7);
        float v[3] = {(float)cos(p * D2R), (float)sin(p * D2R), -0.3f};
        btf_interp r = btf_dirset_interp_vec(&d, v), q = btf_dirset_interp(&d, 90.0f, (float)p);
        for (int k = 0; k < 3; k++)
            cr_assert(fabs(weight_of(&r, q.idx[k]) - weight_of(&q, q.idx[k])) < 1e-5, "vector below horizon, phi %g", p);
    }
}

/* Rings that break the nesting assumption or have 1-2 directions off the pole:
 * no continuity promise (doc/data-model.md), but always valid weights. */
Test(interp, degenerate_tables_stay_valid)
{
    static const btf_ring t1[3] = {{0, 1, 0}, {30, 1, 40}, {60, 2, 10}};
    static const btf_ring t2[2] = {{10, 3, 0}, {80, 200, 0}};
    static const btf_ring t3[1] = {{0, 1, 0}};
    static const btf_ring t4[1] = {{45, 7, 3}};
    const btf_ring *tabs[4] = {t1, t2, t3, t4};
    int n[4] = {3, 2, 1, 1};
    char what[96];
    for (int k = 0; k < 4; k++) {
        btf_dirset d;
        cr_assert_eq(btf_dirset_make(tabs[k], n[k], &d, NULL), BTF_OK);
        for (int m = 0; m < 5000; m++) {
            double t = -5 + 100 * urand(), p = 360 * urand();
            snprintf(what, sizeof what, "table %d theta %g phi %g", k, t, p);
            assert_valid(&d, btf_dirset_interp(&d, (float)t, (float)p), what);
        }
    }
}

Test(interp, vector_matches_angles)
{
    btf_dirset d = btf_dirset_dome151();
    for (int n = 0; n < 5000; n++) {
        double t, p, v[3];
        rand_dir(90, &t, &p);
        dir_d(t, p, v);
        float s = (float)(0.1 + 10 * urand()), fv[3] = {(float)v[0] * s, (float)v[1] * s, (float)v[2] * s};
        double a = 0, b = interp_value(&d, t, p);
        btf_interp r = btf_dirset_interp_vec(&d, fv);
        for (int k = 0; k < 3; k++) {
            double q[3];
            meas_d(&d, r.idx[k], q);
            a += r.w[k] * f_smooth(q);
        }
        /* the two paths differ only by float rounding of the angles (~1e-5 deg) */
        cr_assert(fabs(a - b) < 1e-5, "(%g, %g): vector %g vs angles %g", t, p, a, b);
    }
}

/* ------------------------------------------------------------ continuity */

typedef double (*value_fn)(const btf_dirset *d, double t, double p);

/* Largest change of fn between consecutive samples along a theta line
 * (dir 0: theta from a to b at fixed c = phi) or a phi line (dir 1). */
static double scan(value_fn fn, const btf_dirset *d, int dir, double a, double b, double c, double h, double *where)
{
    double prev = dir ? fn(d, c, a) : fn(d, a, c), worst = 0;
    for (double x = a + h; x <= b; x += h) {
        double v = dir ? fn(d, c, x) : fn(d, x, c);
        if (fabs(v - prev) > worst) {
            worst = fabs(v - prev);
            *where = x;
        }
        prev = v;
    }
    return worst;
}

/* Step 0.004 deg = 7.0e-5 rad. A continuous piecewise-linear interpolant of f
 * changes by at most G * step, G = |grad f| (<= 1.12) times the mesh's
 * gradient amplification (< 4 for triangles whose smallest angle exceeds ~15
 * deg), so G <= 5: 3.5e-4; float32 weights add ~1e-5. A seam jumps by the
 * difference of two triangles' interpolants, typically 1e-3 .. 1e-1 (the
 * thesis's literal rule jumps by up to 0.12 with this f near theta 15). */
#define SCAN_H 0.004
#define SCAN_BOUND (5.0 * SCAN_H * D2R + 2e-5)

static void continuity_scans(const btf_dirset *d, const char *name)
{
    double where = 0, w;
    /* theta lines through every ring, the outer ring, 90 and below, at vertex and generic phis */
    const btf_ring *o = &d->rings[d->n_rings - 1];
    for (int k = 0; k < 40; k++) {
        double p = k < 20 ? o->phi_offset_deg + k * (360.0 / o->count) / 2.0 : 9.0 * k + 0.123;
        w = scan(interp_value, d, 0, 0.05, 92.0, p, SCAN_H, &where);
        cr_assert(w <= SCAN_BOUND, "%s: jump %.3g > %.3g at theta %.4f, phi %.3f", name, w, SCAN_BOUND, where, p);
    }
    /* full phi lines across the wrap (-2 .. 362): just outside each ring, just inside it
     * (crossing its polygon edges in and out) and mid-band */
    for (int r = 0; r < d->n_rings; r++) {
        double next = r + 1 < d->n_rings ? d->rings[r + 1].theta_deg : 90.0;
        double ts[3] = {d->rings[r].theta_deg + 0.05, d->rings[r].theta_deg - 0.02, 0.5 * (d->rings[r].theta_deg + next)};
        for (int j = 0; j < 3; j++) {
            if (ts[j] <= 0)
                continue;
            w = scan(interp_value, d, 1, -2.0, 362.0, ts[j], SCAN_H, &where);
            cr_assert(w <= SCAN_BOUND, "%s: jump %.3g > %.3g at theta %.4f, phi %.4f", name, w, SCAN_BOUND, ts[j], where);
        }
    }
}

Test(interp, continuity_ubo2003)
{
    btf_dirset d = btf_dirset_ubo2003();
    continuity_scans(&d, "ubo2003");
}

Test(interp, continuity_dome151)
{
    btf_dirset d = btf_dirset_dome151();
    continuity_scans(&d, "dome151");
}

Test(interp, continuity_irregular_sets)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    continuity_scans(&sets[2], "irregular");
    /* no pole: the cap blends by azimuth, a seam only at theta 0 itself (scans start at 0.05) */
    continuity_scans(&sets[3], "no-pole");
}

/* The scanner can fail: nearest-direction lookup has seams it must flag. */
Test(interp, continuity_scanner_detects_seams)
{
    btf_dirset d = btf_dirset_ubo2003();
    double worst = 0, where = 0;
    for (int k = 0; k < 6; k++)
        worst = fmax(worst, scan(nearest_value, &d, 1, 0.0, 360.0, 20.0 + 11.0 * k, 0.05, &where));
    cr_assert(worst > 10 * SCAN_BOUND, "nearest-neighbour seams not detected: %g", worst);
}

/* Interpolation error against f evaluated directly: the denser 151-direction
 * dome must beat UBO2003 (81). Linear interpolation error scales with the
 * squared spacing; dome151's is ~0.73x UBO2003's, so ~0.55x the error is
 * expected: require < 0.85x, and UBO2003 itself below 0.01 (f spans ~1). */
Test(interp, accuracy_improves_with_density)
{
    btf_dirset u = btf_dirset_ubo2003(), m = btf_dirset_dome151();
    double eu = 0, em = 0;
    int n = 20000;
    for (int k = 0; k < n; k++) {
        double t, p, v[3];
        rand_dir(72.0, &t, &p);
        dir_d(t, p, v);
        double f = f_smooth(v);
        eu += fabs(interp_value(&u, t, p) - f);
        em += fabs(interp_value(&m, t, p) - f);
    }
    eu /= n;
    em /= n;
    cr_log_info("mean abs interpolation error: ubo2003 %.5f, dome151 %.5f", eu, em);
    cr_assert(eu < 0.01, "ubo2003 error %g", eu);
    cr_assert(em < 0.85 * eu, "dome151 error %g not below ubo2003 %g", em, eu);
}

/* ------------------------------------------------------------ dirset_json */

Test(dirset_json, good_file_matches_builtin)
{
    char dir[256], path[320];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/dome.json", dir);
    /* written from the table in doc/data-model.md section 2, not from the library */
    fx_write_text(path, "{ \"name\": \"dome151\", \"rings\": [\n"
                        " {\"theta\": 0, \"count\": 1, \"phi_offset\": 0},\n"
                        " {\"theta\": 11, \"count\": 6, \"phi_offset\": 15},\n"
                        " {\"theta\": 23.5, \"count\": 12, \"phi_offset\": 0},\n"
                        " {\"theta\": 30, \"count\": 12, \"phi_offset\": 15},\n"
                        " {\"theta\": 37.5, \"count\": 12, \"phi_offset\": 0},\n"
                        " {\"theta\": 45, \"count\": 18, \"phi_offset\": 0},\n"
                        " {\"theta\": 52.5, \"count\": 18, \"phi_offset\": 7.5},\n"
                        " {\"theta\": 60, \"count\": 24, \"phi_offset\": 0},\n"
                        " {\"theta\": 67.5, \"count\": 24, \"phi_offset\": 367.5},\n"
                        " {\"theta\": 75, \"count\": 24, \"phi_offset\": 0} ] }\n");
    btf_dirset d, ref = btf_dirset_dome151();
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_load_json(path, &d, &err), BTF_OK, "%s", err.msg);
    cr_assert(btf_dirset_equal(&d, &ref));
    cr_assert_eq(d.n_dirs, 151);
    cr_assert_eq(d.ring_start[9], 127);
    unlink(path);
    rmdir(dir);
}

/* One bad input: expected code and a fragment the message must contain. */
typedef struct bad_case {
    const char *text;
    btf_result code;
    const char *needle;
} bad_case;

Test(dirset_json, bad_files_clear_errors)
{
    static const bad_case cases[] = {
        {"{}", BTF_ERR_FORMAT, "missing key \"rings\""},
        {"[1,2]", BTF_ERR_FORMAT, "top level"},
        {"{\"rings\": 5}", BTF_ERR_FORMAT, "must be an array"},
        {"{\"rings\": []}", BTF_ERR_RANGE, "0 rings"},
        {"{\"rings\": [7]}", BTF_ERR_FORMAT, "ring 0 is not an object"},
        {"{\"rings\": [{\"count\": 1, \"phi_offset\": 0}]}", BTF_ERR_FORMAT, "missing key \"theta\""},
        {"{\"rings\": [{\"theta\": 0, \"phi_offset\": 0}]}", BTF_ERR_FORMAT, "missing key \"count\""},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1}]}", BTF_ERR_FORMAT, "missing key \"phi_offset\""},
        {"{\"rings\": [{\"theta\": \"0\", \"count\": 1, \"phi_offset\": 0}]}", BTF_ERR_FORMAT, "\"theta\" must be a number"},
        {"{\"rings\": [{\"theta\": 0, \"count\": true, \"phi_offset\": 0}]}", BTF_ERR_FORMAT, "\"count\" must be a number"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": null}]}", BTF_ERR_FORMAT, "must be a number"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1.5, \"phi_offset\": 0}]}", BTF_ERR_FORMAT, "not an integer"},
        {"{\"rings\": [{\"theta\": 10, \"count\": 0, \"phi_offset\": 0}]}", BTF_ERR_RANGE, "count 0"},
        {"{\"rings\": [{\"theta\": 10, \"count\": -3, \"phi_offset\": 0}]}", BTF_ERR_RANGE, "count -3"},
        {"{\"rings\": [{\"theta\": 10, \"count\": 1e12, \"phi_offset\": 0}]}", BTF_ERR_RANGE, "outside 1..2048"},
        {"{\"rings\": [{\"theta\": 10, \"count\": 1e999, \"phi_offset\": 0}]}", BTF_ERR_RANGE, "not finite"},
        {"{\"rings\": [{\"theta\": 95, \"count\": 4, \"phi_offset\": 0}]}", BTF_ERR_RANGE, "theta 95"},
        {"{\"rings\": [{\"theta\": -1, \"count\": 4, \"phi_offset\": 0}]}", BTF_ERR_RANGE, "theta -1"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0}, {\"theta\": 30, \"count\": 6, \"phi_offset\": 0},"
         " {\"theta\": 20, \"count\": 6, \"phi_offset\": 0}]}",
         BTF_ERR_FORMAT, "ascend (ring 2)"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 4, \"phi_offset\": 0}]}", BTF_ERR_FORMAT, "pole"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0, \"phi_ofset\": 3}]}", BTF_ERR_FORMAT,
         "unknown key \"phi_ofset\""},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1, \"count\": 1, \"phi_offset\": 0}]}", BTF_ERR_FORMAT,
         "duplicate key \"count\""},
        {"{\"rings\": [{\"theta\": 10, \"count\": 2000, \"phi_offset\": 0}, {\"theta\": 20, \"count\": 2000, \"phi_offset\": 0}]}",
         BTF_ERR_RANGE, "more than 2048"},
        {"not json at all", BTF_ERR_FORMAT, "not valid JSON"},
        {"{\"rings\": [", BTF_ERR_FORMAT, "not valid JSON"},
        {"{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0}]} trailing", BTF_ERR_FORMAT, "trailing data"},
        {"", BTF_ERR_FORMAT, "empty"},
    };
    char dir[256], path[320];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/bad.json", dir);
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        fx_write_text(path, cases[i].text);
        btf_dirset d;
        btf_error err = {{0}};
        btf_result rc = btf_dirset_load_json(path, &d, &err);
        cr_assert_eq(rc, cases[i].code, "case %zu (%s): code %d (%s): %s", i, cases[i].text, (int)rc,
                     btf_result_string(rc), err.msg);
        cr_assert(strstr(err.msg, cases[i].needle), "case %zu: message \"%s\" lacks \"%s\"", i, err.msg,
                  cases[i].needle);
        cr_assert(strstr(err.msg, path), "case %zu: message \"%s\" does not name the file", i, err.msg);
    }
    unlink(path);
    rmdir(dir);
}

Test(dirset_json, too_many_rings_and_huge_file)
{
    char dir[256], path[320];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(path, sizeof path, "%s/big.json", dir);
    /* 33 rings */
    char text[4096];
    size_t n = (size_t)snprintf(text, sizeof text, "{\"rings\": [");
    for (int r = 0; r < 33; r++)
        n += (size_t)snprintf(text + n, sizeof text - n, "%s{\"theta\": %d, \"count\": 3, \"phi_offset\": 0}",
                              r ? "," : "", 1 + 2 * r);
    snprintf(text + n, sizeof text - n, "]}");
    fx_write_text(path, text);
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_load_json(path, &d, &err), BTF_ERR_RANGE);
    cr_assert(strstr(err.msg, "33 rings"), "%s", err.msg);
    /* a 2 MiB file (valid JSON padded with spaces) is refused before parsing */
    FILE *f = fopen(path, "wb");
    cr_assert(f);
    fputs("{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0}]", f);
    for (int i = 0; i < 2 * 1024; i++) {
        static char pad[1024];
        memset(pad, ' ', sizeof pad);
        fwrite(pad, 1, sizeof pad, f);
    }
    fputs("}", f);
    fclose(f);
    cr_assert_eq(btf_dirset_load_json(path, &d, &err), BTF_ERR_RANGE);
    cr_assert(strstr(err.msg, "larger than"), "%s", err.msg);
    unlink(path);
    rmdir(dir);
}

Test(dirset_json, missing_file_and_bad_args)
{
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_load_json("/nonexistent/dir/rings.json", &d, &err), BTF_ERR_MISSING);
    cr_assert(strstr(err.msg, "/nonexistent/dir/rings.json"), "%s", err.msg);
    cr_assert_eq(btf_dirset_load_json(NULL, &d, &err), BTF_ERR_ARG);
    cr_assert_eq(btf_dirset_load_json("/tmp", &d, &err), BTF_ERR_IO, "a directory: %s", err.msg);
    /* parsing from memory, not NUL-terminated */
    const char txt[] = "{\"rings\":[{\"theta\":0,\"count\":1,\"phi_offset\":0},{\"theta\":45,\"count\":4,\"phi_offset\":45}]}XX";
    cr_assert_eq(btf_dirset_parse_json(txt, sizeof txt - 3, "mem", &d, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(d.n_dirs, 5);
    cr_assert_eq(btf_dirset_parse_json(txt, sizeof txt - 1, "mem", &d, &err), BTF_ERR_FORMAT);
}

/* ------------------------------------------------------------------ dirtab */

static btf_dirtab *tab_of(const btf_dirset *d)
{
    btf_dirtab *t = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirtab_build(d, &t, &err), BTF_OK, "%s", err.msg);
    /* a sphere triangulated with V vertices has 2V - 4 triangles; V = n_dirs + 2
     * with a virtual north pole, n_dirs + 1 when a pole direction replaces it */
    int V = d->n_dirs + (d->rings[0].count > 1 ? 2 : 1);
    cr_assert_eq(t->n_tris, 2 * V - 4, "%d triangles for %d vertices", t->n_tris, V);
    for (int i = 0; i < t->n_tris; i++)
        for (int e = 0; e < 3; e++)
            cr_assert(t->adj[i][e] >= 0, "triangle %d edge %d has no neighbour: not a closed surface", i, e);
    return t;
}

/* The table walk and the ring walk describe the same triangles: same value of f
 * (float rounding of the two paths: the angles vs the vector, < 1e-5) and valid
 * weights at random directions over the whole sphere, below the horizon included. */
Test(interp, dirtab_matches_ring_walk)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    for (int s = 0; s < N_SETS; s++) {
        btf_dirtab *t = tab_of(&sets[s]);
        for (int i = 0; i < 20000; i++) {
            double th, ph;
            rand_dir(i % 4 == 0 ? 180.0 : 90.0, &th, &ph);
            double tc = th > 90 ? 90 : th;
            use_tab = NULL;
            double a = interp_value(&sets[s], tc, ph);
            use_tab = t;
            double b = interp_value(&sets[s], th, ph);
            float v[3] = {(float)(sin(th * D2R) * cos(ph * D2R)), (float)(sin(th * D2R) * sin(ph * D2R)),
                          (float)cos(th * D2R)};
            assert_valid(&sets[s], btf_dirtab_interp_vec(t, v), "dirtab");
            cr_assert(fabs(a - b) < 1e-5, "set %d (%g, %g): ring walk %.7f, table %.7f", s, th, ph, a, b);
        }
        use_tab = NULL;
        btf_dirtab_free(t);
    }
}

/* No seams in the table path either (the same scans as the ring walk's). */
Test(interp, dirtab_continuity)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    const char *names[N_SETS] = {"ubo2003", "dome151", "irregular", "no-pole"};
    for (int s = 0; s < N_SETS; s++) {
        use_tab = tab_of(&sets[s]);
        continuity_scans(&sets[s], names[s]);
        btf_dirtab_free(use_tab);
        use_tab = NULL;
    }
}

/* Every cell's triangle contains the cell's centre, and the walk from it is short:
 * the deepest walk over 200000 random queries stays within BTF_DIRTAB_MAX_STEPS. */
Test(interp, dirtab_exact_at_measured_directions)
{
    btf_dirset sets[N_SETS];
    make_sets(sets);
    for (int s = 0; s < N_SETS; s++) {
        btf_dirtab *t = tab_of(&sets[s]);
        for (int i = 0; i < sets[s].n_dirs; i++) {
            float v[3];
            btf_dirset_vector(&sets[s], i, v);
            btf_interp r = btf_dirtab_interp_vec(t, v);
            cr_assert(weight_of(&r, i) > 1.0 - 1e-5, "set %d direction %d: own weight %g", s, i, weight_of(&r, i));
        }
        btf_dirtab_free(t);
    }
}

Test(interp, dirtab_bad_input)
{
    btf_dirset d = btf_dirset_ubo2003();
    btf_dirtab *t = tab_of(&d);
    float bad[4][3] = {{NAN, 0, 1}, {0, 0, 0}, {INFINITY, 1, 1}, {0, 0, -1}};
    for (int i = 0; i < 4; i++)
        assert_valid(&d, btf_dirtab_interp_vec(t, bad[i]), "bad vector");
    btf_dirtab_free(t);
    btf_dirset none = {0};
    cr_assert_neq(btf_dirtab_build(&none, &t, NULL), BTF_OK);
    cr_assert_neq(btf_dirtab_build(NULL, &t, NULL), BTF_OK);
}

/* Hostile ring tables (rings of one or two directions anywhere, a single ring, huge
 * count jumps, random tables up to the limits) still give a table whose lookups are
 * valid weights everywhere, below the horizon and for NaN/zero vectors included. */
Test(interp, dirtab_degenerate_and_random_tables)
{
    static const btf_ring t1[3] = {{0, 1, 0}, {30, 1, 40}, {60, 2, 10}};
    static const btf_ring t2[2] = {{10, 3, 0}, {80, 200, 0}};
    static const btf_ring t3[1] = {{0, 1, 0}};
    static const btf_ring t4[1] = {{45, 7, 3}};
    static const btf_ring t5[2] = {{20, 2, 0}, {90, 1, 5}};
    const btf_ring *tabs[5] = {t1, t2, t3, t4, t5};
    int n[5] = {3, 2, 1, 1, 2};
    char what[96];
    rng_state = 2718u;
    for (int k = 0; k < 45; k++) {
        btf_dirset d;
        btf_ring r[BTF_MAX_RINGS];
        int nr = k < 5 ? n[k] : 1 + (int)(urand() * BTF_MAX_RINGS);
        for (int i = 0; i < nr && k >= 5; i++) /* ascending theta, counts 1..64, any offset */
            r[i] = (btf_ring){(float)(i == 0 && urand() < 0.3 ? 0.0 : 90.0 * (i + urand()) / nr),
                              1 + (int)(urand() * 64), (float)(720 * urand() - 360)};
        for (int i = 0; i < nr && k >= 5; i++)
            if (r[i].theta_deg == 0.0f)
                r[i].count = 1;
        if (btf_dirset_make(k < 5 ? tabs[k] : r, nr, &d, NULL) != BTF_OK)
            continue; /* e.g. too many directions: refused before any table */
        btf_dirtab *t = NULL;
        cr_assert_eq(btf_dirtab_build(&d, &t, NULL), BTF_OK, "table %d", k);
        for (int m = 0; m < 3000; m++) {
            double th, ph;
            rand_dir(180.0, &th, &ph);
            float v[3] = {(float)(sin(th * D2R) * cos(ph * D2R)), (float)(sin(th * D2R) * sin(ph * D2R)),
                          (float)cos(th * D2R)};
            if (m == 0)
                v[0] = NAN;
            else if (m == 1)
                v[0] = v[1] = v[2] = 0.0f;
            snprintf(what, sizeof what, "table %d (%d rings) theta %g phi %g", k, nr, th, ph);
            assert_valid(&d, btf_dirtab_interp_vec(t, v), what);
        }
        btf_dirtab_free(t);
    }
}
