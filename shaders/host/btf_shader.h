/* btf_shader.h - assembles the GLSL ES 3.00 programs of shaders/ exactly as the
 * browser client does, compiles and links them in a btf_gl context, and reports
 * errors against the line-numbered assembled source.
 *
 * Usage:
 *     btf_shader_define defs[] = {{"BTF_COMPONENTS", "8"}};
 *     btf_shader_desc d = {.program = "solid", .defines = defs, .n_defines = 1};
 *     btf_shader_program *p = NULL;
 *     char *report = NULL;
 *     if (btf_shader_build(gl, &d, &p, &report, &err) != BTF_OK)
 *         fprintf(stderr, "%s\n%s", err.msg, report ? report : "");
 *     free(report);
 *     btf_gl_fn(gl)->UseProgram(p->id);
 *     ...
 *     btf_shader_program_free(gl, p);
 *
 * The one place that says which files make a program is shaders/manifest.json:
 *     {"prefix": ["#version 300 es", "precision highp float;", ...],
 *      "programs": {"NAME": {"vertex": ["a.vert"], "fragment": ["x.glsl", "b.frag"]}}}
 * A stage's source is, in this order (shaders/README.md is the spec both hosts follow):
 *   1. every prefix line, each ending in "\n";
 *   2. "#define NAME VALUE\n" for each define, in the caller's order;
 *   3. per file of the stage's list: "// ---- FILE\n", then the file's text, with a
 *      "\n" appended when it does not end in one.
 * Shader files hold bodies only (no #version). File names are plain names inside the
 * shaders directory (letters, digits, '_', '-', '.'; no paths).
 *
 * Limitations: at most BTF_SHADER_MAX_PIECES files per stage, 1 MiB per file.
 * Not done here: caching of compiled programs, includes inside shader files.
 */
#ifndef BTF_SHADER_H
#define BTF_SHADER_H

#include "btf_gl.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum btf_shader_stage { BTF_SHADER_VERTEX = 0, BTF_SHADER_FRAGMENT = 1 } btf_shader_stage;

/* One preprocessor define; strings owned by the caller. */
typedef struct btf_shader_define {
    const char *name;  /* [A-Za-z_][A-Za-z0-9_]* */
    const char *value; /* one line; NULL or "" defines the name empty */
} btf_shader_define;

/* What to assemble; zero means default. Caller-owned, read during the call. */
typedef struct btf_shader_desc {
    const char *dir;     /* shaders directory; NULL: $BTF_SHADERS, else $BTF_ROOT/shaders, else ./shaders */
    const char *program; /* program name in manifest.json */
    const btf_shader_define *defines;
    int n_defines;
} btf_shader_desc;

#define BTF_SHADER_MAX_PIECES 16

/* Where one file landed in the assembled text; value type inside btf_shader_source. */
typedef struct btf_shader_piece {
    char file[64];  /* file name as listed in the manifest */
    int first_line; /* 1-based line of the file's first line in the assembled text */
    int n_lines;
} btf_shader_piece;

/* One assembled stage. Made by btf_shader_assemble, freed by btf_shader_source_free. */
typedef struct btf_shader_source {
    btf_shader_stage stage;
    char *text; /* malloc'd, NUL-terminated: exactly what is passed to glShaderSource */
    int n_lines;
    int n_pieces;
    btf_shader_piece pieces[BTF_SHADER_MAX_PIECES];
} btf_shader_source;

/* Reads manifest.json and the stage's files and assembles them (no GL needed). */
btf_result btf_shader_assemble(const btf_shader_desc *desc, btf_shader_stage stage, btf_shader_source **out,
                               btf_error *err);
void btf_shader_source_free(btf_shader_source *s);

/* Maps an assembled line to its file and 1-based line there; *file = NULL (and the
 * assembled line returned) for prefix/define/marker lines. */
int btf_shader_source_line(const btf_shader_source *s, int line, const char **file);

/* Compiler log line numbers: "0:LINE(COL): ..." (Mesa), "ERROR: 0:LINE: ..." (ANGLE,
 * WebGL), "0(LINE) : ..." (NVIDIA). Returns LINE or 0 when the log line names none. */
int btf_shader_log_line(const char *log_line);

/* Numbered listing of s with each log message printed under the line it names,
 * messages naming no line first (malloc'd; NULL only when out of memory). */
char *btf_shader_annotate(const btf_shader_source *s, const char *log);

/* A linked program. Made by btf_shader_build, freed by btf_shader_program_free with
 * the same btf_gl (before that btf_gl is freed). */
typedef struct btf_shader_program {
    GLuint id;
    char name[64];
} btf_shader_program;

/* Assembles both stages, compiles, links. On a compile or link failure returns
 * BTF_ERR_FORMAT, err names the program, stage, first message and its file:line, and
 * *report (when report is non-NULL) gets the annotated listing (malloc'd, caller frees). */
btf_result btf_shader_build(btf_gl *gl, const btf_shader_desc *desc, btf_shader_program **out, char **report,
                            btf_error *err);
void btf_shader_program_free(btf_gl *gl, btf_shader_program *p);

#ifdef __cplusplus
}
#endif
#endif
