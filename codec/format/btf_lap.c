/* btf_lap.c - version-4 residual levels: the predictor, its least-squares fit, the
 * residual transform and its inverse (doc/package-format.md section 4.4). */
#include "btf_lap.h"
#include "btf_common.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

btf_lap_pred btf_lap_pred_default(void)
{
    btf_lap_pred pr;
    memset(&pr, 0, sizeof pr);
    for (int c = 0; c < 3; c++)
        pr.w[c][0] = pr.w[c][1] = 16;
    return pr;
}

/* The 9-3-3-1 bilinear prediction p of every fine texel (clamped to its tile) into P. */
static void btf__lap_bilinear(const uint8_t *coarse, int aw, int ah, int tw, int th, int16_t *P)
{
    int cw = aw / 2, tcw = tw / 2, tch = th / 2;
    for (int y = 0; y < ah; y++) {
        int Y = y >> 1, y0 = Y - Y % tch, Y2 = Y + ((y & 1) ? 1 : -1);
        Y2 = Y2 < y0 ? y0 : Y2 > y0 + tch - 1 ? y0 + tch - 1 : Y2;
        const uint8_t *r = coarse + (size_t)Y * cw, *r2 = coarse + (size_t)Y2 * cw;
        for (int x = 0; x < aw; x++) {
            int X = x >> 1, x0 = X - X % tcw, X2 = X + ((x & 1) ? 1 : -1);
            X2 = X2 < x0 ? x0 : X2 > x0 + tcw - 1 ? x0 + tcw - 1 : X2;
            P[(size_t)y * aw + x] = (int16_t)((9 * r[X] + 3 * r[X2] + 3 * r2[X] + r2[X2] + 8) >> 4);
        }
    }
}

/* The six features of texel (x, y) (btf_lap_pred), fine rebuilt before it in raster order. */
static void btf__lap_features(const uint8_t *fine, const int16_t *P, const uint8_t *coarse, int aw, int tw, int th,
                              int x, int y, int f[BTF_LAP_PRED_N])
{
    size_t i = (size_t)y * aw + x, c = (size_t)(y & ~1) * aw + (x & ~1);
    int tx = x % tw, ty = y % th;
    f[0] = tx > 0 ? fine[i - 1] - P[i - 1] : 0;
    f[1] = ty > 0 ? fine[i - aw] - P[i - aw] : 0;
    f[2] = ty > 0 && tx < tw - 1 ? fine[i - aw + 1] - P[i - aw + 1] : 0;
    f[3] = ty > 0 && tx > 0 ? fine[i - aw - 1] - P[i - aw - 1] : 0;
    f[4] = 4 * coarse[(size_t)(y >> 1) * (aw / 2) + (x >> 1)] - (P[c] + P[c + 1] + P[c + aw] + P[c + aw + 1]);
    f[5] = 1;
}

/* floor(v / 64) for any int v. */
static int btf__lap_floor64(int v)
{
    return v >= 0 ? v / 64 : -((-v + 63) / 64);
}

/* The prediction of texel (x, y) (not the last of its cell). */
static int btf__lap_predict(const btf_lap_pred *pr, const uint8_t *fine, const int16_t *P, const uint8_t *coarse,
                            int aw, int tw, int th, int x, int y)
{
    int f[BTF_LAP_PRED_N], s = 0;
    const int *w = pr->w[(x & 1) + 2 * (y & 1)];
    btf__lap_features(fine, P, coarse, aw, tw, th, x, y, f);
    for (int k = 0; k < BTF_LAP_PRED_N; k++)
        s += w[k] * f[k];
    return P[(size_t)y * aw + x] + btf__lap_floor64(s);
}

/* The sum of the three other texels of the cell whose last texel is (x, y). */
static int btf__lap_cell3(const uint8_t *fine, int aw, size_t i)
{
    return fine[i - aw - 1] + fine[i - aw] + fine[i - 1];
}

static int16_t *btf__lap_scratch(const uint8_t *coarse, int aw, int ah, int tw, int th, btf_error *err)
{
    int16_t *P = malloc((size_t)aw * ah * sizeof *P);
    if (!P)
        btf_fail(err, BTF_ERR_NOMEM, "residual level: out of memory (%dx%d prediction)", aw, ah);
    else
        btf__lap_bilinear(coarse, aw, ah, tw, th, P);
    return P;
}

/* What texel (x, y) is expected to be from what came before it in raster order: the
 * prediction, or for the last texel of a cell 4 coarse - the cell's other three. */
static int btf__lap_expect(const btf_lap_pred *pr, const uint8_t *fine, const int16_t *P, const uint8_t *coarse,
                           int aw, int tw, int th, int x, int y)
{
    size_t i = (size_t)y * aw + x;
    if ((x & 1) && (y & 1))
        return 4 * coarse[(size_t)(y >> 1) * (aw / 2) + (x >> 1)] - btf__lap_cell3(fine, aw, i);
    return btf__lap_predict(pr, fine, P, coarse, aw, tw, th, x, y);
}

/* The transform (decode = 0: in = fine, out = res) or its inverse (decode = 1: in =
 * res, out = fine), one raster pass; both see the same fine texels before (x, y). */
static btf_result btf__lap_code(const uint8_t *in, uint8_t *out, const uint8_t *coarse, int aw, int ah, int tw,
                                int th, const btf_lap_pred *pred, int decode, btf_error *err)
{
    int16_t *P = btf__lap_scratch(coarse, aw, ah, tw, th, err);
    if (!P)
        return BTF_ERR_NOMEM;
    const uint8_t *fine = decode ? out : in;
    for (int y = 0; y < ah; y++)
        for (int x = 0; x < aw; x++) {
            size_t i = (size_t)y * aw + x;
            int e = btf__lap_expect(pred, fine, P, coarse, aw, tw, th, x, y);
            out[i] = (uint8_t)(decode ? e + in[i] - 128 : in[i] - e + 128); /* mod 256 */
        }
    free(P);
    return BTF_OK;
}

btf_result btf_lap_encode(const uint8_t *fine, const uint8_t *coarse, int aw, int ah, int tw, int th,
                          const btf_lap_pred *pred, uint8_t *res, btf_error *err)
{
    return btf__lap_code(fine, res, coarse, aw, ah, tw, th, pred, 0, err);
}

btf_result btf_lap_decode(const uint8_t *res, const uint8_t *coarse, int aw, int ah, int tw, int th,
                          const btf_lap_pred *pred, uint8_t *fine, btf_error *err)
{
    return btf__lap_code(res, fine, coarse, aw, ah, tw, th, pred, 1, err);
}

/* The normal equations of class cls (G = sum f f^T, b = sum f t, t = q - p). */
static void btf__lap_normal(const uint8_t *fine, const int16_t *P, const uint8_t *coarse, int aw, int ah, int tw,
                            int th, int cls, double G[BTF_LAP_PRED_N * BTF_LAP_PRED_N], double b[BTF_LAP_PRED_N])
{
    const int n = BTF_LAP_PRED_N;
    memset(G, 0, sizeof(double) * n * n);
    memset(b, 0, sizeof(double) * n);
    for (int y = cls >> 1; y < ah; y += 2)
        for (int x = cls & 1; x < aw; x += 2) {
            int f[BTF_LAP_PRED_N];
            btf__lap_features(fine, P, coarse, aw, tw, th, x, y, f);
            double t = fine[(size_t)y * aw + x] - P[(size_t)y * aw + x];
            for (int r = 0; r < n; r++) {
                b[r] += f[r] * t;
                for (int c = 0; c <= r; c++)
                    G[r * n + c] += (double)f[r] * f[c];
            }
        }
}

/* Solves G w = b (lower triangle of G filled, ridge-regularised) and rounds w into out
 * (the constant term carries the +32 that turns floor into rounding). 0 on failure. */
static int btf__lap_solve(double *G, double *b, int out[BTF_LAP_PRED_N])
{
    const int n = BTF_LAP_PRED_N;
    for (int k = 0; k < n; k++)
        G[k * n + k] += 1e-6 * G[k * n + k] + 1e-9;
    if (LAPACKE_dposv(LAPACK_ROW_MAJOR, 'L', n, 1, G, n, b, 1) != 0)
        return 0;
    for (int k = 0; k < n; k++) {
        double w = 64.0 * b[k] + (k == n - 1 ? 32.0 : 0.0);
        if (!(fabs(w) <= BTF_LAP_PRED_MAX))
            return 0;
        out[k] = (int)lround(w);
    }
    return 1;
}

btf_lap_pred btf_lap_pred_fit(const uint8_t *fine, const uint8_t *coarse, int aw, int ah, int tw, int th)
{
    btf_lap_pred pr = btf_lap_pred_default();
    int16_t *P = btf__lap_scratch(coarse, aw, ah, tw, th, NULL);
    for (int cls = 0; P && cls < 3; cls++) {
        double G[BTF_LAP_PRED_N * BTF_LAP_PRED_N], b[BTF_LAP_PRED_N];
        int w[BTF_LAP_PRED_N];
        btf__lap_normal(fine, P, coarse, aw, ah, tw, th, cls, G, b);
        if (btf__lap_solve(G, b, w))
            memcpy(pr.w[cls], w, sizeof w);
    }
    free(P);
    return pr;
}
