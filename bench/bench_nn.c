/* bench_nn.c - a small nonlinear decoder per material against the package's PCA
 * (doc/performance.md section 11, "A small nonlinear decoder"). Per material the
 * bench trains, on the CPU, a latent texture of Z values a texel and one network
 * shared by every texel and direction:
 *
 *     rgb(x, l, v) = W3 relu(W2 relu(W1 [z(x), l.xy, v.xy, h.xy] + b1) + b2) + b3
 *
 * (l, v the unit light and view directions, h their half vector; H units in both
 * hidden layers), the latents and the network learnt together by Adam on the squared
 * error of the byte/255 samples, batches of NN_BT texels x NN_BP (view, light)
 * pairs drawn at random, NN_EPOCHS passes over the material's samples. Then the
 * latents are quantised to 8 bits a channel (each over its own range), the network
 * trained on for NN_TUNE passes against the quantised latents, and its parameters
 * rounded to half floats: what a page would receive and a shader evaluate.
 *
 *   bytes = each latent channel as an 8-bit grey image, the smaller of a PNG (the
 *           package's smallest-filter choice) and a lossless WebP, + 8 bytes its range,
 *           + the network's parameters at 2 bytes each;
 *   error = the CIELab error of `btf eval` (btf_metrics' lab_thesis) of the decoded
 *           material against the source, every (view, light) pair and texel.
 *
 * At that error the default coder runs: `btf compress SRC OUT --max-error E`, its bytes
 * (chunk files + manifest) and `btf eval`'s error of what it wrote. Printed per
 * material and network (Z, H):
 *
 *   nn_MAT_zZ_hH_train_rmse       RMS (0..255) of the last pass's batches, float latents
 *   nn_MAT_zZ_hH_float_lab        CIELab with float latents and float parameters
 *   nn_MAT_zZ_hH_lab              CIELab as a page would decode it (the quantised form)
 *   nn_MAT_zZ_hH_latent_bytes     the latent images + ranges
 *   nn_MAT_zZ_hH_net_bytes        the parameters at 2 bytes each
 *   nn_MAT_zZ_hH_bytes            both
 *   nn_MAT_zZ_hH_macs             multiply-adds per decoded RGB sample (the shader's work)
 *   nn_MAT_zZ_hH_train_cpu        CPU seconds of the training
 *   nn_MAT_zZ_hH_package_bytes    `btf compress --max-error` at the network's CIELab
 *   nn_MAT_zZ_hH_package_lab      `btf eval` of that package
 *   nn_MAT_zZ_hH_package_cpu      CPU seconds of that compress
 *   nn_MAT_zZ_hH_ratio            network bytes / package bytes at equal error
 *
 * Generated materials at seeds no test uses (the ones bench_vq measures, 64x64 and
 * 81 x 81 directions). The run takes about NN_EPOCHS x 40 s per network on 2 cores.
 * `make bench` runs it with the others; alone: `make build $BUILD/bench/bench_nn`, then
 * `bash bench/run.sh nn` (writes bench/results/nn.txt; NN_ONLY=NAME: one material;
 * NN_SHAPE=Z: one latent size; NN_H: other hidden units; NN_EPOCHS, NN_TUNE: passes;
 * NN_SOURCE=SRC: that `btf compress` source instead of the table, named NN_ONLY or
 * "source", e.g. a thesis package made a DFMF file by `btf import-thesis DIR F --size 64`).
 * Needs $BUILD/btf (BUILD default build). */
#include "bench_util.h"
#include "btf.h"
#include "btf_fs.h"
#include "btf_image.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "btf_source.h"
#include <cblas.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NN_FEAT 6    /* direction inputs: l.xy, v.xy, h.xy */
#define NN_BT 128    /* texels a batch */
#define NN_BP 64     /* (view, light) pairs a batch */
#define NN_B (NN_BT * NN_BP)
#define NN_LR_NET 2e-3f
#define NN_LR_LAT 2e-2f
#define NN_LR_END 0.05f /* the rates fall to this share of themselves, cosine */

/* One material: a name and the `btf compress` source; static table below. */
typedef struct nn_case {
    const char *name, *src;
} nn_case;

static const nn_case cases[] = {
    {"tiles64", "gen:tiles:64:8101"},
    {"knit64", "gen:knit:64:8102"},
    {"stone64", "gen:stone:64:8103"},
};

/* One network shape: latent values a texel, hidden units; static table below. */
typedef struct nn_shape {
    int Z, H;
} nn_shape;

static const nn_shape shapes[] = {{16, 64}, {32, 64}};

/* The parameters (latents first, then W1 b1 W2 b2 W3 b3, row-major) with their
 * gradients and Adam moments; owned by run_shape, lives for one network. */
typedef struct nn_net {
    int T, Z, H, din;   /* texels, latent values, hidden units, inputs */
    size_t n, n_lat;    /* parameters, of which latents */
    float *p, *g, *m, *v;
    float *w1, *b1, *w2, *b2, *w3, *b3; /* into p */
    long step;
} nn_net;

/* One batch's activations; owned by run_shape with the net. */
typedef struct nn_work {
    float *x, *h1, *h2, *y, *dy, *dh2, *dh1, *dx; /* NN_B rows each */
    int *tex, *pair;                               /* NN_B each: the texel and pair of a row */
} nn_work;

/* The material: samples and the direction inputs of every pair; owned by run_case. */
typedef struct nn_data {
    const btf *src;
    int T, L, P;   /* texels, lights, pairs (views x lights) */
    float *feat;   /* P x NN_FEAT */
} nn_data;

#define NN_SEED 0x5eed5eedULL
static uint64_t rng_state = NN_SEED; /* splitmix64; reset for each network */

static uint64_t rng_next(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static float rng_uniform(void) { return (float)((rng_next() >> 40) * (1.0 / 16777216.0)); }

/* A normal deviate (Box-Muller). */
static float rng_normal(void)
{
    float u = rng_uniform() + 1e-7f, w = rng_uniform();
    return sqrtf(-2.0f * logf(u)) * cosf(6.2831853f * w);
}

/* d->feat: each pair's light and view directions and half vector, x and y. */
static void data_features(nn_data *d)
{
    const btf *s = d->src;
    for (int v = 0; v < s->views.n_dirs; v++)
        for (int l = 0; l < d->L; l++) {
            float lv[3], vv[3];
            btf_dirset_vector(&s->lights, l, lv);
            btf_dirset_vector(&s->views, v, vv);
            bench_nn_features(lv, vv, d->feat + (size_t)(v * d->L + l) * NN_FEAT);
        }
}

static int net_make(nn_net *t, int T, int Z, int H)
{
    memset(t, 0, sizeof *t);
    t->T = T, t->Z = Z, t->H = H, t->din = Z + NN_FEAT;
    t->n_lat = (size_t)T * Z;
    t->n = t->n_lat + (size_t)t->din * H + H + (size_t)H * H + H + (size_t)H * 3 + 3;
    t->p = calloc(t->n, sizeof(float)), t->g = calloc(t->n, sizeof(float));
    t->m = calloc(t->n, sizeof(float)), t->v = calloc(t->n, sizeof(float));
    if (!t->p || !t->g || !t->m || !t->v)
        return -1;
    t->w1 = t->p + t->n_lat, t->b1 = t->w1 + (size_t)t->din * H, t->w2 = t->b1 + H, t->b2 = t->w2 + (size_t)H * H;
    t->w3 = t->b2 + H, t->b3 = t->w3 + (size_t)H * 3;
    for (size_t i = 0; i < t->n_lat; i++)
        t->p[i] = 0.1f * rng_normal();
    for (int i = 0; i < t->din * H; i++)
        t->w1[i] = rng_normal() * sqrtf(2.0f / (float)t->din);
    for (int i = 0; i < H * H; i++)
        t->w2[i] = rng_normal() * sqrtf(2.0f / (float)H);
    for (int i = 0; i < H * 3; i++)
        t->w3[i] = rng_normal() * sqrtf(1.0f / (float)H);
    t->b3[0] = t->b3[1] = t->b3[2] = 0.3f;
    return 0;
}

static void net_free(nn_net *t)
{
    free(t->p), free(t->g), free(t->m), free(t->v);
}

static int work_make(nn_work *w, const nn_net *t, size_t rows)
{
    size_t d = (size_t)t->din, h = (size_t)t->H;
    w->x = malloc(sizeof(float) * rows * d), w->dx = malloc(sizeof(float) * rows * d);
    w->h1 = malloc(sizeof(float) * rows * h), w->h2 = malloc(sizeof(float) * rows * h);
    w->dh1 = malloc(sizeof(float) * rows * h), w->dh2 = malloc(sizeof(float) * rows * h);
    w->y = malloc(sizeof(float) * rows * 3), w->dy = malloc(sizeof(float) * rows * 3);
    w->tex = malloc(sizeof(int) * rows), w->pair = malloc(sizeof(int) * rows);
    return w->x && w->dx && w->h1 && w->h2 && w->dh1 && w->dh2 && w->y && w->dy && w->tex && w->pair ? 0 : -1;
}

static void work_free(nn_work *w)
{
    free(w->x), free(w->dx), free(w->h1), free(w->h2), free(w->dh1), free(w->dh2), free(w->y), free(w->dy);
    free(w->tex), free(w->pair);
}

/* out (rows x n) = in (rows x k) . W (k x n) + b, then relu when asked. */
static void layer(const float *in, int rows, int k, const float *W, const float *b, int n, float *out, int relu)
{
    for (int r = 0; r < rows; r++)
        memcpy(out + (size_t)r * n, b, sizeof(float) * (size_t)n);
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, rows, n, k, 1.0f, in, k, W, n, 1.0f, out, n);
    if (relu)
#pragma omp simd
        for (size_t i = 0; i < (size_t)rows * n; i++)
            out[i] *= (float)(out[i] > 0.0f); /* no branch: the signs are random */
}

/* The network's output for the rows of w->x. */
static void forward(const nn_net *t, nn_work *w, int rows)
{
    layer(w->x, rows, t->din, t->w1, t->b1, t->H, w->h1, 1);
    layer(w->h1, rows, t->H, t->w2, t->b2, t->H, w->h2, 1);
    layer(w->h2, rows, t->H, t->w3, t->b3, 3, w->y, 0);
}

/* Gradient of W (k x n) and b from the layer's input (rows x k) and output grad. */
static void layer_grad(const float *in, int rows, int k, const float *dout, int n, float *gW, float *gb)
{
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, k, n, rows, 1.0f, in, k, dout, n, 0.0f, gW, n);
    for (int j = 0; j < n; j++)
        gb[j] = 0.0f;
    for (int r = 0; r < rows; r++)
        for (int j = 0; j < n; j++)
            gb[j] += dout[(size_t)r * n + j];
}

/* din (rows x k) = dout (rows x n) . W^T, masked by the layer input's relu when given. */
static void back_input(const float *dout, int rows, int n, const float *W, int k, const float *mask, float *din)
{
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, rows, k, n, 1.0f, dout, n, W, n, 0.0f, din, k);
    if (mask)
#pragma omp simd
        for (size_t i = 0; i < (size_t)rows * k; i++)
            din[i] *= (float)(mask[i] > 0.0f);
}

/* Gradients of the batch into t->g (latent rows accumulated) from dy. */
static void backward(nn_net *t, nn_work *w, int rows)
{
    size_t off = t->n_lat;
    float *g1 = t->g + off, *gb1 = g1 + (size_t)t->din * t->H, *g2 = gb1 + t->H, *gb2 = g2 + (size_t)t->H * t->H;
    float *g3 = gb2 + t->H, *gb3 = g3 + (size_t)t->H * 3;
    layer_grad(w->h2, rows, t->H, w->dy, 3, g3, gb3);
    back_input(w->dy, rows, 3, t->w3, t->H, w->h2, w->dh2);
    layer_grad(w->h1, rows, t->H, w->dh2, t->H, g2, gb2);
    back_input(w->dh2, rows, t->H, t->w2, t->H, w->h1, w->dh1);
    layer_grad(w->x, rows, t->din, w->dh1, t->H, g1, gb1);
    back_input(w->dh1, rows, t->H, t->w1, t->din, NULL, w->dx);
    memset(t->g, 0, sizeof(float) * t->n_lat);
    for (int r = 0; r < rows; r++)
        for (int z = 0; z < t->Z; z++)
            t->g[(size_t)w->tex[r] * t->Z + z] += w->dx[(size_t)r * t->din + z];
}

/* One Adam step; the latents at lr_lat (0: frozen), the network at lr_net. */
static void adam(nn_net *t, float lr_lat, float lr_net)
{
    const float b1 = 0.9f, b2 = 0.999f, eps = 1e-8f;
    t->step++;
    float c1 = 1.0f - powf(b1, (float)t->step), c2 = 1.0f - powf(b2, (float)t->step);
    for (size_t i = lr_lat > 0.0f ? 0 : t->n_lat; i < t->n; i++) {
        float g = t->g[i], lr = i < t->n_lat ? lr_lat : lr_net;
        t->m[i] = b1 * t->m[i] + (1.0f - b1) * g;
        t->v[i] = b2 * t->v[i] + (1.0f - b2) * g * g;
        t->p[i] -= lr * (t->m[i] / c1) / (sqrtf(t->v[i] / c2) + eps);
    }
}

/* Texel tex's latents (from lat, T x Z) and pair's direction inputs as row r of w->x. */
static void put_row(const nn_net *t, const float *lat, const nn_data *d, nn_work *w, int r, int tex, int pair)
{
    float *x = w->x + (size_t)r * t->din;
    memcpy(x, lat + (size_t)tex * t->Z, sizeof(float) * (size_t)t->Z);
    memcpy(x + t->Z, d->feat + (size_t)pair * NN_FEAT, sizeof(float) * NN_FEAT);
    w->tex[r] = tex, w->pair[r] = pair;
}

/* Sample c of row r (byte/255). */
static float target(const nn_data *d, const nn_work *w, int r, int c)
{
    const uint8_t *s = d->src->data;
    return (float)s[((size_t)w->pair[r] * d->T + w->tex[r]) * 3 + c] * (1.0f / 255.0f);
}

/* One batch drawn from lat, run forward, its loss gradient into w->dy; returns its
 * summed squared error. */
static double batch(const nn_net *t, const float *lat, const nn_data *d, nn_work *w)
{
    int tex[NN_BT];
    for (int i = 0; i < NN_BT; i++)
        tex[i] = (int)(rng_next() % (uint64_t)d->T);
    for (int j = 0; j < NN_BP; j++) {
        int pair = (int)(rng_next() % (uint64_t)d->P);
        for (int i = 0; i < NN_BT; i++)
            put_row(t, lat, d, w, j * NN_BT + i, tex[i], pair);
    }
    forward(t, w, NN_B);
    double se = 0.0;
    for (int r = 0; r < NN_B; r++)
        for (int c = 0; c < 3; c++) {
            float e = w->y[(size_t)r * 3 + c] - target(d, w, r, c);
            se += (double)e * e;
            w->dy[(size_t)r * 3 + c] = e * (2.0f / (3.0f * NN_B));
        }
    return se;
}

/* passes over the samples at rates falling from (lr_lat, lr_net), cosine; latents
 * from lat (t->p's own when it is t->p). Returns the last pass's RMS (0..255). */
static double train(nn_net *t, const float *lat, const nn_data *d, nn_work *w, double passes, float lr_lat,
                    float lr_net)
{
    long steps = (long)(passes * (double)d->T * d->P / NN_B), per = (long)((double)d->T * d->P / NN_B);
    double se = 0.0;
    long n_se = 0;
    for (long s = 0; s < steps; s++) {
        float f = NN_LR_END + (1.0f - NN_LR_END) * 0.5f * (1.0f + cosf(3.14159265f * (float)s / (float)steps));
        double e = batch(t, lat, d, w);
        if (s >= steps - per)
            se += e, n_se += NN_B * 3;
        backward(t, w, NN_B);
        adam(t, lr_lat * f, lr_net * f);
    }
    return n_se ? 255.0 * sqrt(se / (double)n_se) : 0.0;
}

/* The decoded material's error against the source, latents from lat. */
static btf_metrics evaluate(const nn_net *t, const float *lat, const nn_data *d, nn_work *w)
{
    btf_metrics_acc acc = {0};
    float *ref = malloc(sizeof(float) * (size_t)d->T * 3);
    const btf *s = d->src;
    for (int p = 0; ref && p < d->P; p++) {
        for (int i = 0; i < d->T; i++)
            put_row(t, lat, d, w, i, i, p);
        forward(t, w, d->T);
        for (size_t i = 0; i < (size_t)d->T * 3; i++)
            w->y[i] = w->y[i] < 0.0f ? 0.0f : w->y[i] > 1.0f ? 1.0f : w->y[i];
        btf_get_image(s, p / d->L, p % d->L, ref);
        btf_metrics_add(&acc, ref, w->y, (size_t)d->T);
    }
    free(ref);
    btf_metrics m = {0};
    btf_metrics_finish(&acc, &m);
    return m;
}

/* The latents quantised to 8 bits a channel into q (T x Z), their images' bytes; -1
 * when an image could not be encoded (with a message). */
static long long quantise_latents(const nn_net *t, const btf *s, float *q)
{
    uint8_t *plane = malloc((size_t)t->T);
    long long bytes = plane ? 0 : -1;
    for (int z = 0; bytes >= 0 && z < t->Z; z++) {
        float lo = 1e30f, hi = -1e30f;
        for (int i = 0; i < t->T; i++)
            lo = fminf(lo, t->p[(size_t)i * t->Z + z]), hi = fmaxf(hi, t->p[(size_t)i * t->Z + z]);
        float step = hi > lo ? (hi - lo) / 255.0f : 1.0f;
        for (int i = 0; i < t->T; i++) {
            int v = (int)lrintf((t->p[(size_t)i * t->Z + z] - lo) / step);
            plane[i] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
            q[(size_t)i * t->Z + z] = lo + step * (float)plane[i];
        }
        long long best = -1;
        const char *names[2] = {"z.png", "z.webp"};
        for (int k = 0; best != -2 && k < 2; k++) {
            uint8_t *out = NULL;
            size_t n = 0;
            btf_error err = {{0}};
            if (btf_image_encode(names[k], s->width, s->height, 1, 8, plane, BTF_IMAGE_PNG_SMALLEST, &out, &n,
                                 &err) != BTF_OK)
                fprintf(stderr, "bench_nn: %s\n", err.msg), best = -2;
            else if (best < 0 || (long long)n < best)
                best = (long long)n;
            free(out);
        }
        bytes = best < 0 ? -1 : bytes + best + 8; /* + the channel's range, two floats */
    }
    free(plane);
    return bytes;
}

/* The package `btf compress --max-error e` writes: its bytes, `btf eval`'s CIELab and
 * RMSE (0..255) of it and the compress's CPU seconds. 0 on success. */
static int package_at(const char *btf, const char *tmp, const nn_case *c, double e, long long *bytes, double *lab,
                      double *rmse, double *cpu)
{
    char dir[700], cmd[2000];
    snprintf(dir, sizeof dir, "%s/%s", tmp, c->name);
    snprintf(cmd, sizeof cmd, "'%s' compress '%s' '%s' --max-error %.4f --quiet --no-thumbnail", btf, c->src,
             dir, e);
    struct rusage r0, r1;
    getrusage(RUSAGE_CHILDREN, &r0);
    int bad = system(cmd) != 0;
    getrusage(RUSAGE_CHILDREN, &r1);
    *cpu = (double)(r1.ru_utime.tv_sec - r0.ru_utime.tv_sec + r1.ru_stime.tv_sec - r0.ru_stime.tv_sec) +
           1e-6 * (double)(r1.ru_utime.tv_usec - r0.ru_utime.tv_usec + r1.ru_stime.tv_usec - r0.ru_stime.tv_usec);
    btf_package *p = NULL;
    btf_error err = {{0}};
    if (bad || btf_package_read(dir, 0, &p, &err) != BTF_OK) {
        fprintf(stderr, "bench_nn: %s: %s\n", c->name, err.msg[0] ? err.msg : "compress failed");
        return -1;
    }
    *bytes = bench_package_bytes(dir, p);
    btf_package_free(p);
    snprintf(cmd, sizeof cmd, "'%s' eval '%s' '%s' --no-curve --csv", btf, c->src, dir);
    FILE *f = popen(cmd, "r");
    char line[256];
    *lab = -1.0;
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "lab_mae,", 8))
            *lab = atof(line + 8);
        else if (!strncmp(line, "rgb_rmse,", 9))
            *rmse = atof(line + 9);
    bad = !f || pclose(f) != 0 || *lab < 0;
    btf_fs_rmtree(dir, NULL);
    return bad ? -1 : 0;
}

/* The default coder at CIELab e: `btf compress --max-error` at e and, when what it
 * wrote lands below 0.98 e, again at e scaled by the miss; the bytes at e interpolated
 * between the two (log bytes linear in CIELab) when they bracket e, else the fewer
 * bytes of those within e. pt[0], pt[1]: the two runs' (bytes, CIELab, RMSE). */
typedef struct nn_point {
    long long bytes;
    double lab, rmse, cpu;
} nn_point;

static int package_equal(const char *btf, const char *tmp, const nn_case *c, double e, nn_point pt[2], double *bytes)
{
    nn_point *a = &pt[0], *b = &pt[1];
    if (package_at(btf, tmp, c, e, &a->bytes, &a->lab, &a->rmse, &a->cpu) != 0)
        return -1;
    *b = *a;
    if (a->lab < 0.98 * e && package_at(btf, tmp, c, e * e / a->lab, &b->bytes, &b->lab, &b->rmse, &b->cpu) != 0)
        return -1;
    if (a->lab < e && b->lab > e) {
        double f = (e - a->lab) / (b->lab - a->lab);
        *bytes = exp(log((double)a->bytes) + f * (log((double)b->bytes) - log((double)a->bytes)));
    } else
        *bytes = (double)(b->lab <= e && b->bytes < a->bytes ? b->bytes : a->bytes);
    return 0;
}

/* One network shape on one material: trained, quantised, measured, the package at
 * its error; printed. 0 on success. */
static int run_shape(const char *btf, const char *tmp, const nn_case *c, const nn_data *d, nn_shape sh)
{
    const char *ep = getenv("NN_EPOCHS"), *tu = getenv("NN_TUNE");
    double epochs = ep ? atof(ep) : 12.0, tune = tu ? atof(tu) : 1.0;
    nn_net t = {0}; /* net_free is safe on it when q is not allocated */
    nn_work w = {0};
    rng_state = NN_SEED; /* each network the same whichever ran before it */
    float *q = malloc(sizeof(float) * (size_t)d->T * (size_t)sh.Z);
    int bad = !q || net_make(&t, d->T, sh.Z, sh.H) != 0 || work_make(&w, &t, d->T > NN_B ? d->T : NN_B) != 0;
    if (bad) {
        fprintf(stderr, "bench_nn: out of memory\n");
        free(q), net_free(&t), work_free(&w);
        return -1;
    }
    double t0 = cpu_s(), rmse = train(&t, t.p, d, &w, epochs, NN_LR_LAT, NN_LR_NET), cpu = cpu_s() - t0;
    btf_metrics mf = evaluate(&t, t.p, d, &w);
    t0 = cpu_s();
    long long lat_bytes = quantise_latents(&t, d->src, q);
    if (lat_bytes < 0) {
        free(q), net_free(&t), work_free(&w);
        return -1;
    }
    train(&t, q, d, &w, tune, 0.0f, NN_LR_NET * 0.25f);
    for (size_t i = t.n_lat; i < t.n; i++)
        t.p[i] = bench_half_round(t.p[i]);
    cpu += cpu_s() - t0;
    btf_metrics mq = evaluate(&t, q, d, &w);
    long long net_bytes = 2 * (long long)(t.n - t.n_lat), bytes = lat_bytes + net_bytes;
    nn_point pt[2] = {{0}};
    double pkg = 0.0;
    bad = package_equal(btf, tmp, c, mq.lab_thesis, pt, &pkg);
    char k[64];
    snprintf(k, sizeof k, "nn_%s_z%d_h%d", c->name, sh.Z, sh.H);
    printf("%s_train_rmse %.4f level\n%s_float_lab %.4f CIELab\n%s_lab %.4f CIELab\n%s_rmse %.4f level\n", k, rmse, k,
           mf.lab_thesis, k, mq.lab_thesis, k, mq.rmse);
    printf("%s_latent_bytes %lld B\n%s_net_bytes %lld B\n%s_bytes %lld B\n", k, lat_bytes, k, net_bytes, k, bytes);
    printf("%s_macs %d count\n%s_train_cpu %.1f s\n", k, t.din * t.H + t.H * t.H + t.H * 3, k, cpu);
    for (int i = 0; !bad && i < 2; i++)
        printf("%s_package%d_bytes %lld B\n%s_package%d_lab %.4f CIELab\n%s_package%d_rmse %.4f level\n"
               "%s_package%d_cpu %.1f s\n",
               k, i, pt[i].bytes, k, i, pt[i].lab, k, i, pt[i].rmse, k, i, pt[i].cpu);
    if (!bad)
        printf("%s_package_bytes %.0f B\n%s_ratio %.4f x\n", k, pkg, k, (double)bytes / pkg);
    printf("# %s: Z %d, H %d: %lld B (latents %lld, network %lld) at CIELab %.4f, RMSE %.2f (float %.4f, train RMS "
           "%.3f), %.1f CPU s; the package at that CIELab %.0f B (runs: %lld B at %.4f, RMSE %.2f; %lld B at %.4f, "
           "RMSE %.2f; %.1f CPU s): %.3fx\n",
           c->name, sh.Z, sh.H, bytes, lat_bytes, net_bytes, mq.lab_thesis, mq.rmse, mf.lab_thesis, rmse, cpu, pkg,
           pt[0].bytes, pt[0].lab, pt[0].rmse, pt[1].bytes, pt[1].lab, pt[1].rmse, pt[0].cpu,
           pkg > 0 ? (double)bytes / pkg : 0.0);
    fflush(stdout);
    free(q), net_free(&t), work_free(&w);
    return bad;
}

/* One material: generated, every shape run. 0 on success. */
static int run_case(const char *tool, const char *tmp, const nn_case *c)
{
    btf *src = NULL;
    btf_load_options lo = {0};
    lo.storage = BTF_U8;
    btf_error err = {{0}};
    if (btf_source_load(c->src, &lo, &src, &err) != BTF_OK || src->storage != BTF_U8) {
        fprintf(stderr, "bench_nn: %s: %s\n", c->name, err.msg[0] ? err.msg : "not 8-bit");
        btf_free(src);
        return -1;
    }
    nn_data d = {src, src->width * src->height, src->lights.n_dirs, src->views.n_dirs * src->lights.n_dirs, NULL};
    d.feat = malloc(sizeof(float) * NN_FEAT * (size_t)d.P);
    int bad = !d.feat;
    if (!bad)
        data_features(&d);
    const char *only = getenv("NN_SHAPE"), *hid = getenv("NN_H");
    for (size_t i = 0; !bad && i < sizeof shapes / sizeof shapes[0]; i++)
        if (!only || atoi(only) == shapes[i].Z) {
            nn_shape sh = shapes[i];
            sh.H = hid && atoi(hid) > 0 ? atoi(hid) : sh.H;
            bad = run_shape(tool, tmp, c, &d, sh) != 0;
        }
    free(d.feat);
    btf_free(src);
    return bad;
}

int main(void)
{
    char btf[600], tmp[64];
    if (!bench_btf_and_tmp("nn", btf, tmp))
        return 1;
    openblas_set_num_threads(1);
    const char *only = getenv("NN_ONLY"), *given = getenv("NN_SOURCE");
    nn_case one = {only ? only : "source", given};
    int bad = given ? run_case(btf, tmp, &one) != 0 : 0;
    for (size_t i = 0; !given && i < sizeof cases / sizeof cases[0]; i++)
        if (!only || !strcmp(only, cases[i].name))
            bad |= run_case(btf, tmp, &cases[i]) != 0;
    btf_fs_rmtree(tmp, NULL);
    return bad;
}
