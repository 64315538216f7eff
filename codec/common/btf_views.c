/* btf_views.c - view sources (btf_views.h): what every source shares (fill, close,
 * the 8-bit column copy), the in-memory wrapper and whole-source loading. The
 * image-directory and DFMF sources live with their formats (btf_ubo2003.c,
 * btf_dfmf.c); btf_views_open, which picks one by the path, is btf_input.c. */
#include "btf_views.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

size_t btf_views_floats(const btf_views *s)
{
    return 3u * (size_t)s->lights.n_dirs * (size_t)s->width * (size_t)s->height;
}

btf_result btf_views_fill(btf_views *s, int view, float *cols, btf_error *err)
{
    if (!s || !s->fill || !cols || view < 0 || view >= s->views.n_dirs)
        return btf_fail(err, BTF_ERR_ARG, "view source: bad arguments (view %d)", view);
    return s->fill(s, view, cols, err);
}

void btf_views_close(btf_views *s)
{
    if (!s)
        return;
    if (s->close)
        s->close(s);
    s->close = NULL, s->fill = NULL, s->impl = NULL;
}

void btf_views_put_u8(const uint8_t *px, size_t texels, float *cols)
{
    float *c0 = cols, *c1 = cols + texels, *c2 = c1 + texels;
    for (size_t r = 0; r < texels; r++, px += 3) {
        c0[r] = px[0] * (1.0f / 255.0f);
        c1[r] = px[1] * (1.0f / 255.0f);
        c2[r] = px[2] * (1.0f / 255.0f);
    }
}

/* The in-memory source: the copy btf_pca_block_matrix always made. */
static btf_result views_fill_btf(btf_views *s, int v, float *cols, btf_error *err)
{
    (void)err;
    const btf *b = s->impl;
    size_t rows = (size_t)b->width * (size_t)b->height;
    for (int l = 0; l < b->lights.n_dirs; l++) {
        size_t base = btf_index(b, v, l, 0, 0, 0);
        float *c0 = cols + (size_t)l * 3u * rows;
        if (b->storage == BTF_U8) {
            btf_views_put_u8((const uint8_t *)b->data + base, rows, c0);
        } else {
            const float *p = (const float *)b->data + base;
            float *c1 = c0 + rows, *c2 = c1 + rows;
            for (size_t r = 0; r < rows; r++, p += 3) {
                c0[r] = p[0];
                c1[r] = p[1];
                c2[r] = p[2];
            }
        }
    }
    return BTF_OK;
}

void btf_views_wrap(const btf *b, btf_views *out)
{
    memset(out, 0, sizeof *out);
    out->width = b->width, out->height = b->height;
    out->lights = b->lights, out->views = b->views;
    out->name = "BTF in memory";
    out->fill = views_fill_btf;
    out->impl = (void *)b;
}

void btf_views_over(const btf_views *inner,
                    btf_result (*fill)(btf_views *s, int view, float *cols, btf_error *err), void *impl,
                    btf_views *out)
{
    memset(out, 0, sizeof *out);
    out->width = inner->width, out->height = inner->height;
    out->lights = inner->lights, out->views = inner->views;
    out->name = inner->name;
    out->fill = fill, out->impl = impl;
}

btf_result btf_views_load(btf_views *s, int u8, btf **out, btf_error *err)
{
    *out = NULL;
    btf *b = NULL;
    size_t n = btf_views_floats(s), rows = (size_t)s->width * s->height;
    float *cols = malloc(n * sizeof(float));
    btf_result r = cols ? btf_create(s->width, s->height, &s->lights, &s->views, u8 ? BTF_U8 : BTF_F32, &b, err)
                        : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (one view)", s->name);
    for (int v = 0; r == BTF_OK && v < s->views.n_dirs; v++) {
        r = btf_views_fill(s, v, cols, err);
        for (int l = 0; r == BTF_OK && l < s->lights.n_dirs; l++)
            for (int c = 0; c < 3; c++)
                for (size_t t = 0; t < rows; t++) {
                    float x = cols[((size_t)l * 3 + (size_t)c) * rows + t];
                    size_t i = btf_index(b, v, l, 0, 0, 0) + 3 * t + (size_t)c;
                    if (u8)
                        ((uint8_t *)b->data)[i] = (uint8_t)(x <= 0.0f ? 0 : x >= 1.0f ? 255 : lroundf(x * 255.0f));
                    else
                        ((float *)b->data)[i] = x;
                }
    }
    free(cols);
    if (r != BTF_OK) {
        btf_free(b);
        return r;
    }
    *out = b;
    return BTF_OK;
}
