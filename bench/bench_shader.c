/* bench_shader.c - fragment cost of the package shader against two baselines, at
 * 1280x720 in the headless EGL harness, printed as `name value unit` lines:
 *
 *   shader   the product `render` program (shaders/btf_render.*, btf_decode.glsl)
 *            with C = 1, 2, 4, 8, 16 chunks of one package;
 *   thesis   the 2015 thesis's approach (shaders/bench/thesis.frag, benchmark only):
 *            precomputed 512x512 direction/weight lookup maps, 8-bit textures with
 *            4 components per texel, 8-bit weights, WebGL1-style texture() fetches;
 *   textured a plain textured surface, one texture() fetch (shaders/bench/textured.frag);
 *   env      the product program lit by the built-in studio environment alone
 *            (doc/lighting.md; BTF_ENV=1, BTF_POINT=0) at the same C, timed in the
 *            same interleaved run as the point-lit product and the thesis;
 *   fixed    the product program as `btf render` draws this scene (a distant light on
 *            a plane): BTF_FIXED_LIGHT, the light's weights blended once per draw
 *            (shaders/host/btf_gl_fixed.h), same run, same error measure. `shader`
 *            is the run-time light path that curved meshes and point lights take;
 *   nn       bench_nn.c's small nonlinear decoder (shaders/bench/nn.frag, benchmark
 *            only) with Z = 16 latents a texel and H = 64 or 128 hidden units, random
 *            parameters, against `shader` and `fixed` at C = 8 in one interleaved run;
 *            its error is against the same network evaluated on the CPU (nn_eval).
 *
 * All three draw the same plane mesh (btf_render.vert, btf_render.h conventions),
 * camera (30, -90, 1.1), fov 40, the material repeated 8 x 8 so it covers the whole
 * viewport, distant light (40, -30), nearest texels (the thesis's filtering).
 * Material: generated knit 64x64 sampled at UBO2003's 81 x 81 directions,
 * compressed with k = 3, 16 components, 8-bit textures; C = the first C chunks.
 *
 * ms/frame: median of 5 frames after one warm-up (glFinish each), llvmpipe is a CPU
 * rasterizer: compare the ratios (`*_ratio` lines), not the absolute numbers.
 * Error: RGB RMSE and max (0..255 scale) of the RGBA8 output against the CPU
 * reference btf_decode (float, same package, same C, clamped to 0..1) at every 4th
 * pixel in x and y, evaluated at the uv / local light / local view that the product
 * program reports through its debug outputs (tests/gl/test_render.c checks those).
 * BENCH_MAX_C=N limits the run to C <= N (quick checks).
 * Fetches and ALU per fragment: counted from the shader sources (see the
 * `fetches`/`alu` comments below; this Mesa build prints no shader statistics);
 * texture fetches exactly, ALU as scalar operations on the path taken (a vec4
 * multiply-add = 4, sin/cos/atan/sqrt = 1 each), an estimate. llvmpipe runs both
 * sides of every branch under a mask, so there the cost follows the code size of
 * the branchy product shader more than these path counts.
 */
#include "btf.h"
#include "btf_fs.h"
#include "btf_gen.h"
#include "btf_gl.h"
#include "btf_env.h"
#include "btf_gl_fixed.h"
#include "btf_gl_package.h"
#include "btf_lod.h"
#include "btf_package.h"
#include "btf_render.h"
#include "btf_shader.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "bench_util.h"
#include "btf_decode.h"

#define BW 1280
#define BH 720
#define SUB 4        /* error sample stride */
#define MAT 64       /* material side */
#define NCOMP 16     /* components in the package */
#define MAPN 512     /* thesis lookup map side */
#define FRAMES 9

static int die(const char *what, const btf_error *err)
{
    fprintf(stderr, "bench_shader: %s: %s\n", what, err ? err->msg : "");
    return 1;
}

/* ---------------------------------------------------------------- package */

static void remove_dir(const char *dir)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    char path[1200];
    while (d && (e = readdir(d)))
        if (e->d_name[0] != '.') {
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            remove(path);
        }
    if (d)
        closedir(d);
    rmdir(dir);
}

#ifndef BENCH_READ_ONLY
static btf_result make_package(const char *dir, btf_error *err)
{
    btf_dirset d = btf_dirset_ubo2003();
    btf_gen_params gp = btf_gen_defaults(BTF_GEN_KNIT);
    btf *m = NULL;
    btf_result r = btf_gen_create(&gp, MAT, MAT, &d, &d, BTF_F32, &m, err);
    btf_pca_options po = {0};
    po.k = 3;
    po.components = NCOMP;
    btf_package_options ko = {0};
    ko.bits = 8;
    if (r == BTF_OK)
        r = btf_package_compress(m, &po, &ko, dir, NULL, err);
    btf_free(m);
    return r;
}

/* DIR/knit (version 1) and DIR/knit-v2 (3 spatial levels) of the same material. */
static btf_result make_packages(const char *dir, btf_error *err)
{
    char v1[300], v2[300];
    snprintf(v1, sizeof v1, "%s/knit", dir);
    snprintf(v2, sizeof v2, "%s/knit-v2", dir);
    fprintf(stderr, "bench_shader: compressing a 64x64 knit, 81 x 81 directions, 16 components\n");
    btf_lod_options lo = {0};
    lo.levels = 3;
    btf_result r = make_package(v1, err);
    return r == BTF_OK ? btf_lod_build(v1, v2, &lo, NULL, err) : r;
}
#endif

/* ---------------------------------------------------------------- programs */

static char *read_text(const char *path)
{
    char *s = NULL;
    btf_fs_read(path, (size_t)1 << 20, &s, NULL, NULL);
    return s;
}

static GLuint compile_stage(const btf_gl_api *f, GLenum stage, const char *src, const char *name)
{
    GLuint s = f->CreateShader(stage);
    f->ShaderSource(s, 1, &src, NULL);
    f->CompileShader(s);
    GLint ok = 0;
    f->GetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[4096];
        f->GetShaderInfoLog(s, sizeof log, NULL, log);
        fprintf(stderr, "bench_shader: %s does not compile:\n%s\n", name, log);
        f->DeleteShader(s);
        return 0;
    }
    return s;
}

/* The product vertex stage (btf_render.vert, assembled as the manifest says) with a
 * benchmark fragment file from shaders/bench/, after the same prefix lines and the
 * define lines `defs` (may be ""). */
static GLuint build_bench_program(btf_gl *gl, const char *frag_file, const char *defs)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_shader_desc sd = {.program = "render"};
    btf_shader_source *vs = NULL;
    btf_error err = {{0}};
    if (btf_shader_assemble(&sd, BTF_SHADER_VERTEX, &vs, &err) != BTF_OK) {
        die("assembling btf_render.vert", &err);
        return 0;
    }
    const char *root = getenv("BTF_ROOT");
    char path[1024];
    snprintf(path, sizeof path, "%s/shaders/bench/%s", root ? root : ".", frag_file);
    char *body = read_text(path), *src = NULL;
    const char *marker = strstr(vs->text, "// ---- ");
    size_t np = marker ? (size_t)(marker - vs->text) : 0; /* the prefix lines */
    if (body && marker && (src = malloc(np + strlen(defs) + strlen(body) + 64))) {
        memcpy(src, vs->text, np);
        sprintf(src + np, "%s// ---- bench/%s\n%s", defs, frag_file, body);
    }
    GLuint prog = 0;
    GLuint v = src ? compile_stage(f, GL_VERTEX_SHADER, vs->text, "btf_render.vert") : 0;
    GLuint fr = v ? compile_stage(f, GL_FRAGMENT_SHADER, src, frag_file) : 0;
    if (!src)
        fprintf(stderr, "bench_shader: cannot read %s\n", path);
    if (v && fr) {
        prog = f->CreateProgram();
        f->AttachShader(prog, v);
        f->AttachShader(prog, fr);
        f->LinkProgram(prog);
        GLint ok = 0;
        f->GetProgramiv(prog, GL_LINK_STATUS, &ok);
        if (!ok) {
            fprintf(stderr, "bench_shader: %s does not link\n", frag_file);
            f->DeleteProgram(prog);
            prog = 0;
        }
    }
    if (v)
        f->DeleteShader(v);
    if (fr)
        f->DeleteShader(fr);
    free(body);
    free(src);
    btf_shader_source_free(vs);
    return prog;
}

/* ---------------------------------------------------------------- scene */

/* The plane mesh in a VAO, shared by every program. */
typedef struct scene {
    GLuint vao, vbo, ibo;
    int n_indices;
    btf_render_params rp;
    btf_render_camera cam;
} scene;

static int scene_create(btf_gl *gl, scene *s)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_render_mesh *m = NULL;
    btf_error err = {{0}};
    if (btf_render_mesh_create(BTF_RENDER_PLANE, 0, &m, &err) != BTF_OK)
        return die("mesh", &err);
    f->GenVertexArrays(1, &s->vao);
    f->BindVertexArray(s->vao);
    f->GenBuffers(1, &s->vbo);
    f->GenBuffers(1, &s->ibo);
    btf_render_mesh_upload(f, m, s->vbo, s->ibo);
    s->n_indices = m->n_indices;
    btf_render_mesh_free(m);
    s->rp = btf_render_defaults(BTF_RENDER_PLANE);
    s->rp.width = BW;
    s->rp.height = BH;
    s->rp.camera_theta = 30;
    s->rp.camera_dist = 1.1f;
    s->rp.light_theta = 40;
    s->rp.light_phi = -30;
    s->rp.repeat = 8;
    s->rp.filter = 0;
    s->rp.background[0] = s->rp.background[1] = s->rp.background[2] = 0;
    btf_render_camera_make(&s->rp, &s->cam);
    return 0;
}

/* The uniforms every program shares (those a program lacks are ignored by GL). */
static void scene_uniforms(btf_gl *gl, GLuint prog, const scene *s)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    f->UniformMatrix4fv(f->GetUniformLocation(prog, "u_model"), 1, GL_FALSE, s->cam.model);
    f->UniformMatrix4fv(f->GetUniformLocation(prog, "u_view_proj"), 1, GL_FALSE, s->cam.view_proj);
    f->Uniform3f(f->GetUniformLocation(prog, "u_camera"), s->cam.eye[0], s->cam.eye[1], s->cam.eye[2]);
    f->Uniform4f(f->GetUniformLocation(prog, "u_light"), s->cam.light[0], s->cam.light[1], s->cam.light[2], 0);
    f->Uniform2f(f->GetUniformLocation(prog, "u_uv_scale"), s->cam.uv_scale[0], s->cam.uv_scale[1]);
    f->Uniform1i(f->GetUniformLocation(prog, "u_horizon_fade"), 1);
}

static double median(double *v, int n)
{
    for (int i = 0; i < n; i++) /* insertion sort, a few values */
        for (int j = i; j > 0 && v[j] < v[j - 1]; j--) {
            double x = v[j];
            v[j] = v[j - 1];
            v[j - 1] = x;
        }
    return v[n / 2];
}

/* Frame cost: wall ms, CPU ms (all threads) and GPU ms (timer queries; -1 where
 * the context has none), medians of FRAMES frames after a warm-up. The CPU time
 * stays comparable when other work shares the machine; on a real GPU the GPU time
 * is the frame's. A frame faster than REPEAT_MS is drawn several times between two
 * glFinish (the count set in the warm-up) and divided, so driver overhead does not
 * pass for a sub-millisecond GPU frame. */
typedef struct frame_cost {
    double wall_ms, cpu_ms, gpu_ms;
} frame_cost;
#define REPEAT_MS 20.0

/* One program under test: setup() makes it current (program, textures, uniforms)
 * before each of its frames; the frames of every case alternate, so a slow spell
 * of the machine falls on all of them alike. */
typedef struct bench_case {
    int (*setup)(btf_gl *gl, void *ctx);
    void *ctx;
    int reps; /* draws per measured frame, set by the warm-up */
    double wall[FRAMES], cpu[FRAMES], gpu[FRAMES];
    frame_cost cost; /* out */
} bench_case;

/* Draws FRAMES + 1 frames of each case into t, interleaved (case 0, 1, ..., 0, 1, ...);
 * the first round is the warm-up. Returns non-zero when a setup fails. */
static int time_frames(btf_gl *gl, const scene *s, const btf_gl_target *t, bench_case *c, int n)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_gl_target_bind(gl, t);
    f->BindVertexArray(s->vao);
    for (int i = -1; i < FRAMES; i++)
        for (int k = 0; k < n; k++) {
            if (c[k].setup(gl, c[k].ctx))
                return 1;
            int reps = i < 0 ? 1 : c[k].reps;
            f->Finish();
            int timed = btf_gl_timer_begin(gl);
            double t0 = now_s(), c0 = cpu_s();
            for (int r = 0; r < reps; r++) {
                f->ClearColor(0, 0, 0, 1);
                f->Clear(GL_COLOR_BUFFER_BIT);
                f->DrawElements(GL_TRIANGLES, s->n_indices, GL_UNSIGNED_INT, 0);
            }
            f->Finish();
            double wall = (now_s() - t0) * 1e3 / reps, cpu = (cpu_s() - c0) * 1e3 / reps;
            long long ns = timed ? btf_gl_timer_end(gl) : -1;
            if (i < 0) { /* warm-up: how many draws make a measurable frame */
                double one = ns > 0 ? ns / 1e6 : wall;
                c[k].reps = one >= REPEAT_MS ? 1 : one > 0 ? (int)fmin(256.0, ceil(REPEAT_MS / one)) : 256;
                continue;
            }
            c[k].wall[i] = wall, c[k].cpu[i] = cpu;
            c[k].gpu[i] = ns >= 0 ? ns / 1e6 / reps : -1.0;
        }
    for (int k = 0; k < n; k++)
        c[k].cost = (frame_cost){median(c[k].wall, FRAMES), median(c[k].cpu, FRAMES), median(c[k].gpu, FRAMES)};
    return 0;
}

/* ---------------------------------------------------------------- reference and error */

/* Per sampled pixel: uv, light, view from the product program's debug outputs. */
typedef struct ref_pixels {
    int n;
    int *index;      /* pixel index in GL order */
    float *uv, *l, *v; /* 2, 3, 3 per sample */
    float *rgb;      /* reference, 3 per sample */
} ref_pixels;

static int ref_create(btf_gl *gl, const btf_package *p, const char *dir, const scene *s, ref_pixels *r)
{
    btf_error err = {{0}};
    btf_renderer *dbg = NULL;
    btf_gl_target *t = NULL;
    float *out = malloc((size_t)BW * BH * 4 * sizeof(float) * 4);
    if (!out)
        return die("out of memory", NULL);
    if (btf_renderer_create(gl, p, dir, 1, &dbg, &err) != BTF_OK ||
        btf_gl_target_create(gl, BW, BH, BTF_GL_RGBA32F, 4, &t, &err) != BTF_OK ||
        btf_renderer_draw(dbg, &s->rp, t, &err) != BTF_OK)
        return die("debug render", &err);
    for (int a = 0; a < 4; a++)
        if (btf_gl_target_read(gl, t, a, out + (size_t)a * BW * BH * 4, &err) != BTF_OK)
            return die("debug readback", &err);
    btf_gl_target_free(gl, t);
    btf_renderer_free(dbg);
    int cap = (BW / SUB) * (BH / SUB), covered = 0;
    r->index = malloc((size_t)cap * sizeof(int));
    r->uv = malloc((size_t)cap * 2 * sizeof(float));
    r->l = malloc((size_t)cap * 3 * sizeof(float));
    r->v = malloc((size_t)cap * 3 * sizeof(float));
    r->rgb = malloc((size_t)cap * 3 * sizeof(float));
    r->n = 0;
    for (int i = 0; i < BW * BH; i++)
        covered += out[(size_t)i * 4 + 3] == 1.0f;
    for (int y = SUB / 2; y < BH; y += SUB)
        for (int x = SUB / 2; x < BW; x += SUB) {
            size_t i = (size_t)y * BW + x;
            if (out[i * 4 + 3] != 1.0f)
                continue; /* background */
            r->index[r->n] = (int)i;
            memcpy(&r->uv[r->n * 2], &out[(size_t)BW * BH * 4 + i * 4], 2 * sizeof(float));
            memcpy(&r->l[r->n * 3], &out[(size_t)2 * BW * BH * 4 + i * 4], 3 * sizeof(float));
            memcpy(&r->v[r->n * 3], &out[(size_t)3 * BW * BH * 4 + i * 4], 3 * sizeof(float));
            r->n++;
        }
    printf("coverage %.4f fraction\n", (double)covered / (BW * BH));
    printf("error_samples %d pixels\n", r->n);
    free(out);
    return 0;
}

/* Reference colours for the first n chunks (nearest, tiled, clamped to 0..1). */
static void ref_decode(const btf_package *p, ref_pixels *r, int n)
{
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_NEAREST;
    o.wrap = 1;
    o.n_chunks = n;
    for (int i = 0; i < r->n; i++) {
        float rgb[3];
        btf_decode(p, r->uv[i * 2], r->uv[i * 2 + 1], &r->l[i * 3], &r->v[i * 3], &o, rgb);
        for (int c = 0; c < 3; c++)
            r->rgb[i * 3 + c] = rgb[c] < 0 ? 0 : rgb[c] > 1 ? 1 : rgb[c];
    }
}

static void ref_free(ref_pixels *r)
{
    free(r->index);
    free(r->uv);
    free(r->l);
    free(r->v);
    free(r->rgb);
}

/* RMSE and max abs error (0..255) of an RGBA8 render against the reference. */
static int render_error(btf_gl *gl, const btf_gl_target *t, const ref_pixels *r, double *rmse, double *maxe)
{
    btf_error err = {{0}};
    uint8_t *px = malloc((size_t)BW * BH * 4);
    if (!px || btf_gl_target_read(gl, t, 0, px, &err) != BTF_OK) {
        free(px);
        return die("readback", &err);
    }
    double s = 0, m = 0;
    for (int i = 0; i < r->n; i++)
        for (int c = 0; c < 3; c++) {
            double e = px[(size_t)r->index[i] * 4 + c] - 255.0 * r->rgb[i * 3 + c];
            s += e * e;
            m = fabs(e) > m ? fabs(e) : m;
        }
    *rmse = sqrt(s / (3.0 * r->n));
    *maxe = m;
    free(px);
    return 0;
}

/* ---------------------------------------------------------------- thesis textures */

/* GPU data of the thesis baseline for the first C chunks; freed by thesis_free. */
typedef struct thesis_data {
    GLuint map_idx[2], map_w[2]; /* lights, views */
    GLuint L, R;
    int G, Lw, Lh, Rw, Rh;
    float tlo[16], tstep[16], wlo[16], wstep[16], mask[16];
} thesis_data;

static uint8_t quant8(float x, float lo, float step) { return (uint8_t)lrintf(step > 0 ? (x - lo) / step : 0.0f); }

/* 512x512 lookup maps of one direction set (azimuthal-equidistant hemisphere). */
static int thesis_maps(btf_gl *gl, const btf_dirset *d, GLuint *idx, GLuint *w)
{
    uint8_t *a = malloc((size_t)MAPN * MAPN * 4), *b = malloc((size_t)MAPN * MAPN * 4);
    btf_error err = {{0}};
    if (!a || !b || d->n_dirs > 256)
        return die("thesis maps: memory or more than 256 directions", NULL);
    for (int j = 0; j < MAPN; j++)
        for (int i = 0; i < MAPN; i++) {
            double x = (i + 0.5) / MAPN * 2 - 1, y = (j + 0.5) / MAPN * 2 - 1, r = sqrt(x * x + y * y);
            float theta = (float)(90.0 * (r > 1 ? 1 : r)), phi = (float)(atan2(y, x) * 180.0 / M_PI);
            btf_interp in = btf_dirset_interp(d, theta, phi);
            size_t o = ((size_t)j * MAPN + i) * 4;
            for (int k = 0; k < 3; k++) {
                a[o + k] = (uint8_t)in.idx[k];
                b[o + k] = (uint8_t)lrintf(in.w[k] * 255.0f);
            }
            a[o + 3] = b[o + 3] = 255;
        }
    int rc = btf_gl_texture_create(gl, MAPN, MAPN, BTF_GL_RGBA8, a, idx, &err) != BTF_OK ||
             btf_gl_texture_create(gl, MAPN, MAPN, BTF_GL_RGBA8, b, w, &err) != BTF_OK;
    free(a);
    free(b);
    return rc ? die("thesis maps upload", &err) : 0;
}

/* Per-component global 8-bit ranges and the packed L and R textures. */
static int thesis_create(btf_gl *gl, const btf_package *p, int C, thesis_data *t)
{
    memset(t, 0, sizeof *t);
    int W = p->width, H = p->height, B = p->blocks->n_blocks, Ln = p->lights.n_dirs, Vn = p->views.n_dirs;
    t->G = (C + 3) / 4;
    t->Lw = W * t->G;
    t->Lh = H * B;
    t->Rw = Ln * 3 * t->G;
    t->Rh = Vn;
    for (int j = 0; j < C; j++) {
        float lo = 1e30f, hi = -1e30f, wl = 1e30f, wh = -1e30f;
        for (size_t i = 0; i < (size_t)B * W * H; i++) {
            lo = fminf(lo, p->tex[j][i]);
            hi = fmaxf(hi, p->tex[j][i]);
        }
        for (size_t i = 0; i < (size_t)Vn * Ln * 3; i++) {
            wl = fminf(wl, p->wt[j][i]);
            wh = fmaxf(wh, p->wt[j][i]);
        }
        t->tlo[j] = lo;
        t->tstep[j] = (hi - lo) / 255.0f;
        t->wlo[j] = wl;
        t->wstep[j] = (wh - wl) / 255.0f;
        t->mask[j] = 1;
    }
    uint8_t *L = calloc((size_t)t->Lw * t->Lh * 4, 1), *R = calloc((size_t)t->Rw * t->Rh * 4, 1);
    if (!L || !R)
        return die("thesis textures: out of memory", NULL);
    for (int j = 0; j < C; j++) {
        int g = j / 4, ch = j % 4;
        for (int b = 0; b < B; b++)
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++) {
                    float v = p->tex[j][((size_t)b * H + y) * W + x];
                    L[(((size_t)b * H + y) * t->Lw + (size_t)g * W + x) * 4 + ch] = quant8(v, t->tlo[j], t->tstep[j]);
                }
        for (int v = 0; v < Vn; v++)
            for (int l = 0; l < Ln; l++)
                for (int c = 0; c < 3; c++) {
                    float w = p->wt[j][((size_t)v * Ln + l) * 3 + c];
                    size_t col = ((size_t)l * 3 + c) * t->G + g;
                    R[((size_t)v * t->Rw + col) * 4 + ch] = quant8(w, t->wlo[j], t->wstep[j]);
                }
    }
    btf_error err = {{0}};
    int rc = btf_gl_texture_create(gl, t->Lw, t->Lh, BTF_GL_RGBA8, L, &t->L, &err) != BTF_OK ||
             btf_gl_texture_create(gl, t->Rw, t->Rh, BTF_GL_RGBA8, R, &t->R, &err) != BTF_OK;
    free(L);
    free(R);
    if (rc)
        return die("thesis textures upload", &err);
    if (thesis_maps(gl, &p->lights, &t->map_idx[0], &t->map_w[0]) ||
        thesis_maps(gl, &p->views, &t->map_idx[1], &t->map_w[1]))
        return 1;
    return 0;
}

static void thesis_bind(btf_gl *gl, GLuint prog, const btf_package *p, const thesis_data *t)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    const char *names[6] = {"u_light_idx", "u_light_w", "u_view_idx", "u_view_w", "u_L", "u_R"};
    GLuint tex[6] = {t->map_idx[0], t->map_w[0], t->map_idx[1], t->map_w[1], t->L, t->R};
    for (int i = 0; i < 6; i++) {
        f->ActiveTexture((GLenum)(GL_TEXTURE0 + i));
        f->BindTexture(GL_TEXTURE_2D, tex[i]);
        f->Uniform1i(f->GetUniformLocation(prog, names[i]), i);
    }
    f->Uniform2i(f->GetUniformLocation(prog, "u_size"), p->width, p->height);
    f->Uniform2f(f->GetUniformLocation(prog, "u_L_size"), (float)t->Lw, (float)t->Lh);
    f->Uniform2f(f->GetUniformLocation(prog, "u_R_size"), (float)t->Rw, (float)t->Rh);
    f->Uniform1i(f->GetUniformLocation(prog, "u_groups"), t->G);
    int vb[256] = {0};
    for (int v = 0; v < p->views.n_dirs && v < 256; v++)
        vb[v] = p->blocks->block_of_view[v];
    f->Uniform1iv(f->GetUniformLocation(prog, "u_view_block"), p->views.n_dirs, vb);
    f->Uniform4fv(f->GetUniformLocation(prog, "u_tlo"), 4, t->tlo);
    f->Uniform4fv(f->GetUniformLocation(prog, "u_tstep"), 4, t->tstep);
    f->Uniform4fv(f->GetUniformLocation(prog, "u_wlo"), 4, t->wlo);
    f->Uniform4fv(f->GetUniformLocation(prog, "u_wstep"), 4, t->wstep);
    f->Uniform4fv(f->GetUniformLocation(prog, "u_cmask"), 4, t->mask);
}

static void thesis_free(btf_gl *gl, thesis_data *t)
{
    GLuint tex[6] = {t->map_idx[0], t->map_w[0], t->map_idx[1], t->map_w[1], t->L, t->R};
    for (int i = 0; i < 6; i++)
        btf_gl_texture_free(gl, tex[i]);
}

/* The thesis program with its data for one C; owned by run(). */
typedef struct thesis_ctx {
    const scene *s;
    const btf_package *p;
    GLuint prog;
    thesis_data td;
} thesis_ctx;

static int thesis_setup(btf_gl *gl, void *ctx)
{
    thesis_ctx *tc = ctx;
    btf_error err = {{0}};
    btf_gl_fn(gl)->UseProgram(tc->prog);
    thesis_bind(gl, tc->prog, tc->p, &tc->td);
    scene_uniforms(gl, tc->prog, tc->s);
    return btf_gl_check(gl, "thesis setup", &err) != BTF_OK ? die("thesis", &err) : 0;
}

/* The one-fetch textured surface; owned by run(). */
typedef struct textured_ctx {
    const scene *s;
    GLuint prog, tex;
} textured_ctx;

static int textured_setup(btf_gl *gl, void *ctx)
{
    textured_ctx *xc = ctx;
    const btf_gl_api *f = btf_gl_fn(gl);
    f->UseProgram(xc->prog);
    scene_uniforms(gl, xc->prog, xc->s);
    f->ActiveTexture(GL_TEXTURE0);
    f->BindTexture(GL_TEXTURE_2D, xc->tex);
    f->Uniform1i(f->GetUniformLocation(xc->prog, "u_tex"), 0);
    return 0;
}

/* ---------------------------------------------------------------- main */

/* Texture fetches per fragment, from the sources:
 *   shader: 2 direction-table texels (one per set; a walk step, rare, adds one) +
 *           per (view a of 3, layer h of 4 slots): 1 texel of 4 slots (nearest) +
 *           3 weights texels (one per light) = 2 + 12 ceil(C/4); with levels the
 *           same (nearest: one paired texel holds both levels, shaders/README.md "GPU
 *           layout"; bilinear: 4 texels a level, 8 between two);
 *   thesis: 4 map fetches + per (view a, group g of 4 components): 1 L fetch + per
 *           light e: 3 R fetches (one per channel) = 4 + 30 ceil(C/4);
 *   textured: 1.
 * ALU (scalar ops, estimated from the sources): shader: frame + light/view vectors
 *   ~40, lod ~10, 2 direction lookups ~2 x 90 (normalise 12, octahedral cell 10, one
 *   walk step: 3 determinants 39 + argmin 6 + neighbour select 6, weights 15), view
 *   block and tile ~3 x 14 -> ~270; per (a, h) ~120 (texel unpack and dequantise 8,
 *   3 weight texels unpacked 3 x 28, blend 12 + dequantise 12 as multiply-adds... 4 x
 *   4 lanes counted once per vector op: ~120) -> ~270 + 360 ceil(C/4); thesis: frame
 *   ~40, 2 map coordinates ~2 x 12, index and weight unpacking ~20, per (a, g) ~14
 *   (coordinates, dequantise and mask a vec4), per (a, g, e) ~60 (3 coordinates, 3 vec4
 *   dequantisations 24, 3 dot4 21, blend 7) -> ~84 + 582 ceil(C/4); textured: ~4. */
static int shader_fetches(int C) { return 2 + 12 * ((C + 3) / 4); }
/* fixed light: 1 view-table texel + per (view a, layer h) 1 texture + 1 per-draw weight
 * texel; ALU: the run-time path less the light lookup (~90) and, per (a, h), less
 * the 2 extra weight texels' unpacking and the blend (~60 of ~120) */
static int fixed_fetches(int C) { return 1 + 6 * ((C + 3) / 4); }
static int fixed_alu(int C) { return 180 + 180 * ((C + 3) / 4); }
static int shader_alu(int C) { return 270 + 360 * ((C + 3) / 4); }
static int thesis_fetches(int C) { return 4 + 30 * ((C + 3) / 4); }
static int thesis_alu(int C) { return 84 + 582 * ((C + 3) / 4); }

/* The product program specialised for package g at C chunks (C = 0: all), as btf
 * render builds it (btf_gl_package_defines): nearest texels (the level run: also
 * bilinear), lod from derivatives. Owned by the run that made it, which frees prog
 * (btf_shader_program_free). */
typedef struct product_ctx {
    const scene *s;
    const btf_gl_package *g;
    int C;
    btf_shader_program *prog;
    const btf_env_quad *env; /* NULL: the point light; else the environment alone (doc/lighting.md) */
    btf_gl_fixed *fixed;     /* non-NULL: BTF_FIXED_LIGHT with these per-draw weights (not owned) */
    int filter;              /* 0 nearest, 1 bilinear (a package with levels: u_btf_tex laid out for it) */
} product_ctx;

/* Builds pc->prog from the shaders in dir (NULL: the usual place, btf_shader_desc). */
static int product_build(btf_gl *gl, product_ctx *pc, const char *dir)
{
    btf_error err = {{0}};
    btf_shader_define defs[BTF_GL_PACKAGE_DEFINES + 3];
    char vals[BTF_GL_PACKAGE_DEFINES][16];
    btf_shader_desc sd = {.dir = dir, .program = "render", .defines = defs};
    sd.n_defines = btf_gl_package_defines(pc->g, pc->filter, pc->C, defs, vals);
    defs[sd.n_defines++] = (btf_shader_define){"BTF_POINT", pc->env ? "0" : "1"};
    defs[sd.n_defines++] = (btf_shader_define){"BTF_ENV", pc->env ? "1" : "0"};
    if (pc->fixed)
        defs[sd.n_defines++] = (btf_shader_define){"BTF_FIXED_LIGHT", "1"};
    btf_shader_program_free(gl, pc->prog);
    pc->prog = NULL;
    if (btf_shader_build(gl, &sd, &pc->prog, NULL, &err) != BTF_OK)
        return die("product program", &err);
    return 0;
}

static int product_setup(btf_gl *gl, void *ctx)
{
    product_ctx *pc = ctx;
    btf_error err = {{0}};
    btf_gl_fn(gl)->UseProgram(pc->prog->id);
    if (btf_gl_package_bind(gl, pc->g, pc->prog, 0, &err) != BTF_OK)
        return die("bind", &err);
    btf_gl_decode_settings ds = {pc->filter, 1, pc->C};
    btf_gl_package_settings(gl, pc->g, pc->prog, &ds);
    if (pc->fixed) { /* the plane's local frame is the world's: the local light is the world light */
        if (btf_gl_fixed_update(gl, pc->fixed, pc->g, pc->s->cam.light, pc->C, &err) != BTF_OK)
            return die("fixed light", &err);
        btf_gl_fixed_bind(gl, pc->fixed, pc->prog, BTF_GL_FIXED_UNIT);
    }
    scene_uniforms(gl, pc->prog->id, pc->s);
    btf_render_params lp = btf_render_defaults(BTF_RENDER_PLANE);
    lp.no_point_light = pc->env != NULL;
    btf_render_light_uniforms(gl, pc->prog->id, &lp, pc->env);
    return 0;
}

/* Draws one frame of case c into t (for the error measurement). */
static int draw_once(btf_gl *gl, const scene *s, const btf_gl_target *t, const bench_case *c)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_gl_target_bind(gl, t);
    f->BindVertexArray(s->vao);
    if (c->setup(gl, c->ctx))
        return 1;
    f->ClearColor(0, 0, 0, 1);
    f->Clear(GL_COLOR_BUFFER_BIT);
    f->DrawElements(GL_TRIANGLES, s->n_indices, GL_UNSIGNED_INT, 0);
    f->Finish();
    return 0;
}

/* The shortest chunk prefix of g that uses C slots (0, every chunk, where C is all). */
static int levels_prefix(const btf_gl_package *g, int C, int n_loaded)
{
    if (btf_gl_package_slots(g, 0) <= C)
        return 0;
    int n = 1;
    while (n < n_loaded && btf_gl_package_slots(g, n) < C)
        n++;
    return n;
}

/* One C and filter of the level run: the four programs (level 0 alone and the levels
 * package, on the run-time and the fixed-light path; with alt, the fixed-light pair
 * again from those shaders), timed interleaved; cn: the chunk prefixes of g[0] and
 * g[1]. Bilinear lines are named levels_bilinear_*. */
static int run_levels_at(btf_gl *gl, const scene *s, const btf_gl_target *t, const btf_gl_package *g[2],
                         btf_gl_fixed *x[2], const int cn[2], int C, const char *alt, int filter, double row[4])
{
    product_ctx pc[6] = {{s, g[0], cn[0], NULL, NULL, NULL, filter}, {s, g[1], cn[1], NULL, NULL, NULL, filter},
                         {s, g[0], cn[0], NULL, NULL, x[0], filter}, {s, g[1], cn[1], NULL, NULL, x[1], filter},
                         {s, g[0], cn[0], NULL, NULL, x[0], filter}, {s, g[1], cn[1], NULL, NULL, x[1], filter}};
    bench_case c[6];
    int rc = 0, n = alt ? 6 : 4;
    for (int i = 0; i < n; i++) {
        c[i] = (bench_case){.setup = product_setup, .ctx = &pc[i]};
        rc = rc || product_build(gl, &pc[i], i < 4 ? NULL : alt);
    }
    rc = rc || time_frames(gl, s, t, c, n);
    static const char *path[2][3] = {{"", "fixed_", "alt_fixed_"},
                                     {"bilinear_", "bilinear_fixed_", "bilinear_alt_fixed_"}};
    for (int k = 0; k < n / 2 && !rc; k++) {
        double v1 = c[2 * k].cost.cpu_ms, v2 = c[2 * k + 1].cost.cpu_ms;
        const char *pk = path[filter == 1][k];
        printf("levels_%sv1_C%d_cpu_ms %.2f ms\nlevels_%sv2_C%d_cpu_ms %.2f ms\n", pk, C, v1, pk, C, v2);
        printf("levels_%sv2_over_v1_C%d_cpu_ratio %.3f x\n", pk, C, v2 / v1);
        row[2 * k] = v1, row[2 * k + 1] = v2 / v1; /* the table's (run-time, fixed) pairs */
        if (c[2 * k].cost.gpu_ms > 0 && c[2 * k + 1].cost.gpu_ms > 0)
            printf("levels_%sv2_over_v1_C%d_gpu_ratio %.3f x\n", pk, C,
                   c[2 * k + 1].cost.gpu_ms / c[2 * k].cost.gpu_ms);
    }
    fflush(stdout);
    for (int i = 0; i < n; i++)
        btf_shader_program_free(gl, pc[i].prog);
    return rc;
}

/* The level run's table (as comment lines): per C, level 0's CPU ms and the levels
 * package's ratio over it, nearest then bilinear, each for the run-time and the fixed
 * light; a C or filter not run is left out (0). */
static void print_levels_table(const int Cs[4], double tab[4][2][4])
{
    printf("# | C | level 0 ms, nearest (run-time / fixed light) | levels / level 0, nearest | "
           "level 0 ms, bilinear | levels / level 0, bilinear |\n# |---|---|---|---|---|\n");
    for (int k = 0; k < 4; k++) {
        const double *n = tab[k][0], *b = tab[k][1];
        if (n[0] > 0 || b[0] > 0)
            printf("# | %d | %.1f / %.1f | %.3f / %.3f | %.1f / %.1f | %.3f / %.3f |\n", Cs[k], n[0], n[2], n[1], n[3],
                   b[0], b[2], b[1], b[3]);
    }
    fflush(stdout);
}

/* The spatial-levels package (3 levels) of the same material against version 1: the
 * level path's cost over level 0 alone at C = 1, 4, 8, 16 slots (the levels package's
 * shortest chunk prefix with C slots: the same program, every level filled), each C in
 * one run, interleaved, for the run-time light path and for the fixed-light one; with
 * nearest texels (the levels package's texture paired) and then bilinear (not paired:
 * shaders/README.md, "GPU layout"), each against level 0 with the same filter.
 * BENCH_LEVELS_FILTER=0 or 1: one filter alone. */
static int run_levels(btf_gl *gl, const btf_package *p1, const char *dir1, const scene *s, const btf_gl_target *t)
{
    char dir2[1100];
    snprintf(dir2, sizeof dir2, "%s-v2", dir1);
    btf_error err = {{0}};
    btf_package *p2 = NULL;
    btf_gl_package *g1 = NULL, *g2 = NULL;
    btf_gl_fixed *x[2] = {NULL, NULL};
    if (btf_package_read(dir2, 0, &p2, &err) != BTF_OK ||
        btf_gl_package_upload(gl, p1, dir1, &g1, &err) != BTF_OK || btf_gl_package_upload(gl, p2, dir2, &g2, &err) ||
        btf_gl_fixed_create(gl, g1, &x[0], &err) != BTF_OK || btf_gl_fixed_create(gl, g2, &x[1], &err) != BTF_OK)
        return die("levels package", &err);
    const char *alt = getenv("BENCH_ALT_SHADERS"); /* the fixed-light pair again, from these shaders */
    const char *only = getenv("BENCH_LEVELS_C");   /* one C alone */
    const char *fo = getenv("BENCH_LEVELS_FILTER"); /* one filter alone */
    const btf_gl_package *g[2] = {g1, g2};
    static const int Cs[4] = {1, 4, 8, 16};
    double tab[4][2][4] = {{{0}}}; /* per C and filter: level-0 ms and ratio, run-time then fixed light */
    int rc = 0;
    for (int k = 0; k < 4 && !rc; k++) {
        int C = Cs[k], cn[2] = {C, levels_prefix(g2, C, p2->n_loaded)};
        for (int filter = 0; filter < 2 && !rc; filter++)
            if (C <= p1->n_loaded && (!only || atoi(only) == C) && (!fo || atoi(fo) == filter))
                rc = run_levels_at(gl, s, t, g, x, cn, C, alt, filter, tab[k][filter]);
    }
    if (!rc)
        print_levels_table(Cs, tab);
    btf_gl_fixed_free(gl, x[0]);
    btf_gl_fixed_free(gl, x[1]);
    btf_gl_package_free(gl, g1);
    btf_gl_package_free(gl, g2);
    btf_package_free(p2);
    return rc;
}

/* ---------------------------------------------------------------- fetch costs */

#define FETCH_KINDS 7
#define FETCH_SIDE 256
static const char *fetch_names[FETCH_KINDS] = {"rgba8_texelfetch", "rgba8_texture", "rgba16ui_texelfetch",
                                               "rgba32ui_texelfetch", "r32ui_texelfetch", "ubo_vec4", "none"};

/* The textures and block of shaders/bench/fetch.frag; owned by run_fetch. */
typedef struct fetch_data {
    GLuint tex[4]; /* RGBA8, RGBA16UI, RGBA32UI, R32UI */
    GLuint ubo;
} fetch_data;

/* One program of fetch.frag (kind, count) with its data; owned by run_fetch. */
typedef struct fetch_ctx {
    const scene *s;
    const fetch_data *d;
    int kind;
    GLuint prog;
} fetch_ctx;

static int fetch_setup(btf_gl *gl, void *ctx)
{
    fetch_ctx *fc = ctx;
    const btf_gl_api *f = btf_gl_fn(gl);
    static const int int_tex[FETCH_KINDS] = {1, 1, 1, 2, 3, 1, 1}; /* u_fu per kind (any integer one if unread) */
    f->UseProgram(fc->prog);
    scene_uniforms(gl, fc->prog, fc->s);
    f->ActiveTexture(GL_TEXTURE0);
    f->BindTexture(GL_TEXTURE_2D, fc->d->tex[0]);
    f->Uniform1i(f->GetUniformLocation(fc->prog, "u_f8"), 0);
    f->ActiveTexture(GL_TEXTURE1);
    f->BindTexture(GL_TEXTURE_2D, fc->d->tex[int_tex[fc->kind]]);
    f->Uniform1i(f->GetUniformLocation(fc->prog, "u_fu"), 1);
    GLuint block = f->GetUniformBlockIndex(fc->prog, "fetch_block");
    if (block != GL_INVALID_INDEX)
        f->UniformBlockBinding(fc->prog, block, 1);
    f->BindBufferBase(GL_UNIFORM_BUFFER, 1, fc->d->ubo);
    return 0;
}

/* 256 x 256 textures of every format fetch.frag reads, filled with noise. */
static int fetch_data_create(btf_gl *gl, fetch_data *d)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    static const GLenum ifmt[4] = {GL_RGBA8, GL_RGBA16UI, GL_RGBA32UI, GL_R32UI};
    static const GLenum fmt[4] = {GL_RGBA, GL_RGBA_INTEGER, GL_RGBA_INTEGER, GL_RED_INTEGER};
    static const GLenum type[4] = {GL_UNSIGNED_BYTE, GL_UNSIGNED_SHORT, GL_UNSIGNED_INT, GL_UNSIGNED_INT};
    uint32_t *noise = malloc((size_t)FETCH_SIDE * FETCH_SIDE * 4 * sizeof(uint32_t));
    if (!noise)
        return die("fetch data: out of memory", NULL);
    uint32_t x = 2463534242u; /* xorshift32 */
    for (size_t i = 0; i < (size_t)FETCH_SIDE * FETCH_SIDE * 4; i++) {
        x ^= x << 13, x ^= x >> 17, x ^= x << 5;
        noise[i] = x;
    }
    f->GenTextures(4, d->tex);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    for (int i = 0; i < 4; i++) {
        f->BindTexture(GL_TEXTURE_2D, d->tex[i]);
        f->TexImage2D(GL_TEXTURE_2D, 0, (GLint)ifmt[i], FETCH_SIDE, FETCH_SIDE, 0, fmt[i], type[i], noise);
        f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    f->GenBuffers(1, &d->ubo);
    f->BindBuffer(GL_UNIFORM_BUFFER, d->ubo);
    f->BufferData(GL_UNIFORM_BUFFER, 1024 * 16, noise, GL_STATIC_DRAW);
    f->BindBuffer(GL_UNIFORM_BUFFER, 0);
    free(noise);
    btf_error err = {{0}};
    return btf_gl_check(gl, "fetch data", &err) != BTF_OK ? die("fetch data", &err) : 0;
}

/* The cost of one read of each kind: fetch.frag with 4 and with 16 reads per fragment,
 * all 14 programs interleaved frame by frame; (t16 - t4) / 12 is the CPU time one
 * more read of that kind adds to a 1280x720 frame. */
static int run_fetch(btf_gl *gl, const scene *s, const btf_gl_target *t)
{
    fetch_data d;
    memset(&d, 0, sizeof d);
    fetch_ctx fc[2 * FETCH_KINDS];
    bench_case c[2 * FETCH_KINDS];
    int rc = fetch_data_create(gl, &d);
    for (int i = 0; i < 2 * FETCH_KINDS && !rc; i++) {
        char defs[96];
        snprintf(defs, sizeof defs, "#define FETCH_N %d\n#define FETCH_KIND %d\n", i % 2 ? 16 : 4, i / 2);
        fc[i] = (fetch_ctx){s, &d, i / 2, build_bench_program(gl, "fetch.frag", defs)};
        c[i] = (bench_case){.setup = fetch_setup, .ctx = &fc[i]};
        rc = fc[i].prog == 0;
    }
    if (!rc)
        rc = time_frames(gl, s, t, c, 2 * FETCH_KINDS);
    for (int k = 0; k < FETCH_KINDS && !rc; k++)
        printf("fetch_%s_cpu_ms %.3f ms_per_read\n", fetch_names[k], (c[2 * k + 1].cost.cpu_ms - c[2 * k].cost.cpu_ms) / 12);
    for (int i = 0; i < 2 * FETCH_KINDS; i++)
        if (fc[i].prog)
            btf_gl_fn(gl)->DeleteProgram(fc[i].prog);
    btf_gl_fn(gl)->DeleteBuffers(1, &d.ubo);
    for (int i = 0; i < 4; i++)
        btf_gl_texture_free(gl, d.tex[i]);
    return rc;
}

/* One C of the comparison, for the summary table. */
typedef struct bench_row {
    int C;
    double shader_ms, thesis_ms, env_ms, fixed_ms, e_s, m_s, e_t, m_t, e_x, m_x;
} bench_row;

/* ---------------------------------------------------------------- nonlinear decoder */

#define NN_Z 16      /* latents a texel: bench_nn.c's smaller shape */
#define NN_TEXW 1024 /* parameter texture row, in vec4 (nn.frag) */

/* A network of bench_nn.c's shape with random parameters (its cost does not depend on
 * them; the error compares the program with nn_eval on the same ones), its program and
 * textures; owned by run_nn, one per hidden width, freed by nn_free. */
typedef struct nn_ctx {
    const scene *s;
    int H, K1, G, n_vec; /* hidden units, input vec4 (latents + 2), vec4 a layer, parameter vec4 */
    int off[6];          /* W1 b1 W2 b2 W3 b3: first vec4 of each (nn.frag's order) */
    float *w;            /* n_vec x 4, half-float values */
    uint8_t *lat;        /* MAT x MAT x NN_Z latent bytes */
    float lo[NN_Z], step[NN_Z];
    GLuint prog, wtex, ltex;
} nn_ctx;

/* Multiply-adds and texel fetches per fragment (padded inputs counted as evaluated). */
static int nn_macs(int H) { return H * (NN_Z + 8) + H * H + 3 * H; }
static int nn_fetches(int H) { return NN_Z / 4 + H * (NN_Z / 4 + 2) + H * H / 4 + 5 * H / 4 + 1; }

/* Uniform in (-a, a), half-rounded. */
static float nn_rand(unsigned short st[3], double a) { return bench_half_round((float)((erand48(st) * 2 - 1) * a)); }

/* Fills the parameters (He-uniform layers, an output around mid-grey) and latents. */
static void nn_fill(nn_ctx *n)
{
    unsigned short st[3] = {0x5eed, 0x00aa, (unsigned short)n->H};
    int din = NN_Z + 6, fan[3] = {din, n->H, n->H}, rows[3] = {n->H, n->H, 3}, len[3] = {n->K1, n->G, n->G};
    double gain[3] = {1.0, 1.0, 0.2};
    for (int layer = 0; layer < 3; layer++) {
        float *w = n->w + 4 * (size_t)n->off[2 * layer], *b = n->w + 4 * (size_t)n->off[2 * layer + 1];
        double a = gain[layer] * sqrt(6.0 / fan[layer]);
        for (int u = 0; u < rows[layer]; u++) {
            for (int k = 0; k < 4 * len[layer]; k++) /* inputs past din (the padding) get 0 */
                w[(size_t)u * 4 * len[layer] + k] = layer == 0 && k >= din ? 0.0f : nn_rand(st, a);
            b[u] = layer == 2 ? 0.5f : nn_rand(st, 0.05);
        }
    }
    for (int z = 0; z < NN_Z; z++)
        n->lo[z] = -1.0f - 0.05f * z, n->step[z] = (2.0f + 0.1f * z) / 255.0f;
    for (size_t i = 0; i < (size_t)MAT * MAT * NN_Z; i++)
        n->lat[i] = (uint8_t)(erand48(st) * 256);
}

/* The network's value at texel (x, y) for local light l and view v (unit), clamped. */
static void nn_eval(const nn_ctx *n, int x, int y, const float l[3], const float v[3], float rgb[3])
{
    float in[NN_Z + 8] = {0}, h1[128], h2[128];
    for (int z = 0; z < NN_Z; z++)
        in[z] = n->lo[z] + n->step[z] * n->lat[((size_t)y * MAT + x) * NN_Z + z];
    bench_nn_features(l, v, in + NN_Z);
    const float *src[3] = {in, h1, h2};
    float *dst[3] = {h1, h2, rgb};
    int rows[3] = {n->H, n->H, 3}, len[3] = {4 * n->K1, n->H, n->H};
    for (int layer = 0; layer < 3; layer++) {
        const float *w = n->w + 4 * (size_t)n->off[2 * layer], *b = n->w + 4 * (size_t)n->off[2 * layer + 1];
        for (int u = 0; u < rows[layer]; u++) {
            double a = b[u];
            for (int k = 0; k < len[layer]; k++)
                a += (double)w[(size_t)u * len[layer] + k] * src[layer][k];
            dst[layer][u] = layer < 2 ? (float)fmax(a, 0.0) : (float)fmin(fmax(a, 0.0), 1.0);
        }
    }
}

/* n's parameters, latents, textures and program for H hidden units; 0 on success. */
static int nn_create(btf_gl *gl, const scene *s, int H, nn_ctx *n)
{
    memset(n, 0, sizeof *n);
    n->s = s, n->H = H, n->K1 = NN_Z / 4 + 2, n->G = H / 4;
    int sizes[6] = {H * n->K1, n->G, H * n->G, n->G, 3 * n->G, 1};
    for (int i = 0; i < 6; i++)
        n->off[i] = n->n_vec, n->n_vec += sizes[i];
    int rows = (n->n_vec + NN_TEXW - 1) / NN_TEXW;
    n->w = calloc((size_t)rows * NN_TEXW * 4, sizeof(float));
    n->lat = malloc((size_t)MAT * MAT * NN_Z);
    uint8_t *img = malloc((size_t)MAT * MAT * NN_Z);
    if (!n->w || !n->lat || !img) {
        free(img);
        return die("nn: out of memory", NULL);
    }
    nn_fill(n);
    for (int q = 0; q < NN_Z / 4; q++) /* layer q of 4 latents below layer q - 1 */
        for (size_t i = 0; i < (size_t)MAT * MAT; i++)
            memcpy(img + ((size_t)q * MAT * MAT + i) * 4, n->lat + i * NN_Z + 4 * q, 4);
    btf_error err = {{0}};
    int bad = btf_gl_texture_create(gl, NN_TEXW, rows, BTF_GL_RGBA32F, n->w, &n->wtex, &err) != BTF_OK ||
              btf_gl_texture_create(gl, MAT, MAT * NN_Z / 4, BTF_GL_RGBA8, img, &n->ltex, &err) != BTF_OK;
    free(img);
    if (bad)
        return die("nn textures", &err);
    char defs[160];
    snprintf(defs, sizeof defs, "#define NN_Z %d\n#define NN_H %d\n#define NN_TEXW %d\n", NN_Z, H, NN_TEXW);
    n->prog = build_bench_program(gl, "nn.frag", defs);
    return n->prog ? 0 : 1;
}

static int nn_setup(btf_gl *gl, void *ctx)
{
    nn_ctx *n = ctx;
    const btf_gl_api *f = btf_gl_fn(gl);
    f->UseProgram(n->prog);
    GLuint tex[2] = {n->ltex, n->wtex};
    const char *names[2] = {"u_lat", "u_w"};
    for (int i = 0; i < 2; i++) {
        f->ActiveTexture((GLenum)(GL_TEXTURE0 + i));
        f->BindTexture(GL_TEXTURE_2D, tex[i]);
        f->Uniform1i(f->GetUniformLocation(n->prog, names[i]), i);
    }
    f->Uniform2i(f->GetUniformLocation(n->prog, "u_size"), MAT, MAT);
    f->Uniform4fv(f->GetUniformLocation(n->prog, "u_lat_lo"), NN_Z / 4, n->lo);
    f->Uniform4fv(f->GetUniformLocation(n->prog, "u_lat_step"), NN_Z / 4, n->step);
    scene_uniforms(gl, n->prog, n->s);
    btf_error err = {{0}};
    return btf_gl_check(gl, "nn setup", &err) != BTF_OK ? die("nn", &err) : 0;
}

/* r->rgb: n's values at the sampled pixels (their uv, local light and view); returns
 * the share of values inside (0, 1), which the comparison sees unclamped. */
static double nn_ref(const nn_ctx *n, ref_pixels *r)
{
    int inside = 0;
    for (int i = 0; i < r->n; i++) {
        float l[3], v[3], ln = 0, vn = 0;
        for (int c = 0; c < 3; c++)
            ln += r->l[i * 3 + c] * r->l[i * 3 + c], vn += r->v[i * 3 + c] * r->v[i * 3 + c];
        for (int c = 0; c < 3; c++)
            l[c] = r->l[i * 3 + c] / sqrtf(ln), v[c] = r->v[i * 3 + c] / sqrtf(vn);
        int xy[2];
        for (int a = 0; a < 2; a++) {
            float u = r->uv[i * 2 + a];
            xy[a] = (int)floorf((u - floorf(u)) * MAT);
            xy[a] = xy[a] < 0 ? 0 : xy[a] >= MAT ? MAT - 1 : xy[a];
        }
        nn_eval(n, xy[0], xy[1], l, v, &r->rgb[i * 3]);
        for (int c = 0; c < 3; c++)
            inside += r->rgb[i * 3 + c] > 0.0f && r->rgb[i * 3 + c] < 1.0f;
    }
    return r->n ? inside / (3.0 * r->n) : 0.0;
}

static void nn_free(btf_gl *gl, nn_ctx *n)
{
    btf_gl_texture_free(gl, n->wtex);
    btf_gl_texture_free(gl, n->ltex);
    if (n->prog)
        btf_gl_fn(gl)->DeleteProgram(n->prog);
    free(n->w);
    free(n->lat);
}

/* The network at H = 64 and 128 against the product program at C = 8 (run-time and
 * fixed light), frames interleaved; each network's render against nn_eval. */
static int run_nn(btf_gl *gl, const scene *s, const btf_gl_target *t, const btf_gl_package *g, btf_gl_fixed *fixed,
                  ref_pixels *ref)
{
    static const int Hs[2] = {64, 128};
    nn_ctx nn[2] = {{0}}; /* nn_free is safe on one nn_create did not reach */
    product_ctx pc = {s, g, 8, NULL, NULL, NULL, 0}, px = {s, g, 8, NULL, NULL, fixed, 0};
    int bad = product_build(gl, &pc, NULL) || product_build(gl, &px, NULL);
    for (int i = 0; i < 2; i++)
        bad = bad || nn_create(gl, s, Hs[i], &nn[i]);
    bench_case c[4] = {{.setup = product_setup, .ctx = &pc}, {.setup = product_setup, .ctx = &px},
                       {.setup = nn_setup, .ctx = &nn[0]}, {.setup = nn_setup, .ctx = &nn[1]}};
    bad = bad || time_frames(gl, s, t, c, 4);
    for (int i = 0; !bad && i < 2; i++) {
        double e, m;
        double inside = nn_ref(&nn[i], ref);
        if ((bad = draw_once(gl, s, t, &c[2 + i]) || render_error(gl, t, ref, &e, &m)) != 0)
            break;
        frame_cost k = c[2 + i].cost;
        int H = Hs[i];
        printf("nn_h%d_cpu_ms %.2f ms\nnn_h%d_over_shader_C8_cpu_ratio %.3f x\nnn_h%d_over_fixed_C8_cpu_ratio %.3f x\n", H,
               k.cpu_ms, H, k.cpu_ms / c[0].cost.cpu_ms, H, k.cpu_ms / c[1].cost.cpu_ms);
        if (k.gpu_ms > 0 && c[0].cost.gpu_ms > 0 && c[1].cost.gpu_ms > 0)
            printf("nn_h%d_gpu_ms %.3f ms\nnn_h%d_over_shader_C8_gpu_ratio %.3f x\nnn_h%d_over_fixed_C8_gpu_ratio %.3f x\n",
                   H, k.gpu_ms, H, k.gpu_ms / c[0].cost.gpu_ms, H, k.gpu_ms / c[1].cost.gpu_ms);
        printf("nn_h%d_rmse_vs_cpu %.3f 0..255\nnn_h%d_max_err_vs_cpu %.1f 0..255\nnn_h%d_unclamped %.3f fraction\n", H,
               e, H, m, H, inside);
        printf("nn_h%d_macs %d per_fragment\nnn_h%d_fetches %d per_fragment\n", H, nn_macs(H), H, nn_fetches(H));
        printf("# nn H = %d (Z = %d): %.2f ms CPU a frame against %.2f (product, run-time light, C = 8) and %.2f "
               "(fixed light): %.2fx / %.2fx; RMSE %.3f against the CPU evaluation\n",
               H, NN_Z, k.cpu_ms, c[0].cost.cpu_ms, c[1].cost.cpu_ms, k.cpu_ms / c[0].cost.cpu_ms,
               k.cpu_ms / c[1].cost.cpu_ms, e);
    }
    fflush(stdout);
    for (int i = 0; i < 2; i++)
        nn_free(gl, &nn[i]);
    btf_shader_program_free(gl, pc.prog);
    btf_shader_program_free(gl, px.prog);
    return bad;
}

/* The results as a markdown table, as comment lines of the results file: the product
 * as btf render draws this scene (fixed light), then the run-time light path. */
static void print_table(const bench_row *r, int n)
{
    printf("# | C | product ms (fixed light) | thesis ms | thesis / product | run-time light ms | thesis / run-time | "
           "environment ms | environment / run-time | fetches (fixed / run-time / thesis) | ALU est. (fixed / thesis) | "
           "RMSE vs btf_decode (fixed / run-time / thesis) | max error (fixed / run-time / thesis) |\n");
    printf("# |---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int i = 0; i < n; i++)
        printf("# | %d | %.1f | %.1f | %.2f | %.1f | %.2f | %.1f | %.2f | %d / %d / %d | %d / %d | %.3f / %.3f / %.3f | "
               "%.1f / %.1f / %.1f |\n",
               r[i].C, r[i].fixed_ms, r[i].thesis_ms, r[i].thesis_ms / r[i].fixed_ms, r[i].shader_ms,
               r[i].thesis_ms / r[i].shader_ms, r[i].env_ms, r[i].env_ms / r[i].shader_ms, fixed_fetches(r[i].C),
               shader_fetches(r[i].C), thesis_fetches(r[i].C), fixed_alu(r[i].C), thesis_alu(r[i].C), r[i].e_x, r[i].e_s,
               r[i].e_t, r[i].m_x, r[i].m_s, r[i].m_t);
}

static int run(btf_gl *gl, const btf_package *p, const char *dir)
{
    btf_error err = {{0}};
    scene s;
    memset(&s, 0, sizeof s);
    if (scene_create(gl, &s))
        return 1;
    ref_pixels ref;
    if (ref_create(gl, p, dir, &s, &ref))
        return 1;
    const btf_gl_api *f = btf_gl_fn(gl);
    btf_gl_target *t = NULL;
    if (btf_gl_target_create(gl, BW, BH, BTF_GL_RGBA8, 1, &t, &err) != BTF_OK)
        return die("target", &err);
    /* product program */
    btf_shader_program *prog = NULL;
    btf_gl_package *g = NULL;
    if (btf_gl_package_upload(gl, p, dir, &g, &err))
        return die("product package", &err);
    btf_env *env = NULL; /* the built-in studio: the environment case */
    btf_env_quad studio;
    if (btf_env_studio(&env, &err) != BTF_OK)
        return die("studio", &err);
    btf_env_quadratic(env, 0, &studio);
    btf_env_free(env);
    GLuint thesis = build_bench_program(gl, "thesis.frag", ""), textured = build_bench_program(gl, "textured.frag", "");
    if (!thesis || !textured)
        return 1;
    /* textured: the package's value for light = view = normal, RGBA8, bilinear, tiled */
    uint8_t *img = malloc((size_t)p->width * p->height * 4);
    const float z[3] = {0, 0, 1};
    btf_decode_options dop = {0};
    for (int y = 0; y < p->height; y++)
        for (int x = 0; x < p->width; x++) {
            float rgb[3];
            btf_decode(p, (x + 0.5f) / p->width, (y + 0.5f) / p->height, z, z, &dop, rgb);
            for (int c = 0; c < 4; c++)
                img[((size_t)y * p->width + x) * 4 + c] = c == 3 ? 255 : (uint8_t)lrintf(255 * fminf(fmaxf(rgb[c], 0), 1));
        }
    GLuint tex = 0;
    if (btf_gl_texture_create(gl, p->width, p->height, BTF_GL_RGBA8, img, &tex, &err) != BTF_OK)
        return die("textured texture", &err);
    free(img);
    f->BindTexture(GL_TEXTURE_2D, tex);
    f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);

    textured_ctx xc = {&s, textured, tex};
    bench_case cx = {.setup = textured_setup, .ctx = &xc};
    double e_tex, m_tex;
    ref_decode(p, &ref, 0);
    if (time_frames(gl, &s, t, &cx, 1) || draw_once(gl, &s, t, &cx) || render_error(gl, t, &ref, &e_tex, &m_tex))
        return 1;
    frame_cost ms_tex = cx.cost;
    printf("textured_ms %.2f ms\ntextured_cpu_ms %.2f ms\n", ms_tex.wall_ms, ms_tex.cpu_ms);
    printf("textured_fetches 1 per_fragment\ntextured_alu 4 per_fragment_est\n");
    printf("textured_rmse_vs_all_chunks %.3f 0..255\n", e_tex);

    /* BENCH_ALT_SHADERS=DIR: one more case, the product program assembled from DIR's
     * shader files (same host layout), for A/B runs of a shader change; with
     * BENCH_ALT_FIXED=1 built and bound as the fixed-light case, else as `shader`. */
    const char *alt = getenv("BENCH_ALT_SHADERS");
    int alt_fixed = getenv("BENCH_ALT_FIXED") && atoi(getenv("BENCH_ALT_FIXED")) == 1;
    btf_gl_fixed *fixed = NULL; /* the per-draw light weights of the fixed-light case */
    if (btf_gl_fixed_create(gl, g, &fixed, &err) != BTF_OK)
        return die("fixed light", &err);
    static const int Cs[5] = {1, 2, 4, 8, 16};
    bench_row rows[5];
    int n_rows = 0;
    for (int k = 0; k < 5; k++) {
        int C = Cs[k];
        if (C > p->n_loaded || (getenv("BENCH_MAX_C") && C > atoi(getenv("BENCH_MAX_C"))))
            break;
        ref_decode(p, &ref, C);
        /* product: the program specialised for the package (no levels), the filter
         * (nearest) and C, as btf render builds it (btf_gl_package_defines) */
        product_ctx pc = {&s, g, C, prog, NULL, NULL, 0}, pe = {&s, g, C, NULL, &studio, NULL, 0},
                    px = {&s, g, C, NULL, NULL, fixed, 0}, pa = {&s, g, C, NULL, NULL, alt_fixed ? fixed : NULL, 0};
        thesis_ctx tc = {.s = &s, .p = p, .prog = thesis};
        bench_case c[5] = {{.setup = product_setup, .ctx = &pc}, {.setup = thesis_setup, .ctx = &tc},
                           {.setup = product_setup, .ctx = &pe}, {.setup = product_setup, .ctx = &px},
                           {.setup = product_setup, .ctx = &pa}};
        int n_cases = alt ? 5 : 4;
        if (product_build(gl, &pc, NULL) || product_build(gl, &pe, NULL) || product_build(gl, &px, NULL) ||
            (alt && product_build(gl, &pa, alt)) || thesis_create(gl, p, C, &tc.td))
            return 1;
        prog = pc.prog;
        double e[5], m[5];
        if (time_frames(gl, &s, t, c, n_cases))
            return 1;
        for (int i = 0; i < n_cases; i++) /* the environment's picture is not btf_decode's */
            if (i != 2 && (draw_once(gl, &s, t, &c[i]) || render_error(gl, t, &ref, &e[i], &m[i])))
                return 1;
        thesis_free(gl, &tc.td);
        btf_shader_program_free(gl, pa.prog);
        btf_shader_program_free(gl, px.prog);
        btf_shader_program_free(gl, pe.prog);
        frame_cost ms_s = c[0].cost, ms_t = c[1].cost;
        printf("shader_C%d_ms %.2f ms\nthesis_C%d_ms %.2f ms\n", C, ms_s.wall_ms, C, ms_t.wall_ms);
        if (ms_s.gpu_ms > 0 && ms_t.gpu_ms > 0)
            printf("shader_C%d_gpu_ms %.3f ms\nthesis_C%d_gpu_ms %.3f ms\nthesis_over_shader_C%d_gpu_ratio %.3f x\n", C,
                   ms_s.gpu_ms, C, ms_t.gpu_ms, C, ms_t.gpu_ms / ms_s.gpu_ms);
        printf("shader_C%d_cpu_ms %.2f ms\nthesis_C%d_cpu_ms %.2f ms\n", C, ms_s.cpu_ms, C, ms_t.cpu_ms);
        printf("thesis_over_shader_C%d_cpu_ratio %.3f x\nshader_over_textured_C%d_cpu_ratio %.2f x\n", C,
               ms_t.cpu_ms / ms_s.cpu_ms, C, ms_s.cpu_ms / ms_tex.cpu_ms);
        printf("shader_C%d_rmse %.3f 0..255\nshader_C%d_max_err %.1f 0..255\n", C, e[0], C, m[0]);
        printf("thesis_C%d_rmse %.3f 0..255\nthesis_C%d_max_err %.1f 0..255\n", C, e[1], C, m[1]);
        frame_cost ms_e = c[2].cost;
        printf("env_C%d_cpu_ms %.2f ms\nenv_over_point_C%d_cpu_ratio %.3f x\nthesis_over_env_C%d_cpu_ratio %.3f x\n", C,
               ms_e.cpu_ms, C, ms_e.cpu_ms / ms_s.cpu_ms, C, ms_t.cpu_ms / ms_e.cpu_ms);
        if (ms_e.gpu_ms > 0 && ms_s.gpu_ms > 0)
            printf("env_over_point_C%d_gpu_ratio %.3f x\n", C, ms_e.gpu_ms / ms_s.gpu_ms);
        frame_cost ms_x = c[3].cost;
        printf("fixed_C%d_cpu_ms %.2f ms\nthesis_over_fixed_C%d_cpu_ratio %.3f x\nfixed_over_shader_C%d_cpu_ratio %.3f x\n"
               "fixed_C%d_rmse %.3f 0..255\nfixed_C%d_max_err %.1f 0..255\n",
               C, ms_x.cpu_ms, C, ms_t.cpu_ms / ms_x.cpu_ms, C, ms_x.cpu_ms / ms_s.cpu_ms, C, e[3], C, m[3]);
        if (ms_x.gpu_ms > 0 && ms_t.gpu_ms > 0)
            printf("fixed_C%d_gpu_ms %.3f ms\nthesis_over_fixed_C%d_gpu_ratio %.3f x\n", C, ms_x.gpu_ms, C,
                   ms_t.gpu_ms / ms_x.gpu_ms);
        if (alt)
            printf("alt_C%d_cpu_ms %.2f ms\nthesis_over_alt_C%d_cpu_ratio %.3f x\nalt_over_%s_C%d_cpu_ratio %.3f x\n"
                   "alt_C%d_rmse %.3f 0..255\nalt_C%d_max_err %.1f 0..255\n",
                   C, c[4].cost.cpu_ms, C, ms_t.cpu_ms / c[4].cost.cpu_ms, alt_fixed ? "fixed" : "shader", C,
                   c[4].cost.cpu_ms / (alt_fixed ? ms_x : ms_s).cpu_ms, C, e[4], C, m[4]);
        printf("shader_C%d_fetches %d per_fragment\nthesis_C%d_fetches %d per_fragment\n", C, shader_fetches(C), C,
               thesis_fetches(C));
        printf("fixed_C%d_fetches %d per_fragment\nfixed_C%d_alu %d per_fragment_est\n", C, fixed_fetches(C), C,
               fixed_alu(C));
        printf("shader_C%d_alu %d per_fragment_est\nthesis_C%d_alu %d per_fragment_est\n", C, shader_alu(C), C,
               thesis_alu(C));
        fflush(stdout);
        rows[n_rows++] = (bench_row){C, ms_s.cpu_ms, ms_t.cpu_ms, ms_e.cpu_ms, ms_x.cpu_ms, e[0], m[0], e[1], m[1], e[3], m[3]};
    }
    print_table(rows, n_rows);
    const char *max_c = getenv("BENCH_MAX_C"); /* 0: the level run alone */
    if ((!max_c || atoi(max_c) >= 8) && 8 <= p->n_loaded && run_nn(gl, &s, t, g, fixed, &ref))
        return 1;
    if ((!max_c || atoi(max_c) == 0) && run_levels(gl, p, dir, &s, t))
        return 1;
    if (!max_c && run_fetch(gl, &s, t))
        return 1;
    printf("renderer %s\nplatform %s\n", btf_gl_renderer(gl), btf_gl_platform(gl));
    btf_gl_texture_free(gl, tex);
    f->DeleteProgram(thesis);
    f->DeleteProgram(textured);
    btf_gl_fixed_free(gl, fixed);
    btf_gl_package_free(gl, g);
    btf_shader_program_free(gl, prog);
    btf_gl_target_free(gl, t);
    ref_free(&ref);
    return 0;
}

/* bench_shader                     makes its packages in a temp dir, runs, removes them
 * bench_shader --write-packages D  makes D/knit and D/knit-v2 and exits
 * BENCH_PACKAGES=D bench_shader    runs on packages made before (the GPU folder) */
int main(int argc, char **argv)
{
    char dir[256] = "/tmp/bench-shader-XXXXXX", pkg[300];
    btf_error err = {{0}};
    const char *given = getenv("BENCH_PACKAGES");
#ifndef BENCH_READ_ONLY
    if (argc == 3 && !strcmp(argv[1], "--write-packages"))
        return make_packages(argv[2], &err) == BTF_OK ? 0 : die("packages", &err);
    if (!given && !mkdtemp(dir))
        return die("mkdtemp", NULL);
    if (!given && make_packages(dir, &err) != BTF_OK)
        return die("package", &err);
#else
    (void)argc, (void)argv;
    if (!given)
        return die("BENCH_PACKAGES (a folder with knit and knit-v2) is not set", NULL);
#endif
    snprintf(pkg, sizeof pkg, "%s/knit", given ? given : dir);
    btf_package *p = NULL;
    if (btf_package_read(pkg, 0, &p, &err) != BTF_OK)
        return die("package read", &err);
    btf_gl *gl = NULL;
    btf_gl_desc gd = {.backend = BTF_GL_EGL};
    if (btf_gl_create(&gd, &gl, &err) != BTF_OK)
        return die("EGL", &err);
    int rc = run(gl, p, pkg);
    btf_gl_free(gl);
    btf_package_free(p);
    if (!given) {
        char v2[320];
        snprintf(v2, sizeof v2, "%s-v2", pkg);
        remove_dir(v2);
        remove_dir(pkg);
        rmdir(dir);
    }
    return rc;
}
