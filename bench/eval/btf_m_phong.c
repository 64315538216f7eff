/* btf_m_phong.c - "phong": lit texture, per texel
 *     linear = a + kd max(l.z,0) + ks (e+8)/8 max(n.h,0)^e max(l.z,0)
 * per colour channel (a, kd, ks >= 0), e from a fixed grid shared by the channels.
 * For each grid exponent the three coefficients are a non-negative least-squares fit
 * over every measured (view, light) pair (linear light); the exponent with the
 * smallest residual over RGB is kept. The normal equations' matrix depends only on
 * the directions, so a texel costs one pass over its samples. */
#include "btf_method.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const float btf__phong_exp[] = {1, 2, 4, 8, 16, 32, 64, 128, 256, 512};
#define BTF__NE ((int)(sizeof btf__phong_exp / sizeof btf__phong_exp[0]))
#define BTF__PHONG_FLOATS 10 /* per texel: e, a[3], kd[3], ks[3] */

/* Phong model data: width*height records of 10 floats; owned by its btf_model. */
typedef struct btf__phong {
    float *p;
} btf__phong;

/* Specular basis value for unit l, v (view already clamped to the horizon). */
static float btf__phong_spec(const float l[3], const float v[3], float e)
{
    float lz = l[2] > 0.0f ? l[2] : 0.0f;
    float h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    float n2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
    if (!(n2 > 1e-12f) || lz == 0.0f)
        return 0.0f;
    float hz = h[2] / sqrtf(n2);
    if (!(hz > 0.0f))
        return 0.0f;
    return (e + 8.0f) / 8.0f * powf(hz > 1.0f ? 1.0f : hz, e) * lz;
}

/* Per pair: lz and the specular basis for every grid exponent (N x (1 + NE)). */
static float *btf__phong_basis(const btf *src, int *n_pairs)
{
    int V = src->views.n_dirs, L = src->lights.n_dirs, N = V * L;
    float *B = malloc(sizeof(float) * (size_t)N * (1 + BTF__NE));
    if (!B)
        return NULL;
    for (int v = 0; v < V; v++)
        for (int l = 0; l < L; l++) {
            float lv[3], vv[3], lu[3], vu[3];
            btf_dirset_vector(&src->lights, l, lv);
            btf_dirset_vector(&src->views, v, vv);
            btf__unit(lv, lu);
            btf__unit_view(vv, vu);
            float *row = B + (size_t)(v * L + l) * (1 + BTF__NE);
            row[0] = lu[2] > 0.0f ? lu[2] : 0.0f;
            for (int e = 0; e < BTF__NE; e++)
                row[1 + e] = btf__phong_spec(lu, vu, btf__phong_exp[e]);
        }
    *n_pairs = N;
    return B;
}

/* Texel-independent normal matrices G_e (3x3 each) of the basis [1, lz, s_e]. */
static void btf__phong_gram(const float *B, int N, double *G)
{
    memset(G, 0, sizeof(double) * 9 * BTF__NE);
    for (int i = 0; i < N; i++) {
        const float *row = B + (size_t)i * (1 + BTF__NE);
        for (int e = 0; e < BTF__NE; e++) {
            double b[3] = {1.0, row[0], row[1 + e]};
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    G[e * 9 + r * 3 + c] += b[r] * b[c];
        }
    }
}

/* acc per texel and channel: [sum y, sum lz y, sum s_e y (NE), sum y^2, max y]. */
#define BTF__ACC (4 + BTF__NE)
/* A lobe may peak at most 4x the texel's brightest linear sample (+0.05): a narrow
 * lobe fitted between measured directions cannot flash at unmeasured ones. */
#define BTF__PEAK 4.0
static btf_result btf__phong_accumulate(const btf *src, const float *B, double *acc, btf_error *err)
{
    int V = src->views.n_dirs, L = src->lights.n_dirs;
    size_t T = (size_t)src->width * src->height;
    float *img = malloc(sizeof(float) * btf_image_samples(src));
    if (!img)
        return btf_fail(err, BTF_ERR_NOMEM, "phong: cannot allocate an image");
    for (int v = 0; v < V; v++)
        for (int l = 0; l < L; l++) {
            btf__image_linear(src, v, l, img);
            const float *row = B + (size_t)(v * L + l) * (1 + BTF__NE);
            for (size_t t = 0; t < T * 3; t++) {
                double y = img[t], *a = acc + t * BTF__ACC;
                a[0] += y;
                a[1] += row[0] * y;
                for (int e = 0; e < BTF__NE; e++)
                    a[2 + e] += row[1 + e] * y;
                a[2 + BTF__NE] += y * y;
                a[3 + BTF__NE] = y > a[3 + BTF__NE] ? y : a[3 + BTF__NE];
            }
        }
    free(img);
    return BTF_OK;
}

/* Best exponent and coefficients of one texel from its accumulators (3 channels);
 * an exponent whose lobe would peak too high is skipped (the ambient + Lambert fit,
 * ks = 0, is always allowed). */
static void btf__phong_texel(const double *G, const double *acc, float *out)
{
    double best = INFINITY;
    memset(out, 0, sizeof(float) * BTF__PHONG_FLOATS);
    out[0] = btf__phong_exp[0];
    for (int e = 0; e < BTF__NE; e++) {
        double sse = 0.0, x[3][3], norm = (btf__phong_exp[e] + 8.0) / 8.0;
        for (int c = 0; c < 3; c++) {
            const double *a = acc + c * BTF__ACC;
            double g[3] = {a[0], a[1], a[2 + e]};
            double q = btf__nnls(3, G + e * 9, g, a[2 + BTF__NE], x[c]);
            if (!(x[c][2] * norm <= BTF__PEAK * a[3 + BTF__NE] + 0.05)) {
                double G2[4] = {G[e * 9], G[e * 9 + 1], G[e * 9 + 3], G[e * 9 + 4]};
                q = btf__nnls(2, G2, g, a[2 + BTF__NE], x[c]);
                x[c][2] = 0.0;
            }
            sse += q;
        }
        if (sse < best) {
            best = sse;
            out[0] = btf__phong_exp[e];
            for (int c = 0; c < 3; c++)
                for (int j = 0; j < 3; j++)
                    out[1 + j * 3 + c] = (float)x[c][j];
        }
    }
}

static void btf__phong_free(void *impl)
{
    btf__phong *p = impl;
    if (p)
        free(p->p);
    free(p);
}

static btf_result btf__phong_encode(const btf *src, btf_model *m, btf_error *err)
{
    size_t T = (size_t)src->width * src->height;
    int N = 0;
    btf__phong *ph = calloc(1, sizeof *ph);
    float *B = btf__phong_basis(src, &N);
    double *acc = calloc(T * 3 * BTF__ACC, sizeof(double));
    double G[9 * BTF__NE];
    if (ph)
        ph->p = malloc(sizeof(float) * T * BTF__PHONG_FLOATS);
    btf_result r = BTF_OK;
    if (!ph || !ph->p || !B || !acc)
        r = btf_fail(err, BTF_ERR_NOMEM, "phong: cannot allocate fit buffers for %zu texels", T);
    if (r == BTF_OK)
        r = btf__phong_accumulate(src, B, acc, err);
    if (r == BTF_OK) {
        btf__phong_gram(B, N, G);
        for (size_t t = 0; t < T; t++)
            btf__phong_texel(G, acc + t * 3 * BTF__ACC, ph->p + t * BTF__PHONG_FLOATS);
    }
    free(B);
    free(acc);
    if (r != BTF_OK) {
        btf__phong_free(ph);
        return r;
    }
    m->impl = ph;
    return BTF_OK;
}

static void btf__phong_decode(const btf_model *m, int x, int y, const float light[3], const float view[3],
                              float rgb[3])
{
    const btf__phong *ph = m->impl;
    const float *p = ph->p + ((size_t)y * m->width + x) * BTF__PHONG_FLOATS;
    float l[3], v[3];
    btf__unit(light, l);
    btf__unit_view(view, v);
    float lz = l[2] > 0.0f ? l[2] : 0.0f, s = btf__phong_spec(l, v, p[0]);
    for (int c = 0; c < 3; c++)
        rgb[c] = btf__linear_to_srgb(p[1 + c] + p[4 + c] * lz + p[7 + c] * s);
}

static size_t btf__phong_bytes(const btf_model *m)
{
    return (size_t)m->width * m->height * BTF__PHONG_FLOATS * sizeof(float);
}

static void btf__phong_cost(const btf_model *m, btf_method_cost *out)
{
    (void)m;
    out->fetches = BTF__PHONG_FLOATS;
    out->flops = 60; /* normalise 2 vectors, half vector, pow, 3 x (2 mad), 3 x sRGB encode */
}

btf_result btf_phong_get(const btf_model *m, int x, int y, btf_phong_texel *out, btf_error *err)
{
    if (!m || !out || m->method != &btf_method_phong)
        return btf_fail(err, BTF_ERR_ARG, "phong_get: not a phong model");
    if (x < 0 || y < 0 || x >= m->width || y >= m->height)
        return btf_fail(err, BTF_ERR_RANGE, "phong_get: texel (%d, %d) outside %d x %d", x, y, m->width, m->height);
    const float *p = ((const btf__phong *)m->impl)->p + ((size_t)y * m->width + x) * BTF__PHONG_FLOATS;
    out->exponent = p[0];
    for (int c = 0; c < 3; c++) {
        out->ambient[c] = p[1 + c];
        out->diffuse[c] = p[4 + c];
        out->spec[c] = p[7 + c];
    }
    return BTF_OK;
}

const btf_method btf_method_phong = {
    "phong", "lit texture: ambient + Lambert + Blinn-Phong per texel, NNLS over an exponent grid", 0,
    btf__phong_encode, btf__phong_decode, btf__phong_bytes, btf__phong_cost, btf__phong_free,
};
