/* btf_method.c - the method interface: checked encode, dispatch, registry, and the
 * small numeric helpers the method implementations share. */
#include "btf_method.h"

#include "btf_color.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

float btf__srgb_to_linear(float v)
{
    return v > 0.0f ? (float)btf_color_srgb_decode(v) : 0.0f; /* also NaN -> 0 */
}

float btf__linear_to_srgb(float v)
{
    if (!(v > 0.0f))
        return 0.0f;
    return (float)btf_color_srgb_encode(v > 1e6f ? 1e6f : v);
}

void btf__unit(const float in[3], float out[3])
{
    float x = in[0], y = in[1], z = in[2];
    float n2 = x * x + y * y + z * z;
    if (!isfinite(n2) || !(n2 > 1e-30f)) {
        out[0] = out[1] = 0.0f;
        out[2] = 1.0f;
        return;
    }
    float s = 1.0f / sqrtf(n2);
    out[0] = x * s, out[1] = y * s, out[2] = z * s;
}

void btf__unit_view(const float in[3], float out[3])
{
    btf__unit(in, out);
    if (out[2] >= 0.0f)
        return;
    float r = sqrtf(out[0] * out[0] + out[1] * out[1]);
    if (!(r > 1e-6f)) {
        out[0] = out[1] = 0.0f;
        out[2] = 1.0f;
        return;
    }
    out[0] /= r, out[1] /= r, out[2] = 0.0f;
}

void btf__image_linear(const btf *src, int view, int light, float *dst)
{
    size_t n = btf_image_samples(src), base = btf_index(src, view, light, 0, 0, 0);
    if (src->storage == BTF_U8) {
        float lut[256];
        for (int i = 0; i < 256; i++)
            lut[i] = btf__srgb_to_linear((float)i / 255.0f);
        const uint8_t *d = (const uint8_t *)src->data + base;
        for (size_t i = 0; i < n; i++)
            dst[i] = lut[d[i]];
    } else {
        const float *d = (const float *)src->data + base;
        for (size_t i = 0; i < n; i++)
            dst[i] = btf__srgb_to_linear(d[i]);
    }
}

/* Solves the s x s system M z = r (row-major, overwritten) by Cholesky; 0 if not
 * positive definite. */
static int btf__chol_solve(int s, double *M, double *r)
{
    for (int j = 0; j < s; j++) {
        double d = M[j * s + j];
        for (int k = 0; k < j; k++)
            d -= M[j * s + k] * M[j * s + k];
        if (!(d > 0.0))
            return 0;
        d = sqrt(d);
        M[j * s + j] = d;
        for (int i = j + 1; i < s; i++) {
            double v = M[i * s + j];
            for (int k = 0; k < j; k++)
                v -= M[i * s + k] * M[j * s + k];
            M[i * s + j] = v / d;
        }
    }
    for (int i = 0; i < s; i++) { /* L y = r */
        double v = r[i];
        for (int k = 0; k < i; k++)
            v -= M[i * s + k] * r[k];
        r[i] = v / M[i * s + i];
    }
    for (int i = s - 1; i >= 0; i--) { /* L^T z = y */
        double v = r[i];
        for (int k = i + 1; k < s; k++)
            v -= M[k * s + i] * r[k];
        r[i] = v / M[i * s + i];
    }
    return 1;
}

/* Residual sum of squares of x from the normal equations. */
static double btf__rss(int p, const double *G, const double *g, double yy, const double *x)
{
    double q = yy;
    for (int i = 0; i < p; i++) {
        q -= 2.0 * g[i] * x[i];
        for (int j = 0; j < p; j++)
            q += x[i] * G[i * p + j] * x[j];
    }
    return q > 0.0 ? q : 0.0;
}

double btf__nnls(int p, const double *G, const double *g, double yy, double *x)
{
    double best = isfinite(yy) ? yy : 0.0, tr = 0.0;
    for (int i = 0; i < p; i++) {
        x[i] = 0.0;
        tr += G[i * p + i];
    }
    double ridge = 1e-12 * (tr / (p > 0 ? p : 1)) + 1e-300;
    for (unsigned mask = 1; mask < (1u << p); mask++) {
        int idx[6], s = 0;
        for (int i = 0; i < p; i++)
            if (mask & (1u << i))
                idx[s++] = i;
        double M[36], r[6], full[6] = {0};
        for (int a = 0; a < s; a++) {
            r[a] = g[idx[a]];
            for (int b = 0; b < s; b++)
                M[a * s + b] = G[idx[a] * p + idx[b]] + (a == b ? ridge : 0.0);
        }
        if (!btf__chol_solve(s, M, r))
            continue;
        int ok = 1;
        for (int a = 0; a < s; a++) {
            if (!isfinite(r[a]) || r[a] < 0.0)
                ok = 0;
            full[idx[a]] = r[a];
        }
        if (!ok)
            continue;
        double q = btf__rss(p, G, g, yy, full);
        if (q < best) {
            best = q;
            memcpy(x, full, sizeof(double) * (size_t)p);
        }
    }
    return best;
}

static double btf__now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Smallest and largest sample; BTF_ERR_NUMERIC names the first non-finite one. */
static btf_result btf__range(const btf *src, float *lo, float *hi, btf_error *err)
{
    btf_result r = btf_check_finite(src, err);
    if (r != BTF_OK)
        return r;
    float a = INFINITY, b = -INFINITY;
    for (size_t i = 0; i < src->count; i++) {
        float v = src->storage == BTF_U8 ? ((const uint8_t *)src->data)[i] / 255.0f : ((const float *)src->data)[i];
        a = v < a ? v : a;
        b = v > b ? v : b;
    }
    *lo = a, *hi = b;
    return BTF_OK;
}

btf_result btf_model_encode(const btf_method *method, const btf *src, const btf_method_params *params,
                            btf_model **out, btf_error *err)
{
    if (out)
        *out = NULL;
    if (!method || !src || !out)
        return btf_fail(err, BTF_ERR_ARG, "model encode: NULL method, source or output");
    if (!src->data || src->count == 0 || src->width < 1 || src->height < 1)
        return btf_fail(err, BTF_ERR_ARG, "%s: empty source BTF", method->name);
    btf_model *m = calloc(1, sizeof *m);
    if (!m)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate the model", method->name);
    m->method = method;
    if (params)
        m->params = *params;
    m->width = src->width, m->height = src->height;
    m->lights = src->lights, m->views = src->views;
    btf_result r = btf__range(src, &m->lo, &m->hi, err);
    double t0 = btf__now();
    if (r == BTF_OK)
        r = method->encode(src, m, err);
    m->seconds = btf__now() - t0;
    if (r != BTF_OK) {
        btf_model_free(m);
        return r;
    }
    *out = m;
    return BTF_OK;
}

void btf_model_decode(const btf_model *m, int x, int y, const float light[3], const float view[3], float rgb[3])
{
    x = x < 0 ? 0 : x >= m->width ? m->width - 1 : x;
    y = y < 0 ? 0 : y >= m->height ? m->height - 1 : y;
    m->method->decode(m, x, y, light, view, rgb);
    for (int c = 0; c < 3; c++)
        if (!isfinite(rgb[c])) /* defence in depth: no method should get here */
            rgb[c] = 0.0f;
}

size_t btf_model_bytes(const btf_model *m)
{
    return m ? m->method->bytes(m) : 0;
}

btf_method_cost btf_model_cost(const btf_model *m)
{
    btf_method_cost c = {0, 0};
    if (m && m->method->cost)
        m->method->cost(m, &c);
    return c;
}

void btf_model_free(btf_model *m)
{
    if (!m)
        return;
    if (m->impl && m->method)
        m->method->free_impl(m->impl);
    free(m);
}

const btf_method *btf_method_find(const char *name)
{
    const btf_method *all[] = {&btf_method_phong, &btf_method_lafortune, &btf_method_pca, &btf_method_pca_q,
                               &btf_method_lpyr};
    for (size_t i = 0; name && i < sizeof all / sizeof all[0]; i++)
        if (strcmp(all[i]->name, name) == 0)
            return all[i];
    return NULL;
}

#define BTF__P(...) ((btf_method_params){__VA_ARGS__})
static const btf_method_setting btf__registry[] = {
    {&btf_method_phong, BTF__P(0), "phong", "phong"},
    {&btf_method_lafortune, BTF__P(.lobes = 1), "lafortune 1", "lafortune"},
    {&btf_method_lafortune, BTF__P(.lobes = 2), "lafortune 2", "lafortune"},
    {&btf_method_pca, BTF__P(.k = 1, .components = 8), "pca k1 C8", "pca C8"},
    {&btf_method_pca, BTF__P(.k = 3, .components = 8), "pca k3 C8", "pca C8"},
    {&btf_method_pca, BTF__P(.k = 9, .components = 8), "pca k9 C8", "pca C8"},
    {&btf_method_pca, BTF__P(.k = 27, .components = 8), "pca k27 C8", "pca C8"},
    {&btf_method_pca, BTF__P(.k = 81, .components = 8), "pca k81 C8", "pca C8"},
    {&btf_method_pca, BTF__P(.k = 3, .components = 2), "pca k3 C2", "pca k3"},
    {&btf_method_pca, BTF__P(.k = 3, .components = 4), "pca k3 C4", "pca k3"},
    {&btf_method_pca, BTF__P(.k = 3, .components = 16), "pca k3 C16", "pca k3"},
    {&btf_method_pca, BTF__P(.k = 3, .components = 32), "pca k3 C32", "pca k3"},
    {&btf_method_pca_q, BTF__P(.k = 3, .components = 8), "pca-q k3 C8", "pca-q k3"},
    {&btf_method_lpyr, BTF__P(.levels = 3, .components = 4), "lpyr L3 C4", "lpyr"},
    {&btf_method_lpyr, BTF__P(.levels = 3, .components = 8), "lpyr L3 C8", "lpyr"},
    {&btf_method_lpyr, BTF__P(.levels = 3, .components = 16), "lpyr L3 C16", "lpyr"},
    {&btf_method_lpyr, BTF__P(.levels = 3, .components = 8, .decode_levels = 2), "lpyr L3 C8 far", "lpyr far"},
};

int btf_method_registry(const btf_method_setting **out)
{
    if (out)
        *out = btf__registry;
    return (int)(sizeof btf__registry / sizeof btf__registry[0]);
}
