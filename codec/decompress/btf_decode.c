/* btf_decode.c - CPU reference decoder of a (possibly partial) package at any texel
 * and any (light, view) direction: doc/package-format.md section 6, the arithmetic
 * the GLSL decoder reproduces. */
#include <math.h>

#include "btf_package.h"
#include "btf_lod.h"
#include "btf_dirtab.h"
#include "btf_decode.h"

/* Up to 4 texels and their filter weights; value type. */
typedef struct btf__taps {
    int n;
    size_t idx[4]; /* y*W + x inside a tile */
    float w[4];
} btf__taps;

static int btf__wrap_or_clamp(int i, int n, int wrap)
{
    if (wrap) {
        i %= n;
        return i < 0 ? i + n : i;
    }
    return i < 0 ? 0 : i >= n ? n - 1 : i;
}

/* Coordinates far outside any tile are clamped before the float->int conversion. */
static float btf__sane(float t)
{
    if (!isfinite(t))
        return 0.0f;
    return t < -1e6f ? -1e6f : t > 1e6f ? 1e6f : t;
}

static btf__taps btf__texel_taps(const btf_package *p, float u, float v, const btf_decode_options *o, int level)
{
    btf__taps t = {0};
    int W = p->width >> level, H = p->height >> level;
    float fx = btf__sane(u) * (float)W, fy = btf__sane(v) * (float)H;
    if (o->filter != BTF_FILTER_BILINEAR) {
        int x = btf__wrap_or_clamp((int)floorf(fx), W, o->wrap), y = btf__wrap_or_clamp((int)floorf(fy), H, o->wrap);
        t.n = 1;
        t.idx[0] = (size_t)y * W + x;
        t.w[0] = 1.0f;
        return t;
    }
    fx -= 0.5f;
    fy -= 0.5f;
    float x0f = floorf(fx), y0f = floorf(fy), ax = fx - x0f, ay = fy - y0f;
    int x0 = (int)x0f, y0 = (int)y0f;
    int xs[2] = {btf__wrap_or_clamp(x0, W, o->wrap), btf__wrap_or_clamp(x0 + 1, W, o->wrap)};
    int ys[2] = {btf__wrap_or_clamp(y0, H, o->wrap), btf__wrap_or_clamp(y0 + 1, H, o->wrap)};
    t.n = 4;
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            t.idx[j * 2 + i] = (size_t)ys[j] * W + xs[i];
            t.w[j * 2 + i] = (i ? ax : 1.0f - ax) * (j ? ay : 1.0f - ay);
        }
    return t;
}

/* Filtered texture value of chunk j in block b (taps of the chunk's level). */
static float btf__tex(const btf_package *p, int j, int b, const btf__taps *t)
{
    const float *tile = p->tex[j] + (size_t)b * (p->width >> p->chunk[j].level) * (p->height >> p->chunk[j].level);
    float s = 0.0f;
    for (int i = 0; i < t->n; i++)
        s += t->w[i] * tile[t->idx[i]];
    return s;
}

/* Interpolation of set 0 (lights) or 1 (views): the package's direction table (the
 * GPU decoder's) when the reader built it, else the ring walk (same triangles). */
static btf_interp btf__interp(const btf_package *p, int set, const float v[3])
{
    const btf_dirtab *t = p->dirtab[set];
    return t ? btf_dirtab_interp_vec(t, v) : btf_dirset_interp_vec(set ? &p->views : &p->lights, v);
}

/* Level range [fine, coarse] loaded for component c among the first n chunks. */
static void btf__loaded_levels(const btf_package *p, int n, int c, int *fine, int *coarse)
{
    *fine = p->n_levels, *coarse = -1;
    for (int i = 0; i < n; i++)
        if (p->chunk[i].component == c) {
            *fine = p->chunk[i].level < *fine ? p->chunk[i].level : *fine;
            *coarse = p->chunk[i].level > *coarse ? p->chunk[i].level : *coarse;
        }
}

/* Level-l value of component c in block b with taps on level l's grid: the chunk of
 * level clamp(l, fine, coarse), texels mapped by btf_lod_texel_of. */
static float btf__tex_level(const btf_package *p, int n, int c, int b, int l, int fine, int coarse,
                            const btf__taps *t)
{
    int lam = l < fine ? fine : l > coarse ? coarse : l, j = btf_package_chunk_at(p, n, c, lam);
    int wl = p->width >> l, wm = p->width >> lam, hm = p->height >> lam;
    const float *tile = p->tex[j] + (size_t)b * wm * hm;
    float s = 0.0f;
    for (int i = 0; i < t->n; i++) {
        int x = (int)(t->idx[i] % (size_t)wl), y = (int)(t->idx[i] / (size_t)wl);
        s += t->w[i] * tile[(size_t)btf_lod_texel_of(y, l, lam) * wm + btf_lod_texel_of(x, l, lam)];
    }
    return s;
}

/* Version 2 (doc/package-format.md section 6): lod clamped to [0, N-1], trilinear
 * between floor(lod) and the next level; a level a component has not loaded takes
 * its nearest loaded level, texel by texel (btf_lod_texel_of). */
static void btf__decode_levels(const btf_package *p, float u, float v, const float light[3], const float view[3],
                               const btf_decode_options *o, int n, float rgb[3])
{
    btf_interp il = btf__interp(p, 0, light);
    btf_interp iv = btf__interp(p, 1, view);
    int L = p->lights.n_dirs, N = p->n_levels;
    float lod = isfinite(o->lod) ? o->lod : 0.0f;
    float lc = lod < 0.0f ? 0.0f : lod > (float)(N - 1) ? (float)(N - 1) : lod;
    int l0 = (int)floorf(lc), l1 = l0 + 1 > N - 1 ? N - 1 : l0 + 1;
    float f = lc - (float)l0;
    btf__taps t0 = btf__texel_taps(p, u, v, o, l0), t1 = btf__texel_taps(p, u, v, o, l1);
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    for (int j = 0; j < n; j++) {
        int c = p->chunk[j].component, fine, coarse, first = 1;
        for (int e = 0; e < j && first; e++)
            first = p->chunk[e].component != c;
        if (!first)
            continue; /* each component once, at its first chunk */
        btf__loaded_levels(p, n, c, &fine, &coarse);
        for (int a = 0; a < 3; a++) {
            if (iv.w[a] == 0.0f)
                continue;
            int vi = iv.idx[a], b = p->blocks->block_of_view[vi];
            float t = (1.0f - f) * btf__tex_level(p, n, c, b, l0, fine, coarse, &t0);
            if (f > 0.0f)
                t += f * btf__tex_level(p, n, c, b, l1, fine, coarse, &t1);
            for (int ch = 0; ch < 3; ch++) {
                float s = 0.0f;
                for (int e = 0; e < 3; e++)
                    if (il.w[e] != 0.0f)
                        s += il.w[e] * p->wt[j][((size_t)vi * L + il.idx[e]) * 3 + ch];
                rgb[ch] += iv.w[a] * t * s;
            }
        }
    }
}

void btf_decode(const btf_package *p, float u, float v, const float light[3], const float view[3],
                const btf_decode_options *opt, float rgb[3])
{
    btf_decode_options o = {0};
    if (opt)
        o = *opt;
    int n = o.n_chunks <= 0 || o.n_chunks > p->n_loaded ? p->n_loaded : o.n_chunks;
    if (p->n_levels > 1) {
        btf__decode_levels(p, u, v, light, view, &o, n, rgb);
        return;
    }
    btf__taps taps = btf__texel_taps(p, u, v, &o, 0);
    btf_interp il = btf__interp(p, 0, light);
    btf_interp iv = btf__interp(p, 1, view);
    int L = p->lights.n_dirs;
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    for (int a = 0; a < 3; a++) {
        if (iv.w[a] == 0.0f)
            continue;
        int vi = iv.idx[a], b = p->blocks->block_of_view[vi];
        for (int j = 0; j < n; j++) {
            float t = btf__tex(p, j, b, &taps);
            for (int c = 0; c < 3; c++) {
                float s = 0.0f; /* sum over the 3 lights of wl * Wt_j[vi][li][c] */
                for (int e = 0; e < 3; e++)
                    if (il.w[e] != 0.0f)
                        s += il.w[e] * p->wt[j][((size_t)vi * L + il.idx[e]) * 3 + c];
                rgb[c] += iv.w[a] * t * s;
            }
        }
    }
}
