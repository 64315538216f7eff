/* fixtures.h - the fixtures every Criterion suite shares (prefix fx_; fixtures.c).
 *
 * The suites live in one folder per room they test (tests/codec, tests/gen,
 * tests/gl, tests/eval, tests/tools, tests/server) and link into one binary,
 * build/run_tests. The fixtures that make something (a direction set, a material,
 * a package, a file) fail the calling test with the library's message when they
 * cannot (Criterion's cr_assert), so a test never goes on with a half-made input.
 *
 *     btf_dirset d = fx_dirs11();
 *     btf *m = fx_gen(BTF_GEN_KNIT, 8, &d, BTF_U8);
 *     char dir[256];
 *     cr_assert(fx_tmpdir(dir, sizeof dir));
 */
#ifndef BTF_TEST_FIXTURES_H
#define BTF_TEST_FIXTURES_H

/* The headers nearly every suite uses. */
#include <criterion/criterion.h>
#include <dirent.h>
#include <errno.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf.h"
#include "btf_fs.h"
#include "btf_gen.h"
#include "btf_gl.h"
#include "btf_lod.h"
#include "btf_package.h"
#include "btf_shader.h"

/* ------------------------------------------------------------ files and folders */

/* Path under ../shared (BTF_SHARED, exported by the Makefile) into buf; 1 if it exists. */
int fx_shared_path(char *buf, size_t n, const char *rel);

/* Fresh empty temporary directory (mkdtemp, /tmp/btftest-XXXXXX) into buf; 1 on success. */
int fx_tmpdir(char *buf, size_t n);

/* Entries of dir whose names do not start with '.'; 0 when dir cannot be opened. */
int fx_count_files(const char *dir);

/* 1 if dir_a/name and dir_b/name both exist and hold the same bytes. */
int fx_same_file(const char *dir_a, const char *dir_b, const char *name);

/* Removes path and, for a directory, everything under it (no symlinks followed).
 * 0 on success or when path does not exist, -1 otherwise. */
int fx_rmtree(const char *path);

/* Writes n bytes to path (created or truncated); the test fails if it cannot
 * open the file or write every byte. */
void fx_write(const char *path, const void *data, size_t n);

/* fx_write of the string text, without its terminating NUL. */
void fx_write_text(const char *path, const char *text);

/* fx_write / fx_write_text of dir/name. */
void fx_put(const char *dir, const char *name, const void *data, size_t n);
void fx_put_text(const char *dir, const char *name, const char *text);

/* The whole file, with a NUL after its bytes (n: their count, when not NULL);
 * NULL when path cannot be opened (a short read fails the test). The caller frees it. */
char *fx_read(const char *path, size_t *n);

/* ------------------------------------------------------------ direction sets */

/* The set of the n rings r (btf_dirset_make); the test fails if they are refused. */
btf_dirset fx_rings(const btf_ring *r, int n);

/* fx_rings of the rings listed: FX_RINGS({0, 1, 0}, {45, 6, 0}). */
#define FX_RINGS(...) \
    fx_rings((const btf_ring[]){__VA_ARGS__}, (int)(sizeof((const btf_ring[]){__VA_ARGS__}) / sizeof(btf_ring)))

/* 7 directions: the pole and 6 at 45 degrees (the default of fx_gen and fx_material). */
btf_dirset fx_dirs7(void);
/* 11 directions: the pole, 4 at 30 degrees, 6 at 60 degrees (offset 15). */
btf_dirset fx_dirs11(void);
/* 19 directions: the pole, 6 at 30 degrees, 12 at 60 degrees (offset 15): rings of
 * different counts and offsets, and 60..90 beyond the outer ring (the GL suites),
 * while compression stays fast. */
btf_dirset fx_dirs19(void);

/* Unit vector at theta, phi (degrees) in the local frame (z = the normal). */
void fx_dir(double theta_deg, double phi_deg, double v[3]);
/* fx_dir rounded to float. */
void fx_dirf(double theta_deg, double phi_deg, float v[3]);

/* ------------------------------------------------------------ materials and packages */

/* Generated material KIND (its default parameters) at size x size texels, lights =
 * views = d (NULL: fx_dirs7), stored as st; the caller frees it (btf_free). */
btf *fx_gen(btf_gen_kind kind, int size, const btf_dirset *d, btf_storage st);

/* fx_gen at 8 bits with lights = views = the n rings given (NULL: fx_dirs7). */
btf *fx_material(btf_gen_kind kind, int size, const btf_ring *rings, int n);

/* A copy of b with storage st, sample by sample through btf_get/btf_set (BTF_U8
 * rounds as an 8-bit store does); the caller frees it. */
btf *fx_convert(const btf *b, btf_storage st);

/* btf_package_read of dir (or dir/sub when sub is not NULL), its first n_chunks
 * chunks (0: all); the test fails if it is refused. */
btf_package *fx_package(const char *dir, const char *sub, int n_chunks);

/* What fx_levels builds: a generated material on lights = views = dirs. */
typedef struct {
    btf_gen_kind kind;
    int size;               /* size x size texels */
    btf_storage storage;
    const btf_dirset *dirs;
    int k, components;      /* btf_pca_options */
    int bits;               /* btf_package_options (0: the default) */
    int levels;             /* btf_lod_options */
} fx_levels_spec;

/* A fresh temporary directory into dir with DIR/v1, the material of s compressed
 * (btf_package_compress, version 1), and DIR/v2, btf_lod_build of v1 with s->levels
 * levels (its stats into st when not NULL). */
void fx_levels(char *dir, size_t n, const fx_levels_spec *s, btf_lod_stats *st);

/* ------------------------------------------------------------ pseudo-random numbers */

/* Each test keeps its own state (seeded where the test starts), so a sequence does
 * not depend on which tests ran before it. */

/* Marsaglia's xorshift32 (13, 17, 5): the next state, stored in *s. */
uint32_t fx_xorshift32(uint32_t *s);
/* The LCG of the C standard's example rand (1103515245, 12345): steps *s, returns *s >> 16. */
uint32_t fx_lcg(uint32_t *s);
/* The LCG of Numerical Recipes (1664525, 1013904223): the next state, stored in *s. */
uint32_t fx_lcg_nr(uint32_t *s);
/* The top 24 bits of x as a number in [0, 1): (x >> 8) / 2^24 (exact in float too). */
double fx_unit(uint32_t x);

/* ------------------------------------------------------------ clock */

/* Milliseconds of the codec's monotonic clock (btf_seconds), for deadlines and durations. */
long long fx_now_ms(void);

/* ------------------------------------------------------------ GL (shaders/host) */

/* Context on backend b; the test fails with the backend's message if it cannot start. */
btf_gl *fx_gl_open(btf_gl_backend b);

/* Program `program` of shaders/manifest.json; the test fails with the numbered-source report. */
btf_shader_program *fx_gl_build(btf_gl *gl, const char *program);

/* ------------------------------------------------------------ the documented camera */

/* shaders/README.md "Scene conventions", restated apart from btf_render's matrices:
 * eye = target + dist * dir(theta, phi), forward = -dir, up0 = (-cos t cos p,
 * -cos t sin p, sin t), right = normalize(forward x up0), up = right x forward,
 * aspect = width / height, tan(fovy/2) = tan(fov/2) / min(aspect, 1). Plain value. */
typedef struct fx_cam {
    double eye[3], fwd[3], right[3], up[3], th, aspect;
} fx_cam;

struct btf_render_params;
fx_cam fx_cam_make(const struct btf_render_params *p);
/* Direction (not unit) of the ray through the centre of pixel (px, py) of a w x h
 * image, py = 0 the bottom row (GL order). */
void fx_cam_ray(const fx_cam *c, int px, int py, int w, int h, double d[3]);

/* ------------------------------------------------------------ environment light sums */

/* doc/lighting.md restated apart from the shader: the light sum at one surface point
 * over the measured light cells, in its frame. Made by fx_env_sum_make for a package's
 * light set, freed by fx_env_sum_free. */
typedef struct fx_env_sum {
    int n_lights;
    int *cell; /* BTF_ENV_SAMPLES: the light each hemisphere sample belongs to (nearest) */
} fx_env_sum;

/* A surface point: uv (as the decoder takes it), frame columns t, b, n (world, unit)
 * and the unit direction to the eye (world). Plain value. */
typedef struct fx_surface {
    double uv[2], t[3], b[3], n[3], v[3];
} fx_surface;

/* The sums at a point (doc/lighting.md 1): exact (the environment's mean radiance
 * over each cell), and with the environment replaced by its quadratic q (what the
 * shader computes), each as the shader combines a package's values (sRGB-encoded
 * package: the sum of encoded values, then decoded); true_srgb: each decoded value
 * made linear before it is weighted (the true sum of an sRGB package). Plain value. */
typedef struct fx_light_sums {
    double exact[3], l2[3], true_srgb[3];
} fx_light_sums;

struct btf_env;
struct btf_env_quad;
fx_env_sum fx_env_sum_make(const btf_package *p);
void fx_env_sum_free(fx_env_sum *s);
/* The quadratic of q at unit world direction d, channel c. */
double fx_quad_eval(const struct btf_env_quad *q, int c, const double d[3]);
/* A coloured environment (a blue sky brightening to the zenith, a warm sun, a green
 * floor): its radiance at unit world direction d, channel c; and the function as a
 * flat (not run-length) Radiance file of w x h, written byte by byte. */
double fx_sky(const double d[3], int c);
void fx_write_sky(const char *path, int w, int h);
void fx_env_sums(const fx_env_sum *s, const btf_package *p, const struct btf_env *e, double rot,
                 const struct btf_env_quad *q, int wrap, const fx_surface *at, fx_light_sums *out);

#endif
