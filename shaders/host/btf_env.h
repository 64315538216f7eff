/* btf_env.h - environment light (doc/lighting.md): an equirectangular radiance image
 * (a Radiance .hdr or the built-in studio), its order-2 quadratic for the shader, and
 * the cells of a package's light directions.
 *
 *     btf_env *e;
 *     btf_env_load("studio.hdr", &e, &err);          // or "studio": the built-in one
 *     btf_env_quad q; btf_env_quadratic(e, 30.0f, &q); // rotated 30 degrees about +z
 *     ...
 *     btf_env_free(e);
 */
#ifndef BTF_ENV_H
#define BTF_ENV_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Images larger than this are box-averaged down while read (doc/lighting.md 2). */
#define BTF_ENV_MAX_W 1024
#define BTF_ENV_MAX_H 512
/* The built-in studio's size. */
#define BTF_ENV_STUDIO_W 128
#define BTF_ENV_STUDIO_H 64
/* Hemisphere samples of the light cells (doc/lighting.md 1.1): bands x azimuths. */
#define BTF_ENV_BANDS 64
#define BTF_ENV_AZIMUTHS 128
#define BTF_ENV_SAMPLES (BTF_ENV_BANDS * BTF_ENV_AZIMUTHS)
/* Functions per cell: 1, x, y, z, xx, yy, xy, xz, yz. */
#define BTF_ENV_FUNCS 9

/* Linear radiance over directions; made by btf_env_load / btf_env_studio, freed by
 * btf_env_free; read-only in between. */
typedef struct btf_env {
    int width, height; /* row 0 up (+z); column i at phi = pi - 2 pi (i + 0.5) / width */
    float *rgb;        /* width * height * 3 (malloc'd) */
} btf_env;

/* The order-2 quadratic c0 + a.d + d^T Q d per channel (world); plain value. */
typedef struct btf_env_quad {
    float c0[3];
    float a[9];  /* column-major mat3: column ch = a of channel ch (u_env_a) */
    float q[27]; /* three column-major mat3, Q of channel 0, 1, 2 (u_env_q) */
} btf_env_quad;

/* path "studio": the built-in studio; else an image file (btf_image_read_rgb_f32). */
btf_result btf_env_load(const char *path, btf_env **out, btf_error *err);
btf_result btf_env_studio(btf_env **out, btf_error *err);
void btf_env_free(btf_env *e);
/* The studio's radiance (all channels equal) at unit world direction d. */
double btf_env_studio_radiance(const double d[3]);
/* Radiance of the pixel world direction d (any length) falls in, the environment
 * turned rot_deg about +z (L_rot(d) = L(Rz(-rot) d)). */
void btf_env_radiance(const btf_env *e, double rot_deg, const double d[3], float rgb[3]);
/* The quadratic of e's projection on the nine spherical harmonics of order <= 2,
 * turned rot_deg about +z. */
void btf_env_quadratic(const btf_env *e, double rot_deg, btf_env_quad *out);
/* Hemisphere sample s (0..BTF_ENV_SAMPLES-1), local frame, unit. */
void btf_env_sample(int s, double v[3]);
/* The nearest of n unit directions to v (largest dot product, a tie to the lower). */
int btf_env_nearest(const float (*dirs)[3], int n, const double v[3]);
/* M (n_lights * BTF_ENV_FUNCS, row i = light i): per light the solid angle times the
 * mean of each function over its cell. */
btf_result btf_env_cells(const btf_dirset *lights, double *m, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
