/* btf_gl_dirs.c - direction tables on the GPU (btf_gl_dirs.h). */
#include "btf_gl_dirs.h"
#include "btf_common.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define BTF__CELLS BTF_DIRTAB_CELLS
#define BTF__TRI_W 1024 /* u_btf_dir_tris row length */

/* Texel of triangle i of t: vertices and neighbours offset by the set's bases. */
static void btf__tri_texel(const btf_dirtab *t, int i, int vbase, int tbase, uint32_t out[4])
{
    uint32_t n[3];
    for (int e = 0; e < 3; e++)
        n[e] = t->adj[i][e] < 0 ? 0xFFFFu : (uint32_t)(t->adj[i][e] + tbase);
    out[0] = (uint32_t)(t->tri[i][0] + vbase) | (uint32_t)(t->tri[i][1] + vbase) << 16;
    out[1] = (uint32_t)(t->tri[i][2] + vbase);
    out[2] = n[0] | n[1] << 16;
    out[3] = n[2];
}

/* One set's vertices into the block: xyz, w = direction + 1 (0 virtual) + 4096 * block. */
static void btf__verts(const btf_dirtab *t, const int *block, float *dst)
{
    for (int v = 0; v < t->n_verts; v++) {
        memcpy(dst + 4 * v, t->vert[v], 3 * sizeof(float));
        int d = t->vert[v][3] > 0.0f ? t->dir[v] : -1;
        dst[4 * v + 3] = d >= 0 ? (float)(d + 1 + 4096 * (block ? block[d] : 0)) : 0.0f;
    }
}

btf_result btf_gl_dirs_upload(btf_gl *gl, const btf_dirtab *lights, const btf_dirtab *views, const int *view_block,
                              btf_gl_dirs *out, btf_error *err)
{
    if (!gl || !lights || !out)
        return btf_fail(err, BTF_ERR_ARG, "gl dirs: NULL argument");
    memset(out, 0, sizeof *out);
    btf_dirtab none = {0};
    views = views ? views : &none;
    int nv = lights->n_verts + views->n_verts, nt = lights->n_tris + views->n_tris;
    if (nv > BTF_GL_MAX_VERTS || nt >= 0xFFFF || lights->n_dirs >= 4096 || views->n_dirs >= 4096)
        return btf_fail(err, BTF_ERR_RANGE, "gl dirs: %d + %d directions: the GPU tables hold at most %d in all",
                        lights->n_dirs, views->n_dirs, BTF_GL_MAX_VERTS - 4);
    const btf_dirtab *set[2] = {lights, views};
    int vbase[2] = {0, lights->n_verts}, tbase[2] = {0, lights->n_tris}, rows = (nt + BTF__TRI_W - 1) / BTF__TRI_W;
    float *verts = calloc((size_t)BTF_GL_MAX_VERTS * 4, sizeof(float));
    uint32_t *cells = calloc((size_t)BTF__CELLS * BTF__CELLS * 2 * 4, sizeof(uint32_t));
    uint32_t *tris = calloc((size_t)(rows > 0 ? rows : 1) * BTF__TRI_W * 4, sizeof(uint32_t));
    btf_result r = verts && cells && tris ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "gl dirs: out of memory");
    for (int s = 0; s < 2 && r == BTF_OK; s++) {
        btf__verts(set[s], s ? view_block : NULL, verts + 4 * vbase[s]);
        for (int i = 0; i < set[s]->n_tris; i++)
            btf__tri_texel(set[s], i, vbase[s], tbase[s], tris + 4 * (size_t)(tbase[s] + i));
        for (int c = 0; c < BTF__CELLS * BTF__CELLS && set[s]->n_tris > 0; c++)
            btf__tri_texel(set[s], set[s]->cell[c], vbase[s], tbase[s], cells + 4 * (size_t)(s * BTF__CELLS * BTF__CELLS + c));
    }
    const btf_gl_api *f = btf_gl_fn(gl);
    if (r == BTF_OK) {
        f->GenBuffers(1, &out->ubo);
        f->BindBuffer(GL_UNIFORM_BUFFER, out->ubo);
        f->BufferData(GL_UNIFORM_BUFFER, (GLsizeiptr)(BTF_GL_MAX_VERTS * 4 * sizeof(float)), verts, GL_STATIC_DRAW);
        f->BindBuffer(GL_UNIFORM_BUFFER, 0);
        r = btf_gl_texture_create(gl, BTF__CELLS, 2 * BTF__CELLS, BTF_GL_RGBA32UI, cells, &out->cells, err);
    }
    if (r == BTF_OK)
        r = btf_gl_texture_create(gl, BTF__TRI_W, rows > 0 ? rows : 1, BTF_GL_RGBA32UI, tris, &out->tris, err);
    free(verts);
    free(cells);
    free(tris);
    if (r != BTF_OK)
        btf_gl_dirs_free(gl, out);
    return r;
}

btf_result btf_gl_dirs_bind(btf_gl *gl, const btf_gl_dirs *d, const btf_shader_program *prog, int first_unit,
                            btf_error *err)
{
    if (!gl || !d || !prog)
        return btf_fail(err, BTF_ERR_ARG, "gl dirs: NULL argument");
    const btf_gl_api *f = btf_gl_fn(gl);
    GLuint block = f->GetUniformBlockIndex(prog->id, "btf_dirs_block");
    if (block == GL_INVALID_INDEX)
        return btf_fail(err, BTF_ERR_MISSING, "shader '%s': no uniform block btf_dirs_block", prog->name);
    f->UniformBlockBinding(prog->id, block, 0);
    f->BindBufferBase(GL_UNIFORM_BUFFER, 0, d->ubo);
    static const char *names[2] = {"u_btf_dir_cells", "u_btf_dir_tris"};
    const GLuint tex[2] = {d->cells, d->tris};
    for (int i = 0; i < 2; i++) {
        GLint loc = f->GetUniformLocation(prog->id, names[i]);
        if (loc < 0)
            return btf_fail(err, BTF_ERR_MISSING, "shader '%s': no sampler %s", prog->name, names[i]);
        f->ActiveTexture((GLenum)(GL_TEXTURE0 + first_unit + i));
        f->BindTexture(GL_TEXTURE_2D, tex[i]);
        f->Uniform1i(loc, first_unit + i);
    }
    return btf_gl_check(gl, "binding the direction tables", err);
}

void btf_gl_dirs_free(btf_gl *gl, btf_gl_dirs *d)
{
    if (!gl || !d)
        return;
    if (d->ubo)
        btf_gl_fn(gl)->DeleteBuffers(1, &d->ubo);
    btf_gl_texture_free(gl, d->cells);
    btf_gl_texture_free(gl, d->tris);
    memset(d, 0, sizeof d[0]);
}
