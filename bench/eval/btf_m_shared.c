/* btf_m_shared.c - the small numeric helpers the method implementations share
 * (colour decoding, unit directions, one image in linear light, a tiny NNLS);
 * declared at the end of btf_method.h. */
#include "btf_method.h"

#include "btf_color.h"

#include <math.h>
#include <string.h>

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
