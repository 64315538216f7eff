/* btf_metrics.c - RGB MAE/RMSE/PSNR and CIELab errors between BTFs or images.
 *
 * Colour pipeline per pixel (both operands): clamp to 0..1 (byte/255 scale),
 * sRGB decode to linear (IEC 61966-2-1), XYZ with the sRGB/D65 matrix, Lab
 * with the D65 white (Xn 0.95047, Yn 1, Zn 1.08883).
 * Speed: 8-bit inputs decode through a 256-entry table; float inputs that are
 * exact byte values use the same table, other floats a 4096-segment linear
 * interpolation of the curve (abs. error < 3e-8 in linear light, < 1e-4 in L).
 * The float decode and the Lab step run four pixels at a time through GCC/Clang
 * vector extensions (SSE2 on x86-64, generic code elsewhere); the cube root is a
 * bit-trick guess refined by two Halley steps (float precision). btf_compare splits
 * the (view, light) images over OpenMP's threads (OMP_NUM_THREADS) and sums
 * per-image partials in image order, so the result does not depend on the thread
 * count.
 */
#include "btf_metrics.h"

#include "btf_color.h"
#include "btf_common.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define BTF__LIN_SEGMENTS 4096

/* ---------------------------------------------------------------- tables */

/* sRGB -> linear tables, filled once (pthread_once), read-only afterwards. */
static float btf__lin8[256];
static float btf__lin_tab[BTF__LIN_SEGMENTS + 2];
static pthread_once_t btf__tables_once = PTHREAD_ONCE_INIT;

static void btf__init_tables(void)
{
    for (int i = 0; i < 256; i++)
        btf__lin8[i] = (float)btf_color_srgb_decode(i / 255.0);
    for (int i = 0; i <= BTF__LIN_SEGMENTS; i++)
        btf__lin_tab[i] = (float)btf_color_srgb_decode((double)i / BTF__LIN_SEGMENTS);
    btf__lin_tab[BTF__LIN_SEGMENTS + 1] = btf__lin_tab[BTF__LIN_SEGMENTS];
}

static void btf__tables(void) { pthread_once(&btf__tables_once, btf__init_tables); }

/* ---------------------------------------------------------------- Lab */

#define BTF__XN 0.95047f
#define BTF__ZN 1.08883f
#define BTF__LAB_EPS 0.008856451679035631f /* (6/29)^3 */
#define BTF__LAB_K 7.787037037037037f      /* 1 / (3 (6/29)^2) */

/* ---------------------------------------------------------------- accumulation */

/* Sums over one run of pixels; stack value of the function filling it. */
typedef struct btf__sums {
    double abs, sq, lab, de;
} btf__sums;

#define BTF__BLOCK 64
/* Pixel pairs waiting for the Lab step, planar ([0] ref, [1] test): linear light, or
 * with raw byte/255-scale values linearised at the flush; with ref_lab the ref's L,
 * a, b in r, g, b [0]. Stack value of one summing call. */
typedef struct btf__lab_block {
    float r[2][BTF__BLOCK], g[2][BTF__BLOCK], b[2][BTF__BLOCK];
    int n, ref_lab, raw;
} btf__lab_block;

/* Four lanes at a time through GCC/Clang vector extensions (SSE2 on x86-64). */
typedef float btf__v4 __attribute__((vector_size(16)));
typedef int32_t btf__v4i __attribute__((vector_size(16)));

static inline btf__v4 btf__v4_set(float x) { return (btf__v4){x, x, x, x}; }

static inline btf__v4 btf__v4_select(btf__v4i mask, btf__v4 a, btf__v4 b)
{
    return (btf__v4)(((btf__v4i)a & mask) | ((btf__v4i)b & ~mask));
}

/* Linear light of four byte/255-scale values: 0 below 0 (and NaN), 1 from 1, the
 * byte table for a value within 1e-4 of a byte, else the segment interpolation (its
 * loads one lane at a time). */
static inline btf__v4 btf__v4_lin(btf__v4 v)
{
    btf__v4i pos = v > btf__v4_set(0.0f), one = v >= btf__v4_set(1.0f);
    btf__v4 c = btf__v4_select(pos & ~one, v, btf__v4_set(0.0f)); /* in [0, 1): safe indices */
    btf__v4 s = c * btf__v4_set(255.0f);
    btf__v4i q = __builtin_convertvector(s + btf__v4_set(0.5f), btf__v4i);
    btf__v4 dq = (btf__v4)((btf__v4i)(s - __builtin_convertvector(q, btf__v4)) & 0x7fffffff);
    btf__v4i exact = dq < btf__v4_set(1e-4f);
    btf__v4 p = c * btf__v4_set((float)BTF__LIN_SEGMENTS);
    btf__v4i i = __builtin_convertvector(p, btf__v4i);
    btf__v4 t = p - __builtin_convertvector(i, btf__v4);
    btf__v4 lo, hi, e8;
    for (int k = 0; k < 4; k++)
        lo[k] = btf__lin_tab[i[k]], hi[k] = btf__lin_tab[i[k] + 1], e8[k] = btf__lin8[q[k]];
    btf__v4 lin = btf__v4_select(exact, e8, lo + t * (hi - lo));
    lin = btf__v4_select(one, btf__v4_set(1.0f), lin);
    return btf__v4_select(pos, lin, btf__v4_set(0.0f));
}

/* Lab f() of four values: cube root (bit-trick guess, two Halley steps) or the linear toe. */
static inline btf__v4 btf__v4_lab_f(btf__v4 t)
{
    btf__v4i bits = (btf__v4i)t;
    btf__v4 third = __builtin_convertvector(bits, btf__v4) * btf__v4_set(1.0f / 3.0f);
    btf__v4 y = (btf__v4)(__builtin_convertvector(third, btf__v4i) + 709921077);
    for (int k = 0; k < 2; k++) {
        btf__v4 y3 = y * y * y;
        y = y * (y3 + t + t) / (y3 + y3 + t);
    }
    btf__v4 toe = t * btf__v4_set(BTF__LAB_K) + btf__v4_set(4.0f / 29.0f);
    return btf__v4_select(t > btf__v4_set(BTF__LAB_EPS), y, toe);
}

static inline void btf__v4_lab(btf__v4 r, btf__v4 g, btf__v4 b, btf__v4 lab[3])
{
    btf__v4 x = (btf__v4_set(0.4124564f) * r + btf__v4_set(0.3575761f) * g + btf__v4_set(0.1804375f) * b) *
                btf__v4_set(1.0f / BTF__XN);
    btf__v4 y = btf__v4_set(0.2126729f) * r + btf__v4_set(0.7151522f) * g + btf__v4_set(0.0721750f) * b;
    btf__v4 z = (btf__v4_set(0.0193339f) * r + btf__v4_set(0.1191920f) * g + btf__v4_set(0.9503041f) * b) *
                btf__v4_set(1.0f / BTF__ZN);
    btf__v4 fx = btf__v4_lab_f(x), fy = btf__v4_lab_f(y), fz = btf__v4_lab_f(z);
    lab[0] = btf__v4_set(116.0f) * fy - btf__v4_set(16.0f);
    lab[1] = btf__v4_set(500.0f) * (fx - fy);
    lab[2] = btf__v4_set(200.0f) * (fy - fz);
}

static inline btf__v4 btf__v4_abs(btf__v4 v) { return (btf__v4)((btf__v4i)v & 0x7fffffff); }

/* Lab differences of the queued pairs into s; empties the block. */
static void btf__flush(btf__lab_block *q, btf__sums *s)
{
    int real = q->n;
    while (q->n % 4) { /* pad with black pairs, left out of the sums */
        for (int k = 0; k < 2; k++)
            q->r[k][q->n] = q->g[k][q->n] = q->b[k][q->n] = 0.0f;
        q->n++;
    }
    if (q->raw) /* byte/255-scale values to linear light, four at a time */
        for (int k = q->ref_lab ? 1 : 0; k < 2; k++)
            for (int i = 0; i < q->n; i += 4) {
                float *ch[3] = {&q->r[k][i], &q->g[k][i], &q->b[k][i]};
                for (int c = 0; c < 3; c++) {
                    btf__v4 v;
                    memcpy(&v, ch[c], sizeof v);
                    v = btf__v4_lin(v);
                    memcpy(ch[c], &v, sizeof v);
                }
            }
    float dsum[BTF__BLOCK], dsq[BTF__BLOCK];
    for (int i = 0; i < q->n; i += 4) {
        btf__v4 la[3], lb[3], v[3];
        for (int k = 0; k < 2; k++) {
            btf__v4 r, g, b;
            memcpy(&r, &q->r[k][i], sizeof r);
            memcpy(&g, &q->g[k][i], sizeof g);
            memcpy(&b, &q->b[k][i], sizeof b);
            if (k == 0 && q->ref_lab)
                la[0] = r, la[1] = g, la[2] = b;
            else
                btf__v4_lab(r, g, b, k ? lb : la);
        }
        for (int c = 0; c < 3; c++)
            v[c] = la[c] - lb[c];
        btf__v4 sum = btf__v4_abs(v[0]) + btf__v4_abs(v[1]) + btf__v4_abs(v[2]);
        btf__v4 sq = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        memcpy(&dsum[i], &sum, sizeof sum);
        memcpy(&dsq[i], &sq, sizeof sq);
    }
    double lab = 0.0, de = 0.0;
    for (int i = 0; i < real; i++) {
        lab += dsum[i];
        de += sqrtf(dsq[i]);
    }
    s->lab += lab * (1.0 / 3.0);
    s->de += de;
    q->n = 0;
}

/* Queues one pixel pair given in linear light; flushes when full. */
static inline void btf__queue(btf__lab_block *q, btf__sums *s, const float la[3], const float lb[3])
{
    int i = q->n++;
    q->r[0][i] = la[0], q->g[0][i] = la[1], q->b[0][i] = la[2];
    q->r[1][i] = lb[0], q->g[1][i] = lb[1], q->b[1][i] = lb[2];
    if (q->n == BTF__BLOCK)
        btf__flush(q, s);
}

/* n pixels of 8-bit data. */
static void btf__sum_u8(btf__sums *s, const uint8_t *a, const uint8_t *b, size_t n)
{
    uint64_t sabs = 0, ssq = 0;
    btf__lab_block q;
    q.n = 0, q.ref_lab = 0, q.raw = 0;
    for (size_t i = 0; i < n; i++, a += 3, b += 3) {
        int d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
        if ((d0 | d1 | d2) == 0)
            continue;
        sabs += (uint64_t)(abs(d0) + abs(d1) + abs(d2));
        ssq += (uint64_t)(d0 * d0 + d1 * d1 + d2 * d2);
        float la[3] = {btf__lin8[a[0]], btf__lin8[a[1]], btf__lin8[a[2]]};
        float lb[3] = {btf__lin8[b[0]], btf__lin8[b[1]], btf__lin8[b[2]]};
        btf__queue(&q, s, la, lb);
    }
    btf__flush(&q, s);
    s->abs += (double)sabs;
    s->sq += (double)ssq;
}

/* n pixels of byte/255-scale floats; a_lab: NULL, or a's Lab (btf_metrics_lab). */
static void btf__sum_f32(btf__sums *s, const float *a, const float *a_lab, const float *b, size_t n)
{
    btf__lab_block q;
    q.n = 0, q.ref_lab = a_lab != NULL, q.raw = 1; /* linearised at the flush */
    for (size_t i = 0; i < n; i++, a += 3, b += 3) {
        double d0 = ((double)a[0] - b[0]) * 255.0, d1 = ((double)a[1] - b[1]) * 255.0,
               d2 = ((double)a[2] - b[2]) * 255.0;
        s->abs += fabs(d0) + fabs(d1) + fabs(d2);
        s->sq += d0 * d0 + d1 * d1 + d2 * d2;
        if (a[0] == b[0] && a[1] == b[1] && a[2] == b[2])
            continue;
        btf__queue(&q, s, a_lab ? a_lab + 3 * i : a, b);
    }
    btf__flush(&q, s);
}

void btf_metrics_lab(const float *rgb, size_t n_pixels, float *lab)
{
    if (!rgb || !lab)
        return;
    btf__tables();
    for (size_t i = 0; i < n_pixels; i += 4) {
        float p[3][4] = {{0.0f}};
        size_t m = n_pixels - i < 4 ? n_pixels - i : 4;
        for (size_t k = 0; k < m; k++)
            for (int c = 0; c < 3; c++)
                p[c][k] = rgb[3 * (i + k) + c];
        btf__v4 r, g, b, out[3];
        memcpy(&r, p[0], sizeof r), memcpy(&g, p[1], sizeof g), memcpy(&b, p[2], sizeof b);
        btf__v4_lab(btf__v4_lin(r), btf__v4_lin(g), btf__v4_lin(b), out);
        for (size_t k = 0; k < m; k++)
            for (int c = 0; c < 3; c++)
                lab[3 * (i + k) + c] = out[c][k];
    }
}

void btf_metrics_add(btf_metrics_acc *acc, const float *ref_rgb, const float *test_rgb, size_t n_pixels)
{
    btf_metrics_add_lab(acc, ref_rgb, NULL, test_rgb, n_pixels);
}

void btf_metrics_add_lab(btf_metrics_acc *acc, const float *ref_rgb, const float *ref_lab, const float *test_rgb,
                         size_t n_pixels)
{
    if (!acc || !ref_rgb || !test_rgb || n_pixels == 0)
        return;
    btf__tables();
    btf__sums s = {0};
    btf__sum_f32(&s, ref_rgb, ref_lab, test_rgb, n_pixels);
    acc->sum_abs += s.abs;
    acc->sum_sq += s.sq;
    acc->sum_lab += s.lab;
    acc->sum_de += s.de;
    acc->samples += 3u * n_pixels;
    acc->pixels += n_pixels;
}

void btf_metrics_merge(btf_metrics_acc *acc, const btf_metrics_acc *other)
{
    acc->sum_abs += other->sum_abs, acc->sum_sq += other->sum_sq;
    acc->sum_lab += other->sum_lab, acc->sum_de += other->sum_de;
    acc->samples += other->samples, acc->pixels += other->pixels;
}

void btf_metrics_displayed(float *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        v[i] = (float)btf_to_u8(v[i]) * (1.0f / 255.0f); /* the float a BTF_U8 sample reads as (btf_get) */
}

void btf_metrics_finish(const btf_metrics_acc *acc, btf_metrics *out)
{
    if (!out)
        return;
    memset(out, 0, sizeof *out);
    out->psnr = 999.0;
    if (!acc || acc->samples == 0 || acc->pixels == 0)
        return;
    out->mae = acc->sum_abs / (double)acc->samples;
    out->rmse = sqrt(acc->sum_sq / (double)acc->samples);
    out->psnr = out->rmse > 0.0 ? 20.0 * log10(255.0 / out->rmse) : 999.0;
    out->lab_thesis = acc->sum_lab / (double)acc->pixels;
    out->delta_e76 = acc->sum_de / (double)acc->pixels;
    out->pixels = acc->pixels;
}

/* ---------------------------------------------------------------- btf_compare */

/* Shared, read-only job description plus the per-image results array (malloc'd,
 * one slot per image); lives for one btf_compare call. */
typedef struct btf__cmp_job {
    const btf *ref, *test;
    const btf_pair_subset *subset;
    int n_images;
    btf__sums *partial;
} btf__cmp_job;

static void btf__sum_image(const btf *ref, const btf *test, int v, int l, btf__sums *s)
{
    size_t base = btf_index(ref, v, l, 0, 0, 0);
    size_t n = (size_t)ref->width * (size_t)ref->height;
    if (ref->storage == BTF_U8 && test->storage == BTF_U8) {
        btf__sum_u8(s, (const uint8_t *)ref->data + base, (const uint8_t *)test->data + base, n);
        return;
    }
    if (ref->storage == BTF_F32 && test->storage == BTF_F32) {
        btf__sum_f32(s, (const float *)ref->data + base, NULL, (const float *)test->data + base, n);
        return;
    }
    enum { CHUNK = 1024 };
    float a[3 * CHUNK], b[3 * CHUNK];
    for (size_t i = 0; i < n; i += CHUNK) {
        size_t m = n - i < CHUNK ? n - i : CHUNK;
        btf_get_texels(ref, v, l, i, m, a);
        btf_get_texels(test, v, l, i, m, b);
        btf__sum_f32(s, a, NULL, b, m);
    }
}

/* Per-image partial sums on OpenMP's threads (OMP_NUM_THREADS); small jobs stay on
 * the calling thread. Partials are summed in image order afterwards, so the result
 * does not depend on the thread count. */
static void btf__cmp_run(const btf__cmp_job *j, size_t total_pixels)
{
#pragma omp parallel for schedule(static) if (total_pixels >= BTF_METRICS_THREAD_MIN_PIXELS)
    for (int i = 0; i < j->n_images; i++) {
        int v = j->subset ? j->subset->views[i] : i / j->ref->lights.n_dirs;
        int l = j->subset ? j->subset->lights[i] : i % j->ref->lights.n_dirs;
        btf__sums s = {0};
        btf__sum_image(j->ref, j->test, v, l, &s);
        j->partial[i] = s;
    }
}

static btf_result btf__check_shapes(const btf *ref, const btf *test, btf_error *err)
{
    if (ref->width != test->width || ref->height != test->height)
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: sizes differ (%dx%d vs %dx%d)", ref->width, ref->height,
                        test->width, test->height);
    if (!btf_dirset_equal(&ref->lights, &test->lights))
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: light direction sets differ (%d vs %d directions)",
                        ref->lights.n_dirs, test->lights.n_dirs);
    if (!btf_dirset_equal(&ref->views, &test->views))
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: view direction sets differ (%d vs %d directions)",
                        ref->views.n_dirs, test->views.n_dirs);
    if (ref->storage != BTF_U8 && ref->storage != BTF_F32)
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: reference has unknown storage %d", (int)ref->storage);
    if (test->storage != BTF_U8 && test->storage != BTF_F32)
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: test has unknown storage %d", (int)test->storage);
    if (!ref->data || !test->data)
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: BTF without data");
    return BTF_OK;
}

static btf_result btf__check_subset(const btf *ref, const btf_pair_subset *s, btf_error *err)
{
    if (s->n < 1 || !s->views || !s->lights)
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: empty pair subset (n = %d)", s->n);
    for (int i = 0; i < s->n; i++) {
        if (s->views[i] < 0 || s->views[i] >= ref->views.n_dirs)
            return btf_fail(err, BTF_ERR_ARG, "btf_compare: subset pair %d: view %d outside 0..%d", i, s->views[i],
                            ref->views.n_dirs - 1);
        if (s->lights[i] < 0 || s->lights[i] >= ref->lights.n_dirs)
            return btf_fail(err, BTF_ERR_ARG, "btf_compare: subset pair %d: light %d outside 0..%d", i,
                            s->lights[i], ref->lights.n_dirs - 1);
    }
    return BTF_OK;
}

btf_result btf_compare(const btf *ref, const btf *test, const btf_pair_subset *subset, btf_metrics *out,
                       btf_error *err)
{
    if (!ref || !test || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_compare: NULL argument");
    btf_result r = btf__check_shapes(ref, test, err);
    if (r == BTF_OK && subset)
        r = btf__check_subset(ref, subset, err);
    if (r != BTF_OK)
        return r;
    btf__tables();
    btf__cmp_job job = {ref, test, subset, 0, NULL};
    job.n_images = subset ? subset->n : ref->views.n_dirs * ref->lights.n_dirs;
    job.partial = calloc((size_t)job.n_images, sizeof *job.partial);
    if (!job.partial)
        return btf_fail(err, BTF_ERR_NOMEM, "btf_compare: cannot allocate %d partial sums", job.n_images);
    size_t img_pixels = (size_t)ref->width * (size_t)ref->height;
    btf__cmp_run(&job, img_pixels * (size_t)job.n_images);
    btf_metrics_acc acc = {0};
    for (int i = 0; i < job.n_images; i++) {
        acc.sum_abs += job.partial[i].abs;
        acc.sum_sq += job.partial[i].sq;
        acc.sum_lab += job.partial[i].lab;
        acc.sum_de += job.partial[i].de;
    }
    acc.pixels = img_pixels * (size_t)job.n_images;
    acc.samples = 3u * acc.pixels;
    free(job.partial);
    btf_metrics_finish(&acc, out);
    return BTF_OK;
}
