/* btf_scene.c - a glTF model with bound packages in one frame (btf_scene.h). */
#include "btf_scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "btf_common.h"
#include "btf_shader.h"

#define BTF__PI 3.14159265358979323846

/* Everything one scene owns on the GPU; see btf_scene_create. */
struct btf_scene {
    btf_gl *gl;
    const btf_gltf *model;
    int n_bind;
    btf_package **pkg;    /* n_bind: each binding's package as read (its renderer reads it on every bind) */
    btf_renderer **rend;  /* n_bind: each binding's package and `render` program */
    float *repeat;        /* n_bind */
    int *part_bind;       /* n_parts: binding index, or -1 (base colour) */
    GLuint *vao, *vbo, *ibo; /* n_parts each */
    btf_shader_program *flat; /* NULL when every part is bound */
};

void btf_scene_frame(const btf_gltf *m, btf_render_params *p)
{
    double r2 = 0;
    for (int c = 0; c < 3; c++) {
        p->target[c] = 0.5f * (m->min[c] + m->max[c]);
        double h = 0.5 * ((double)m->max[c] - m->min[c]);
        r2 += h * h;
    }
    double r = sqrt(r2) > 1e-6 ? sqrt(r2) : 1e-6;
    p->extent = (float)r;
    p->camera_dist = (float)(1.05 * r / sin(p->fov_deg * BTF__PI / 360.0));
}

btf_result btf_scene_bind(const btf_gltf *m, const btf_scene_binding *b, int n, int *part_bind, btf_error *err)
{
    if (n < 0 || n > BTF_SCENE_MAX_BINDINGS)
        return btf_fail(err, BTF_ERR_RANGE, "scene: %d bindings (0..%d)", n, BTF_SCENE_MAX_BINDINGS);
    int any = -1;
    for (int j = 0; j < n; j++) {
        if (!b[j].material || !b[j].dir)
            return btf_fail(err, BTF_ERR_ARG, "scene: binding %d lacks a material or a package", j);
        if (!(b[j].repeat >= 0.0f && b[j].repeat <= 1e4f))
            return btf_fail(err, BTF_ERR_RANGE, "scene: binding %s: repeat %g outside [0, 1e4]", b[j].material,
                            (double)b[j].repeat);
        if (strcmp(b[j].material, "*") == 0)
            any = j;
    }
    for (int i = 0; i < m->n_parts; i++) {
        part_bind[i] = any;
        for (int j = 0; j < n; j++)
            if (strcmp(b[j].material, m->parts[i].material) == 0)
                part_bind[i] = j;
        if (part_bind[i] >= 0 && !m->parts[i].has_uv)
            return btf_fail(err, BTF_ERR_FORMAT, "scene: part %d (material \"%s\") has no TEXCOORD_0: a BTF needs "
                            "texture coordinates", i, m->parts[i].material);
    }
    for (int j = 0; j < n; j++) {
        int used = j == any;
        for (int i = 0; i < m->n_parts && !used; i++)
            used = strcmp(b[j].material, m->parts[i].material) == 0;
        if (!used)
            return btf_fail(err, BTF_ERR_ARG, "scene: the model has no material named \"%s\"", b[j].material);
    }
    return BTF_OK;
}

/* The packages of the bindings, read and uploaded with their programs. */
static btf_result btf__scene_renderers(btf_scene *s, const btf_scene_binding *b, btf_error *err)
{
    for (int j = 0; j < s->n_bind; j++) {
        btf_result r = btf_package_read(b[j].dir, -1, &s->pkg[j], err);
        if (r == BTF_OK && s->pkg[j]->n_loaded < 1)
            r = btf_fail(err, BTF_ERR_MISSING, "scene: %s: no chunk present", b[j].dir);
        if (r == BTF_OK)
            r = btf_renderer_create(s->gl, s->pkg[j], b[j].dir, 0, &s->rend[j], err);
        if (r != BTF_OK)
            return r;
        s->repeat[j] = b[j].repeat > 0.0f ? b[j].repeat : 1.0f;
    }
    return BTF_OK;
}

/* Every part's mesh in its own vertex array; the flat program when a part needs it. */
static btf_result btf__scene_meshes(btf_scene *s, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(s->gl);
    int flat = 0;
    for (int i = 0; i < s->model->n_parts; i++) {
        f->GenVertexArrays(1, &s->vao[i]);
        f->GenBuffers(1, &s->vbo[i]);
        f->GenBuffers(1, &s->ibo[i]);
        f->BindVertexArray(s->vao[i]);
        btf_render_mesh_upload(f, &s->model->parts[i].mesh, s->vbo[i], s->ibo[i]);
        flat |= s->part_bind[i] < 0;
    }
    f->BindVertexArray(0);
    btf_result r = btf_gl_check(s->gl, "uploading the model", err);
    if (r == BTF_OK && flat) {
        btf_shader_desc sd = {.program = "flat"};
        r = btf_shader_build(s->gl, &sd, &s->flat, NULL, err);
    }
    return r;
}

btf_result btf_scene_create(btf_gl *gl, const btf_gltf *m, const btf_scene_binding *b, int n, btf_scene **out,
                            btf_error *err)
{
    if (!gl || !m || (!b && n) || !out)
        return btf_fail(err, BTF_ERR_ARG, "scene: NULL argument");
    *out = NULL;
    btf_scene *s = calloc(1, sizeof *s);
    size_t np = (size_t)m->n_parts;
    if (!s)
        return btf_fail(err, BTF_ERR_NOMEM, "scene: out of memory");
    s->gl = gl, s->model = m, s->n_bind = n;
    s->rend = calloc((size_t)n + 1, sizeof *s->rend);
    s->pkg = calloc((size_t)n + 1, sizeof *s->pkg);
    s->repeat = calloc((size_t)n + 1, sizeof *s->repeat);
    s->part_bind = calloc(np, sizeof *s->part_bind);
    s->vao = calloc(np, sizeof(GLuint)), s->vbo = calloc(np, sizeof(GLuint)), s->ibo = calloc(np, sizeof(GLuint));
    btf_result r = BTF_OK;
    if (!s->rend || !s->pkg || !s->repeat || !s->part_bind || !s->vao || !s->vbo || !s->ibo)
        r = btf_fail(err, BTF_ERR_NOMEM, "scene: out of memory (%d parts)", m->n_parts);
    if (r == BTF_OK)
        r = btf_scene_bind(m, b, n, s->part_bind, err);
    if (r == BTF_OK)
        r = btf__scene_renderers(s, b, err);
    if (r == BTF_OK)
        r = btf__scene_meshes(s, err);
    if (r != BTF_OK) {
        btf_scene_free(s);
        return r;
    }
    *out = s;
    return BTF_OK;
}

void btf_scene_free(btf_scene *s)
{
    if (!s)
        return;
    const btf_gl_api *f = btf_gl_fn(s->gl);
    for (int i = 0; s->vao && i < s->model->n_parts; i++) {
        if (s->vao[i])
            f->DeleteVertexArrays(1, &s->vao[i]);
        if (s->vbo[i])
            f->DeleteBuffers(1, &s->vbo[i]);
        if (s->ibo[i])
            f->DeleteBuffers(1, &s->ibo[i]);
    }
    for (int j = 0; s->rend && j < s->n_bind; j++)
        btf_renderer_free(s->rend[j]);
    for (int j = 0; s->pkg && j < s->n_bind; j++)
        btf_package_free(s->pkg[j]);
    btf_shader_program_free(s->gl, s->flat);
    free(s->rend), free(s->pkg), free(s->repeat), free(s->part_bind), free(s->vao), free(s->vbo), free(s->ibo);
    free(s);
}

/* The parts bound to binding j (or, j = -1, to none) drawn with the current program. */
static void btf__scene_parts(btf_scene *s, int j)
{
    const btf_gl_api *f = btf_gl_fn(s->gl);
    for (int i = 0; i < s->model->n_parts; i++) {
        if (s->part_bind[i] != j)
            continue;
        f->BindVertexArray(s->vao[i]);
        f->DrawElements(GL_TRIANGLES, s->model->parts[i].mesh.n_indices, GL_UNSIGNED_INT, 0);
    }
}

/* The unbound parts with the flat program, one draw each in its base colour. */
static void btf__scene_flat(btf_scene *s, const btf_render_params *p, const btf_render_camera *c)
{
    const btf_gl_api *f = btf_gl_fn(s->gl);
    GLuint id = s->flat->id;
    f->UseProgram(id);
    btf_env_quad q;
    if (p->env)
        btf_env_quadratic(p->env, p->env_rotation, &q);
    btf_render_light_uniforms(s->gl, id, p, p->env ? &q : NULL);
    f->UniformMatrix4fv(f->GetUniformLocation(id, "u_model"), 1, GL_FALSE, c->model);
    f->UniformMatrix4fv(f->GetUniformLocation(id, "u_view_proj"), 1, GL_FALSE, c->view_proj);
    f->Uniform4f(f->GetUniformLocation(id, "u_light"), c->light[0], c->light[1], c->light[2], 0.0f);
    f->Uniform1f(f->GetUniformLocation(id, "u_flat_ambient"), BTF_SCENE_FLAT_AMBIENT);
    GLint color = f->GetUniformLocation(id, "u_base_color");
    for (int i = 0; i < s->model->n_parts; i++) {
        if (s->part_bind[i] >= 0)
            continue;
        const float *bc = s->model->parts[i].base_color;
        f->Uniform4f(color, bc[0], bc[1], bc[2], bc[3]);
        f->BindVertexArray(s->vao[i]);
        f->DrawElements(GL_TRIANGLES, s->model->parts[i].mesh.n_indices, GL_UNSIGNED_INT, 0);
    }
}

btf_result btf_scene_draw(btf_scene *s, const btf_render_params *p, btf_gl_target *t, btf_error *err)
{
    if (!s || !p || !t)
        return btf_fail(err, BTF_ERR_ARG, "scene: NULL argument");
    btf_result r = btf_render_check_params(p, err);
    if (r != BTF_OK)
        return r;
    btf_render_camera cam;
    btf_render_camera_make(p, &cam);
    GLuint depth = 0;
    r = btf_render_frame_begin(s->gl, p, t, &depth, err);
    for (int j = 0; r == BTF_OK && j < s->n_bind; j++) {
        btf_render_camera cj = cam; /* the model's own uvs, the binding's repeat, tiled */
        cj.uv_scale[0] = cj.uv_scale[1] = s->repeat[j];
        cj.wrap = 1;
        r = btf_renderer_use(s->rend[j], p, &cj, err);
        if (r == BTF_OK)
            btf__scene_parts(s, j);
    }
    if (r == BTF_OK && s->flat)
        btf__scene_flat(s, p, &cam);
    if (r == BTF_OK) {
        btf_gl_fn(s->gl)->Finish();
        r = btf_gl_check(s->gl, "drawing the model", err);
    }
    btf_render_frame_end(s->gl, depth);
    return r;
}

/* What btf_scene_png draws (a btf_render_draw_fn): the model with its bindings. */
typedef struct btf__scene_job {
    const btf_gltf *m;
    const btf_scene_binding *b;
    int n;
    const btf_render_params *p;
} btf__scene_job;

static btf_result btf__scene_draw_job(void *ctx, btf_gl *gl, btf_gl_target *t, btf_error *err)
{
    const btf__scene_job *j = ctx;
    btf_scene *s = NULL;
    btf_result r = btf_scene_create(gl, j->m, j->b, j->n, &s, err);
    if (r == BTF_OK)
        r = btf_scene_draw(s, j->p, t, err);
    btf_scene_free(s);
    return r;
}

btf_result btf_scene_png(const btf_gltf *m, const btf_scene_binding *b, int n, const btf_render_params *p,
                         btf_gl_backend backend, const char *out_path, btf_error *err)
{
    if (!m || !p || !out_path)
        return btf_fail(err, BTF_ERR_ARG, "scene: NULL argument");
    btf__scene_job job = {m, b, n, p};
    return btf_render_to_png(p, backend, btf__scene_draw_job, &job, out_path, err);
}
