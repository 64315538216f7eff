/* test_gen.c - room gen, suite "gen": the synthetic material generator
 * (bench/gen/btf_gen.h) and `btf gen`. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf.h"
#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "fixtures.h"
#include "btf_input.h"

#define DEG (3.14159265358979 / 180.0)

/* theta 0 (1), 45 (4), 75 (4): 9 directions, enough for most checks. */
static btf_dirset small_set(void)
{
    return FX_RINGS({0, 1, 0}, {45, 4, 0}, {75, 4, 0});
}

static btf *make(btf_gen_kind k, unsigned seed, int size, const btf_dirset *l, const btf_dirset *v, btf_storage st)
{
    btf_gen_params p = btf_gen_defaults(k);
    p.seed = seed;
    btf *b = NULL;
    btf_error e = {{0}};
    cr_assert_eq(btf_gen_create(&p, size, size, l, v, st, &b, &e), BTF_OK, "%s", e.msg);
    return b;
}

static void dir_vec(double theta_deg, double phi_deg, float v[3])
{
    v[0] = (float)(sin(theta_deg * DEG) * cos(phi_deg * DEG));
    v[1] = (float)(sin(theta_deg * DEG) * sin(phi_deg * DEG));
    v[2] = (float)cos(theta_deg * DEG);
}

/* Mean over texels and channels of one (view, light) image. */
static double image_mean(const btf *b, int view, int light)
{
    double s = 0;
    for (int y = 0; y < b->height; y++)
        for (int x = 0; x < b->width; x++)
            for (int c = 0; c < 3; c++)
                s += btf_get(b, view, light, x, y, c);
    return s / (3.0 * b->width * b->height);
}

/* Mean of a model's luminance-like value (channel mean) over all texels for (l, v). */
static double model_mean(const btf_gen_model *m, int size, const float l[3], const float v[3])
{
    double s = 0;
    for (int y = 0; y < size; y++)
        for (int x = 0; x < size; x++) {
            float rgb[3];
            btf_gen_model_eval(m, x, y, l, v, rgb);
            s += (rgb[0] + rgb[1] + rgb[2]) / 3.0;
        }
    return s / (size * size);
}

Test(gen, kind_names_round_trip)
{
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++)
        cr_expect_eq(btf_gen_kind_from_name(btf_gen_kind_name((btf_gen_kind)k)), k);
    cr_expect_eq(btf_gen_kind_from_name("velvet"), -1);
    cr_expect_eq(btf_gen_kind_from_name(NULL), -1);
    cr_expect_str_eq(btf_gen_kind_name((btf_gen_kind)7), "unknown");
}

Test(gen, deterministic_for_a_seed)
{
    btf_dirset d = small_set();
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf *a = make((btf_gen_kind)k, 42, 32, &d, &d, BTF_U8), *b = make((btf_gen_kind)k, 42, 32, &d, &d, BTF_U8);
        cr_assert_eq(a->count, b->count);
        cr_expect_eq(memcmp(a->data, b->data, a->count), 0, "kind %d not deterministic", k);
        btf_free(a);
        btf_free(b);
    }
}

Test(gen, different_seeds_differ)
{
    btf_dirset d = small_set();
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf *a = make((btf_gen_kind)k, 1, 32, &d, &d, BTF_U8), *b = make((btf_gen_kind)k, 2, 32, &d, &d, BTF_U8);
        size_t differ = 0;
        const uint8_t *pa = a->data, *pb = b->data;
        for (size_t i = 0; i < a->count; i++)
            differ += abs((int)pa[i] - (int)pb[i]) > 2;
        /* a new seed re-draws colours, tints, noise: most samples must move by more than 2 levels */
        cr_expect_gt(differ, a->count / 4, "kind %d: only %zu of %zu samples differ", k, differ, a->count);
        btf_free(a);
        btf_free(b);
    }
}

/* Every stored sample equals the model evaluated at the set's direction vectors. */
static void check_eval_matches(btf_storage st, double tol_255)
{
    btf_dirset d = small_set();
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        p.seed = 7;
        btf *b = NULL;
        btf_gen_model *m = NULL;
        cr_assert_eq(btf_gen_create(&p, 24, 20, &d, &d, st, &b, NULL), BTF_OK);
        cr_assert_eq(btf_gen_model_create(&p, 24, 20, &m, NULL), BTF_OK);
        double worst = 0;
        for (int v = 0; v < d.n_dirs; v++)
            for (int l = 0; l < d.n_dirs; l++) {
                float lv[3], vv[3];
                btf_dirset_vector(&d, l, lv);
                btf_dirset_vector(&d, v, vv);
                for (int y = 0; y < 20; y++)
                    for (int x = 0; x < 24; x++) {
                        float rgb[3];
                        btf_gen_model_eval(m, x, y, lv, vv, rgb);
                        for (int c = 0; c < 3; c++)
                            worst = fmax(worst, fabs(255.0 * rgb[c] - 255.0 * btf_get(b, v, l, x, y, c)));
                    }
            }
        cr_expect_leq(worst, tol_255, "kind %d: eval differs from stored by %g levels", k, worst);
        /* the one-shot btf_gen_eval is the same function */
        float lv[3], vv[3], r1[3], r2[3];
        btf_dirset_vector(&d, 5, lv);
        btf_dirset_vector(&d, 3, vv);
        btf_gen_eval(&p, 24, 20, 13, 11, lv, vv, r1);
        btf_gen_model_eval(m, 13, 11, lv, vv, r2);
        cr_expect_eq(memcmp(r1, r2, sizeof r1), 0);
        btf_gen_model_free(m);
        btf_free(b);
    }
}

/* F32 stores exactly the evaluated floats (same code path, same inputs). */
Test(gen, eval_equals_stored_f32) { check_eval_matches(BTF_F32, 0.0); }
/* U8: rounding to the nearest level, so at most half a level (plus float slack). */
Test(gen, eval_equals_stored_u8) { check_eval_matches(BTF_U8, 0.5 + 1e-3); }

Test(gen, brightness_falls_with_theta_light)
{
    btf_dirset l = btf_dirset_ubo2003(), v = small_set();
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf *b = make((btf_gen_kind)k, 3, 32, &l, &v, BTF_F32);
        /* mean over texels, over the ring's lights and over all 9 views */
        double prev = INFINITY;
        for (int r = 0; r < l.n_rings; r++) {
            double s = 0;
            for (int i = 0; i < l.rings[r].count; i++)
                for (int vi = 0; vi < v.n_dirs; vi++)
                    s += image_mean(b, vi, l.ring_start[r] + i);
            s /= l.rings[r].count * v.n_dirs;
            cr_expect_lt(s, prev, "%s: ring theta %g mean %g not below %g", btf_gen_kind_name((btf_gen_kind)k),
                         (double)l.rings[r].theta_deg, s, prev);
            prev = s;
        }
        btf_free(b);
    }
}

/* Texels whose green value under a light at 45 / 80 deg falls below 40% of the value
 * under the top light: more at 80 deg (shadows lengthen) and a real share of the
 * surface (the cos factor alone, cos 80 = 0.17 in linear, is 0.45 in sRGB). */
Test(gen, shadows_lengthen_at_grazing_light)
{
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        btf_gen_model *m = NULL;
        cr_assert_eq(btf_gen_model_create(&p, 32, 32, &m, NULL), BTF_OK);
        float v[3] = {0, 0, 1}, l0[3], l1[3], l2[3];
        dir_vec(0, 0, l0);
        dir_vec(45, 30, l1);
        dir_vec(80, 30, l2);
        int dark45 = 0, dark80 = 0;
        for (int y = 0; y < 32; y++)
            for (int x = 0; x < 32; x++) {
                float a[3], b1[3], b2[3];
                btf_gen_model_eval(m, x, y, l0, v, a);
                btf_gen_model_eval(m, x, y, l1, v, b1);
                btf_gen_model_eval(m, x, y, l2, v, b2);
                dark45 += b1[1] < 0.4f * a[1];
                dark80 += b2[1] < 0.4f * a[1];
            }
        cr_expect_gt(dark80, dark45, "%s: %d dark texels at 80 deg, %d at 45", btf_gen_kind_name((btf_gen_kind)k),
                     dark80, dark45);
        cr_expect_gt(dark80, 32 * 32 / 20, "%s: too few shadowed texels at 80 deg (%d)",
                     btf_gen_kind_name((btf_gen_kind)k), dark80);
        btf_gen_model_free(m);
    }
}

/* Mirror over off-specular mean brightness for view (45, 0): lights (45, 180) vs (45, 90);
 * both lights have the same elevation, so cos factor and shadow length are the same. */
static double specular_ratio(btf_gen_kind k)
{
    btf_gen_params p = btf_gen_defaults(k);
    btf_gen_model *m = NULL;
    cr_assert_eq(btf_gen_model_create(&p, 32, 32, &m, NULL), BTF_OK);
    float v[3], lm[3], lo[3];
    dir_vec(45, 0, v);
    dir_vec(45, 180, lm);
    dir_vec(45, 90, lo);
    double r = model_mean(m, 32, lm, v) / model_mean(m, 32, lo, v);
    btf_gen_model_free(m);
    return r;
}

Test(gen, tiles_are_glossy)
{
    double r = specular_ratio(BTF_GEN_TILES);
    cr_expect_gt(r, 1.25, "tiles mirror/off-specular ratio %g", r);
    /* and the brightest light of the 45-degree ring (18 lights) for that view is the mirror one */
    btf_gen_params p = btf_gen_defaults(BTF_GEN_TILES);
    btf_gen_model *m = NULL;
    cr_assert_eq(btf_gen_model_create(&p, 32, 32, &m, NULL), BTF_OK);
    float v[3];
    dir_vec(45, 0, v);
    int best = -1;
    double best_mean = -1;
    for (int i = 0; i < 18; i++) {
        float l[3];
        dir_vec(45, i * 20.0, l);
        double s = model_mean(m, 32, l, v);
        if (s > best_mean)
            best_mean = s, best = i;
    }
    cr_expect_eq(best * 20, 180, "brightest light at phi %d", best * 20);
    btf_gen_model_free(m);
}

Test(gen, kinds_differ_in_character)
{
    double spec[BTF_GEN_KIND_COUNT], mean[BTF_GEN_KIND_COUNT][3];
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        spec[k] = specular_ratio((btf_gen_kind)k);
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        btf_gen_model *m = NULL;
        cr_assert_eq(btf_gen_model_create(&p, 32, 32, &m, NULL), BTF_OK);
        float top[3] = {0, 0, 1};
        memset(mean[k], 0, sizeof mean[k]);
        for (int y = 0; y < 32; y++)
            for (int x = 0; x < 32; x++) {
                float b[3];
                btf_gen_model_eval(m, x, y, top, top, b);
                for (int c = 0; c < 3; c++)
                    mean[k][c] += b[c] / (32.0 * 32.0);
            }
        btf_gen_model_free(m);
    }
    /* tiles: a clear specular excess (ratio - 1); the matte kinds: almost none, either
     * sign (the knit's stitches make the two azimuths differ a little) */
    cr_expect_gt(spec[BTF_GEN_TILES] - 1.0, 0.25, "tiles %g", spec[BTF_GEN_TILES]);
    cr_expect_lt(fabs(spec[BTF_GEN_STONE] - 1.0), 0.1, "stone %g", spec[BTF_GEN_STONE]);
    cr_expect_lt(fabs(spec[BTF_GEN_KNIT] - 1.0), 0.1, "knit %g", spec[BTF_GEN_KNIT]);
    /* mean colours under a top light differ by more than 0.05 in some channel */
    for (int a = 0; a < BTF_GEN_KIND_COUNT; a++)
        for (int b = a + 1; b < BTF_GEN_KIND_COUNT; b++) {
            double d = 0;
            for (int c = 0; c < 3; c++)
                d = fmax(d, fabs(mean[a][c] - mean[b][c]));
            cr_expect_gt(d, 0.05, "kinds %d and %d have the same mean colour", a, b);
        }
}

Test(gen, grazing_and_below_horizon_are_finite)
{
    float nanv[3] = {NAN, 0, 1}, zero[3] = {0, 0, 0}, infv[3] = {INFINITY, 1, 1}, big[3] = {0, 3e20f, 4e20f};
    const float *odd[4] = {nanv, zero, infv, big};
    double thetas[4] = {89.9, 90, 95, 180};
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        btf_gen_model *m = NULL;
        cr_assert_eq(btf_gen_model_create(&p, 16, 16, &m, NULL), BTF_OK);
        for (int t = 0; t < 4; t++)
            for (int ph = 0; ph < 360; ph += 45)
                for (int y = 0; y < 16; y += 3)
                    for (int x = 0; x < 16; x += 3) {
                        float g[3], n[3], rgb[3];
                        dir_vec(thetas[t], ph, g);
                        dir_vec(30, ph + 100, n);
                        btf_gen_model_eval(m, x, y, n, g, rgb); /* grazing / below-horizon view */
                        for (int c = 0; c < 3; c++)
                            cr_assert(rgb[c] >= 0.0f && rgb[c] <= 1.0f, "view theta %g: %g", thetas[t], rgb[c]);
                        btf_gen_model_eval(m, x, y, g, n, rgb); /* grazing / below-horizon light */
                        for (int c = 0; c < 3; c++) {
                            cr_assert(rgb[c] >= 0.0f && rgb[c] <= 1.0f, "light theta %g: %g", thetas[t], rgb[c]);
                            if (thetas[t] > 90)
                                cr_assert_eq(rgb[c], 0.0f, "light below the horizon is not black");
                            if (thetas[t] == 90) /* z = 6e-17 after rounding: lit, but by nothing */
                                cr_assert_lt(rgb[c], 1e-6f, "light on the horizon: %g", rgb[c]);
                        }
                    }
        for (int i = 0; i < 4; i++) {
            float n[3] = {0.2f, 0.1f, 1.0f}, rgb[3];
            btf_gen_model_eval(m, 3, 4, odd[i], n, rgb);
            for (int c = 0; c < 3; c++)
                cr_expect(rgb[c] >= 0.0f && rgb[c] <= 1.0f, "odd light %d: %g", i, rgb[c]);
            btf_gen_model_eval(m, 3, 4, n, odd[i], rgb);
            for (int c = 0; c < 3; c++)
                cr_expect(rgb[c] >= 0.0f && rgb[c] <= 1.0f, "odd view %d: %g", i, rgb[c]);
        }
        /* a view below the horizon is the horizon view at its azimuth */
        float l[3], v90[3] = {0.6f, 0.8f, 0.0f}, v95[3], a[3], b[3];
        dir_vec(40, 200, l);
        dir_vec(95, atan2(0.8, 0.6) / DEG, v95);
        btf_gen_model_eval(m, 5, 9, l, v90, a);
        btf_gen_model_eval(m, 5, 9, l, v95, b);
        for (int c = 0; c < 3; c++)
            cr_expect_float_eq(a[c], b[c], 1e-5, "view 95 deg differs from the horizon");
        /* texel indices wrap (the material tiles) */
        btf_gen_model_eval(m, 5 + 16, 9 - 32, l, v90, b);
        cr_expect_eq(memcmp(a, b, sizeof a), 0);
        btf_gen_model_free(m);
    }
}

/* Continuity: a perturbation of 1e-4 rad changes values by little, and crossing the
 * horizon (light 89.99 -> 90.01 deg, view likewise) has no jump. A jump (e.g. a march
 * whose step count depends on the direction) would not shrink with the perturbation. */
Test(gen, continuous_in_light_and_view)
{
    unsigned s = 12345u;
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        btf_gen_model *m = NULL;
        cr_assert_eq(btf_gen_model_create(&p, 32, 32, &m, NULL), BTF_OK);
        double worst = 0;
        for (int i = 0; i < 3000; i++) {
            fx_lcg_nr(&s);
            int x = (int)(s >> 8) % 32, y = (int)(s >> 16) % 32;
            double tl = (s % 8500) / 100.0, pl = (s % 3600) / 10.0, tv = ((s >> 4) % 8800) / 100.0,
                   pv = ((s >> 3) % 3600) / 10.0, e = 1e-4 / DEG;
            float l[3], v[3], l2[3], v2[3], a[3], b[3], c2[3];
            dir_vec(tl, pl, l), dir_vec(tv, pv, v), dir_vec(tl + e, pl + e, l2), dir_vec(tv + e, pv - e, v2);
            btf_gen_model_eval(m, x, y, l, v, a);
            btf_gen_model_eval(m, x, y, l2, v, b);
            btf_gen_model_eval(m, x, y, l, v2, c2);
            for (int c = 0; c < 3; c++)
                worst = fmax(worst, fmax(fabs(a[c] - b[c]), fabs(a[c] - c2[c])));
        }
        /* steepest places: silhouettes at near-grazing views (the soft first hit blends
         * front and back over about a march step); measured 0.032 there, and 10x less at
         * 1e-5 rad, i.e. steep but continuous. A jump (a march whose step count depends
         * on the direction, a wrong pole or horizon case) is 0.1 or more. */
        cr_expect_lt(worst, 0.05, "%s: a 1e-4 rad change moved a value by %g", btf_gen_kind_name((btf_gen_kind)k),
                     worst);
        float l0[3], l1[3], v[3] = {0.1f, 0.2f, 1.0f}, a[3], b[3];
        dir_vec(89.99, 33, l0);
        dir_vec(90.01, 33, l1);
        btf_gen_model_eval(m, 4, 4, l0, v, a);
        btf_gen_model_eval(m, 4, 4, l1, v, b);
        for (int c = 0; c < 3; c++)
            cr_expect_lt(fabs(a[c] - b[c]), 0.01, "light horizon jump %g -> %g", a[c], b[c]);
        dir_vec(89.99, 33, l0);
        dir_vec(90.01, 33, l1);
        float lt[3];
        dir_vec(30, 10, lt);
        btf_gen_model_eval(m, 4, 4, lt, l0, a);
        btf_gen_model_eval(m, 4, 4, lt, l1, b);
        for (int c = 0; c < 3; c++)
            cr_expect_lt(fabs(a[c] - b[c]), 0.01, "view horizon jump %g -> %g", a[c], b[c]);
        btf_gen_model_free(m);
    }
}

/* Where a direction-dependent special case could hide a jump: the pole (azimuth
 * undefined) and the parallax cap tan(theta_v) = 8 (82.87 deg). */
Test(gen, continuous_at_pole_and_parallax_cap)
{
    double cap = atan(8.0) / DEG;
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        btf_gen_model *m = NULL;
        cr_assert_eq(btf_gen_model_create(&p, 16, 16, &m, NULL), BTF_OK);
        float top[3] = {0, 0, 1}, other[3], ref_l[3], ref_v[3];
        dir_vec(40, 120, other);
        btf_gen_model_eval(m, 6, 7, top, other, ref_l);
        btf_gen_model_eval(m, 6, 7, other, top, ref_v);
        for (int ph = 0; ph < 360; ph += 30) {
            float d[3], a[3], b[3];
            dir_vec(1e-3, ph, d);
            btf_gen_model_eval(m, 6, 7, d, other, a);
            btf_gen_model_eval(m, 6, 7, other, d, b);
            for (int c = 0; c < 3; c++) { /* 1e-3 deg: values move by ~1e-5 per unit slope */
                cr_expect_lt(fabs(a[c] - ref_l[c]), 1e-3, "light near the pole, phi %d", ph);
                cr_expect_lt(fabs(b[c] - ref_v[c]), 1e-3, "view near the pole, phi %d", ph);
            }
        }
        for (int y = 0; y < 16; y += 5)
            for (int x = 0; x < 16; x += 5) {
                float lo[3], hi[3], a[3], b[3];
                dir_vec(cap - 1e-4, 20, lo);
                dir_vec(cap + 1e-4, 20, hi);
                btf_gen_model_eval(m, x, y, other, lo, a);
                btf_gen_model_eval(m, x, y, other, hi, b);
                for (int c = 0; c < 3; c++)
                    cr_expect_lt(fabs(a[c] - b[c]), 5e-3, "view across the parallax cap, texel %d %d", x, y);
            }
        btf_gen_model_free(m);
    }
}

/* Circular cross-correlation (mean-removed green channel) of two size x size images;
 * returns the shift (dx, dy) of b relative to a with the highest correlation. */
static void best_shift(const float *a, const float *b, int size, int *bx, int *by)
{
    double ma = 0, mb = 0, best = -INFINITY;
    for (int i = 0; i < size * size; i++)
        ma += a[i], mb += b[i];
    ma /= size * size, mb /= size * size;
    for (int dy = -size / 2; dy < size / 2; dy++)
        for (int dx = -size / 2; dx < size / 2; dx++) {
            double s = 0;
            for (int y = 0; y < size; y++)
                for (int x = 0; x < size; x++) {
                    int xs = ((x + dx) % size + size) % size, ys = ((y + dy) % size + size) % size;
                    s += (a[y * size + x] - ma) * (b[ys * size + xs] - mb);
                }
            if (s > best)
                best = s, *bx = dx, *by = dy;
        }
}

/* Rectification on the base plane: raised, visible texture appears displaced away from
 * the viewer by height * tan(theta_v): for a view towards +x (phi 0) the content moves to
 * lower columns; towards phi 90 (image row 0) it moves to higher rows. */
Test(gen, parallax_shifts_grazing_views)
{
    const int size = 32;
    for (int k = 0; k < BTF_GEN_KIND_COUNT; k++) {
        btf_gen_params p = btf_gen_defaults((btf_gen_kind)k);
        btf_gen_model *m = NULL;
        p.spec_strength = 0; /* compare the diffuse texture only */
        cr_assert_eq(btf_gen_model_create(&p, size, size, &m, NULL), BTF_OK);
        float top[3] = {0, 0, 1}, l[3] = {0, 0, 1}, v0[3], v90[3];
        dir_vec(75, 0, v0);
        dir_vec(75, 90, v90);
        float *a = malloc(sizeof(float) * size * size * 3), *b = a + size * size, *c = b + size * size;
        for (int y = 0; y < size; y++)
            for (int x = 0; x < size; x++) {
                float rgb[3];
                btf_gen_model_eval(m, x, y, l, top, rgb);
                a[y * size + x] = rgb[1];
                btf_gen_model_eval(m, x, y, l, v0, rgb);
                b[y * size + x] = rgb[1];
                btf_gen_model_eval(m, x, y, l, v90, rgb);
                c[y * size + x] = rgb[1];
            }
        int dx, dy;
        best_shift(a, b, size, &dx, &dy);
        cr_expect_lt(dx, 0, "%s: phi 0 view shifted by (%d, %d)", btf_gen_kind_name((btf_gen_kind)k), dx, dy);
        cr_expect_leq(abs(dy), 1, "%s: phi 0 view shifted by (%d, %d)", btf_gen_kind_name((btf_gen_kind)k), dx, dy);
        best_shift(a, c, size, &dx, &dy);
        cr_expect_gt(dy, 0, "%s: phi 90 view shifted by (%d, %d)", btf_gen_kind_name((btf_gen_kind)k), dx, dy);
        cr_expect_leq(abs(dx), 1, "%s: phi 90 view shifted by (%d, %d)", btf_gen_kind_name((btf_gen_kind)k), dx, dy);
        free(a);
        btf_gen_model_free(m);
    }
}

Test(gen, dome151_sampling)
{
    btf_dirset d = btf_dirset_dome151(), v = small_set();
    cr_assert_eq(d.n_dirs, 151);
    btf *b = make(BTF_GEN_STONE, 5, 16, &d, &v, BTF_F32);
    cr_expect_eq(b->lights.n_dirs, 151);
    cr_expect_eq(b->views.n_dirs, 9);
    btf_gen_params p = btf_gen_defaults(BTF_GEN_STONE);
    p.seed = 5;
    btf_gen_model *m = NULL;
    cr_assert_eq(btf_gen_model_create(&p, 16, 16, &m, NULL), BTF_OK);
    for (int i = 0; i < 200; i++) {
        int l = (i * 37) % 151, vi = i % 9, x = (i * 7) % 16, y = (i * 11) % 16;
        float lv[3], vv[3], rgb[3];
        btf_dirset_vector(&d, l, lv);
        btf_dirset_vector(&v, vi, vv);
        btf_gen_model_eval(m, x, y, lv, vv, rgb);
        for (int c = 0; c < 3; c++)
            cr_expect_eq(rgb[c], btf_get(b, vi, l, x, y, c), "light %d view %d", l, vi);
    }
    double prev = INFINITY; /* ring means fall with theta here too (top view) */
    for (int r = 0; r < d.n_rings; r++) {
        double s = 0;
        for (int i = 0; i < d.rings[r].count; i++)
            s += image_mean(b, 0, d.ring_start[r] + i);
        s /= d.rings[r].count;
        cr_expect_lt(s, prev, "ring %d", r);
        prev = s;
    }
    btf_gen_model_free(m);
    btf_free(b);
}

Test(gen, bad_arguments_fail_cleanly)
{
    btf_dirset d = small_set(), empty = {0};
    btf_gen_params p = btf_gen_defaults(BTF_GEN_KNIT);
    btf *b = (btf *)1;
    btf_error e = {{0}};
    cr_expect_eq(btf_gen_create(&p, 0, 8, &d, &d, BTF_U8, &b, &e), BTF_ERR_RANGE);
    cr_expect_null(b);
    cr_expect(strstr(e.msg, "0x8") != NULL, "%s", e.msg);
    cr_expect_eq(btf_gen_create(&p, 8, BTF_MAX_SIDE + 1, &d, &d, BTF_U8, &b, &e), BTF_ERR_RANGE);
    cr_expect_eq(btf_gen_create(&p, 8, 8, &empty, &d, BTF_U8, &b, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_gen_create(&p, 8, 8, NULL, &d, BTF_U8, &b, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_gen_create(NULL, 8, 8, &d, &d, BTF_U8, &b, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_gen_create(&p, 8, 8, &d, &d, BTF_U8, NULL, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_gen_create(&p, 8, 8, &d, &d, (btf_storage)9, &b, &e), BTF_ERR_ARG);
    btf_gen_params q = p;
    q.kind = (btf_gen_kind)5;
    cr_expect_eq(btf_gen_create(&q, 8, 8, &d, &d, BTF_U8, &b, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "kind") != NULL, "%s", e.msg);
    q = p, q.height_scale = NAN;
    cr_expect_eq(btf_gen_check_params(&q, &e), BTF_ERR_RANGE);
    cr_expect(strstr(e.msg, "height_scale") != NULL, "%s", e.msg);
    q = p, q.roughness_min = 0.9f, q.roughness_max = 0.2f;
    cr_expect_eq(btf_gen_check_params(&q, &e), BTF_ERR_RANGE);
    q = p, q.spec_strength = -1;
    cr_expect_eq(btf_gen_check_params(&q, &e), BTF_ERR_RANGE);
    q = p, q.repeats = 100000;
    cr_expect_eq(btf_gen_check_params(&q, &e), BTF_ERR_RANGE);
    /* btf_gen_eval with bad parameters: black, not a crash */
    float l[3] = {0, 0, 1}, rgb[3] = {1, 1, 1};
    btf_gen_eval(&q, 8, 8, 0, 0, l, l, rgb);
    cr_expect(rgb[0] == 0 && rgb[1] == 0 && rgb[2] == 0);
    btf_gen_eval(&p, -3, 8, 0, 0, l, l, rgb);
    cr_expect(rgb[0] == 0 && rgb[1] == 0 && rgb[2] == 0);
    btf_gen_model_free(NULL);
    /* flat material (no relief) still works: no division by a zero range */
    q = p, q.height_scale = 0;
    btf_gen_model *m = NULL;
    cr_assert_eq(btf_gen_model_create(&q, 8, 8, &m, NULL), BTF_OK);
    float v[3] = {0.9f, 0.0f, 0.1f};
    btf_gen_model_eval(m, 1, 1, l, v, rgb);
    cr_expect(rgb[0] > 0 && rgb[0] <= 1);
    btf_gen_model_free(m);
}

/* ---------------------------------------------------------------- the command */

static int run_gen(const char *a0, const char *a1, const char *a2, const char *a3, const char *a4, const char *a5,
                   const char *a6, const char *a7, const char *a8)
{
    const char *all[] = {"gen", a0, a1, a2, a3, a4, a5, a6, a7, a8};
    char *argv[11];
    int n = 0;
    for (int i = 0; i < 10 && all[i]; i++)
        argv[n++] = (char *)all[i];
    argv[n] = NULL;
    return cmd_gen(n, argv);
}

Test(gen, cli_writes_images_that_load_back)
{
    char dir[64], json[128], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(json, sizeof json, "%s/set.json", dir);
    snprintf(out, sizeof out, "%s/tiles8", dir);
    fx_write_text(json, "{\"rings\":[{\"theta\":0,\"count\":1,\"phi_offset\":0},"
                        "{\"theta\":45,\"count\":4,\"phi_offset\":0}]}");
    cr_assert_eq(run_gen("tiles", out, "--size", "8", "--sampling", json, "--seed", "9", NULL), 0);
    btf_dirset d;
    cr_assert_eq(btf_dirset_load_json(json, &d, NULL), BTF_OK);
    btf_load_options o = {0};
    o.sampling = &d;
    btf *got = NULL, *want = NULL;
    btf_error e = {{0}};
    cr_assert_eq(btf_load_ubo2003_dir(out, &o, &got, &e), BTF_OK, "%s", e.msg);
    btf_gen_params p = btf_gen_defaults(BTF_GEN_TILES);
    p.seed = 9;
    cr_assert_eq(btf_gen_create(&p, 8, 8, &d, &d, BTF_U8, &want, NULL), BTF_OK);
    cr_assert_eq(got->count, want->count);
    size_t bad = 0;
    for (size_t i = 0; i < got->count; i++) /* PNG is lossless */
        bad += ((uint8_t *)got->data)[i] != ((uint8_t *)want->data)[i];
    cr_expect_eq(bad, 0, "%zu samples differ after the PNG round trip", bad);
    btf_free(got);
    btf_free(want);
}

Test(gen, cli_writes_dfmf_that_loads_back)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf_dirset d = btf_dirset_ubo2003();
    btf *got = NULL, *want = NULL;
    btf_error e = {{0}};
    /* DFMF file, full rank: float factors of the byte data, exact to float rounding */
    snprintf(out, sizeof out, "%s/knit.btf", dir);
    cr_assert_eq(run_gen("knit", out, "--size", "4", "--seed", "3", NULL, NULL, NULL), 0);
    cr_assert_eq(btf_load_dfmf(out, NULL, &got, &e), BTF_OK, "%s", e.msg);
    btf_gen_params p = btf_gen_defaults(BTF_GEN_KNIT);
    p.seed = 3;
    cr_assert_eq(btf_gen_create(&p, 4, 4, &d, &d, BTF_U8, &want, NULL), BTF_OK);
    cr_assert_eq(got->count, want->count);
    cr_assert(btf_dirset_equal(&got->lights, &d) && btf_dirset_equal(&got->views, &d));
    double worst = 0;
    for (int v = 0; v < d.n_dirs; v++)
        for (int l = 0; l < d.n_dirs; l++)
            for (int y = 0; y < 4; y++)
                for (int x = 0; x < 4; x++)
                    for (int c = 0; c < 3; c++)
                        worst = fmax(worst, fabs(btf_get(got, v, l, x, y, c) - btf_get(want, v, l, x, y, c)));
    cr_expect_lt(worst, 1e-3, "DFMF round trip off by %g", worst);
    btf_free(got);
    btf_free(want);
}

Test(gen, cli_rejects_bad_usage)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/x", dir);
    cr_expect_eq(run_gen("velvet", out, NULL, NULL, NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", out, "--size", "0", NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", out, "--size", "12x", NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", out, "--format", "gif", NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", out, "--seed", NULL, NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", out, "--components", "-1", NULL, NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("knit", out, "extra", "--size", "4", NULL, NULL, NULL, NULL), 2);
    cr_expect_eq(run_gen("--help", NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL), 0);
    /* failures: a missing sampling file; an output directory under a regular file */
    cr_expect_eq(run_gen("knit", out, "--size", "4", "--sampling", "/nonexistent/set.json", NULL, NULL, NULL), 1);
    fx_write_text(out, "");
    char under[160];
    snprintf(under, sizeof under, "%s/sub", out);
    cr_expect_eq(run_gen("knit", under, "--size", "2", NULL, NULL, NULL, NULL, NULL), 1);
}
