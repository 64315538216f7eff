/* test_export.c - room eval, suite "export": btf_export_thesis (bench/eval/btf_export.h): the project's PCA written
 * in the thesis's format must decode, through the thesis reader, to the float PCA
 * within the documented quantisation bound; bad k, C and sources fail cleanly. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_cli.h"
#include "btf_export.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "btf_pca.h"
#include "fixtures.h"
#include "btf_input.h"

/* 13 directions on three rings: small, and not a set the thesis reader knows. */
static btf_dirset small_dirs(void)
{
    return FX_RINGS({0.0f, 1, 0.0f}, {30.0f, 6, 0.0f}, {60.0f, 6, 30.0f});
}

/* Float reconstruction sum_j L sigma V of an unquantised package, in double. */
static double model_value(const btf_thesis_pkg *p, int view, int light, int x, int y, int c)
{
    int b = view / p->k;
    const float *l = p->L + (((size_t)b * p->S + y) * p->S + x) * p->C;
    const float *v = p->V + (((size_t)view * p->N + light) * 3 + c) * p->C;
    double s = 0.0;
    for (int j = 0; j < p->C; j++)
        s += (double)l[j] * p->sigma[b * p->C + j] * v[j];
    return s;
}

/* Exports src, reads it back with the thesis reader and checks every sample:
 * (1) the unquantised export equals the project's float PCA (same k, C, row
 *     centring, consecutive blocks) computed separately: only the scaling differs,
 *     so they agree to float rounding (1e-4 on values of order 1);
 * (2) every stored L, V is within one half byte step (1/255) and sigma within 0.05
 *     of the export (plus 1e-5 / 1e-3 for float32 and the 0.1-step decode);
 * (3) the thesis decoder's value is within btf_export_thesis_bound of (1), + 1e-5. */
static void check_round_trip(const btf *src, int k, int C, btf_thesis_scale scale)
{
    char tmp[64], dir[128];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(dir, sizeof dir, "%s/pkg", tmp);
    btf_export_options o = {k, C, scale, BTF_PCA_GRAM};
    btf_error err = {0};
    btf_thesis_pkg model, back;
    cr_assert_eq(btf_export_thesis_model(src, &o, &model, &err), BTF_OK, "%s", err.msg);
    btf_export_stats st;
    cr_assert_eq(btf_export_thesis(src, &o, dir, &st, &err), BTF_OK, "%s", err.msg);
    cr_assert_gt(st.bytes, 0);
    cr_assert_eq(btf_thesis_read(dir, &back, &err), BTF_OK, "%s", err.msg);
    cr_assert(back.C == C && back.k == k && back.N == src->views.n_dirs && back.S == src->width);

    btf_pca_options po = {.k = k, .components = C, .grouping = BTF_GROUP_CONSECUTIVE, .method = BTF_PCA_GRAM,
                          .center = BTF_CENTER_ROW, .clipped = BTF_CLIPPED_KEEP}; /* the thesis method's fit */
    btf_pca_model *pm = NULL;
    cr_assert_eq(btf_pca_compress(src, &po, NULL, NULL, &pm, &err), BTF_OK, "%s", err.msg);

    size_t nl = (size_t)model.nb * model.S * model.S * C, nv = (size_t)model.nb * k * model.N * 3 * C;
    for (size_t i = 0; i < nl; i++)
        cr_assert_leq(fabsf(back.L[i] - model.L[i]), 1.0f / 255.0f + 1e-5f, "L entry %zu", i);
    for (size_t i = 0; i < nv; i++)
        cr_assert_leq(fabsf(back.V[i] - model.V[i]), 1.0f / 255.0f + 1e-5f, "V entry %zu", i);
    for (int i = 0; i < model.nb * C; i++)
        cr_assert_leq(fabsf(back.sigma[i] - model.sigma[i]), 0.05f + 1e-3f, "sigma %d", i);

    double worst_ratio = 0.0;
    for (int v = 0; v < model.N; v++)
        for (int l = 0; l < model.N; l++)
            for (int y = 0; y < model.S; y++)
                for (int x = 0; x < model.S; x++) {
                    float dec[3];
                    btf_thesis_decode_pixel(&back, v, l, x, y, dec);
                    float bound = btf_export_thesis_bound(&model, v, l, x, y);
                    for (int c = 0; c < 3; c++) {
                        double f = model_value(&model, v, l, x, y, c);
                        double pca = btf_pca_model_value(pm, v, l, x, y, c, C);
                        cr_assert_leq(fabs(f - pca), 1e-4, "scaling changed the model at v%d l%d (%d,%d)", v, l,
                                      x, y);
                        double d = fabs(dec[c] - f);
                        cr_assert_leq(d, bound + 1e-5, "v%d l%d (%d,%d) c%d: |%g - %g| > bound %g", v, l, x, y, c,
                                      dec[c], f, bound);
                        if (bound > 0 && d / bound > worst_ratio)
                            worst_ratio = d / bound;
                    }
                }
    cr_assert_gt(worst_ratio, 0.0, "quantisation should change something");
    btf_pca_model_free(pm);
    btf_thesis_free(&model);
    btf_thesis_free(&back);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(export, round_trip_thesis_scaling_k3_c8)
{
    btf_dirset d = small_dirs();
    btf *m = fx_gen(BTF_GEN_KNIT, 16, &d, BTF_U8);
    check_round_trip(m, 3, 8, BTF_THESIS_SCALE_THESIS);
    btf_free(m);
}

Test(export, round_trip_fit_scaling_padded_last_block)
{
    btf_dirset d = small_dirs(); /* 13 views, k = 4: last block holds one view and 3 padded slots */
    btf *m = fx_gen(BTF_GEN_TILES, 16, &d, BTF_U8);
    check_round_trip(m, 4, 5, BTF_THESIS_SCALE_FIT);
    check_round_trip(m, 1, 2, BTF_THESIS_SCALE_THESIS);
    check_round_trip(m, 13, 1, BTF_THESIS_SCALE_FIT); /* the mean alone, one block */
    btf_free(m);
}

/* The fit scaling uses the byte range better: its decode is closer to the float
 * PCA (squared error over all samples) than the thesis scaling's, on a 16x16
 * material where the thesis's fixed factor 10 is mostly capped by 1/max|U|. */
Test(export, fit_scaling_not_worse_than_thesis_scaling)
{
    btf_dirset d = small_dirs();
    btf *m = fx_gen(BTF_GEN_STONE, 16, &d, BTF_U8);
    double e[2] = {0, 0};
    for (int s = 0; s < 2; s++) {
        char tmp[64], dir[128];
        cr_assert(fx_tmpdir(tmp, sizeof tmp));
        snprintf(dir, sizeof dir, "%s/pkg", tmp);
        btf_export_options o = {3, 8, s ? BTF_THESIS_SCALE_FIT : BTF_THESIS_SCALE_THESIS, BTF_PCA_GRAM};
        btf_thesis_pkg model, back;
        cr_assert_eq(btf_export_thesis_model(m, &o, &model, NULL), BTF_OK);
        cr_assert_eq(btf_export_thesis(m, &o, dir, NULL, NULL), BTF_OK);
        cr_assert_eq(btf_thesis_read(dir, &back, NULL), BTF_OK);
        for (int v = 0; v < d.n_dirs; v++)
            for (int l = 0; l < d.n_dirs; l++)
                for (int y = 0; y < 16; y++)
                    for (int x = 0; x < 16; x++) {
                        float dec[3];
                        btf_thesis_decode_pixel(&back, v, l, x, y, dec);
                        for (int c = 0; c < 3; c++) {
                            double q = dec[c] - model_value(&model, v, l, x, y, c);
                            e[s] += q * q;
                        }
                    }
        btf_thesis_free(&model);
        btf_thesis_free(&back);
        cr_assert_eq(fx_rmtree(tmp), 0);
    }
    cr_assert_leq(e[1], e[0] * 1.001, "fit %g vs thesis %g", e[1], e[0]);
    btf_free(m);
}

/* UBO2003 sampling: the foundation's importer (btf_import_thesis, U8) reproduces
 * the thesis decoder's values, rounded and clamped to bytes (within 1 byte: the
 * importer's float sum order may differ by rounding at .5). */
Test(export, import_thesis_reproduces_decoder)
{
    btf_dirset d = btf_dirset_ubo2003();
    btf *m = fx_gen(BTF_GEN_KNIT, 8, &d, BTF_U8);
    char tmp[64], dir[128];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(dir, sizeof dir, "%s/pkg", tmp);
    btf_export_options o = {3, 8, 0, 0};
    btf_error err = {0};
    cr_assert_eq(btf_export_thesis(m, &o, dir, NULL, &err), BTF_OK, "%s", err.msg);
    btf_thesis_pkg back;
    btf *imp = NULL;
    cr_assert_eq(btf_thesis_read(dir, &back, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_import_thesis(dir, NULL, &imp, &err), BTF_OK, "%s", err.msg);
    cr_assert(imp->width == 8 && imp->views.n_dirs == 81 && imp->lights.n_dirs == 81);
    for (int v = 0; v < 81; v++)
        for (int l = 0; l < 81; l++)
            for (int y = 0; y < 8; y++)
                for (int x = 0; x < 8; x++) {
                    float dec[3];
                    btf_thesis_decode_pixel(&back, v, l, x, y, dec);
                    for (int c = 0; c < 3; c++) {
                        float want = fminf(fmaxf(dec[c], 0.0f), 1.0f) * 255.0f;
                        cr_assert_leq(fabsf(btf_get(imp, v, l, x, y, c) * 255.0f - want), 1.0f);
                    }
                }
    /* writing again over the existing package replaces it */
    o.components = 4;
    cr_assert_eq(btf_export_thesis(m, &o, dir, NULL, &err), BTF_OK, "%s", err.msg);
    btf_thesis_free(&back);
    cr_assert_eq(btf_thesis_read(dir, &back, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(back.C, 4);
    btf_thesis_free(&back);
    btf_free(imp);
    btf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* A constant material: every centred block is zero (rank 0); the export must hold
 * the mean exactly to a byte step and zeros elsewhere, no NaN. */
Test(export, constant_material_rank_deficient)
{
    btf_dirset d = small_dirs();
    btf *m = NULL;
    cr_assert_eq(btf_create(8, 8, &d, &d, BTF_F32, &m, NULL), BTF_OK);
    for (size_t i = 0; i < m->count; i++)
        ((float *)m->data)[i] = 0.4f;
    char tmp[64], dir[128];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(dir, sizeof dir, "%s/pkg", tmp);
    btf_export_options o = {3, 6, BTF_THESIS_SCALE_FIT, 0};
    btf_error err = {0};
    cr_assert_eq(btf_export_thesis(m, &o, dir, NULL, &err), BTF_OK, "%s", err.msg);
    btf_thesis_pkg back;
    cr_assert_eq(btf_thesis_read(dir, &back, &err), BTF_OK, "%s", err.msg);
    for (int v = 0; v < d.n_dirs; v++)
        for (int l = 0; l < d.n_dirs; l++) {
            float dec[3];
            btf_thesis_decode_pixel(&back, v, l, 3, 5, dec);
            for (int c = 0; c < 3; c++) /* mean byte step 2/255: within 1/255 */
                cr_assert(isfinite(dec[c]) && fabsf(dec[c] - 0.4f) <= 1.0f / 255.0f + 1e-6f, "%g", dec[c]);
        }
    btf_thesis_free(&back);
    btf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

static void expect_fail(const btf *src, int k, int C, btf_result code, const char *needle)
{
    char tmp[64], dir[128];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(dir, sizeof dir, "%s/pkg", tmp);
    btf_export_options o = {k, C, 0, 0};
    btf_error err = {0};
    btf_result r = btf_export_thesis(src, &o, dir, NULL, &err);
    cr_assert_eq(r, code, "k %d C %d: got %s (%s)", k, C, btf_result_string(r), err.msg);
    cr_assert(strstr(err.msg, needle), "message '%s' lacks '%s'", err.msg, needle);
    struct stat st;
    cr_assert_neq(stat(dir, &st), 0, "nothing may be written on failure");
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(export, bad_k_and_components)
{
    btf_dirset d = small_dirs();
    btf *m = fx_gen(BTF_GEN_KNIT, 4, &d, BTF_U8); /* 16 texels: C <= 16 */
    expect_fail(m, -1, 8, BTF_ERR_RANGE, "k = -1");
    expect_fail(m, 14, 8, BTF_ERR_RANGE, "k = 14");
    expect_fail(m, 3, -2, BTF_ERR_RANGE, "C = -2");
    expect_fail(m, 3, 17, BTF_ERR_RANGE, "C = 17");
    expect_fail(m, 3, 300, BTF_ERR_RANGE, "C = 300");
    btf_free(m);
}

Test(export, bad_sources)
{
    btf_dirset d = small_dirs(), u = btf_dirset_ubo2003();
    btf *m = NULL;
    cr_assert_eq(btf_create(8, 8, &u, &d, BTF_F32, &m, NULL), BTF_OK); /* lights != views */
    expect_fail(m, 3, 2, BTF_ERR_UNSUPPORTED, "same light and view");
    btf_free(m);
    cr_assert_eq(btf_create(8, 6, &d, &d, BTF_F32, &m, NULL), BTF_OK);
    expect_fail(m, 3, 2, BTF_ERR_UNSUPPORTED, "square");
    btf_free(m);
    cr_assert_eq(btf_create(7, 7, &d, &d, BTF_F32, &m, NULL), BTF_OK);
    expect_fail(m, 3, 2, BTF_ERR_UNSUPPORTED, "even side");
    btf_free(m);
    cr_assert_eq(btf_create(8, 8, &d, &d, BTF_F32, &m, NULL), BTF_OK);
    ((float *)m->data)[100] = NAN;
    expect_fail(m, 3, 2, BTF_ERR_NUMERIC, "");
    ((float *)m->data)[100] = 0.0f;
    for (size_t i = 0; i < m->count; i++)
        ((float *)m->data)[i] = 3.0f; /* a mean the format cannot hold */
    expect_fail(m, 3, 2, BTF_ERR_RANGE, "mean");
    btf_free(m);
    btf_error err = {0};
    cr_assert_eq(btf_export_thesis(NULL, NULL, "/tmp/x", NULL, &err), BTF_ERR_ARG);
}

/* A non-empty directory that is not a thesis package is never replaced. */
Test(export, foreign_directory_kept)
{
    btf_dirset d = small_dirs();
    btf *m = fx_gen(BTF_GEN_KNIT, 4, &d, BTF_U8);
    char tmp[64], file[128];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(file, sizeof file, "%s/keep.txt", tmp);
    fx_write_text(file, "mine");
    btf_export_options o = {3, 2, 0, 0};
    btf_error err = {0};
    cr_assert_neq(btf_export_thesis(m, &o, tmp, NULL, &err), BTF_OK);
    cr_assert(access(file, F_OK) == 0, "foreign file removed");
    btf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(export, cli_usage_and_failures)
{
    char *a1[] = {"export-thesis", "in", NULL};
    cr_assert_eq(cmd_export_thesis(2, a1), 2);
    char *a2[] = {"export-thesis", "in", "out", "--k", "zero", NULL};
    cr_assert_eq(cmd_export_thesis(5, a2), 2);
    char *a3[] = {"export-thesis", "in", "out", "--scale", "best", NULL};
    cr_assert_eq(cmd_export_thesis(5, a3), 2);
    char *a4[] = {"export-thesis", "/nonexistent/in", "/tmp/btf-export-never", NULL};
    cr_assert_eq(cmd_export_thesis(3, a4), 1);
    struct stat st;
    cr_assert_neq(stat("/tmp/btf-export-never", &st), 0);
}

/* The package writer's equal-noise texture steps (doc/package-format.md section 10.4):
 * against full-range 8-bit steps they must save bytes, and the quantised error must
 * stay within the documented noise: each of the C components adds at most
 * tex_noise RMS (0..255 scale), uncorrelated between components, so
 * rmse^2 <= rmse_float^2 + C * tex_noise^2 (10% slack: rounding errors are only
 * approximately uniform and independent; 16-bit weights add ~1e-3). */
Test(export, package_equal_noise_steps_save_bytes_within_noise)
{
    btf_dirset d = small_dirs();
    btf *m = fx_gen(BTF_GEN_KNIT, 32, &d, BTF_U8);
    char tmp[64], dir[128];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(dir, sizeof dir, "%s/pkg", tmp);
    btf_pca_options po = {.k = 3, .components = 12};
    btf_compress_stats st[2];
    for (int v = 0; v < 2; v++) {
        btf_package_options ko = {0};
        ko.tex_noise = v ? 2.0f : -1.0f;
        btf_error err = {0};
        cr_assert_eq(btf_package_compress(m, &po, &ko, dir, &st[v], &err), BTF_OK, "%s", err.msg);
    }
    cr_assert_lt(st[1].bytes, st[0].bytes, "coarser steps must deflate better: %lld vs %lld", st[1].bytes,
                 st[0].bytes);
    double limit = sqrt(st[1].rmse_float * st[1].rmse_float + 12 * 2.0 * 2.0) * 1.1;
    cr_assert_leq(st[1].rmse, limit, "rmse %g, float %g", st[1].rmse, st[1].rmse_float);
    cr_assert_geq(st[1].rmse, st[0].rmse - 1e-3, "coarser steps cannot be more accurate");
    btf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* `btf eval REF PACKAGE`: the package branch succeeds on a complete package and
 * fails cleanly (exit 1) when a chunk file is missing. */
Test(export, eval_on_package)
{
    btf_dirset d = small_dirs();
    btf *m = fx_gen(BTF_GEN_TILES, 8, &d, BTF_U8);
    char tmp[64], ref[128], pkg[128], wt[160];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(ref, sizeof ref, "%s/ref.btf", tmp);
    snprintf(pkg, sizeof pkg, "%s/pkg", tmp);
    btf_error err = {0};
    cr_assert_eq(btf_save_dfmf(m, ref, 0, &err), BTF_OK, "%s", err.msg);
    btf_pca_options po = {.k = 3, .components = 4};
    cr_assert_eq(btf_package_compress(m, &po, NULL, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    char *argv[] = {"eval", ref, pkg, "--csv", NULL};
    cr_assert_eq(cmd_eval(4, argv), 0);
    snprintf(wt, sizeof wt, "%s/wt-02.bin", pkg);
    cr_assert_eq(unlink(wt), 0);
    cr_assert_eq(cmd_eval(4, argv), 1);
    btf_free(m);
    cr_assert_eq(fx_rmtree(tmp), 0);
}
