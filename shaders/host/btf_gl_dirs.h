/* btf_gl_dirs.h - the light and view direction tables of shaders/btf_dirs.glsl on
 * the GPU (the layout is documented there and in shaders/README.md).
 *
 *     btf_gl_dirs d;
 *     btf_gl_dirs_upload(gl, light_tab, view_tab, view_block, &d, &err);
 *     f->UseProgram(prog->id);
 *     btf_gl_dirs_bind(gl, &d, prog, 4, &err);  // texture units 4, 5; uniform block binding 0
 *     ... draw ...
 *     btf_gl_dirs_free(gl, &d);
 */
#ifndef BTF_GL_DIRS_H
#define BTF_GL_DIRS_H

#include "btf_dirtab.h"
#include "btf_gl.h"
#include "btf_shader.h"

#ifdef __cplusplus
extern "C" {
#endif

#define BTF_GL_MAX_VERTS 1024 /* vertices of both sets together: (n_lights + 2) + (n_views + 2) */

/* GPU names of both tables; filled by btf_gl_dirs_upload, owned by the caller,
 * released by btf_gl_dirs_free with the same btf_gl. */
typedef struct btf_gl_dirs {
    GLuint ubo;     /* btf_dirs_block */
    GLuint cells;   /* u_btf_dir_cells */
    GLuint tris;    /* u_btf_dir_tris */
} btf_gl_dirs;

/* Uploads both tables (views may be NULL: lights only); view_block (n views, may be NULL = all 0) goes into bits 12..
 * of each view vertex's .w. Fails (BTF_ERR_RANGE) beyond BTF_GL_MAX_VERTS vertices. */
btf_result btf_gl_dirs_upload(btf_gl *gl, const btf_dirtab *lights, const btf_dirtab *views, const int *view_block,
                              btf_gl_dirs *out, btf_error *err);
/* Binds the two textures to units first_unit, first_unit + 1 and the block to uniform
 * buffer binding 0, of prog (in use). */
btf_result btf_gl_dirs_bind(btf_gl *gl, const btf_gl_dirs *d, const btf_shader_program *prog, int first_unit,
                            btf_error *err);
void btf_gl_dirs_free(btf_gl *gl, btf_gl_dirs *d);

#ifdef __cplusplus
}
#endif
#endif
