/* test_thumbnail.c - room codec, suite "thumbnail": the poster a package gets
 * (codec/compress/btf_package_thumbnail.c, doc/package-format.md section 2) from the
 * library calls, plain (btf_package_compress), under a budget (btf_budget_compress),
 * with levels and residual levels (btf_lod_compress) and version 3 (rd); the
 * commands' --no-thumbnail (`btf compress`, `btf lod`); its pixels against the
 * package decoded here on another path.
 *
 * Tolerance: one 8-bit level. The thumbnail comes from btf_decode (the head-on
 * light and view through the angular interpolation: weight 1 on the measured
 * direction) and, above 128 texels, a box filter summed in float; the expected
 * values here come from btf_package_value (the direct sum at the measured pair)
 * and an area mean in double. The two orders of float operations may put a value
 * that lies within float rounding of a half level on either side of it, so a
 * sample may round to the neighbouring byte, never further. Almost every sample
 * must match exactly (a bias, such as truncating instead of rounding, fails). */
#include <criterion/criterion.h>
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_budget.h"
#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_image.h"
#include "btf_lod.h"
#include "btf_package.h"
#include "fixtures.h"

static char g_dir[256];

static void setup(void)
{
    cr_assert(fx_tmpdir(g_dir, sizeof g_dir));
}

static void teardown(void)
{
    fx_rmtree(g_dir);
}

TestSuite(thumbnail, .init = setup, .fini = teardown, .timeout = 120);

/* `btf compress gen:knit:16 g_dir/NAME --components 4 --name knit --quiet EXTRA...`
 * (extra NULL-terminated); the package's path into out. */
static void compress(const char *name, const char *const *extra, char *out, size_t n)
{
    snprintf(out, n, "%s/%s", g_dir, name);
    char *argv[32] = {"compress", "gen:knit:16", out, "--components", "4", "--name", "knit", "--quiet"};
    int argc = 8;
    for (int i = 0; extra && extra[i] && argc < 31; i++)
        argv[argc++] = (char *)extra[i];
    argv[argc] = NULL;
    cr_assert_eq(cmd_compress(argc, argv), 0, "compress %s", out);
}

/* How compress_knit writes the package. */
typedef enum { PLAIN, NO_THUMBNAIL, BUDGET, LEVELS, RESIDUAL, RD } knit_variant;

/* The material of gen:knit:16 (16x16, UBO2003 directions, 8-bit) compressed by the
 * library into g_dir/NAME as `btf compress --components 4 --name knit` does (k 3,
 * 8-bit textures, a thumbnail of at most BTF_PACKAGE_THUMBNAIL_SIDE), and: PLAIN as
 * it is; NO_THUMBNAIL without the thumbnail; BUDGET under 150000 bytes with k 3 and
 * at most 8 components (btf_budget_compress); LEVELS, RESIDUAL with 2 levels
 * (btf_lod_compress: version 2, version 4); RD version 3. The path into out. */
static void compress_knit(const char *name, knit_variant v, char *out, size_t n)
{
    snprintf(out, n, "%s/%s", g_dir, name);
    btf_dirset ubo = btf_dirset_ubo2003();
    btf *src = fx_gen(BTF_GEN_KNIT, 16, &ubo, BTF_U8);
    btf_pca_options po = {0};
    po.k = 3, po.components = 4;
    btf_package_options ko = {0};
    ko.bits = 8, ko.name = "knit", ko.thumbnail = v == NO_THUMBNAIL ? 0 : BTF_PACKAGE_THUMBNAIL_SIDE;
    ko.rd = v == RD;
    btf_lod_options lo = {0};
    lo.levels = v == LEVELS || v == RESIDUAL ? 2 : 0;
    lo.residual = v == RESIDUAL;
    btf_error err = {0};
    if (v == BUDGET) {
        btf_budget b = {0};
        b.max_bytes = 150000, b.k[0] = 3, b.n_k = 1, b.max_components = 8;
        po.components = 8;
        btf_budget_result res;
        cr_assert_eq(btf_budget_compress(src, &po, &ko, &b, out, &res, &err), BTF_OK, "%s: %s", out, err.msg);
    } else {
        cr_assert_eq(btf_lod_compress(src, &po, &ko, &lo, out, NULL, &err), BTF_OK, "%s: %s", out, err.msg);
    }
    btf_free(src);
}

/* dir/thumbnail.png as 8-bit RGB; its size into *w, *h (the caller frees it). */
static uint8_t *read_thumbnail(const char *dir, int *w, int *h)
{
    char path[512];
    snprintf(path, sizeof path, "%s/thumbnail.png", dir);
    uint8_t *px = NULL;
    int ch = 0;
    btf_error err = {0};
    cr_assert_eq(btf_image_read_u8(path, w, h, &ch, &px, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(ch, 3, "%s: %d channels, not RGB", path, ch);
    return px;
}

/* Index of the smallest theta of d (the first of equals), found here by angle. */
static int smallest_theta(const btf_dirset *d)
{
    int best = 0;
    for (int i = 1; i < d->n_dirs; i++) {
        float ti, pi, tb, pb;
        btf_dirset_angles(d, i, &ti, &pi);
        btf_dirset_angles(d, best, &tb, &pb);
        best = ti < tb ? i : best;
    }
    return best;
}

/* The package seen head-on by the direct reconstruction at the measured pair
 * (btf_package_value, all loaded chunks), 0..255 scale, width * height * 3. */
static double *head_on_values(const btf_package *p)
{
    int v = smallest_theta(&p->views), l = smallest_theta(&p->lights);
    double *out = malloc((size_t)p->width * p->height * 3 * sizeof(double));
    cr_assert_not_null(out);
    for (int y = 0; y < p->height; y++)
        for (int x = 0; x < p->width; x++) {
            float rgb[3];
            btf_package_value(p, v, l, x, y, 0, rgb);
            for (int c = 0; c < 3; c++)
                out[((size_t)y * p->width + x) * 3 + c] = 255.0 * rgb[c];
        }
    return out;
}

/* Thumbnail pixel (i, j) of a w x h thumbnail of the W x H values full: the mean of
 * the texels under the pixel's footprint, each weighted by the area it covers. */
static void area_mean(const double *full, int W, int H, int w, int h, int i, int j, double out[3])
{
    double sx = (double)W / w, sy = (double)H / h, x0 = i * sx, x1 = x0 + sx, y0 = j * sy, y1 = y0 + sy;
    out[0] = out[1] = out[2] = 0.0;
    for (int y = (int)y0; y < H && y < y1; y++)
        for (int x = (int)x0; x < W && x < x1; x++) {
            double a = (fmin(x + 1.0, x1) - fmax(x, x0)) * (fmin(y + 1.0, y1) - fmax(y, y0));
            for (int c = 0; c < 3; c++)
                out[c] += a > 0.0 ? a * full[((size_t)y * W + x) * 3 + c] : 0.0;
        }
    for (int c = 0; c < 3; c++)
        out[c] /= sx * sy;
}

/* The thumbnail px (w x h) of package p against the head-on values, box-averaged
 * when the thumbnail is smaller than the material. */
static void expect_head_on(const btf_package *p, const uint8_t *px, int w, int h, const char *what)
{
    double *full = head_on_values(p), m[3];
    int worst = 0, exact = 0, n = w * h * 3;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            area_mean(full, p->width, p->height, w, h, i, j, m);
            for (int c = 0; c < 3; c++) {
                int want = (int)lround(fmin(fmax(m[c], 0.0), 255.0)), d = abs(px[(j * w + i) * 3 + c] - want);
                worst = d > worst ? d : worst;
                exact += d == 0;
            }
        }
    free(full);
    cr_expect_leq(worst, 1, "%s: a sample is %d levels off the head-on decode", what, worst);
    cr_expect_geq(exact, n - n / 50, "%s: only %d of %d samples match exactly", what, exact, n);
}

/* 1 when some chunk of p lists name. */
static int listed(const btf_package *p, const char *name)
{
    for (int i = 0; i < p->n_chunks; i++)
        for (int f = 0; f < p->chunk[i].n_files; f++)
            if (!strcmp(p->chunk[i].files[f], name))
                return 1;
    return 0;
}

/* Files in dir that are neither manifest.json nor listed by a chunk of p. */
static int unlisted_files(const btf_package *p, const char *dir)
{
    int n = fx_count_files(dir) - 1;
    for (int i = 0; i < p->n_chunks; i++)
        n -= p->chunk[i].n_files;
    return n;
}

Test(thumbnail, compress_writes_the_head_on_swatch_outside_the_manifest)
{
    char with[320], without[320];
    compress_knit("with", PLAIN, with, sizeof with);
    compress_knit("without", NO_THUMBNAIL, without, sizeof without);
    btf_package *p = fx_package(with, NULL, 0);
    int w = 0, h = 0;
    uint8_t *px = read_thumbnail(with, &w, &h);
    cr_expect(w == 16 && h == 16, "a 16x16 material keeps its size: %dx%d", w, h);
    cr_expect_eq(smallest_theta(&p->views), 0, "UBO2003: the pole is direction 0");
    expect_head_on(p, px, w, h, "16x16 knit");
    cr_expect(!listed(p, "thumbnail.png"), "no chunk lists the thumbnail");
    cr_expect_eq(unlisted_files(p, with), 1, "the thumbnail is the one file no chunk lists");
    cr_expect(fx_same_file(with, without, "manifest.json"), "the thumbnail changed the manifest (and the etag)");
    free(px);
    btf_package_free(p);
}

Test(thumbnail, no_thumbnail_writes_none)
{
    char out[320], path[400];
    const char *no[] = {"--no-thumbnail", NULL};
    compress("p", no, out, sizeof out);
    snprintf(path, sizeof path, "%s/thumbnail.png", out);
    cr_expect_eq(btf_fs_size(path), -1, "--no-thumbnail wrote %s", path);
    btf_package *p = fx_package(out, NULL, 0);
    cr_expect_eq(unlisted_files(p, out), 0);
    btf_package_free(p);
}

/* m compressed (k views a block, 4 components) with its thumbnail into g_dir/NAME
 * by the library call; the package read back. */
static btf_package *compress_material(const btf *m, int k, const char *name, char *out, size_t n)
{
    btf_pca_options po = {0};
    po.k = k, po.components = 4;
    btf_package_options ko = {0};
    ko.thumbnail = BTF_PACKAGE_THUMBNAIL_SIDE;
    snprintf(out, n, "%s/%s", g_dir, name);
    btf_error err = {0};
    cr_assert_eq(btf_package_compress(m, &po, &ko, out, NULL, &err), BTF_OK, "%s", err.msg);
    return fx_package(out, NULL, 0);
}

/* A W x H part of a 200x200 generated knit on 7 directions, compressed into g_dir/NAME. */
static btf_package *large_package(int W, int H, const char *name, char *out, size_t n)
{
    btf *m = fx_material(BTF_GEN_KNIT, 200, NULL, 0), *part = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_crop(m, 0, 0, W, H, &part, &err), BTF_OK, "%s", err.msg);
    btf_package *p = compress_material(part, 3, name, out, n);
    btf_free(part);
    btf_free(m);
    return p;
}

Test(thumbnail, a_large_material_is_box_filtered_to_128_on_its_longer_side)
{
    static const int sizes[2][4] = {{200, 200, 128, 128}, {200, 50, 128, 32}}; /* material, thumbnail */
    for (int s = 0; s < 2; s++) {
        char out[320], what[64];
        snprintf(what, sizeof what, "%dx%d", sizes[s][0], sizes[s][1]);
        btf_package *p = large_package(sizes[s][0], sizes[s][1], what, out, sizeof out);
        int w = 0, h = 0;
        uint8_t *px = read_thumbnail(out, &w, &h);
        cr_expect(w == sizes[s][2] && h == sizes[s][3], "%s: thumbnail %dx%d, want %dx%d", what, w, h, sizes[s][2],
                  sizes[s][3]);
        if (w == sizes[s][2] && h == sizes[s][3])
            expect_head_on(p, px, w, h, what);
        free(px);
        btf_package_free(p);
    }
}

Test(thumbnail, the_head_on_direction_is_the_smallest_theta_of_a_list_set)
{
    /* surrounds the normal; its smallest theta is direction 4, not 0 */
    static const float dirs[7][2] = {{60, 0}, {60, 90}, {60, 180}, {60, 270}, {15, 30}, {35, 200}, {40, 120}};
    btf_dirset d;
    btf_error err = {0};
    cr_assert_eq(btf_dirset_make_list(dirs, 7, &d, &err), BTF_OK, "%s", err.msg);
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_TILES);
    btf *m = NULL;
    cr_assert_eq(btf_gen_create(&gp, 16, 16, &d, &d, BTF_U8, &m, &err), BTF_OK, "%s", err.msg);
    char out[320];
    btf_package *p = compress_material(m, 1, "list", out, sizeof out);
    cr_assert_eq(smallest_theta(&p->views), 4);
    int w = 0, h = 0;
    uint8_t *px = read_thumbnail(out, &w, &h);
    expect_head_on(p, px, w, h, "list set");
    free(px);
    btf_package_free(p);
    btf_free(m);
}

Test(thumbnail, budget_levels_and_rd_packages_get_the_poster_of_what_they_hold)
{
    static const knit_variant variants[4] = {BUDGET, LEVELS, RESIDUAL, RD}; /* BUDGET: cut to fewer chunks than 8 */
    static const char *const what[4] = {"budget", "levels", "residual levels", "rd"};
    for (int v = 0; v < 4; v++) {
        char out[320], name[16];
        snprintf(name, sizeof name, "v%d", v);
        compress_knit(name, variants[v], out, sizeof out);
        btf_package *p = fx_package(out, NULL, 0);
        if (v == 0)
            cr_expect_lt(p->n_chunks, 8, "the budget did not cut the package: the test proves nothing");
        int w = 0, h = 0;
        uint8_t *px = read_thumbnail(out, &w, &h);
        cr_expect(w == 16 && h == 16, "%s: %dx%d", what[v], w, h);
        expect_head_on(p, px, w, h, what[v]);
        cr_expect(!listed(p, "thumbnail.png"), "%s: a chunk lists the thumbnail", what[v]);
        cr_expect_eq(unlisted_files(p, out), 1, "%s: files besides the chunks' and the thumbnail", what[v]);
        free(px);
        btf_package_free(p);
    }
}

Test(thumbnail, lod_writes_one_of_the_levelled_package_unless_told_not_to)
{
    char v1[320], v2[400], none[400], path[480];
    const char *no[] = {"--no-thumbnail", NULL};
    compress("v1", no, v1, sizeof v1);
    snprintf(v2, sizeof v2, "%s/v2", g_dir);
    snprintf(none, sizeof none, "%s/none", g_dir);
    char *lod[] = {"lod", v1, v2, "--levels", "2", "--quiet", NULL};
    char *lod_none[] = {"lod", v1, none, "--levels", "2", "--no-thumbnail", "--quiet", NULL};
    cr_assert_eq(cmd_lod(6, lod), 0);
    cr_assert_eq(cmd_lod(7, lod_none), 0);
    btf_package *p = fx_package(v2, NULL, 0);
    int w = 0, h = 0;
    uint8_t *px = read_thumbnail(v2, &w, &h);
    cr_expect(w == 16 && h == 16, "%dx%d", w, h);
    expect_head_on(p, px, w, h, "btf lod");
    snprintf(path, sizeof path, "%s/thumbnail.png", none);
    cr_expect_eq(btf_fs_size(path), -1, "btf lod --no-thumbnail wrote %s", path);
    free(px);
    btf_package_free(p);
}
