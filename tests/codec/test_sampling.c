/* test_sampling.c - room codec, suites "sampling" and "slow_sampling": image
 * directories in any sampling (codec/input/btf_ubo2003.c): file
 * names carry whole degrees, so a direction at 52.5 degrees is named 053; the
 * loader matches names to the nearest direction of the set it is given
 * (--sampling) and infers the set when exactly one built-in set fits ("slow_sampling":
 * the 151-direction dome writes 22801 images). */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <string.h>

#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "fixtures.h"
#include "btf_input.h"

/* Writes the knit material in set d as an image directory dir (.ext). */
static btf *write_dir(const btf_dirset *d, int size, const char *dir, const char *ext)
{
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf *b = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_gen_create(&gp, size, size, d, d, BTF_U8, &b, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_save_ubo2003_dir(b, dir, "Knit", ext, &err), BTF_OK, "%s", err.msg);
    return b;
}

/* Mean absolute difference of two BTFs of the same shape, 0..255 scale. */
static double mean_abs(const btf *a, const btf *b)
{
    size_t n = (size_t)a->views.n_dirs * a->lights.n_dirs * btf_image_samples(a);
    double s = 0.0;
    for (size_t i = 0; i < n; i++)
        s += abs((int)((const uint8_t *)a->data)[i] - (int)((const uint8_t *)b->data)[i]);
    return s / (double)n;
}

/* A set with rings at 22.5 and 52.5 degrees: names round them to 023 and 053. */
static btf_dirset half_degree_set(void)
{
    return FX_RINGS({0.0f, 1, 0.0f}, {22.5f, 5, 7.5f}, {52.5f, 7, 0.0f});
}

Test(sampling, half_degree_rings_load_exactly_with_their_set)
{
    char dir[64], img[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    btf_dirset d = half_degree_set();
    btf *ref = write_dir(&d, 4, img, "png");
    btf_load_options o = {0};
    btf *b = NULL;
    btf_error err = {0};
    cr_expect_neq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_OK, "a set no built-in fits was inferred");
    cr_expect(strstr(err.msg, "not in the expected sampling"), "%s", err.msg);
    o.sampling = &d;
    cr_assert_eq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_OK, "%s", err.msg);
    cr_expect(btf_dirset_equal(&b->lights, &d) && btf_dirset_equal(&b->views, &d));
    cr_expect_eq(mean_abs(ref, b), 0.0, "PNG is lossless: every sample must come back in its place");
    btf_free(b), btf_free(ref);
    fx_rmtree(dir);
}

/* gen -> compress -> eval through the commands, with --sampling FILE. */
Test(sampling, commands_take_sampling_json)
{
    char dir[64], set[128], img[128], pkg[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(set, sizeof set, "%s/set.json", dir);
    snprintf(img, sizeof img, "%s/img", dir);
    snprintf(pkg, sizeof pkg, "%s/pkg", dir);
    fx_write_text(set, "{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0},"
                       " {\"theta\": 22.5, \"count\": 5, \"phi_offset\": 7.5},"
                       " {\"theta\": 52.5, \"count\": 7, \"phi_offset\": 0}]}");
    char *gen[] = {"gen", "tiles", img, "--size", "4", "--sampling", set, "--format", "png", NULL};
    cr_assert_eq(cmd_gen(9, gen), 0);
    char *bad[] = {"compress", img, pkg, "--quiet", NULL};
    cr_expect_eq(cmd_compress(4, bad), 1, "compress inferred a set the names do not fit");
    char *comp[] = {"compress", img, pkg, "--sampling", set, "--k", "1", "--components", "4", "--quiet", NULL};
    cr_assert_eq(cmd_compress(10, comp), 0);
    char *ev[] = {"eval", img, pkg, "--sampling", set, "--csv", NULL};
    cr_expect_eq(cmd_eval(6, ev), 0);
    fx_rmtree(dir);
}

/* A dome directory is recognised without --sampling; a missing image is named. */
Test(slow_sampling, dome151_is_inferred_from_the_names, .timeout = 900)
{
    char dir[64], img[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/dome", dir);
    btf_dirset d = btf_dirset_dome151();
    btf *ref = write_dir(&d, 2, img, "jpg");
    btf *b = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_load_ubo2003_dir(img, NULL, &b, &err), BTF_OK, "%s", err.msg);
    cr_expect(btf_dirset_equal(&b->views, &d), "the dome was not inferred (%d directions)", b->views.n_dirs);
    double e = mean_abs(ref, b);
    cr_expect_lt(e, 12.0, "JPEG round trip off by %.2f on average: images in the wrong slots?", e);
    btf_free(b);
    char victim[512];
    snprintf(victim, sizeof victim, "%s/Knit_00000_tl000_pl000_tv000_pv000.jpg", img);
    cr_assert_eq(remove(victim), 0, "%s", victim);
    btf_load_options o = {0};
    o.sampling = &d;
    cr_expect_eq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_ERR_MISSING);
    cr_expect(strstr(err.msg, "tl000_pl000_tv000_pv000"), "%s", err.msg);
    btf_free(ref);
    fx_rmtree(dir);
}

/* Mean absolute difference of image (v, l) of two BTFs, 0..255 scale; and image's mean. */
static double image_diff(const btf *a, const btf *b, int v, int l, double *mean)
{
    size_t n = btf_image_samples(a), at = btf_index(a, v, l, 0, 0, 0);
    double s = 0.0, m = 0.0;
    for (size_t i = 0; i < n; i++) {
        int x = ((const uint8_t *)a->data)[at + i], y = ((const uint8_t *)b->data)[at + i];
        s += abs(x - y), m += x;
    }
    *mean = m / (double)n;
    return s / (double)n;
}

/* Missing images: a clear error naming one, or with fill_missing an interpolation
 * from the view's nearest lights that is close to the truth, never a zero image. */
Test(sampling, missing_images_are_refused_or_interpolated)
{
    char dir[64], img[128], victim[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    btf_dirset d = half_degree_set();
    btf *ref = write_dir(&d, 8, img, "png");
    int lights[2] = {3, 9}, views[2] = {2, 10}; /* (view, light) pairs removed */
    for (int k = 0; k < 2; k++) {
        int tl, pl, tv, pv;
        float t, p;
        btf_dirset_angles(&d, lights[k], &t, &p), tl = (int)lroundf(t), pl = (int)lroundf(p) % 360;
        btf_dirset_angles(&d, views[k], &t, &p), tv = (int)lroundf(t), pv = (int)lroundf(p) % 360;
        snprintf(victim, sizeof victim, "%s/Knit_%05d_tl%03d_pl%03d_tv%03d_pv%03d.png", img,
                 lights[k] * d.n_dirs + views[k], tl, pl, tv, pv);
        cr_assert_eq(remove(victim), 0, "%s", victim);
    }
    btf_load_options o = {0};
    o.sampling = &d;
    btf *b = NULL;
    btf_error err = {0};
    cr_expect_eq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_ERR_MISSING);
    cr_expect(strstr(err.msg, "missing image") && strstr(err.msg, "2 of"), "%s", err.msg);
    int filled = -1;
    o.fill_missing = 1, o.n_filled = &filled;
    cr_assert_eq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(filled, 2);
    for (int k = 0; k < 2; k++) {
        double mean, e = image_diff(ref, b, views[k], lights[k], &mean);
        cr_expect_lt(e, 0.5 * mean, "view %d light %d: interpolated image off by %.1f (mean %.1f)", views[k],
                     lights[k], e, mean);
    }
    double mean, e = image_diff(ref, b, 0, 0, &mean);
    cr_expect_eq(e, 0.0, "a present image changed");
    btf_free(b), btf_free(ref);
    fx_rmtree(dir);
}
