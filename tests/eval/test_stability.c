/* test_stability.c - room eval, suite "stability": every method family (btf_method.h) at the
 * directions and on the materials where methods break.
 *
 * Cases: view or light at theta 0, 74.9, 75, 80, 89.9, 90, 95 (below the horizon);
 * phi 359.99 and 0 (and the seam between them); light = view; light opposite the
 * view in azimuth (mirror configuration). Materials (16x16, 49 x 49 directions up to
 * theta 75): two generated ones (ground truth from btf_gen at any direction),
 * constant, black, white, a single-sample spike, and a rank-1 material (every PCA
 * block rank deficient; its truth is analytic at any direction).
 *
 * Asserted (guaranteed by the methods): finite output; output inside the source's
 * value range widened by RANGE_MARGIN; no seam across phi = 0; NaN/Inf sources
 * refused; a Lafortune fit that cannot converge falls back. Recorded, not asserted
 * (soft): the error at an off-grid direction against the same method's error at
 * the measured directions around it, bound ERR_FACTOR * near + ERR_SLACK.
 * The table goes to $BTF_STABILITY_OUT when set (temp file + rename): `make chart`
 * sets it to doc/figures/stability.md; `make test` leaves it unset, so running the
 * suite leaves the source tree as it was.
 */
#include <criterion/criterion.h>
#include <criterion/logging.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_gen.h"
#include "btf_method.h"
#include "fixtures.h"

#define SIDE 16
/* Range margin: 0.05 absolute (rounding of U8 sources, PCA ringing of a few levels)
 * plus 10% of the source's span (analytic lobes evaluated between measured samples). */
#define RANGE_MARGIN(lo, hi) (0.05f + 0.1f * ((hi) - (lo)))
/* Soft bound: off-grid error <= 2 x the worst neighbouring measured direction's
 * error + 8/255 (the angular interpolation of a 15-degree grid alone costs a few
 * byte levels on the generated materials). */
#define ERR_FACTOR 2.0
#define ERR_SLACK (8.0 / 255.0)
/* Seam: outputs at phi 359.99 and phi 0 differ by at most 2/255 (0.01 degrees apart). */
#define SEAM_MAX (2.0 / 255.0)

/* ------------------------------------------------------------ materials */

typedef enum mat_kind { MAT_GEN, MAT_CONST, MAT_SPIKE, MAT_RANK1 } mat_kind;

/* A test material and its ground truth; owns src and gm. */
typedef struct material {
    const char *name;
    mat_kind kind;
    btf *src;
    btf_gen_model *gm; /* MAT_GEN */
    float value;       /* MAT_CONST, MAT_SPIKE background */
} material;

#define SPIKE_X 5
#define SPIKE_Y 7

static btf_dirset test_set(void)
{
    return FX_RINGS({0, 1, 0}, {15, 4, 0}, {30, 8, 0}, {45, 10, 0}, {60, 12, 0}, {75, 14, 0});
}

static float rank1_a(int x, int y)
{
    return 0.3f + 0.5f * (float)((x * 7 + y * 3) % 5) / 4.0f;
}

static float rank1_b(const float l[3], const float v[3])
{
    float lz = l[2] > 0 ? l[2] : 0, vz = v[2] > 0 ? v[2] : 0;
    return 0.2f + 0.8f * lz * vz;
}

/* Ground truth at texel (x, y) for unit directions. */
static void truth(const material *m, int x, int y, const float l[3], const float v[3], float rgb[3])
{
    switch (m->kind) {
    case MAT_GEN:
        btf_gen_model_eval(m->gm, x, y, l, v, rgb);
        return;
    case MAT_RANK1:
        rgb[0] = rgb[1] = rgb[2] = rank1_a(x, y) * rank1_b(l, v);
        return;
    default: /* the spike has no off-grid truth at its texel: excluded from errors */
        rgb[0] = rgb[1] = rgb[2] = m->value;
    }
}

static material make_gen(const char *name, btf_gen_kind kind)
{
    btf_dirset d = test_set();
    material m = {name, MAT_GEN, NULL, NULL, 0};
    btf_gen_params p = btf_gen_defaults(kind);
    btf_error err;
    cr_assert_eq(btf_gen_create(&p, SIDE, SIDE, &d, &d, BTF_F32, &m.src, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gen_model_create(&p, SIDE, SIDE, &m.gm, &err), BTF_OK, "%s", err.msg);
    return m;
}

/* Constant, spike or rank-1 material on the test directions. */
static material make_synth(const char *name, mat_kind kind, float value)
{
    btf_dirset d = test_set();
    material m = {name, kind, NULL, NULL, value};
    btf_error err;
    cr_assert_eq(btf_create(SIDE, SIDE, &d, &d, BTF_F32, &m.src, &err), BTF_OK);
    for (int v = 0; v < d.n_dirs; v++)
        for (int l = 0; l < d.n_dirs; l++) {
            float lv[3], vv[3];
            btf_dirset_vector(&d, l, lv);
            btf_dirset_vector(&d, v, vv);
            for (int y = 0; y < SIDE; y++)
                for (int x = 0; x < SIDE; x++) {
                    float rgb[3];
                    truth(&m, x, y, lv, vv, rgb);
                    for (int c = 0; c < 3; c++)
                        btf_set(m.src, v, l, x, y, c, rgb[c]);
                }
        }
    if (kind == MAT_SPIKE)
        for (int c = 0; c < 3; c++)
            btf_set(m.src, 10, 20, SPIKE_X, SPIKE_Y, c, 1.0f);
    return m;
}

static void material_free(material *m)
{
    btf_free(m->src);
    btf_gen_model_free(m->gm);
}

/* ------------------------------------------------------------ methods, cases */

/* A method setting under test; static table. */
typedef struct setting {
    const char *label;
    const btf_method *method;
    btf_method_params params;
} setting;

#define P(...) ((btf_method_params){__VA_ARGS__})
static const setting settings[] = {
    {"phong", &btf_method_phong, P(0)},
    {"laf1", &btf_method_lafortune, P(.lobes = 1, .fit_pairs = 128)},
    {"laf2", &btf_method_lafortune, P(.lobes = 2, .fit_pairs = 128)},
    {"pca k1", &btf_method_pca, P(.k = 1, .components = 8)},
    {"pca k3", &btf_method_pca, P(.k = 3, .components = 8)},
    {"pca k27", &btf_method_pca, P(.k = 27, .components = 8)},
    {"pca k81", &btf_method_pca, P(.k = 81, .components = 8)},
    {"pca-q k3", &btf_method_pca_q, P(.k = 3, .components = 8)},
    {"lpyr k1", &btf_method_lpyr, P(.levels = 3, .components = 8, .k = 1)},
};
#define N_SET ((int)(sizeof settings / sizeof settings[0]))

/* One direction case (degrees); static table. */
typedef struct dcase {
    const char *name;
    float lt, lp, vt, vp;
} dcase;

static const dcase cases[] = {
    {"view 0", 35, 100, 0, 40},         {"view 74.9", 35, 100, 74.9f, 40}, {"view 75", 35, 100, 75, 40},
    {"view 80", 35, 100, 80, 40},       {"view 89.9", 35, 100, 89.9f, 40}, {"view 90", 35, 100, 90, 40},
    {"view 95", 35, 100, 95, 40},       {"light 0", 0, 40, 35, 100},       {"light 74.9", 74.9f, 40, 35, 100},
    {"light 75", 75, 40, 35, 100},      {"light 80", 80, 40, 35, 100},     {"light 89.9", 89.9f, 40, 35, 100},
    {"light 90", 90, 40, 35, 100},      {"light 95", 95, 40, 35, 100},     {"light phi 359.99", 50, 359.99f, 40, 200},
    {"light phi 0", 50, 0, 40, 200},    {"view phi 359.99", 40, 200, 50, 359.99f},
    {"view phi 0", 40, 200, 50, 0},     {"light = view", 50, 70, 50, 70}, {"light opposite view", 50, 70, 50, 250},
};
#define N_CASE ((int)(sizeof cases / sizeof cases[0]))

static void dir_of(float theta, float phi, float v[3])
{
    float t = theta * 0.017453292519943295f, p = phi * 0.017453292519943295f;
    v[0] = sinf(t) * cosf(p), v[1] = sinf(t) * sinf(p), v[2] = cosf(t);
}

/* Outcome of one (setting, material, case); plain value. */
typedef struct outcome {
    int finite, in_range;
    double err, near, bound; /* MAE 0..1 scale against truth: off-grid, neighbours, soft bound */
    float out_lo, out_hi;
    int soft_ok;
} outcome;

static int skip_texel(const material *m, int x, int y)
{
    return m->kind == MAT_SPIKE && x == SPIKE_X && y == SPIKE_Y;
}

/* MAE of the model against the truth at one pair of unit directions; tracks range. */
static double mae_at(const btf_model *mod, const material *m, const float l[3], const float v[3], outcome *o)
{
    double s = 0;
    int n = 0;
    for (int y = 0; y < SIDE; y++)
        for (int x = 0; x < SIDE; x++) {
            float a[3], b[3];
            btf_model_decode(mod, x, y, l, v, a);
            truth(m, x, y, l, v, b);
            for (int c = 0; c < 3; c++) {
                if (!isfinite(a[c])) {
                    o->finite = 0;
                    continue;
                }
                o->out_lo = fminf(o->out_lo, a[c]);
                o->out_hi = fmaxf(o->out_hi, a[c]);
                if (!skip_texel(m, x, y))
                    s += fabs(a[c] - b[c]), n++;
            }
        }
    return n ? s / n : 0.0;
}

/* Worst error of the model at the measured (view, light) pairs around l, v. */
static double near_err(const btf_model *mod, const material *m, const float l[3], const float v[3])
{
    btf_interp il = btf_dirset_interp_vec(&m->src->lights, l), iv = btf_dirset_interp_vec(&m->src->views, v);
    double worst = 0;
    outcome scratch = {1, 1, 0, 0, 0, INFINITY, -INFINITY, 1};
    for (int a = 0; a < 3; a++)
        for (int e = 0; e < 3; e++) {
            if (iv.w[a] * il.w[e] == 0.0f)
                continue;
            float lv[3], vv[3];
            btf_dirset_vector(&m->src->lights, il.idx[e], lv);
            btf_dirset_vector(&m->src->views, iv.idx[a], vv);
            worst = fmax(worst, mae_at(mod, m, lv, vv, &scratch));
        }
    return worst;
}

static outcome run_case(const btf_model *mod, const material *m, const dcase *dc)
{
    outcome o = {1, 1, 0, 0, 0, INFINITY, -INFINITY, 1};
    float l[3], v[3];
    dir_of(dc->lt, dc->lp, l);
    dir_of(dc->vt, dc->vp, v);
    o.err = mae_at(mod, m, l, v, &o);
    o.near = near_err(mod, m, l, v);
    o.bound = ERR_FACTOR * o.near + ERR_SLACK;
    o.soft_ok = o.err <= o.bound;
    float mg = RANGE_MARGIN(mod->lo, mod->hi);
    o.in_range = o.out_lo >= mod->lo - mg && o.out_hi <= mod->hi + mg;
    return o;
}

/* Largest |difference| over texels and channels between two direction cases. */
static double seam(const btf_model *mod, const dcase *a, const dcase *b)
{
    float la[3], va[3], lb[3], vb[3];
    dir_of(a->lt, a->lp, la), dir_of(a->vt, a->vp, va), dir_of(b->lt, b->lp, lb), dir_of(b->vt, b->vp, vb);
    double worst = 0;
    for (int y = 0; y < SIDE; y++)
        for (int x = 0; x < SIDE; x++) {
            float p[3], q[3];
            btf_model_decode(mod, x, y, la, va, p);
            btf_model_decode(mod, x, y, lb, vb, q);
            for (int c = 0; c < 3; c++)
                worst = fmax(worst, fabs(p[c] - q[c]));
        }
    return worst;
}

/* ------------------------------------------------------------ the table */

#define N_MAT 7

/* Everything measured for one material; lives during the table test. */
typedef struct mat_result {
    const char *name;
    outcome o[N_SET][N_CASE];
    double seam_light[N_SET], seam_view[N_SET], measured[N_SET];
    size_t bytes[N_SET];
    int fallback[N_SET], unconverged[N_SET];
    float lo, hi;
} mat_result;

static int case_index(const char *name)
{
    for (int i = 0; i < N_CASE; i++)
        if (strcmp(cases[i].name, name) == 0)
            return i;
    cr_assert_fail("no case %s", name);
    return 0;
}

/* MAE over a strided subset of the measured pairs (overall fit quality). */
static double measured_err(const btf_model *mod, const material *m)
{
    int L = m->src->lights.n_dirs, N = m->src->views.n_dirs * L, n = 0;
    double s = 0;
    outcome scratch = {1, 1, 0, 0, 0, INFINITY, -INFINITY, 1};
    for (int i = 0; i < N; i += 97, n++) {
        float lv[3], vv[3];
        btf_dirset_vector(&m->src->lights, i % L, lv);
        btf_dirset_vector(&m->src->views, i / L, vv);
        s += mae_at(mod, m, lv, vv, &scratch);
    }
    return s / n;
}

static void run_material(const material *m, mat_result *r)
{
    r->name = m->name;
    int lp = case_index("light phi 359.99"), l0 = case_index("light phi 0");
    int vp = case_index("view phi 359.99"), v0 = case_index("view phi 0");
    for (int s = 0; s < N_SET; s++) {
        btf_model *mod = NULL;
        btf_error err;
        cr_assert_eq(btf_model_encode(settings[s].method, m->src, &settings[s].params, &mod, &err), BTF_OK,
                     "%s on %s: %s", settings[s].label, m->name, err.msg);
        r->lo = mod->lo, r->hi = mod->hi;
        if (getenv("BTF_STABILITY_VERBOSE"))
            cr_log_info("%s on %s: encode %.3f s", settings[s].label, m->name, mod->seconds);
        for (int c = 0; c < N_CASE; c++) {
            outcome *o = &r->o[s][c];
            *o = run_case(mod, m, &cases[c]);
            cr_expect(o->finite, "%s on %s, %s: non-finite output", settings[s].label, m->name, cases[c].name);
            cr_expect(o->in_range, "%s on %s, %s: output %g..%g outside %g..%g + margin", settings[s].label, m->name,
                      cases[c].name, o->out_lo, o->out_hi, mod->lo, mod->hi);
        }
        r->seam_light[s] = seam(mod, &cases[lp], &cases[l0]);
        r->seam_view[s] = seam(mod, &cases[vp], &cases[v0]);
        cr_expect(r->seam_light[s] <= SEAM_MAX && r->seam_view[s] <= SEAM_MAX, "%s on %s: seam at phi 0: %g / %g",
                  settings[s].label, m->name, r->seam_light[s], r->seam_view[s]);
        r->measured[s] = measured_err(mod, m);
        r->bytes[s] = btf_model_bytes(mod);
        r->fallback[s] = mod->n_fallback;
        r->unconverged[s] = mod->n_unconverged;
        btf_model_free(mod);
    }
}

static void write_cell(FILE *f, const outcome *o)
{
    if (!o->finite)
        fprintf(f, " NaN! |");
    else if (!o->in_range)
        fprintf(f, " RANGE %.0f..%.0f |", 255 * o->out_lo, 255 * o->out_hi);
    else if (!o->soft_ok)
        fprintf(f, " **fail** %.1f > %.1f |", 255 * o->err, 255 * o->bound);
    else
        fprintf(f, " ok %.1f |", 255 * o->err);
}

static void write_header(FILE *f)
{
    fprintf(f, "# Stability of the method families\n\n"
               "Generated by `tests/eval/test_stability.c` (suite `stability`, written by `make chart`; "
               "`make test` runs it without writing): do not edit by hand.\n\n"
               "Materials: %dx%d texels, 49 light x 49 view directions (rings at theta 0..75 step 15, counts "
               "1, 4, 8, 10, 12, 14). `knit`, `stone`: generated (bench/gen/btf_gen.h), ground truth at any direction; "
               "`constant` 0.5, `black`, `white`: flat; `spike`: 0.2 with one sample at 1.0 (its texel is left out "
               "of the errors); `rank1`: texture x direction function (every PCA block rank deficient).\n\n"
               "Cells: MAE against the ground truth at the off-grid direction, byte levels (0..255). "
               "`ok e`: e <= bound; `**fail** e > b`: the soft bound b = %.0f x (worst MAE of the same model at the "
               "measured direction pairs around the case) + %.0f is exceeded (recorded, not asserted). "
               "`NaN!` (non-finite output) and `RANGE lo..hi` (output outside the source range +/- "
               "(0.05 + 10%% of its span)) would be hard failures: the suite asserts they never occur.\n\n",
            SIDE, SIDE, ERR_FACTOR, ERR_SLACK * 255);
}

static void write_material(FILE *f, const mat_result *r)
{
    fprintf(f, "## %s (source range %.3f..%.3f)\n\n| case |", r->name, r->lo, r->hi);
    for (int s = 0; s < N_SET; s++)
        fprintf(f, " %s |", settings[s].label);
    fprintf(f, "\n|---|");
    for (int s = 0; s < N_SET; s++)
        fprintf(f, "---|");
    fprintf(f, "\n");
    for (int c = 0; c < N_CASE; c++) {
        fprintf(f, "| %s |", cases[c].name);
        for (int s = 0; s < N_SET; s++)
            write_cell(f, &r->o[s][c]);
        fprintf(f, "\n");
    }
    fprintf(f, "| MAE at measured pairs |");
    for (int s = 0; s < N_SET; s++)
        fprintf(f, " %.1f |", 255 * r->measured[s]);
    fprintf(f, "\n| seam at phi 0 (light / view) |");
    for (int s = 0; s < N_SET; s++)
        fprintf(f, " %.2f / %.2f |", 255 * r->seam_light[s], 255 * r->seam_view[s]);
    fprintf(f, "\n| bytes (fits rejected / stopped at the cap) |");
    for (int s = 0; s < N_SET; s++)
        fprintf(f, " %zu (%d / %d) |", r->bytes[s], r->fallback[s], r->unconverged[s]);
    fprintf(f, "\n\n");
}

static void write_summary(FILE *f, const mat_result *r, int n_mat)
{
    fprintf(f, "## Summary: soft-bound failures per method and material (of %d cases)\n\n| method |", N_CASE);
    for (int i = 0; i < n_mat; i++)
        fprintf(f, " %s |", r[i].name);
    fprintf(f, " failing cases (any material) |\n|---|");
    for (int i = 0; i <= n_mat; i++)
        fprintf(f, "---|");
    fprintf(f, "\n");
    for (int s = 0; s < N_SET; s++) {
        fprintf(f, "| %s |", settings[s].label);
        int any[N_CASE] = {0};
        for (int i = 0; i < n_mat; i++) {
            int n = 0;
            for (int c = 0; c < N_CASE; c++)
                if (!r[i].o[s][c].soft_ok || !r[i].o[s][c].in_range || !r[i].o[s][c].finite)
                    n++, any[c] = 1;
            fprintf(f, " %d |", n);
        }
        const char *sep = " ";
        for (int c = 0; c < N_CASE; c++)
            if (any[c])
                fprintf(f, "%s%s", sep, cases[c].name), sep = ", ";
        fprintf(f, " |\n");
    }
    fprintf(f, "\n");
}

/* Writes the table to $BTF_STABILITY_OUT (when set) through a temporary file and a rename. */
static void write_doc(const mat_result *r, int n_mat)
{
    const char *path = getenv("BTF_STABILITY_OUT");
    if (!path || !*path)
        return; /* make test: the table is made by make chart */
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "w");
    cr_assert_not_null(f, "cannot write %s", tmp);
    write_header(f);
    write_summary(f, r, n_mat);
    for (int i = 0; i < n_mat; i++)
        write_material(f, &r[i]);
    int bad = ferror(f);
    bad |= fclose(f) != 0;
    if (bad || rename(tmp, path) != 0) {
        unlink(tmp);
        cr_assert_fail("cannot write %s", path);
    }
}

Test(stability, table, .timeout = 120)
{
    material mats[N_MAT] = {
        make_gen("knit", BTF_GEN_KNIT),           make_gen("stone", BTF_GEN_STONE),
        make_synth("constant", MAT_CONST, 0.5f),  make_synth("black", MAT_CONST, 0.0f),
        make_synth("white", MAT_CONST, 1.0f),     make_synth("spike", MAT_SPIKE, 0.2f),
        make_synth("rank1", MAT_RANK1, 0.0f),
    };
    mat_result *res = calloc(N_MAT, sizeof *res);
    cr_assert_not_null(res);
    for (int i = 0; i < N_MAT; i++)
        run_material(&mats[i], &res[i]);
    write_doc(res, N_MAT);
    for (int i = 0; i < N_MAT; i++)
        material_free(&mats[i]);
    free(res);
}

/* ------------------------------------------------------------ refusals, fallbacks */

Test(stability, nan_inf_refused)
{
    material m = make_synth("constant", MAT_CONST, 0.5f);
    float bad[2] = {NAN, INFINITY};
    for (int b = 0; b < 2; b++) {
        ((float *)m.src->data)[1234] = bad[b];
        for (int s = 0; s < N_SET; s++) {
            btf_model *mod = NULL;
            btf_error err = {{0}};
            cr_expect_eq(btf_model_encode(settings[s].method, m.src, &settings[s].params, &mod, &err),
                         BTF_ERR_NUMERIC, "%s accepted a %s sample", settings[s].label, b ? "Inf" : "NaN");
            cr_expect_null(mod);
            cr_expect(strlen(err.msg) > 0, "%s: no message", settings[s].label);
        }
    }
    material_free(&m);
}

/* Noise no lobe can fit, and an iteration cap of 1: every texel must fall back to
 * its grid start, and outputs stay finite and in range at every case. */
Test(stability, lafortune_fallback)
{
    material m = make_synth("noise", MAT_CONST, 0.0f);
    unsigned st = 99u;
    float *d = m.src->data;
    for (size_t i = 0; i < m.src->count; i++) {
        st ^= st << 13, st ^= st >> 17, st ^= st << 5;
        d[i] = (float)(st % 1000u) / 999.0f;
    }
    int caps[2] = {1, 0};
    for (int k = 0; k < 2; k++) {
        btf_method_params p = {0};
        p.lobes = 2, p.max_iter = caps[k], p.fit_pairs = 128;
        btf_model *mod = NULL;
        btf_error err;
        cr_assert_eq(btf_model_encode(&btf_method_lafortune, m.src, &p, &mod, &err), BTF_OK, "%s", err.msg);
        if (caps[k] == 1)
            cr_expect_eq(mod->n_unconverged, SIDE * SIDE, "cap 1: %d of %d texels unconverged",
                         mod->n_unconverged, SIDE * SIDE);
        cr_log_info("noise, lafortune 2 lobes, cap %d: %d fallbacks, %d unconverged", caps[k], mod->n_fallback,
                    mod->n_unconverged);
        for (int c = 0; c < N_CASE; c++) {
            outcome o = {1, 1, 0, 0, 0, INFINITY, -INFINITY, 1};
            float l[3], v[3];
            dir_of(cases[c].lt, cases[c].lp, l);
            dir_of(cases[c].vt, cases[c].vp, v);
            mae_at(mod, &m, l, v, &o);
            float mg = RANGE_MARGIN(mod->lo, mod->hi);
            cr_expect(o.finite, "cap %d, %s: non-finite", caps[k], cases[c].name);
            cr_expect(o.out_lo >= mod->lo - mg && o.out_hi <= mod->hi + mg, "cap %d, %s: %g..%g", caps[k],
                      cases[c].name, o.out_lo, o.out_hi);
        }
        btf_model_free(mod);
    }
    material_free(&m);
}
