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

/* Layer j of the atlas array from chunk j's PNG, checked against the manifest. */
static btf_result btf__upload_atlas_layer(btf_gl *gl, const btf_package *p, const char *dir, int j, int aw, int ah,
                                          btf_error *err)
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
    if (w != aw || h != ah || ch != want_ch) {
        free(px);
        return btf_fail(err, BTF_ERR_FORMAT, "gl package: %s is %dx%d with %d channels, expected %dx%d with %d", path,
                        w, h, ch, aw, ah, want_ch);
    }
    const btf_gl_api *f = btf_gl_fn(gl);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    f->TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, j, w, h, 1, want_ch == 3 ? GL_RGB : GL_RED, GL_UNSIGNED_BYTE, px);
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
    f->TexImage3D(GL_TEXTURE_2D_ARRAY, 0, p->bits == 16 ? GL_RGB8 : GL_R8, aw, ah, p->n_loaded, 0,
                  p->bits == 16 ? GL_RGB : GL_RED, GL_UNSIGNED_BYTE, NULL);
    btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
    btf_result r = btf_gl_check(gl, "allocating the texture atlas array", err);
    for (int j = 0; j < p->n_loaded && r == BTF_OK; j++)
        r = btf__upload_atlas_layer(gl, p, dir, j, aw, ah, err);
    return r;
}

static btf_result btf__upload_weights(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    f->GenTextures(1, &g->wt);
    f->BindTexture(GL_TEXTURE_2D_ARRAY, g->wt);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    f->TexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGB32F, L, V, p->n_loaded, 0, GL_RGB, GL_FLOAT, NULL);
    btf__nearest_params(f, GL_TEXTURE_2D_ARRAY);
    for (int j = 0; j < p->n_loaded; j++) /* layout (v*L + l)*3 + c is rows of L RGB texels */
        f->TexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, j, L, V, 1, GL_RGB, GL_FLOAT, p->wt[j]);
    return btf_gl_check(gl, "uploading the weights", err);
}

/* Range table (block, chunk) and the view -> block map, as RGBA32F 2D textures. */
static btf_result btf__upload_tables(btf_gl *gl, btf_gl_package *g, const btf_package *p, btf_error *err)
{
    int B = p->blocks->n_blocks, V = p->views.n_dirs, n = p->n_loaded;
    float *range = calloc((size_t)B * (size_t)n * 4, sizeof(float));
    float *vb = calloc((size_t)V * 4, sizeof(float));
    btf_result r = BTF_OK;
    if (!range || !vb)
        r = btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    for (int j = 0; j < n && r == BTF_OK; j++)
        for (int b = 0; b < B; b++) {
            range[((size_t)j * B + b) * 4 + 0] = p->chunk[j].tex_range[2 * b];
            range[((size_t)j * B + b) * 4 + 1] = p->chunk[j].tex_range[2 * b + 1];
        }
    for (int v = 0; v < V && r == BTF_OK; v++)
        vb[(size_t)v * 4] = (float)p->blocks->block_of_view[v];
    if (r == BTF_OK)
        r = btf_gl_texture_create(gl, B, n, BTF_GL_RGBA32F, range, &g->range, err);
    if (r == BTF_OK)
        r = btf_gl_texture_create(gl, V, 1, BTF_GL_RGBA32F, vb, &g->view_block, err);
    free(range);
    free(vb);
    return r;
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
    for (int j = 0; j < p->n_loaded; j++) /* spatial levels (version 2) are not uploaded yet */
        if (p->chunk[j].level != 0)
            return btf_fail(err, BTF_ERR_UNSUPPORTED, "gl package: %s: chunk %d is spatial level %d (version 2 "
                            "packages cannot be drawn by the shaders yet)", dir, j, p->chunk[j].level);
    btf_gl_package *g = calloc(1, sizeof *g);
    if (!g)
        return btf_fail(err, BTF_ERR_NOMEM, "gl package: out of memory");
    g->width = p->width;
    g->height = p->height;
    g->n_blocks = p->blocks->n_blocks;
    g->atlas_cols = p->atlas_cols;
    g->bits = p->bits;
    g->n_chunks = p->n_loaded;
    g->lights = p->lights;
    g->views = p->views;
    btf_result r = btf__upload_atlas(gl, g, p, dir, err);
    if (r == BTF_OK)
        r = btf__upload_weights(gl, g, p, err);
    if (r == BTF_OK)
        r = btf__upload_tables(gl, g, p, err);
    if (r != BTF_OK) {
        btf_gl_package_free(gl, g);
        return r;
    }
    *out = g;
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
    free(g);
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
    btf_gl_decode_settings s = {0};
    btf_gl_package_settings(gl, g, prog, &s);
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
    int n = s->n_chunks <= 0 || s->n_chunks > g->n_chunks ? g->n_chunks : s->n_chunks;
    btf__set_int(f, prog, "u_btf_filter", s->filter);
    btf__set_int(f, prog, "u_btf_wrap", s->wrap);
    btf__set_int(f, prog, "u_btf_chunks", n);
}
