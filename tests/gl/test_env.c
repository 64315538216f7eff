/* test_env.c - room gl (shaders/host), suite "env": environment light, exposure and
 * tone mapping (doc/lighting.md, shaders/btf_light.glsl, shaders/host/btf_env.h).
 *
 * The main test renders a package on a plane and on a sphere under two environments
 * at two rotations and compares every covered pixel with a CPU light sum computed
 * here from a ray cast of the documented scene (not btf_render's matrices): per pixel
 * the surface frame, the environment's mean radiance over each measured light
 * direction's cell in that frame, and btf_decode at each light direction. */
#include <criterion/criterion.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_decode.h"
#include "btf_env.h"
#include "btf_gen.h"
#include "btf_package.h"
#include "btf_render.h"
#include "btf_color.h"
#include "fixtures.h"

#define TW 16 /* material side in texels */
#define RW 48 /* render size */
#define RH 40

static const btf_gl_backend backends[2] = {BTF_GL_EGL, BTF_GL_OSMESA};

/* ---------------------------------------------------------------- fixtures */

/* A package of a generated tiles material (19 directions, k 3, 4 components) at
 * dir/name, linear light or not. */
static void make_package(const char *dir, const char *name, int linear, char *pkg, size_t n)
{
    snprintf(pkg, n, "%s/%s", dir, name);
    btf_dirset d = fx_dirs19();
    btf *m = fx_gen(BTF_GEN_TILES, TW, &d, BTF_U8);
    btf_pca_options po = {0};
    po.k = 3;
    po.components = 4;
    btf_package_options ko = {0};
    ko.bits = 8;
    ko.linear = linear;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_compress(m, &po, &ko, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(m);
}

/* ---------------------------------------------------------------- the quadratic */

/* Fibonacci point i of n on the sphere. */
static void fib(int i, int n, double d[3])
{
    double z = 1.0 - (2.0 * i + 1.0) / n, r = sqrt(1.0 - z * z), ph = i * M_PI * (3.0 - sqrt(5.0));
    d[0] = r * cos(ph), d[1] = r * sin(ph), d[2] = z;
}

/* A constant environment is the constant quadratic; the studio's residual L - L2 is
 * orthogonal to 1, x, y, z and the five quadratic harmonics (it is the projection),
 * integrated here over 200000 Fibonacci points with the pixel lookup (a quadrature
 * apart from the one btf_env_quadratic uses: its error, about 1% of the mean radiance
 * for lobes 4 pixels wide, bounds the check). */
Test(env, quadratic_is_the_order_2_projection)
{
    btf_env flat = {64, 32, calloc(64 * 32 * 3, sizeof(float))};
    for (int i = 0; i < 64 * 32 * 3; i++)
        flat.rgb[i] = 1.0f;
    btf_env_quad q;
    btf_env_quadratic(&flat, 0, &q);
    for (int c = 0; c < 3; c++) {
        /* the pixel-centre rule over 32 rows integrates 3z^2 - 1 to about 1e-3, not 0 */
        cr_assert(fabsf(q.c0[c] - 1.0f) < 2e-3f, "constant: c0 %g", (double)q.c0[c]);
        for (int k = 0; k < 3; k++)
            cr_assert(fabsf(q.a[3 * c + k]) < 1e-5f, "constant: a %g", (double)q.a[3 * c + k]);
        for (int k = 0; k < 9; k++)
            cr_assert(fabsf(q.q[9 * c + k]) < 4e-3f, "constant: Q %g", (double)q.q[9 * c + k]);
    }
    free(flat.rgb);

    btf_env *e = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_env_load("studio", &e, &err), BTF_OK, "%s", err.msg);
    btf_env_quadratic(e, 0, &q);
    const int n = 200000;
    double dot[9] = {0}, mean = 0;
    for (int i = 0; i < n; i++) {
        double d[3];
        fib(i, n, d);
        float L[3];
        btf_env_radiance(e, 0, d, L);
        double r = L[0] - fx_quad_eval(&q, 0, d);
        const double f[9] = {1, d[0], d[1], d[2], d[0] * d[1], d[1] * d[2], 3 * d[2] * d[2] - 1, d[0] * d[2],
                             d[0] * d[0] - d[1] * d[1]};
        for (int k = 0; k < 9; k++)
            dot[k] += r * f[k] * 4 * M_PI / n;
        mean += L[0] / n;
    }
    for (int k = 0; k < 9; k++)
        cr_assert(fabs(dot[k]) < 0.01 * 4 * M_PI * mean, "residual not orthogonal to function %d: %g (mean %g)", k,
                  dot[k], mean);
    btf_env_free(e);
}

/* Turning the environment by r turns its quadratic: a -> Rz a, Q -> Rz Q Rz^T; the
 * radiance lookup agrees (L_r(d) = L(Rz(-r) d)). */
Test(env, rotation_turns_the_quadratic_and_the_lookup)
{
    btf_env *e = NULL;
    btf_error err = {{0}};
    char tmp[256], path[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    snprintf(path, sizeof path, "%s/sky.hdr", tmp);
    fx_write_sky(path, 64, 32);
    cr_assert_eq(btf_env_load(path, &e, &err), BTF_OK, "%s", err.msg);
    const double r = 75.0, cr = cos(r * M_PI / 180), sr = sin(r * M_PI / 180);
    btf_env_quad q0, q1;
    btf_env_quadratic(e, 0, &q0);
    btf_env_quadratic(e, r, &q1);
    for (int i = 0; i < 50; i++) {
        double d[3], back[3];
        fib(i, 50, d);
        back[0] = cr * d[0] + sr * d[1], back[1] = -sr * d[0] + cr * d[1], back[2] = d[2]; /* Rz(-r) d */
        for (int c = 0; c < 3; c++) {
            double a = fx_quad_eval(&q1, c, d), b = fx_quad_eval(&q0, c, back);
            cr_assert(fabs(a - b) < 1e-4 * (1 + fabs(b)), "channel %d: turned %g, expected %g", c, a, b);
        }
        float la[3], lb[3];
        btf_env_radiance(e, r, d, la);
        btf_env_radiance(e, 0, back, lb);
        cr_assert(la[0] == lb[0] && la[1] == lb[1] && la[2] == lb[2], "lookup of a turned environment");
    }
    /* the file holds the sky function: pixel (i, j) read back within RGBE's precision
     * (8 bits of mantissa shared by the channels: 1/128 of the largest, truncated) */
    for (int j = 0; j < 32; j += 5)
        for (int i = 0; i < 64; i += 7) {
            double th = M_PI * (j + 0.5) / 32, ph = M_PI - 2 * M_PI * (i + 0.5) / 64;
            double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
            double big = fmax(fx_sky(d, 0), fmax(fx_sky(d, 1), fx_sky(d, 2)));
            for (int c = 0; c < 3; c++) {
                double want = fx_sky(d, c), got = e->rgb[(j * 64 + i) * 3 + c];
                cr_assert(fabs(got - want) <= big / 128, "pixel (%d,%d) c%d: %g, wrote %g", i, j, c, got, want);
            }
        }
    btf_env_free(e);
    fx_rmtree(tmp);
}

/* The cells cover the hemisphere (solid angles sum to 2 pi) and each cell's centroid
 * lies in the cell (a Voronoi cell on the sphere contains its centroid direction). */
Test(env, cells_partition_the_hemisphere)
{
    btf_dirset sets[2] = {fx_dirs19(), btf_dirset_ubo2003()};
    for (int s = 0; s < 2; s++) {
        int n = sets[s].n_dirs;
        double *m = malloc((size_t)n * BTF_ENV_FUNCS * sizeof *m), sum = 0;
        float(*dirs)[3] = malloc((size_t)n * sizeof *dirs);
        btf_error err = {{0}};
        cr_assert_eq(btf_env_cells(&sets[s], m, &err), BTF_OK, "%s", err.msg);
        for (int i = 0; i < n; i++)
            btf_dirset_vector(&sets[s], i, dirs[i]);
        for (int i = 0; i < n; i++) {
            const double *row = m + (size_t)i * BTF_ENV_FUNCS;
            cr_assert_gt(row[0], 0.0, "set %d: light %d has an empty cell", s, i);
            sum += row[0];
            double c[3] = {row[1], row[2], row[3]};
            cr_assert_eq(btf_env_nearest((const float(*)[3])dirs, n, c), i, "set %d: centroid of cell %d", s, i);
            /* the second moments' trace is the solid angle (x^2 + y^2 + z^2 = 1) */
            double zz = 0;
            for (int k = 0; k < BTF_ENV_SAMPLES; k++) {
                double v[3];
                btf_env_sample(k, v);
                if (btf_env_nearest((const float(*)[3])dirs, n, v) == i)
                    zz += v[2] * v[2] * 2 * M_PI / BTF_ENV_SAMPLES;
            }
            cr_assert(fabs(row[4] + row[5] + zz - row[0]) < 1e-9, "set %d cell %d: trace", s, i);
        }
        cr_assert(fabs(sum - 2 * M_PI) < 1e-9, "set %d: solid angles sum to %.12f", s, sum);
        free(m), free(dirs);
    }
}

/* ---------------------------------------------------------------- tone curves */

static double neutral(double c[3], int ch)
{ /* Khronos PBR Neutral, as published */
    double x = fmin(c[0], fmin(c[1], c[2])), off = x < 0.08 ? x - 6.25 * x * x : 0.04, v[3];
    for (int k = 0; k < 3; k++)
        v[k] = c[k] - off;
    double peak = fmax(v[0], fmax(v[1], v[2])), start = 0.76, d = 1 - start;
    if (peak < start)
        return v[ch];
    double np = 1 - d * d / (peak + d - start), g = 1 - 1 / (0.15 * (peak - np) + 1);
    return v[ch] * np / peak * (1 - g) + np * g;
}

static double aces(double c[3], int ch)
{ /* the RRT + ODT fit with three.js's input scale 1/0.6 and AP1 matrices (rows) */
    static const double in[3][3] = {{0.59719, 0.35458, 0.04823}, {0.07600, 0.90834, 0.01566},
                                    {0.02840, 0.13383, 0.83777}};
    static const double out[3][3] = {{1.60475, -0.53108, -0.07367}, {-0.10208, 1.10813, -0.00605},
                                     {-0.00327, -0.07276, 1.07602}};
    double a[3], f[3];
    for (int r = 0; r < 3; r++)
        a[r] = (in[r][0] * c[0] + in[r][1] * c[1] + in[r][2] * c[2]) / 0.6;
    for (int r = 0; r < 3; r++)
        f[r] = (a[r] * (a[r] + 0.0245786) - 0.000090537) / (a[r] * (0.983729 * a[r] + 0.4329510) + 0.238081);
    double v = out[ch][0] * f[0] + out[ch][1] * f[1] + out[ch][2] * f[2];
    return fmin(fmax(v, 0), 1);
}

/* The shader's curves (probe: value ramp 0..8, green at half) against the published
 * formulas computed here in double, then the sRGB encoding: within 2e-4 (float32
 * arithmetic; pow in the encoding). */
Test(env, tone_curves_match_their_published_formulas)
{
    for (int b = 0; b < 2; b++) {
        btf_gl *gl = fx_gl_open(backends[b]);
        const btf_gl_api *f = btf_gl_fn(gl);
        btf_shader_program *p = fx_gl_build(gl, "tone_probe");
        const int w = 257;
        btf_gl_target *t = NULL;
        btf_error err = {{0}};
        cr_assert_eq(btf_gl_target_create(gl, w, 1, BTF_GL_RGBA32F, 1, &t, &err), BTF_OK, "%s", err.msg);
        static float got[257 * 4];
        for (int op = 0; op < 3; op++) {
            btf_gl_target_bind(gl, t);
            f->UseProgram(p->id);
            f->Uniform1i(f->GetUniformLocation(p->id, "u_probe_op"), op);
            f->Uniform1f(f->GetUniformLocation(p->id, "u_probe_max"), 8.0f);
            f->Uniform1i(f->GetUniformLocation(p->id, "u_probe_width"), w);
            btf_gl_draw_fullscreen(gl);
            cr_assert_eq(btf_gl_target_read(gl, t, 0, got, &err), BTF_OK, "%s", err.msg);
            for (int x = 0; x < w; x++) {
                double v = 8.0 * x / (w - 1), c[3] = {v, 0.5 * v, v};
                for (int ch = 0; ch < 3; ch++) {
                    double m = op == 0 ? c[ch] : op == 1 ? neutral(c, ch) : aces(c, ch);
                    double want = btf_color_srgb_encode(fmin(fmax(m, 0), 1));
                    cr_assert(fabs(got[x * 4 + ch] - want) < 2e-4, "backend %d op %d value %g c%d: %g, formula %g", b,
                              op, v, ch, (double)got[x * 4 + ch], want);
                }
            }
        }
        btf_gl_target_free(gl, t);
        btf_shader_program_free(gl, p);
        btf_gl_free(gl);
    }
}

/* ---------------------------------------------------------------- the light sum */

/* The surface at pixel (px, py): uv (after the geometry's repeats), frame columns
 * t, b, n and the unit direction to the eye; 0 where the ray misses or grazes an
 * edge or the sphere's seam and poles. */
static int cast(const fx_cam *c, btf_render_geometry g, const btf_render_camera *rc, int px, int py, fx_surface *h)
{
    double d[3], p[3];
    fx_cam_ray(c, px, py, RW, RH, d);
    double dl = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; k < 3; k++)
        d[k] /= dl;
    if (g == BTF_RENDER_PLANE) {
        if (!(d[2] < -1e-9))
            return 0;
        double s = -c->eye[2] / d[2];
        for (int k = 0; k < 3; k++)
            p[k] = c->eye[k] + s * d[k];
        if (fabs(p[0]) > 0.97 || fabs(p[1]) > 0.97)
            return 0;
        h->uv[0] = (p[0] + 1) / 2, h->uv[1] = (1 - p[1]) / 2;
        const double t[3] = {1, 0, 0}, b[3] = {0, 1, 0}, n[3] = {0, 0, 1};
        memcpy(h->t, t, sizeof t), memcpy(h->b, b, sizeof b), memcpy(h->n, n, sizeof n);
    } else {
        double od = d[0] * c->eye[0] + d[1] * c->eye[1] + d[2] * c->eye[2];
        double ee = c->eye[0] * c->eye[0] + c->eye[1] * c->eye[1] + c->eye[2] * c->eye[2];
        double disc = od * od - (ee - 1.0);
        if (disc < 0.05) /* misses, or within a few pixels of the silhouette */
            return 0;
        double s = -od - sqrt(disc);
        for (int k = 0; k < 3; k++)
            p[k] = c->eye[k] + s * d[k];
        double lon = atan2(p[1], p[0]) * 180 / M_PI, colat = acos(fmax(-1, fmin(1, p[2]))) * 180 / M_PI;
        if (colat < 12 || colat > 168 || fabs(lon - 90) < 6)
            return 0;
        double u = fmod((lon - 90) / 360 + 2.0, 1.0);
        h->uv[0] = u, h->uv[1] = colat / 180;
        memcpy(h->n, p, sizeof p);
        double sl = sin(lon * M_PI / 180), cl = cos(lon * M_PI / 180);
        h->t[0] = -sl, h->t[1] = cl, h->t[2] = 0;
        h->b[0] = h->n[1] * h->t[2] - h->n[2] * h->t[1]; /* n x t: towards decreasing v (north) */
        h->b[1] = h->n[2] * h->t[0] - h->n[0] * h->t[2];
        h->b[2] = h->n[0] * h->t[1] - h->n[1] * h->t[0];
    }
    h->uv[0] *= rc->uv_scale[0], h->uv[1] *= rc->uv_scale[1];
    double vl = 0;
    for (int k = 0; k < 3; k++)
        h->v[k] = c->eye[k] - p[k], vl += h->v[k] * h->v[k];
    for (int k = 0; k < 3; k++)
        h->v[k] /= sqrt(vl);
    double tx = h->uv[0] * TW, ty = h->uv[1] * TW;
    if (fabs(tx - floor(tx) - 0.5) < 0.02 || fabs(ty - floor(ty) - 0.5) < 0.02)
        return 0; /* a texel centre line: bilinear taps switch there, GPU and CPU uv may differ */
    return 1;
}

/* Tone mapping none with exposure 1: the screen value is the encoded, clamped sum. */
static double screen(double lin) { return btf_color_srgb_encode(fmin(fmax(lin, 0), 1)); }

/* Errors of one render against the sums, over its covered pixels. */
typedef struct env_stats {
    int n;
    double worst_l2, sq_l2, sq_exact, sq_true; /* GPU vs L2 sum (max, squares); vs exact; exact vs true */
    char worst[128];
} env_stats;

static void check_setting(const btf_package *p, const char *pkg, btf_render_geometry g, const btf_env *e, double rot,
                          const char *what, env_stats *st)
{
    btf_render_params rp = btf_render_defaults(g);
    rp.width = RW, rp.height = RH;
    rp.env = e, rp.env_rotation = (float)rot, rp.no_point_light = 1;
    rp.tone_mapping = BTF_TONE_NONE; /* the sums on the screen scale, no curve */
    rp.exposure = 0.5f;              /* keeps the sums below 1 (no clamping) */
    btf_render_camera rc;
    btf_render_camera_make(&rp, &rc);
    fx_cam c = fx_cam_make(&rp);
    btf_env_quad q;
    btf_env_quadratic(e, rot, &q);
    fx_env_sum es = fx_env_sum_make(p);
    static float out[2][RW * RH * 4];
    for (int b = 0; b < 2; b++) {
        btf_gl *gl = fx_gl_open(backends[b]);
        btf_renderer *r = NULL;
        btf_gl_target *t = NULL;
        btf_error err = {{0}};
        cr_assert_eq(btf_renderer_create(gl, p, pkg, 0, &r, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(btf_gl_target_create(gl, RW, RH, BTF_GL_RGBA32F, 1, &t, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_OK, "%s: %s", what, err.msg);
        cr_assert_eq(btf_gl_target_read(gl, t, 0, out[b], &err), BTF_OK, "%s", err.msg);
        btf_gl_target_free(gl, t);
        btf_renderer_free(r);
        btf_gl_free(gl);
    }
    for (int py = 0; py < RH; py++)
        for (int px = 0; px < RW; px++) {
            fx_surface h;
            if (!cast(&c, g, &rc, px, py, &h))
                continue;
            fx_light_sums s;
            fx_env_sums(&es, p, e, rot, &q, rc.wrap, &h, &s);
            st->n++;
            for (int ch = 0; ch < 3; ch++) {
                double l2 = screen(0.5 * s.l2[ch]), ex = screen(0.5 * s.exact[ch]), tr = screen(0.5 * s.true_srgb[ch]);
                st->sq_true += (ex - tr) * (ex - tr);
                for (int b = 0; b < 2; b++) {
                    double gpu = out[b][(py * RW + px) * 4 + ch];
                    st->worst_l2 = fmax(st->worst_l2, fabs(gpu - l2));
                    st->sq_l2 += (gpu - l2) * (gpu - l2) / 2;
                    st->sq_exact += (gpu - ex) * (gpu - ex) / 2;
                    if (fabs(gpu - l2) >= st->worst_l2) /* where the worst pixel is, for the message */
                        snprintf(st->worst, sizeof st->worst, "backend %d pixel (%d,%d) c%d: GPU %.5f, L2 sum %.5f", b,
                                 px, py, ch, gpu, l2);
                }
            }
        }
    fx_env_sum_free(&es);
}

/* Plane and sphere, the studio and the coloured sky, two rotations, a linear and an
 * sRGB package, both backends: each covered pixel within 4e-3 (screen scale, about
 * one 8-bit step) of the light sum of the environment's quadratic computed here (the
 * GPU decodes 16-bit requantised textures and tabled directions in float32; the
 * sphere's mesh normal is within 0.1 degree of the exact one). The truncation to
 * order 2 (GPU against the exact light sum) is measured and printed: RMSE 0.006 to
 * 0.021 (1.5 to 5 8-bit steps) on these settings, bounded by 0.04 here (a regression
 * bound for these smooth environments, not a promise for sharp ones;
 * doc/performance.md, "Environment light", has the numbers). */
Test(env, render_equals_the_light_sum, .timeout = 300)
{
    char tmp[256], lin[300], srgb[300], sky_path[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    make_package(tmp, "lin", 1, lin, sizeof lin);
    make_package(tmp, "srgb", 0, srgb, sizeof srgb);
    snprintf(sky_path, sizeof sky_path, "%s/sky.hdr", tmp);
    fx_write_sky(sky_path, 64, 32);
    btf_env *envs[2] = {NULL, NULL};
    btf_error err = {{0}};
    cr_assert_eq(btf_env_load("studio", &envs[0], &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_env_load(sky_path, &envs[1], &err), BTF_OK, "%s", err.msg);
    const char *pkgs[2] = {lin, srgb};
    for (int k = 0; k < 2; k++) {
        btf_package *p = fx_package(pkgs[k], NULL, 0);
        cr_assert_eq(p->linear, 1 - k);
        for (int g = 0; g < 2; g++)
            for (int ei = 0; ei < 2; ei++)
                for (int ri = 0; ri < 2; ri++) {
                    env_stats st = {0};
                    char what[128];
                    snprintf(what, sizeof what, "%s %s %s rot %d", k ? "srgb" : "linear", g ? "sphere" : "plane",
                             ei ? "sky" : "studio", ri * 75);
                    check_setting(p, pkgs[k], g ? BTF_RENDER_SPHERE : BTF_RENDER_PLANE, envs[ei], ri * 75.0, what, &st);
                    cr_assert_gt(st.n, 200, "%s: %d pixels checked", what, st.n);
                    double rl2 = sqrt(st.sq_l2 / (3.0 * st.n)), rex = sqrt(st.sq_exact / (3.0 * st.n)),
                           rtr = sqrt(st.sq_true / (3.0 * st.n));
                    cr_log_info("%s: %d px; GPU vs L2 sum rmse %.5f max %.5f; vs exact sum (order-2 truncation) rmse "
                                "%.5f; sRGB sum of encoded values vs true sum rmse %.5f",
                                what, st.n, rl2, st.worst_l2, rex, k ? rtr : 0.0);
                    cr_assert_lt(st.worst_l2, 4e-3, "%s: %s", what, st.worst);
                    cr_assert_lt(rex, 0.04, "%s: order-2 truncation rmse %.4f", what, rex);
                }
        btf_package_free(p);
    }
    btf_env_free(envs[0]);
    btf_env_free(envs[1]);
    fx_rmtree(tmp);
}

/* Hostile environment files get clear errors: missing, not an image, a header
 * claiming more than the largest side, negative values. */
Test(env, bad_environment_files_are_refused)
{
    char tmp[256], path[300];
    cr_assert(fx_tmpdir(tmp, sizeof tmp));
    btf_env *e = NULL;
    btf_error err = {{0}};
    snprintf(path, sizeof path, "%s/none.hdr", tmp);
    cr_assert_neq(btf_env_load(path, &e, &err), BTF_OK);
    cr_assert_null(e);
    snprintf(path, sizeof path, "%s/huge.hdr", tmp);
    FILE *f = fopen(path, "wb");
    fprintf(f, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n");
    fwrite("\x80\x80\x80\x80", 1, 4, f);
    fclose(f);
    cr_assert_neq(btf_env_load(path, &e, &err), BTF_OK);
    cr_assert(strstr(err.msg, "huge.hdr"), "%s", err.msg);
    snprintf(path, sizeof path, "%s/short.hdr", tmp);
    f = fopen(path, "wb");
    fprintf(f, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8 +X 8\n");
    fwrite("\x80\x80\x80\x81", 1, 4, f);
    fclose(f);
    cr_assert_neq(btf_env_load(path, &e, &err), BTF_OK, "a truncated file was read");
    cr_assert(strstr(err.msg, "short.hdr"), "%s", err.msg);
    fx_rmtree(tmp);
}
