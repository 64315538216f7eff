/* btf_core.c - result codes, error messages and the in-memory BTF container. */
#include "btf.h"
#include "btf_common.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <string.h>

const char *btf_result_string(btf_result r)
{
    switch (r) {
    case BTF_OK: return "ok";
    case BTF_ERR_ARG: return "invalid argument";
    case BTF_ERR_IO: return "input/output error";
    case BTF_ERR_FORMAT: return "bad format";
    case BTF_ERR_RANGE: return "value out of range";
    case BTF_ERR_NOMEM: return "out of memory";
    case BTF_ERR_UNSUPPORTED: return "unsupported";
    case BTF_ERR_NUMERIC: return "numerical error";
    case BTF_ERR_MISSING: return "missing file or entry";
    }
    return "unknown error";
}

int btf_name_index(const char *const *names, int n, const char *name)
{
    for (int i = 0; name && i < n; i++)
        if (!strcmp(name, names[i]))
            return i;
    return -1;
}

btf_result btf_fail(btf_error *err, btf_result code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        for (char *c = err->msg; *c; c++) /* one line: names and text from files may hold control bytes */
            if ((unsigned char)*c < 0x20 || *c == 0x7f)
                *c = '?';
    }
    return code;
}

void btf_free(btf *b)
{
    if (b)
        free(b->data), free(b);
}

btf_result btf_create(int width, int height, const btf_dirset *lights, const btf_dirset *views,
                      btf_storage storage, btf **out, btf_error *err)
{
    if (!out || !lights || !views)
        return btf_fail(err, BTF_ERR_ARG, "btf_create: NULL argument");
    *out = NULL;
    if (width < 1 || height < 1 || width > BTF_MAX_SIDE || height > BTF_MAX_SIDE)
        return btf_fail(err, BTF_ERR_RANGE, "btf_create: size %dx%d outside 1..%d", width, height, BTF_MAX_SIDE);
    if (lights->n_dirs < 1 || views->n_dirs < 1 || lights->n_dirs > BTF_MAX_DIRS || views->n_dirs > BTF_MAX_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "btf_create: direction counts %d x %d invalid", lights->n_dirs,
                        views->n_dirs);
    if (storage != BTF_U8 && storage != BTF_F32)
        return btf_fail(err, BTF_ERR_ARG, "btf_create: unknown storage %d", (int)storage);
    size_t count = (size_t)width * (size_t)height * 3u * (size_t)lights->n_dirs * (size_t)views->n_dirs;
    if (count > BTF_MAX_SAMPLES)
        return btf_fail(err, BTF_ERR_RANGE, "btf_create: %zu samples exceed the limit", count);
    btf *b = calloc(1, sizeof *b);
    if (!b)
        return btf_fail(err, BTF_ERR_NOMEM, "btf_create: out of memory");
    size_t elem = storage == BTF_U8 ? 1u : sizeof(float);
    b->data = btf_big_calloc(count, elem);
    if (!b->data) {
        free(b);
        return btf_fail(err, BTF_ERR_NOMEM, "btf_create: cannot allocate %zu bytes", count * elem);
    }
    b->width = width;
    b->height = height;
    b->lights = *lights;
    b->views = *views;
    b->storage = storage;
    b->count = count;
    *out = b;
    return BTF_OK;
}

float btf_get(const btf *b, int view, int light, int x, int y, int c)
{
    size_t i = btf_index(b, view, light, x, y, c);
    if (b->storage == BTF_U8)
        return ((const uint8_t *)b->data)[i] * (1.0f / 255.0f);
    return ((const float *)b->data)[i];
}

void btf_set(btf *b, int view, int light, int x, int y, int c, float v)
{
    size_t i = btf_index(b, view, light, x, y, c);
    if (b->storage == BTF_F32) {
        ((float *)b->data)[i] = v;
        return;
    }
    ((uint8_t *)b->data)[i] = btf_to_u8(v);
}

void btf_get_texels(const btf *b, int view, int light, size_t first, size_t n, float *dst)
{
    size_t base = btf_index(b, view, light, 0, 0, 0) + 3u * first;
    if (b->storage == BTF_U8) {
        const uint8_t *s = (const uint8_t *)b->data + base;
        for (size_t i = 0; i < 3u * n; i++)
            dst[i] = s[i] * (1.0f / 255.0f);
    } else {
        memcpy(dst, (const float *)b->data + base, 3u * n * sizeof(float));
    }
}

void btf_get_image(const btf *b, int view, int light, float *dst)
{
    btf_get_texels(b, view, light, 0, (size_t)b->width * b->height, dst);
}

btf_result btf_downsample(const btf *src, int factor, btf **out, btf_error *err)
{
    if (!src || !out || factor < 1)
        return btf_fail(err, BTF_ERR_ARG, "btf_downsample: bad argument");
    if (src->width % factor || src->height % factor)
        return btf_fail(err, BTF_ERR_ARG, "btf_downsample: %dx%d not divisible by %d", src->width, src->height,
                        factor);
    int w = src->width / factor, h = src->height / factor;
    btf_result r = btf_create(w, h, &src->lights, &src->views, src->storage, out, err);
    if (r != BTF_OK)
        return r;
    float inv = 1.0f / (float)(factor * factor);
    for (int v = 0; v < src->views.n_dirs; v++)
        for (int l = 0; l < src->lights.n_dirs; l++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    for (int c = 0; c < 3; c++) {
                        float s = 0.0f;
                        for (int dy = 0; dy < factor; dy++)
                            for (int dx = 0; dx < factor; dx++)
                                s += btf_get(src, v, l, x * factor + dx, y * factor + dy, c);
                        btf_set(*out, v, l, x, y, c, s * inv);
                    }
    return BTF_OK;
}

int btf_area_weights(int n_in, int n_out, int *first, int *cnt, float *w, int maxc)
{
    double scale = (double)n_in / (double)n_out;
    for (int i = 0; i < n_out; i++) {
        double a = i * scale, e = (i + 1) * scale;
        int s0 = (int)floor(a), s1 = (int)ceil(e);
        if (s1 > n_in)
            s1 = n_in;
        if (s1 - s0 > maxc)
            return -1;
        first[i] = s0;
        cnt[i] = s1 - s0;
        for (int s = s0; s < s1; s++) {
            double lo = s > a ? s : a, hi = s + 1 < e ? s + 1 : e;
            w[i * maxc + (s - s0)] = (float)((hi - lo) / scale);
        }
    }
    return 0;
}

btf_result btf_crop(const btf *src, int x0, int y0, int w, int h, btf **out, btf_error *err)
{
    if (!src || !out || x0 < 0 || y0 < 0 || w < 1 || h < 1 || w > src->width - x0 || h > src->height - y0)
        return btf_fail(err, BTF_ERR_ARG, "btf_crop: window %dx%d at (%d, %d) is outside %dx%d", w, h, x0, y0,
                        src ? src->width : 0, src ? src->height : 0);
    btf_result r = btf_create(w, h, &src->lights, &src->views, src->storage, out, err);
    if (r != BTF_OK)
        return r;
    size_t es = src->storage == BTF_U8 ? 1 : sizeof(float), row = (size_t)w * 3 * es;
    const uint8_t *s = src->data;
    uint8_t *d = (*out)->data;
    for (int v = 0; v < src->views.n_dirs; v++)
        for (int l = 0; l < src->lights.n_dirs; l++)
            for (int y = 0; y < h; y++)
                memcpy(d + btf_index(*out, v, l, 0, y, 0) * es, s + btf_index(src, v, l, x0, y0 + y, 0) * es, row);
    return BTF_OK;
}

btf_result btf_check_finite(const btf *b, btf_error *err)
{
    if (b->storage == BTF_U8)
        return BTF_OK;
    const float *f = b->data;
    for (size_t i = 0; i < b->count; i++)
        if (!isfinite(f[i])) {
            size_t img = i / btf_image_samples(b);
            return btf_fail(err, BTF_ERR_NUMERIC, "non-finite sample at view %zu light %zu", img / (size_t)b->lights.n_dirs,
                            img % (size_t)b->lights.n_dirs);
        }
    return BTF_OK;
}

double btf_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
