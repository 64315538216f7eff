/* test_views.c - room codec, suite "views": view sources (codec/include/btf_views.h): a streamed compression writes the
 * same package, byte for byte, as the in-memory one; sources with problems
 * (images of another size, clipped highlights, missing images) are named. */
#include <criterion/criterion.h>
#include <dirent.h>
#include <math.h>
#include <string.h>

#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_image.h"
#include "btf_package.h"
#include "btf_views.h"
#include "fixtures.h"
#include "btf_input.h"
#include "btf_lossy.h"
#include "btf_lod.h"
#include "btf_lod_error.h"

/* Every file of package a equals the same file of package b (and b has no other). */
static void expect_same_package(const char *a, const char *b, const char *what)
{
    DIR *d = opendir(a);
    cr_assert_not_null(d, "%s", a);
    struct dirent *e;
    int n = 0;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        char pa[512], pb[512], *x = NULL, *y = NULL;
        size_t nx = 0, ny = 0;
        snprintf(pa, sizeof pa, "%s/%s", a, e->d_name);
        snprintf(pb, sizeof pb, "%s/%s", b, e->d_name);
        cr_assert_eq(btf_fs_read(pa, 1 << 26, &x, &nx, NULL), BTF_OK, "%s", pa);
        cr_expect_eq(btf_fs_read(pb, 1 << 26, &y, &ny, NULL), BTF_OK, "%s: %s missing", what, pb);
        cr_expect(y && nx == ny && memcmp(x, y, nx) == 0, "%s: %s differs", what, e->d_name);
        free(x), free(y);
        n++;
    }
    closedir(d);
    d = opendir(b);
    cr_assert_not_null(d, "%s", b);
    while ((e = readdir(d)) != NULL)
        n -= e->d_name[0] != '.';
    closedir(d);
    cr_expect_eq(n, 0, "%s: the packages hold different file counts", what);
}

/* Compresses the loaded BTF and the view source at k = 1, 3 and all views (and one
 * spatial grouping, and row centring) and expects the same packages. */
static void expect_streamed_equal(const btf *loaded, btf_views *s, const char *dir, const char *what)
{
    cr_assert_eq(s->width, loaded->width);
    cr_assert(btf_dirset_equal(&s->views, &loaded->views) && btf_dirset_equal(&s->lights, &loaded->lights));
    int V = loaded->views.n_dirs;
    struct { int k; btf_grouping g; btf_center c; } runs[] = { /* stack table of this call: the settings tried */
        {1, BTF_GROUP_CONSECUTIVE, BTF_CENTER_NONE},
        {3, BTF_GROUP_CONSECUTIVE, BTF_CENTER_NONE},
        {V, BTF_GROUP_CONSECUTIVE, BTF_CENTER_NONE},
        {2, BTF_GROUP_SPATIAL, BTF_CENTER_ROW},
    };
    for (size_t i = 0; i < sizeof runs / sizeof runs[0]; i++) {
        char a[256], b[256], label[128];
        snprintf(a, sizeof a, "%s/mem-%zu", dir, i);
        snprintf(b, sizeof b, "%s/stream-%zu", dir, i);
        snprintf(label, sizeof label, "%s, k %d", what, runs[i].k);
        btf_pca_options po = {0};
        po.k = runs[i].k, po.components = 4, po.grouping = runs[i].g, po.center = runs[i].c;
        btf_package_options ko = {0};
        ko.name = "m"; /* not the directory names */
        btf_error err = {0};
        cr_assert_eq(btf_package_compress(loaded, &po, &ko, a, NULL, &err), BTF_OK, "%s: %s", label, err.msg);
        cr_assert_eq(btf_package_compress_views(s, &po, &ko, b, NULL, &err), BTF_OK, "%s: %s", label, err.msg);
        expect_same_package(a, b, label);
    }
}

/* The dome's first two rings (7 directions), 8x8 knit. */
static btf *small_material(void) { return fx_material(BTF_GEN_KNIT, 8, NULL, 0); }

Test(views, dfmf_streamed_compress_equals_in_memory)
{
    char dir[64], path[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf *m = small_material();
    int ranks[2] = {0, 5}; /* full rank (what btf gen writes) and a truncated one */
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s/m%d.btf", dir, i);
        btf_error err = {0};
        cr_assert_eq(btf_save_dfmf(m, path, ranks[i], &err), BTF_OK, "%s", err.msg);
        btf *loaded = NULL;
        cr_assert_eq(btf_load_dfmf(path, NULL, &loaded, &err), BTF_OK, "%s", err.msg);
        btf_views s;
        cr_assert_eq(btf_views_open(path, NULL, &s, &err), BTF_OK, "%s", err.msg);
        btf *back = NULL;
        cr_assert_eq(btf_views_load(&s, 0, &back, &err), BTF_OK, "%s", err.msg);
        cr_expect_eq(memcmp(back->data, loaded->data, loaded->count * sizeof(float)), 0,
                     "rank %d: view-by-view decoding differs from the loader", ranks[i]);
        expect_streamed_equal(loaded, &s, dir, i ? "DFMF rank 5" : "DFMF full rank");
        btf_views_close(&s);
        btf_free(back), btf_free(loaded);
    }
    btf_free(m);
    fx_rmtree(dir);
}

Test(views, image_directory_streamed_compress_equals_in_memory)
{
    char dir[64], img[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    btf *m = small_material();
    btf_error err = {0};
    cr_assert_eq(btf_save_ubo2003_dir(m, img, "Knit", "png", &err), BTF_OK, "%s", err.msg);
    btf_load_options o = {0};
    o.sampling = &m->views;
    btf *loaded = NULL;
    cr_assert_eq(btf_load_ubo2003_dir(img, &o, &loaded, &err), BTF_OK, "%s", err.msg);
    btf_views s;
    cr_assert_eq(btf_views_open(img, &o, &s, &err), BTF_OK, "%s", err.msg);
    expect_streamed_equal(loaded, &s, dir, "PNG directory");
    cr_expect_eq(s.n_filled, 0);
    btf_views_close(&s);
    /* downsampled on the fly, the same as the loader's box filter */
    o.downsample = 2;
    btf *half = NULL;
    cr_assert_eq(btf_load_ubo2003_dir(img, &o, &half, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_views_open(img, &o, &s, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(s.width, 4);
    expect_streamed_equal(half, &s, dir, "PNG directory, downsample 2");
    btf_views_close(&s);
    btf_free(half), btf_free(loaded), btf_free(m);
    fx_rmtree(dir);
}

/* A missing image, interpolated the same way view by view as by the loader. */
Test(views, fill_missing_streamed_equals_in_memory)
{
    char dir[64], img[128], victim[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    btf *m = small_material();
    btf_error err = {0};
    cr_assert_eq(btf_save_ubo2003_dir(m, img, "Knit", "png", &err), BTF_OK, "%s", err.msg);
    /* light 3 (45 deg, phi 120) x view 2 (45 deg, phi 60): number 3 * 7 + 2 */
    snprintf(victim, sizeof victim, "%s/Knit_00023_tl045_pl120_tv045_pv060.png", img);
    cr_assert_eq(remove(victim), 0, "%s", victim);
    btf_load_options o = {0};
    o.sampling = &m->views;
    btf_views s;
    cr_expect_eq(btf_views_open(img, &o, &s, &err), BTF_ERR_MISSING, "a missing image must be refused");
    cr_expect(strstr(err.msg, "tl045_pl120_tv045_pv060"), "the message names the image: %s", err.msg);
    o.fill_missing = 1;
    btf *loaded = NULL;
    cr_assert_eq(btf_load_ubo2003_dir(img, &o, &loaded, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_views_open(img, &o, &s, &err), BTF_OK, "%s", err.msg);
    expect_streamed_equal(loaded, &s, dir, "PNG directory with a missing image");
    cr_expect_eq(s.n_filled, 1, "one image was interpolated, counted once (%d)", s.n_filled);
    btf_views_close(&s);
    btf_free(loaded), btf_free(m);
    fx_rmtree(dir);
}

/* The generator view by view renders what btf_gen_create stores; written view by
 * view it gives the same image directory. */
Test(views, generator_views_equal_the_whole_material)
{
    char dir[64], a[128], b[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf *m = small_material();
    btf_gen_params p = btf_gen_defaults(BTF_GEN_KNIT);
    btf_views s;
    btf_error err = {0};
    cr_assert_eq(btf_gen_views_open(&p, 8, 8, &m->lights, &m->views, &s, &err), BTF_OK, "%s", err.msg);
    btf *back = NULL;
    cr_assert_eq(btf_views_load(&s, 1, &back, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(memcmp(back->data, m->data, m->count), 0, "view-by-view rendering differs");
    expect_streamed_equal(m, &s, dir, "generator");
    snprintf(a, sizeof a, "%s/whole", dir);
    snprintf(b, sizeof b, "%s/views", dir);
    cr_assert_eq(btf_save_ubo2003_dir(m, a, "Knit", "png", &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_views_save_ubo2003(&s, b, "Knit", "png", &err), BTF_OK, "%s", err.msg);
    expect_same_package(a, b, "image directory written view by view");
    btf_views_close(&s);
    btf_free(back), btf_free(m);
    fx_rmtree(dir);
}

/* The command: btf gen writes a dome directory view by view, btf compress reads it
 * view by view, and the package equals the in-memory compression of the loaded images. */
Test(views, commands_stream_and_match_the_library)
{
    char dir[64], img[128], pkg[128], ref[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    snprintf(pkg, sizeof pkg, "%s/pkg", dir);
    snprintf(ref, sizeof ref, "%s/ref", dir);
    char *gen[] = {"gen", "stone", img, "--size", "4", "--sampling", "dome151", NULL};
    cr_assert_eq(cmd_gen(7, gen), 0);
    char *comp[] = {"compress", img, pkg, "--k", "3", "--components", "4", "--quiet", NULL};
    cr_assert_eq(cmd_compress(8, comp), 0);
    btf *loaded = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_load_ubo2003_dir(img, NULL, &loaded, &err), BTF_OK, "%s", err.msg);
    btf_gen_params p = btf_gen_defaults(BTF_GEN_STONE);
    btf *m = NULL;
    btf_dirset d = btf_dirset_dome151();
    cr_assert_eq(btf_gen_create(&p, 4, 4, &d, &d, BTF_U8, &m, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(memcmp(m->data, loaded->data, m->count), 0, "btf gen wrote other samples than it generates");
    btf_pca_options po = {0};
    po.k = 3, po.components = 4;
    btf_package_options ko = {0};
    ko.name = "pkg", ko.thumbnail = BTF_PACKAGE_THUMBNAIL_SIDE, ko.rd = 1; /* as btf compress writes it: */
    ko.lossy = BTF_LOSSY_WEBP;                                               /* lossy where it wins */
    cr_assert_eq(btf_package_compress(loaded, &po, &ko, ref, NULL, &err), BTF_OK, "%s", err.msg);
    expect_same_package(ref, pkg, "btf compress of a dome directory");
    btf_free(loaded), btf_free(m);
    fx_rmtree(dir);
}

/* Writes the small material's images, then replaces image `victim` (file number)
 * by w x h pixels of value `value` (w, h <= 8). */
static void write_with_victim(const char *img, const btf *m, int victim, int w, int h, int value, char *path,
                              size_t n)
{
    btf_error err = {0};
    cr_assert_eq(btf_save_ubo2003_dir(m, img, "Knit", "png", &err), BTF_OK, "%s", err.msg);
    DIR *d = opendir(img);
    struct dirent *e;
    char tag[16];
    snprintf(tag, sizeof tag, "_%05d_", victim);
    path[0] = 0;
    while ((e = readdir(d)) != NULL)
        if (strstr(e->d_name, tag))
            snprintf(path, n, "%s/%s", img, e->d_name);
    closedir(d);
    cr_assert(path[0], "no image numbered %d", victim);
    uint8_t px[8 * 8 * 3];
    memset(px, value, sizeof px);
    cr_assert_eq(btf_image_write(path, w, h, 3, 8, px, &err), BTF_OK, "%s", err.msg);
}

/* One image a pixel narrower: refused by both readers, naming that file, before any work. */
Test(views, image_a_pixel_smaller_is_named)
{
    char dir[64], img[128], bad[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    btf *m = small_material();
    write_with_victim(img, m, 40, 7, 8, 100, bad, sizeof bad);
    btf_load_options o = {0};
    o.sampling = &m->views;
    btf_error err = {0};
    btf *b = NULL;
    cr_expect_eq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_ERR_FORMAT);
    cr_expect(strstr(err.msg, bad) && strstr(err.msg, "7x8") && strstr(err.msg, "expected 8x8"), "%s", err.msg);
    btf_views s;
    memset(&err, 0, sizeof err);
    cr_expect_eq(btf_views_open(img, &o, &s, &err), BTF_ERR_FORMAT, "the view source checks every header on open");
    cr_expect(strstr(err.msg, bad) && strstr(err.msg, "7x8"), "%s", err.msg);
    char pkg[128], set[128];
    snprintf(pkg, sizeof pkg, "%s/pkg", dir);
    snprintf(set, sizeof set, "%s/set.json", dir);
    fx_write_text(set, "{\"rings\": [{\"theta\": 0, \"count\": 1, \"phi_offset\": 0},"
                       " {\"theta\": 45, \"count\": 6, \"phi_offset\": 0}]}");
    char *comp[] = {"compress", img, pkg, "--sampling", set, "--quiet", NULL};
    cr_expect_eq(cmd_compress(6, comp), 1);
    struct stat st;
    cr_expect_neq(stat(pkg, &st), 0, "nothing written");
    btf_free(m);
    fx_rmtree(dir);
}

/* Clipped highlights: counted (with the worst file) by both readers; images with a
 * few 255s are not reported as clipped. */
Test(views, saturated_images_are_counted_and_named)
{
    char dir[64], img[128], bad[512];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(img, sizeof img, "%s/img", dir);
    btf *m = small_material();
    write_with_victim(img, m, 12, 8, 8, 255, bad, sizeof bad);
    long long base = 0; /* 255s the material itself has */
    for (size_t i = 0; i < m->count; i++)
        base += ((const uint8_t *)m->data)[i] == 255;
    btf_load_options o = {0};
    btf_load_report rep;
    memset(&rep, 0, sizeof rep);
    o.sampling = &m->views, o.report = &rep;
    btf_error err = {0};
    btf *b = NULL;
    cr_assert_eq(btf_load_ubo2003_dir(img, &o, &b, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(rep.n_samples, (long long)m->count);
    cr_expect_geq(rep.n_saturated, 192, "the all-255 image alone has 192 samples at 255 (%lld)", rep.n_saturated);
    cr_expect_leq(rep.n_saturated, 192 + base);
    cr_expect_geq(rep.n_images_clipped, 1);
    cr_expect_str_eq(rep.worst_file, bad);
    cr_expect_eq(rep.worst_saturated, 192);
    btf_views s;
    cr_assert_eq(btf_views_open(img, &o, &s, &err), BTF_OK, "%s", err.msg);
    char pkg[128];
    snprintf(pkg, sizeof pkg, "%s/pkg", dir);
    btf_pca_options po = {0};
    cr_assert_eq(btf_package_compress_views(&s, &po, NULL, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(s.report.n_saturated, rep.n_saturated, "the view source counts what the loader counts");
    cr_expect_eq(s.report.n_images_clipped, rep.n_images_clipped);
    cr_expect_str_eq(s.report.worst_file, bad);
    btf_views_close(&s);
    btf_free(b), btf_free(m);
    fx_rmtree(dir);
}

/* A view source that counts its fills (over a wrapped BTF). Lives on the test's stack. */
typedef struct counted_views {
    btf_views inner; /* btf_views_wrap of the material */
    int fills;
} counted_views;

static btf_result counted_fill(btf_views *s, int view, float *cols, btf_error *err)
{
    counted_views *c = s->impl;
    c->fills++;
    return btf_views_fill(&c->inner, view, cols, err);
}

static void counted_open(const btf *m, counted_views *c, btf_views *out)
{
    memset(c, 0, sizeof *c);
    btf_views_wrap(m, &c->inner);
    btf_views_over(&c->inner, counted_fill, c, out);
}

/* With levels matched to level 0's error (doc/package-format.md section 10.7) a view
 * source is read as often as without levels: the level references are gathered during
 * the compression's own pass (btf_lod_error.h), not by a pass of their own; and the
 * package equals the in-memory one, whose references come from that separate pass. */
Test(views, levels_gather_their_references_in_the_compressions_pass)
{
    char dir[256], a[300], b[300], c[300];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(a, sizeof a, "%s/plain", dir), snprintf(b, sizeof b, "%s/views", dir), snprintf(c, sizeof c, "%s/mem", dir);
    static const btf_ring rings[3] = {{0.0f, 1, 0.0f}, {30.0f, 6, 0.0f}, {60.0f, 8, 10.0f}};
    btf *m = fx_material(BTF_GEN_TILES, 64, rings, 3); /* where lossy textures win (test_rd.c) */
    btf_pca_options po = {0};
    po.k = 3, po.components = 4;
    btf_package_options ko = {0};
    ko.name = "m", ko.rd = 1, ko.lossy = BTF_LOSSY_WEBP;
    btf_lod_options none = {0}, lo = {0};
    lo.levels = 3;
    btf_error err = {0};
    counted_views cv;
    btf_views s;
    counted_open(m, &cv, &s);
    cr_assert_eq(btf_lod_compress_views(&s, &po, &ko, &none, a, NULL, &err), BTF_OK, "%s", err.msg);
    int without = cv.fills;
    counted_open(m, &cv, &s);
    cr_assert_eq(btf_lod_compress_views(&s, &po, &ko, &lo, b, NULL, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(cv.fills, without, "levels read the source %d times, the compression alone %d", cv.fills, without);
    cr_expect_geq(without, m->views.n_dirs);
    cr_assert_eq(btf_lod_compress(m, &po, &ko, &lo, c, NULL, &err), BTF_OK, "%s", err.msg);
    expect_same_package(b, c, "levels, streamed and in memory");
    btf_package *p = fx_package(b, NULL, 0);
    int lossy = 0;
    for (int i = 0; i < p->n_chunks; i++) { /* the matching ran: some coarse file is lossy */
        char path[600], *f = NULL;
        size_t n = 0;
        snprintf(path, sizeof path, "%s/%s", b, p->chunk[i].files[0]);
        cr_assert_eq(btf_fs_read(path, 1 << 26, &f, &n, NULL), BTF_OK, "%s", path);
        lossy += p->chunk[i].level > 0 && btf_lossy_codec_of((const uint8_t *)f, n) != BTF_LOSSY_NONE;
        free(f);
    }
    cr_expect_gt(lossy, 0, "no coarse level is lossy: nothing was matched");
    btf_package_free(p);
    btf_free(m);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* The sRGB transfer written out here (IEC 61966-2-1), apart from btf_color's. */
static double srgb_to_linear(double v) { return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4); }
static double linear_to_srgb(double v) { return v <= 0.0031308 ? v * 12.92 : 1.055 * pow(v, 1.0 / 2.4) - 0.055; }

/* A linear package's level references (btf_lod_error.h) are the source's means in
 * linear light, encoded back to sRGB: the probe, which decodes each view in place,
 * and the gathering, which decodes a copy and leaves the caller's view as it was,
 * give the same references, and both the means this test computes itself. */
Test(views, linear_level_references_are_means_in_linear_light)
{
    btf *m = small_material();
    btf_views s;
    btf_views_wrap(m, &s);
    btf_package pkg = {0}; /* what the probe reads of a package: size, directions, linear */
    pkg.width = m->width, pkg.height = m->height, pkg.lights = m->lights, pkg.views = m->views, pkg.linear = 1;
    btf_error err = {0};
    btf_lod_probe pr[2];
    cr_assert_eq(btf_lod_probe_make(&s, &pkg, 2, 16, pr, &err), BTF_OK, "%s", err.msg);
    btf_lod_gather g;
    cr_assert_eq(btf_lod_gather_begin(&s, 1, 2, 16, &g, &err), BTF_OK, "%s", err.msg);
    size_t nf = btf_views_floats(&s), texels = (size_t)m->width * m->height;
    int V = m->views.n_dirs, L = m->lights.n_dirs;
    float *cols = malloc(nf * sizeof(float)), *copy = malloc(nf * sizeof(float));
    cr_assert(cols && copy);
    double worst = 0.0;
    for (int v = 0; v < V; v++) {
        cr_assert_eq(btf_views_fill(&s, v, cols, &err), BTF_OK, "%s", err.msg);
        memcpy(copy, cols, nf * sizeof(float));
        cr_assert_eq(btf_lod_gather_add(&g, v, cols, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(memcmp(copy, cols, nf * sizeof(float)), 0, "view %d: the gathering changed the caller's view", v);
        for (int l = 0; l < 2; l++)
            for (int i = 0; i < pr[l].n; i++)
                for (int k = 0; k < L * 3; k++) {
                    int f = 1 << l, x0 = pr[l].xy[2 * i] * f, y0 = pr[l].xy[2 * i + 1] * f;
                    double sum = 0.0;
                    for (int dy = 0; dy < f; dy++)
                        for (int dx = 0; dx < f; dx++)
                            sum += srgb_to_linear(cols[(size_t)k * texels + (size_t)(y0 + dy) * m->width + x0 + dx]);
                    double want = linear_to_srgb(sum / (f * f));
                    float got = pr[l].ref[((size_t)i * V + v) * L * 3 + k];
                    worst = fmax(worst, fabs(got - want));
                }
    }
    cr_assert(btf_lod_gather_done(&g));
    /* float sums of at most 4 samples and the float transfer functions: a few ulps */
    cr_log_info("largest difference from the means in linear light: %g", worst);
    cr_expect_lt(worst, 2e-6, "references %g from the means in linear light", worst);
    for (int l = 0; l < 2; l++) {
        cr_assert_eq(pr[l].n, g.pr[l].n);
        size_t n = (size_t)pr[l].n * V * L * 3;
        cr_expect_eq(memcmp(pr[l].ref, g.pr[l].ref, n * sizeof(float)), 0, "level %d: probe and gathering differ", l);
        cr_expect_eq(memcmp(pr[l].ref_lab, g.pr[l].ref_lab, n * sizeof(float)), 0, "level %d: CIELab differs", l);
    }
    free(cols), free(copy);
    btf_lod_gather_free(&g);
    btf_lod_probe_free(pr, 2);
    btf_views_close(&s);
    btf_free(m);
}
