/* btf_render.h - scene setup of `btf render`: meshes (plane, sphere, cylinder),
 * camera and light from angles, and drawing a package with the shared `render`
 * program of shaders/ (btf_render.vert/.frag) in a headless btf_gl context.
 *
 *     btf_render_params rp = btf_render_defaults(BTF_RENDER_SPHERE);
 *     rp.camera_theta = 60; rp.light_phi = 30;
 *     btf_renderer *r;
 *     btf_renderer_create(gl, pkg, "lib/wool", 0, &r, &err);   // uploads the package
 *     btf_gl_target *t; btf_gl_target_create(gl, rp.width, rp.height, BTF_GL_RGBA8, 1, &t, &err);
 *     btf_renderer_draw(r, &rp, t, &err);                       // clear, draw, finish
 *     ...
 *     btf_render_png("lib/wool", &rp, BTF_GL_DEFAULT, "wool.png", &err);  // all in one
 *
 * Conventions (shaders/README.md, "Scene conventions", is the spec the browser
 * client follows; tests/gl/test_render.c checks them with an independent ray cast):
 * - World: right-handed, +z up. Angles in degrees. A direction (theta, phi) is
 *   (sin t cos p, sin t sin p, cos t): theta from +z, phi from +x towards +y.
 * - Objects (model matrix = identity, uv in 0..1 scaled by u_uv_scale):
 *   plane    square [-1,1]^2 at z = 0, normal +z, uv = ((x+1)/2, (1-y)/2);
 *            its local BTF frame equals the world frame (x = u, y = towards row 0)
 *   sphere   radius 1, u = (longitude - 90)/360 mod 1 (longitude from +x towards
 *            +y: the seam faces +y, away from the default camera), v = colatitude/180
 *   cylinder axis along x, length 2 (x in [-1,1]), radius 2/pi (circumference 4),
 *            u = (x+1)/2, v = 0.5 + angle/360, angle from the top line (z max)
 *            towards -y (seam along the bottom line)
 *   default repeats: plane 1 x 1, sphere 2 x 1, cylinder 1 x 2 (square texels)
 *   times `repeat`.
 * - Camera at target + dist * dir(camera_theta, camera_phi), looking at target, up =
 *   -d(dir)/d(theta) = (-cos t cos p, -cos t sin p, sin t) (defined at theta 0 too),
 *   field of view fov_deg across the narrower side (vertical when width >= height;
 *   taller than wide: horizontal, tan(fovy/2) = tan(fov/2) / aspect), aspect =
 *   width/height, near 0.05*dist, far dist + 2*extent (extent 0: 2).
 * - Light: distant, towards dir(light_theta, light_phi) (u_light.w = 0), unless
 *   no_point_light; an environment (env) lights too when given. On the plane the
 *   light's local direction is the same at every pixel: btf_renderer_draw blends it
 *   once per draw (btf_gl_fixed.h, BTF_FIXED_LIGHT); btf_renderer_use (any mesh) does not.
 * Output: with the point light alone, exposure 1 and no tone mapping, the BTF's own
 * values (byte/255 scale), clamped to 0..1; else doc/lighting.md section 4.
 *
 * Limitations: one material per draw; convex objects only (depth-tested, no
 * shadows between objects); the whole loaded package is uploaded.
 */
#ifndef BTF_RENDER_H
#define BTF_RENDER_H

#include "btf_gl.h"
#include "btf_env.h"
#include "btf_gl_package.h"
#include "btf_package.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_render_geometry {
    BTF_RENDER_PLANE = 0,
    BTF_RENDER_SPHERE = 1,
    BTF_RENDER_CYLINDER = 2,
    BTF_RENDER_GEOMETRY_COUNT
} btf_render_geometry;

/* "plane" / "sphere" / "cylinder"; "?" if unknown. */
const char *btf_render_geometry_name(btf_render_geometry g);
/* -1 if the name is unknown. */
int btf_render_geometry_from_name(const char *name);

/* What to draw and from where; plain value. Start from btf_render_defaults(). */
typedef struct btf_render_params {
    int width, height;              /* pixels, 1..8192 */
    btf_render_geometry geometry;
    float camera_theta, camera_phi; /* degrees: camera direction from the origin */
    float camera_dist;              /* world units from the origin, > 0 */
    float light_theta, light_phi;   /* degrees: direction towards a distant light */
    float fov_deg;                  /* field of view across the narrower side, 1..170 */
    float background[3];            /* 0..1, written as is */
    float repeat;                   /* material repeats, times the geometry's default; > 0 */
    int filter;                     /* 0 nearest texel, 1 bilinear (default) */
    int n_chunks;                   /* first n uploaded chunks; 0 = all */
    int horizon_fade;               /* 1 (default): light beyond the outermost measured
                                       ring fades linearly in cos(theta) to 0 at the horizon */
    float target[3];                /* the point the camera looks at (0 = the origin) */
    float extent;                   /* radius around target of what is drawn (the far plane);
                                       0 = 2, the built-in geometries' */
    int no_point_light;             /* 1: the distant light is off (doc/lighting.md) */
    const btf_env *env;             /* environment light (btf_env.h; NULL none), not owned */
    float env_rotation;             /* degrees about +z */
    float exposure;                 /* linear scale before tone mapping, 0..1e6 (default 1) */
    int tone_mapping;               /* btf_render_tone */
} btf_render_params;

/* Tone mappings (doc/lighting.md 4); auto: neutral under an environment, else none. */
typedef enum btf_render_tone {
    BTF_TONE_AUTO = 0,
    BTF_TONE_NONE = 1,
    BTF_TONE_NEUTRAL = 2,
    BTF_TONE_ACES = 3,
    BTF_TONE_COUNT
} btf_render_tone;

/* "auto" / "none" / "neutral" / "aces"; -1 if unknown. */
int btf_render_tone_from_name(const char *name);

/* Defaults for a geometry: 320 x 240, a camera that frames the object in any aspect,
 * a light 28 to 35 degrees off the camera (plane (30, -90, 3.5), sphere (60, -90, 3.6),
 * cylinder (50, -90, 3.6); light (45, -50)). */
btf_render_params btf_render_defaults(btf_render_geometry g);
/* BTF_ERR_RANGE / BTF_ERR_ARG naming the first bad field. */
btf_result btf_render_check_params(const btf_render_params *p, btf_error *err);

/* Matrices (column-major float[16], as glUniformMatrix4fv wants) and uniforms of
 * one view; plain value filled by btf_render_camera_make. */
typedef struct btf_render_camera {
    float model[16], view[16], proj[16], view_proj[16];
    float eye[3];      /* world position of the camera */
    float forward[3], right[3], up[3]; /* unit camera axes in world */
    float light[3];    /* unit direction towards the light, world */
    float uv_scale[2]; /* u_uv_scale */
    int wrap;          /* u_btf_wrap: 1 for sphere and cylinder (seam) or repeat != 1 */
} btf_render_camera;

void btf_render_camera_make(const btf_render_params *p, btf_render_camera *out);
/* c = a * b for column-major 4x4 matrices (c may not alias a or b). */
void btf_render_mat4_mul(const double a[16], const double b[16], double c[16]);
/* Pixels per world unit at the origin's distance (the object's scale on screen):
 * min(width, height) / (2 dist tan(fov/2)). The client's pixelsPerUnit (client/scene.js). */
double btf_render_pixels_per_unit(const btf_render_params *p);

/* Triangle mesh, interleaved per vertex: position 3, normal 3, tangent 4 (w = +1),
 * uv 2 (attribute locations 0..3 of btf_render.vert). Owned by the caller,
 * btf_render_mesh_free. */
typedef struct btf_render_mesh {
    float *vertices; /* n_vertices * BTF_RENDER_VERTEX_FLOATS (malloc'd) */
    int n_vertices;
    unsigned *indices; /* n_indices (malloc'd), triangles */
    int n_indices;
} btf_render_mesh;

#define BTF_RENDER_VERTEX_FLOATS 12

/* segments: subdivisions around (sphere, cylinder) or per side (plane); 0 = default 64. */
btf_result btf_render_mesh_create(btf_render_geometry g, int segments, btf_render_mesh **out, btf_error *err);
void btf_render_mesh_free(btf_render_mesh *m);
/* Uploads m into the bound vertex array: vertices into vbo, indices into ibo, the
 * four attributes (position, normal, tangent, uv) at locations 0..3. */
void btf_render_mesh_upload(const btf_gl_api *f, const btf_render_mesh *m, GLuint vbo, GLuint ibo);

/* A package on the GPU plus the compiled `render` program and mesh buffers, ready
 * to draw many frames. Made by btf_renderer_create with a current btf_gl, freed by
 * btf_renderer_free with the same btf_gl (before that btf_gl is freed). */
typedef struct btf_renderer btf_renderer;

/* debug = 1 builds the program with BTF_RENDER_DEBUG (colour attachments 1..3 get
 * uv, local light, local view; draw into a target with 4 attachments). dir is the
 * package directory (its texture files are uploaded as a browser receives them). */
btf_result btf_renderer_create(btf_gl *gl, const btf_package *p, const char *dir, int debug, btf_renderer **out,
                               btf_error *err);
void btf_renderer_free(btf_renderer *r);
/* The package on the GPU that r draws (owned by r). */
const btf_gl_package *btf_renderer_package(const btf_renderer *r);
/* Sets the light uniforms of shaders/btf_light.glsl on prog (in use) for p: point
 * light on/off, environment quadratic (q: from btf_env_quadratic, NULL when p->env is
 * NULL), exposure, tone mapping. */
void btf_render_light_uniforms(btf_gl *gl, GLuint prog, const btf_render_params *p, const btf_env_quad *q);
/* Clears t to the background (depth too), draws the scene, waits for the GPU. */
btf_result btf_renderer_draw(btf_renderer *r, const btf_render_params *p, btf_gl_target *t, btf_error *err);

/* A frame in t for p: a depth buffer, colour cleared to p's background (debug
 * attachments to 0), depth test on. *depth goes to btf_render_frame_end, which
 * detaches and frees it. */
btf_result btf_render_frame_begin(btf_gl *gl, const btf_render_params *p, btf_gl_target *t, GLuint *depth,
                                  btf_error *err);
void btf_render_frame_end(btf_gl *gl, GLuint depth);
/* Makes r's program current with its package bound and the uniforms of p and c:
 * any mesh in a bound vertex array (btf_render_mesh_upload) then draws with it. */
btf_result btf_renderer_use(btf_renderer *r, const btf_render_params *p, const btf_render_camera *c, btf_error *err);

/* Reads colour attachment 0 of an RGBA8 target into rgb (width*height*3 bytes),
 * top row first (image order). */
btf_result btf_render_read_rgb8(btf_gl *gl, const btf_gl_target *t, uint8_t *rgb, btf_error *err);

/* Draws one frame into t (an RGBA8 target of the parameters' size) with gl current. */
typedef btf_result (*btf_render_draw_fn)(void *ctx, btf_gl *gl, btf_gl_target *t, btf_error *err);
/* All in one around draw: a context of the backend, an RGBA8 target of p's size,
 * draw(ctx, ...), the pixels written as an RGB PNG (or any format btf_image_write
 * knows) to out_path. */
btf_result btf_render_to_png(const btf_render_params *p, btf_gl_backend backend, btf_render_draw_fn draw, void *ctx,
                             const char *out_path, btf_error *err);

/* All in one: reads the package in dir (the first n_chunks present when
 * p->n_chunks > 0, else every chunk present), renders with the backend into an
 * RGBA8 target and writes an RGB PNG (or any format btf_image_write knows). */
btf_result btf_render_png(const char *dir, const btf_render_params *p, btf_gl_backend backend, const char *out_path,
                          btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
