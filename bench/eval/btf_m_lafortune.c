/* btf_m_lafortune.c - "lafortune": per texel (McAllister's Lafortune fitting)
 *     linear = a + max(l.z,0) (d + sum_i s_i f_i),  f_i = (n_i+2)/2 max(b_i, 0)^n_i,
 *     b_i = cxy_i (lx vx + ly vy) + lz vz,
 * a, d, s_i per colour channel (>= 0), lobe shapes (cxy_i in [-1, 1], n_i in [1, 256])
 * shared by the channels, so |b_i| <= 1 and every lobe is bounded.
 *
 * Fit, per texel, on a fixed subsample of the (view, light) pairs, linear light:
 * 1. grid start: the best of a few lobe shapes (and of "no lobe"), colours by
 *    non-negative least squares (btf__nnls);
 * 2. Levenberg-Marquardt (GSL gsl_multifit_nlinear, analytic Jacobian) on luminance
 *    over transformed parameters that cannot leave their bounds (squares, tanh);
 * 3. colours again by NNLS for the new shapes.
 * The LM result is kept only when the solver converged or stopped at its iteration
 * cap (counted in btf_model.n_unconverged), every value is finite, no lobe peaks
 * above BTF__PEAK times the texel's brightest sample, and the RGB residual is not
 * worse than the grid start's; otherwise (solver error, divergence, out of bounds,
 * worse) the texel keeps the grid start (counted in btf_model.n_fallback). Never NaN. */
#include "btf_method.h"
#include "btf_common.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BTF__LAF_FLOATS 16 /* cxy[2], n[2], a[3], d[3], s[2][3] */
#define BTF__PEAK 4.0      /* a lobe may peak at most 4x the texel's brightest linear sample (+0.05) */
#define BTF__N_MIN 1.0
#define BTF__N_MAX 256.0

/* Lafortune model data: width*height records; owned by its btf_model. */
typedef struct btf__laf {
    int lobes;
    float *p;
} btf__laf;

/* Geometry of one (view, light) pair; value type. */
typedef struct btf__geo {
    float lz, u, w; /* max(l.z,0), lx vx + ly vy, lz vz */
} btf__geo;

/* Fit context of one texel; lives during one texel's fit. */
typedef struct btf__fit {
    int P, lobes;
    const btf__geo *g;
    const float *y;   /* P x 3 linear samples of the texel */
    double *ylum;     /* P luminance values */
    double ymax;      /* brightest linear sample */
} btf__fit;

static double btf__lobe(double b, double n)
{
    return b > 0.0 ? 0.5 * (n + 2.0) * pow(b, n) : 0.0;
}

static btf__geo btf__geometry(const float l[3], const float v[3])
{
    btf__geo g;
    g.lz = l[2] > 0.0f ? l[2] : 0.0f;
    g.u = l[0] * v[0] + l[1] * v[1];
    g.w = l[2] * v[2];
    return g;
}

/* Colours for fixed shapes (cxy[i], n[i], i < nl) by NNLS per channel; writes
 * rec (a, d, s) and returns the RGB residual, or INFINITY if a lobe is out of bounds. */
static double btf__colours(const btf__fit *f, int nl, const double *cxy, const double *n, float *rec)
{
    int p = 2 + nl;
    double G[16] = {0}, g[3][4] = {{0}}, yy[3] = {0}, x[3][4];
    for (int j = 0; j < f->P; j++) {
        const btf__geo *q = &f->g[j];
        double b[4] = {1.0, q->lz, 0, 0};
        for (int i = 0; i < nl; i++)
            b[2 + i] = q->lz * btf__lobe(cxy[i] * q->u + q->w, n[i]);
        for (int r = 0; r < p; r++)
            for (int c = 0; c < p; c++)
                G[r * p + c] += b[r] * b[c];
        for (int c = 0; c < 3; c++) {
            double y = f->y[j * 3 + c];
            yy[c] += y * y;
            for (int r = 0; r < p; r++)
                g[c][r] += b[r] * y;
        }
    }
    double sse = 0.0;
    for (int c = 0; c < 3; c++) {
        sse += btf__nnls(p, G, g[c], yy[c], x[c]);
        for (int i = 0; i < nl; i++)
            if (!(x[c][2 + i] * 0.5 * (n[i] + 2.0) <= BTF__PEAK * f->ymax + 0.05))
                return INFINITY;
    }
    memset(rec, 0, sizeof(float) * BTF__LAF_FLOATS);
    for (int i = 0; i < 2; i++) {
        rec[i] = (float)(i < nl ? cxy[i] : -1.0);
        rec[2 + i] = (float)(i < nl ? n[i] : 1.0);
    }
    for (int c = 0; c < 3; c++) {
        rec[4 + c] = (float)x[c][0];
        rec[7 + c] = (float)x[c][1];
        for (int i = 0; i < nl; i++)
            rec[10 + i * 3 + c] = (float)x[c][2 + i];
    }
    return isfinite(sse) ? sse : INFINITY;
}

/* Grid start: "no lobe", then lobe 1 from a grid, then (2 lobes) lobe 2 from a grid. */
static double btf__grid(const btf__fit *f, float *rec)
{
    static const double g1c[] = {-1.0, -0.5}, g1n[] = {2, 8, 32, 128};
    static const double g2c[] = {0.0, 1.0}, g2n[] = {2, 8};
    double cxy[2] = {-1, 0}, n[2] = {1, 1}, best = btf__colours(f, 0, cxy, n, rec);
    float tmp[BTF__LAF_FLOATS];
    double bc = -1.0, bn = 0.0;
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 4; b++) {
            double c1[1] = {g1c[a]}, n1[1] = {g1n[b]}, s = btf__colours(f, 1, c1, n1, tmp);
            if (s < best)
                best = s, bc = g1c[a], bn = g1n[b], memcpy(rec, tmp, sizeof tmp);
        }
    if (f->lobes < 2 || bn == 0.0)
        return best;
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++) {
            double c2[2] = {bc, g2c[a]}, n2[2] = {bn, g2n[b]}, s = btf__colours(f, 2, c2, n2, tmp);
            if (s < best)
                best = s, memcpy(rec, tmp, sizeof tmp);
        }
    return best;
}

/* ---- LM on luminance: theta = [pa, pd, (ps, pc, pn) per lobe] ---- */

static double btf__n_of(double pn)
{
    return BTF__N_MIN + (BTF__N_MAX - BTF__N_MIN) * 0.5 * (1.0 + tanh(pn));
}

static int btf__lm_f(const gsl_vector *th, void *ctx, gsl_vector *r)
{
    const btf__fit *f = ctx;
    double a = gsl_vector_get(th, 0), d = gsl_vector_get(th, 1);
    for (int j = 0; j < f->P; j++) {
        const btf__geo *q = &f->g[j];
        double s = d * d;
        for (int i = 0; i < f->lobes; i++) {
            double ps = gsl_vector_get(th, 2 + 3 * i), c = tanh(gsl_vector_get(th, 3 + 3 * i));
            s += ps * ps * btf__lobe(c * q->u + q->w, btf__n_of(gsl_vector_get(th, 4 + 3 * i)));
        }
        gsl_vector_set(r, (size_t)j, a * a + q->lz * s - f->ylum[j]);
    }
    return GSL_SUCCESS;
}

static int btf__lm_df(const gsl_vector *th, void *ctx, gsl_matrix *J)
{
    const btf__fit *f = ctx;
    double pa = gsl_vector_get(th, 0), pd = gsl_vector_get(th, 1);
    for (int j = 0; j < f->P; j++) {
        const btf__geo *q = &f->g[j];
        gsl_matrix_set(J, (size_t)j, 0, 2.0 * pa);
        gsl_matrix_set(J, (size_t)j, 1, q->lz * 2.0 * pd);
        for (int i = 0; i < f->lobes; i++) {
            double ps = gsl_vector_get(th, 2 + 3 * i), tc = tanh(gsl_vector_get(th, 3 + 3 * i));
            double tn = tanh(gsl_vector_get(th, 4 + 3 * i)), n = btf__n_of(gsl_vector_get(th, 4 + 3 * i));
            double b = tc * q->u + q->w, lobe = 0.0, dl_db = 0.0, dl_dn = 0.0;
            if (b > 1e-12) {
                double bn = pow(b, n);
                lobe = 0.5 * (n + 2.0) * bn;
                dl_db = 0.5 * (n + 2.0) * n * bn / b;
                dl_dn = 0.5 * bn + lobe * log(b);
            }
            size_t k = (size_t)(2 + 3 * i);
            gsl_matrix_set(J, (size_t)j, k, q->lz * 2.0 * ps * lobe);
            gsl_matrix_set(J, (size_t)j, k + 1, q->lz * ps * ps * dl_db * q->u * (1.0 - tc * tc));
            gsl_matrix_set(J, (size_t)j, k + 2,
                           q->lz * ps * ps * dl_dn * (BTF__N_MAX - BTF__N_MIN) * 0.5 * (1.0 - tn * tn));
        }
    }
    return GSL_SUCCESS;
}

static double btf__atanh_c(double v)
{
    v = v < -0.995 ? -0.995 : v > 0.995 ? 0.995 : v;
    return atanh(v);
}

/* Transformed start vector from a grid record (luminance of its colours). */
static void btf__lm_start(const float *rec, int lobes, gsl_vector *th)
{
    static const double wl[3] = {0.2126, 0.7152, 0.0722};
    double a = 0, d = 0, s[2] = {0, 0};
    for (int c = 0; c < 3; c++) {
        a += wl[c] * rec[4 + c];
        d += wl[c] * rec[7 + c];
        for (int i = 0; i < lobes; i++)
            s[i] += wl[c] * rec[10 + i * 3 + c];
    }
    gsl_vector_set(th, 0, sqrt(a) + 1e-3);
    gsl_vector_set(th, 1, sqrt(d) + 1e-3);
    for (int i = 0; i < lobes; i++) {
        double nn = (rec[2 + i] - BTF__N_MIN) / (BTF__N_MAX - BTF__N_MIN) * 2.0 - 1.0;
        gsl_vector_set(th, (size_t)(2 + 3 * i), sqrt(s[i]) + 1e-2);
        gsl_vector_set(th, (size_t)(3 + 3 * i), btf__atanh_c(rec[i]));
        gsl_vector_set(th, (size_t)(4 + 3 * i), btf__atanh_c(nn));
    }
}

/* LM refinement of one texel: 1 if rec was replaced by a better, valid fit, 0 if
 * the texel keeps its grid start. *converged: the solver met its tolerances within
 * max_iter (LM only takes steps that lower the cost, so a capped run is still a
 * candidate; it is validated like a converged one). */
static int btf__lm(btf__fit *f, gsl_multifit_nlinear_workspace *w, int max_iter, double start_sse, float *rec,
                   int *converged)
{
    size_t p = (size_t)(2 + 3 * f->lobes);
    gsl_vector *th = gsl_vector_alloc(p);
    if (!th)
        return 0;
    btf__lm_start(rec, f->lobes, th);
    gsl_multifit_nlinear_fdf fdf = {btf__lm_f, btf__lm_df, NULL, (size_t)f->P, p, f, 0, 0, 0};
    int info = 0, ok = 0;
    int st = gsl_multifit_nlinear_init(th, &fdf, w);
    if (st == GSL_SUCCESS)
        st = gsl_multifit_nlinear_driver((size_t)max_iter, 1e-6, 1e-8, 1e-8, NULL, NULL, &info, w);
    *converged = st == GSL_SUCCESS;
    if (st == GSL_SUCCESS || st == GSL_EMAXITER) {
        const gsl_vector *x = gsl_multifit_nlinear_position(w);
        double cxy[2] = {0, 0}, n[2] = {1, 1};
        int finite = 1;
        for (int i = 0; i < f->lobes; i++) {
            cxy[i] = tanh(gsl_vector_get(x, (size_t)(3 + 3 * i)));
            n[i] = btf__n_of(gsl_vector_get(x, (size_t)(4 + 3 * i)));
            finite &= isfinite(cxy[i]) && isfinite(n[i]) && n[i] >= BTF__N_MIN && n[i] <= BTF__N_MAX;
        }
        float cand[BTF__LAF_FLOATS];
        double sse = finite ? btf__colours(f, f->lobes, cxy, n, cand) : INFINITY;
        if (isfinite(sse) && sse <= start_sse * (1.0 + 1e-9) + 1e-30) {
            memcpy(rec, cand, sizeof cand);
            ok = 1;
        }
    }
    gsl_vector_free(th);
    return ok;
}

/* Pair subsample (P of N, evenly strided) and its geometry. */
static btf__geo *btf__pairs(const btf *src, int P, int *pair)
{
    int L = src->lights.n_dirs, N = src->views.n_dirs * L;
    btf__geo *g = malloc(sizeof *g * (size_t)P);
    if (!g)
        return NULL;
    for (int j = 0; j < P; j++) {
        pair[j] = (int)((long long)j * N / P);
        float lv[3], vv[3], lu[3], vu[3];
        btf_dirset_vector(&src->lights, pair[j] % L, lv);
        btf_dirset_vector(&src->views, pair[j] / L, vv);
        btf__unit(lv, lu);
        btf__unit_view(vv, vu);
        g[j] = btf__geometry(lu, vu);
    }
    return g;
}

/* Y[t][j][c]: linear samples of every texel at the chosen pairs. */
static btf_result btf__samples(const btf *src, int P, const int *pair, float *Y, btf_error *err)
{
    int L = src->lights.n_dirs;
    size_t T = (size_t)src->width * src->height;
    float *img = malloc(sizeof(float) * btf_image_samples(src));
    if (!img)
        return btf_fail(err, BTF_ERR_NOMEM, "lafortune: cannot allocate an image");
    for (int j = 0; j < P; j++) {
        btf__image_linear(src, pair[j] / L, pair[j] % L, img);
        for (size_t t = 0; t < T; t++)
            for (int c = 0; c < 3; c++)
                Y[(t * P + j) * 3 + c] = img[t * 3 + c];
    }
    free(img);
    return BTF_OK;
}

/* Fits every texel: grid start, then LM; counts fallbacks. */
static btf_result btf__laf_fit(const btf *src, btf_model *m, btf__laf *lf, btf_error *err)
{
    int N = src->views.n_dirs * src->lights.n_dirs, P = m->params.fit_pairs;
    P = P > N ? N : P;
    size_t T = (size_t)src->width * src->height, np = (size_t)(2 + 3 * lf->lobes);
    int *pair = malloc(sizeof(int) * (size_t)P);
    btf__geo *g = pair ? btf__pairs(src, P, pair) : NULL;
    float *Y = malloc(sizeof(float) * T * (size_t)P * 3);
    double *ylum = malloc(sizeof(double) * (size_t)P);
    gsl_multifit_nlinear_parameters par = gsl_multifit_nlinear_default_parameters();
    gsl_multifit_nlinear_workspace *w =
        (size_t)P > np ? gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &par, (size_t)P, np) : NULL;
    btf_result r = BTF_OK;
    if (!pair || !g || !Y || !ylum)
        r = btf_fail(err, BTF_ERR_NOMEM, "lafortune: cannot allocate %d pairs x %zu texels", P, T);
    if (r == BTF_OK)
        r = btf__samples(src, P, pair, Y, err);
    for (size_t t = 0; t < T && r == BTF_OK; t++) {
        btf__fit f = {P, lf->lobes, g, Y + t * (size_t)P * 3, ylum, 0.0};
        for (int j = 0; j < P; j++) {
            const float *y = f.y + j * 3;
            ylum[j] = 0.2126 * y[0] + 0.7152 * y[1] + 0.0722 * y[2];
            for (int c = 0; c < 3; c++)
                f.ymax = y[c] > f.ymax ? y[c] : f.ymax;
        }
        float *rec = lf->p + t * BTF__LAF_FLOATS;
        double start = btf__grid(&f, rec);
        int conv = 0;
        if (!w || !btf__lm(&f, w, m->params.max_iter, start, rec, &conv))
            m->n_fallback++;
        m->n_unconverged += !conv;
    }
    if (w)
        gsl_multifit_nlinear_free(w);
    free(pair);
    free(g);
    free(Y);
    free(ylum);
    return r;
}

static void btf__laf_free(void *impl)
{
    btf__laf *p = impl;
    if (p)
        free(p->p);
    free(p);
}

static btf_result btf__laf_encode(const btf *src, btf_model *m, btf_error *err)
{
    btf_method_params *p = &m->params;
    if (p->lobes == 0)
        p->lobes = 1;
    if (p->lobes < 1 || p->lobes > 2)
        return btf_fail(err, BTF_ERR_RANGE, "lafortune: lobes = %d, must be 1 or 2", p->lobes);
    if (p->max_iter <= 0)
        p->max_iter = 50;
    if (p->fit_pairs <= 0)
        p->fit_pairs = 512;
    gsl_set_error_handler_off();
    size_t T = (size_t)src->width * src->height;
    btf__laf *lf = calloc(1, sizeof *lf);
    if (lf)
        lf->p = calloc(T * BTF__LAF_FLOATS, sizeof(float));
    if (!lf || !lf->p) {
        btf__laf_free(lf);
        return btf_fail(err, BTF_ERR_NOMEM, "lafortune: cannot allocate %zu texel records", T);
    }
    lf->lobes = p->lobes;
    btf_result r = btf__laf_fit(src, m, lf, err);
    if (r != BTF_OK) {
        btf__laf_free(lf);
        return r;
    }
    m->impl = lf;
    return BTF_OK;
}

static void btf__laf_decode(const btf_model *m, int x, int y, const float light[3], const float view[3], float rgb[3])
{
    const btf__laf *lf = m->impl;
    const float *p = lf->p + ((size_t)y * m->width + x) * BTF__LAF_FLOATS;
    float l[3], v[3];
    btf__unit(light, l);
    btf__unit_view(view, v);
    btf__geo q = btf__geometry(l, v);
    float f[2] = {0, 0};
    for (int i = 0; i < lf->lobes; i++)
        f[i] = (float)btf__lobe(p[i] * q.u + q.w, p[2 + i]);
    for (int c = 0; c < 3; c++) {
        float s = p[7 + c] + p[10 + c] * f[0] + p[13 + c] * f[1];
        rgb[c] = btf__linear_to_srgb(p[4 + c] + q.lz * s);
    }
}

static size_t btf__laf_bytes(const btf_model *m)
{
    const btf__laf *lf = m->impl;
    return (size_t)m->width * m->height * (size_t)(6 + 5 * lf->lobes) * sizeof(float);
}

static void btf__laf_cost(const btf_model *m, btf_method_cost *out)
{
    const btf__laf *lf = m->impl;
    out->fetches = 6 + 5 * lf->lobes;
    out->flops = 40 + 25 * lf->lobes;
}

btf_result btf_lafortune_get(const btf_model *m, int x, int y, btf_lafortune_texel *out, btf_error *err)
{
    if (!m || !out || m->method != &btf_method_lafortune)
        return btf_fail(err, BTF_ERR_ARG, "lafortune_get: not a lafortune model");
    if (x < 0 || y < 0 || x >= m->width || y >= m->height)
        return btf_fail(err, BTF_ERR_RANGE, "lafortune_get: texel (%d, %d) outside %d x %d", x, y, m->width,
                        m->height);
    const btf__laf *lf = m->impl;
    const float *p = lf->p + ((size_t)y * m->width + x) * BTF__LAF_FLOATS;
    out->lobes = lf->lobes;
    for (int i = 0; i < 2; i++)
        out->cxy[i] = p[i], out->n[i] = p[2 + i];
    for (int c = 0; c < 3; c++) {
        out->ambient[c] = p[4 + c];
        out->diffuse[c] = p[7 + c];
        out->spec[0][c] = p[10 + c];
        out->spec[1][c] = p[13 + c];
    }
    return BTF_OK;
}

const btf_method btf_method_lafortune = {
    "lafortune", "ambient + diffuse + 1-2 Lafortune lobes per texel, LM (GSL) with bounded parameters", 0,
    btf__laf_encode, btf__laf_decode, btf__laf_bytes, btf__laf_cost, btf__laf_free,
};
