/* test_linear.c - room codec, suite "linear": linear-light packages (manifest
 * "encoding", btf_package_options.linear, btf_package_to_source; doc/package-format.md
 * section 3.7). */
#include <cjson/cJSON.h>
#include <math.h>

#include "btf_budget.h"
#include "btf_color.h"
#include "btf_decode.h"
#include "btf_manifest.h"
#include "btf_metrics.h"
#include "fixtures.h"

/* The sRGB EOTF written out here (IEC 61966-2-1), apart from the codec's copy. */
static double srgb_to_linear(double v)
{
    return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

/* A generated knit, 16 x 16 texels, 8 bits, on fx_dirs7. */
static btf *knit16(void)
{
    return fx_material(BTF_GEN_KNIT, 16, NULL, 0);
}

/* src compressed into dir/sub with k, C, bits and linear. */
static void compress(const btf *src, const char *dir, const char *sub, int k, int C, int bits, int linear)
{
    char out[600];
    snprintf(out, sizeof out, "%s/%s", dir, sub);
    btf_pca_options po = {0};
    po.k = k, po.components = C;
    btf_package_options ko = {0};
    ko.bits = bits, ko.linear = linear;
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(src, &po, &ko, out, NULL, &err), BTF_OK, "%s", err.msg);
}

/* The manifest text of dir/sub with "encoding" set to e (NULL: removed), parsed. */
static btf_result parse_with(const char *dir, const char *sub, cJSON *e, btf_package *p, btf_error *err)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s/manifest.json", dir, sub);
    char *text = fx_read(path, NULL);
    cr_assert(text);
    cJSON *m = cJSON_Parse(text);
    cJSON_DeleteItemFromObjectCaseSensitive(m, "encoding");
    if (e)
        cJSON_AddItemToObject(m, "encoding", e);
    char *again = cJSON_PrintUnformatted(m);
    memset(p, 0, sizeof *p);
    btf_result r = btf_manifest_parse(again, path, p, err);
    free(again), free(text);
    cJSON_Delete(m);
    return r;
}

/* Absent and "srgb" read as 0, "linear" as 1; any other value or type refused with
 * the field's name; the printer writes the field for linear packages only. */
Test(linear, manifest_encoding_parsed_and_printed)
{
    char tmp[256];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf *src = knit16();
    compress(src, tmp, "s", 3, 4, 8, 0);
    btf_package p;
    btf_error err = {0};
    struct {
        cJSON *e;
        int linear;
    } ok[] = {{NULL, 0}, {cJSON_CreateString("srgb"), 0}, {cJSON_CreateString("linear"), 1}};
    for (int i = 0; i < 3; i++) {
        cr_assert_eq(parse_with(tmp, "s", ok[i].e, &p, &err), BTF_OK, "case %d: %s", i, err.msg);
        cr_expect_eq(p.linear, ok[i].linear, "case %d", i);
        char *text = btf_manifest_print(&p, &err);
        cr_expect_eq(strstr(text, "\"encoding\"") != NULL, ok[i].linear, "case %d: printed %s", i, text);
        free(text);
        btf_manifest_clear(&p);
    }
    cJSON *bad[] = {cJSON_CreateString("Linear"), cJSON_CreateString(""), cJSON_CreateString("rgb"),
                    cJSON_CreateNumber(1), cJSON_CreateTrue(), cJSON_CreateNull(), cJSON_CreateArray(),
                    cJSON_CreateObject()};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        cr_expect_eq(parse_with(tmp, "s", bad[i], &p, &err), BTF_ERR_FORMAT, "bad case %zu", i);
        cr_expect(strstr(err.msg, "\"encoding\" must be \"srgb\" or \"linear\""), "bad case %zu: %s", i, err.msg);
        btf_manifest_clear(&p);
    }
    /* an sRGB package as written has no "encoding": its bytes are what they were */
    char path[600];
    snprintf(path, sizeof path, "%s/s/manifest.json", tmp);
    char *text = fx_read(path, NULL);
    cr_expect(text && !strstr(text, "encoding"));
    free(text);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* Largest |a - b| over the samples of two BTFs of one shape, on the 0..255 scale. */
static double max_diff(const btf *a, const btf *b)
{
    double m = 0.0;
    for (int v = 0; v < a->views.n_dirs; v++)
        for (int l = 0; l < a->lights.n_dirs; l++)
            for (int y = 0; y < a->height; y++)
                for (int x = 0; x < a->width; x++)
                    for (int c = 0; c < 3; c++)
                        m = fmax(m, 255.0 * fabs(btf_get(a, v, l, x, y, c) - btf_get(b, v, l, x, y, c)));
    return m;
}

/* Full rank (k 1: C = 3 L = 21 columns per block, 256 texels), 16-bit textures: the PCA
 * loses nothing and the 16-bit texture and weight steps (range / 65535) leave errors
 * of order 1e-5 on the 0..1 scale (6e-6 measured in linear light); encoding to sRGB
 * magnifies them at most 12.92 times (the slope of the OETF's linear segment), so
 * both stay far under half a byte (0.002 of 255 measured) and both packages give back
 * every source byte once rounded: the bound asserted. The writer's
 * Lab error (its subsample is every texel at 16 x 16) is the one btf_compare
 * measures on the source's scale, for both encodings. */
Test(linear, round_trip_full_rank_to_the_source_bytes)
{
    char tmp[256];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf *src = knit16();
    const char *sub[2] = {"srgb", "linear"};
    for (int lin = 0; lin < 2; lin++) {
        compress(src, tmp, sub[lin], 1, 21, 16, lin);
        btf_package *p = fx_package(tmp, sub[lin], 0);
        cr_assert_eq(p->linear, lin);
        btf *rec = NULL;
        btf_error err = {0};
        cr_assert_eq(btf_package_reconstruct(p, 0, &rec, &err), BTF_OK, "%s", err.msg);
        double d = max_diff(src, rec);
        cr_expect_lt(d, 0.5, "%s: largest error %.4f of 255", sub[lin], d);
        btf_metrics m;
        cr_assert_eq(btf_compare(src, rec, NULL, &m, &err), BTF_OK, "%s", err.msg);
        cr_expect_float_eq(p->chunk[p->n_chunks - 1].lab, m.lab_thesis, 1e-4, "%s: manifest %g, measured %g",
                           sub[lin], p->chunk[p->n_chunks - 1].lab, m.lab_thesis);
        btf_free(rec);
        btf_package_free(p);
    }
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* At the default settings (k 3, C 8, 8 bits) both packages approximate the source
 * on its scale; the Lab errors the writer records match btf_compare's for every
 * chunk prefix, linear or not (so a --max-error budget means the same). */
Test(linear, default_settings_errors_on_the_source_scale)
{
    char tmp[256];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf *src = knit16();
    const char *sub[2] = {"srgb", "linear"};
    for (int lin = 0; lin < 2; lin++) {
        compress(src, tmp, sub[lin], 3, 8, 8, lin);
        btf_package *p = fx_package(tmp, sub[lin], 0);
        for (int n = 1; n <= p->n_chunks; n++) {
            btf *rec = NULL;
            btf_error err = {0};
            btf_metrics m;
            cr_assert_eq(btf_package_reconstruct(p, n, &rec, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(btf_compare(src, rec, NULL, &m, &err), BTF_OK, "%s", err.msg);
            cr_expect_float_eq(p->chunk[n - 1].lab, m.lab_thesis, 1e-4, "%s, %d chunks", sub[lin], n);
            btf_metrics mv; /* a view at a time, encoded back to sRGB the same way */
            cr_assert_eq(btf_package_compare(p, n, src, &mv, &err), BTF_OK, "%s", err.msg);
            cr_expect_float_eq(mv.lab_thesis, m.lab_thesis, 1e-9 * m.lab_thesis, "%s, %d chunks", sub[lin], n);
            if (n == p->n_chunks) /* a usable package: the knit's error at k 3, C 8 is about 1 */
                cr_expect_lt(m.lab_thesis, 3.0, "%s: Lab %g", sub[lin], m.lab_thesis);
            btf_free(rec);
        }
        btf_package_free(p);
    }
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* What btf_decode returns from a linear package is linear light: at every measured
 * direction pair and texel centre it equals the EOTF (written out above) of the
 * source's byte, within the full-rank 16-bit quantisation (see above: 6e-6 measured,
 * bounded here by 1e-4 on the 0..1 scale, a third of the smallest linear step
 * between two bytes, 3.0e-4 from 0 to 1/255); btf_package_to_source puts it back on
 * the source's bytes. */
Test(linear, decoded_value_is_the_eotf_of_the_source)
{
    char tmp[256];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf *src = knit16();
    compress(src, tmp, "lin", 1, 21, 16, 1);
    btf_package *p = fx_package(tmp, "lin", 0);
    btf_decode_options o = {0};
    float dl[3], dv[3], rgb[3];
    double worst = 0.0;
    for (int v = 0; v < 7; v++)
        for (int l = 0; l < 7; l++) {
            btf_dirset_vector(&p->views, v, dv);
            btf_dirset_vector(&p->lights, l, dl);
            for (int y = 0; y < 16; y++)
                for (int x = 0; x < 16; x++) {
                    btf_decode(p, (x + 0.5f) / 16.0f, (y + 0.5f) / 16.0f, dl, dv, &o, rgb);
                    const uint8_t *s = (const uint8_t *)src->data + btf_index(src, v, l, x, y, 0);
                    for (int c = 0; c < 3; c++)
                        worst = fmax(worst, fabs(rgb[c] - srgb_to_linear(s[c] / 255.0)));
                    btf_package_to_source(p, rgb, 3);
                    for (int c = 0; c < 3; c++)
                        cr_assert_lt(fabs(rgb[c] * 255.0 - s[c]), 0.5, "v %d l %d x %d y %d c %d", v, l, x, y, c);
                }
        }
    cr_expect_lt(worst, 1e-4, "largest linear error %g", worst);
    btf_package_free(p);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* The flag survives every writer: levels (versions 2 and 4), --rd (version 3) and
 * a budget; the thumbnail of a lossless linear package is the sRGB one's. */
Test(linear, levels_rd_budget_and_thumbnail_keep_it)
{
    char tmp[256], out[600];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf *src = knit16();
    btf_pca_options po = {0};
    po.k = 3, po.components = 6;
    btf_package_options ko = {0};
    ko.linear = 1;
    btf_error err = {0};
    for (int resid = 0; resid < 2; resid++) {
        btf_lod_options lo = {0};
        lo.levels = 2, lo.residual = resid;
        snprintf(out, sizeof out, "%s/lod%d", tmp, resid);
        cr_assert_eq(btf_lod_compress(src, &po, &ko, &lo, out, NULL, &err), BTF_OK, "%s", err.msg);
        btf_package *p = fx_package(out, NULL, 0);
        cr_expect(p->linear && p->version == (resid ? 4 : 2), "levels, residual %d", resid);
        btf_package_free(p);
    }
    ko.rd = 1;
    snprintf(out, sizeof out, "%s/rd", tmp);
    cr_assert_eq(btf_package_compress(src, &po, &ko, out, NULL, &err), BTF_OK, "%s", err.msg);
    btf_package *p = fx_package(out, NULL, 0);
    cr_expect(p->linear && p->version == 3);
    btf_package_free(p);
    ko.rd = 0;
    btf_budget b = {0};
    b.max_error = 2.0, b.k[0] = 3, b.n_k = 1, b.max_components = 6;
    btf_budget_result res;
    snprintf(out, sizeof out, "%s/budget", tmp);
    cr_assert_eq(btf_budget_compress(src, &po, &ko, &b, out, &res, &err), BTF_OK, "%s", err.msg);
    p = fx_package(out, NULL, 0);
    cr_expect(p->linear && p->budget);
    btf_package_free(p);
    /* thumbnails: full rank, 16 bits, so both are the source's own head-on picture */
    uint8_t *img[2] = {NULL, NULL};
    int w[2], h[2];
    const char *sub[2] = {"srgb", "linear"};
    for (int lin = 0; lin < 2; lin++) {
        compress(src, tmp, sub[lin], 1, 21, 16, lin);
        p = fx_package(tmp, sub[lin], 0);
        cr_assert_eq(btf_package_thumbnail_rgb(p, 128, &w[lin], &h[lin], &img[lin], &err), BTF_OK, "%s", err.msg);
        btf_package_free(p);
    }
    cr_assert(w[0] == w[1] && h[0] == h[1]);
    for (int i = 0; i < w[0] * h[0] * 3; i++)
        cr_assert_eq(img[0][i], img[1][i], "byte %d", i);
    free(img[0]), free(img[1]);
    btf_free(src);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* The array helpers give exactly the per-value formulas, the 8-bit table of
 * btf_color_srgb_decode_n included (byte values, values between them, negative
 * and above 1); encode_n takes NaN to 0. */
Test(linear, array_helpers_equal_the_formulas)
{
    enum { N = 8192 };
    static float v[N], e[N];
    uint32_t seed = 33;
    for (int i = 0; i < N; i++)
        v[i] = i < 256 ? (float)i * (1.0f / 255.0f) : (float)(fx_unit(fx_xorshift32(&seed)) * 1.4 - 0.2);
    memcpy(e, v, sizeof v);
    btf_color_srgb_decode_n(v, N);
    for (int i = 0; i < N; i++)
        cr_assert_eq(v[i], (float)btf_color_srgb_decode(e[i]), "decode %d: %.9g", i, e[i]);
    memcpy(v, e, sizeof v); /* the original values again */
    btf_color_srgb_encode_n(e, N);
    for (int i = 0; i < N; i++) /* the EOTF written out here undoes the encoding */
        cr_assert_float_eq(srgb_to_linear(e[i]), (double)v[i], 1e-6 + 1e-6 * fabs(v[i]), "round trip %d", i);
    float nan[2] = {NAN, -NAN};
    btf_color_srgb_encode_n(nan, 2);
    cr_assert(nan[0] == 0.0f && nan[1] == 0.0f);
}
