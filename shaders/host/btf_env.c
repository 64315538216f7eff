/* btf_env.c - environment images, their order-2 quadratic and the light cells
 * (doc/lighting.md sections 1.1, 2 and 3). */
#include "btf_env.h"
#include "btf_image.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BTF_ENV_PI 3.14159265358979323846

static void btf__env_dir(double theta_deg, double phi_deg, double v[3])
{
    double t = theta_deg * BTF_ENV_PI / 180.0, p = phi_deg * BTF_ENV_PI / 180.0;
    v[0] = sin(t) * cos(p), v[1] = sin(t) * sin(p), v[2] = cos(t);
}

static double btf__env_lobe(const double d[3], double theta, double phi, double radius_deg)
{
    double k[3], c = cos(radius_deg * BTF_ENV_PI / 180.0);
    btf__env_dir(theta, phi, k);
    double t = (d[0] * k[0] + d[1] * k[1] + d[2] * k[2] - c) / (1.0 - c);
    return t > 0.0 ? t * t : 0.0;
}

double btf_env_studio_radiance(const double d[3])
{
    return 0.25 + 0.15 * d[2] + 6.0 * btf__env_lobe(d, 35, -60, 20) + 2.0 * btf__env_lobe(d, 60, 130, 30) +
           3.0 * btf__env_lobe(d, 80, 180, 12);
}

/* World direction of the centre of pixel (i, j). */
static void btf__env_pixel_dir(const btf_env *e, int i, int j, double d[3])
{
    double theta = BTF_ENV_PI * (j + 0.5) / e->height, phi = BTF_ENV_PI - 2.0 * BTF_ENV_PI * (i + 0.5) / e->width;
    d[0] = sin(theta) * cos(phi), d[1] = sin(theta) * sin(phi), d[2] = cos(theta);
}

static btf_result btf__env_alloc(int w, int h, btf_env **out, btf_error *err)
{
    btf_env *e = calloc(1, sizeof *e);
    float *rgb = malloc((size_t)w * h * 3 * sizeof(float));
    if (!e || !rgb) {
        free(e), free(rgb);
        return btf_fail(err, BTF_ERR_NOMEM, "environment: out of memory");
    }
    e->width = w, e->height = h, e->rgb = rgb;
    *out = e;
    return BTF_OK;
}

btf_result btf_env_studio(btf_env **out, btf_error *err)
{
    btf_result r = btf__env_alloc(BTF_ENV_STUDIO_W, BTF_ENV_STUDIO_H, out, err);
    for (int j = 0; r == BTF_OK && j < BTF_ENV_STUDIO_H; j++)
        for (int i = 0; i < BTF_ENV_STUDIO_W; i++) {
            double d[3];
            btf__env_pixel_dir(*out, i, j, d);
            float v = (float)btf_env_studio_radiance(d);
            float *p = (*out)->rgb + ((size_t)j * BTF_ENV_STUDIO_W + i) * 3;
            p[0] = p[1] = p[2] = v;
        }
    return r;
}

btf_result btf_env_load(const char *path, btf_env **out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "environment: NULL argument");
    *out = NULL;
    if (!strcmp(path, "studio"))
        return btf_env_studio(out, err);
    int w = 0, h = 0;
    float *rgb = NULL;
    btf_result r = btf_image_read_rgb_f32(path, BTF_ENV_MAX_W, BTF_ENV_MAX_H, &w, &h, &rgb, err);
    if (r != BTF_OK)
        return r;
    btf_env *e = calloc(1, sizeof *e);
    if (!e) {
        free(rgb);
        return btf_fail(err, BTF_ERR_NOMEM, "environment: out of memory");
    }
    e->width = w, e->height = h, e->rgb = rgb;
    *out = e;
    return BTF_OK;
}

void btf_env_free(btf_env *e)
{
    if (e)
        free(e->rgb), free(e);
}

void btf_env_radiance(const btf_env *e, double rot_deg, const double d[3], float rgb[3])
{
    double a = -rot_deg * BTF_ENV_PI / 180.0;
    double x = cos(a) * d[0] - sin(a) * d[1], y = sin(a) * d[0] + cos(a) * d[1], z = d[2];
    double len = sqrt(x * x + y * y + z * z);
    double theta = len > 0.0 ? acos(fmax(-1.0, fmin(1.0, z / len))) : 0.0, phi = atan2(y, x);
    int j = (int)floor(theta / BTF_ENV_PI * e->height);
    double u = (BTF_ENV_PI - phi) / (2.0 * BTF_ENV_PI); /* 0..1 */
    int i = (int)floor(u * e->width);
    j = j < 0 ? 0 : j >= e->height ? e->height - 1 : j;
    i = ((i % e->width) + e->width) % e->width;
    memcpy(rgb, e->rgb + ((size_t)j * e->width + i) * 3, 3 * sizeof(float));
}

/* The nine real spherical harmonics of order <= 2 at unit d. */
static void btf__env_sh(const double d[3], double y[9])
{
    double x = d[0], yy = d[1], z = d[2];
    y[0] = 0.282095;
    y[1] = 0.488603 * yy, y[2] = 0.488603 * z, y[3] = 0.488603 * x;
    y[4] = 1.092548 * x * yy, y[5] = 1.092548 * yy * z, y[6] = 0.315392 * (3.0 * z * z - 1.0);
    y[7] = 1.092548 * x * z, y[8] = 0.546274 * (x * x - yy * yy);
}

/* Coefficients e[9][3] as the quadratic of one channel (doc/lighting.md 3). */
static void btf__env_to_quad(const double e[9], float *c0, float a[3], float q[9])
{
    *c0 = (float)(0.282095 * e[0] - 0.315392 * e[6]);
    a[0] = (float)(0.488603 * e[3]), a[1] = (float)(0.488603 * e[1]), a[2] = (float)(0.488603 * e[2]);
    double xy = 0.5 * 1.092548 * e[4], yz = 0.5 * 1.092548 * e[5], xz = 0.5 * 1.092548 * e[7];
    double xx = 0.546274 * e[8], yy = -0.546274 * e[8], zz = 3.0 * 0.315392 * e[6];
    const double m[9] = {xx, xy, xz, xy, yy, yz, xz, yz, zz}; /* symmetric: column- = row-major */
    for (int k = 0; k < 9; k++)
        q[k] = (float)m[k];
}

void btf_env_quadratic(const btf_env *e, double rot_deg, btf_env_quad *out)
{
    double sh[3][9] = {{0}};
    double rot = rot_deg * BTF_ENV_PI / 180.0, cr = cos(rot), sr = sin(rot);
    for (int j = 0; j < e->height; j++) {
        double t0 = BTF_ENV_PI * j / e->height, t1 = BTF_ENV_PI * (j + 1) / e->height;
        double dw = 2.0 * BTF_ENV_PI / e->width * (cos(t0) - cos(t1));
        for (int i = 0; i < e->width; i++) {
            double d[3], r[3], y[9];
            btf__env_pixel_dir(e, i, j, d);
            r[0] = cr * d[0] - sr * d[1], r[1] = sr * d[0] + cr * d[1], r[2] = d[2]; /* turned: Rz(rot) d */
            btf__env_sh(r, y);
            const float *p = e->rgb + ((size_t)j * e->width + i) * 3;
            for (int c = 0; c < 3; c++)
                for (int k = 0; k < 9; k++)
                    sh[c][k] += p[c] * y[k] * dw;
        }
    }
    for (int c = 0; c < 3; c++) {
        float a[3];
        btf__env_to_quad(sh[c], &out->c0[c], a, out->q + 9 * c);
        memcpy(out->a + 3 * c, a, sizeof a);
    }
}

void btf_env_sample(int s, double v[3])
{
    int b = s / BTF_ENV_AZIMUTHS, a = s % BTF_ENV_AZIMUTHS;
    double z = 1.0 - (b + 0.5) / BTF_ENV_BANDS, phi = 2.0 * BTF_ENV_PI * (a + 0.5) / BTF_ENV_AZIMUTHS;
    double r = sqrt(fmax(0.0, 1.0 - z * z));
    v[0] = r * cos(phi), v[1] = r * sin(phi), v[2] = z;
}

int btf_env_nearest(const float (*dirs)[3], int n, const double v[3])
{
    int best = 0;
    double bd = -2.0;
    for (int i = 0; i < n; i++) {
        double d = dirs[i][0] * v[0] + dirs[i][1] * v[1] + dirs[i][2] * v[2];
        if (d > bd)
            bd = d, best = i;
    }
    return best;
}

btf_result btf_env_cells(const btf_dirset *lights, double *m, btf_error *err)
{
    int n = lights ? lights->n_dirs : 0;
    if (n < 1 || !m)
        return btf_fail(err, BTF_ERR_ARG, "environment cells: no light directions");
    float(*dirs)[3] = malloc((size_t)n * sizeof *dirs);
    if (!dirs)
        return btf_fail(err, BTF_ERR_NOMEM, "environment cells: out of memory");
    for (int i = 0; i < n; i++)
        btf_dirset_vector(lights, i, dirs[i]);
    memset(m, 0, (size_t)n * BTF_ENV_FUNCS * sizeof *m);
    const double dw = 2.0 * BTF_ENV_PI / BTF_ENV_SAMPLES;
    for (int s = 0; s < BTF_ENV_SAMPLES; s++) {
        double v[3];
        btf_env_sample(s, v);
        double *row = m + (size_t)btf_env_nearest((const float(*)[3])dirs, n, v) * BTF_ENV_FUNCS;
        const double f[BTF_ENV_FUNCS] = {1.0, v[0], v[1], v[2], v[0] * v[0], v[1] * v[1], v[0] * v[1], v[0] * v[2], v[1] * v[2]};
        for (int k = 0; k < BTF_ENV_FUNCS; k++)
            row[k] += f[k] * dw;
    }
    free(dirs);
    return BTF_OK;
}
