/* btf_scene.h - a glTF model (btf_gltf.h) with its materials bound to packages,
 * drawn in one frame: each bound part with the `render` program of its package,
 * every other part in its base colour with the `flat` program (shaders/btf_flat.frag).
 *
 *     btf_scene_binding b[2] = {{"Seat", "lib/wool", 4.0f}, {"*", "lib/impalla", 1.0f}};
 *     btf_render_params rp = btf_render_defaults(BTF_RENDER_PLANE);
 *     btf_scene_frame(model, &rp);                      // the camera frames the model
 *     btf_scene_png(model, b, 2, &rp, BTF_GL_DEFAULT, "sofa.png", &err);
 *
 * Binding: a part takes the binding that names its material exactly, else the
 * binding "*" when there is one, else none (base colour). A binding that names no
 * material of the model, or a bound part without TEXCOORD_0, is an error naming
 * it. Texture coordinates: the part's TEXCOORD_0 times the binding's repeat, the
 * package tiling (wrap) across them.
 */
#ifndef BTF_SCENE_H
#define BTF_SCENE_H

#include "btf_gltf.h"
#include "btf_render.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_SCENE_MAX_BINDINGS 64
#define BTF_SCENE_FLAT_AMBIENT 0.25f /* u_flat_ambient: share of full light an unlit side keeps */

/* A material bound to a package; plain value, strings the caller's. */
typedef struct btf_scene_binding {
    const char *material; /* glTF material name, or "*" for every part no other binding names */
    const char *dir;      /* package directory (every chunk present is used) */
    float repeat;         /* package repeats per unit of TEXCOORD_0; 0 = 1 */
} btf_scene_binding;

/* The model's bounds framed: target = their centre, extent = the radius of their
 * bounding sphere, camera_dist so that sphere fills the field of view across the
 * narrower side with a 5% margin. Camera and light angles stay as they are. */
void btf_scene_frame(const btf_gltf *m, btf_render_params *p);

/* Which binding (index) each part takes, or -1: into part_bind (m->n_parts). */
btf_result btf_scene_bind(const btf_gltf *m, const btf_scene_binding *b, int n, int *part_bind, btf_error *err);

/* The model and its packages on the GPU, ready to draw many frames. Made with a
 * current btf_gl by btf_scene_create, freed by btf_scene_free with the same btf_gl
 * (before that btf_gl is freed). The model must outlive it. */
typedef struct btf_scene btf_scene;

btf_result btf_scene_create(btf_gl *gl, const btf_gltf *m, const btf_scene_binding *b, int n, btf_scene **out,
                            btf_error *err);
void btf_scene_free(btf_scene *s);
/* Clears t to the background, draws every part, waits for the GPU. */
btf_result btf_scene_draw(btf_scene *s, const btf_render_params *p, btf_gl_target *t, btf_error *err);

/* All in one: reads the packages, renders with the backend into an
 * RGBA8 target and writes an RGB PNG. */
btf_result btf_scene_png(const btf_gltf *m, const btf_scene_binding *b, int n, const btf_render_params *p,
                         btf_gl_backend backend, const char *out_path, btf_error *err);

#ifdef __cplusplus
}
#endif
#endif
