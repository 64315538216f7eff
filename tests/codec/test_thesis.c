/* test_thesis.c - room codec, suites "thesis" and "slow_thesis": the thesis's
 * package format (codec/input/btf_thesis.h): reader against the published
 * wool/corduroy packages (the format's facts restated here, and an independent
 * per-pixel decoder written here from them), reconstruction, writer round
 * trip, and bad packages. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_cli.h"
#include "btf_image.h"
#include "btf_io.h"
#include "btf_thesis.h"
#include "fixtures.h"
#include "btf_input.h"

/* ------------------------------------------------------------ helpers */

static void cleanup(const char *tmp);

static int material_dir(char *buf, size_t n, const char *name)
{
    char rel[256];
    snprintf(rel, sizeof rel, "data/thesis-ubo2003/%s/meta.json", name);
    if (!fx_shared_path(buf, n, rel))
        return 0;
    buf[strlen(buf) - strlen("/meta.json")] = '\0';
    return 1;
}

#define NEED_MATERIAL(buf, name)                                                                                \
    char buf[4096];                                                                                            \
    if (!material_dir(buf, sizeof buf, name))                                                                  \
    cr_skip_test("shared thesis data absent")

/* The raw bytes of a published package (C = 8, N = 81, k = 3, S = 256, as published). */
typedef struct raw_pkg {
    uint8_t *comp[8]; /* j.png pixels, flat */
    uint8_t *r;       /* R.png pixels, flat */
} raw_pkg;

static void raw_read(const char *dir, raw_pkg *raw)
{
    char path[4200];
    int w, h, ch;
    for (int j = 0; j < 8; j++) {
        snprintf(path, sizeof path, "%s/%d.png", dir, j);
        cr_assert_eq(btf_image_read_u8(path, &w, &h, &ch, &raw->comp[j], NULL), BTF_OK);
        cr_assert(w == 128 && h == 128 * 27 && ch == 4);
    }
    snprintf(path, sizeof path, "%s/R.png", dir);
    cr_assert_eq(btf_image_read_u8(path, &w, &h, &ch, &raw->r, NULL), BTF_OK);
    cr_assert(w == 256 && h == 256 && ch == 4);
}

static void raw_free(raw_pkg *raw)
{
    for (int j = 0; j < 8; j++)
        free(raw->comp[j]);
    free(raw->r);
}

/* The package's decoding written out independently of the library, one value at a time. */
static double raw_decode(const raw_pkg *raw, int view, int light, int x, int y, int c)
{
    const int C = 8, N = 81, k = 3, S = 256, nb = 27;
    int b = view / k;
    long s0 = (long)(C / 4) * 3 * N * k * nb;
    double sum = 0.0;
    for (int j = 0; j < C; j++) {
        double l = raw->comp[j][(long)b * S * S + (long)y * S + x] * 2.0 / 255.0 - 1.0;
        long wp = ((long)(view * N + light) * 3 + c) * (C / 4) + j / 4;
        double v = raw->r[wp * 4 + j % 4] * 2.0 / 255.0 - 1.0;
        const uint8_t *sp = raw->r + (s0 + (long)b * C / 2 + j / 2) * 4 + (j % 2) * 2;
        double sigma = 10.0 * sp[0] + 0.1 * sp[1];
        sum += l * sigma * v;
    }
    return sum;
}

/* (view, light, x, y): first/last views and lights, a block crossing ring boundaries
 * (block 2 = views 6,7,8: theta 15 and 30), edges and corners of the texture. */
static const int probes[][4] = {{0, 0, 0, 0},     {1, 80, 255, 0},  {6, 7, 17, 200}, {7, 40, 255, 255},
                                {8, 56, 128, 64}, {36, 37, 3, 250}, {57, 2, 99, 1},  {80, 80, 200, 31}};
#define NPROBES (int)(sizeof probes / sizeof probes[0])

/* ------------------------------------------------------------ published data */

static void check_spec_facts(const char *name)
{
    NEED_MATERIAL(dir, name);
    btf_thesis_pkg p;
    btf_error e = {0};
    cr_assert_eq(btf_thesis_read(dir, &p, &e), BTF_OK, "%s", e.msg);
    cr_expect(p.C == 8 && p.N == 81 && p.k == 3 && p.S == 256 && p.r_size == 256 && p.tex_size == 2048);
    cr_expect_eq(p.nb, 27, "block count");
    /* failures are counted, not asserted one by one: Criterion assertions are slow in loops */
    long bad = -1;
    for (int b = 0; b < p.nb; b++)
        if (p.sigma[b * p.C] != 1.0f)
            bad = b;
    cr_expect_eq(bad, -1, "sigma_0 of block %ld is not 1", bad);
    for (size_t row = 0; row < (size_t)p.nb * p.k * p.N * 3; row++)
        if (p.V[row * p.C] != 1.0f)
            bad = (long)row;
    cr_expect_eq(bad, -1, "weight of component 0 (row %ld) is not byte 255", bad);
    /* component 0 is the block mean of data in 0..1 (up to one quantisation step) */
    for (size_t t = 0; t < (size_t)p.nb * p.S * p.S; t++)
        if (p.L[t * p.C] < -1.0f / 255.0f)
            bad = (long)t;
    cr_expect_eq(bad, -1, "mean component at texel %ld negative", bad);
    btf_thesis_free(&p);
}

Test(thesis, spec_facts_wool) { check_spec_facts("wool"); }
Test(thesis, spec_facts_corduroy) { check_spec_facts("corduroy"); }

Test(thesis, decode_matches_independent_per_pixel_decoder)
{
    NEED_MATERIAL(dir, "corduroy");
    raw_pkg raw = {0};
    raw_read(dir, &raw);
    btf_thesis_pkg p;
    cr_assert_eq(btf_thesis_read(dir, &p, NULL), BTF_OK);
    for (int i = 0; i < NPROBES; i++) {
        float rgb[3];
        btf_thesis_decode_pixel(&p, probes[i][0], probes[i][1], probes[i][2], probes[i][3], rgb);
        for (int c = 0; c < 3; c++) {
            double want = raw_decode(&raw, probes[i][0], probes[i][1], probes[i][2], probes[i][3], c);
            /* 8 float products of magnitude <= ~2560: float rounding stays far below 1e-3 */
            cr_expect(fabs(rgb[c] - want) < 1e-3, "probe %d c %d: %f vs %f", i, c, rgb[c], want);
        }
    }
    btf_thesis_free(&p);
    raw_free(&raw);
}

Test(thesis, import_box_filtered_matches_independent_decoder)
{
    NEED_MATERIAL(dir, "wool");
    raw_pkg raw = {0};
    raw_read(dir, &raw);
    btf_load_options o = {0};
    o.downsample = 8; /* 256 -> 32: each output texel is an 8x8 box */
    o.storage = BTF_F32;
    btf *f = NULL, *u = NULL;
    btf_error e = {0};
    cr_assert_eq(btf_import_thesis(dir, &o, &f, &e), BTF_OK, "%s", e.msg);
    o.storage = 0; /* default: bytes, clamped */
    cr_assert_eq(btf_import_thesis(dir, &o, &u, &e), BTF_OK, "%s", e.msg);
    cr_assert(f->width == 32 && f->height == 32 && u->storage == BTF_U8);
    btf_dirset ubo = btf_dirset_ubo2003();
    cr_expect(btf_dirset_equal(&f->views, &ubo) && btf_dirset_equal(&f->lights, &ubo));
    for (int i = 0; i < NPROBES; i++) {
        int v = probes[i][0], l = probes[i][1], x = probes[i][2] / 8, y = probes[i][3] / 8;
        for (int c = 0; c < 3; c++) {
            double mean = 0.0;
            for (int dy = 0; dy < 8; dy++)
                for (int dx = 0; dx < 8; dx++)
                    mean += raw_decode(&raw, v, l, x * 8 + dx, y * 8 + dy, c) / 64.0;
            cr_expect(fabs(btf_get(f, v, l, x, y, c) - mean) < 1e-3, "probe %d: %f vs %f", i,
                      btf_get(f, v, l, x, y, c), mean);
            /* bytes: the clamped value rounded; float summation order may move a
             * value sitting on a rounding boundary by one step */
            double want = fmin(fmax(mean, 0.0), 1.0) * 255.0;
            double got = ((uint8_t *)u->data)[btf_index(u, v, l, x, y, c)];
            cr_expect(fabs(got - want) <= 0.5 + 1e-3, "probe %d bytes: %f vs %f", i, got, want);
        }
    }
    btf_free(f);
    btf_free(u);
    raw_free(&raw);
}

Test(thesis, about_one_percent_outside_unit_range)
{
    NEED_MATERIAL(dir, "wool");
    btf_thesis_pkg p;
    cr_assert_eq(btf_thesis_read(dir, &p, NULL), BTF_OK);
    float *img = malloc(sizeof(float) * 256 * 256 * 3);
    size_t out = 0, n = 0;
    /* every 5th view and light: 17 x 17 images; measured 2.50% for wool (2.50% on
     * all 6561 images too; corduroy 1.09%). The thesis says "about 1%": accept
     * 0.1%..5%, which still catches a wrong scale (sigma x10 or /10 changes it a lot). */
    for (int v = 0; v < 81; v += 5)
        for (int l = 0; l < 81; l += 5) {
            btf_thesis_decode_image(&p, v, l, img);
            for (int i = 0; i < 256 * 256 * 3; i++, n++)
                out += img[i] < 0.0f || img[i] > 1.0f;
        }
    double frac = (double)out / (double)n;
    cr_expect(frac > 0.001 && frac < 0.05, "fraction outside [0,1]: %f", frac);
    free(img);
    btf_thesis_free(&p);
}

Test(thesis, non_divisor_size_preserves_image_mean)
{
    NEED_MATERIAL(dir, "corduroy");
    btf_thesis_pkg p;
    cr_assert_eq(btf_thesis_read(dir, &p, NULL), BTF_OK);
    btf *b = NULL;
    btf_error e = {0};
    /* 48 x 40 does not divide 256: area-weighted resampling, which keeps the
     * image mean (every output texel covers the same source area). */
    cr_assert_eq(btf_thesis_reconstruct(&p, NULL, 48, 40, BTF_F32, &b, &e), BTF_OK, "%s", e.msg);
    cr_assert(b->width == 48 && b->height == 40);
    float *img = malloc(sizeof(float) * 256 * 256 * 3);
    const int pairs[][2] = {{0, 0}, {40, 12}, {80, 79}};
    for (int i = 0; i < 3; i++) {
        btf_thesis_decode_image(&p, pairs[i][0], pairs[i][1], img);
        for (int c = 0; c < 3; c++) {
            double src = 0.0, dst = 0.0;
            for (int t = 0; t < 256 * 256; t++)
                src += img[t * 3 + c];
            for (int y = 0; y < 40; y++)
                for (int x = 0; x < 48; x++)
                    dst += btf_get(b, pairs[i][0], pairs[i][1], x, y, c);
            src /= 256.0 * 256.0, dst /= 48.0 * 40.0;
            cr_expect(fabs(src - dst) < 1e-4, "pair %d c %d: %f vs %f", i, c, src, dst);
        }
    }
    free(img);
    btf_free(b);
    btf_thesis_free(&p);
}

/* Re-encodes a whole published package (8 PNGs of 1.8 MB): a few seconds. */
Test(slow_thesis, rewrite_of_published_package_is_lossless)
{
    NEED_MATERIAL(dir, "wool");
    btf_thesis_pkg p, q;
    cr_assert_eq(btf_thesis_read(dir, &p, NULL), BTF_OK);
    char tmp[256], out[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/wool", tmp);
    btf_error e = {0};
    cr_assert_eq(btf_thesis_write(out, &p, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(btf_thesis_read(out, &q, &e), BTF_OK, "%s", e.msg);
    cr_expect(q.C == p.C && q.N == p.N && q.k == p.k && q.S == p.S && q.r_size == p.r_size && q.tex_size == p.tex_size);
    /* every dequantised byte re-quantises to itself: identical arrays */
    cr_expect(memcmp(p.L, q.L, sizeof(float) * (size_t)p.nb * p.S * p.S * p.C) == 0);
    cr_expect(memcmp(p.V, q.V, sizeof(float) * (size_t)p.nb * p.k * p.N * 3 * p.C) == 0);
    cr_expect(memcmp(p.sigma, q.sigma, sizeof(float) * (size_t)p.nb * p.C) == 0);
    btf_thesis_free(&p);
    btf_thesis_free(&q);
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    cr_expect_eq(system(cmd), 0);
}

/* ------------------------------------------------------------ writer, synthetic */

/* Small package with values spread over the whole range (C = 5: not a multiple of 4;
 * N = 7, k = 3: the last block is padded). */
static void make_small(btf_thesis_pkg *p)
{
    cr_assert_eq(btf_thesis_alloc(5, 7, 3, 8, p, NULL), BTF_OK);
    cr_assert_eq(p->nb, 3);
    unsigned s = 12345u;
#define RND() ((s = s * 1103515245u + 12345u), (float)((s >> 8) & 0xffff) / 65535.0f)
    for (size_t i = 0; i < (size_t)p->nb * p->S * p->S * p->C; i++)
        p->L[i] = RND() * 2.0f - 1.0f;
    for (size_t i = 0; i < (size_t)p->nb * p->k * p->N * 3 * p->C; i++)
        p->V[i] = i % (size_t)p->C ? RND() * 2.0f - 1.0f : 1.0f;
    for (int b = 0; b < p->nb; b++)
        for (int j = 0; j < p->C; j++)
            p->sigma[b * p->C + j] = j ? RND() * 2559.9f : 1.0f;
#undef RND
}

Test(thesis, write_read_round_trip_within_quantisation)
{
    btf_thesis_pkg p, q;
    make_small(&p);
    char tmp[256], out[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/pkg", tmp);
    btf_error e = {0};
    cr_assert_eq(btf_thesis_write(out, &p, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(btf_thesis_read(out, &q, &e), BTF_OK, "%s", e.msg);
    cr_assert(q.C == 5 && q.N == 7 && q.k == 3 && q.S == 8 && q.nb == 3);
    /* byte steps are 2/255: rounding moves a value by at most half a step */
    const float half = 1.0f / 255.0f + 1e-6f;
    long bad = -1;
    for (size_t i = 0; i < (size_t)p.nb * p.S * p.S * p.C; i++)
        if (!(fabsf(p.L[i] - q.L[i]) <= half))
            bad = (long)i;
    cr_expect_eq(bad, -1, "L[%ld] moved more than half a step", bad);
    for (size_t i = 0; i < (size_t)p.nb * p.k * p.N * 3 * p.C; i++)
        if (!(fabsf(p.V[i] - q.V[i]) <= half))
            bad = (long)i;
    cr_expect_eq(bad, -1, "V[%ld] moved more than half a step", bad);
    /* sigma in 0.1 steps: at most 0.05 off (plus float rounding of values ~2560) */
    for (int i = 0; i < p.nb * p.C; i++)
        cr_assert(fabsf(p.sigma[i] - q.sigma[i]) <= 0.0501f, "sigma[%d] %f vs %f", i, p.sigma[i], q.sigma[i]);
    cr_expect_eq(q.sigma[0], 1.0f);
    /* a non-empty target is refused, nothing is left behind on failure */
    cr_expect_eq(btf_thesis_write(out, &p, &e), BTF_ERR_IO);
    cr_expect(strstr(e.msg, "not an empty directory") != NULL, "%s", e.msg);
    btf_thesis_free(&q);
    p.L[17] = 1.5f;
    snprintf(out, sizeof out, "%s/bad", tmp);
    cr_expect_eq(btf_thesis_write(out, &p, &e), BTF_ERR_RANGE);
    cr_expect(strstr(e.msg, "L value") != NULL, "%s", e.msg);
    p.L[17] = 0.0f;
    p.sigma[3] = 3000.0f;
    cr_expect_eq(btf_thesis_write(out, &p, &e), BTF_ERR_RANGE);
    cr_expect(access(out, F_OK) != 0, "nothing written for a refused package");
    btf_thesis_free(&p);
    btf_thesis_free(&p); /* double free of a zeroed struct is harmless */
    btf_thesis_free(NULL);
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    cr_expect_eq(system(cmd), 0);
}

Test(thesis, every_byte_and_sigma_digit_pair_survives_exactly)
{
    /* C = 8, N = 2, k = 1, S = 16: 2 blocks x 256 texels, so L holds every byte value */
    btf_thesis_pkg p, q;
    cr_assert_eq(btf_thesis_alloc(8, 2, 1, 16, &p, NULL), BTF_OK);
    size_t nl = (size_t)p.nb * p.S * p.S * p.C, nv = (size_t)p.nb * p.k * p.N * 3 * p.C;
    for (size_t i = 0; i < nl; i++)
        p.L[i] = (float)((double)((i * 7) % 256) * 2.0 / 255.0 - 1.0);
    for (size_t i = 0; i < nv; i++)
        p.V[i] = (float)((double)((i * 13) % 256) * 2.0 / 255.0 - 1.0);
    static const int digits[16][2] = {{0, 10}, {0, 0}, {255, 99}, {14, 85}, {2, 34}, {1, 96}, {100, 1}, {0, 99},
                                      {1, 0},  {9, 9}, {254, 50}, {3, 3},   {0, 1},  {17, 70}, {128, 64}, {200, 5}};
    for (int i = 0; i < 16; i++)
        p.sigma[i] = (float)(10.0 * digits[i][0] + 0.1 * digits[i][1]);
    char tmp[256], out[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/pkg", tmp);
    btf_error e = {0};
    cr_assert_eq(btf_thesis_write(out, &p, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(btf_thesis_read(out, &q, &e), BTF_OK, "%s", e.msg);
    /* exact to float rounding (1e-6 << the 2/255 byte step and the 0.1 sigma step) */
    long bad = -1;
    for (size_t i = 0; i < nl; i++)
        if (!(fabsf(p.L[i] - q.L[i]) < 1e-6f))
            bad = (long)i;
    cr_expect_eq(bad, -1, "L[%ld] changed", bad);
    for (size_t i = 0; i < nv; i++)
        if (!(fabsf(p.V[i] - q.V[i]) < 1e-6f))
            bad = (long)i;
    cr_expect_eq(bad, -1, "V[%ld] changed", bad);
    for (int i = 0; i < 16; i++)
        cr_expect(fabsf(p.sigma[i] - q.sigma[i]) < 1e-3f, "sigma %d: %f vs %f", i, p.sigma[i], q.sigma[i]);
    btf_thesis_free(&p);
    btf_thesis_free(&q);
    cleanup(tmp);
}

/* ------------------------------------------------------------ bad packages */

/* Writes the small synthetic package to <tmp>/pkg; returns its path in out. */
static void small_on_disk(char *tmp, size_t tn, char *out, size_t on)
{
    btf_thesis_pkg p;
    make_small(&p);
    cr_assert(fx_tmpdir(tmp, tn));
    snprintf(out, on, "%s/pkg", tmp);
    cr_assert_eq(btf_thesis_write(out, &p, NULL), BTF_OK);
    btf_thesis_free(&p);
}

static void expect_fail(const char *dir, btf_result code, const char *needle)
{
    btf_thesis_pkg p;
    btf_error e = {0};
    btf_result r = btf_thesis_read(dir, &p, &e);
    cr_expect_eq(r, code, "got %s (%s), want %s", btf_result_string(r), e.msg, btf_result_string(code));
    cr_expect(strstr(e.msg, needle) != NULL, "message '%s' lacks '%s'", e.msg, needle);
    cr_expect_null(p.L);
    btf *b = (btf *)1;
    cr_expect_eq(btf_import_thesis(dir, NULL, &b, NULL), code);
    cr_expect_null(b);
}

static void cleanup(const char *tmp)
{
    cr_expect_eq(fx_rmtree(tmp), 0);
}

Test(thesis, bad_meta_json)
{
    char tmp[256], dir[300], path[400];
    small_on_disk(tmp, sizeof tmp, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/meta.json", dir);
    unlink(path);
    expect_fail(dir, BTF_ERR_MISSING, "meta.json");
    const char *ok = "\"numDirections\":\"7\",\"texSize\":\"64\",\"blockSize\":\"3\",\"imageSize\":\"8\",\"RSize\":\"16\"";
    char text[400];
    snprintf(text, sizeof text, "{\"numComp\":\"five\",%s}", ok);
    fx_put_text(dir, "meta.json", text);
    expect_fail(dir, BTF_ERR_FORMAT, "numComp");
    snprintf(text, sizeof text, "{\"numComp\":\"5x\",%s}", ok);
    fx_put_text(dir, "meta.json", text);
    expect_fail(dir, BTF_ERR_FORMAT, "numComp");
    snprintf(text, sizeof text, "{\"numComp\":\"0\",%s}", ok);
    fx_put_text(dir, "meta.json", text);
    expect_fail(dir, BTF_ERR_RANGE, "numComp");
    snprintf(text, sizeof text, "{\"numComp\":\"99999999999\",%s}", ok);
    fx_put_text(dir, "meta.json", text);
    expect_fail(dir, BTF_ERR_FORMAT, "numComp");
    snprintf(text, sizeof text, "{%s}", ok);
    fx_put_text(dir, "meta.json", text);
    expect_fail(dir, BTF_ERR_FORMAT, "missing \"numComp\"");
    fx_put_text(dir, "meta.json",
                "{\"numComp\":\"5\",\"numDirections\":\"7\",\"texSize\":\"64\",\"blockSize\":\"9\",\"imageSize\":\"8\","
                "\"RSize\":\"16\"}");
    expect_fail(dir, BTF_ERR_RANGE, "blockSize");
    fx_put_text(dir, "meta.json",
                "{\"numComp\":\"5\",\"numDirections\":\"7\",\"texSize\":\"64\",\"blockSize\":\"3\",\"imageSize\":\"7\","
                "\"RSize\":\"16\"}");
    expect_fail(dir, BTF_ERR_RANGE, "imageSize");
    /* 2*3*7*3*3 + 3*3 = 387 pixels do not fit in 16 x 16 */
    fx_put_text(dir, "meta.json",
                "{\"numComp\":\"5\",\"numDirections\":\"7\",\"texSize\":\"64\",\"blockSize\":\"3\",\"imageSize\":\"8\","
                "\"RSize\":\"16\"}");
    expect_fail(dir, BTF_ERR_RANGE, "RSize");
    fx_put_text(dir, "meta.json", "{\"numComp\":\"5\",");
    expect_fail(dir, BTF_ERR_FORMAT, "not a JSON object");
    fx_put_text(dir, "meta.json", "[1,2,3]");
    expect_fail(dir, BTF_ERR_FORMAT, "not a JSON object");
    cleanup(tmp);
}

Test(thesis, bad_png_parts)
{
    char tmp[256], dir[300], path[400];
    small_on_disk(tmp, sizeof tmp, dir, sizeof dir);
    /* sanity: the untouched copy reads */
    btf_thesis_pkg p;
    btf_error e = {0};
    cr_assert_eq(btf_thesis_read(dir, &p, &e), BTF_OK, "%s", e.msg);
    btf_thesis_free(&p);
    /* wrong size: a 4 x 4 RGBA image as component 2 */
    uint8_t px[4 * 4 * 4] = {0};
    snprintf(path, sizeof path, "%s/2.png", dir);
    cr_assert_eq(btf_image_write(path, 4, 4, 4, 8, px, NULL), BTF_OK);
    expect_fail(dir, BTF_ERR_FORMAT, "2.png");
    /* right size, 3 channels instead of RGBA */
    uint8_t rgb[4 * 12 * 3] = {0};
    cr_assert_eq(btf_image_write(path, 4, 12, 3, 8, rgb, NULL), BTF_OK);
    expect_fail(dir, BTF_ERR_FORMAT, "2.png");
    /* missing component */
    unlink(path);
    expect_fail(dir, BTF_ERR_MISSING, "2.png");
    /* R.png of the wrong size */
    cleanup(tmp);
    small_on_disk(tmp, sizeof tmp, dir, sizeof dir); /* a fresh copy */
    snprintf(path, sizeof path, "%s/R.png", dir);
    cr_assert_eq(btf_image_write(path, 4, 4, 4, 8, px, NULL), BTF_OK);
    expect_fail(dir, BTF_ERR_FORMAT, "R.png");
    cleanup(tmp);
}

Test(thesis, truncated_png_of_published_package)
{
    NEED_MATERIAL(src, "wool");
    char tmp[256], cmd[9000], path[400];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(cmd, sizeof cmd, "cp '%s'/*.png '%s'/meta.json '%s'/", src, src, tmp);
    cr_assert_eq(system(cmd), 0);
    snprintf(path, sizeof path, "%s/5.png", tmp);
    FILE *f = fopen(path, "rb");
    cr_assert(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fclose(f);
    cr_assert_eq(truncate(path, n / 2), 0);
    btf_thesis_pkg p;
    btf_error e = {0};
    btf_result r = btf_thesis_read(tmp, &p, &e);
    cr_expect(r == BTF_ERR_FORMAT || r == BTF_ERR_IO, "%s", btf_result_string(r));
    cr_expect(strstr(e.msg, "5.png") != NULL, "%s", e.msg);
    cr_assert_eq(truncate(path, 20), 0); /* header cut: size unknown */
    r = btf_thesis_read(tmp, &p, &e);
    cr_expect(r == BTF_ERR_FORMAT || r == BTF_ERR_IO, "%s", btf_result_string(r));
    cr_expect(strstr(e.msg, "5.png") != NULL, "%s", e.msg);
    cleanup(tmp);
}

/* ------------------------------------------------------------ command line */

Test(thesis, import_command_writes_a_btf_file_that_loads_back)
{
    NEED_MATERIAL(dir, "corduroy");
    char tmp[256], out[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(out, sizeof out, "%s/c8.btf", tmp);
    char *argv[] = {"import-thesis", dir, out, "--size", "8", NULL};
    cr_assert_eq(cmd_import_thesis(5, argv), 0);
    btf *f = NULL, *ref = NULL;
    btf_error e = {0};
    cr_assert_eq(btf_load_dfmf(out, NULL, &f, &e), BTF_OK, "%s", e.msg);
    btf_load_options o = {0};
    o.width = o.height = 8;
    cr_assert_eq(btf_import_thesis(dir, &o, &ref, &e), BTF_OK, "%s", e.msg);
    cr_assert(f->width == 8 && f->height == 8 && btf_dirset_equal(&f->views, &ref->views));
    /* the command stores the clamped bytes; the full-rank file keeps byte/255 exactly */
    long bad = -1;
    for (size_t i = 0; i < ref->count; i++)
        if (fabsf(((float *)f->data)[i] - ((uint8_t *)ref->data)[i] / 255.0f) > 1e-6f)
            bad = (long)i;
    cr_expect_eq(bad, -1, "sample %ld differs", bad);
    btf_free(f);
    btf_free(ref);
    char *bad_args[] = {"import-thesis", dir, NULL};
    cr_expect_eq(cmd_import_thesis(2, bad_args), 2, "usage error");
    char *bad_size[] = {"import-thesis", dir, out, "--size", "0", NULL};
    cr_expect_eq(cmd_import_thesis(5, bad_size), 2);
    char *missing[] = {"import-thesis", tmp, out, NULL};
    cr_expect_eq(cmd_import_thesis(3, missing), 1, "no meta.json: failure");
    cleanup(tmp);
}
