/* btf_render.c - scene setup and drawing for `btf render` (see btf_render.h). */
#include "btf_render.h"
#include "btf_env.h"
#include "btf_gl_fixed.h"

#include "btf_image.h"
#include "btf_shader.h"
#include "btf_common.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BTF__PI 3.14159265358979323846

/* ---------------------------------------------------------------- parameters */

static const char *const btf__geometry_names[BTF_RENDER_GEOMETRY_COUNT] = {"plane", "sphere", "cylinder"};

const char *btf_render_geometry_name(btf_render_geometry g)
{
    return (unsigned)g < BTF_RENDER_GEOMETRY_COUNT ? btf__geometry_names[g] : "?";
}

int btf_render_geometry_from_name(const char *name)
{
    return btf_name_index(btf__geometry_names, BTF_RENDER_GEOMETRY_COUNT, name);
}

btf_render_params btf_render_defaults(btf_render_geometry g)
{
    btf_render_params p;
    memset(&p, 0, sizeof p);
    p.width = 320;
    p.height = 240;
    p.geometry = g;
    p.camera_phi = -90.0f; /* camera south of the object, image row 0 (world +y) at the top */
    /* each object inside the view at any aspect (the fov spans the narrower side); the
     * plane's near corners are its widest part, hence a steeper view from further off */
    p.camera_theta = g == BTF_RENDER_PLANE ? 30.0f : g == BTF_RENDER_SPHERE ? 60.0f : 50.0f;
    p.camera_dist = g == BTF_RENDER_PLANE ? 3.5f : 3.6f;
    /* 28 to 35 degrees off the camera, up and to the right: the lit side faces the
     * camera (nearly all of the default sphere's visible pixels lit) and the relief shows */
    p.light_theta = 45.0f;
    p.light_phi = -50.0f;
    p.fov_deg = 40.0f;
    p.background[0] = p.background[1] = p.background[2] = 0.12f;
    p.repeat = 1.0f;
    p.filter = 1;
    p.horizon_fade = 1;
    p.exposure = 1.0f;
    return p;
}

int btf_render_tone_from_name(const char *name)
{
    static const char *const names[BTF_TONE_COUNT] = {"auto", "none", "neutral", "aces"};
    for (int i = 0; name && i < BTF_TONE_COUNT; i++)
        if (!strcmp(name, names[i]))
            return i;
    return -1;
}

static int btf__finite(float x) { return x == x && fabsf(x) <= 1e30f; }

btf_result btf_render_check_params(const btf_render_params *p, btf_error *err)
{
    if (!p)
        return btf_fail(err, BTF_ERR_ARG, "render: NULL parameters");
    if (p->width < 1 || p->width > 8192 || p->height < 1 || p->height > 8192)
        return btf_fail(err, BTF_ERR_RANGE, "render: size %dx%d outside 1..8192", p->width, p->height);
    if ((unsigned)p->geometry >= BTF_RENDER_GEOMETRY_COUNT)
        return btf_fail(err, BTF_ERR_ARG, "render: unknown geometry %d", (int)p->geometry);
    const float angles[4] = {p->camera_theta, p->camera_phi, p->light_theta, p->light_phi};
    for (int i = 0; i < 4; i++)
        if (!btf__finite(angles[i]))
            return btf_fail(err, BTF_ERR_RANGE, "render: camera/light angle %d is not finite", i);
    if (p->camera_theta < 0 || p->camera_theta > 180 || p->light_theta < 0 || p->light_theta > 180)
        return btf_fail(err, BTF_ERR_RANGE, "render: theta outside 0..180 (camera %g, light %g)",
                        (double)p->camera_theta, (double)p->light_theta);
    if (!btf__finite(p->camera_dist) || !(p->camera_dist > 0.0f) || p->camera_dist > 1e7f)
        return btf_fail(err, BTF_ERR_RANGE, "render: camera distance %g outside (0, 1e7]", (double)p->camera_dist);
    if (!(p->fov_deg >= 1.0f && p->fov_deg <= 170.0f))
        return btf_fail(err, BTF_ERR_RANGE, "render: field of view %g outside 1..170 degrees", (double)p->fov_deg);
    for (int c = 0; c < 3; c++)
        if (!(p->background[c] >= 0.0f && p->background[c] <= 1.0f))
            return btf_fail(err, BTF_ERR_RANGE, "render: background component %d = %g outside 0..1", c,
                            (double)p->background[c]);
    if (!(p->repeat > 0.0f && p->repeat <= 1e4f))
        return btf_fail(err, BTF_ERR_RANGE, "render: repeat %g outside (0, 1e4]", (double)p->repeat);
    if (p->filter != 0 && p->filter != 1)
        return btf_fail(err, BTF_ERR_ARG, "render: filter %d is neither 0 (nearest) nor 1 (bilinear)", p->filter);
    if (p->n_chunks < 0)
        return btf_fail(err, BTF_ERR_RANGE, "render: negative chunk count %d", p->n_chunks);
    for (int c = 0; c < 3; c++)
        if (!btf__finite(p->target[c]) || fabsf(p->target[c]) > 1e6f)
            return btf_fail(err, BTF_ERR_RANGE, "render: camera target component %d is not finite or beyond 1e6", c);
    if (!btf__finite(p->extent) || p->extent < 0.0f || p->extent > 1e6f)
        return btf_fail(err, BTF_ERR_RANGE, "render: extent %g outside [0, 1e6]", (double)p->extent);
    if (!btf__finite(p->exposure) || p->exposure < 0.0f || p->exposure > 1e6f)
        return btf_fail(err, BTF_ERR_RANGE, "render: exposure %g outside [0, 1e6]", (double)p->exposure);
    if (!btf__finite(p->env_rotation) || fabsf(p->env_rotation) > 1e6f)
        return btf_fail(err, BTF_ERR_RANGE, "render: environment rotation is not finite or beyond 1e6");
    if ((unsigned)p->tone_mapping >= BTF_TONE_COUNT)
        return btf_fail(err, BTF_ERR_ARG, "render: unknown tone mapping %d", p->tone_mapping);
    if (p->no_point_light && !p->env)
        return btf_fail(err, BTF_ERR_ARG, "render: no light (the point light is off and no environment is given)");
    return BTF_OK;
}

/* ---------------------------------------------------------------- camera */

static void btf__dir(double theta_deg, double phi_deg, double v[3])
{
    double t = theta_deg * BTF__PI / 180.0, p = phi_deg * BTF__PI / 180.0;
    v[0] = sin(t) * cos(p);
    v[1] = sin(t) * sin(p);
    v[2] = cos(t);
}

static void btf__cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static void btf__normalize(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

void btf_render_mat4_mul(const double a[16], const double b[16], double c[16])
{
    for (int col = 0; col < 4; col++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += a[k * 4 + row] * b[col * 4 + k];
            c[col * 4 + row] = s;
        }
}

static void btf__to_float(const double *src, float *dst, int n)
{
    for (int i = 0; i < n; i++)
        dst[i] = (float)src[i];
}

void btf_render_camera_make(const btf_render_params *p, btf_render_camera *c)
{
    memset(c, 0, sizeof *c);
    double t = p->camera_theta * BTF__PI / 180.0, ph = p->camera_phi * BTF__PI / 180.0, d = p->camera_dist;
    double dir[3], eye[3], fwd[3], right[3], up[3];
    btf__dir(p->camera_theta, p->camera_phi, dir);
    double up0[3] = {-cos(t) * cos(ph), -cos(t) * sin(ph), sin(t)}; /* -d(dir)/d(theta) */
    for (int i = 0; i < 3; i++) {
        eye[i] = p->target[i] + d * dir[i];
        fwd[i] = -dir[i];
    }
    btf__cross(fwd, up0, right);
    btf__normalize(right);
    btf__cross(right, fwd, up);
    double view[16] = {right[0], up[0], -fwd[0], 0, right[1], up[1], -fwd[1], 0, right[2], up[2], -fwd[2], 0,
                       -(right[0] * eye[0] + right[1] * eye[1] + right[2] * eye[2]),
                       -(up[0] * eye[0] + up[1] * eye[1] + up[2] * eye[2]),
                       fwd[0] * eye[0] + fwd[1] * eye[1] + fwd[2] * eye[2], 1};
    double aspect = (double)p->width / p->height;
    double th = tan(p->fov_deg * BTF__PI / 360.0) / (aspect < 1.0 ? aspect : 1.0); /* fov spans the narrower side */
    double zn = 0.05 * d, zf = d + 2.0 * (p->extent > 0.0f ? p->extent : 2.0);
    double proj[16] = {1 / (th * aspect), 0, 0, 0, 0, 1 / th, 0, 0, 0, 0, -(zf + zn) / (zf - zn), -1, 0, 0,
                       -2 * zf * zn / (zf - zn), 0};
    double vp[16], ident[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    btf_render_mat4_mul(proj, view, vp);
    btf__to_float(ident, c->model, 16);
    btf__to_float(view, c->view, 16);
    btf__to_float(proj, c->proj, 16);
    btf__to_float(vp, c->view_proj, 16);
    btf__to_float(eye, c->eye, 3);
    btf__to_float(fwd, c->forward, 3);
    btf__to_float(right, c->right, 3);
    btf__to_float(up, c->up, 3);
    double l[3];
    btf__dir(p->light_theta, p->light_phi, l);
    btf__to_float(l, c->light, 3);
    static const float base[BTF_RENDER_GEOMETRY_COUNT][2] = {{1, 1}, {2, 1}, {1, 2}};
    int g = (unsigned)p->geometry < BTF_RENDER_GEOMETRY_COUNT ? (int)p->geometry : 0;
    c->uv_scale[0] = base[g][0] * p->repeat;
    c->uv_scale[1] = base[g][1] * p->repeat;
    c->wrap = g != BTF_RENDER_PLANE || p->repeat != 1.0f;
}

double btf_render_pixels_per_unit(const btf_render_params *p)
{
    int side = p->width < p->height ? p->width : p->height;
    return side / (2.0 * p->camera_dist * tan(p->fov_deg * BTF__PI / 360.0));
}

/* ---------------------------------------------------------------- meshes */

/* Vertex (i, j) of a (nu+1) x (nv+1) grid at parameters s = i/nu, t = j/nv. */
static void btf__grid_vertex(btf_render_geometry g, double s, double t, float *v)
{
    double pos[3], n[3], tan4[4] = {1, 0, 0, 1};
    if (g == BTF_RENDER_PLANE) {
        pos[0] = 2 * s - 1;
        pos[1] = 1 - 2 * t;
        pos[2] = 0;
        n[0] = n[1] = 0;
        n[2] = 1;
    } else if (g == BTF_RENDER_SPHERE) {
        double lon = 2 * BTF__PI * s + BTF__PI / 2, colat = BTF__PI * t; /* seam at +y, the back */
        n[0] = sin(colat) * cos(lon);
        n[1] = sin(colat) * sin(lon);
        n[2] = cos(colat);
        memcpy(pos, n, sizeof pos);
        tan4[0] = -sin(lon);
        tan4[1] = cos(lon);
        tan4[2] = 0;
    } else { /* cylinder: axis x, angle a from the top line towards -y, seam at the bottom */
        double r = 2.0 / BTF__PI, a = 2 * BTF__PI * (t - 0.5);
        n[0] = 0;
        n[1] = -sin(a);
        n[2] = cos(a);
        pos[0] = 2 * s - 1;
        pos[1] = r * n[1];
        pos[2] = r * n[2];
    }
    float a[BTF_RENDER_VERTEX_FLOATS] = {(float)pos[0], (float)pos[1], (float)pos[2], (float)n[0], (float)n[1],
                                         (float)n[2], (float)tan4[0], (float)tan4[1], (float)tan4[2], (float)tan4[3],
                                         (float)s, (float)t};
    memcpy(v, a, sizeof a);
}

btf_result btf_render_mesh_create(btf_render_geometry g, int segments, btf_render_mesh **out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "render mesh: NULL output");
    *out = NULL;
    if ((unsigned)g >= BTF_RENDER_GEOMETRY_COUNT)
        return btf_fail(err, BTF_ERR_ARG, "render mesh: unknown geometry %d", (int)g);
    if (segments == 0)
        segments = 64;
    if (segments < 3 || segments > 1024)
        return btf_fail(err, BTF_ERR_RANGE, "render mesh: %d segments outside 3..1024", segments);
    int nu = g == BTF_RENDER_PLANE ? 1 : g == BTF_RENDER_SPHERE ? segments : 1;
    int nv = g == BTF_RENDER_PLANE ? 1 : g == BTF_RENDER_SPHERE ? segments / 2 : segments;
    if (nv < 2 && g != BTF_RENDER_PLANE)
        nv = 2;
    btf_render_mesh *m = calloc(1, sizeof *m);
    if (!m)
        return btf_fail(err, BTF_ERR_NOMEM, "render mesh: out of memory");
    m->n_vertices = (nu + 1) * (nv + 1);
    m->n_indices = nu * nv * 6;
    m->vertices = malloc((size_t)m->n_vertices * BTF_RENDER_VERTEX_FLOATS * sizeof(float));
    m->indices = malloc((size_t)m->n_indices * sizeof(unsigned));
    if (!m->vertices || !m->indices) {
        btf_render_mesh_free(m);
        return btf_fail(err, BTF_ERR_NOMEM, "render mesh: out of memory");
    }
    for (int j = 0; j <= nv; j++)
        for (int i = 0; i <= nu; i++)
            btf__grid_vertex(g, (double)i / nu, (double)j / nv,
                             &m->vertices[(size_t)(j * (nu + 1) + i) * BTF_RENDER_VERTEX_FLOATS]);
    unsigned *ix = m->indices;
    for (int j = 0; j < nv; j++)
        for (int i = 0; i < nu; i++) {
            unsigned a = (unsigned)(j * (nu + 1) + i), b = a + 1, c = a + (unsigned)(nu + 1), d = c + 1;
            unsigned q[6] = {a, c, b, b, c, d};
            memcpy(ix, q, sizeof q);
            ix += 6;
        }
    *out = m;
    return BTF_OK;
}

void btf_render_mesh_free(btf_render_mesh *m)
{
    if (!m)
        return;
    free(m->vertices), free(m->indices), free(m);
}

/* ---------------------------------------------------------------- renderer */

/* Everything one renderer owns on the GPU; see btf_renderer_create. */
struct btf_renderer {
    btf_gl *gl;
    btf_shader_program *prog;     /* the one in use: one of progs */
    btf_shader_program *progs[8]; /* by lights: 1 point, 2 environment, 3 both; + 4: the point light
                                     blended per draw (BTF_FIXED_LIGHT); built when first used */
    btf_gl_fixed *fixed;          /* the per-draw light weights of progs[4 + ...]; made when first used */
    int debug;
    btf_env_quad quad;            /* the environment's quadratic, for quad_env turned quad_rot */
    const btf_env *quad_env;
    float quad_rot;
    btf_gl_package *pkg;
    btf_render_geometry mesh_geometry; /* geometry in vbo/ibo; -1 none yet */
    GLuint vao, vbo, ibo;
    int n_indices;
};

/* Makes progs[lights] (1 point, 2 environment, 3 both; + 4 the point light blended per
 * draw) current, building it first: specialised for the package (levels, layers in use)
 * and the lights; the filter stays a uniform. */
static btf_result btf__renderer_program(btf_renderer *r, int lights, btf_error *err)
{
    if (!r->progs[lights]) {
        btf_shader_define defs[BTF_GL_PACKAGE_DEFINES + 3];
        char vals[BTF_GL_PACKAGE_DEFINES][16];
        int n = btf_gl_package_defines(r->pkg, 0, 0, defs, vals);
        defs[0] = (btf_shader_define){"BTF_RENDER_DEBUG", "1"}; /* in place of BTF_FILTER: a uniform here */
        defs[n] = (btf_shader_define){"BTF_POINT", lights & 1 ? "1" : "0"};
        defs[n + 1] = (btf_shader_define){"BTF_ENV", lights & 2 ? "1" : "0"};
        defs[n + 2] = (btf_shader_define){"BTF_FIXED_LIGHT", lights & 4 ? "1" : "0"};
        btf_shader_desc sd = {.program = "render", .defines = r->debug ? defs : defs + 1, .n_defines = n + 2 + !!r->debug};
        btf_result res = btf_shader_build(r->gl, &sd, &r->progs[lights], NULL, err);
        if (res != BTF_OK)
            return res;
    }
    r->prog = r->progs[lights];
    return BTF_OK;
}

btf_result btf_renderer_create(btf_gl *gl, const btf_package *p, const char *dir, int debug, btf_renderer **out,
                               btf_error *err)
{
    if (!gl || !p || !dir || !out)
        return btf_fail(err, BTF_ERR_ARG, "renderer: NULL argument");
    *out = NULL;
    btf_renderer *r = calloc(1, sizeof *r);
    if (!r)
        return btf_fail(err, BTF_ERR_NOMEM, "renderer: out of memory");
    r->gl = gl;
    r->mesh_geometry = (btf_render_geometry)-1;
    r->debug = debug;
    btf_result res = btf_gl_package_upload(gl, p, dir, &r->pkg, err);
    if (res == BTF_OK)
        res = btf__renderer_program(r, 1, err);
    if (res != BTF_OK) {
        btf_renderer_free(r);
        return res;
    }
    const btf_gl_api *f = btf_gl_fn(gl);
    f->GenVertexArrays(1, &r->vao);
    f->GenBuffers(1, &r->vbo);
    f->GenBuffers(1, &r->ibo);
    *out = r;
    return BTF_OK;
}

const btf_gl_package *btf_renderer_package(const btf_renderer *r) { return r ? r->pkg : NULL; }

void btf_renderer_free(btf_renderer *r)
{
    if (!r)
        return;
    const btf_gl_api *f = btf_gl_fn(r->gl);
    if (r->vbo)
        f->DeleteBuffers(1, &r->vbo);
    if (r->ibo)
        f->DeleteBuffers(1, &r->ibo);
    if (r->vao)
        f->DeleteVertexArrays(1, &r->vao);
    btf_gl_package_free(r->gl, r->pkg);
    for (int i = 0; i < 8; i++)
        btf_shader_program_free(r->gl, r->progs[i]);
    btf_gl_fixed_free(r->gl, r->fixed);
    free(r);
}

void btf_render_mesh_upload(const btf_gl_api *f, const btf_render_mesh *m, GLuint vbo, GLuint ibo)
{
    f->BindBuffer(GL_ARRAY_BUFFER, vbo);
    f->BufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)m->n_vertices * BTF_RENDER_VERTEX_FLOATS * sizeof(float)),
                  m->vertices, GL_STATIC_DRAW);
    f->BindBuffer(GL_ELEMENT_ARRAY_BUFFER, ibo);
    f->BufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)((size_t)m->n_indices * sizeof(unsigned)), m->indices,
                  GL_STATIC_DRAW);
    static const int sizes[4] = {3, 3, 4, 2}, offs[4] = {0, 3, 6, 10};
    for (int a = 0; a < 4; a++) {
        f->EnableVertexAttribArray((GLuint)a);
        f->VertexAttribPointer((GLuint)a, sizes[a], GL_FLOAT, GL_FALSE, BTF_RENDER_VERTEX_FLOATS * sizeof(float),
                               (const void *)(size_t)(offs[a] * sizeof(float)));
    }
}

/* Uploads the mesh of geometry g unless it is already in the buffers. */
static btf_result btf__renderer_mesh(btf_renderer *r, btf_render_geometry g, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(r->gl);
    f->BindVertexArray(r->vao);
    if (r->mesh_geometry == g)
        return BTF_OK;
    btf_render_mesh *m = NULL;
    btf_result res = btf_render_mesh_create(g, 0, &m, err);
    if (res != BTF_OK)
        return res;
    btf_render_mesh_upload(f, m, r->vbo, r->ibo);
    r->n_indices = m->n_indices;
    r->mesh_geometry = g;
    btf_render_mesh_free(m);
    return btf_gl_check(r->gl, "uploading the mesh", err);
}

static void btf__renderer_uniforms(btf_renderer *r, const btf_render_params *p, const btf_render_camera *c)
{
    const btf_gl_api *f = btf_gl_fn(r->gl);
    GLuint id = r->prog->id;
    f->UniformMatrix4fv(f->GetUniformLocation(id, "u_model"), 1, GL_FALSE, c->model);
    f->UniformMatrix4fv(f->GetUniformLocation(id, "u_view_proj"), 1, GL_FALSE, c->view_proj);
    f->Uniform3f(f->GetUniformLocation(id, "u_camera"), c->eye[0], c->eye[1], c->eye[2]);
    f->Uniform4f(f->GetUniformLocation(id, "u_light"), c->light[0], c->light[1], c->light[2], 0.0f);
    f->Uniform2f(f->GetUniformLocation(id, "u_uv_scale"), c->uv_scale[0], c->uv_scale[1]);
    f->Uniform1i(f->GetUniformLocation(id, "u_horizon_fade"), p->horizon_fade ? 1 : 0);
    if (p->env && (p->env != r->quad_env || p->env_rotation != r->quad_rot)) {
        btf_env_quadratic(p->env, p->env_rotation, &r->quad);
        r->quad_env = p->env, r->quad_rot = p->env_rotation;
    }
    btf_render_light_uniforms(r->gl, id, p, p->env ? &r->quad : NULL);
    btf_gl_decode_settings s = {p->filter, c->wrap, p->n_chunks};
    btf_gl_package_settings(r->gl, r->pkg, r->prog, &s);
}

void btf_render_light_uniforms(btf_gl *gl, GLuint prog, const btf_render_params *p, const btf_env_quad *q)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    f->Uniform1i(f->GetUniformLocation(prog, "u_point_off"), p->no_point_light ? 1 : 0);
    f->Uniform1i(f->GetUniformLocation(prog, "u_env_on"), q ? 1 : 0);
    f->Uniform1f(f->GetUniformLocation(prog, "u_exposure"), p->exposure);
    int tone = p->tone_mapping == BTF_TONE_AUTO ? (q ? BTF_TONE_NEUTRAL : BTF_TONE_NONE) : p->tone_mapping;
    f->Uniform1i(f->GetUniformLocation(prog, "u_tone"), tone - BTF_TONE_NONE);
    if (!q)
        return;
    f->Uniform3fv(f->GetUniformLocation(prog, "u_env_c0"), 1, q->c0);
    f->UniformMatrix3fv(f->GetUniformLocation(prog, "u_env_a"), 1, GL_FALSE, q->a);
    f->UniformMatrix3fv(f->GetUniformLocation(prog, "u_env_q"), 3, GL_FALSE, q->q);
}

/* The per-draw light weights for local light l (made when first needed) bound to the
 * program in use. */
static btf_result btf__renderer_fixed(btf_renderer *r, const float l[3], int n_chunks, btf_error *err)
{
    btf_result res = r->fixed ? BTF_OK : btf_gl_fixed_create(r->gl, r->pkg, &r->fixed, err);
    if (res == BTF_OK)
        res = btf_gl_fixed_update(r->gl, r->fixed, r->pkg, l, n_chunks, err);
    if (res == BTF_OK)
        btf_gl_fixed_bind(r->gl, r->fixed, r->prog, BTF_GL_FIXED_UNIT);
    return res;
}

/* btf_renderer_use; fixed = 1: the distant light has one local direction, c->light,
 * over the whole mesh (the built-in plane: its local frame is the world frame), so the
 * point light is blended per draw (BTF_FIXED_LIGHT). */
static btf_result btf__renderer_use(btf_renderer *r, const btf_render_params *p, const btf_render_camera *c,
                                    int fixed, btf_error *err)
{
    int lights = (p->no_point_light ? 0 : 1) | (p->env ? 2 : 0);
    btf_result pr = btf__renderer_program(r, lights | (fixed && (lights & 1) ? 4 : 0), err);
    if (pr != BTF_OK)
        return pr;
    btf_gl_fn(r->gl)->UseProgram(r->prog->id);
    btf_result res = btf_gl_package_bind(r->gl, r->pkg, r->prog, 0, err);
    if (res == BTF_OK)
        btf__renderer_uniforms(r, p, c);
    if (res == BTF_OK && fixed && (lights & 1))
        res = btf__renderer_fixed(r, c->light, p->n_chunks, err);
    return res;
}

btf_result btf_renderer_use(btf_renderer *r, const btf_render_params *p, const btf_render_camera *c, btf_error *err)
{
    return btf__renderer_use(r, p, c, 0, err);
}

btf_result btf_render_frame_begin(btf_gl *gl, const btf_render_params *p, btf_gl_target *t, GLuint *depth,
                                  btf_error *err)
{
    if (t->width != p->width || t->height != p->height)
        return btf_fail(err, BTF_ERR_ARG, "render: target %dx%d, parameters ask for %dx%d", t->width, t->height,
                        p->width, p->height);
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_gl_target_bind(gl, t);
    f->GenRenderbuffers(1, depth);
    f->BindRenderbuffer(GL_RENDERBUFFER, *depth);
    f->RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, t->width, t->height);
    f->FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, *depth);
    f->Enable(GL_DEPTH_TEST);
    const float zero[4] = {0, 0, 0, 0};
    f->ClearColor(p->background[0], p->background[1], p->background[2], 1.0f);
    f->Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    for (int i = 1; i < t->n_color; i++) /* debug outputs: 0 where nothing is drawn */
        f->ClearBufferfv(GL_COLOR, i, zero);
    return BTF_OK;
}

void btf_render_frame_end(btf_gl *gl, GLuint depth)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    f->Disable(GL_DEPTH_TEST);
    f->FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, 0);
    f->DeleteRenderbuffers(1, &depth);
    f->BindVertexArray(0);
}

btf_result btf_renderer_draw(btf_renderer *r, const btf_render_params *p, btf_gl_target *t, btf_error *err)
{
    if (!r || !p || !t)
        return btf_fail(err, BTF_ERR_ARG, "renderer: NULL argument");
    btf_result res = btf_render_check_params(p, err);
    if (res != BTF_OK)
        return res;
    btf_render_camera cam;
    btf_render_camera_make(p, &cam);
    GLuint depth = 0;
    res = btf_render_frame_begin(r->gl, p, t, &depth, err);
    if (res != BTF_OK)
        return res;
    res = btf__renderer_use(r, p, &cam, p->geometry == BTF_RENDER_PLANE, err);
    if (res == BTF_OK)
        res = btf__renderer_mesh(r, p->geometry, err);
    if (res == BTF_OK) {
        const btf_gl_api *f = btf_gl_fn(r->gl);
        f->DrawElements(GL_TRIANGLES, r->n_indices, GL_UNSIGNED_INT, 0);
        f->Finish();
        res = btf_gl_check(r->gl, "drawing the scene", err);
    }
    btf_render_frame_end(r->gl, depth);
    return res;
}

btf_result btf_render_read_rgb8(btf_gl *gl, const btf_gl_target *t, uint8_t *rgb, btf_error *err)
{
    if (!gl || !t || !rgb)
        return btf_fail(err, BTF_ERR_ARG, "render: NULL argument");
    if (t->format != BTF_GL_RGBA8)
        return btf_fail(err, BTF_ERR_ARG, "render: RGB readback needs an RGBA8 target");
    size_t n = (size_t)t->width * (size_t)t->height;
    uint8_t *px = malloc(n * 4);
    if (!px)
        return btf_fail(err, BTF_ERR_NOMEM, "render: out of memory for %dx%d pixels", t->width, t->height);
    btf_result res = btf_gl_target_read(gl, t, 0, px, err);
    for (int y = 0; res == BTF_OK && y < t->height; y++) {
        const uint8_t *src = px + (size_t)(t->height - 1 - y) * (size_t)t->width * 4; /* GL rows are bottom-up */
        uint8_t *dst = rgb + (size_t)y * (size_t)t->width * 3;
        for (int x = 0; x < t->width; x++)
            memcpy(dst + x * 3, src + x * 4, 3);
    }
    free(px);
    return res;
}

btf_result btf_render_to_png(const btf_render_params *p, btf_gl_backend backend, btf_render_draw_fn draw, void *ctx,
                             const char *out_path, btf_error *err)
{
    btf_result res = btf_render_check_params(p, err);
    uint8_t *rgb = NULL;
    if (res == BTF_OK && !(rgb = malloc((size_t)p->width * (size_t)p->height * 3)))
        res = btf_fail(err, BTF_ERR_NOMEM, "render: out of memory for %dx%d pixels", p->width, p->height);
    btf_gl *gl = NULL;
    btf_gl_target *t = NULL;
    btf_gl_desc gd = {.backend = backend};
    if (res == BTF_OK)
        res = btf_gl_create(&gd, &gl, err);
    if (res == BTF_OK)
        res = btf_gl_target_create(gl, p->width, p->height, BTF_GL_RGBA8, 1, &t, err);
    if (res == BTF_OK)
        res = draw(ctx, gl, t, err);
    if (res == BTF_OK)
        res = btf_render_read_rgb8(gl, t, rgb, err);
    btf_gl_target_free(gl, t);
    btf_gl_free(gl);
    if (res == BTF_OK)
        res = btf_image_write(out_path, p->width, p->height, 3, 8, rgb, err);
    free(rgb);
    return res;
}

/* What btf_render_png draws (a btf_render_draw_fn): the package on its geometry. */
typedef struct btf__render_job {
    const btf_package *pkg;
    const char *dir;
    const btf_render_params *p;
} btf__render_job;

static btf_result btf__render_draw(void *ctx, btf_gl *gl, btf_gl_target *t, btf_error *err)
{
    const btf__render_job *j = ctx;
    btf_renderer *r = NULL;
    btf_result res = btf_renderer_create(gl, j->pkg, j->dir, 0, &r, err);
    if (res == BTF_OK)
        res = btf_renderer_draw(r, j->p, t, err);
    btf_renderer_free(r);
    return res;
}

btf_result btf_render_png(const char *dir, const btf_render_params *p, btf_gl_backend backend, const char *out_path,
                          btf_error *err)
{
    if (!dir || !p || !out_path)
        return btf_fail(err, BTF_ERR_ARG, "render: NULL argument");
    btf_result res = btf_render_check_params(p, err);
    if (res != BTF_OK)
        return res;
    btf_package *pkg = NULL;
    res = btf_package_read(dir, -1, &pkg, err);
    if (res == BTF_OK && pkg->n_loaded < 1)
        res = btf_fail(err, BTF_ERR_MISSING, "render: %s: no chunk present", dir);
    btf__render_job job = {pkg, dir, p};
    if (res == BTF_OK)
        res = btf_render_to_png(p, backend, btf__render_draw, &job, out_path, err);
    btf_package_free(pkg);
    return res;
}
