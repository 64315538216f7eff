/* btf_package_thumbnail.c - a package's thumbnail.png (doc/package-format.md
 * section 2): the material as a flat swatch seen head-on, as the CPU reference
 * decoder reconstructs it from every chunk, box-filtered to a small poster. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "btf_package.h"
#include "btf_common.h"
#include "btf_decode.h"

/* Index of the direction of d nearest the normal: the smallest theta, the first
 * such in index order (0 for a ring set). */
static int btf__head_on(const btf_dirset *d)
{
    int best = 0;
    float best_theta = 1e9f;
    for (int i = 0; i < d->n_dirs; i++) {
        float theta, phi;
        btf_dirset_angles(d, i, &theta, &phi);
        if (theta < best_theta)
            best_theta = theta, best = i;
    }
    return best;
}

/* Every texel of p (rgb: width * height * 3 floats, byte/255 scale) by btf_decode at
 * the head-on light and view: the texel's own value (nearest, its centre), level 0,
 * every loaded chunk. */
static void btf__decode_swatch(const btf_package *p, float *rgb)
{
    float light[3], view[3];
    btf_dirset_vector(&p->lights, btf__head_on(&p->lights), light);
    btf_dirset_vector(&p->views, btf__head_on(&p->views), view);
    btf_decode_options o = {0};
    for (int y = 0; y < p->height; y++)
        for (int x = 0; x < p->width; x++)
            btf_decode(p, ((float)x + 0.5f) / (float)p->width, ((float)y + 0.5f) / (float)p->height, light, view, &o,
                       rgb + ((size_t)y * p->width + x) * 3);
}

/* Resampling weights of one axis (btf_area_weights); owned by btf__shrink for one call. */
typedef struct btf__axis {
    int *first, *cnt;
    float *w;
    int maxc;
} btf__axis;

static int btf__axis_make(btf__axis *a, int n_in, int n_out)
{
    a->maxc = n_in / n_out + 2;
    a->first = malloc(2 * (size_t)n_out * sizeof(int));
    a->w = malloc((size_t)n_out * a->maxc * sizeof(float));
    a->cnt = a->first ? a->first + n_out : NULL;
    return a->first && a->w && btf_area_weights(n_in, n_out, a->first, a->cnt, a->w, a->maxc) == 0;
}

/* src (sw x sh RGB floats) box-filtered to dst (dw x dh, dw <= sw, dh <= sh): each
 * output pixel the mean of the source area it covers, rows first, then columns. */
static btf_result btf__shrink(const float *src, int sw, int sh, float *dst, int dw, int dh, btf_error *err)
{
    btf__axis ax = {0}, ay = {0};
    float *rows = calloc((size_t)sh * dw * 3, sizeof(float)); /* sh rows of dw pixels */
    btf_result r = BTF_OK;
    if (!rows || !btf__axis_make(&ax, sw, dw) || !btf__axis_make(&ay, sh, dh))
        r = btf_fail(err, BTF_ERR_NOMEM, "thumbnail: out of memory");
    for (int y = 0; r == BTF_OK && y < sh; y++)
        for (int x = 0; x < dw; x++)
            for (int s = 0; s < ax.cnt[x]; s++)
                for (int c = 0; c < 3; c++)
                    rows[((size_t)y * dw + x) * 3 + c] +=
                        ax.w[x * ax.maxc + s] * src[((size_t)y * sw + ax.first[x] + s) * 3 + c];
    if (r == BTF_OK)
        memset(dst, 0, (size_t)dw * dh * 3 * sizeof(float));
    for (int y = 0; r == BTF_OK && y < dh; y++)
        for (int s = 0; s < ay.cnt[y]; s++)
            for (size_t i = 0; i < (size_t)dw * 3; i++)
                dst[(size_t)y * dw * 3 + i] += ay.w[y * ay.maxc + s] * rows[(size_t)(ay.first[y] + s) * dw * 3 + i];
    free(rows), free(ax.first), free(ax.w), free(ay.first), free(ay.w);
    return r;
}

/* The thumbnail's size for a w x h material: the longer side max_side when it is
 * longer than that, the other in proportion (at least 1); else the material's. */
static void btf__thumb_size(int w, int h, int max_side, int *tw, int *th)
{
    int longest = w > h ? w : h;
    *tw = w, *th = h;
    if (longest <= max_side)
        return;
    *tw = (int)lround((double)w * max_side / longest);
    *th = (int)lround((double)h * max_side / longest);
    *tw = *tw < 1 ? 1 : *tw;
    *th = *th < 1 ? 1 : *th;
}

btf_result btf_package_thumbnail_rgb(const btf_package *p, int max_side, int *w, int *h, uint8_t **rgb,
                                     btf_error *err)
{
    *rgb = NULL;
    if (!p || max_side < 1 || p->n_loaded < 1)
        return btf_fail(err, BTF_ERR_ARG, "thumbnail: needs a package with loaded chunks and a side >= 1");
    int W = p->width, H = p->height;
    btf__thumb_size(W, H, max_side, w, h);
    size_t n = (size_t)*w * *h * 3;
    float *full = malloc((size_t)W * H * 3 * sizeof(float));
    float *small = full && (*w != W || *h != H) ? malloc(n * sizeof(float)) : full;
    uint8_t *out = malloc(n);
    btf_result r = full && small && out ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "thumbnail: out of memory");
    if (r == BTF_OK)
        btf__decode_swatch(p, full);
    if (r == BTF_OK && small != full)
        r = btf__shrink(full, W, H, small, *w, *h, err); /* a linear package's mean is of radiance */
    if (r == BTF_OK)
        btf_package_to_source(p, small, n);
    for (size_t i = 0; r == BTF_OK && i < n; i++)
        out[i] = btf_to_u8(small[i]);
    if (small != full)
        free(small);
    free(full);
    if (r != BTF_OK)
        free(out), out = NULL;
    *rgb = out;
    return r;
}

btf_result btf_package_thumbnail(const char *dir, int max_side, btf_error *err)
{
    char path[BTF_FS_PATH_MAX];
    if (!dir || snprintf(path, sizeof path, "%s/thumbnail.png", dir) >= (int)sizeof path)
        return btf_fail(err, BTF_ERR_ARG, "thumbnail: no package directory, or its path is too long");
    btf_package *p = NULL;
    btf_result r = btf_package_read(dir, 0, &p, err);
    uint8_t *rgb = NULL;
    int w = 0, h = 0;
    if (r == BTF_OK)
        r = btf_package_thumbnail_rgb(p, max_side, &w, &h, &rgb, err);
    if (r == BTF_OK)
        r = btf_image_write(path, w, h, 3, 8, rgb, err);
    free(rgb);
    btf_package_free(p);
    return r;
}
