/* test_fixed_gl.c - room gl (shaders/host), suite "gl_fixed": the decoder with the light
 * blended once per draw (BTF_FIXED_LIGHT, shaders/host/btf_gl_fixed.h).
 *
 * Bounds. The run-time decoder agrees with btf_decode within 1e-4 + Q (worst case) and
 * 3e-5 + R (RMS), Q and R from btf_gl_package_quant_error (tests/gl/test_gl.c says why).
 * The fixed-light decoder computes the same sums except that each blended weight is
 * rounded once more, onto its per-draw grid (half a step dL at most, per slot and
 * channel): btf_gl_fixed_quant_error adds max|T| dL/2 + dT dL/4 to Q and E[T^2] dL^2/12
 * to R^2 (Qf, Rf), the bound it is guaranteed. The tests hold it to the run-time path's
 * own tolerance, 1e-4 + Q and 3e-5 + R, which it meets with room on these packages (the
 * per-draw step is no coarser than the package's, and the worst case needs every
 * rounding at its extreme, aligned; measured max 3.6e-4 against 1e-4 + Q >= 1e-3), and
 * check Qf >= Q. Against the run-time program on the same queries the difference is the
 * added rounding alone plus float noise: within 1e-4 + (Qf - Q). */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_decode.h"
#include "btf_gen.h"
#include "btf_gl_fixed.h"
#include "btf_gl_package.h"
#include "btf_package.h"
#include "btf_render.h"
#include "fixtures.h"

#define FW 16   /* material side */
#define FC 6    /* components: two layers of 4 slots */
#define FQW 24  /* queries per draw: FQW x FQW */
#define FQ (FQW * FQW)

static const btf_gl_backend backends[2] = {BTF_GL_EGL, BTF_GL_OSMESA};

/* Local lights of the draws (theta, phi): the normal, inside the rings, on a measured
 * direction, between rings, beyond the outermost ring (60) and below the horizon. */
static const float lights[6][2] = {{0, 0}, {27, 41}, {30, 0}, {52, 200}, {75, 300}, {97, 10}};

/* A package of a generated knit (fx_dirs19, FC components) in a fresh temp dir. */
static void make_package(char *tmp, size_t n, char *pkg, size_t pn, int bits)
{
    cr_assert(fx_tmpdir(tmp, n));
    snprintf(pkg, pn, "%s/knit", tmp);
    btf_dirset d = fx_dirs19();
    btf *m = fx_gen(BTF_GEN_KNIT, FW, &d, BTF_F32);
    btf_pca_options po = {0};
    po.k = 3, po.components = FC;
    btf_package_options ko = {0};
    ko.bits = bits;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_compress(m, &po, &ko, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(m);
}

/* decode_probe with the package's specialisation, fixed = 1: BTF_FIXED_LIGHT. */
static btf_shader_program *build_probe(btf_gl *gl, const btf_gl_package *g, int filter, int n, int fixed)
{
    btf_shader_define defs[BTF_GL_PACKAGE_DEFINES + 1];
    char vals[BTF_GL_PACKAGE_DEFINES][16];
    btf_shader_desc sd = {.program = "decode_probe", .defines = defs};
    sd.n_defines = btf_gl_package_defines(g, filter, n, defs, vals);
    defs[sd.n_defines++] = (btf_shader_define){"BTF_FIXED_LIGHT", fixed ? "1" : "0"};
    btf_shader_program *prog = NULL;
    char *report = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_shader_build(gl, &sd, &prog, &report, &err), BTF_OK, "%s\n%s", err.msg, report ? report : "");
    free(report);
    return prog;
}

/* Queries of one draw: q0 = (light, u), q1 = (view, v); every light the same, views
 * over the hemisphere (and below it), uv across and beyond the tile. */
static void make_queries(const float l[3], uint32_t seed, float *q0, float *q1)
{
    for (int i = 0; i < FQ; i++) {
        memcpy(&q0[i * 4], l, 3 * sizeof(float));
        fx_dirf(acos(fx_unit(fx_xorshift32(&seed)) * 1.1 - 0.1) * 57.29578, fx_unit(fx_xorshift32(&seed)) * 360.0,
                &q1[i * 4]);
        q0[i * 4 + 3] = (float)(fx_unit(fx_xorshift32(&seed)) * 1.4 - 0.2);
        q1[i * 4 + 3] = (float)(fx_unit(fx_xorshift32(&seed)) * 1.4 - 0.2);
    }
}

/* One draw of prog over the queries into out (FQ RGBA floats); fixed: x bound. */
static void probe_draw(btf_gl *gl, btf_shader_program *prog, const btf_gl_package *g, const btf_gl_fixed *x,
                       const btf_gl_decode_settings *s, float lod, const float *q0, const float *q1, float *out)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_error err = {{0}};
    GLuint t0 = 0, t1 = 0;
    cr_assert_eq(btf_gl_texture_create(gl, FQW, FQW, BTF_GL_RGBA32F, q0, &t0, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_texture_create(gl, FQW, FQW, BTF_GL_RGBA32F, q1, &t1, &err), BTF_OK, "%s", err.msg);
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, FQW, FQW, BTF_GL_RGBA32F, 1, &t, &err), BTF_OK, "%s", err.msg);
    btf_gl_target_bind(gl, t);
    f->UseProgram(prog->id);
    cr_assert_eq(btf_gl_package_bind(gl, g, prog, 0, &err), BTF_OK, "%s", err.msg);
    btf_gl_package_settings(gl, g, prog, s);
    btf_gl_package_lod(gl, prog, 1, lod);
    btf_gl_fixed_bind(gl, x, prog, BTF_GL_FIXED_UNIT);
    f->ActiveTexture(GL_TEXTURE6);
    f->BindTexture(GL_TEXTURE_2D, t0);
    f->Uniform1i(f->GetUniformLocation(prog->id, "u_q0"), 6);
    f->ActiveTexture(GL_TEXTURE7);
    f->BindTexture(GL_TEXTURE_2D, t1);
    f->Uniform1i(f->GetUniformLocation(prog->id, "u_q1"), 7);
    btf_gl_draw_fullscreen(gl);
    cr_assert_eq(btf_gl_target_read(gl, t, 0, out, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_check(gl, "probe draw", &err), BTF_OK, "%s", err.msg);
    btf_gl_target_free(gl, t);
    btf_gl_texture_free(gl, t0);
    btf_gl_texture_free(gl, t1);
}

/* Largest differences over every draw of one test; a plain value on that test's stack. */
typedef struct diff_stats {
    double cpu, runtime, rms; /* max |fixed - cpu|, max |fixed - run-time|, largest RMS |fixed - cpu| of a draw */
    double runtime_cpu;       /* max |run-time - cpu|, for comparison */
} diff_stats;

/* Fixed-light and run-time programs (prefix n, filter, lod) on one light's queries:
 * fixed vs btf_decode within 1e-4 + Q, RMS within 3e-5 + R (the run-time path's
 * tolerance); fixed vs run-time within 1e-4 + Qf - Q. */
static void compare_light(btf_gl *gl, const btf_package *p, const btf_gl_package *g, btf_gl_fixed *x,
                          btf_shader_program *fixed, btf_shader_program *runtime, const btf_gl_decode_settings *s,
                          float lod, const float l[3], const char *what, diff_stats *st)
{
    static float q0[FQ * 4], q1[FQ * 4], a[FQ * 4], b[FQ * 4];
    btf_error err = {{0}};
    make_queries(l, 7u + (uint32_t)s->n_chunks * 31u, q0, q1);
    cr_assert_eq(btf_gl_fixed_update(gl, x, g, l, s->n_chunks, &err), BTF_OK, "%s", err.msg);
    probe_draw(gl, fixed, g, x, s, lod, q0, q1, a);
    probe_draw(gl, runtime, g, x, s, lod, q0, q1, b);
    double q, r, qf, rf, sq = 0;
    btf_gl_package_quant_error(g, &q, &r);
    btf_gl_fixed_quant_error(x, g, &qf, &rf);
    cr_assert(qf >= q && rf >= r);
    btf_decode_options o = {0};
    o.filter = s->filter ? BTF_FILTER_BILINEAR : BTF_FILTER_NEAREST;
    o.wrap = s->wrap, o.n_chunks = s->n_chunks, o.lod = lod;
    for (int i = 0; i < FQ; i++) {
        float rgb[3];
        btf_decode(p, q0[i * 4 + 3], q1[i * 4 + 3], l, &q1[i * 4], &o, rgb);
        for (int c = 0; c < 3; c++) {
            double e = fabs(a[i * 4 + c] - rgb[c]), d = fabs(a[i * 4 + c] - b[i * 4 + c]);
            cr_assert(e <= 1e-4 + q, "%s query %d c%d: fixed %.7f cpu %.7f (bound %.2e)", what, i, c,
                      (double)a[i * 4 + c], (double)rgb[c], 1e-4 + q);
            cr_assert(d <= 1e-4 + qf - q, "%s query %d c%d: fixed %.7f run-time %.7f (bound %.2e)", what, i, c,
                      (double)a[i * 4 + c], (double)b[i * 4 + c], 1e-4 + qf - q);
            sq += e * e;
            st->cpu = fmax(st->cpu, e);
            st->runtime = fmax(st->runtime, d);
            st->runtime_cpu = fmax(st->runtime_cpu, fabs(b[i * 4 + c] - rgb[c]));
        }
    }
    double rms = sqrt(sq / (3.0 * FQ));
    cr_assert(rms <= 3e-5 + r, "%s: RMS %.3g above %.3g", what, rms, 3e-5 + r);
    cr_assert(r < 0.1 / 255.0 && rf < 0.1 / 255.0, "%s: requantisation RMS bounds %.3g, %.3g", what, r, rf);
    st->rms = fmax(st->rms, rms);
}

/* Every light of `lights`, prefixes 1, 4 and all, both filters, on one backend. */
static void check_fixed(btf_gl_backend b, int bits)
{
    char tmp[256], pkg[300];
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, bits);
    btf_package *p = fx_package(pkg, NULL, 0);
    btf_gl *gl = fx_gl_open(b);
    btf_gl_package *g = NULL;
    btf_gl_fixed *x = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gl_package_upload(gl, p, pkg, &g, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_fixed_create(gl, g, &x, &err), BTF_OK, "%s", err.msg);
    const int prefixes[3] = {1, 4, 0};
    diff_stats st = {0, 0, 0, 0};
    for (int k = 0; k < 3; k++)
        for (int filter = 0; filter < 2; filter++) {
            btf_shader_program *fixed = build_probe(gl, g, filter, prefixes[k], 1);
            btf_shader_program *runtime = build_probe(gl, g, filter, prefixes[k], 0);
            for (int li = 0; li < 6; li++) {
                btf_gl_decode_settings s = {filter, 1, prefixes[k]};
                float l[3];
                fx_dirf(lights[li][0], lights[li][1], l);
                char what[128];
                snprintf(what, sizeof what, "%s %d-bit n=%d filter=%d light (%g, %g)", btf_gl_backend_name(b), bits,
                         prefixes[k], filter, (double)lights[li][0], (double)lights[li][1]);
                compare_light(gl, p, g, x, fixed, runtime, &s, 0.0f, l, what, &st);
            }
            btf_shader_program_free(gl, fixed);
            btf_shader_program_free(gl, runtime);
        }
    cr_log_info("fixed light %s %d-bit: max |fixed - cpu| %.2e (RMS %.2e), |run-time - cpu| %.2e, |fixed - run-time| "
                "%.2e", btf_gl_backend_name(b), bits, st.cpu, st.rms, st.runtime_cpu, st.runtime);
    btf_gl_fixed_free(gl, x);
    btf_gl_package_free(gl, g);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(gl_fixed, decode_matches_cpu_egl) { check_fixed(BTF_GL_EGL, 8); }
Test(gl_fixed, decode_matches_cpu_osmesa) { check_fixed(BTF_GL_OSMESA, 8); }
Test(gl_fixed, decode_matches_cpu_16bit) { check_fixed(BTF_GL_EGL, 16); }

/* A package with 3 spatial levels (the level blend compiled in): lods between and
 * beyond the levels, two prefixes, both filters. */
Test(gl_fixed, decode_levels_match_cpu)
{
    char dir[256], v2[300];
    btf_dirset d = fx_dirs19();
    fx_levels_spec spec = {BTF_GEN_KNIT, FW, BTF_F32, &d, 3, FC, 8, 3};
    fx_levels(dir, sizeof dir, &spec, NULL);
    snprintf(v2, sizeof v2, "%s/v2", dir);
    btf_package *p = fx_package(dir, "v2", 0);
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_gl_package *g = NULL;
    btf_gl_fixed *x = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gl_package_upload(gl, p, v2, &g, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_fixed_create(gl, g, &x, &err), BTF_OK, "%s", err.msg);
    const int prefixes[2] = {p->n_chunks / 2, 0};
    const float lods[4] = {-1.0f, 0.4f, 1.5f, 2.7f};
    diff_stats st = {0, 0, 0, 0};
    for (int k = 0; k < 2; k++)
        for (int filter = 0; filter < 2; filter++) {
            btf_shader_program *fixed = build_probe(gl, g, filter, prefixes[k], 1);
            btf_shader_program *runtime = build_probe(gl, g, filter, prefixes[k], 0);
            for (int li = 0; li < 4; li++) {
                btf_gl_decode_settings s = {filter, 1, prefixes[k]};
                float l[3];
                fx_dirf(lights[li + 1][0], lights[li + 1][1], l);
                char what[128];
                snprintf(what, sizeof what, "levels n=%d filter=%d lod %g", prefixes[k], filter, (double)lods[li]);
                compare_light(gl, p, g, x, fixed, runtime, &s, lods[li], l, what, &st);
            }
            btf_shader_program_free(gl, fixed);
            btf_shader_program_free(gl, runtime);
        }
    cr_log_info("fixed light, levels: max |fixed - cpu| %.2e, |run-time - cpu| %.2e, |fixed - run-time| %.2e", st.cpu,
                st.runtime_cpu, st.runtime);
    btf_gl_fixed_free(gl, x);
    btf_gl_package_free(gl, g);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(dir), 0);
}

/* ---------------------------------------------------------------- the renderer */

#define RW 64
#define RH 48

/* The plane drawn by btf_renderer_draw (the fixed-light program: a distant light on
 * the plane) and by btf_renderer_use with the plane's mesh (the run-time program), same
 * parameters, debug outputs: the same fragments (uv, local light and view equal), colour
 * within 1e-4 + Qf - Q of each other and within 1e-4 + Q (the run-time path's tolerance,
 * test_gl.c) of btf_decode at the fragment's own uv, light and view (the horizon fade
 * applied as btf_render.frag does). */
static void check_renderer(btf_gl_backend b, int filter, float light_theta, float light_phi)
{
    char tmp[256], pkg[300];
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, 8);
    btf_package *p = fx_package(pkg, NULL, 0);
    btf_gl *gl = fx_gl_open(b);
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_renderer *r = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_renderer_create(gl, p, pkg, 1, &r, &err), BTF_OK, "%s", err.msg);
    btf_render_params rp = btf_render_defaults(BTF_RENDER_PLANE);
    rp.width = RW, rp.height = RH, rp.filter = filter, rp.repeat = 2;
    rp.camera_theta = 40, rp.camera_phi = -60, rp.camera_dist = 2.5f;
    rp.light_theta = light_theta, rp.light_phi = light_phi;
    static float out[2][4][RW * RH * 4];
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, RW, RH, BTF_GL_RGBA32F, 4, &t, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_OK, "%s", err.msg);
    for (int a = 0; a < 4; a++)
        cr_assert_eq(btf_gl_target_read(gl, t, a, out[0][a], &err), BTF_OK, "%s", err.msg);
    /* the run-time program on the same mesh */
    btf_render_camera cam;
    btf_render_camera_make(&rp, &cam);
    btf_render_mesh *m = NULL;
    cr_assert_eq(btf_render_mesh_create(BTF_RENDER_PLANE, 0, &m, &err), BTF_OK, "%s", err.msg);
    GLuint vao = 0, buf[2] = {0, 0}, depth = 0;
    f->GenVertexArrays(1, &vao);
    f->BindVertexArray(vao);
    f->GenBuffers(2, buf);
    btf_render_mesh_upload(f, m, buf[0], buf[1]);
    cr_assert_eq(btf_render_frame_begin(gl, &rp, t, &depth, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_renderer_use(r, &rp, &cam, &err), BTF_OK, "%s", err.msg);
    f->BindVertexArray(vao);
    f->DrawElements(GL_TRIANGLES, m->n_indices, GL_UNSIGNED_INT, 0);
    btf_render_frame_end(gl, depth);
    for (int a = 0; a < 4; a++)
        cr_assert_eq(btf_gl_target_read(gl, t, a, out[1][a], &err), BTF_OK, "%s", err.msg);
    double q, rq, qf, rf;
    const btf_gl_package *g = btf_renderer_package(r);
    btf_gl_fixed *x = NULL; /* the bound of the renderer's blend: the same light, same blend */
    cr_assert_eq(btf_gl_fixed_create(gl, g, &x, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_fixed_update(gl, x, g, cam.light, 0, &err), BTF_OK, "%s", err.msg);
    btf_gl_package_quant_error(g, &q, &rq);
    btf_gl_fixed_quant_error(x, g, &qf, &rf);
    btf_decode_options o = {0};
    o.filter = filter ? BTF_FILTER_BILINEAR : BTF_FILTER_NEAREST;
    o.wrap = 1;
    double outer = cos(btf_dirset_max_theta(&p->lights) * M_PI / 180), worst[2] = {0, 0};
    int drawn = 0;
    for (int i = 0; i < RW * RH; i++) {
        const float *lp = &out[0][2][i * 4];
        if (lp[0] == 0.0f && lp[1] == 0.0f && lp[2] == 0.0f)
            continue; /* background: the debug outputs are cleared to 0, a drawn fragment's light is a unit vector */
        drawn++;
        for (int a = 1; a < 4; a++)
            for (int c = 0; c < 3; c++)
                cr_assert(fabs(out[0][a][i * 4 + c] - out[1][a][i * 4 + c]) <= 1e-6, "pixel %d output %d differs", i, a);
        const float *uv = &out[0][1][i * 4], *l = &out[0][2][i * 4], *v = &out[0][3][i * 4];
        float rgb[3];
        o.lod = uv[2];
        btf_decode(p, uv[0], uv[1], l, v, &o, rgb);
        double len = sqrt((double)l[0] * l[0] + (double)l[1] * l[1] + (double)l[2] * l[2]), cz = l[2] / len;
        double fade = cz >= outer ? 1.0 : fmax(cz, 0.0) / outer;
        for (int c = 0; c < 3; c++) {
            double want = fmin(fmax(rgb[c] * fade, 0.0), 1.0), got = out[0][0][i * 4 + c];
            double e = fabs(got - want), d = fabs(got - out[1][0][i * 4 + c]);
            cr_assert(e <= 1e-4 + q, "%s pixel %d c%d: fixed %.7f cpu %.7f", btf_gl_backend_name(b), i, c, got, want);
            cr_assert(d <= 1e-4 + qf - q, "%s pixel %d c%d: fixed %.7f run-time %.7f", btf_gl_backend_name(b), i, c,
                      got, (double)out[1][0][i * 4 + c]);
            worst[0] = fmax(worst[0], e), worst[1] = fmax(worst[1], d);
        }
    }
    cr_assert_gt(drawn, RW * RH / 3, "only %d pixels drawn", drawn);
    cr_log_info("%s renderer, light (%g, %g): max |fixed - cpu| %.2e, |fixed - run-time| %.2e (bounds %.2e, %.2e)",
                btf_gl_backend_name(b), (double)light_theta, (double)light_phi, worst[0], worst[1], 1e-4 + q,
                1e-4 + qf - q);
    btf_gl_fixed_free(gl, x);
    btf_render_mesh_free(m);
    f->DeleteBuffers(2, buf);
    f->DeleteVertexArrays(1, &vao);
    btf_gl_target_free(gl, t);
    btf_renderer_free(r);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(gl_fixed, renderer_plane_matches_runtime_path)
{
    for (int bi = 0; bi < 2; bi++) {
        check_renderer(backends[bi], bi, 40, -30); /* the bench's light; nearest on EGL, bilinear on OSMesa */
        check_renderer(backends[bi], 1 - bi, 75, 120); /* beyond the outer ring: the horizon fade */
    }
}

/* The per-draw texture is rebuilt only when the light or the prefix changes; slots
 * beyond the prefix get zero codes and grids. */
Test(gl_fixed, update_only_on_change)
{
    char tmp[256], pkg[300];
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, 8);
    btf_package *p = fx_package(pkg, NULL, 0);
    btf_gl *gl = fx_gl_open(BTF_GL_EGL);
    btf_gl_package *g = NULL;
    btf_gl_fixed *x = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gl_package_upload(gl, p, pkg, &g, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_gl_fixed_create(gl, g, &x, &err), BTF_OK, "%s", err.msg);
    float l[3], l2[3];
    fx_dirf(30, 10, l);
    fx_dirf(31, 10, l2);
    cr_assert_eq(btf_gl_fixed_update(gl, x, g, l, 0, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(x->slots, FC);
    uint32_t c0 = x->codes[0];
    x->codes[0] = c0 ^ 1u; /* a mark that a rebuild clears */
    cr_assert_eq(btf_gl_fixed_update(gl, x, g, l, 0, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(x->codes[0], c0 ^ 1u, "same light and prefix: not rebuilt");
    cr_assert_eq(btf_gl_fixed_update(gl, x, g, l, 2, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(x->slots, 2);
    cr_assert_eq(x->codes[0], c0, "another prefix: rebuilt");
    for (int v = 0; v < x->n_views; v++)
        cr_assert_eq(x->codes[v * 4 + 2] | x->codes[v * 4 + 3] | x->codes[(x->n_views + v) * 4], 0u);
    for (int k = 0; k < 6; k++)
        cr_assert(x->lq[k * 4 + 2] == 0.0f && x->lq[k * 4 + 3] == 0.0f && x->lq[24 + k * 4] == 0.0f);
    cr_assert_eq(btf_gl_fixed_update(gl, x, g, l2, 2, &err), BTF_OK, "%s", err.msg);
    cr_assert(!memcmp(x->light, l2, sizeof l2), "another light: rebuilt");
    btf_gl_fixed_free(gl, x);
    btf_gl_package_free(gl, g);
    btf_gl_free(gl);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}
