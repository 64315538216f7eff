/* fixtures.c - the fixtures every Criterion suite shares (see fixtures.h). */
#include "fixtures.h"

#include "btf_render.h"
#include "btf_env.h"
#include "btf_decode.h"
#include "btf_color.h"

#include <criterion/criterion.h>
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "btf_common.h"
#include "btf_fs.h"
#include "btf_pca.h"

/* ------------------------------------------------------------ files and folders */

int fx_shared_path(char *buf, size_t n, const char *rel)
{
    const char *root = getenv("BTF_SHARED");
    snprintf(buf, n, "%s/%s", root ? root : "../shared", rel);
    struct stat st;
    return stat(buf, &st) == 0;
}

int fx_tmpdir(char *buf, size_t n)
{
    snprintf(buf, n, "/tmp/btftest-XXXXXX");
    return mkdtemp(buf) != NULL;
}

int fx_count_files(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += e->d_name[0] != '.';
    if (d)
        closedir(d);
    return n;
}

int fx_same_file(const char *dir_a, const char *dir_b, const char *name)
{
    char pa[1024], pb[1024];
    snprintf(pa, sizeof pa, "%s/%s", dir_a, name);
    snprintf(pb, sizeof pb, "%s/%s", dir_b, name);
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    int same = fa && fb;
    for (int ca = 0; same && ca != EOF;) {
        ca = fgetc(fa);
        same = ca == fgetc(fb);
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

int fx_rmtree(const char *path)
{
    return btf_fs_rmtree(path, NULL) == BTF_OK ? 0 : -1;
}

void fx_write(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    cr_assert_not_null(f, "cannot write %s", path);
    cr_assert_eq(fwrite(data, 1, n, f), n, "cannot write %s", path);
    cr_assert_eq(fclose(f), 0, "cannot write %s", path);
}

void fx_write_text(const char *path, const char *text)
{
    fx_write(path, text, strlen(text));
}

void fx_put(const char *dir, const char *name, const void *data, size_t n)
{
    char path[4400];
    cr_assert_lt((size_t)snprintf(path, sizeof path, "%s/%s", dir, name), sizeof path, "path too long: %s/%s", dir,
                 name);
    fx_write(path, data, n);
}

void fx_put_text(const char *dir, const char *name, const char *text)
{
    fx_put(dir, name, text, strlen(text));
}

char *fx_read(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *b = malloc(len > 0 ? (size_t)len + 1 : 1);
    cr_assert_not_null(b);
    size_t got = len > 0 ? fread(b, 1, (size_t)len, f) : 0;
    cr_assert_eq(got, len > 0 ? (size_t)len : 0, "%s: short read", path);
    b[got] = 0;
    fclose(f);
    if (n)
        *n = got;
    return b;
}

/* ------------------------------------------------------------ direction sets */

btf_dirset fx_rings(const btf_ring *r, int n)
{
    btf_dirset d;
    btf_error err = {{0}};
    cr_assert_eq(btf_dirset_make(r, n, &d, &err), BTF_OK, "%s", err.msg);
    return d;
}

btf_dirset fx_dirs7(void)
{
    return FX_RINGS({0.0f, 1, 0.0f}, {45.0f, 6, 0.0f});
}

btf_dirset fx_dirs11(void)
{
    return FX_RINGS({0.0f, 1, 0.0f}, {30.0f, 4, 0.0f}, {60.0f, 6, 15.0f});
}

btf_dirset fx_dirs19(void)
{
    return FX_RINGS({0.0f, 1, 0.0f}, {30.0f, 6, 0.0f}, {60.0f, 12, 15.0f});
}

void fx_dir(double theta_deg, double phi_deg, double v[3])
{
    double t = theta_deg * M_PI / 180.0, p = phi_deg * M_PI / 180.0;
    v[0] = sin(t) * cos(p);
    v[1] = sin(t) * sin(p);
    v[2] = cos(t);
}

void fx_dirf(double theta_deg, double phi_deg, float v[3])
{
    double d[3];
    fx_dir(theta_deg, phi_deg, d);
    v[0] = (float)d[0], v[1] = (float)d[1], v[2] = (float)d[2];
}

/* ------------------------------------------------------------ materials and packages */

btf *fx_convert(const btf *b, btf_storage st)
{
    btf *c = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_create(b->width, b->height, &b->lights, &b->views, st, &c, &err), BTF_OK, "%s", err.msg);
    for (int v = 0; v < b->views.n_dirs; v++)
        for (int l = 0; l < b->lights.n_dirs; l++)
            for (int y = 0; y < b->height; y++)
                for (int x = 0; x < b->width; x++)
                    for (int k = 0; k < 3; k++)
                        btf_set(c, v, l, x, y, k, btf_get(b, v, l, x, y, k));
    return c;
}

btf *fx_gen(btf_gen_kind kind, int size, const btf_dirset *d, btf_storage st)
{
    btf_dirset dflt;
    if (!d) {
        dflt = fx_dirs7();
        d = &dflt;
    }
    btf_gen_params gp = btf_gen_defaults(kind);
    btf *b = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_gen_create(&gp, size, size, d, d, st, &b, &err), BTF_OK, "%s", err.msg);
    return b;
}

btf *fx_material(btf_gen_kind kind, int size, const btf_ring *rings, int n)
{
    btf_dirset d = rings ? fx_rings(rings, n) : fx_dirs7();
    return fx_gen(kind, size, &d, BTF_U8);
}

btf_package *fx_package(const char *dir, const char *sub, int n_chunks)
{
    char path[4400];
    if (sub)
        snprintf(path, sizeof path, "%s/%s", dir, sub);
    else
        snprintf(path, sizeof path, "%s", dir);
    btf_package *p = NULL;
    btf_error err = {{0}};
    cr_assert_eq(btf_package_read(path, n_chunks, &p, &err), BTF_OK, "%s", err.msg);
    return p;
}

void fx_levels(char *dir, size_t n, const fx_levels_spec *s, btf_lod_stats *st)
{
    cr_assert(fx_tmpdir(dir, n));
    btf *src = fx_gen(s->kind, s->size, s->dirs, s->storage);
    btf_pca_options po = {0};
    po.k = s->k, po.components = s->components;
    btf_package_options ko = {0};
    ko.bits = s->bits;
    char v1[4400], v2[4400];
    snprintf(v1, sizeof v1, "%s/v1", dir);
    snprintf(v2, sizeof v2, "%s/v2", dir);
    btf_error err = {{0}};
    cr_assert_eq(btf_package_compress(src, &po, &ko, v1, NULL, &err), BTF_OK, "%s", err.msg);
    btf_free(src);
    btf_lod_options lo = {0};
    lo.levels = s->levels;
    cr_assert_eq(btf_lod_build(v1, v2, &lo, st, &err), BTF_OK, "%s", err.msg);
}

/* ------------------------------------------------------------ pseudo-random numbers */

uint32_t fx_xorshift32(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return *s = x;
}

uint32_t fx_lcg(uint32_t *s)
{
    *s = *s * 1103515245u + 12345u;
    return *s >> 16;
}

uint32_t fx_lcg_nr(uint32_t *s)
{
    return *s = *s * 1664525u + 1013904223u;
}

double fx_unit(uint32_t x)
{
    return (double)(x >> 8) / 16777216.0;
}

/* ------------------------------------------------------------ clock */

long long fx_now_ms(void)
{
    return (long long)(btf_seconds() * 1000.0);
}

/* ------------------------------------------------------------ GL (shaders/host) */

btf_gl *fx_gl_open(btf_gl_backend b)
{
    btf_gl *gl = NULL;
    btf_error err = {{0}};
    btf_gl_desc d = {.backend = b};
    cr_assert_eq(btf_gl_create(&d, &gl, &err), BTF_OK, "%s: %s", btf_gl_backend_name(b), err.msg);
    return gl;
}

btf_shader_program *fx_gl_build(btf_gl *gl, const char *program)
{
    btf_shader_desc d = {.program = program};
    btf_shader_program *p = NULL;
    char *report = NULL;
    btf_error err = {{0}};
    btf_result r = btf_shader_build(gl, &d, &p, &report, &err);
    cr_assert_eq(r, BTF_OK, "%s\n%s", err.msg, report ? report : "");
    free(report);
    return p;
}

/* ------------------------------------------------------------ the documented camera */

fx_cam fx_cam_make(const btf_render_params *p)
{
    fx_cam c;
    double d[3], t = p->camera_theta * M_PI / 180, ph = p->camera_phi * M_PI / 180;
    fx_dir(p->camera_theta, p->camera_phi, d);
    double up0[3] = {-cos(t) * cos(ph), -cos(t) * sin(ph), sin(t)};
    for (int i = 0; i < 3; i++)
        c.eye[i] = p->target[i] + p->camera_dist * d[i], c.fwd[i] = -d[i];
    c.right[0] = c.fwd[1] * up0[2] - c.fwd[2] * up0[1];
    c.right[1] = c.fwd[2] * up0[0] - c.fwd[0] * up0[2];
    c.right[2] = c.fwd[0] * up0[1] - c.fwd[1] * up0[0];
    double n = sqrt(c.right[0] * c.right[0] + c.right[1] * c.right[1] + c.right[2] * c.right[2]);
    for (int i = 0; i < 3; i++)
        c.right[i] /= n;
    c.up[0] = c.right[1] * c.fwd[2] - c.right[2] * c.fwd[1];
    c.up[1] = c.right[2] * c.fwd[0] - c.right[0] * c.fwd[2];
    c.up[2] = c.right[0] * c.fwd[1] - c.right[1] * c.fwd[0];
    c.aspect = (double)p->width / p->height;
    c.th = tan(p->fov_deg * M_PI / 360) / (c.aspect < 1 ? c.aspect : 1);
    return c;
}

void fx_cam_ray(const fx_cam *c, int px, int py, int w, int h, double d[3])
{
    double nx = 2.0 * (px + 0.5) / w - 1, ny = 2.0 * (py + 0.5) / h - 1;
    for (int i = 0; i < 3; i++)
        d[i] = c->fwd[i] + c->right[i] * nx * c->th * c->aspect + c->up[i] * ny * c->th;
}

/* ------------------------------------------------------------ environment light sums */

fx_env_sum fx_env_sum_make(const btf_package *p)
{
    fx_env_sum s = {p->lights.n_dirs, malloc(BTF_ENV_SAMPLES * sizeof(int))};
    float(*dirs)[3] = malloc((size_t)s.n_lights * sizeof *dirs);
    cr_assert(s.cell && dirs);
    for (int i = 0; i < s.n_lights; i++)
        btf_dirset_vector(&p->lights, i, dirs[i]);
    for (int k = 0; k < BTF_ENV_SAMPLES; k++) {
        double v[3];
        btf_env_sample(k, v);
        s.cell[k] = btf_env_nearest((const float(*)[3])dirs, s.n_lights, v);
    }
    free(dirs);
    return s;
}

void fx_env_sum_free(fx_env_sum *s) { free(s->cell), s->cell = NULL; }

double fx_quad_eval(const btf_env_quad *q, int c, const double d[3])
{
    double v = q->c0[c];
    for (int i = 0; i < 3; i++) {
        v += q->a[3 * c + i] * d[i];
        for (int k = 0; k < 3; k++)
            v += q->q[9 * c + 3 * k + i] * d[i] * d[k];
    }
    return v;
}

void fx_env_sums(const fx_env_sum *s, const btf_package *p, const btf_env *e, double rot, const btf_env_quad *q,
                 int wrap, const fx_surface *at, fx_light_sums *out)
{
    int L = s->n_lights;
    double *mean = calloc((size_t)L * 7, sizeof(double)); /* per light: exact RGB, quadratic RGB, count */
    cr_assert(mean);
    for (int k = 0; k < BTF_ENV_SAMPLES; k++) {
        double v[3], d[3];
        btf_env_sample(k, v);
        for (int i = 0; i < 3; i++)
            d[i] = v[0] * at->t[i] + v[1] * at->b[i] + v[2] * at->n[i];
        float rgb[3];
        btf_env_radiance(e, rot, d, rgb);
        double *m = mean + (size_t)s->cell[k] * 7;
        for (int c = 0; c < 3; c++)
            m[c] += rgb[c], m[3 + c] += fx_quad_eval(q, c, d);
        m[6] += 1;
    }
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_BILINEAR;
    o.wrap = wrap;
    float view[3] = {0, 0, 0};
    for (int i = 0; i < 3; i++) {
        view[0] += (float)(at->v[i] * at->t[i]);
        view[1] += (float)(at->v[i] * at->b[i]);
        view[2] += (float)(at->v[i] * at->n[i]);
    }
    memset(out, 0, sizeof *out);
    for (int i = 0; i < L; i++) {
        const double *m = mean + (size_t)i * 7, dw = m[6] * 2 * M_PI / BTF_ENV_SAMPLES;
        if (m[6] == 0)
            continue;
        float l[3], rgb[3];
        btf_dirset_vector(&p->lights, i, l);
        btf_decode(p, (float)at->uv[0], (float)at->uv[1], l, view, &o, rgb);
        for (int c = 0; c < 3; c++) {
            out->exact[c] += rgb[c] * m[c] / m[6] * dw / M_PI;
            out->l2[c] += rgb[c] * m[3 + c] / m[6] * dw / M_PI;
            out->true_srgb[c] += btf_color_srgb_decode(fmax(rgb[c], 0)) * m[c] / m[6] * dw / M_PI;
        }
    }
    for (int c = 0; c < 3 && !p->linear; c++) { /* as the shader: the sum of encoded values, decoded */
        out->exact[c] = btf_color_srgb_decode(fmax(out->exact[c], 0));
        out->l2[c] = btf_color_srgb_decode(fmax(out->l2[c], 0));
    }
    free(mean);
}

/* A coloured environment: a blue sky brightening to the zenith, a warm sun and a
 * green floor, as a flat (not run-length) Radiance file written here byte by byte. */
double fx_sky(const double d[3], int c)
{
    static const double sun[3] = {0.5, -0.5, 0.7071067811865476};
    double s = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2], lobe = s > 0.9 ? (s - 0.9) * 10.0 : 0.0;
    static const double base[3] = {0.3, 0.45, 0.9}, floor_[3] = {0.1, 0.35, 0.08}, warm[3] = {9.0, 6.0, 3.0};
    double b = d[2] > 0 ? base[c] * (0.6 + 0.4 * d[2]) : floor_[c];
    return b + warm[c] * lobe * lobe;
}

static void fx__rgbe(const float v[3], unsigned char out[4])
{
    float m = fmaxf(v[0], fmaxf(v[1], v[2]));
    if (m < 1e-32f) {
        memset(out, 0, 4);
        return;
    }
    int e;
    float f = frexpf(m, &e) * 256.0f / m;
    for (int c = 0; c < 3; c++)
        out[c] = (unsigned char)(v[c] * f);
    out[3] = (unsigned char)(e + 128);
}

void fx_write_sky(const char *path, int w, int h)
{
    FILE *f = fopen(path, "wb");
    cr_assert(f, "cannot write %s", path);
    fprintf(f, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n", h, w);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            double th = M_PI * (j + 0.5) / h, ph = M_PI - 2 * M_PI * (i + 0.5) / w;
            double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
            float v[3] = {(float)fx_sky(d, 0), (float)fx_sky(d, 1), (float)fx_sky(d, 2)};
            unsigned char b[4];
            fx__rgbe(v, b);
            fwrite(b, 1, 4, f);
        }
    cr_assert_eq(fclose(f), 0);
}

