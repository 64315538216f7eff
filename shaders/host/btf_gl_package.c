/* btf_gl_package.c - uploads a package's loaded chunks into GL textures and sets the
 * uniforms of shaders/btf_decode.glsl (see btf_gl_package.h). */
#include "btf_gl_package.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_env.h"
#include "btf_lod.h"
#include "btf_common.h"

#include <math.h>
#include <stdint.h>

static void btf__nearest_params(const btf_gl_api *f, GLenum target)
{
    f->TexParameteri(target, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    f->TexParameteri(target, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    f->TexParameteri(target, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    f->TexParameteri(target, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

static int btf__quads(int slots) { return (slots + 3) / 4; }

/* Whether u_btf_tex is paired for g drawn with `filter` (shaders/README.md, "GPU layout"):
 * levels on nearest taps, where one texel read serves two levels; bilinear taps read each
 * level's own texels, so there and without levels RGBA16UI, half the memory. */
static int btf__paired(const btf_gl_package *g, int filter) { return g->n_levels > 1 && filter != 1; }

/* Chunks a prefix of n_chunks draws (0 or more than loaded: all loaded). */
static int btf__prefix(const btf_gl_package *g, int n_chunks)
{
    return n_chunks <= 0 || n_chunks > g->n_loaded ? g->n_loaded : n_chunks;
}

/* Slots among the first n loaded chunks (0 if none). */
static int btf__slots_used(const btf_gl_package *g, int n)
{
    int used = 0;
    for (int j = 0; j < n; j++)
        used = g->chunk_slot[j] + 1 > used ? g->chunk_slot[j] + 1 : used;
    return used;
}

/* Component of slot s: that of the slot's first chunk. */
static int btf__slot_component(const btf_gl_package *g, const btf_package *p, int s)
{
    for (int j = 0; j < g->n_loaded; j++)
        if (g->chunk_slot[j] == s)
            return p->chunk[j].component;
    return -1;
}

/* The 16-bit grid of slot s: lo = the smallest lo, step = the span of every chunk of
 * its component in the manifest (all blocks, all levels) over 65535. */
static void btf__tex_grid(const btf_gl_package *g, const btf_package *p, int s, float *lo, float *step)
{
    int c = btf__slot_component(g, p, s);
    float qmax = (float)((1 << p->bits) - 1), a = 1e30f, b = -1e30f;
    for (int i = 0; i < p->n_chunks; i++)
        if (p->version < 2 ? i == s : p->chunk[i].component == c)
            for (int k = 0; k < g->n_blocks; k++) {
                a = fminf(a, p->chunk[i].tex_range[2 * k]);
                b = fmaxf(b, p->chunk[i].tex_range[2 * k] + p->chunk[i].tex_range[2 * k + 1] * qmax);
            }
    *lo = a <= b ? a : 0.0f;
    *step = a < b ? (b - a) / 65535.0f : 0.0f;
}

/* Chunk of slot s at level l among the first n loaded chunks (-1 if none) and the
 * slot's loaded range [fine, coarse] there (coarse -1: none). */
static int btf__slot_chunk(const btf_gl_package *g, int n, int s, int l, int *fine, int *coarse)
{
    int at = -1;
    *fine = g->n_levels, *coarse = -1;
    for (int j = n - 1; j >= 0; j--)
        if (g->chunk_slot[j] == s) {
            at = g->chunk_level[j] == l ? j : at;
            *fine = g->chunk_level[j] < *fine ? g->chunk_level[j] : *fine;
            *coarse = g->chunk_level[j] > *coarse ? g->chunk_level[j] : *coarse;
        }
    return at;
}

/* Slot s at mip level l into channel s % 4 of its layer's texels: each texel takes
 * the slot's nearest loaded level (btf_decode does the same). */
static void btf__pack_slot(const btf_gl_package *g, const btf_package *p, int n, int s, int l, uint16_t *dst)
{
    int fine, coarse;
    btf__slot_chunk(g, n, s, l, &fine, &coarse);
    if (coarse < 0)
        return;
    int lam = l < fine ? fine : l > coarse ? coarse : l, dummy0, dummy1;
    const float *src = p->tex[btf__slot_chunk(g, n, s, lam, &dummy0, &dummy1)];
    float lo = g->tq[(s / 4) * 8 + s % 4], step = g->tq[(s / 4) * 8 + 4 + s % 4]; /* btf__tex_grid, at upload */
    int wl = g->width >> l, hl = g->height >> l, wm = g->width >> lam, hm = g->height >> lam;
    int aw = wl * g->atlas_cols, ah = hl * g->atlas_rows;
    for (int y = 0; y < ah; y++)
        for (int x = 0; x < aw; x++) {
            int b = (y / hl) * g->atlas_cols + x / wl;
            if (b >= g->n_blocks)
                continue;
            int xm = btf_lod_texel_of(x % wl, l, lam), ym = btf_lod_texel_of(y % hl, l, lam);
            float t = src[((size_t)b * hm + ym) * wm + xm];
            float q = step > 0.0f ? rintf((t - lo) / step) : 0.0f;
            dst[((size_t)y * aw + x) * 4 + s % 4] = (uint16_t)(q < 0.0f ? 0.0f : q > 65535.0f ? 65535.0f : q);
        }
}

/* Layer k of u_btf_tex at level l for the first n loaded chunks: its 4 slots' 16-bit
 * values into buf (RGBA, the level's atlas). */
static void btf__pack_layer(const btf_gl_package *g, const btf_package *p, int n, int k, int l, uint16_t *buf)
{
    size_t texels = (size_t)(g->width >> l) * g->atlas_cols * (g->height >> l) * g->atlas_rows;
    memset(buf, 0, texels * 4 * sizeof(uint16_t));
    for (int s = 4 * k; s < 4 * k + 4 && s < g->n_chunks; s++)
        btf__pack_slot(g, p, n, s, l, buf);
}

/* The RGBA32UI texels of a level with levels (shaders/README.md, "GPU layout"): level
 * l's values q (aw x ah) in bits 0..15, those of texel (x / 2, y / 2) of level l + 1
 * (next, aw / 2 wide; NULL at the top level: 0) in bits 16..31. */
static void btf__pair_levels(const uint16_t *q, const uint16_t *next, int aw, int ah, uint32_t *out)
{
    for (int y = 0; y < ah; y++)
        for (int x = 0; x < aw; x++)
            for (int c = 0; c < 4; c++) {
                size_t i = ((size_t)y * aw + x) * 4 + c;
                uint32_t hi = next ? next[((size_t)(y / 2) * (aw / 2) + x / 2) * 4 + c] : 0;
                out[i] = q[i] | hi << 16;
            }
}

/* u_btf_tex for the first n loaded chunks: every layer (4 slots), every level; paired
 * (g->paired), each level with the next coarser one, coarsest first. */
static btf_result btf__pack_textures(btf_gl *gl, const btf_gl_package *g, const btf_package *p, int n, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int quads = btf__quads(g->n_chunks), paired = g->paired;
    size_t texels = (size_t)g->width * g->atlas_cols * g->height * g->atlas_rows;
    uint16_t *buf = malloc(texels * 4 * sizeof(uint16_t) * (paired ? 2 : 1)); /* paired: the level above next */
    uint32_t *pair = paired ? malloc(texels * 4 * sizeof(uint32_t)) : NULL;
    if (!buf || (paired && !pair)) {
        free(buf), free(pair);
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    }
    uint16_t *next = paired ? buf + texels * 4 : NULL;
    GLint was = 0; /* the caller's binding on the active unit (a bound sampler's) is kept */
    f->GetIntegerv(GL_TEXTURE_BINDING_2D_ARRAY, &was);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->tex);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    for (int k = 0; k < quads; k++)
        for (int l = g->n_levels - 1; l >= 0; l--) {
            int aw = (g->width >> l) * g->atlas_cols, ah = (g->height >> l) * g->atlas_rows;
            btf__pack_layer(g, p, n, k, l, buf);
            if (paired) {
                btf__pair_levels(buf, l < g->n_levels - 1 ? next : NULL, aw, ah, pair);
                memcpy(next, buf, (size_t)aw * ah * 4 * sizeof(uint16_t));
            }
            f->TexSubImage3D(GL_TEXTURE_2D_ARRAY, l, 0, 0, k, aw, ah, 1, GL_RGBA_INTEGER,
                             paired ? GL_UNSIGNED_INT : GL_UNSIGNED_SHORT, paired ? (void *)pair : (void *)buf);
        }
    f->BindTexture(GL_TEXTURE_2D_ARRAY, (GLuint)was);
    free(buf), free(pair);
    return btf_gl_check(gl, "uploading the packed textures", err);
}

/* Every level of u_btf_tex (re)specified empty, paired (RGBA32UI) or not (RGBA16UI):
 * the texture keeps its name, its parameters and the caller's binding. */
static void btf__tex_storage(const btf_gl_api *f, btf_gl_package *g, int paired)
{
    int aw = g->atlas_cols * g->width, ah = g->atlas_rows * g->height, quads = btf__quads(g->n_chunks);
    GLint was = 0;
    f->GetIntegerv(GL_TEXTURE_BINDING_2D_ARRAY, &was);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->tex);
    for (int l = 0; l < g->n_levels; l++)
        f->TexImage3D(GL_TEXTURE_2D_ARRAY, l, paired ? GL_RGBA32UI : GL_RGBA16UI, aw >> l, ah >> l, quads, 0,
                      GL_RGBA_INTEGER, paired ? GL_UNSIGNED_INT : GL_UNSIGNED_SHORT, NULL);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, (GLuint)was);
    g->paired = paired;
}

/* u_btf_tex, laid out for the default settings (nearest: paired where there are levels). */
static btf_result btf__upload_atlas(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    g->tq = calloc((size_t)btf__quads(g->n_chunks) * 8, sizeof(float));
    if (!g->tq)
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    for (int s = 0; s < g->n_chunks; s++)
        btf__tex_grid(g, p, s, &g->tq[(s / 4) * 8 + s % 4], &g->tq[(s / 4) * 8 + 4 + s % 4]);
    f->GenTextures(1, &g->tex);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->tex);
    btf__tex_storage(f, g, btf__paired(g, 0));
    btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
    if (g->n_levels > 1) { /* mipmap complete: texelFetch may read levels 0..N-1 */
        f->TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST_MIPMAP_NEAREST);
        f->TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAX_LEVEL, g->n_levels - 1);
    }
    btf_result r = btf_gl_check(gl, "allocating the texture atlas array", err);
    return r == BTF_OK ? btf__pack_textures(gl, g, p, p->n_loaded, err) : r;
}

/* Weights of slot s (its first chunk holds the most precise loaded; btf_decode reads
 * the same) on its own grid per channel: 11, 11 and 10 bits. */
static void btf__pack_weights_slot(btf_gl_package *g, const btf_package *p, const float *w, int s, uint32_t *dst)
{
    int n = p->lights.n_dirs * p->views.n_dirs;
    static const float qmax[3] = {2047.0f, 2047.0f, 1023.0f};
    static const int shift[3] = {0, 11, 22};
    for (int c = 0; c < 3; c++) {
        float lo = 1e30f, hi = -1e30f;
        for (int i = 0; i < n; i++)
            lo = fminf(lo, w[i * 3 + c]), hi = fmaxf(hi, w[i * 3 + c]);
        float step = hi > lo ? (hi - lo) / qmax[c] : 0.0f;
        g->wq[(s / 4) * 24 + c * 4 + s % 4] = lo;
        g->wq[(s / 4) * 24 + 12 + c * 4 + s % 4] = step;
        for (int i = 0; i < n; i++) {
            float q = step > 0.0f ? rintf((w[i * 3 + c] - lo) / step) : 0.0f;
            dst[(size_t)i * 4 + s % 4] |= (uint32_t)(q < 0.0f ? 0.0f : q > qmax[c] ? qmax[c] : q) << shift[c];
        }
    }
}

/* Mean squares of chunk j's texture values and of its weights per channel. */
static void btf__mean_squares(const btf_package *p, int j, double ms[4])
{
    size_t nt = (size_t)p->blocks->n_blocks * (p->width >> p->chunk[j].level) * (p->height >> p->chunk[j].level);
    size_t nw = (size_t)p->lights.n_dirs * p->views.n_dirs;
    for (size_t i = 0; i < nt; i++)
        ms[0] += (double)p->tex[j][i] * p->tex[j][i] / (double)nt;
    for (size_t i = 0; i < nw * 3; i++)
        ms[1 + i % 3] += (double)p->wt[j][i] * p->wt[j][i] / (double)nw;
}

static btf_result btf__upload_weights(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int L = p->lights.n_dirs, V = p->views.n_dirs, quads = btf__quads(g->n_chunks);
    g->wq = calloc((size_t)quads * 24, sizeof(float));
    uint32_t *buf = calloc((size_t)L * V * 4 * quads, sizeof(uint32_t));
    if (!g->wq || !buf) {
        free(buf);
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    }
    g->ms = calloc((size_t)g->n_chunks * 4, sizeof(double));
    if (!g->ms) {
        free(buf);
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    }
    for (int j = 0, next = 0; j < p->n_loaded; j++) /* layout (v*L + l)*3 + c */
        if (g->chunk_slot[j] == next) {
            btf__mean_squares(p, j, g->ms + 4 * next);
            btf__pack_weights_slot(g, p, p->wt[j], next, buf + (size_t)L * V * 4 * (next / 4));
            next++;
        }
    f->GenTextures(1, &g->wt);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->wt);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    f->TexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA32UI, L, V, quads, 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT, buf);
    btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
    free(buf);
    return btf_gl_check(gl, "uploading the weights", err);
}

/* G_j of doc/lighting.md section 3 for one slot from its weights w (layout
 * (v*L + l)*3 + ch) into g (layout (v*9 + j)*3 + ch); m: the light cells
 * (btf_env_cells). Returns the largest |G|. */
static double btf__env_g(int L, int V, const float *w, const double *m, float *g)
{
    double big = 0.0;
    for (int v = 0; v < V; v++)
        for (int j = 0; j < BTF_ENV_FUNCS; j++)
            for (int ch = 0; ch < 3; ch++) {
                double sum = 0.0;
                for (int l = 0; l < L; l++)
                    sum += w[((size_t)v * L + l) * 3 + ch] * m[(size_t)l * BTF_ENV_FUNCS + j];
                sum /= 3.14159265358979323846;
                g[((size_t)v * BTF_ENV_FUNCS + j) * 3 + ch] = (float)sum;
                big = fmax(big, fabs(sum));
            }
    return big;
}

/* One slot's G at scale s into its channel (slot % 4) of buf, the layer of its 4:
 * texel (j, v) = R | G << 11 | B << 22, codes m + round(G / s * (m - 1)) with m =
 * 1024, 1024, 512 (shaders/btf_light.glsl). */
static void btf__env_pack(int V, const float *g, double s, int slot, uint32_t *buf)
{
    static const int mid[3] = {1024, 1024, 512}, shift[3] = {0, 11, 22};
    for (int v = 0; v < V; v++)
        for (int j = 0; j < BTF_ENV_FUNCS; j++) {
            uint32_t u = 0;
            for (int ch = 0; ch < 3; ch++) {
                long q = mid[ch] + lrint(g[((size_t)v * BTF_ENV_FUNCS + j) * 3 + ch] / s * (mid[ch] - 1));
                u |= (uint32_t)q << shift[ch];
            }
            buf[((size_t)v * BTF_ENV_FUNCS + j) * 4 + slot % 4] = u;
        }
}

/* u_btf_env_w: RGBA32UI array, 9 x V, layer h = slots 4h..4h+3; u_btf_env_s their scales. */
static btf_result btf__upload_env_weights(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int L = p->lights.n_dirs, V = p->views.n_dirs, quads = btf__quads(g->n_chunks);
    size_t layer = (size_t)V * BTF_ENV_FUNCS * 4;
    double *m = malloc((size_t)L * BTF_ENV_FUNCS * sizeof *m);
    float *gv = malloc((size_t)V * BTF_ENV_FUNCS * 3 * sizeof(float));
    uint32_t *buf = calloc(layer * quads, sizeof(uint32_t));
    g->env_s = calloc((size_t)quads * 4, sizeof(float));
    btf_result r = m && gv && buf && g->env_s ? btf_env_cells(&p->lights, m, err)
                                              : btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    for (int j = 0, next = 0; r == BTF_OK && j < p->n_loaded; j++)
        if (g->chunk_slot[j] == next) {
            double big = btf__env_g(L, V, p->wt[j], m, gv);
            g->env_s[next] = big > 0.0 ? (float)big : 1.0f;
            btf__env_pack(V, gv, g->env_s[next], next, buf + layer * (next / 4));
            next++;
        }
    if (r == BTF_OK) {
        f->GenTextures(1, &g->env_w);
        f->BindTexture(GL_TEXTURE_2D_ARRAY, g->env_w);
        f->TexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA32UI, BTF_ENV_FUNCS, V, quads, 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT,
                      buf);
        btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
        r = btf_gl_check(gl, "uploading the environment weights", err);
    }
    free(m), free(gv), free(buf);
    return r;
}

/* The direction tables (the same btf_dirtab the CPU decoder reads) and the horizon. */
static btf_result btf__upload_dirs(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    btf_dirtab *tl = NULL, *tv = NULL;
    btf_result r = p->dirtab[0] ? BTF_OK : btf_dirtab_build(&p->lights, &tl, err);
    if (r == BTF_OK && !p->dirtab[1])
        r = btf_dirtab_build(&p->views, &tv, err);
    if (r == BTF_OK)
        r = btf_gl_dirs_upload(gl, tl ? tl : p->dirtab[0], tv ? tv : p->dirtab[1], p->blocks->block_of_view,
                               &g->dirs, err);
    btf_dirtab_free(tl);
    btf_dirtab_free(tv);
    g->outer_cos = cosf(btf_dirset_max_theta(&p->lights) * 0.017453292519943295f);
    return r;
}

/* Slot and level of every loaded chunk (version 1: slot = chunk, level 0); checks
 * that each prefix loads contiguous levels of each component, each level once. */
static btf_result btf__make_slots(btf_gl_package *g, const btf_package *p, const char *dir, btf_error *err)
{
    int n = p->n_loaded;
    g->chunk_slot = calloc((size_t)n, sizeof(int));
    g->chunk_level = calloc((size_t)n, sizeof(int));
    if (!g->chunk_slot || !g->chunk_level)
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    g->n_chunks = 0;
    for (int j = 0; j < n; j++) {
        int lv = p->chunk[j].level, s = g->n_chunks, fine = g->n_levels, coarse = -1;
        if (lv < 0 || lv >= g->n_levels)
            return btf_fail(err, BTF_ERR_FORMAT, "gl package: %s: chunk %d has level %d of %d", dir, j, lv,
                            g->n_levels);
        for (int e = 0; e < j && p->version >= 2; e++)
            if (p->chunk[e].component == p->chunk[j].component) {
                s = g->chunk_slot[e];
                fine = g->chunk_level[e] < fine ? g->chunk_level[e] : fine;
                coarse = g->chunk_level[e] > coarse ? g->chunk_level[e] : coarse;
            }
        if (coarse >= 0 && lv != fine - 1 && lv != coarse + 1)
            return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl package: %s: chunk %d (component %d, level %d) does not "
                            "extend the loaded levels %d..%d of its component", dir, j, p->chunk[j].component, lv,
                            fine, coarse);
        g->chunk_slot[j] = s;
        g->chunk_level[j] = lv;
        if (s == g->n_chunks)
            g->n_chunks++;
    }
    return BTF_OK;
}

void btf_gl_package_free(btf_gl *gl, btf_gl_package *g)
{
    if (!g)
        return;
    btf_gl_texture_free(gl, g->tex);
    btf_gl_texture_free(gl, g->wt);
    btf_gl_texture_free(gl, g->env_w);
    btf_gl_dirs_free(gl, &g->dirs);
    free(g->chunk_slot);
    free(g->chunk_level);
    free(g->tq);
    free(g->wq);
    free(g->ms);
    free(g->env_s);
    free(g);
}

btf_result btf_gl_package_upload(btf_gl *gl, const btf_package *p, const char *dir, btf_gl_package **out,
                                 btf_error *err)
{
    if (!gl || !p || !dir || !out)
        return btf_fail(err, BTF_ERR_ARG, "gl package: NULL argument");
    *out = NULL;
    if (p->n_loaded < 1)
        return btf_fail(err, BTF_ERR_ARG, "gl package: %s has no loaded chunk", dir);
    if (p->bits != 8 && p->bits != 16)
        return btf_fail(err, BTF_ERR_FORMAT, "gl package: %d-bit textures unsupported", p->bits);
    if (p->n_levels < 1 || p->n_levels > 15)
        return btf_fail(err, BTF_ERR_FORMAT, "gl package: %s: %d levels", dir, p->n_levels);
    btf_gl_package *g = calloc(1, sizeof *g);
    if (!g)
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    g->width = p->width;
    g->height = p->height;
    g->n_blocks = p->blocks->n_blocks;
    g->atlas_cols = p->atlas_cols;
    g->atlas_rows = p->atlas_rows;
    g->src = p;
    g->bits = p->bits;
    g->n_levels = p->n_levels;
    g->n_loaded = p->n_loaded;
    g->lights = p->lights;
    g->views = p->views;
    btf_result r = btf__make_slots(g, p, dir, err);
    if (r == BTF_OK)
        r = btf__upload_atlas(gl, g, p, err);
    if (r == BTF_OK)
        r = btf__upload_weights(gl, g, p, err);
    if (r == BTF_OK)
        r = btf__upload_env_weights(gl, g, p, err);
    if (r == BTF_OK)
        r = btf__upload_dirs(gl, g, p, err);
    if (r != BTF_OK)
        btf_gl_package_free(gl, g), g = NULL;
    *out = g;
    return r;
}

static void btf__set_int(const btf_gl_api *f, const btf_shader_program *prog, const char *name, int v)
{
    GLint loc = f->GetUniformLocation(prog->id, name);
    if (loc >= 0)
        f->Uniform1i(loc, v);
}

btf_result btf_gl_package_bind(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog, int first_unit,
                               btf_error *err)
{
    if (!gl || !g || !prog)
        return btf_fail(err, BTF_ERR_ARG, "gl package: NULL argument");
    const btf_gl_api *f = btf_gl_fn(gl);
    static const char *names[2] = {"u_btf_tex", "u_btf_wt"};
    const GLuint tex[2] = {g->tex, g->wt};
    int env = f->GetUniformLocation(prog->id, "u_btf_env_w") >= 0;
    int fixed = f->GetUniformLocation(prog->id, "u_btf_lw") >= 0;
    for (int i = 0; i < 2; i++) {
        GLint loc = f->GetUniformLocation(prog->id, names[i]);
        if (loc < 0 && i == 1 && (env || fixed))
            continue; /* environment light alone, or the light blended per draw: no light weights */
        if (loc < 0)
            return btf_fail(err, BTF_ERR_MISSING, "shader '%s': no sampler %s", prog->name, names[i]);
        f->ActiveTexture((GLenum)(GL_TEXTURE0 + first_unit + i));
        f->BindTexture(GL_TEXTURE_2D_ARRAY, tex[i]);
        f->Uniform1i(loc, first_unit + i);
    }
    f->Uniform2i(f->GetUniformLocation(prog->id, "u_btf_size"), g->width, g->height);
    btf__set_int(f, prog, "u_btf_atlas_cols", g->atlas_cols);
    btf__set_int(f, prog, "u_btf_levels", g->n_levels);
    GLint oc = f->GetUniformLocation(prog->id, "u_btf_outer_cos");
    if (oc >= 0)
        f->Uniform1f(oc, g->outer_cos);
    GLint tq = f->GetUniformLocation(prog->id, "u_btf_tq");
    if (tq >= 0)
        f->Uniform4fv(tq, 2 * btf__quads(g->n_chunks), g->tq);
    GLint ew = f->GetUniformLocation(prog->id, "u_btf_env_w");
    if (ew >= 0) { /* programs lit by an environment */
        f->ActiveTexture((GLenum)(GL_TEXTURE0 + first_unit + 4));
        f->BindTexture(GL_TEXTURE_2D_ARRAY, g->env_w);
        f->Uniform1i(ew, first_unit + 4);
        GLint es = f->GetUniformLocation(prog->id, "u_btf_env_s");
        if (es >= 0)
            f->Uniform4fv(es, btf__quads(g->n_chunks), g->env_s);
    }
    btf__set_int(f, prog, "u_btf_linear", g->src->linear);
    btf_gl_decode_settings s = {g->n_levels > 1 && !g->paired, 0, 0}; /* the filter u_btf_tex is laid out for */
    btf_gl_package_settings(gl, g, prog, &s);
    btf_gl_package_lod(gl, prog, 0, 0.0f);
    btf_result r = btf_gl_dirs_bind(gl, &g->dirs, prog, first_unit + 2, err);
    if (r == BTF_OK)
        r = btf_gl_check(gl, "binding a package", err);
    return r;
}

void btf_gl_package_settings(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog,
                             const btf_gl_decode_settings *s)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int n = btf__prefix(g, s->n_chunks), used = btf__slots_used(g, n);
    if (g->n_levels > 1) { /* the layout follows the filter; the prefix's loaded levels decide each slot's fill */
        btf_error err = {{0}};
        if (btf__paired(g, s->filter) != g->paired) /* the package's GPU state, not its contents */
            btf__tex_storage(f, (btf_gl_package *)g, btf__paired(g, s->filter));
        btf__pack_textures(gl, g, g->src, n, &err);
    }
    int quads = btf__quads(g->n_chunks);
    float *wq = malloc((size_t)quads * 24 * sizeof(float));
    if (wq) { /* slots beyond the prefix: zero weights */
        memcpy(wq, g->wq, (size_t)quads * 24 * sizeof(float));
        for (int k = used; k < 4 * quads; k++)
            for (int c = 0; c < 6; c++)
                wq[(k / 4) * 24 + c * 4 + k % 4] = 0.0f;
        GLint loc = f->GetUniformLocation(prog->id, "u_btf_wq");
        if (loc >= 0)
            f->Uniform4fv(loc, 6 * quads, wq);
        free(wq);
    }
    btf__set_int(f, prog, "u_btf_filter", s->filter);
    btf__set_int(f, prog, "u_btf_wrap", s->wrap);
    btf__set_int(f, prog, "u_btf_chunks", used);
}

void btf_gl_package_lod(btf_gl *gl, const btf_shader_program *prog, int fixed, float lod)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf__set_int(f, prog, "u_btf_lod_auto", !fixed);
    GLint loc = f->GetUniformLocation(prog->id, "u_btf_lod");
    if (loc >= 0)
        f->Uniform1f(loc, lod);
}

void btf_gl_package_quant_error(const btf_gl_package *g, double *worst, double *rms)
{
    static const double qmax[3] = {2047.0, 2047.0, 1023.0};
    *worst = *rms = 0.0;
    for (int c = 0; c < 3 && g; c++) {
        double e = 0.0, v = 0.0;
        for (int s = 0; s < g->n_chunks; s++) {
            const float *tq = g->tq + (s / 4) * 8, *wq = g->wq + (s / 4) * 24;
            double tlo = tq[s % 4], tst = tq[4 + s % 4], wlo = wq[c * 4 + s % 4], wst = wq[12 + c * 4 + s % 4];
            double tmax = fmax(fabs(tlo), fabs(tlo + 65535.0 * tst)), wmax = fmax(fabs(wlo), fabs(wlo + qmax[c] * wst));
            e += tmax * wst / 2 + wmax * tst / 2 + tst * wst / 4;
            v += (g->ms[4 * s] * wst * wst + g->ms[4 * s + 1 + c] * tst * tst) / 12.0;
        }
        *worst = fmax(*worst, e);
        *rms = fmax(*rms, sqrt(v));
    }
}

int btf_gl_package_slots(const btf_gl_package *g, int n_chunks)
{
    int used = btf__slots_used(g, btf__prefix(g, n_chunks));
    return used > 0 ? used : 1;
}

float btf_gl_package_weight(const btf_gl_package *g, int s, int l, int v, int c)
{
    static const float qmax[3] = {2047.0f, 2047.0f, 1023.0f};
    int j = 0;
    while (j < g->n_loaded - 1 && g->chunk_slot[j] != s)
        j++; /* the slot's first chunk: the weights btf__upload_weights packed */
    float lo = g->wq[(s / 4) * 24 + c * 4 + s % 4], step = g->wq[(s / 4) * 24 + 12 + c * 4 + s % 4];
    float w = g->src->wt[j][((size_t)v * g->lights.n_dirs + l) * 3 + c];
    float q = step > 0.0f ? rintf((w - lo) / step) : 0.0f; /* as btf__pack_weights_slot rounds */
    q = q < 0.0f ? 0.0f : q > qmax[c] ? qmax[c] : q;
    return lo + step * q;
}

int btf_gl_package_defines(const btf_gl_package *g, int filter, int n_chunks, btf_shader_define *defs,
                           char vals[][16])
{
    int used = btf__slots_used(g, btf__prefix(g, n_chunks));
    used = used > 0 ? used : 1;
    static const char *names[BTF_GL_PACKAGE_DEFINES] = {"BTF_FILTER", "BTF_LEVELS", "BTF_QUADS"};
    int v[BTF_GL_PACKAGE_DEFINES] = {filter == 1, g->n_levels > 1, btf__quads(used)};
    for (int i = 0; i < BTF_GL_PACKAGE_DEFINES; i++) {
        snprintf(vals[i], 16, "%d", v[i]);
        defs[i].name = names[i];
        defs[i].value = vals[i];
    }
    return BTF_GL_PACKAGE_DEFINES;
}
