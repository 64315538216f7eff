/* test_methods.c - room eval, suite "methods": each method family's encoder and decoder
 * against independent computations (synthetic materials built here from the
 * models' own formulas, the project's PCA run directly, byte counts by hand). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "btf_method.h"
#include "btf_pca.h"
#include "fixtures.h"

/* 25 directions: rings at theta 0, 30, 60, 75 (counts 1, 6, 8, 10). */
static btf_dirset small_set(void)
{
    return FX_RINGS({0, 1, 0}, {30, 6, 0}, {60, 8, 10}, {75, 10, 0});
}

static float srgb(float v)
{
    if (!(v > 0.0f))
        return 0.0f;
    return v <= 0.0031308f ? v * 12.92f : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
}

static void unit(const float in[3], float out[3])
{
    float n = sqrtf(in[0] * in[0] + in[1] * in[1] + in[2] * in[2]);
    for (int i = 0; i < 3; i++)
        out[i] = in[i] / n;
}

/* Independent Blinn-Phong value (linear) of the model documented in btf_method.h. */
static float phong_lin(float a, float kd, float ks, float e, const float l[3], const float v[3])
{
    float lz = l[2] > 0 ? l[2] : 0, h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]}, hu[3];
    unit(h, hu);
    float hz = hu[2] > 0 ? hu[2] : 0;
    return a + kd * lz + ks * (e + 8) / 8 * powf(hz, e) * lz;
}

typedef struct phong_truth {
    float a[3], kd[3], ks[3], e;
} phong_truth;

static phong_truth phong_at(int x, int y)
{
    static const float es[3] = {8, 32, 128};
    phong_truth t;
    t.e = es[(x + 2 * y) % 3];
    for (int c = 0; c < 3; c++) {
        t.a[c] = 0.01f * (float)((x + c) % 3);
        t.kd[c] = 0.2f + 0.05f * (float)c + 0.02f * (float)y;
        t.ks[c] = (x % 2) ? 0.15f + 0.02f * (float)c : 0.0f;
    }
    return t;
}

/* F32 material whose every texel is an exact Blinn-Phong (phong_at). */
static btf *phong_material(int w, int h)
{
    btf_dirset d = small_set();
    btf *m = NULL;
    btf_error err;
    cr_assert_eq(btf_create(w, h, &d, &d, BTF_F32, &m, &err), BTF_OK, "%s", err.msg);
    for (int v = 0; v < d.n_dirs; v++)
        for (int l = 0; l < d.n_dirs; l++) {
            float lv[3], vv[3];
            btf_dirset_vector(&d, l, lv);
            btf_dirset_vector(&d, v, vv);
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    phong_truth t = phong_at(x, y);
                    for (int c = 0; c < 3; c++)
                        btf_set(m, v, l, x, y, c, srgb(phong_lin(t.a[c], t.kd[c], t.ks[c], t.e, lv, vv)));
                }
        }
    return m;
}

Test(methods, phong_recovers_parameters)
{
    btf *src = phong_material(6, 6);
    btf_model *m = NULL;
    btf_error err;
    cr_assert_eq(btf_model_encode(&btf_method_phong, src, NULL, &m, &err), BTF_OK, "%s", err.msg);
    for (int y = 0; y < 6; y++)
        for (int x = 0; x < 6; x++) {
            phong_truth t = phong_at(x, y);
            btf_phong_texel p;
            cr_assert_eq(btf_phong_get(m, x, y, &p, &err), BTF_OK);
            /* texels without a lobe (ks = 0) may report any exponent */
            if (t.ks[0] > 0)
                cr_expect_eq(p.exponent, t.e, "texel %d,%d exponent %g, truth %g", x, y, p.exponent, t.e);
            /* exact model, float32 samples: coefficients to ~1e-5; 1e-3 leaves room for
             * the sRGB round trip of the stored samples */
            for (int c = 0; c < 3; c++) {
                cr_expect(fabsf(p.ambient[c] - t.a[c]) < 1e-3f, "a %g vs %g", p.ambient[c], t.a[c]);
                cr_expect(fabsf(p.diffuse[c] - t.kd[c]) < 1e-3f, "kd %g vs %g", p.diffuse[c], t.kd[c]);
                cr_expect(fabsf(p.spec[c] - t.ks[c]) < 1e-3f, "ks %g vs %g", p.spec[c], t.ks[c]);
            }
        }
    /* off-grid directions: the decoder evaluates the model, not a table */
    float l[3] = {0.3f, -0.2f, 0.9f}, v[3] = {-0.25f, 0.3f, 0.85f}, lu[3], vu[3], rgb[3];
    unit(l, lu);
    unit(v, vu);
    phong_truth t = phong_at(3, 2);
    btf_model_decode(m, 3, 2, l, v, rgb);
    for (int c = 0; c < 3; c++)
        cr_expect(fabsf(rgb[c] - srgb(phong_lin(t.a[c], t.kd[c], t.ks[c], t.e, lu, vu))) < 2e-3f);
    cr_expect_eq(btf_model_bytes(m), (size_t)6 * 6 * 10 * sizeof(float));
    btf_model_free(m);
    btf_free(src);
}

/* Lafortune lobe of btf_method.h, linear. */
static float laf_lin(float a, float d, float s, float cxy, float n, const float l[3], const float v[3])
{
    float lz = l[2] > 0 ? l[2] : 0, b = cxy * (l[0] * v[0] + l[1] * v[1]) + l[2] * v[2];
    float f = b > 0 ? 0.5f * (n + 2) * powf(b, n) : 0;
    return a + lz * (d + s * f);
}

Test(methods, lafortune_single_lobe)
{
    btf_dirset d = small_set();
    int W = 4, H = 4;
    btf *src = NULL;
    btf_error err;
    cr_assert_eq(btf_create(W, H, &d, &d, BTF_F32, &src, &err), BTF_OK);
    const float cxy = -0.8f, n = 20.0f;
    for (int v = 0; v < d.n_dirs; v++)
        for (int l = 0; l < d.n_dirs; l++) {
            float lv[3], vv[3];
            btf_dirset_vector(&d, l, lv);
            btf_dirset_vector(&d, v, vv);
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++)
                    for (int c = 0; c < 3; c++)
                        btf_set(src, v, l, x, y, c,
                                srgb(laf_lin(0.01f, 0.2f + 0.05f * c, 0.3f + 0.02f * (x + y), cxy, n, lv, vv)));
        }
    btf_method_params p = {0};
    p.lobes = 1;
    btf_model *m = NULL;
    cr_assert_eq(btf_model_encode(&btf_method_lafortune, src, &p, &m, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(m->n_fallback, 0, "fallbacks %d on data the model fits exactly", m->n_fallback);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            btf_lafortune_texel t;
            cr_assert_eq(btf_lafortune_get(m, x, y, &t, &err), BTF_OK);
            /* LM on exact data: shape to a few percent (xtol 1e-6, but float samples) */
            cr_expect(fabsf(t.cxy[0] - cxy) < 0.02f, "cxy %g", t.cxy[0]);
            cr_expect(fabsf(t.n[0] - n) < 0.5f, "n %g", t.n[0]);
        }
    float l[3] = {0.4f, 0.1f, 0.8f}, v[3] = {-0.3f, -0.1f, 0.9f}, lu[3], vu[3], rgb[3];
    unit(l, lu);
    unit(v, vu);
    btf_model_decode(m, 1, 2, l, v, rgb);
    for (int c = 0; c < 3; c++)
        cr_expect(fabsf(rgb[c] - srgb(laf_lin(0.01f, 0.2f + 0.05f * c, 0.36f, cxy, n, lu, vu))) < 5e-3f,
                  "c %d: %g", c, rgb[c]);
    cr_expect_eq(btf_model_bytes(m), (size_t)W * H * 11 * sizeof(float));
    btf_model_free(m);

    /* an iteration cap of 1 cannot converge: every texel is reported, output finite */
    p.max_iter = 1;
    p.lobes = 2;
    cr_assert_eq(btf_model_encode(&btf_method_lafortune, src, &p, &m, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(m->n_unconverged, W * H);
    btf_model_decode(m, 0, 0, l, v, rgb);
    cr_expect(isfinite(rgb[0]) && isfinite(rgb[1]) && isfinite(rgb[2]));
    cr_expect_eq(btf_model_bytes(m), (size_t)W * H * 16 * sizeof(float));
    btf_model_free(m);
    btf_free(src);
}

/* F32 material with pseudo-random content (xorshift), values 0..1. */
static btf *noise_material(int w, int h, const btf_dirset *d)
{
    btf *m = NULL;
    btf_error err;
    cr_assert_eq(btf_create(w, h, d, d, BTF_F32, &m, &err), BTF_OK);
    unsigned s = 12345u;
    float *f = m->data;
    for (size_t i = 0; i < m->count; i++) {
        fx_xorshift32(&s);
        f[i] = (float)(s % 1000u) / 999.0f;
    }
    return m;
}

/* Level 0 of the Laplacian pyramid built here: F0 - up(box2x2(F0)). */
static btf *level0(const btf *f)
{
    btf *o = NULL;
    btf_error err;
    cr_assert_eq(btf_create(f->width, f->height, &f->lights, &f->views, BTF_F32, &o, &err), BTF_OK);
    for (int v = 0; v < f->views.n_dirs; v++)
        for (int l = 0; l < f->lights.n_dirs; l++)
            for (int y = 0; y < f->height; y++)
                for (int x = 0; x < f->width; x++)
                    for (int c = 0; c < 3; c++) {
                        int x0 = x & ~1, y0 = y & ~1;
                        float mean = 0.25f * (btf_get(f, v, l, x0, y0, c) + btf_get(f, v, l, x0 + 1, y0, c) +
                                              btf_get(f, v, l, x0, y0 + 1, c) + btf_get(f, v, l, x0 + 1, y0 + 1, c));
                        btf_set(o, v, l, x, y, c, btf_get(f, v, l, x, y, c) - mean);
                    }
    return o;
}

Test(methods, lpyr_levels)
{
    btf_dirset d = small_set();
    btf *src = noise_material(8, 8, &d);
    btf_error err;
    /* per level: equals the project's PCA of an independently built Laplacian level */
    btf_method_params p = {0};
    p.levels = 3, p.components = 4, p.k = 3;
    btf_model *m = NULL;
    cr_assert_eq(btf_model_encode(&btf_method_lpyr, src, &p, &m, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_lpyr_levels(m), 3);
    btf *lap = level0(src);
    btf_pca_options o = {0};
    o.k = 3, o.components = 4;
    btf_pca_model *pm = NULL;
    cr_assert_eq(btf_pca_compress(lap, &o, NULL, NULL, &pm, &err), BTF_OK, "%s", err.msg);
    double maxd = 0;
    for (int v = 0; v < d.n_dirs; v += 3)
        for (int l = 0; l < d.n_dirs; l += 2)
            for (int y = 0; y < 8; y++)
                for (int x = 0; x < 8; x++) {
                    float a = btf_lpyr_level_value(m, 0, v, l, x, y, 1), b = btf_pca_model_value(pm, v, l, x, y, 1, 4);
                    maxd = fmax(maxd, fabs(a - b));
                }
    cr_expect(maxd < 1e-4, "level 0 differs from the direct PCA by %g", maxd); /* float32 PCA, same input */
    btf_pca_model_free(pm);
    btf_free(lap);
    btf_model_free(m);

    /* full rank at every level: decode reproduces the source; the coarsest level
     * alone is the 4x4 box mean (8x8, 3 levels -> top 2x2) */
    p.components = 10000;
    cr_assert_eq(btf_model_encode(&btf_method_lpyr, src, &p, &m, &err), BTF_OK, "%s", err.msg);
    float lv[3], vv[3], rgb[3];
    btf_dirset_vector(&d, 7, lv);
    btf_dirset_vector(&d, 12, vv);
    maxd = 0;
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++) {
            btf_model_decode(m, x, y, lv, vv, rgb);
            for (int c = 0; c < 3; c++)
                maxd = fmax(maxd, fabs(rgb[c] - btf_get(src, 12, 7, x, y, c)));
        }
    cr_expect(maxd < 1e-3, "full-rank pyramid misses the source by %g", maxd); /* float PCA of 0..1 data */
    btf_lpyr_set_decode_levels(m, 1);
    btf_model_decode(m, 5, 2, lv, vv, rgb);
    for (int c = 0; c < 3; c++) {
        double s = 0;
        for (int y = 0; y < 4; y++)
            for (int x = 4; x < 8; x++)
                s += btf_get(src, 12, 7, x, y, c);
        cr_expect(fabs(rgb[c] - s / 16) < 1e-3, "coarsest level %g, box mean %g", rgb[c], s / 16);
    }
    /* bytes: per level, blocks of 3 views (8 x 225 columns + 1 x 75) of (texels +
     * columns) x C floats, C = min(texels, 75 columns of the smallest block) */
    size_t want = 0;
    int side[3] = {8, 4, 2};
    for (int i = 0; i < 3; i++) {
        size_t rows = (size_t)side[i] * side[i], C = rows < 75 ? rows : 75;
        want += (8 * (rows + 225) + (rows + 75)) * C * sizeof(float);
    }
    cr_expect_eq(btf_model_bytes(m), want);
    btf_model_free(m);
    btf_free(src);
}

Test(methods, pca_adapters)
{
    btf_dirset d = small_set();
    btf *src = noise_material(6, 6, &d);
    btf_error err;
    btf_method_params p = {0};
    p.k = 3, p.components = 36; /* full rank: 36 texels */
    btf_model *m = NULL, *q = NULL;
    cr_assert_eq(btf_model_encode(&btf_method_pca, src, &p, &m, &err), BTF_OK, "%s", err.msg);
    float lv[3], vv[3], a[3], b[3];
    btf_dirset_vector(&d, 3, lv);
    btf_dirset_vector(&d, 20, vv);
    double maxd = 0;
    for (int y = 0; y < 6; y++)
        for (int x = 0; x < 6; x++) {
            btf_model_decode(m, x, y, lv, vv, a);
            for (int c = 0; c < 3; c++)
                maxd = fmax(maxd, fabs(a[c] - btf_get(src, 20, 3, x, y, c)));
        }
    cr_expect(maxd < 1e-3, "full-rank PCA misses the source by %g", maxd);
    /* 25 views in blocks of 3: 8 blocks of 225 columns and one of 75, 36 texels */
    cr_expect_eq(btf_model_bytes(m), (size_t)(8 * (36 + 225) + (36 + 75)) * 36 * sizeof(float));
    btf_model_free(m);

    p.components = 4;
    cr_assert_eq(btf_model_encode(&btf_method_pca, src, &p, &m, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_model_encode(&btf_method_pca_q, src, &p, &q, &err), BTF_OK, "%s", err.msg);
    maxd = 0;
    float lo[3] = {0.2f, 0.1f, 0.9f}, vo[3] = {-0.1f, 0.4f, 0.7f};
    for (int y = 0; y < 6; y++)
        for (int x = 0; x < 6; x++) {
            btf_model_decode(m, x, y, lo, vo, a);
            btf_model_decode(q, x, y, lo, vo, b);
            for (int c = 0; c < 3; c++)
                maxd = fmax(maxd, fabs(a[c] - b[c]));
        }
    /* 8-bit textures and weights: each product term errs by ~1/255 relative */
    cr_expect(maxd < 0.03, "8-bit package differs from the float model by %g", maxd);
    cr_expect(btf_model_bytes(q) > 0 && btf_model_bytes(q) < btf_model_bytes(m));
    btf_model_free(m);
    btf_model_free(q);
    btf_free(src);
}

Test(methods, bad_input)
{
    btf_dirset d = small_set();
    btf *src = noise_material(4, 4, &d);
    btf_error err = {{0}};
    btf_model *m = (btf_model *)&err; /* must be reset to NULL on failure */
    cr_expect_eq(btf_model_encode(&btf_method_phong, NULL, NULL, &m, &err), BTF_ERR_ARG);
    cr_expect_null(m);
    btf_method_params p = {0};
    p.lobes = 3;
    cr_expect_eq(btf_model_encode(&btf_method_lafortune, src, &p, &m, &err), BTF_ERR_RANGE);
    cr_expect(strstr(err.msg, "lobes") != NULL, "%s", err.msg);
    ((float *)src->data)[100] = INFINITY;
    cr_expect_eq(btf_model_encode(&btf_method_pca, src, NULL, &m, &err), BTF_ERR_NUMERIC);
    btf_model_free(NULL);
    btf_free(src);
}

Test(methods, registry)
{
    const btf_method_setting *s;
    int n = btf_method_registry(&s);
    cr_assert(n >= 5);
    int seen[5] = {0};
    const char *names[5] = {"phong", "lafortune", "pca", "pca-q", "lpyr"};
    for (int i = 0; i < n; i++) {
        cr_assert_not_null(s[i].method);
        for (int j = 0; j < i; j++)
            cr_expect_str_neq(s[i].label, s[j].label);
        for (int j = 0; j < 5; j++)
            if (strcmp(s[i].method->name, names[j]) == 0)
                seen[j] = 1;
    }
    for (int j = 0; j < 5; j++) {
        cr_expect(seen[j], "%s not in the registry", names[j]);
        cr_expect_not_null(btf_method_find(names[j]));
    }
    cr_expect_null(btf_method_find("nope"));
}
