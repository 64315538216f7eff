/* btf_method.c - the method interface: checked encode, dispatch and the registry,
 * the one place that names every method (the helpers the methods share are
 * btf_m_shared.c, below both). */
#include "btf_method.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

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
    double t0 = btf_seconds();
    if (r == BTF_OK)
        r = method->encode(src, m, err);
    m->seconds = btf_seconds() - t0;
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
