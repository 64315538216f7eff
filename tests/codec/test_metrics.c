/* test_metrics.c - room codec, suite "metrics": RGB and CIELab error metrics
 * (codec/common/btf_metrics.c), and `btf eval`'s output and exit codes. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>
#include <unistd.h>

#include "btf_color.h"
#include "btf_metrics.h"
#include "fixtures.h"

/* ---------------------------------------------------------------- helpers */

/* Small direction set (1 + 4 directions) so BTFs stay tiny. */
static btf_dirset small_dirs(void)
{
    return FX_RINGS({0, 1, 0}, {45, 4, 0});
}

static btf *make_btf(int w, int h, const btf_dirset *l, const btf_dirset *v, btf_storage s)
{
    btf *b = NULL;
    btf_error e = {0};
    cr_assert_eq(btf_create(w, h, l, v, s, &b, &e), BTF_OK, "%s", e.msg);
    return b;
}

/* Deterministic pseudo-random bytes (LCG). */
static uint8_t next_byte(uint32_t *s)
{
    return (uint8_t)(fx_lcg_nr(s) >> 24);
}

static void fill_random_u8(btf *b, uint32_t seed)
{
    uint8_t *p = b->data;
    for (size_t i = 0; i < b->count; i++)
        p[i] = next_byte(&seed);
}

static void one_pair(const float a[3], const float b[3], btf_metrics *m)
{
    btf_metrics_acc acc = {0};
    btf_metrics_add(&acc, a, b, 1);
    btf_metrics_finish(&acc, m);
}

/* Independent CIELab conversion in double. The white (Xn, Yn, Zn) is the XYZ of
 * sRGB (1, 1, 1) through the matrix, i.e. the D65 white sRGB is defined against
 * (0.95047, 1, 1.08883); deriving it from the xy chromaticity (0.3127, 0.3290)
 * instead moves b* by up to 0.014, which is the convention, not an error. */
static void ref_lab(double r8, double g8, double b8, double lab[3])
{
    double rgb[3] = {r8 / 255.0, g8 / 255.0, b8 / 255.0}, lin[3];
    for (int c = 0; c < 3; c++)
        lin[c] = rgb[c] <= 0.04045 ? rgb[c] / 12.92 : pow((rgb[c] + 0.055) / 1.055, 2.4);
    double X = 0.4124564 * lin[0] + 0.3575761 * lin[1] + 0.1804375 * lin[2];
    double Y = 0.2126729 * lin[0] + 0.7151522 * lin[1] + 0.0721750 * lin[2];
    double Z = 0.0193339 * lin[0] + 0.1191920 * lin[1] + 0.9503041 * lin[2];
    double xn = 0.4124564 + 0.3575761 + 0.1804375, zn = 0.0193339 + 0.1191920 + 0.9503041;
    double t[3] = {X / xn, Y, Z / zn}, f[3];
    for (int c = 0; c < 3; c++)
        f[c] = t[c] > pow(6.0 / 29.0, 3) ? cbrt(t[c]) : t[c] / (3.0 * pow(6.0 / 29.0, 2)) + 4.0 / 29.0;
    lab[0] = 116.0 * f[1] - 16.0;
    lab[1] = 500.0 * (f[0] - f[1]);
    lab[2] = 200.0 * (f[1] - f[2]);
}

/* ---------------------------------------------------------------- Lab of single colours */

static void expect_lab(float r, float g, float b, double L, double A, double B, double tol)
{
    float rgb[3] = {r / 255.0f, g / 255.0f, b / 255.0f}, lab[3];
    btf_color_srgb_to_lab(rgb, lab);
    cr_expect(fabs(lab[0] - L) <= tol && fabs(lab[1] - A) <= tol && fabs(lab[2] - B) <= tol,
              "(%g,%g,%g) -> Lab (%.4f, %.4f, %.4f), expected (%.4f, %.4f, %.4f) +- %g", r, g, b, lab[0], lab[1],
              lab[2], L, A, B, tol);
}

Test(metrics, lab_of_known_colours)
{
    /* White and black are exact by construction (Xn, Yn, Zn are the matrix row
     * sums): 0.01 allows only float rounding. */
    expect_lab(255, 255, 255, 100.0, 0.0, 0.0, 0.01);
    expect_lab(0, 0, 0, 0.0, 0.0, 0.0, 0.01);
    /* Published sRGB/D65 values (Lindbloom's calculator, 2 decimals): tolerance
     * 0.05 covers the rounding of the published figures and of the white point. */
    expect_lab(255, 0, 0, 53.24, 80.09, 67.20, 0.05);
    expect_lab(0, 255, 0, 87.73, -86.18, 83.18, 0.05);
    expect_lab(0, 0, 255, 32.30, 79.19, -107.86, 0.05);
    /* Mid grey: neutral, L* 53.59 (published 53.585). */
    expect_lab(128, 128, 128, 53.59, 0.0, 0.0, 0.01);
}

Test(metrics, lab_clamps_out_of_range_and_nan)
{
    float over[3] = {2.0f, 1.5f, 7.0f}, under[3] = {-1.0f, -0.5f, NAN}, lab[3];
    btf_color_srgb_to_lab(over, lab);
    cr_expect(fabsf(lab[0] - 100.0f) < 0.01f && fabsf(lab[1]) < 0.01f && fabsf(lab[2]) < 0.01f);
    btf_color_srgb_to_lab(under, lab);
    cr_expect(fabsf(lab[0]) < 0.01f && fabsf(lab[1]) < 0.01f && fabsf(lab[2]) < 0.01f);
}

Test(metrics, lab_matches_independent_double_conversion)
{
    /* Every 15th value of each channel (18^3 colours): the library's reference
     * conversion against the double-precision one above; 0.001 covers the float
     * output (|Lab| <= 130, float ulp ~1e-5). */
    double worst = 0.0;
    for (int r = 0; r < 256; r += 15)
        for (int g = 0; g < 256; g += 15)
            for (int b = 0; b < 256; b += 15) {
                float rgb[3] = {r / 255.0f, g / 255.0f, b / 255.0f}, lab[3];
                double want[3];
                btf_color_srgb_to_lab(rgb, lab);
                ref_lab(r, g, b, want);
                for (int c = 0; c < 3; c++)
                    worst = fmax(worst, fabs(lab[c] - want[c]));
            }
    cr_expect_lt(worst, 0.001, "worst Lab difference %g", worst);
}

/* ---------------------------------------------------------------- the fast path */

Test(metrics, fast_path_matches_reference_conversion)
{
    /* btf_metrics_add uses tables and a float cube root; for one pair its Delta E
     * must equal the distance of the reference Lab values. Byte values go through
     * the 256-entry table, the off-grid values (x + 0.37)/255 through the
     * interpolated one. Tolerance 5e-4 Delta E: float Lab (|L| <= 100, ulp ~1e-5)
     * plus the documented < 1e-4 L error of the interpolated decode. */
    const float partner[2][3] = {{0.5f, 0.25f, 0.75f}, {0.02f, 0.9f, 0.0f}};
    double worst = 0.0;
    for (int off = 0; off < 2; off++)
        for (int r = 0; r < 256; r += 17)
            for (int g = 0; g < 256; g += 17)
                for (int b = 0; b < 256; b += 17)
                    for (int p = 0; p < 2; p++) {
                        float o = off ? 0.37f : 0.0f;
                        float c[3] = {(r + o) / 255.0f, (g + o) / 255.0f, (b + o) / 255.0f};
                        float l1[3], l2[3];
                        btf_color_srgb_to_lab(c, l1);
                        btf_color_srgb_to_lab(partner[p], l2);
                        double de = sqrt(pow(l1[0] - l2[0], 2) + pow(l1[1] - l2[1], 2) + pow(l1[2] - l2[2], 2));
                        double th = (fabs(l1[0] - l2[0]) + fabs(l1[1] - l2[1]) + fabs(l1[2] - l2[2])) / 3.0;
                        btf_metrics m;
                        one_pair(c, partner[p], &m);
                        worst = fmax(worst, fmax(fabs(m.delta_e76 - de), fabs(m.lab_thesis - th)));
                    }
    cr_expect_lt(worst, 5e-4, "worst fast-path difference %g", worst);
}

Test(metrics, a_reference_lab_given_once_gives_the_same_sums)
{
    /* The error curve converts its reference once (btf_metrics_lab) for many tests
     * (btf_metrics_add_lab): the sums must be those of btf_metrics_add bit for bit,
     * over off-grid values, byte values, out-of-range values, pixels equal to the
     * reference and a count that is neither a multiple of 4 nor of the queue. */
    enum { N = 301 };
    float ref[3 * N], test[3 * N], lab[3 * N];
    uint32_t seed = 4242;
    for (int i = 0; i < 3 * N; i++) {
        ref[i] = (float)next_byte(&seed) / 255.0f + (i % 7 == 0 ? 0.0013f : 0.0f);
        test[i] = (float)next_byte(&seed) / 250.0f - 0.01f;
    }
    memcpy(test + 30, ref + 30, 9 * sizeof(float)); /* three pixels without error */
    btf_metrics_lab(ref, N, lab);
    btf_metrics_acc a = {0}, b = {0};
    btf_metrics_add(&a, ref, test, N);
    btf_metrics_add_lab(&b, ref, lab, test, N);
    cr_expect(a.sum_lab == b.sum_lab && a.sum_de == b.sum_de, "Lab %.17g vs %.17g, Delta E %.17g vs %.17g", a.sum_lab,
              b.sum_lab, a.sum_de, b.sum_de);
    cr_expect(a.sum_abs == b.sum_abs && a.sum_sq == b.sum_sq && a.pixels == b.pixels && a.samples == b.samples);
    /* and the Lab it gives is the reference conversion's (tolerance as in the fast
     * path test: float Lab plus the interpolated decode's < 1e-4 in L) */
    double worst = 0.0;
    for (int i = 0; i < N; i++) {
        float want[3];
        btf_color_srgb_to_lab(ref + 3 * i, want);
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(lab[3 * i + c] - want[c]));
    }
    cr_expect_lt(worst, 5e-4, "worst Lab difference %g", worst);
}

/* ---------------------------------------------------------------- RGB metrics by hand */

Test(metrics, mae_rmse_psnr_by_hand)
{
    /* Two pixels on the 0..255 scale. Differences: 2, 0, 3 and 0, 0, 255. */
    const float ref[6] = {10 / 255.0f, 20 / 255.0f, 30 / 255.0f, 0, 0, 0};
    const float test[6] = {12 / 255.0f, 20 / 255.0f, 27 / 255.0f, 0, 0, 1.0f};
    btf_metrics_acc acc = {0};
    btf_metrics m;
    btf_metrics_add(&acc, ref, test, 2);
    btf_metrics_finish(&acc, &m);
    double mae = (2.0 + 3.0 + 255.0) / 6.0;
    double rmse = sqrt((4.0 + 9.0 + 65025.0) / 6.0);
    /* 1e-4: the inputs are float (x/255 carries ~3e-8 relative error). */
    cr_expect(fabs(m.mae - mae) < 1e-4, "mae %f vs %f", m.mae, mae);
    cr_expect(fabs(m.rmse - rmse) < 1e-4, "rmse %f vs %f", m.rmse, rmse);
    cr_expect(fabs(m.psnr - 20.0 * log10(255.0 / rmse)) < 1e-4, "psnr %f", m.psnr);
    cr_expect_eq(m.pixels, 2u);
    cr_expect_eq(acc.samples, 6u);
}

Test(metrics, rgb_metrics_unclamped_lab_clamped)
{
    /* 1.5 vs 1.0 is 127.5 apart on the 0..255 scale but both show as white. */
    const float a[3] = {1.5f, 1.5f, 1.5f}, b[3] = {1.0f, 1.0f, 1.0f};
    btf_metrics m;
    one_pair(a, b, &m);
    cr_expect(fabs(m.mae - 127.5) < 1e-3, "mae %f", m.mae);
    cr_expect(m.lab_thesis < 1e-6 && m.delta_e76 < 1e-6, "lab %f de %f", m.lab_thesis, m.delta_e76);
}

Test(metrics, delta_e_versus_thesis_lab_mae)
{
    /* White vs black: dL = 100, da = db = 0: thesis MAE 100/3, Delta E 100. */
    const float w[3] = {1, 1, 1}, k[3] = {0, 0, 0}, red[3] = {1, 0, 0};
    btf_metrics m;
    one_pair(w, k, &m);
    cr_expect(fabs(m.lab_thesis - 100.0 / 3.0) < 0.01, "thesis %f", m.lab_thesis);
    cr_expect(fabs(m.delta_e76 - 100.0) < 0.01, "de %f", m.delta_e76);
    /* Red vs black with red's published Lab (53.24, 80.09, 67.20): thesis MAE is
     * their mean 66.84, Delta E their norm 117.34; 0.05 as for the published Lab. */
    one_pair(red, k, &m);
    cr_expect(fabs(m.lab_thesis - (53.24 + 80.09 + 67.20) / 3.0) < 0.05, "thesis %f", m.lab_thesis);
    cr_expect(fabs(m.delta_e76 - sqrt(53.24 * 53.24 + 80.09 * 80.09 + 67.20 * 67.20)) < 0.05, "de %f",
              m.delta_e76);
    /* Over several pixels both are means: pairs (w,k) and (red,k) average. */
    btf_metrics_acc acc = {0};
    btf_metrics_add(&acc, w, k, 1);
    btf_metrics_add(&acc, red, k, 1);
    btf_metrics_finish(&acc, &m);
    cr_expect(fabs(m.delta_e76 - (100.0 + 117.34) / 2.0) < 0.05, "mean de %f", m.delta_e76);
    cr_expect_eq(m.pixels, 2u);
}

Test(metrics, finish_of_empty_accumulator)
{
    btf_metrics_acc acc = {0};
    btf_metrics m;
    btf_metrics_add(&acc, NULL, NULL, 3); /* ignored */
    btf_metrics_finish(&acc, &m);
    cr_expect_eq(m.pixels, 0u);
    cr_expect_eq(m.mae, 0.0);
    cr_expect_eq(m.psnr, 999.0);
}

/* ---------------------------------------------------------------- btf_compare */

Test(metrics, identical_btfs_have_zero_error)
{
    btf_dirset d = small_dirs();
    for (int s = BTF_U8; s <= BTF_F32; s++) {
        btf *a = make_btf(8, 6, &d, &d, BTF_U8);
        fill_random_u8(a, 7);
        btf *a2 = fx_convert(a, (btf_storage)s), *b = fx_convert(a, (btf_storage)s);
        btf_metrics m;
        btf_error e = {0};
        cr_assert_eq(btf_compare(a2, b, NULL, &m, &e), BTF_OK, "%s", e.msg);
        cr_expect_eq(m.mae, 0.0);
        cr_expect_eq(m.rmse, 0.0);
        cr_expect_eq(m.lab_thesis, 0.0);
        cr_expect_eq(m.delta_e76, 0.0);
        cr_expect_eq(m.psnr, 999.0, "PSNR sentinel, got %f", m.psnr);
        cr_expect_eq(m.pixels, (size_t)8 * 6 * 5 * 5);
        btf_free(a);
        btf_free(a2);
        btf_free(b);
    }
}

Test(metrics, compare_equals_per_pixel_sums)
{
    /* Random 4x3 BTF pair: btf_compare against an independent loop over btf_get
     * with the double Lab conversion of this file. Tolerances: 1e-9 relative for
     * the exact integer RGB sums, 2e-3 for the Lab means (float fast path). */
    btf_dirset d = small_dirs();
    btf *a = make_btf(4, 3, &d, &d, BTF_U8), *b = make_btf(4, 3, &d, &d, BTF_U8);
    fill_random_u8(a, 1);
    fill_random_u8(b, 2);
    double sabs = 0, ssq = 0, slab = 0, sde = 0;
    size_t n = 0;
    for (int v = 0; v < 5; v++)
        for (int l = 0; l < 5; l++)
            for (int y = 0; y < 3; y++)
                for (int x = 0; x < 4; x++, n++) {
                    double pa[3], pb[3], la[3], lb[3], dd = 0, dl = 0;
                    for (int c = 0; c < 3; c++) {
                        pa[c] = ((uint8_t *)a->data)[btf_index(a, v, l, x, y, c)];
                        pb[c] = ((uint8_t *)b->data)[btf_index(b, v, l, x, y, c)];
                        sabs += fabs(pa[c] - pb[c]);
                        ssq += (pa[c] - pb[c]) * (pa[c] - pb[c]);
                    }
                    ref_lab(pa[0], pa[1], pa[2], la);
                    ref_lab(pb[0], pb[1], pb[2], lb);
                    for (int c = 0; c < 3; c++) {
                        dl += fabs(la[c] - lb[c]);
                        dd += (la[c] - lb[c]) * (la[c] - lb[c]);
                    }
                    slab += dl / 3.0;
                    sde += sqrt(dd);
                }
    btf_metrics m;
    cr_assert_eq(btf_compare(a, b, NULL, &m, NULL), BTF_OK);
    cr_expect_eq(m.pixels, n);
    cr_expect(fabs(m.mae - sabs / (3.0 * n)) < 1e-9 * m.mae, "mae %f", m.mae);
    cr_expect(fabs(m.rmse - sqrt(ssq / (3.0 * n))) < 1e-9 * m.rmse, "rmse %f", m.rmse);
    cr_expect(fabs(m.lab_thesis - slab / n) < 2e-3, "lab %f vs %f", m.lab_thesis, slab / n);
    cr_expect(fabs(m.delta_e76 - sde / n) < 2e-3, "de %f vs %f", m.delta_e76, sde / n);
    btf_free(a);
    btf_free(b);
}

Test(metrics, u8_and_f32_storage_agree)
{
    btf_dirset d = small_dirs();
    btf *a8 = make_btf(5, 4, &d, &d, BTF_U8), *b8 = make_btf(5, 4, &d, &d, BTF_U8);
    fill_random_u8(a8, 11);
    fill_random_u8(b8, 12);
    btf *af = fx_convert(a8, BTF_F32), *bf = fx_convert(b8, BTF_F32);
    btf_metrics m88, mff, m8f, mf8;
    cr_assert_eq(btf_compare(a8, b8, NULL, &m88, NULL), BTF_OK);
    cr_assert_eq(btf_compare(af, bf, NULL, &mff, NULL), BTF_OK);
    cr_assert_eq(btf_compare(a8, bf, NULL, &m8f, NULL), BTF_OK);
    cr_assert_eq(btf_compare(af, b8, NULL, &mf8, NULL), BTF_OK);
    /* Same values, same tables: only the float difference (x/255 - y/255) * 255
     * rounds differently from the integer one, ~1e-7 relative. */
    const btf_metrics *o[3] = {&mff, &m8f, &mf8};
    for (int i = 0; i < 3; i++) {
        cr_expect(fabs(o[i]->mae - m88.mae) < 1e-6 * m88.mae, "case %d mae %.9f vs %.9f", i, o[i]->mae, m88.mae);
        cr_expect(fabs(o[i]->rmse - m88.rmse) < 1e-6 * m88.rmse, "case %d rmse", i);
        cr_expect(fabs(o[i]->lab_thesis - m88.lab_thesis) < 1e-6 * m88.lab_thesis, "case %d lab %.9f vs %.9f", i,
                  o[i]->lab_thesis, m88.lab_thesis);
        cr_expect(fabs(o[i]->delta_e76 - m88.delta_e76) < 1e-6 * m88.delta_e76, "case %d de", i);
        cr_expect_eq(o[i]->pixels, m88.pixels);
    }
    btf_free(a8);
    btf_free(b8);
    btf_free(af);
    btf_free(bf);
}

Test(metrics, subset_selects_pairs)
{
    /* Only pair (view 3, light 1) differs: by 6 in the red channel of every texel. */
    btf_dirset d = small_dirs();
    btf *a = make_btf(4, 4, &d, &d, BTF_U8), *b = make_btf(4, 4, &d, &d, BTF_U8);
    fill_random_u8(a, 5);
    memcpy(b->data, a->data, a->count);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 4; x++) {
            uint8_t *p = (uint8_t *)a->data + btf_index(a, 3, 1, x, y, 0);
            *p = (uint8_t)(*p % 200);
            ((uint8_t *)b->data)[btf_index(b, 3, 1, x, y, 0)] = (uint8_t)(*p + 6);
        }
    int views[2] = {3, 0}, lights[2] = {1, 4};
    btf_pair_subset only = {views, lights, 1}, both = {views, lights, 2}, other = {views + 1, lights + 1, 1};
    btf_metrics m;
    cr_assert_eq(btf_compare(a, b, &only, &m, NULL), BTF_OK);
    cr_expect(fabs(m.mae - 2.0) < 1e-12, "one pair: 6 in one channel of three -> 2, got %f", m.mae);
    cr_expect_eq(m.pixels, 16u);
    cr_expect_gt(m.delta_e76, 0.0);
    cr_assert_eq(btf_compare(a, b, &both, &m, NULL), BTF_OK);
    cr_expect(fabs(m.mae - 1.0) < 1e-12, "two pairs -> 1, got %f", m.mae);
    cr_assert_eq(btf_compare(a, b, &other, &m, NULL), BTF_OK);
    cr_expect_eq(m.mae, 0.0);
    cr_expect_eq(m.psnr, 999.0);
    cr_assert_eq(btf_compare(a, b, NULL, &m, NULL), BTF_OK);
    cr_expect(fabs(m.mae - 2.0 / 25.0) < 1e-12, "all 25 pairs, got %f", m.mae);
    btf_free(a);
    btf_free(b);
}

Test(metrics, threaded_compare_matches_image_by_image)
{
    /* 16x16 texels x 81 x 81 pairs = 1.7M pixels: above the threading threshold.
     * Reference: the same images fed one by one through btf_metrics_add. */
    btf_dirset d = btf_dirset_ubo2003();
    btf *a = make_btf(16, 16, &d, &d, BTF_U8), *b = make_btf(16, 16, &d, &d, BTF_U8);
    fill_random_u8(a, 3);
    uint8_t *pa = a->data, *pb = b->data;
    uint32_t seed = 4;
    for (size_t i = 0; i < b->count; i++) {
        int v = pa[i] + (next_byte(&seed) & 15) - 7;
        pb[i] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
    }
    btf_metrics_acc acc = {0};
    float *ia = malloc(btf_image_samples(a) * sizeof(float)), *ib = malloc(btf_image_samples(a) * sizeof(float));
    cr_assert(ia && ib);
    for (int v = 0; v < 81; v++)
        for (int l = 0; l < 81; l++) {
            btf_get_image(a, v, l, ia);
            btf_get_image(b, v, l, ib);
            btf_metrics_add(&acc, ia, ib, 256);
        }
    btf_metrics want, got;
    btf_metrics_finish(&acc, &want);
    cr_assert_eq(btf_compare(a, b, NULL, &got, NULL), BTF_OK);
    /* Summation order differs (per image, then images in order): 1e-9 relative. */
    cr_expect(fabs(got.mae - want.mae) < 1e-6 * want.mae, "mae %f vs %f", got.mae, want.mae);
    cr_expect(fabs(got.rmse - want.rmse) < 1e-6 * want.rmse);
    cr_expect(fabs(got.lab_thesis - want.lab_thesis) < 1e-6 * want.lab_thesis);
    cr_expect(fabs(got.delta_e76 - want.delta_e76) < 1e-6 * want.delta_e76);
    cr_expect_eq(got.pixels, want.pixels);
    free(ia);
    free(ib);
    btf_free(a);
    btf_free(b);
}

Test(metrics, mismatched_shapes_are_rejected)
{
    btf_dirset d = small_dirs(), u = btf_dirset_ubo2003();
    btf *a = make_btf(4, 4, &d, &d, BTF_U8), *wide = make_btf(5, 4, &d, &d, BTF_U8);
    btf *lights = make_btf(4, 4, &u, &d, BTF_U8), *views = make_btf(4, 4, &d, &u, BTF_U8);
    btf_metrics m;
    btf_error e = {0};
    cr_expect_eq(btf_compare(a, wide, NULL, &m, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "4x4") && strstr(e.msg, "5x4"), "%s", e.msg);
    cr_expect_eq(btf_compare(a, lights, NULL, &m, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "light"), "%s", e.msg);
    cr_expect_eq(btf_compare(a, views, NULL, &m, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "view"), "%s", e.msg);
    cr_expect_eq(btf_compare(NULL, a, NULL, &m, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_compare(a, a, NULL, NULL, &e), BTF_ERR_ARG);
    btf_free(a);
    btf_free(wide);
    btf_free(lights);
    btf_free(views);
}

Test(metrics, subset_bounds_are_checked)
{
    btf_dirset d = small_dirs();
    btf *a = make_btf(2, 2, &d, &d, BTF_U8);
    btf_metrics m;
    btf_error e = {0};
    int views[3] = {0, 5, 1}, lights[3] = {0, 0, -1};
    btf_pair_subset bad_view = {views, lights, 2}, bad_light = {views + 2, lights + 2, 1};
    btf_pair_subset empty = {views, lights, 0}, null_arrays = {NULL, lights, 1};
    cr_expect_eq(btf_compare(a, a, &bad_view, &m, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "pair 1") && strstr(e.msg, "view 5"), "%s", e.msg);
    cr_expect_eq(btf_compare(a, a, &bad_light, &m, &e), BTF_ERR_ARG);
    cr_expect(strstr(e.msg, "light -1"), "%s", e.msg);
    cr_expect_eq(btf_compare(a, a, &empty, &m, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_compare(a, a, &null_arrays, &m, &e), BTF_ERR_ARG);
    btf_free(a);
}

/* ---------------------------------------------------------------- btf eval */

#include <criterion/redirect.h>

#include "btf_cli.h"
#include "btf_io.h"
#include "fixtures.h"

static int run_eval(int argc, const char **argv)
{
    int rc = cmd_eval(argc, (char **)argv);
    fflush(stdout);
    fflush(stderr);
    return rc;
}

Test(metrics, eval_usage_errors_exit_2, .init = cr_redirect_stderr)
{
    const char *none[] = {"eval"};
    const char *three[] = {"eval", "a", "b", "c"};
    const char *opt[] = {"eval", "a", "b", "--frobnicate"};
    const char *pairs[] = {"eval", "a", "b", "--pairs", "1:"};
    const char *pairs2[] = {"eval", "a", "b", "--pairs", "x"};
    const char *ds[] = {"eval", "a", "b", "--downsample", "0"};
    const char *dangling[] = {"eval", "a", "b", "--pairs"};
    cr_expect_eq(run_eval(1, none), 2);
    cr_expect_eq(run_eval(4, three), 2);
    cr_expect_eq(run_eval(4, opt), 2);
    cr_expect_eq(run_eval(5, pairs), 2);
    cr_expect_eq(run_eval(5, pairs2), 2);
    cr_expect_eq(run_eval(5, ds), 2);
    cr_expect_eq(run_eval(4, dangling), 2);
}

Test(metrics, eval_missing_input_exits_1, .init = cr_redirect_stderr)
{
    const char *argv[] = {"eval", "/nonexistent/ref.btf", "/nonexistent/test.btf"};
    cr_expect_eq(run_eval(3, argv), 1);
    fflush(stderr);
    char line[1024] = "";
    FILE *f = cr_get_redirected_stderr();
    cr_assert_not_null(fgets(line, sizeof line, f));
    cr_expect(strstr(line, "/nonexistent/ref.btf") != NULL, "message names the file: %s", line);
}

/* Reads "metric,value,unit" CSV rows from f into the named slots. */
static void read_csv(FILE *f, btf_metrics *m)
{
    char line[256], name[64];
    double v;
    memset(m, 0, sizeof *m);
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "%63[^,],%lf", name, &v) == 2) {
            if (!strcmp(name, "rgb_mae")) m->mae = v;
            if (!strcmp(name, "rgb_rmse")) m->rmse = v;
            if (!strcmp(name, "psnr")) m->psnr = v;
            if (!strcmp(name, "lab_mae")) m->lab_thesis = v;
            if (!strcmp(name, "delta_e76")) m->delta_e76 = v;
            if (!strcmp(name, "pixels")) m->pixels = (size_t)v;
        }
}

/* REF and TEST (thesis packages) as `btf eval REF TEST --downsample 16` loads them:
 * REF as its import stores it, TEST reconstructed in floats. */
static void load_as_eval(const char *ref, const char *test, btf **a, btf **b)
{
    btf_load_options o = {0};
    o.downsample = 16;
    btf_error e = {0};
    cr_assert_eq(btf_load_any(ref, &o, a, &e), BTF_OK, "%s", e.msg);
    o.storage = BTF_F32;
    cr_assert_eq(btf_load_any(test, &o, b, &e), BTF_OK, "%s", e.msg);
}

Test(metrics, eval_thesis_materials_matches_compare, .init = cr_redirect_stdout)
{
    char wool[4096], cord[4096];
    if (!fx_shared_path(wool, sizeof wool, "data/thesis-ubo2003/wool") ||
        !fx_shared_path(cord, sizeof cord, "data/thesis-ubo2003/corduroy"))
        cr_skip_test("thesis materials absent under BTF_SHARED");
    /* Reference numbers: the same loads and btf_compare called directly (TEST, a
     * thesis package, reconstructed in floats, as a package's decode is measured). */
    btf *a = NULL, *b = NULL;
    btf_error e = {0};
    load_as_eval(wool, cord, &a, &b);
    int views[2] = {0, 40}, lights[2] = {0, 7};
    btf_pair_subset sub = {views, lights, 2};
    btf_metrics want, got;
    cr_assert_eq(btf_compare(a, b, &sub, &want, &e), BTF_OK, "%s", e.msg);
    btf_free(a);
    btf_free(b);
    const char *argv[] = {"eval", wool, cord, "--downsample", "16", "--pairs", "0:0,40:7", "--csv"};
    cr_assert_eq(run_eval(8, argv), 0);
    read_csv(cr_get_redirected_stdout(), &got);
    /* The CSV prints 6 decimals: 1e-5 absolute. */
    cr_expect_eq(got.pixels, want.pixels);
    cr_expect(fabs(got.mae - want.mae) < 1e-5, "mae %f vs %f", got.mae, want.mae);
    cr_expect(fabs(got.rmse - want.rmse) < 1e-5, "rmse %f vs %f", got.rmse, want.rmse);
    cr_expect(fabs(got.lab_thesis - want.lab_thesis) < 1e-5, "lab %f vs %f", got.lab_thesis, want.lab_thesis);
    cr_expect(fabs(got.delta_e76 - want.delta_e76) < 1e-5, "de %f vs %f", got.delta_e76, want.delta_e76);
    cr_expect_gt(got.mae, 1.0, "different materials must differ");
}

Test(metrics, eval_identical_inputs_report_sentinel, .init = cr_redirect_stdout)
{
    char wool[4096];
    if (!fx_shared_path(wool, sizeof wool, "data/thesis-ubo2003/wool"))
        cr_skip_test("thesis wool absent under BTF_SHARED");
    /* as displayed, a thesis package is its import's bytes: identical to REF */
    const char *argv[] = {"eval", wool, wool, "--downsample", "16", "--csv", "--displayed"};
    cr_assert_eq(run_eval(7, argv), 0);
    btf_metrics got;
    read_csv(cr_get_redirected_stdout(), &got);
    cr_expect_eq(got.psnr, 999.0);
    cr_expect_eq(got.mae, 0.0);
    cr_expect_eq(got.delta_e76, 0.0);
    cr_expect_eq(got.pixels, (size_t)16 * 16 * 81 * 81);
}

/* A thesis package as TEST is its reconstruction in floats, its import (REF) the same
 * values rounded to bytes: every sample of REF is its TEST sample rounded, and btf
 * eval measures that rounding (CIELab over 0), what btf_compare of the two gives. */
Test(metrics, eval_of_a_thesis_package_against_its_import_is_its_rounding, .init = cr_redirect_stdout)
{
    char wool[4096];
    if (!fx_shared_path(wool, sizeof wool, "data/thesis-ubo2003/wool"))
        cr_skip_test("thesis wool absent under BTF_SHARED");
    btf *a = NULL, *b = NULL;
    btf_error e = {0};
    load_as_eval(wool, wool, &a, &b);
    cr_assert(a->storage == BTF_U8 && b->storage == BTF_F32 && a->count == b->count);
    const uint8_t *q = a->data;
    const float *f = b->data;
    size_t off = 0;
    for (size_t i = 0; i < a->count; i++)
        off += q[i] != btf_to_u8(f[i]);
    cr_assert_eq(off, 0, "%zu samples of the import are not the reconstruction rounded", off);
    btf_metrics want, got;
    cr_assert_eq(btf_compare(a, b, NULL, &want, &e), BTF_OK, "%s", e.msg);
    btf_free(a);
    btf_free(b);
    const char *argv[] = {"eval", wool, wool, "--downsample", "16", "--csv"};
    cr_assert_eq(run_eval(6, argv), 0);
    read_csv(cr_get_redirected_stdout(), &got);
    cr_expect(got.lab_thesis > 0.01, "lab %f", got.lab_thesis);
    cr_expect(fabs(got.lab_thesis - want.lab_thesis) < 1e-5, "lab %f vs %f", got.lab_thesis, want.lab_thesis);
    cr_expect(fabs(got.rmse - want.rmse) < 1e-5, "rmse %f vs %f", got.rmse, want.rmse);
}

/* Saves b as DIR/NAME (.btf, full rank) and returns the path in buf. */
static void save_btf(const btf *b, const char *dir, const char *name, char *buf, size_t n)
{
    snprintf(buf, n, "%s/%s", dir, name);
    btf_error e = {0};
    cr_assert_eq(btf_save_dfmf(b, buf, 0, &e), BTF_OK, "%s", e.msg);
}

Test(metrics, eval_btf_files, .init = cr_redirect_stdout)
{
    char dir[256], pa[512], pb[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf_dirset d = small_dirs();
    btf *a = make_btf(4, 4, &d, &d, BTF_U8), *b = make_btf(4, 4, &d, &d, BTF_U8);
    fill_random_u8(a, 21);
    fill_random_u8(b, 22);
    save_btf(a, dir, "a.btf", pa, sizeof pa);
    save_btf(b, dir, "b.btf", pb, sizeof pb);
    btf_free(a);
    btf_free(b);
    /* Reference: what the loader gives back, compared directly. */
    btf *la = NULL, *lb = NULL;
    cr_assert_eq(btf_load_any(pa, NULL, &la, NULL), BTF_OK);
    cr_assert_eq(btf_load_any(pb, NULL, &lb, NULL), BTF_OK);
    btf_metrics want, got;
    cr_assert_eq(btf_compare(la, lb, NULL, &want, NULL), BTF_OK);
    btf_free(la);
    btf_free(lb);
    const char *argv[] = {"eval", pa, pb, "--csv", "--pairs", "measured"};
    cr_assert_eq(run_eval(6, argv), 0);
    read_csv(cr_get_redirected_stdout(), &got);
    /* The CSV prints 6 decimals (4 for PSNR). */
    cr_expect_eq(got.pixels, (size_t)4 * 4 * 5 * 5);
    cr_expect(fabs(got.mae - want.mae) < 1e-5, "mae %f vs %f", got.mae, want.mae);
    cr_expect(fabs(got.rmse - want.rmse) < 1e-5, "rmse %f vs %f", got.rmse, want.rmse);
    cr_expect(fabs(got.psnr - want.psnr) < 1e-4, "psnr %f vs %f", got.psnr, want.psnr);
    cr_expect(fabs(got.lab_thesis - want.lab_thesis) < 1e-5, "lab %f vs %f", got.lab_thesis, want.lab_thesis);
    cr_expect(fabs(got.delta_e76 - want.delta_e76) < 1e-5, "de %f vs %f", got.delta_e76, want.delta_e76);
    cr_expect_gt(got.mae, 50.0, "independent random data differ by ~85 on average");
    remove(pa);
    remove(pb);
    rmdir(dir);
}

Test(metrics, eval_mismatched_shapes_exit_1, .init = cr_redirect_stderr)
{
    char dir[256], pa[512], pb[512], pc[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf_dirset d = small_dirs(), one;
    btf_ring r = {30, 3, 0};
    cr_assert_eq(btf_dirset_make(&r, 1, &one, NULL), BTF_OK);
    btf *a = make_btf(4, 4, &d, &d, BTF_U8), *b = make_btf(5, 4, &d, &d, BTF_U8);
    btf *c = make_btf(4, 4, &one, &d, BTF_U8);
    save_btf(a, dir, "a.btf", pa, sizeof pa);
    save_btf(b, dir, "b.btf", pb, sizeof pb);
    save_btf(c, dir, "c.btf", pc, sizeof pc);
    btf_free(a);
    btf_free(b);
    btf_free(c);
    const char *size[] = {"eval", pa, pb};
    const char *dirs[] = {"eval", pa, pc};
    const char *pairs[] = {"eval", pa, pa, "--pairs", "0:0,4:5"};
    cr_expect_eq(run_eval(3, size), 1);
    cr_expect_eq(run_eval(3, dirs), 1);
    cr_expect_eq(run_eval(5, pairs), 1, "light 5 is outside 0..4");
    char text[4096] = "";
    size_t n = fread(text, 1, sizeof text - 1, cr_get_redirected_stderr());
    text[n] = 0;
    cr_expect(strstr(text, "sizes differ") && strstr(text, "light direction sets differ") &&
                  strstr(text, "light 5 outside"),
              "messages: %s", text);
    remove(pa);
    remove(pb);
    remove(pc);
    rmdir(dir);
}
