/* test_render.c - room gl (shaders/host), suite "render": `btf render` and its scene
 * module (shaders/host/btf_render.h).
 *
 * The main test renders a package of a generated material on a plane (float target)
 * and compares each pixel with the generator's ground truth at that pixel's texel,
 * local light and local view, found by a CPU ray cast that follows the documented
 * scene conventions (shaders/README.md), not btf_render's own matrices. */
#include <criterion/criterion.h>
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_cli.h"
#include "btf_gen.h"
#include "btf_image.h"
#include "btf_package.h"
#include "btf_render.h"
#include "fixtures.h"
#include "btf_decode.h"

#define TW 16 /* material side in texels */
#define TC 4  /* components */
#define RW 48 /* render size */
#define RH 40

static const btf_gl_backend backends[2] = {BTF_GL_EGL, BTF_GL_OSMESA};

/* ---------------------------------------------------------------- fixtures */

/* A package of a generated knit in a fresh temp dir (tmp), at pkg = tmp/knit. */
static void make_package(char *tmp, size_t n, char *pkg, size_t pn, btf_gen_params *gp)
{
    cr_assert(fx_tmpdir(tmp, n));
    snprintf(pkg, pn, "%s/knit", tmp);
    *gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf_dirset d = fx_dirs19();
    btf *m = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gen_create(gp, TW, TW, &d, &d, BTF_F32, &m, &err), BTF_OK, "%s", err.msg);
    btf_pca_options po = {0};
    po.k = 3;
    po.components = TC;
    btf_package_options ko = {0};
    ko.bits = 8;
    cr_assert_eq(btf_package_compress(m, &po, &ko, pkg, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(m);
}

/* Ray through pixel (px, py) (py = 0 the bottom row, GL order) hits the plane z = 0
 * at (x, y); 0 if it misses the square [-lim, lim]^2. */
static int ray_plane(const fx_cam *c, int px, int py, int w, int h, double lim, double hit[3])
{
    double d[3];
    fx_cam_ray(c, px, py, w, h, d);
    if (!(d[2] < -1e-9))
        return 0;
    double s = -c->eye[2] / d[2];
    for (int i = 0; i < 3; i++)
        hit[i] = c->eye[i] + s * d[i];
    return fabs(hit[0]) <= lim && fabs(hit[1]) <= lim;
}

/* ---------------------------------------------------------------- render vs ground truth */

/* Error terms gathered over the checked pixels of one render. */
typedef struct gt_stats {
    int n;
    double render_truth, pkg, interp, render_interp; /* sums of squares */
} gt_stats;

/* One setting: render (debug outputs), then per pixel inside the plane:
 *   R = GPU colour, G = btf_gen_model_eval at (texel, l, v),
 *   I = sum wl wv G(texel, li, vi) over btf_dirset_interp's 3 x 3 measured pairs,
 *   E = sum wl wv |P(vi, li, texel) - G(texel, li, vi)|, P = btf_package_value,
 * and asserts |R - I| <= E + tol and |R - G| <= E + |I - G| + tol (R - I is exactly the
 * weighted package error when the renderer decodes at the right texel and directions;
 * the second bound is its triangle inequality). tol = 1e-4 plus the GPU layout's
 * worst-case requantisation error (btf_gl_package_quant_error): the GPU decode agrees
 * with btf_decode within that (tests/gl/test_gl.c); the sums here are in double. */
static void check_setting(btf_gl *gl, btf_renderer *r, const btf_package *p, const btf_gen_model *gm,
                          btf_render_params rp, const char *what, gt_stats *st)
{
    btf_error err = {{0}};
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, rp.width, rp.height, BTF_GL_RGBA32F, 4, &t, &err), BTF_OK, "%s", err.msg);
    cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_OK, "%s: %s", what, err.msg);
    static float out[4][RW * RH * 4];
    for (int a = 0; a < 4; a++)
        cr_assert_eq(btf_gl_target_read(gl, t, a, out[a], &err), BTF_OK, "%s", err.msg);
    btf_gl_target_free(gl, t);
    fx_cam c = fx_cam_make(&rp);
    float l[3];
    double ld[3];
    fx_dir(rp.light_theta, rp.light_phi, ld);
    for (int i = 0; i < 3; i++)
        l[i] = (float)ld[i]; /* the plane's local frame is the world frame */
    double qw, qr;
    btf_gl_package_quant_error(btf_renderer_package(r), &qw, &qr);
    const double tol = 1e-4 + qw;
    int misses = 0;
    for (int py = 0; py < rp.height; py++)
        for (int px = 0; px < rp.width; px++) {
            size_t o = (size_t)(py * rp.width + px) * 4;
            double hit[3];
            if (!ray_plane(&c, px, py, rp.width, rp.height, 1.02, hit)) { /* clear of the edge: background */
                misses++;
                for (int k = 0; k < 3; k++)
                    cr_assert_eq(out[0][o + k], rp.background[k], "%s pixel (%d,%d) off the plane drawn", what, px,
                                 py);
                continue;
            }
            if (fabs(hit[0]) > 0.98 || fabs(hit[1]) > 0.98)
                continue; /* within a pixel of the edge */
            double u = (hit[0] + 1) / 2, v = (1 - hit[1]) / 2;
            /* conventions: the GPU decoded at the uv the documented camera gives (1e-4 =
             * 0.0016 texels; perspective-correct float interpolation is ~1e-6) */
            cr_assert(fabs(out[1][o] - u) < 1e-4 && fabs(out[1][o + 1] - v) < 1e-4,
                      "%s pixel (%d,%d): GPU uv %g %g, ray cast %g %g", what, px, py, (double)out[1][o],
                      (double)out[1][o + 1], u, v);
            double fx = u * TW, fy = v * TW;
            if (fabs(fx - floor(fx + 0.5)) < 0.005 || fabs(fy - floor(fy + 0.5)) < 0.005)
                continue; /* texel boundary: GPU and CPU uv may pick different texels */
            int x = (int)floor(fx), y = (int)floor(fy);
            float vw[3];
            double vn = 0;
            for (int k = 0; k < 3; k++)
                vn += (c.eye[k] - hit[k]) * (c.eye[k] - hit[k]);
            for (int k = 0; k < 3; k++)
                vw[k] = (float)((c.eye[k] - hit[k]) / sqrt(vn));
            float g[3], gi[3] = {0, 0, 0}, e[3] = {0, 0, 0};
            btf_gen_model_eval(gm, x, y, l, vw, g);
            btf_interp il = btf_dirset_interp_vec(&p->lights, l), iv = btf_dirset_interp_vec(&p->views, vw);
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) {
                    float w = iv.w[a] * il.w[b];
                    if (w == 0.0f)
                        continue;
                    float ldir[3], vdir[3], gm3[3], pk[3];
                    btf_dirset_vector(&p->lights, il.idx[b], ldir);
                    btf_dirset_vector(&p->views, iv.idx[a], vdir);
                    btf_gen_model_eval(gm, x, y, ldir, vdir, gm3);
                    btf_package_value(p, iv.idx[a], il.idx[b], x, y, 0, pk);
                    for (int k = 0; k < 3; k++) {
                        gi[k] += w * gm3[k];
                        e[k] += w * fabsf(pk[k] - gm3[k]);
                    }
                }
            for (int k = 0; k < 3; k++) {
                double R = out[0][o + k], G = g[k], I = gi[k], E = e[k];
                cr_assert(fabs(R - I) <= E + tol, "%s pixel (%d,%d) c%d: render %.5f, interpolated truth %.5f, "
                          "package error bound %.5f", what, px, py, k, R, I, E);
                cr_assert(fabs(R - G) <= E + fabs(I - G) + tol,
                          "%s pixel (%d,%d) c%d: render %.5f truth %.5f: more than package %.5f + interpolation %.5f",
                          what, px, py, k, R, G, E, fabs(I - G));
                st->render_truth += (R - G) * (R - G);
                st->render_interp += (R - I) * (R - I);
                st->pkg += E * E;
                st->interp += (I - G) * (I - G);
            }
            st->n++;
        }
    cr_assert_gt(misses, 0, "%s: the plane fills the view, background never checked", what);
}

static void check_ground_truth(btf_gl_backend b)
{
    char tmp[256], pkg[300];
    btf_gen_params gp;
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, &gp);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    btf_gen_model *gm = NULL;
    cr_assert_eq(btf_gen_model_create(&gp, TW, TW, &gm, &err), BTF_OK, "%s", err.msg);
    btf_gl *gl = fx_gl_open(b);
    btf_renderer *r = NULL;
    cr_assert_eq(btf_renderer_create(gl, p, pkg, 1, &r, &err), BTF_OK, "%s", err.msg);
    /* camera straight above / oblique / grazing-ish from another side / the default
     * camera in a portrait view (fov across its width); lights inside the measured
     * range (theta <= 60) so the horizon fade plays no part; sizes of RW x RH pixels */
    static const float set[5][8] = {{0, 0, 2.6f, 20, 40, 50, RW, RH},
                                    {35, -90, 3.0f, 45, -50, 40, RW, RH},
                                    {55, 120, 2.8f, 55, 200, 45, RW, RH},
                                    {20, 200, 2.4f, 0, 0, 60, RW, RH},
                                    {30, -90, 3.5f, 45, -50, 40, 30, 64}};
    gt_stats st = {0};
    for (int s = 0; s < 5; s++) {
        btf_render_params rp = btf_render_defaults(BTF_RENDER_PLANE);
        rp.width = (int)set[s][6];
        rp.height = (int)set[s][7];
        cr_assert_leq(rp.width * rp.height, RW * RH);
        rp.camera_theta = set[s][0];
        rp.camera_phi = set[s][1];
        rp.camera_dist = set[s][2];
        rp.light_theta = set[s][3];
        rp.light_phi = set[s][4];
        rp.fov_deg = set[s][5];
        rp.filter = 0;
        rp.horizon_fade = 0;
        rp.background[0] = 0.25f;
        char what[96];
        snprintf(what, sizeof what, "%s setting %d", btf_gl_backend_name(b), s);
        check_setting(gl, r, p, gm, rp, what, &st);
    }
    cr_assert_gt(st.n, 800, "only %d pixels checked", st.n);
    double n3 = 3.0 * st.n;
    cr_log_info("%s: %d pixels, RMS (0..255): render-truth %.3f, package %.3f, interpolation %.3f, render-interp %.3f",
                btf_gl_backend_name(b), st.n, 255 * sqrt(st.render_truth / n3), 255 * sqrt(st.pkg / n3),
                255 * sqrt(st.interp / n3), 255 * sqrt(st.render_interp / n3));
    /* not vacuous: both terms are present and the render is not closer to the truth
     * than the interpolated truth itself can explain */
    cr_assert_gt(st.pkg, 0.0);
    cr_assert_gt(st.interp, 0.0);
    /* aggregate form of the bound (Minkowski): RMS(render - truth) <= RMS(E) + RMS(I - G) */
    cr_assert_leq(sqrt(st.render_truth), sqrt(st.pkg) + sqrt(st.interp) + 1e-4 * sqrt(n3));
    btf_renderer_free(r);
    btf_gl_free(gl);
    btf_gen_model_free(gm);
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

Test(render, plane_vs_ground_truth_egl) { check_ground_truth(BTF_GL_EGL); }
Test(render, plane_vs_ground_truth_osmesa) { check_ground_truth(BTF_GL_OSMESA); }

/* ---------------------------------------------------------------- horizon fade */

/* A light beyond the outer measured ring (60 degrees) at 80 degrees: colour =
 * btf_decode * cos(80)/cos(60); below the horizon: black. CPU decode at the ray cast's
 * uv and directions (nearest filter, same tolerance as above). */
Test(render, horizon_fade_both_backends)
{
    char tmp[256], pkg[300];
    btf_gen_params gp;
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, &gp);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(pkg, 0, &p, &err), BTF_OK, "%s", err.msg);
    for (int bi = 0; bi < 2; bi++) {
        btf_gl *gl = fx_gl_open(backends[bi]);
        btf_renderer *r = NULL;
        cr_assert_eq(btf_renderer_create(gl, p, pkg, 0, &r, &err), BTF_OK, "%s", err.msg);
        static const float light_theta[2] = {80, 100};
        for (int s = 0; s < 2; s++) {
            btf_render_params rp = btf_render_defaults(BTF_RENDER_PLANE);
            rp.width = RW;
            rp.height = RH;
            rp.camera_theta = 10;
            rp.light_theta = light_theta[s];
            rp.light_phi = 30;
            rp.filter = 0;
            btf_gl_target *t = NULL;
            cr_assert_eq(btf_gl_target_create(gl, RW, RH, BTF_GL_RGBA32F, 1, &t, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_OK, "%s", err.msg);
            static float out[RW * RH * 4];
            cr_assert_eq(btf_gl_target_read(gl, t, 0, out, &err), BTF_OK, "%s", err.msg);
            btf_gl_target_free(gl, t);
            fx_cam c = fx_cam_make(&rp);
            double ld[3];
            fx_dir(rp.light_theta, rp.light_phi, ld);
            float l[3] = {(float)ld[0], (float)ld[1], (float)ld[2]};
            double fade = s == 0 ? cos(80 * M_PI / 180) / cos(60 * M_PI / 180) : 0.0;
            int checked = 0;
            for (int py = 0; py < RH; py++)
                for (int px = 0; px < RW; px++) {
                    double hit[3];
                    if (!ray_plane(&c, px, py, RW, RH, 0.98, hit))
                        continue;
                    double u = (hit[0] + 1) / 2, v = (1 - hit[1]) / 2, fx = u * TW, fy = v * TW;
                    if (fabs(fx - floor(fx + 0.5)) < 0.005 || fabs(fy - floor(fy + 0.5)) < 0.005)
                        continue;
                    float vw[3], rgb[3];
                    for (int k = 0; k < 3; k++)
                        vw[k] = (float)(c.eye[k] - hit[k]);
                    btf_decode_options o = {0};
                    btf_decode(p, (float)u, (float)v, l, vw, &o, rgb);
                    for (int k = 0; k < 3; k++) {
                        double want = rgb[k] * fade;
                        want = want < 0 ? 0 : want > 1 ? 1 : want;
                        cr_assert(fabs(out[(py * RW + px) * 4 + k] - want) <= 1e-4, "%s light %g pixel (%d,%d): %g vs %g",
                                  btf_gl_backend_name(backends[bi]), (double)light_theta[s], px, py,
                                  (double)out[(py * RW + px) * 4 + k], want);
                    }
                    checked++;
                }
            cr_assert_gt(checked, 200);
        }
        btf_renderer_free(r);
        btf_gl_free(gl);
    }
    btf_package_free(p);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* ---------------------------------------------------------------- default light */

/* A generated package, read, and a renderer of it on one backend; owned by one test,
 * from render_fixture_open to render_fixture_close. */
typedef struct render_fixture {
    char tmp[256], pkg[300];
    btf_gen_params gp;
    btf_package *p;
    btf_gl *gl;
    btf_renderer *r;
} render_fixture;

static void render_fixture_open(render_fixture *f, btf_gl_backend b)
{
    btf_error err = {{0}};
    make_package(f->tmp, sizeof f->tmp, f->pkg, sizeof f->pkg, &f->gp);
    f->p = NULL;
    cr_assert_eq(btf_package_read(f->pkg, 0, &f->p, &err), BTF_OK, "%s", err.msg);
    f->gl = fx_gl_open(b);
    f->r = NULL;
    cr_assert_eq(btf_renderer_create(f->gl, f->p, f->pkg, 0, &f->r, &err), BTF_OK, "%s", err.msg);
}

static void render_fixture_close(render_fixture *f)
{
    btf_renderer_free(f->r);
    btf_gl_free(f->gl);
    btf_package_free(f->p);
    cr_assert_eq(fx_rmtree(f->tmp), 0);
}

/* Fractions of the default scene's object pixels that are lit (a channel above
 * 10/255) for each geometry, under the default light or light[2] = (theta, phi): the
 * object is where two renders with different backgrounds agree. */
static void lit_fractions(btf_gl_backend b, const float *light, double lit[BTF_RENDER_GEOMETRY_COUNT])
{
    render_fixture f;
    render_fixture_open(&f, b);
    btf_gl *gl = f.gl;
    btf_renderer *r = f.r;
    btf_error err = {{0}};
    enum { W = 160, H = 120 };
    static uint8_t rgb[2][W * H * 3];
    static const float bgs[2][3] = {{0.12f, 0.12f, 0.12f}, {0.5f, 0.2f, 0.9f}};
    for (int g = 0; g < BTF_RENDER_GEOMETRY_COUNT; g++) {
        btf_render_params rp = btf_render_defaults((btf_render_geometry)g);
        rp.width = W, rp.height = H;
        if (light)
            rp.light_theta = light[0], rp.light_phi = light[1];
        for (int k = 0; k < 2; k++) {
            memcpy(rp.background, bgs[k], sizeof rp.background);
            btf_gl_target *t = NULL;
            cr_assert_eq(btf_gl_target_create(gl, W, H, BTF_GL_RGBA8, 1, &t, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_OK, "%s", err.msg);
            cr_assert_eq(btf_render_read_rgb8(gl, t, rgb[k], &err), BTF_OK, "%s", err.msg);
            btf_gl_target_free(gl, t);
        }
        int object = 0, on = 0;
        for (int i = 0; i < W * H; i++) {
            const uint8_t *a = &rgb[0][i * 3], *c = &rgb[1][i * 3];
            if (a[0] != c[0] || a[1] != c[1] || a[2] != c[2])
                continue;
            object++;
            on += a[0] > 10 || a[1] > 10 || a[2] > 10;
        }
        cr_assert_gt(object, W * H / 5, "%s: %d object pixels", btf_render_geometry_name(g), object);
        lit[g] = (double)on / object;
        cr_log_info("%s default %s, light (%g, %g): %d object pixels, %.1f%% lit", btf_gl_backend_name(b),
                    btf_render_geometry_name(g), (double)rp.light_theta, (double)rp.light_phi, object, 100 * lit[g]);
    }
    render_fixture_close(&f);
}

/* The default light faces the camera's side of each object: the sphere and the
 * cylinder are mostly lit (this package, outer light ring 60 degrees: sphere 96.6%,
 * cylinder 98.5%, plane 100%), not the crescent a light behind them leaves (the
 * default light turned 120 degrees about +z, (45, 70): 31% of the sphere). */
Test(render, default_light_lights_the_visible_object)
{
    double lit[BTF_RENDER_GEOMETRY_COUNT], behind[BTF_RENDER_GEOMETRY_COUNT];
    lit_fractions(BTF_GL_EGL, NULL, lit);
    cr_assert_geq(lit[BTF_RENDER_SPHERE], 0.92, "sphere %.3f lit", lit[BTF_RENDER_SPHERE]);
    cr_assert_geq(lit[BTF_RENDER_CYLINDER], 0.92, "cylinder %.3f lit", lit[BTF_RENDER_CYLINDER]);
    cr_assert_geq(lit[BTF_RENDER_PLANE], 0.98, "plane %.3f lit", lit[BTF_RENDER_PLANE]);
    static const float back[2] = {45, 70};
    lit_fractions(BTF_GL_EGL, back, behind); /* the measure tells a dark sphere */
    cr_assert_leq(behind[BTF_RENDER_SPHERE], 0.5, "sphere lit from behind: %.3f lit", behind[BTF_RENDER_SPHERE]);
}

/* ---------------------------------------------------------------- framing */

/* Points whose projections bound the object's: the plane's corners, the cylinder's two
 * rims (the object is inside their convex hull, and a perspective view keeps hulls),
 * the sphere at every degree. Returns the count written to pts (room for 65341). */
static int bounding_points(btf_render_geometry g, double (*pts)[3])
{
    int n = 0;
    if (g == BTF_RENDER_PLANE)
        for (int i = 0; i < 4; i++) {
            pts[n][0] = i & 1 ? 1 : -1, pts[n][1] = i & 2 ? 1 : -1, pts[n][2] = 0;
            n++;
        }
    else if (g == BTF_RENDER_SPHERE)
        for (int t = 0; t <= 180; t++)
            for (int p = 0; p < 360; p++) {
                fx_dir(t, p, pts[n]);
                n++;
            }
    else
        for (int e = -1; e <= 1; e += 2)
            for (int a = 0; a < 360; a++) {
                pts[n][0] = e, pts[n][1] = 2 / M_PI * cos(a * M_PI / 180), pts[n][2] = 2 / M_PI * sin(a * M_PI / 180);
                n++;
            }
    return n;
}

/* The default camera of each geometry frames it in portrait, square and landscape
 * views: the bounding points, projected here through btf_render_camera_make's
 * view_proj, stay inside clip space with a 5% margin on both axes, fill most of the
 * view's narrower side (the elongated cylinder, 2 x 1.27, less of a wide view's
 * height, as the fov there is the vertical one it always was) and sit near the centre
 * (the plane's near half is nearer: a little below). Before the fov spanned the
 * narrower side, the plane's near corners left a 390 x 600 view at x = +-1.74. */
Test(render, default_camera_frames_the_object_in_any_aspect)
{
    static double pts[181 * 360][3];
    static const int widths[6] = {300, 390, 450, 600, 800, 1067}; /* height 600: aspect 0.5 .. 16/9 */
    static const double min_fill[BTF_RENDER_GEOMETRY_COUNT] = {0.6, 0.6, 0.45};
    for (int g = 0; g < BTF_RENDER_GEOMETRY_COUNT; g++) {
        int n = bounding_points((btf_render_geometry)g, pts);
        for (int a = 0; a < 6; a++) {
            btf_render_params rp = btf_render_defaults((btf_render_geometry)g);
            rp.width = widths[a];
            rp.height = 600;
            btf_render_camera c;
            btf_render_camera_make(&rp, &c);
            double lo[2] = {1e9, 1e9}, hi[2] = {-1e9, -1e9};
            for (int i = 0; i < n; i++) {
                double clip[4];
                for (int r = 0; r < 4; r++)
                    clip[r] = c.view_proj[r] * pts[i][0] + c.view_proj[4 + r] * pts[i][1] +
                              c.view_proj[8 + r] * pts[i][2] + c.view_proj[12 + r];
                cr_assert_gt(clip[3], 0.0);
                for (int k = 0; k < 2; k++) {
                    double v = clip[k] / clip[3];
                    lo[k] = v < lo[k] ? v : lo[k];
                    hi[k] = v > hi[k] ? v : hi[k];
                }
            }
            const char *name = btf_render_geometry_name((btf_render_geometry)g);
            cr_log_info("%s %dx600: x %.3f..%.3f y %.3f..%.3f", name, rp.width, lo[0], hi[0], lo[1], hi[1]);
            for (int k = 0; k < 2; k++) {
                cr_assert(lo[k] >= -0.95 && hi[k] <= 0.95, "%s %dx600: axis %d from %.3f to %.3f, outside the view", name,
                          rp.width, k, lo[k], hi[k]);
                cr_assert(fabs(lo[k] + hi[k]) / 2 <= 0.12, "%s %dx600: axis %d centred at %.3f", name, rp.width, k,
                          (lo[k] + hi[k]) / 2);
            }
            int narrow = rp.width < rp.height ? 0 : 1;
            double fill = (hi[narrow] - lo[narrow]) / 2;
            cr_assert_geq(fill, min_fill[g], "%s %dx600: fills %.2f of the narrower side", name, rp.width, fill);
            /* the scale the client's footprint uses: pixels per unit along the view's
             * right axis at the origin, measured through the same matrix */
            double e = 1e-3, x = 0, w = 0;
            for (int k = 0; k < 3; k++) {
                x += c.view_proj[4 * k] * e * c.right[k];
                w += c.view_proj[4 * k + 3] * e * c.right[k];
            }
            x += c.view_proj[12], w += c.view_proj[15];
            double ppu = x / w * rp.width / 2 / e;
            cr_assert(fabs(ppu / btf_render_pixels_per_unit(&rp) - 1) < 1e-4, "%s %dx600: %g pixels per unit, %g measured",
                      name, rp.width, btf_render_pixels_per_unit(&rp), ppu);
        }
    }
}

/* ---------------------------------------------------------------- meshes */

/* Every geometry's frame follows the convention: unit normal; tangent unit, orthogonal
 * to the normal and along d(position)/du; cross(normal, tangent) along -d(position)/dv
 * (w = +1: local y towards image row 0). Derivatives by finite differences over the
 * grid, an independent check of the analytic frame. */
Test(render, mesh_frames_follow_convention)
{
    for (int g = 0; g < BTF_RENDER_GEOMETRY_COUNT; g++) {
        btf_render_mesh *m = NULL;
        btf_error err = {{0}};
        cr_assert_eq(btf_render_mesh_create((btf_render_geometry)g, 16, &m, &err), BTF_OK, "%s", err.msg);
        cr_assert_eq(m->n_indices % 3, 0);
        for (int i = 0; i < m->n_indices; i++)
            cr_assert_lt(m->indices[i], (unsigned)m->n_vertices);
        int checked = 0;
        for (int t = 0; t < m->n_indices; t += 3) {
            const float *a = &m->vertices[m->indices[t] * BTF_RENDER_VERTEX_FLOATS];
            const float *b = &m->vertices[m->indices[t + 1] * BTF_RENDER_VERTEX_FLOATS];
            const float *c = &m->vertices[m->indices[t + 2] * BTF_RENDER_VERTEX_FLOATS];
            /* solve dP = Pu du + Pv dv over the triangle's two edges */
            double e1[3], e2[3], du1 = b[10] - a[10], dv1 = b[11] - a[11], du2 = c[10] - a[10], dv2 = c[11] - a[11];
            double det = du1 * dv2 - du2 * dv1;
            if (fabs(det) < 1e-12)
                continue;
            double pu[3], pv[3], tn[3], tt[3], n2 = 0;
            for (int k = 0; k < 3; k++) {
                e1[k] = b[k] - a[k];
                e2[k] = c[k] - a[k];
                pu[k] = (e1[k] * dv2 - e2[k] * dv1) / det;
                pv[k] = (e2[k] * du1 - e1[k] * du2) / det;
                tn[k] = (a[3 + k] + b[3 + k] + c[3 + k]) / 3; /* face-average frame */
                tt[k] = (a[6 + k] + b[6 + k] + c[6 + k]) / 3;
                n2 += (double)a[3 + k] * a[3 + k];
            }
            cr_assert(fabs(n2 - 1) < 1e-5, "%s: normal not unit", btf_render_geometry_name(g));
            cr_assert_eq(a[9], 1.0f);
            double by[3] = {tn[1] * tt[2] - tn[2] * tt[1], tn[2] * tt[0] - tn[0] * tt[2], tn[0] * tt[1] - tn[1] * tt[0]};
            double dpu = 0, dpv = 0, lu = 0, lv = 0, nt = 0;
            for (int k = 0; k < 3; k++) {
                dpu += pu[k] * tt[k];
                dpv += -pv[k] * by[k];
                lu += pu[k] * pu[k];
                lv += pv[k] * pv[k];
                nt += a[3 + k] * a[6 + k];
            }
            cr_assert(fabs(nt) < 1e-5, "%s: tangent not orthogonal to the normal", btf_render_geometry_name(g));
            if (lu < 1e-12 || lv < 1e-12)
                continue; /* sphere pole rows */
            /* cosines close to 1 (coarse 16-segment grid: about 0.9 at worst) */
            cr_assert_gt(dpu / sqrt(lu), 0.9, "%s triangle %d: tangent not along dP/du", btf_render_geometry_name(g), t);
            cr_assert_gt(dpv / sqrt(lv), 0.9, "%s triangle %d: n x t not along -dP/dv", btf_render_geometry_name(g), t);
            checked++;
        }
        cr_assert_gt(checked, 1);
        btf_render_mesh_free(m);
    }
    btf_render_mesh *m = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_render_mesh_create((btf_render_geometry)7, 0, &m, &err), BTF_ERR_ARG);
    cr_assert_eq(btf_render_mesh_create(BTF_RENDER_SPHERE, 2, &m, &err), BTF_ERR_RANGE);
    cr_assert_null(m);
    btf_render_mesh_free(NULL);
}

Test(render, params_rejected)
{
    btf_error err = {{0}};
    btf_render_params p = btf_render_defaults(BTF_RENDER_SPHERE);
    cr_assert_eq(btf_render_check_params(&p, &err), BTF_OK, "%s", err.msg);
    btf_render_params bad[7];
    for (int i = 0; i < 7; i++)
        bad[i] = p;
    bad[0].width = 0;
    bad[1].camera_dist = -1;
    bad[2].fov_deg = 180;
    bad[3].background[1] = 2;
    bad[4].camera_theta = NAN;
    bad[5].repeat = 0;
    bad[6].geometry = (btf_render_geometry)9;
    for (int i = 0; i < 7; i++)
        cr_assert_neq(btf_render_check_params(&bad[i], &err), BTF_OK, "case %d accepted", i);
    cr_assert_str_eq(btf_render_geometry_name(BTF_RENDER_CYLINDER), "cylinder");
    cr_assert_eq(btf_render_geometry_from_name("sphere"), BTF_RENDER_SPHERE);
    cr_assert_eq(btf_render_geometry_from_name("cube"), -1);
}

/* ---------------------------------------------------------------- CLI */

static int run_cli(int n, const char **argv) { return cmd_render(n, (char **)argv); }

Test(render, cli_writes_png_and_checks_arguments)
{
    char tmp[256], pkg[300], out[400], out2[400];
    btf_gen_params gp;
    make_package(tmp, sizeof tmp, pkg, sizeof pkg, &gp);
    snprintf(out, sizeof out, "%s/a.png", tmp);
    snprintf(out2, sizeof out2, "%s/b.png", tmp);
    const char *ok[] = {"render", pkg, out, "--geometry", "sphere", "--size", "40x30", "--camera", "60,-90,3.5",
                        "--light", "30,10", "--background", "0.2,0.4,0.6", "--backend", "egl"};
    cr_assert_eq(run_cli(15, ok), 0);
    int w, h, ch;
    uint8_t *px = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_image_read_u8(out, &w, &h, &ch, &px, &err), BTF_OK, "%s", err.msg);
    cr_assert(w == 40 && h == 30 && ch == 3, "%dx%dx%d", w, h, ch);
    /* corner: background round(255 * (0.2, 0.4, 0.6)) +- 1; centre: the sphere */
    cr_assert(abs(px[0] - 51) <= 1 && abs(px[1] - 102) <= 1 && abs(px[2] - 153) <= 1, "%d %d %d", px[0], px[1],
              px[2]);
    const uint8_t *c = &px[(15 * 40 + 20) * 3];
    cr_assert(abs(c[0] - 51) + abs(c[1] - 102) + abs(c[2] - 153) > 6, "centre is background");
    /* the same scene on OSMesa: same image within one step */
    const char *ok2[] = {"render", pkg, out2, "--geometry", "sphere", "--size", "40x30", "--camera", "60,-90,3.5",
                         "--light", "30,10", "--background", "0.2,0.4,0.6", "--backend", "osmesa"};
    cr_assert_eq(run_cli(15, ok2), 0);
    uint8_t *px2 = NULL;
    cr_assert_eq(btf_image_read_u8(out2, &w, &h, &ch, &px2, &err), BTF_OK, "%s", err.msg);
    for (int i = 0; i < 40 * 30 * 3; i++)
        cr_assert(abs(px[i] - px2[i]) <= 1, "egl vs osmesa byte %d: %d vs %d", i, px[i], px2[i]);
    /* one chunk differs from all chunks */
    const char *one[] = {"render", pkg, out2, "--geometry", "sphere", "--size", "40x30", "--camera", "60,-90,3.5",
                         "--light", "30,10", "--background", "0.2,0.4,0.6", "--chunks", "1"};
    cr_assert_eq(run_cli(15, one), 0);
    free(px2);
    cr_assert_eq(btf_image_read_u8(out2, &w, &h, &ch, &px2, &err), BTF_OK, "%s", err.msg);
    int differ = 0;
    for (int i = 0; i < 40 * 30 * 3; i++)
        differ += abs(px[i] - px2[i]) > 2;
    cr_assert_gt(differ, 20, "--chunks 1 looks like all chunks");
    free(px);
    free(px2);

    /* usage errors: exit 2, nothing written */
    const char *bad[][4] = {
        {"--geometry", "cube", NULL}, {"--size", "0x5", NULL},    {"--size", "12y4", NULL},
        {"--camera", "a,b", NULL},    {"--camera", "1,2,3,4", NULL}, {"--fov", "0", NULL},
        {"--chunks", "0", NULL},      {"--backend", "vulkan", NULL}, {"--frobnicate", "1", NULL},
        {"--light", "30", NULL},      {"--background", "1,1,2", NULL}, {"--camera", "30,0,-2", NULL},
        {"--size", NULL},
    };
    char out3[400];
    snprintf(out3, sizeof out3, "%s/c.png", tmp);
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *argv[6] = {"render", pkg, out3, bad[i][0], bad[i][1]};
        int n = bad[i][1] ? 5 : 4;
        cr_assert_eq(run_cli(n, argv), 2, "case %zu (%s %s) not a usage error", i, bad[i][0],
                     bad[i][1] ? bad[i][1] : "");
    }
    const char *missing_out[] = {"render", pkg};
    cr_assert_eq(run_cli(2, missing_out), 2);
    const char *extra[] = {"render", pkg, out3, "extra"};
    cr_assert_eq(run_cli(4, extra), 2);
    struct stat st;
    cr_assert_neq(stat(out3, &st), 0, "a usage error wrote %s", out3);
    /* failures: exit 1 */
    char nopkg[400];
    snprintf(nopkg, sizeof nopkg, "%s/no-such-package", tmp);
    const char *missing[] = {"render", nopkg, out3};
    cr_assert_eq(run_cli(3, missing), 1);
    cr_assert_neq(stat(out3, &st), 0);
    const char *help[] = {"render", "--help"};
    cr_assert_eq(run_cli(2, help), 0);
    cr_assert_eq(fx_rmtree(tmp), 0);
}

/* A target of the wrong size and NULL arguments are errors, not crashes. */
Test(render, draw_bad_arguments)
{
    render_fixture f;
    render_fixture_open(&f, BTF_GL_EGL);
    btf_gl *gl = f.gl;
    btf_renderer *r = f.r;
    btf_error err = {{0}};
    btf_gl_target *t = NULL;
    cr_assert_eq(btf_gl_target_create(gl, 8, 8, BTF_GL_RGBA8, 1, &t, &err), BTF_OK, "%s", err.msg);
    btf_render_params rp = btf_render_defaults(BTF_RENDER_PLANE);
    cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_ERR_ARG);
    cr_assert(strstr(err.msg, "8x8"), "%s", err.msg);
    cr_assert_eq(btf_renderer_draw(r, NULL, t, &err), BTF_ERR_ARG);
    rp.width = rp.height = 8;
    cr_assert_eq(btf_renderer_draw(r, &rp, t, &err), BTF_OK, "%s", err.msg);
    uint8_t rgb[8 * 8 * 3];
    cr_assert_eq(btf_render_read_rgb8(gl, t, rgb, &err), BTF_OK, "%s", err.msg);
    btf_renderer *r2 = NULL;
    cr_assert_eq(btf_renderer_create(gl, NULL, f.pkg, 0, &r2, &err), BTF_ERR_ARG);
    cr_assert_null(r2);
    btf_gl_target_free(gl, t);
    btf_renderer_free(NULL);
    render_fixture_close(&f);
}
