/* test_lap.c - room codec, suite "lap": package version 4, spatial levels stored as
 * residuals over the next coarser level (a Laplacian-style pyramid,
 * doc/package-format.md sections 4.3 and 4.4; codec/format/btf_lap.h). Checked
 * against independent computations: the residual transform against a direct
 * implementation of the section's formulas written here; the version-4 package
 * against the version-2 package built from the same version-1 package (its levels
 * are the same bytes, so every chunk's texels and weights must be equal, and so
 * every prefix decode); a coarse prefix copied alone; hostile files; `btf compress
 * --residual`'s options. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "btf_gen.h"
#include "btf_lap.h"
#include "btf_lod.h"
#include "btf_package.h"
#include "fixtures.h"
#include "btf_decode.h"

#define SIZE 32
#define COMPS 5
#define LEVELS 3

/* dir/v1 (a generated tiles material on fx_dirs11, 8 bits), dir/v2 and dir/v4 made from it. */
static void make_packages(char *dir, size_t n, long long bytes[3])
{
    btf_dirset d = fx_dirs11();
    fx_levels_spec spec = {.kind = BTF_GEN_TILES, .size = SIZE, .storage = BTF_U8, .dirs = &d, .k = 3,
                           .components = COMPS, .levels = LEVELS};
    btf_lod_stats s2, s4;
    fx_levels(dir, n, &spec, &s2);
    char v1[600], v4[600];
    snprintf(v1, sizeof v1, "%s/v1", dir);
    snprintf(v4, sizeof v4, "%s/v4", dir);
    btf_lod_options lo = {0};
    lo.levels = LEVELS;
    lo.residual = 1;
    btf_error err = {0};
    cr_assert_eq(btf_lod_build(v1, v4, &lo, &s4, &err), BTF_OK, "%s", err.msg);
    lo.png_only = 1; /* the same with every texture a PNG (doc/package-format.md section 4.1) */
    snprintf(v4, sizeof v4, "%s/v4png", dir);
    cr_assert_eq(btf_lod_build(v1, v4, &lo, NULL, &err), BTF_OK, "%s", err.msg);
    if (bytes)
        bytes[0] = s2.bytes_v1, bytes[1] = s2.bytes, bytes[2] = s4.bytes;
}

/* Runs a shell command with one quoted path: "cp P P.bak", "mv P.bak P" and the like. */
static void run(const char *before, const char *path, const char *after)
{
    char cmd[4000];
    snprintf(cmd, sizeof cmd, "%s'%s'%s", before, path, after);
    cr_assert_eq(system(cmd), 0, "%s", cmd);
}

static void backup(const char *path)
{
    char cmd[4000];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s.bak'", path, path);
    cr_assert_eq(system(cmd), 0);
}

static void restore(const char *path)
{
    char cmd[4000];
    snprintf(cmd, sizeof cmd, "mv '%s.bak' '%s'", path, path);
    cr_assert_eq(system(cmd), 0);
}

/* ---------------------------------------------------------------- the transform */

/* Section 12 written out directly (per 2x2 cell, with the bilinear weights as
 * fractions and the rounding as floor(x + 1/2)), independent of btf_lod.c. */
static int ref_pred(const uint8_t *c, int cw, int tcw, int tch, int x, int y)
{
    int X = x / 2, Y = y / 2, tx = X / tcw * tcw, ty = Y / tch * tch;
    int X2 = x % 2 ? X + 1 : X - 1, Y2 = y % 2 ? Y + 1 : Y - 1;
    if (X2 < tx) X2 = tx;
    if (X2 > tx + tcw - 1) X2 = tx + tcw - 1;
    if (Y2 < ty) Y2 = ty;
    if (Y2 > ty + tch - 1) Y2 = ty + tch - 1;
    double v = 0.5625 * c[Y * cw + X] + 0.1875 * c[Y * cw + X2] + 0.1875 * c[Y2 * cw + X] + 0.0625 * c[Y2 * cw + X2];
    return (int)floor(v + 0.5);
}

static int mod256(int v) { return ((v % 256) + 256) % 256; }

/* Texel (x, y)'s bilinear prediction error q - p, 0 outside its tile (dx, dy: offset). */
static double ref_err(const uint8_t *fine, const uint8_t *c, int aw, int tw, int th, int x, int y, int dx, int dy)
{
    int nx = x + dx, ny = y + dy;
    if (nx / tw != x / tw || ny / th != y / th || nx < 0 || ny < 0)
        return 0.0;
    return fine[ny * aw + nx] - ref_pred(c, aw / 2, tw / 2, th / 2, nx, ny);
}

/* The residual byte of texel (x, y) by section 4.4's formulas (pr: the predictor). */
static int ref_residual(const uint8_t *fine, const uint8_t *c, int aw, int tw, int th, const btf_lap_pred *pr, int x,
                        int y)
{
    int cw = aw / 2;
    if (x % 2 && y % 2)
        return mod256(fine[(y - 1) * aw + x - 1] + fine[(y - 1) * aw + x] + fine[y * aw + x - 1] + fine[y * aw + x] -
                      4 * c[(y / 2) * cw + x / 2] + 128);
    int x0 = x / 2 * 2, y0 = y / 2 * 2;
    double d = 4.0 * c[(y / 2) * cw + x / 2];
    for (int k = 0; k < 4; k++)
        d -= ref_pred(c, cw, tw / 2, th / 2, x0 + k % 2, y0 + k / 2);
    double f[6] = {ref_err(fine, c, aw, tw, th, x, y, -1, 0), ref_err(fine, c, aw, tw, th, x, y, 0, -1),
                   ref_err(fine, c, aw, tw, th, x, y, 1, -1), ref_err(fine, c, aw, tw, th, x, y, -1, -1), d, 1.0};
    const int *w = pr->w[x % 2 + 2 * (y % 2)];
    double s = 0.0;
    for (int k = 0; k < 6; k++)
        s += w[k] * f[k];
    int pred = ref_pred(c, cw, tw / 2, th / 2, x, y) + (int)floor(s / 64.0);
    return mod256(fine[y * aw + x] - pred + 128);
}

/* The default predictor is the one version 4 had before predictors were listed:
 * p + floor((eL + eU) / 4). */
Test(lap, default_predictor_is_a_quarter_of_the_left_and_upper_errors)
{
    btf_lap_pred d = btf_lap_pred_default();
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 6; k++)
            cr_assert_eq(d.w[c][k], k < 2 ? 16 : 0, "class %d weight %d", c, k);
}

Test(lap, residual_transform_matches_the_formulas_and_inverts)
{
    /* tiles of 4x2, 2x2, 2x4 and 6x4 texels (coarse tiles of 1 texel: no neighbour) in a 3 x 2 atlas */
    int tws[4][2] = {{4, 2}, {2, 2}, {2, 4}, {6, 4}};
    unsigned seed = 12345;
    btf_error err = {0};
    for (int t = 0; t < 4; t++) {
        int tw = tws[t][0], th = tws[t][1], aw = 3 * tw, ah = 2 * th;
        uint8_t fine[144], coarse[36], res[144], back[144];
        for (int rep = 0; rep < 200; rep++) {
            for (int i = 0; i < aw * ah; i++)
                fine[i] = (uint8_t)(rep % 3 == 0 ? (fx_lcg(&seed) & 1) * 255 : fx_lcg(&seed) & 255); /* extremes too */
            for (int i = 0; i < aw * ah / 4; i++)
                coarse[i] = (uint8_t)(rep % 5 == 0 ? 255u - fine[2 * i] : fx_lcg(&seed) & 255u);
            btf_lap_pred pr = btf_lap_pred_default();
            if (rep % 2) /* any weights within the bound, the extremes too */
                for (int k = 0; k < 18; k++)
                    pr.w[k / 6][k % 6] = rep % 7 == 1 ? (k % 2 ? BTF_LAP_PRED_MAX : -BTF_LAP_PRED_MAX)
                                                       : (int)(fx_lcg(&seed) % 257) - 128;
            cr_assert_eq(btf_lap_encode(fine, coarse, aw, ah, tw, th, &pr, res, &err), BTF_OK, "%s", err.msg);
            for (int y = 0; y < ah; y++)
                for (int x = 0; x < aw; x++)
                    cr_assert_eq(res[y * aw + x], ref_residual(fine, coarse, aw, tw, th, &pr, x, y),
                                 "tile %dx%d texel (%d, %d), rep %d", tw, th, x, y, rep);
            cr_assert_eq(btf_lap_decode(res, coarse, aw, ah, tw, th, &pr, back, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(memcmp(back, fine, (size_t)aw * ah), 0, "decode(encode(x)) == x, tile %dx%d", tw, th);
        }
    }
}

/* The fitted predictor recovers a known linear model: fine texels made as p + the
 * given weights over their features + noise (the generator's own arithmetic, in
 * double, independent of the fit). The features are themselves made of that noise,
 * so a weight's standard error is about 1/sqrt(N) = 1/64 with N = 4096 texels per
 * class, 1 in units of 1/64: the fitted weights must be within 4 (4 sigma) of the
 * planted ones. And the fitted residual has less energy than the default's. */
Test(lap, fitted_predictor_recovers_a_planted_model)
{
    enum { TW = 16, TH = 16, AW = 8 * TW, AH = 8 * TH };
    static uint8_t fine[AW * AH], coarse[AW * AH / 4];
    unsigned seed = 777;
    const int want[3][6] = {{20, -10, 6, 0, 12, 32}, {-16, 8, 0, 10, 16, 32}, {12, -20, 8, -4, 24, 32}};
    for (int i = 0; i < AW * AH / 4; i++)
        coarse[i] = (uint8_t)(96 + fx_lcg(&seed) % 64);
    /* raster order: each texel from the already made ones, as the decoder would */
    for (int y = 0; y < AH; y++)
        for (int x = 0; x < AW; x++) {
            double v;
            if (x % 2 && y % 2) {
                v = 4.0 * coarse[(y / 2) * (AW / 2) + x / 2] - fine[(y - 1) * AW + x - 1] - fine[(y - 1) * AW + x] -
                    fine[y * AW + x - 1] + (double)(fx_lcg(&seed) % 4) - 2.0;
            } else {
                int x0 = x / 2 * 2, y0 = y / 2 * 2;
                double d = 4.0 * coarse[(y / 2) * (AW / 2) + x / 2];
                for (int k = 0; k < 4; k++)
                    d -= ref_pred(coarse, AW / 2, TW / 2, TH / 2, x0 + k % 2, y0 + k / 2);
                double f[5] = {ref_err(fine, coarse, AW, TW, TH, x, y, -1, 0), ref_err(fine, coarse, AW, TW, TH, x, y, 0, -1),
                               ref_err(fine, coarse, AW, TW, TH, x, y, 1, -1), ref_err(fine, coarse, AW, TW, TH, x, y, -1, -1), d};
                const int *w = want[x % 2 + 2 * (y % 2)];
                double s = 0.0;
                for (int k = 0; k < 5; k++)
                    s += w[k] / 64.0 * f[k];
                v = ref_pred(coarse, AW / 2, TW / 2, TH / 2, x, y) + s +
                    ((double)(fx_lcg(&seed) % 1001) / 1000.0 - 0.5) * 6.0;
            }
            fine[y * AW + x] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : lround(v));
        }
    btf_lap_pred pr = btf_lap_pred_fit(fine, coarse, AW, AH, TW, TH);
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 5; k++)
            cr_assert(abs(pr.w[c][k] - want[c][k]) <= 4, "class %d weight %d: fitted %d, planted %d", c, k, pr.w[c][k],
                      want[c][k]);
    /* the fitted residual has less energy than the default's */
    static uint8_t res[AW * AH];
    double e[2] = {0.0, 0.0};
    btf_lap_pred d = btf_lap_pred_default();
    btf_error err = {0};
    for (int m = 0; m < 2; m++) {
        cr_assert_eq(btf_lap_encode(fine, coarse, AW, AH, TW, TH, m ? &pr : &d, res, &err), BTF_OK, "%s", err.msg);
        for (int i = 0; i < AW * AH; i++)
            e[m] += (res[i] - 128.0) * (res[i] - 128.0);
    }
    cr_assert(e[1] < 0.8 * e[0], "fitted residual energy %.0f against the default's %.0f", e[1], e[0]);
}

/* ---------------------------------------------------------------- packages */

/* Every chunk of v4 holds exactly the texels and weights of the same chunk of v2
 * (same order): the residual coding loses nothing; and v4 is smaller. */
Test(lap, version4_reconstructs_version2_exactly)
{
    char dir[256];
    long long bytes[3];
    make_packages(dir, sizeof dir, bytes);
    btf_package *p2 = fx_package(dir, "v2", 0), *p4 = fx_package(dir, "v4", 0);
    cr_assert_eq(p4->version, 4);
    cr_assert_eq(p4->n_chunks, p2->n_chunks);
    size_t nwt = (size_t)p2->views.n_dirs * p2->lights.n_dirs * 3;
    int residual_files = 0;
    for (int i = 0; i < p2->n_chunks; i++) {
        int l = p2->chunk[i].level;
        size_t nt = (size_t)p2->blocks->n_blocks * (p2->width >> l) * (p2->height >> l);
        cr_assert_eq(p4->chunk[i].component, p2->chunk[i].component);
        cr_assert_eq(p4->chunk[i].level, l);
        cr_assert_eq(memcmp(p4->tex[i], p2->tex[i], nt * sizeof(float)), 0, "chunk %d (level %d): texels", i, l);
        cr_assert_eq(memcmp(p4->wt[i], p2->wt[i], nwt * sizeof(float)), 0, "chunk %d: weights", i);
        for (int f = 0; f < p4->chunk[i].n_files; f++)
            residual_files += strstr(p4->chunk[i].files[f], "-d") != NULL || strstr(p4->chunk[i].files[f], "-r.z") != NULL;
    }
    cr_assert_gt(residual_files, COMPS, "residual levels and weights are really used");
    /* textures as lossless WebP where smaller: the same texels as the PNG-only twin */
    btf_package *pp = fx_package(dir, "v4png", 0);
    int webp = 0, webp_png = 0;
    for (int i = 0; i < p4->n_chunks; i++) {
        int l = p4->chunk[i].level;
        size_t nt = (size_t)p4->blocks->n_blocks * (p4->width >> l) * (p4->height >> l);
        webp += strstr(p4->chunk[i].files[0], ".webp") != NULL;
        webp_png += strstr(pp->chunk[i].files[0], ".webp") != NULL;
        cr_assert_eq(memcmp(p4->tex[i], pp->tex[i], nt * sizeof(float)), 0, "chunk %d: WebP vs PNG texels", i);
    }
    cr_assert(webp >= 1 && webp_png == 0, "%d WebP textures, %d in the --png twin", webp, webp_png);
    btf_package_free(pp);
    cr_assert_lt(bytes[2], bytes[1], "v4 %lld B < v2 %lld B", bytes[2], bytes[1]);
    /* every prefix decodes the same (decoder, lod blending, 8-bit weights of coarse prefixes) */
    for (int n = 1; n <= p2->n_chunks; n += 3) {
        btf_package *a = fx_package(dir, "v2", n), *b = fx_package(dir, "v4", n);
        for (int k = 0; k < 40; k++) {
            float u = (float)((k * 7) % 40) / 40.0f + 0.01f, v = (float)((k * 13) % 40) / 40.0f + 0.02f;
            float li[3] = {0.3f * cosf((float)k), 0.3f * sinf((float)k), 1.0f}, vi[3] = {0.1f, -0.2f, 1.0f};
            btf_decode_options o = {0};
            o.filter = BTF_FILTER_BILINEAR, o.lod = (float)(k % 9) * 0.3f;
            float ra[3], rb[3];
            btf_decode(a, u, v, li, vi, &o, ra);
            btf_decode(b, u, v, li, vi, &o, rb);
            for (int c = 0; c < 3; c++)
                cr_assert_eq(ra[c], rb[c], "prefix %d sample %d channel %d: %g vs %g", n, k, c, ra[c], rb[c]);
        }
        btf_package_free(a);
        btf_package_free(b);
    }
    btf_package_free(p2);
    btf_package_free(p4);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Chunk 0 of v4 (the coarsest level: no residual) copied alone with the manifest is a
 * partial package that reads (n < 0: what is there) and renders finite colours, equal
 * to v2's chunk 0. */
Test(lap, coarse_prefix_renders_alone)
{
    char dir[256], part[700], src[700];
    make_packages(dir, sizeof dir, NULL);
    btf_package *p4 = fx_package(dir, "v4", 1);
    snprintf(part, sizeof part, "%s/part", dir);
    snprintf(src, sizeof src, "%s/v4", dir);
    run("mkdir -p ", part, "");
    for (int f = -1; f < p4->chunk[0].n_files; f++) {
        char cmd[3000];
        snprintf(cmd, sizeof cmd, "cp '%s/%s' '%s/'", src, f < 0 ? "manifest.json" : p4->chunk[0].files[f], part);
        cr_assert_eq(system(cmd), 0);
    }
    cr_assert_eq(p4->chunk[0].level, LEVELS - 1, "chunk 0 is the coarsest level");
    btf_package *q = NULL;
    btf_error err = {0};
    cr_assert_eq(btf_package_read(part, -1, &q, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(q->n_loaded, 1);
    btf_package *p2 = fx_package(dir, "v2", 1);
    int finite = 1, same = 1;
    for (int k = 0; k < 25; k++) {
        float li[3] = {0.2f, 0.1f * (float)k, 1.0f}, vi[3] = {0.0f, 0.0f, 1.0f}, a[3], b[3];
        btf_decode_options o = {0};
        o.filter = BTF_FILTER_BILINEAR;
        btf_decode(q, (float)k / 25.0f, 0.5f, li, vi, &o, a);
        btf_decode(p2, (float)k / 25.0f, 0.5f, li, vi, &o, b);
        for (int c = 0; c < 3; c++)
            finite &= isfinite(a[c]), same &= a[c] == b[c];
    }
    cr_assert(finite && same, "chunk 0 alone renders as v2's chunk 0");
    /* the next residual chunk's files without its coarse level make no longer prefix */
    btf_package_free(q);
    btf_package_free(p2);
    btf_package_free(p4);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* Hostile version-4 packages: each gets a clear error naming the problem. */
Test(lap, hostile_packages)
{
    char dir[256], v4[700], man[800];
    make_packages(dir, sizeof dir, NULL);
    snprintf(v4, sizeof v4, "%s/v4", dir);
    snprintf(man, sizeof man, "%s/manifest.json", v4);
    btf_package *p = fx_package(dir, "v4", 0), *q = NULL;
    btf_error err = {0};
    /* the first residual level and the first residual weights in the chunk order */
    int ir = -1, iw = -1;
    const char *rf = NULL, *wf = NULL;
    for (int i = 0; i < p->n_chunks; i++)
        for (int f = 0; f < p->chunk[i].n_files; f++) {
            const char *n = p->chunk[i].files[f];
            if (ir < 0 && strstr(n, "-d"))
                ir = i, rf = n;
            if (iw < 0 && strstr(n, "-r.z"))
                iw = i, wf = n;
        }
    cr_assert(ir >= 0 && iw >= 0);
    char path[1000], cmd[4000];
    /* 1. a residual texture that is not a PNG */
    snprintf(path, sizeof path, "%s/%s", v4, rf);
    backup(path);
    run("head -c 300 /dev/urandom > ", path, "");
    cr_assert_neq(btf_package_read(v4, ir + 1, &q, &err), BTF_OK);
    cr_assert_null(q);
    cr_assert(strstr(err.msg, rf), "names the file: %s", err.msg);
    /* 2. a residual texture of the wrong size (the coarser level's file) */
    snprintf(cmd, sizeof cmd, "cp '%s/%s' '%s'", v4, p->chunk[0].files[0], path);
    cr_assert_eq(system(cmd), 0);
    cr_assert_eq(btf_package_read(v4, ir + 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    restore(path);
    /* 3. residual weights: garbage, then a zlib stream of the wrong length */
    snprintf(path, sizeof path, "%s/%s", v4, wf);
    backup(path);
    run("head -c 500 /dev/urandom > ", path, "");
    cr_assert_eq(btf_package_read(v4, iw + 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_assert(strstr(err.msg, wf), "%s", err.msg);
    uint8_t zeros[10] = {0}, z[64];
    uLongf nz = sizeof z;
    cr_assert_eq(compress(z, &nz, zeros, sizeof zeros), Z_OK);
    fx_write(path, z, nz);
    cr_assert_eq(btf_package_read(v4, iw + 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    restore(path);
    /* 4. chunk order: chunk 0 (the coarsest level) claimed to be level 0, a residual with nothing before it */
    backup(man);
    run("sed -i '0,/\"level\":2,/s//\"level\":0,/' ", man, ""); /* LEVELS - 1 = 2: chunk 0's level */
    cr_assert_eq(btf_package_read(v4, 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    cr_assert(strstr(err.msg, "comes before") || strstr(err.msg, "both hold"), "%s", err.msg);
    restore(man);
    /* 4b. predictors: too short, out of range, not an integer, on a level that is no residual */
    const char *bad_pred[] = {"s/\"predictor\":\\[[-0-9]*,/\"predictor\":[/", "s/\"predictor\":\\[[-0-9]*,/\"predictor\":[4097,/",
                              "s/\"predictor\":\\[[-0-9]*,/\"predictor\":[0.5,/",
                              "0,/\"level\":2,/s//\"level\":2,\"predictor\":[0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0],/"};
    for (int k = 0; k < 4; k++) {
        backup(man);
        snprintf(cmd, sizeof cmd, "sed -i '%s' '%s'", bad_pred[k], man);
        cr_assert_eq(system(cmd), 0, "%s", cmd);
        cr_assert_eq(btf_package_read(v4, 1, &q, &err), BTF_ERR_FORMAT, "case %d: %s", k, err.msg);
        cr_assert(strstr(err.msg, "predictor"), "case %d names the field: %s", k, err.msg);
        restore(man);
    }
    /* 4c. the reader uses the listed predictor: another valid one rebuilds other texels */
    backup(man);
    run("sed -i 's/\"predictor\":\\[[-0-9]*,/\"predictor\":[99,/' ", man, "");
    btf_package *p2 = fx_package(dir, "v2", 0), *pm = fx_package(dir, "v4", 0);
    size_t nt = (size_t)p2->blocks->n_blocks * (p2->width >> p2->chunk[ir].level) * (p2->height >> p2->chunk[ir].level);
    cr_assert_neq(memcmp(pm->tex[ir], p2->tex[ir], nt * sizeof(float)), 0, "chunk %d rebuilt with another predictor", ir);
    btf_package_free(p2);
    btf_package_free(pm);
    restore(man);
    /* 5. a version-4 manifest claiming 16-bit textures */
    backup(man);
    run("sed -i 's/\"bits\":8,/\"bits\":16,/' ", man, "");
    cr_assert_eq(btf_package_read(v4, 1, &q, &err), BTF_ERR_FORMAT, "%s", err.msg);
    restore(man);
    /* 6. a 16-bit version-1 package cannot become version 4 */
    btf_dirset d = fx_dirs11();
    btf *src = fx_gen(BTF_GEN_TILES, 16, &d, BTF_U8);
    btf_pca_options po = {0};
    po.k = 3, po.components = 2;
    btf_package_options ko = {0};
    ko.bits = 16;
    char a[700], b[700];
    snprintf(a, sizeof a, "%s/v1-16", dir);
    snprintf(b, sizeof b, "%s/v4-16", dir);
    cr_assert_eq(btf_package_compress(src, &po, &ko, a, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(src);
    btf_lod_options lo = {0};
    lo.levels = 2, lo.residual = 1;
    cr_assert_eq(btf_lod_build(a, b, &lo, NULL, &err), BTF_ERR_UNSUPPORTED, "%s", err.msg);
    /* the untouched package still reads whole */
    btf_package_free(p);
    p = fx_package(dir, "v4", 0);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(dir), 0);
}

int cmd_compress(int argc, char **argv);

/* `btf compress --levels N --residual` writes version 4 in one step; --residual
 * alone (no levels) or with 16-bit textures is a usage error. */
Test(lap, compress_writes_version4_directly)
{
    char dir[64], out[128];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(out, sizeof out, "%s/pkg", dir);
    char *ok[] = {"compress", "gen:tiles:16:90210", out, "--components", "3", "--levels", "3", "--residual", "--quiet",
                  NULL};
    cr_assert_eq(cmd_compress(9, ok), 0);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(out, 0, &p, &err), BTF_OK, "%s", err.msg);
    cr_expect_eq(p->version, 4);
    cr_expect_eq(p->n_levels, 3);
    btf_package_free(p);
    char *none[] = {"compress", "gen:tiles:16", out, "--residual", "--quiet", NULL};
    cr_expect_eq(cmd_compress(5, none), 2);
    char *wide[] = {"compress", "gen:tiles:16", out, "--levels", "2", "--residual", "--bits", "16", "--quiet", NULL};
    cr_expect_eq(cmd_compress(9, wide), 2);
    fx_rmtree(dir);
}
