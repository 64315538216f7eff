/* btf_gl_package.c - uploads a package's loaded chunks into GL textures and sets the
 * uniforms of shaders/btf_decode.glsl (see btf_gl_package.h). */
#include "btf_gl_package.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_image.h"

static void btf__nearest_params(const btf_gl_api *f, GLenum target)
{
    f->TexParameteri(target, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    f->TexParameteri(target, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    f->TexParameteri(target, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    f->TexParameteri(target, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

/* The texture file of chunk j (the one named tex-*). */
static const char *btf__tex_file(const btf_package *p, int j)
{
    for (int i = 0; i < p->chunk[j].n_files; i++)
        if (!strncmp(p->chunk[j].files[i], "tex-", 4))
            return p->chunk[j].files[i];
    return NULL;
}

/* Mip level `level`, layer `slot` of the atlas array from chunk j's PNG, checked
 * against the manifest (level l atlas = (aw >> l) x (ah >> l)). */
static btf_result btf__upload_atlas_layer(btf_gl *gl, const btf_package *p, const char *dir, int j, int slot,
                                          int level, int aw, int ah, btf_error *err)
{
    const char *name = btf__tex_file(p, j);
    if (!name)
        return btf_fail(err, BTF_ERR_FORMAT, "gl package: chunk %d has no tex-* file", j);
    char path[1200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    int w = 0, h = 0, ch = 0;
    uint8_t *px = NULL;
    btf_result r = btf_image_read_u8(path, &w, &h, &ch, &px, err);
    if (r != BTF_OK)
        return r;
    int want_ch = p->bits == 16 ? 3 : 1;
    if (w != aw >> level || h != ah >> level || ch != want_ch) {
        free(px);
        return btf_fail(err, BTF_ERR_FORMAT, "gl package: %s is %dx%d with %d channels, expected %dx%d with %d", path,
                        w, h, ch, aw >> level, ah >> level, want_ch);
    }
    const btf_gl_api *f = btf_gl_fn(gl);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    f->TexSubImage3D(GL_TEXTURE_2D_ARRAY, level, 0, 0, slot, w, h, 1, want_ch == 3 ? GL_RGB : GL_RED,
                     GL_UNSIGNED_BYTE, px);
    free(px);
    return btf_gl_check(gl, "uploading a texture atlas layer", err);
}

static btf_result btf__upload_atlas(btf_gl *gl, btf_gl_package *g, const btf_package *p, const char *dir,
                                    btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int aw = p->atlas_cols * p->width, ah = p->atlas_rows * p->height;
    f->GenTextures(1, &g->tex);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->tex);
    for (int l = 0; l < g->n_levels; l++)
        f->TexImage3D(GL_TEXTURE_2D_ARRAY, l, p->bits == 16 ? GL_RGB8 : GL_R8, aw >> l, ah >> l, g->n_chunks, 0,
                      p->bits == 16 ? GL_RGB : GL_RED, GL_UNSIGNED_BYTE, NULL);
    btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
    if (g->n_levels > 1) { /* mipmap complete: texelFetch may read levels 0..N-1 */
        f->TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_NEAREST_MIPMAP_NEAREST);
        f->TexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAX_LEVEL, g->n_levels - 1);
    }
    btf_result r = btf_gl_check(gl, "allocating the texture atlas array", err);
    for (int j = 0; j < p->n_loaded && r == BTF_OK; j++)
        r = btf__upload_atlas_layer(gl, p, dir, j, g->chunk_slot[j], g->chunk_level[j], aw, ah, err);
    return r;
}

/* Layer s = the weights of slot s's first chunk (the reader keeps there the most
 * precise weights of the component loaded so far; btf_decode reads the same). */
static btf_result btf__upload_weights(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    f->GenTextures(1, &g->wt);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->wt);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    f->TexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGB32F, L, V, g->n_chunks, 0, GL_RGB, GL_FLOAT, NULL);
    btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
    for (int j = 0, next = 0; j < p->n_loaded; j++) /* layout (v*L + l)*3 + c is rows of L RGB texels */
        if (g->chunk_slot[j] == next)
            f->TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, next++, L, V, 1, GL_RGB, GL_FLOAT, p->wt[j]);
    return btf_gl_check(gl, "uploading the weights", err);
}

/* .zw of every texel of every slot = its loaded level range [fine, coarse] among the
 * first n chunks (0, 0 for a slot not among them); returns the slots among them. */
static int btf__fill_levels(btf_gl_package *g, int n)
{
    int N = g->n_levels, B = g->n_blocks, used = 0;
    for (int s = 0; s < g->n_chunks; s++) {
        int fine = N, coarse = -1;
        for (int i = 0; i < n; i++)
            if (g->chunk_slot[i] == s) {
                fine = g->chunk_level[i] < fine ? g->chunk_level[i] : fine;
                coarse = g->chunk_level[i] > coarse ? g->chunk_level[i] : coarse;
            }
        if (coarse < 0)
            fine = coarse = 0;
        else
            used = s + 1;
        for (size_t t = (size_t)s * N * B; t < (size_t)(s + 1) * N * B; t++) {
            g->range_host[t * 4 + 2] = (float)fine;
            g->range_host[t * 4 + 3] = (float)coarse;
        }
    }
    return used;
}

/* Range table (block, slot * N + level) and the view -> block map, as RGBA32F 2D textures. */
static btf_result btf__upload_tables(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    int B = g->n_blocks, V = p->views.n_dirs, rows = g->n_chunks * g->n_levels;
    g->range_host = calloc((size_t)B * (size_t)rows * 4, sizeof(float));
    float *vb = calloc((size_t)V * 4, sizeof(float));
    btf_result r = BTF_OK;
    if (!g->range_host || !vb)
        r = btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    for (int j = p->n_loaded - 1; j >= 0 && r == BTF_OK; j--) { /* the first chunk of a (slot, level) wins */
        float *row = g->range_host + (size_t)(g->chunk_slot[j] * g->n_levels + g->chunk_level[j]) * B * 4;
        for (int b = 0; b < B; b++) {
            row[b * 4 + 0] = p->chunk[j].tex_range[2 * b];
            row[b * 4 + 1] = p->chunk[j].tex_range[2 * b + 1];
        }
    }
    if (r == BTF_OK)
        btf__fill_levels(g, p->n_loaded);
    for (int v = 0; v < V && r == BTF_OK; v++)
        vb[(size_t)v * 4] = (float)p->blocks->block_of_view[v];
    if (r == BTF_OK)
        r = btf_gl_texture_create(gl, B, rows, BTF_GL_RGBA32F, g->range_host, &g->range, err);
    if (r == BTF_OK)
        r = btf_gl_texture_create(gl, V, 1, BTF_GL_RGBA32F, vb, &g->view_block, err);
    free(vb);
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
    btf_gl_texture_free(gl, g->range);
    btf_gl_texture_free(gl, g->view_block);
    free(g->chunk_slot);
    free(g->chunk_level);
    free(g->range_host);
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
    g->bits = p->bits;
    g->n_levels = p->n_levels;
    g->n_loaded = p->n_loaded;
    g->lights = p->lights;
    g->views = p->views;
    btf_result r = btf__make_slots(g, p, dir, err);
    if (r == BTF_OK)
        r = btf__upload_atlas(gl, g, p, dir, err);
    if (r == BTF_OK)
        r = btf__upload_weights(gl, g, p, err);
    if (r == BTF_OK)
        r = btf__upload_tables(gl, g, p, err);
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
    static const char *names[4] = {"u_btf_tex", "u_btf_wt", "u_btf_range", "u_btf_view_block"};
    const GLuint tex[4] = {g->tex, g->wt, g->range, g->view_block};
    const GLenum target[4] = {GL_TEXTURE_2D_ARRAY, GL_TEXTURE_2D_ARRAY, GL_TEXTURE_2D, GL_TEXTURE_2D};
    for (int i = 0; i < 4; i++) {
        GLint loc = f->GetUniformLocation(prog->id, names[i]);
        if (loc < 0)
            return btf_fail(err, BTF_ERR_MISSING, "shader '%s': no sampler %s", prog->name, names[i]);
        f->ActiveTexture((GLenum)(GL_TEXTURE0 + first_unit + i));
        f->BindTexture(target[i], tex[i]);
        f->Uniform1i(loc, first_unit + i);
    }
    f->Uniform2i(f->GetUniformLocation(prog->id, "u_btf_size"), g->width, g->height);
    btf__set_int(f, prog, "u_btf_atlas_cols", g->atlas_cols);
    btf__set_int(f, prog, "u_btf_bits", g->bits);
    btf__set_int(f, prog, "u_btf_levels", g->n_levels);
    btf_gl_decode_settings s = {0};
    btf_gl_package_settings(gl, g, prog, &s);
    btf_gl_package_lod(gl, prog, 0, 0.0f);
    btf_result r = btf_shader_set_dirset(gl, prog, "u_btf_lights", &g->lights, err);
    if (r == BTF_OK)
        r = btf_shader_set_dirset(gl, prog, "u_btf_views", &g->views, err);
    if (r == BTF_OK)
        r = btf_gl_check(gl, "binding a package", err);
    return r;
}

void btf_gl_package_settings(btf_gl *gl, const btf_gl_package *g, const btf_shader_program *prog,
                             const btf_gl_decode_settings *s)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int n = s->n_chunks <= 0 || s->n_chunks > g->n_loaded ? g->n_loaded : s->n_chunks;
    if (g->n_levels > 1) { /* the prefix's level ranges; the slots among the first n chunks */
        n = btf__fill_levels((btf_gl_package *)g, n);
        GLint was = 0;
        f->GetIntegerv(GL_TEXTURE_BINDING_2D, &was);
        f->BindTexture(GL_TEXTURE_2D, g->range);
        f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
        f->TexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, g->n_blocks, g->n_chunks * g->n_levels, GL_RGBA, GL_FLOAT,
                         g->range_host);
        f->BindTexture(GL_TEXTURE_2D, (GLuint)was);
    }
    btf__set_int(f, prog, "u_btf_filter", s->filter);
    btf__set_int(f, prog, "u_btf_wrap", s->wrap);
    btf__set_int(f, prog, "u_btf_chunks", n);
}

void btf_gl_package_lod(btf_gl *gl, const btf_shader_program *prog, int fixed, float lod)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf__set_int(f, prog, "u_btf_lod_auto", !fixed);
    GLint loc = f->GetUniformLocation(prog->id, "u_btf_lod");
    if (loc >= 0)
        f->Uniform1f(loc, lod);
}
