/* cmd_render.c - `btf render PACKAGE OUT.png`: a package (possibly partial) on a
 * plane, sphere or cylinder, or on a glTF model with other packages bound to its
 * materials, headless (EGL or OSMesa), through the shared shaders.
 *
 *     btf render lib/wool wool.png --geometry cylinder --size 640x480
 *     btf render lib/knit knit-2.png --chunks 2 --camera 60,-90,3.5 --light 30,0
 *     btf render lib/wool sofa.png --model sofa.glb --bind Frame=lib/impalla,2
 *
 * Scene conventions (camera and light angles, objects, uv): shaders/host/btf_render.h and
 * shaders/README.md ("Scene conventions").
 */
#include "btf_args.h"
#include "btf_cli.h"
#include "btf_render.h"
#include "btf_scene.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Parsed command line; stack value of cmd_render, strings point into argv. */
typedef struct render_opts {
    const char *pkg, *out;
    btf_render_params p;
    btf_gl_backend backend;
    const char *model;  /* --model: a glTF file, PACKAGE bound to every part no --bind names */
    int dist_given;     /* --camera gave a distance (else a model is framed) */
    int n_bind;         /* --bind NAME=DIR[,REPEAT], into bind[1..]; bind[0] is PACKAGE's "*" */
    btf_scene_binding bind[BTF_SCENE_MAX_BINDINGS];
    char bind_text[BTF_SCENE_MAX_BINDINGS][512];
    const char *environment; /* --environment FILE|studio (loaded by render_main) */
    int verbose;             /* -v: print the GL platform and renderer first */
} render_opts;

static void render_usage(FILE *f)
{
    fprintf(f, "usage: btf render PACKAGE OUT.png [--chunks N] [--geometry plane|sphere|cylinder]\n"
               "                  [--size W[xH]] [--camera THETA,PHI[,DIST]] [--light THETA,PHI]\n"
               "                  [--fov DEG] [--repeat R] [--filter nearest|bilinear]\n"
               "                  [--no-horizon-fade] [--backend egl|osmesa] [--background R,G,B]\n"
               "                  [--model FILE.glb|FILE.gltf [--bind MATERIAL=DIR[,REPEAT]]...]\n"
               "                  [--environment FILE.hdr|studio [--environment-rotation DEG]]\n"
               "                  [--no-light] [--exposure E] [--tone-mapping auto|none|neutral|aces] [-v]\n"
               "\n"
               "Renders the package directory PACKAGE (its first N chunks; default: every chunk\n"
               "present) headless with the shaders the browser runs, and writes OUT (PNG).\n"
               "World: +z up; a direction (THETA, PHI) in degrees is theta from +z, phi from +x\n"
               "towards +y. The object sits at the origin: plane = [-1,1]^2 at z = 0 (image row 0\n"
               "towards +y), sphere of radius 1, cylinder along x (length 2, circumference 4).\n"
               "  --chunks N           use the first N chunks (default and at most: all present)\n"
               "  --geometry G         plane (default), sphere or cylinder\n"
               "  --size WxH           image size in pixels (default 320x240; W alone: square)\n"
               "  --camera T,P[,D]     camera direction and distance (default per geometry,\n"
               "                       plane 30,-90,3.5; the camera looks at the origin, up = +z tilted)\n"
               "  --light T,P          direction towards a distant light (default 45,-50)\n"
               "  --fov DEG            field of view across the narrower side (default 40)\n"
               "  --repeat R           material repeats across the object (default 1)\n"
               "  --filter F           texel filter (default bilinear)\n"
               "  --no-horizon-fade    keep the decoder's value for lights below the measured range\n"
               "  --backend B          egl or osmesa (default $BTF_GL_BACKEND, else egl, else osmesa)\n"
               "  --background R,G,B   0..1 each (default 0.12,0.12,0.12)\n"
               "  --model FILE         a glTF 2.0 model (.glb, or .gltf with its buffers) instead of\n"
               "                       the geometry: PACKAGE on every part no --bind names (R\n"
               "                       repeats per unit of its TEXCOORD_0; PACKAGE - for none:\n"
               "                       those parts in their glTF base colour), the camera framing\n"
               "                       the model (+y up in the file is +z here; --camera T,P,D\n"
               "                       sets the distance)\n"
               "  --bind M=DIR[,R]     with --model: the package DIR on the parts of material M\n"
               "                       (R repeats per uv unit, default 1); repeatable\n"
               "  --environment FILE   environment light: an equirectangular HDR image (Radiance\n"
               "                       .hdr, OpenEXR; row 0 up) or studio, the built-in one\n"
               "                       (doc/lighting.md); the point light stays unless --no-light\n"
               "  --environment-rotation DEG  turns the environment about +z (default 0)\n"
               "  --no-light           no point light (needs --environment)\n"
               "  --exposure E         linear scale of the light before tone mapping (default 1)\n"
               "  --tone-mapping T     auto (default: neutral with an environment, else none),\n"
               "                       none, neutral (Khronos PBR Neutral) or aces\n"
               "  -v, --verbose        print the GL platform (EGL surfaceless Mesa, EGL device N,\n"
               "                       OSMesa) and renderer on stderr first\n");
    btf_args_exit_codes(f);
}

/* Parses n_min..n comma-separated finite floats, the whole string. */
static int render_floats(const char *s, float *v, int n_min, int n)
{
    const char *c = s;
    for (int k = 0; k < n; k++) {
        char *end;
        errno = 0;
        double x = strtod(c, &end);
        if (errno || end == c || !isfinite(x))
            return 0;
        v[k] = (float)x;
        if (*end == '\0')
            return k + 1 >= n_min;
        if (*end != ',')
            return 0;
        c = end + 1;
    }
    return 0; /* more than n values */
}

static int render_size(const char *s, int *w, int *h)
{
    char *end;
    errno = 0;
    long a = strtol(s, &end, 10), b = a;
    if (errno || end == s)
        return 0;
    if (*end == 'x') {
        const char *c = end + 1;
        b = strtol(c, &end, 10);
        if (errno || end == c)
            return 0;
    }
    if (*end || a < 1 || a > 8192 || b < 1 || b > 8192)
        return 0;
    *w = (int)a;
    *h = (int)b;
    return 1;
}

/* --bind NAME=DIR[,REPEAT] into the next binding; 0 ok, 2 usage error. */
static int render_bind(const btf_args *a, const char *val, render_opts *o)
{
    if (o->n_bind + 1 >= BTF_SCENE_MAX_BINDINGS)
        return btf_args_bad(a, val, "at most %d bindings", BTF_SCENE_MAX_BINDINGS - 1);
    char *t = o->bind_text[o->n_bind + 1];
    snprintf(t, sizeof o->bind_text[0], "%s", val);
    char *eq = strchr(t, '='), *comma = eq ? strrchr(eq, ',') : NULL;
    btf_scene_binding *b = &o->bind[o->n_bind + 1];
    b->repeat = 1.0f;
    if (comma && !render_floats(comma + 1, &b->repeat, 1, 1))
        comma = NULL; /* a comma in the folder name, no repeat */
    else if (comma)
        *comma = '\0';
    if (!eq || eq == t || !eq[1] || strlen(val) >= sizeof o->bind_text[0])
        return btf_args_bad(a, val, "MATERIAL=DIR[,REPEAT]");
    *eq = '\0';
    b->material = t, b->dir = eq + 1;
    o->n_bind++;
    return 0;
}

/* One option with its value of the second pass (btf_args_fn); 0 ok, 2 usage error. */
static int render_option(void *ctx, const btf_args *a, int c, const char *val)
{
    render_opts *o = ctx;
    btf_render_params *p = &o->p;
    float v[3] = {0, 0, p->camera_dist};
    btf_error e = {{0}};
    int ok = 1;
    const char *want = "";
    switch (c) {
    case BTF_ARG_POS: *(a->npos ? &o->out : &o->pkg) = val; break;
    case 'n': return btf_args_int(a, val, 1, 1024, &p->n_chunks);
    case 's': ok = render_size(val, &p->width, &p->height), want = "W or WxH, 1..8192 each"; break;
    case 'c':
        ok = render_floats(val, v, 2, 3), want = "THETA,PHI[,DIST]";
        p->camera_theta = v[0], p->camera_phi = v[1], p->camera_dist = v[2];
        o->dist_given = ok && strchr(strchr(val, ',') + 1, ',') != NULL;
        break;
    case 'm': o->model = val; break;
    case 'M': return render_bind(a, val, o);
    case 'l':
        ok = render_floats(val, v, 2, 2), want = "THETA,PHI";
        p->light_theta = v[0], p->light_phi = v[1];
        break;
    case 'F': ok = render_floats(val, &p->fov_deg, 1, 1), want = "degrees"; break;
    case 'r': ok = render_floats(val, &p->repeat, 1, 1), want = "a number"; break;
    case 'B': ok = render_floats(val, p->background, 3, 3), want = "R,G,B"; break;
    case 'f':
        ok = !strcmp(val, "nearest") || !strcmp(val, "bilinear");
        p->filter = !strcmp(val, "bilinear"), want = "nearest|bilinear";
        break;
    case 'b':
        ok = btf_gl_backend_parse(val, &o->backend, &e) == BTF_OK && o->backend != BTF_GL_DEFAULT;
        want = "egl|osmesa";
        break;
    case 'H': p->horizon_fade = 0; break;
    case 'e': o->environment = val; break;
    case 'R': ok = render_floats(val, &p->env_rotation, 1, 1), want = "degrees"; break;
    case 'x': ok = render_floats(val, &p->exposure, 1, 1) && p->exposure >= 0.0f, want = "a number >= 0"; break;
    case 't':
        p->tone_mapping = btf_render_tone_from_name(val);
        ok = p->tone_mapping >= 0, want = "auto|none|neutral|aces";
        break;
    case 'L': p->no_point_light = 1; break;
    case 'v': o->verbose = 1; break;
    }
    return ok ? 0 : btf_args_bad(a, val, "%s", want);
}

/* --geometry (and --model, which takes the sphere's view), the first pass
 * (btf_args_fn): it sets the defaults the others change. */
static int render_geometry(void *ctx, const btf_args *a, int c, const char *val)
{
    btf_render_geometry *g = ctx;
    if (c == 'm')
        *g = BTF_RENDER_SPHERE;
    if (c != 'g')
        return 0;
    int k = btf_render_geometry_from_name(val);
    if (k < 0)
        return btf_args_bad(a, val, "plane, sphere or cylinder");
    *g = (btf_render_geometry)k;
    return 0;
}

/* 0 ok, 2 usage error, -1 help printed. --geometry is applied first (it sets the
 * defaults the other options then change). */
static int render_parse(int argc, char **argv, render_opts *o)
{
    static const btf_args_spec spec = {"render",
                                       "chunks:n geometry:g size:s camera:c light:l "
                                       "fov:F repeat:r filter:f backend:b background:B no-horizon-fade!H "
                                       "model:m bind:M environment:e environment-rotation:R exposure:x "
                                       "tone-mapping:t no-light!L verbose!v v!v",
                                       render_usage, 2};
    memset(o, 0, sizeof *o);
    btf_render_geometry g = BTF_RENDER_PLANE;
    int rc = btf_args_parse(&spec, argc, argv, render_geometry, &g);
    if (rc)
        return rc;
    o->p = btf_render_defaults(g);
    rc = btf_args_parse(&spec, argc, argv, render_option, o);
    if (rc)
        return rc;
    btf_error err = {{0}};
    if (o->p.no_point_light && !o->environment) {
        fprintf(stderr, "btf render: --no-light needs --environment\n");
        return 2;
    }
    btf_render_params checked = o->p;
    checked.no_point_light = 0; /* the environment is loaded later */
    if (btf_render_check_params(&checked, &err) != BTF_OK) {
        fprintf(stderr, "btf render: %s\n", err.msg);
        return 2;
    }
    if (o->n_bind > 0 && !o->model) {
        fprintf(stderr, "btf render: --bind needs --model\n");
        return 2;
    }
    if (strcmp(o->pkg, "-") == 0 && !o->model) {
        fprintf(stderr, "btf render: PACKAGE \"-\" (no package) needs --model\n");
        return 2;
    }
    o->bind[0] = (btf_scene_binding){"*", o->pkg, o->p.repeat};
    return 0;
}

/* The model drawn with its bindings: framed unless --camera gave a distance. */
static btf_result render_model(render_opts *o, btf_error *err)
{
    btf_gltf *m = NULL;
    btf_result r = btf_gltf_load(o->model, &m, err);
    if (r != BTF_OK)
        return r;
    btf_render_params p = o->p;
    float dist = p.camera_dist;
    btf_scene_frame(m, &p);
    if (o->dist_given)
        p.camera_dist = dist;
    int none = strcmp(o->pkg, "-") == 0; /* only the --bind packages */
    r = btf_scene_png(m, o->bind + none, o->n_bind + 1 - none, &p, o->backend, o->out, err);
    btf_gltf_free(m);
    return r;
}

/* When neither $BTF_SHADERS nor $BTF_ROOT is set and ./shaders has no manifest,
 * points $BTF_SHADERS at the source tree next to the binary (BUILD/btf ->
 * BUILD/../shaders), so `btf render` works from any directory. */
static void render_find_shaders(void)
{
    struct stat st;
    if (getenv("BTF_SHADERS") || getenv("BTF_ROOT") || stat("shaders/manifest.json", &st) == 0)
        return;
    char exe[4096], dir[4200];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return;
    exe[n] = '\0';
    char *slash = strrchr(exe, '/');
    if (!slash)
        return;
    *slash = '\0';
    snprintf(dir, sizeof dir, "%s/../shaders/manifest.json", exe);
    if (stat(dir, &st) == 0) {
        snprintf(dir, sizeof dir, "%s/../shaders", exe);
        setenv("BTF_SHADERS", dir, 0);
    }
}

/* The command once its options are parsed; the exit code. */
static int render_main(void *opts)
{
    render_opts *o = opts;
    render_find_shaders();
    btf_error err = {{0}};
    if (o->verbose) { /* a context of its own, only to say which one a render gets */
        btf_gl_desc gd = {.backend = o->backend};
        btf_gl *gl = NULL;
        if (btf_gl_create(&gd, &gl, &err) == BTF_OK)
            fprintf(stderr, "btf render: %s, %s, renderer %s\n", btf_gl_backend_name(btf_gl_backend_of(gl)),
                    btf_gl_platform(gl), btf_gl_renderer(gl));
        btf_gl_free(gl);
    }
    btf_env *env = NULL;
    btf_result r = o->environment ? btf_env_load(o->environment, &env, &err) : BTF_OK;
    o->p.env = env;
    if (r == BTF_OK)
        r = o->model ? render_model(o, &err) : btf_render_png(o->pkg, &o->p, o->backend, o->out, &err);
    btf_env_free(env);
    if (r != BTF_OK) {
        fprintf(stderr, "btf render: %s\n", err.msg);
        return 1;
    }
    return 0;
}

int cmd_render(int argc, char **argv)
{
    render_opts o;
    return btf_args_finish(render_parse(argc, argv, &o), render_main, &o);
}
