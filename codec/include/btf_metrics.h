/* btf_metrics.h - error metrics between two BTFs (or images) of the same shape.
 *
 *     btf_metrics m;
 *     btf_compare(ref, test, NULL, &m, &err);
 *     printf("PSNR %.2f dB, CIELab %.3f\n", m.psnr, m.lab_thesis);
 *
 * Values are treated as sRGB-encoded 8-bit (btf_get scale * 255), D65 white,
 * clamped to 0..255 before the Lab conversion (as a display would show them; not
 * rounded to its 8-bit codes unless the caller does so: btf_metrics_displayed);
 * MAE/RMSE/PSNR use the unclamped values on the 0..255 scale.
 */
#ifndef BTF_METRICS_H
#define BTF_METRICS_H

#include "btf.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Below this many pixel pairs a comparison stays on the calling thread (btf_compare,
 * the package writer's error curve): small jobs gain nothing, and a process forked
 * after OpenMP has run cannot start OpenMP threads again. */
#define BTF_METRICS_THREAD_MIN_PIXELS ((size_t)1 << 20)

/* Accumulated error statistics; plain value owned by the caller. */
typedef struct btf_metrics {
    double mae;        /* mean |a-b| over samples, 0..255 scale */
    double rmse;       /* root mean squared error, 0..255 scale */
    double psnr;       /* 20 log10(255 / rmse) dB; 999 when rmse == 0 */
    double lab_thesis; /* thesis: mean over pixels of (|dL|+|da|+|db|)/3 */
    double delta_e76;  /* mean CIE 1976 Delta E over pixels */
    size_t pixels;     /* RGB triples compared */
} btf_metrics;

/* Running sums; zero-initialise, feed with btf_metrics_add, read with btf_metrics_finish. */
typedef struct btf_metrics_acc {
    double sum_abs, sum_sq, sum_lab, sum_de;
    size_t samples, pixels;
} btf_metrics_acc;

/* Adds n RGB triples (byte/255 scale floats, interleaved). */
void btf_metrics_add(btf_metrics_acc *acc, const float *ref_rgb, const float *test_rgb, size_t n_pixels);
/* CIELab (L, a, b interleaved) of n RGB triples as btf_metrics_add converts them:
 * the reference of btf_metrics_add_lab. */
void btf_metrics_lab(const float *rgb, size_t n_pixels, float *lab);
/* btf_metrics_add with the reference's Lab given (btf_metrics_lab of ref_rgb): the
 * same sums, the reference converted once for many tests (a package's error curve). */
void btf_metrics_add_lab(btf_metrics_acc *acc, const float *ref_rgb, const float *ref_lab, const float *test_rgb,
                         size_t n_pixels);
/* Adds other's sums into acc (partial sums of one measurement, e.g. per thread). */
void btf_metrics_merge(btf_metrics_acc *acc, const btf_metrics_acc *other);
void btf_metrics_finish(const btf_metrics_acc *acc, btf_metrics *out);
/* Each of the n values at v (byte/255 scale) as the 8-bit code a display stores
 * (btf_to_u8) over 255: what a page's RGBA8 canvas shows of a decode (btf eval
 * --displayed). */
void btf_metrics_displayed(float *v, size_t n);


/* Optional subset of (view, light) pairs; NULL compares all. Owned by the caller. */
typedef struct btf_pair_subset {
    const int *views;  /* n entries */
    const int *lights; /* n entries, pair i = (views[i], lights[i]) */
    int n;
} btf_pair_subset;

/* Compares test against ref over all pairs (or the subset). Shapes must match. */
btf_result btf_compare(const btf *ref, const btf *test, const btf_pair_subset *subset, btf_metrics *out,
                       btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
