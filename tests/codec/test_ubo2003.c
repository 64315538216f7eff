/* test_ubo2003.c - room codec, suites "ubo2003" and "slow_ubo2003": UBO2003 image
 * directories (codec/input/btf_ubo2003.c): writer, loader (both layouts), downsampling,
 * bad inputs, and btf_load_any's dispatch. */
#include <criterion/criterion.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_image.h"
#include "btf_io.h"
#include "fixtures.h"
#include "btf_input.h"

/* 1 + 6 directions: the pole and a ring at 30 deg (phi 0, 60, ..., 300): 49 images. */
static btf_dirset small_set(void)
{
    return FX_RINGS({0, 1, 0}, {30, 6, 0});
}

/* Byte pattern that differs in every index, independent of the code under test. */
static uint8_t pattern(int v, int l, int x, int y, int c)
{
    return (uint8_t)((v * 37 + l * 11 + x * 5 + y * 13 + c * 71 + (x * y) % 7) & 255);
}

/* Smooth pattern (JPEG-friendly): slow gradients, distinct per image. */
static uint8_t smooth(int v, int l, int x, int y, int c)
{
    return (uint8_t)(40 + v * 9 + l * 5 + x * 3 + y * 2 + c * 20);
}

static btf *make_btf(int w, int h, const btf_dirset *d, uint8_t (*f)(int, int, int, int, int))
{
    btf *b = NULL;
    cr_assert_eq(btf_create(w, h, d, d, BTF_U8, &b, NULL), BTF_OK);
    uint8_t *p = b->data;
    for (int v = 0; v < d->n_dirs; v++)
        for (int l = 0; l < d->n_dirs; l++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    for (int c = 0; c < 3; c++)
                        p[btf_index(b, v, l, x, y, c)] = f(v, l, x, y, c);
    return b;
}

/* Saves the small 8x8 pattern into a fresh temp dir. */
static void save_small(char *dir, size_t n, const char *ext, btf **src)
{
    btf_dirset d = small_set();
    cr_assert(fx_tmpdir(dir, n));
    *src = make_btf(8, 8, &d, strcmp(ext, "png") ? smooth : pattern);
    btf_error e = {{0}};
    cr_assert_eq(btf_save_ubo2003_dir(*src, dir, "Mat", ext, &e), BTF_OK, "%s", e.msg);
}

static btf_result load_small(const char *dir, int downsample, btf_storage st, btf **out, btf_error *e)
{
    btf_dirset d = small_set();
    btf_load_options o = {0};
    o.sampling = &d;
    o.downsample = downsample;
    o.storage = st;
    return btf_load_ubo2003_dir(dir, &o, out, e);
}

/* Path of the file the writer names for (light, view) of the small set. */
static void small_name(char *buf, size_t n, const char *dir, int light, int view, const char *ext)
{
    btf_dirset d = small_set();
    float tl, pl, tv, pv;
    btf_dirset_angles(&d, light, &tl, &pl);
    btf_dirset_angles(&d, view, &tv, &pv);
    snprintf(buf, n, "%s/Mat_%05d_tl%03d_pl%03d_tv%03d_pv%03d.%s", dir, light * d.n_dirs + view, (int)tl, (int)pl,
             (int)tv, (int)pv, ext);
}

static void expect_error(const char *dir, btf_result want, const char *needle)
{
    btf *m = (btf *)1;
    btf_error e = {{0}};
    btf_result r = load_small(dir, 0, 0, &m, &e);
    cr_expect_eq(r, want, "got %s: %s", btf_result_string(r), e.msg);
    cr_expect_null(m);
    cr_expect(strstr(e.msg, needle) != NULL, "message \"%s\" does not name \"%s\"", e.msg, needle);
}

Test(ubo2003, png_round_trip_is_exact)
{
    char dir[64];
    btf *src, *m = NULL;
    save_small(dir, sizeof dir, "png", &src);
    btf_error e = {{0}};
    cr_assert_eq(load_small(dir, 0, 0, &m, &e), BTF_OK, "%s", e.msg);
    cr_expect_eq(m->width, 8);
    cr_expect_eq(m->height, 8);
    cr_expect_eq(m->storage, BTF_U8);
    cr_expect(btf_dirset_equal(&m->lights, &src->lights) && btf_dirset_equal(&m->views, &src->views));
    cr_assert_eq(m->count, src->count);
    cr_expect_eq(memcmp(m->data, src->data, src->count), 0);
    btf_free(m);
    /* float storage: byte / 255 */
    cr_assert_eq(load_small(dir, 0, BTF_F32, &m, &e), BTF_OK, "%s", e.msg);
    cr_expect_eq(m->storage, BTF_F32);
    for (int v = 0; v < 7; v += 3)
        for (int l = 0; l < 7; l += 2)
            cr_expect_float_eq(((float *)m->data)[btf_index(m, v, l, 3, 5, 1)], pattern(v, l, 3, 5, 1) / 255.0f,
                               1e-7);
    btf_free(m);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, file_names_follow_the_spec)
{
    char dir[64], path[256];
    btf *src;
    save_small(dir, sizeof dir, "png", &src);
    /* light 3 = (30, 120), view 1 = (30, 0): running number light*7+view = 22 */
    snprintf(path, sizeof path, "%s/Mat_00022_tl030_pl120_tv030_pv000.png", dir);
    cr_expect_eq(access(path, R_OK), 0, "%s absent", path);
    snprintf(path, sizeof path, "%s/Mat_00000_tl000_pl000_tv000_pv000.png", dir);
    cr_expect_eq(access(path, R_OK), 0, "%s absent", path);
    int n = 0;
    DIR *d = opendir(dir);
    for (struct dirent *e; (e = readdir(d));)
        n += e->d_name[0] != '.';
    closedir(d);
    cr_expect_eq(n, 49, "no stray temporary files");
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, jpeg_round_trip_within_codec_loss)
{
    char dir[64], path[256];
    btf *src, *m = NULL;
    save_small(dir, sizeof dir, "jpg", &src);
    btf_error e = {{0}};
    cr_assert_eq(load_small(dir, 0, 0, &m, &e), BTF_OK, "%s", e.msg);
    /* the loader must reproduce exactly what an independent decode of each file gives */
    for (int v = 0; v < 7; v++)
        for (int l = 0; l < 7; l++) {
            small_name(path, sizeof path, dir, l, v, "jpg");
            uint8_t *px;
            int w, h, ch;
            cr_assert_eq(btf_image_read_u8(path, &w, &h, &ch, &px, &e), BTF_OK, "%s", e.msg);
            cr_assert_eq(ch, 3);
            cr_expect_eq(memcmp(px, (uint8_t *)m->data + btf_index(m, v, l, 0, 0, 0), 8 * 8 * 3), 0, "%s", path);
            free(px);
        }
    /* JPEG is lossy. OpenImageIO writes quality 98 (quantiser steps of 1-2 levels) and
     * the pattern is a smooth linear ramp (2-3 levels per texel, which DCT blocks and
     * chroma subsampling represent almost exactly): measured here mean 0.67, max 1 level.
     * Bound: mean below 1 level, none beyond 3. A broken loader (wrong image order,
     * swapped channels or rows) is off by 2..40 levels almost everywhere. */
    double sum = 0;
    int worst = 0;
    const uint8_t *a = src->data, *b = m->data;
    for (size_t i = 0; i < src->count; i++) {
        int d = abs((int)a[i] - (int)b[i]);
        sum += d;
        worst = d > worst ? d : worst;
    }
    cr_expect_lt(sum / (double)src->count, 1.0);
    cr_expect_leq(worst, 3);
    btf_free(m);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, folder_layout_with_spaces)
{
    char dir[64], from[256], to[256], sub[128];
    btf *src, *m = NULL;
    save_small(dir, sizeof dir, "png", &src);
    btf_dirset d = small_set();
    for (int v = 0; v < 7; v++)
        for (int l = 0; l < 7; l++) {
            float tl, pl, tv, pv;
            btf_dirset_angles(&d, l, &tl, &pl);
            btf_dirset_angles(&d, v, &tv, &pv);
            snprintf(sub, sizeof sub, "%s/tv%03d_pv%03d", dir, (int)tv, (int)pv);
            mkdir(sub, 0777);
            small_name(from, sizeof from, dir, l, v, "png");
            snprintf(to, sizeof to, "%s/%05d tl%03d pl%03d tv%03d pv%03d.png", sub, l * 7 + v, (int)tl, (int)pl,
                     (int)tv, (int)pv);
            cr_assert_eq(rename(from, to), 0);
        }
    btf_error e = {{0}};
    cr_assert_eq(load_small(dir, 0, 0, &m, &e), BTF_OK, "%s", e.msg);
    cr_expect_eq(memcmp(m->data, src->data, src->count), 0);
    btf_free(m);
    /* a file whose view angles contradict its folder is refused */
    snprintf(from, sizeof from, "%s/tv030_pv060/00030 tl030 pl180 tv030 pv060.png", dir);
    snprintf(to, sizeof to, "%s/tv030_pv060/00030 tl030 pl180 tv030 pv120.png", dir);
    cr_assert_eq(rename(from, to), 0);
    expect_error(dir, BTF_ERR_FORMAT, "tv030 pv120.png");
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

/* Exact box mean of the source pattern, rounded half up: an independent reference. */
static int box_mean_x2(const btf *src, int v, int l, int x, int y, int c, int f)
{
    int s = 0;
    for (int dy = 0; dy < f; dy++)
        for (int dx = 0; dx < f; dx++)
            s += ((const uint8_t *)src->data)[btf_index(src, v, l, x * f + dx, y * f + dy, c)];
    return s * 2 / f / f; /* twice the mean, floored: odd means a .5 tie */
}

Test(ubo2003, downsample_on_load_equals_btf_downsample)
{
    char dir[64];
    btf *src, *full = NULL, *ref = NULL, *m = NULL;
    save_small(dir, sizeof dir, "png", &src);
    btf_error e = {{0}};
    cr_assert_eq(load_small(dir, 0, 0, &full, &e), BTF_OK, "%s", e.msg);
    for (int f = 2; f <= 4; f += 2) {
        cr_assert_eq(load_small(dir, f, 0, &m, &e), BTF_OK, "%s", e.msg);
        cr_assert_eq(btf_downsample(full, f, &ref, &e), BTF_OK, "%s", e.msg);
        cr_assert_eq(m->width, 8 / f);
        cr_assert_eq(m->count, ref->count);
        /* btf_downsample averages byte/255 floats and rounds: it may round an exact .5
         * tie either way by float error; everywhere else the two must agree exactly. */
        const uint8_t *a = m->data, *b = ref->data;
        for (int v = 0; v < 7; v++)
            for (int l = 0; l < 7; l++)
                for (int y = 0; y < m->height; y++)
                    for (int x = 0; x < m->width; x++)
                        for (int c = 0; c < 3; c++) {
                            size_t i = btf_index(m, v, l, x, y, c);
                            int m2 = box_mean_x2(src, v, l, x, y, c, f);
                            cr_assert_eq(a[i], (m2 + 1) / 2, "round half up of the exact mean");
                            if (m2 % 2 == 0)
                                cr_assert_eq(a[i], b[i], "f %d v %d l %d x %d y %d c %d", f, v, l, x, y, c);
                            else
                                cr_assert_leq(abs((int)a[i] - (int)b[i]), 1);
                        }
        btf_free(m);
        btf_free(ref);
        /* float storage: same means without rounding (float sums of at most 16 terms) */
        cr_assert_eq(load_small(dir, f, BTF_F32, &m, &e), BTF_OK, "%s", e.msg);
        cr_assert_eq(btf_downsample(full, f, &ref, &e), BTF_OK, "%s", e.msg);
        for (int v = 0; v < 7; v += 2)
            for (int l = 0; l < 7; l++)
                for (int c = 0; c < 3; c++)
                    cr_expect_float_eq(btf_get(m, v, l, 1, 1, c), box_mean_x2(src, v, l, 1, 1, c, f) / 2.0f / 255.0f,
                                       0.5f / 255.0f + 1e-6f);
        btf_free(m);
        btf_free(ref);
    }
    /* width/height option reaches the same factor */
    btf_dirset d = small_set();
    btf_load_options o = {0};
    o.sampling = &d;
    o.width = 4;
    o.height = 4;
    cr_assert_eq(btf_load_ubo2003_dir(dir, &o, &m, &e), BTF_OK, "%s", e.msg);
    cr_expect_eq(m->width, 4);
    btf_free(m);
    o.width = 3;
    cr_expect_eq(btf_load_ubo2003_dir(dir, &o, &m, &e), BTF_ERR_UNSUPPORTED);
    cr_expect_eq(load_small(dir, 3, 0, &m, &e), BTF_ERR_ARG, "8x8 is not divisible by 3");
    cr_expect(strstr(e.msg, "divisible") != NULL, "%s", e.msg);
    btf_free(full);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, grey_and_rgba_images)
{
    char dir[64], path[256];
    btf *src, *m = NULL;
    save_small(dir, sizeof dir, "png", &src);
    uint8_t grey[8 * 8], rgba[8 * 8 * 4];
    for (int i = 0; i < 64; i++) {
        grey[i] = (uint8_t)(i * 3);
        for (int c = 0; c < 4; c++)
            rgba[i * 4 + c] = (uint8_t)(c == 3 ? 10 : i + 50 * c); /* alpha far from 255 */
    }
    btf_error e = {{0}};
    small_name(path, sizeof path, dir, 2, 1, "png");
    cr_assert_eq(btf_image_write(path, 8, 8, 1, 8, grey, &e), BTF_OK, "%s", e.msg);
    small_name(path, sizeof path, dir, 5, 6, "png");
    cr_assert_eq(btf_image_write(path, 8, 8, 4, 8, rgba, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(load_small(dir, 0, 0, &m, &e), BTF_OK, "%s", e.msg);
    const uint8_t *p = m->data;
    for (int i = 0; i < 64; i++)
        for (int c = 0; c < 3; c++) {
            cr_expect_eq(p[btf_index(m, 1, 2, i % 8, i / 8, c)], grey[i]);
            cr_expect_eq(p[btf_index(m, 6, 5, i % 8, i / 8, c)], rgba[i * 4 + c], "alpha must not scale RGB");
        }
    cr_expect_eq(p[btf_index(m, 0, 0, 1, 1, 0)], pattern(0, 0, 1, 1, 0), "other images untouched");
    btf_free(m);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, missing_image_names_the_pair)
{
    char dir[64], path[256];
    btf *src;
    save_small(dir, sizeof dir, "png", &src);
    small_name(path, sizeof path, dir, 4, 2, "png"); /* light (30,180), view (30,60) */
    cr_assert_eq(unlink(path), 0);
    expect_error(dir, BTF_ERR_MISSING, "light 4 x view 2");
    expect_error(dir, BTF_ERR_MISSING, "tl030_pl180_tv030_pv060");
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, wrong_size_names_the_file)
{
    char dir[64], path[256];
    btf *src;
    save_small(dir, sizeof dir, "png", &src);
    uint8_t px[4 * 8 * 3] = {0};
    small_name(path, sizeof path, dir, 6, 3, "png");
    cr_assert_eq(btf_image_write(path, 4, 8, 3, 8, px, NULL), BTF_OK);
    expect_error(dir, BTF_ERR_FORMAT, path);
    expect_error(dir, BTF_ERR_FORMAT, "4x8");
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, corrupt_and_truncated_files_name_the_file)
{
    char dir[64], path[256];
    btf *src;
    save_small(dir, sizeof dir, "png", &src);
    small_name(path, sizeof path, dir, 1, 5, "png");
    fx_write(path, "not an image at all", 19);
    btf *m = (btf *)1;
    btf_error e = {{0}};
    cr_expect_neq(load_small(dir, 0, 0, &m, &e), BTF_OK);
    cr_expect_null(m);
    cr_expect(strstr(e.msg, path) != NULL, "%s", e.msg);
    /* a PNG cut in half: header fine, pixel data short */
    char good[256];
    small_name(good, sizeof good, dir, 2, 5, "png");
    FILE *f = fopen(good, "rb");
    cr_assert(f);
    uint8_t buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    cr_assert_gt(n, 60);
    fx_write(path, buf, n / 2);
    e.msg[0] = 0;
    cr_expect_neq(load_small(dir, 0, 0, &m, &e), BTF_OK);
    cr_expect(strstr(e.msg, path) != NULL, "%s", e.msg);
    /* the first image (whose header sets the size) corrupt as well */
    small_name(path, sizeof path, dir, 0, 0, "png");
    fx_write(path, "", 0);
    e.msg[0] = 0;
    cr_expect_neq(load_small(dir, 0, 0, &m, &e), BTF_OK);
    cr_expect(strstr(e.msg, path) != NULL, "%s", e.msg);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, duplicate_and_foreign_angles_name_the_file)
{
    char dir[64], path[256], dup[256];
    btf *src;
    save_small(dir, sizeof dir, "png", &src);
    uint8_t px[8 * 8 * 3] = {0};
    /* same angles as Mat_00015 (light 2, view 1) under another prefix and number */
    snprintf(dup, sizeof dup, "%s/Other_99999_tl030_pl060_tv030_pv000.png", dir);
    cr_assert_eq(btf_image_write(dup, 8, 8, 3, 8, px, NULL), BTF_OK);
    expect_error(dir, BTF_ERR_FORMAT, "duplicate");
    expect_error(dir, BTF_ERR_FORMAT, "_tl030_pl060_tv030_pv000.png");
    cr_assert_eq(unlink(dup), 0);
    /* theta 10 is not in the sampling (nor within 0.5 deg of it) */
    snprintf(path, sizeof path, "%s/Mat_00000_tl010_pl000_tv000_pv000.png", dir);
    cr_assert_eq(btf_image_write(path, 8, 8, 3, 8, px, NULL), BTF_OK);
    expect_error(dir, BTF_ERR_RANGE, path);
    cr_assert_eq(unlink(path), 0);
    /* phi 45 on the 30 deg ring (step 60) */
    snprintf(path, sizeof path, "%s/Mat_00000_tl000_pl000_tv030_pv045.png", dir);
    cr_assert_eq(btf_image_write(path, 8, 8, 3, 8, px, NULL), BTF_OK);
    expect_error(dir, BTF_ERR_RANGE, path);
    cr_assert_eq(unlink(path), 0);
    /* files without angles (notes, an interrupted writer's temp file) are ignored */
    snprintf(path, sizeof path, "%s/readme.txt", dir);
    fx_write(path, "x", 1);
    snprintf(path, sizeof path, "%s/Mat_00001_tl030_pl000_tv000_pv000.png.tmp-123.png", dir);
    fx_write(path, "garbage", 7);
    btf *m = NULL;
    btf_error e = {{0}};
    cr_expect_eq(load_small(dir, 0, 0, &m, &e), BTF_OK, "%s", e.msg);
    btf_free(m);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, empty_missing_and_non_directories)
{
    char dir[64], path[256];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    expect_error(dir, BTF_ERR_MISSING, dir);
    expect_error(dir, BTF_ERR_MISSING, "no UBO2003 images");
    snprintf(path, sizeof path, "%s/plain.txt", dir);
    fx_write(path, "x", 1);
    expect_error(path, BTF_ERR_ARG, "plain.txt: not a directory");
    snprintf(path, sizeof path, "%s/absent", dir);
    expect_error(path, BTF_ERR_MISSING, path);
    btf_load_options o = {0};
    btf *m = NULL;
    cr_expect_eq(btf_load_ubo2003_dir(dir, NULL, NULL, NULL), BTF_ERR_ARG);
    o.downsample = -2;
    cr_expect_eq(btf_load_ubo2003_dir(dir, &o, &m, NULL), BTF_ERR_ARG);
    o.downsample = 0;
    o.storage = (btf_storage)7;
    cr_expect_eq(btf_load_ubo2003_dir(dir, &o, &m, NULL), BTF_ERR_ARG);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, default_sampling_maps_published_names)
{
    /* one file named as the published UBO2003 files are: its angles lie in the UBO2003 set,
     * so the load fails only because the other 6560 images are absent */
    char dir[64], path[256];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    uint8_t px[2 * 2 * 3] = {0};
    snprintf(path, sizeof path, "%s/WoolPKNT256_00084_tl015_pl000_tv015_pv120.jpg", dir);
    cr_assert_eq(btf_image_write(path, 2, 2, 3, 8, px, NULL), BTF_OK);
    snprintf(path, sizeof path, "%s/tv030_pv030", dir);
    cr_assert_eq(mkdir(path, 0777), 0);
    snprintf(path, sizeof path, "%s/tv030_pv030/00008 tl000 pl000 tv030 pv030.jpg", dir);
    cr_assert_eq(btf_image_write(path, 2, 2, 3, 8, px, NULL), BTF_OK);
    snprintf(path, sizeof path, "%s/x_00000_tl000_pl000_tv000_pv000.png", dir);
    cr_assert_eq(btf_image_write(path, 2, 2, 3, 8, px, NULL), BTF_OK);
    btf *m = NULL;
    btf_error e = {{0}};
    cr_expect_eq(btf_load_ubo2003_dir(dir, NULL, &m, &e), BTF_ERR_MISSING, "%s", e.msg);
    /* pairs in order view * 81 + light: (light 0, view 0) is present, (1, 0) is next */
    cr_expect(strstr(e.msg, "light 1 x view 0 (no file ending in tl015_pl000_tv000_pv000)") != NULL, "%s", e.msg);
    cr_expect(strstr(e.msg, "6558 of 6561") != NULL, "%s", e.msg);
    /* theta 90 is no UBO2003 direction */
    snprintf(path, sizeof path, "%s/y_00000_tl090_pl000_tv000_pv000.jpg", dir);
    cr_assert_eq(btf_image_write(path, 2, 2, 3, 8, px, NULL), BTF_OK);
    cr_expect_eq(btf_load_ubo2003_dir(dir, NULL, &m, &e), BTF_ERR_RANGE, "%s", e.msg);
    cr_expect(strstr(e.msg, path) != NULL, "%s", e.msg);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(slow_ubo2003, default_sampling_full_round_trip)
{
    /* the full UBO2003 set with 2x2 images: 6561 files, named as the writer names them */
    char dir[64];
    btf_dirset d = btf_dirset_ubo2003();
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf *src = make_btf(2, 2, &d, pattern), *m = NULL;
    btf_error e = {{0}};
    cr_assert_eq(btf_save_ubo2003_dir(src, dir, "WoolPKNT256", "png", &e), BTF_OK, "%s", e.msg);
    char path[256];
    /* a published-style name: 84 = light 1 (15, 0) * 81 + view 3 (15, 120) */
    snprintf(path, sizeof path, "%s/WoolPKNT256_00084_tl015_pl000_tv015_pv120.png", dir);
    cr_expect_eq(access(path, R_OK), 0, "%s", path);
    cr_assert_eq(btf_load_ubo2003_dir(dir, NULL, &m, &e), BTF_OK, "%s", e.msg);
    cr_expect_eq(memcmp(m->data, src->data, src->count), 0);
    btf_free(m);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, dome_sampling_round_trips_with_half_degree_angles)
{
    /* the dome's ring at theta 52.5 with phi offset 7.5: names carry whole degrees */
    char dir[64], path[256];
    btf_dirset dome = btf_dirset_dome151();
    btf_ring r[2] = {dome.rings[0], dome.rings[6]}; /* 1 + 18 = 19 dirs */
    btf_dirset set;
    cr_assert_eq(btf_dirset_make(r, 2, &set, NULL), BTF_OK);
    btf *src = NULL, *m = NULL;
    cr_assert_eq(btf_create(1, 1, &set, &set, BTF_F32, &src, NULL), BTF_OK);
    for (size_t i = 0; i < src->count; i++)
        ((float *)src->data)[i] = (float)((i * 7) % 256) / 255.0f;
    cr_assert(fx_tmpdir(dir, sizeof dir));
    btf_error e = {{0}};
    cr_assert_eq(btf_save_ubo2003_dir(src, dir, NULL, ".png", &e), BTF_OK, "%s", e.msg);
    /* light 18 = last of the ring: phi 7.5 + 17*20 = 347.5 -> 348 (half away from zero);
     * view 1 = (52.5, 7.5) -> (53, 8); running number 18*19 + 1 = 343; default prefix "btf" */
    snprintf(path, sizeof path, "%s/btf_00343_tl053_pl348_tv053_pv008.png", dir);
    cr_expect_eq(access(path, R_OK), 0, "%s", path);
    btf_load_options o = {0};
    o.sampling = &set;
    o.storage = BTF_F32;
    cr_assert_eq(btf_load_ubo2003_dir(dir, &o, &m, &e), BTF_OK, "%s", e.msg);
    for (size_t i = 0; i < src->count; i++)
        cr_assert_float_eq(((float *)m->data)[i], ((float *)src->data)[i], 1e-6);
    btf_free(m);
    /* the same files against the UBO2003 sampling: theta 53 is foreign */
    cr_expect_eq(btf_load_ubo2003_dir(dir, NULL, &m, &e), BTF_ERR_RANGE, "%s", e.msg);
    cr_expect(strstr(e.msg, "not in the expected sampling") != NULL, "%s", e.msg);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, writer_refuses_bad_requests)
{
    char dir[64], path[256];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    /* 0.5 deg steps: whole-degree names collide */
    btf_ring r[2] = {{0, 1, 0}, {30, 720, 0}};
    btf_dirset d;
    cr_assert_eq(btf_dirset_make(r, 2, &d, NULL), BTF_OK);
    btf *b = NULL;
    cr_assert_eq(btf_create(1, 1, &d, &d, BTF_U8, &b, NULL), BTF_OK);
    btf_error e = {{0}};
    cr_expect_eq(btf_save_ubo2003_dir(b, dir, "x", "png", &e), BTF_ERR_RANGE);
    cr_expect(strstr(e.msg, "whole-degree") != NULL, "%s", e.msg);
    btf_free(b);
    btf_dirset s = small_set();
    cr_assert_eq(btf_create(2, 2, &s, &s, BTF_U8, &b, NULL), BTF_OK);
    cr_expect_eq(btf_save_ubo2003_dir(b, dir, "x", "bmp", &e), BTF_ERR_ARG);
    cr_expect_eq(btf_save_ubo2003_dir(b, dir, "a/b", "png", &e), BTF_ERR_ARG);
    cr_expect_eq(btf_save_ubo2003_dir(NULL, dir, "x", "png", &e), BTF_ERR_ARG);
    /* the target path is a file */
    snprintf(path, sizeof path, "%s/file", dir);
    fx_write(path, "x", 1);
    cr_expect_eq(btf_save_ubo2003_dir(b, path, "x", "png", &e), BTF_ERR_IO);
    cr_expect(strstr(e.msg, path) != NULL, "%s", e.msg);
    /* nested directories are created */
    snprintf(path, sizeof path, "%s/a/b/c", dir);
    cr_expect_eq(btf_save_ubo2003_dir(b, path, "x", "png", &e), BTF_OK, "%s", e.msg);
    btf *m = NULL;
    cr_expect_eq(load_small(path, 0, 0, &m, &e), BTF_OK, "%s", e.msg);
    btf_free(m);
    btf_free(b);
    cr_expect_eq(fx_rmtree(dir), 0);
}

Test(ubo2003, load_any_dispatches_by_content)
{
    char dir[64], path[256];
    btf *src, *m = NULL;
    save_small(dir, sizeof dir, "png", &src);
    btf_dirset d = small_set();
    btf_load_options o = {0};
    o.sampling = &d;
    btf_error e = {{0}};
    cr_assert_eq(btf_load_any(dir, &o, &m, &e), BTF_OK, "%s", e.msg);
    cr_expect_eq(memcmp(m->data, src->data, src->count), 0);
    btf_free(m);
    /* a package directory is refused for now */
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    fx_write(path, "{}", 2);
    cr_expect_eq(btf_load_any(dir, &o, &m, &e), BTF_ERR_UNSUPPORTED);
    cr_expect(strstr(e.msg, "package: use the package API") != NULL, "%s", e.msg);
    /* meta.json takes precedence and goes to the thesis importer: same answer as calling it */
    snprintf(path, sizeof path, "%s/meta.json", dir);
    fx_write(path, "{}", 2);
    btf_error e2 = {{0}};
    btf *m2 = NULL;
    btf_result want = btf_import_thesis(dir, &o, &m2, &e2);
    cr_expect_eq(btf_load_any(dir, &o, &m, &e), want);
    cr_expect_str_eq(e.msg, e2.msg);
    btf_free(m);
    btf_free(m2);
    /* a .btf file goes to the DFMF reader */
    snprintf(path, sizeof path, "%s/bad.btf", dir);
    fx_write(path, "!XYZ", 4);
    want = btf_load_dfmf(path, &o, &m2, &e2);
    cr_expect_neq(want, BTF_OK);
    cr_expect_eq(btf_load_any(path, &o, &m, &e), want);
    cr_expect_str_eq(e.msg, e2.msg);
    /* other files and absent paths */
    snprintf(path, sizeof path, "%s/x.dat", dir);
    fx_write(path, "x", 1);
    cr_expect_eq(btf_load_any(path, &o, &m, &e), BTF_ERR_UNSUPPORTED);
    snprintf(path, sizeof path, "%s/absent", dir);
    cr_expect_eq(btf_load_any(path, &o, &m, &e), BTF_ERR_MISSING);
    cr_expect(strstr(e.msg, path) != NULL, "%s", e.msg);
    cr_expect_null(m);
    btf_free(src);
    cr_expect_eq(fx_rmtree(dir), 0);
}
