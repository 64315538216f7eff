/* btf_shader.c - shader assembly from shaders/manifest.json, compile/link through
 * btf_gl, error reports against the numbered assembled source (see btf_shader.h). */
#include "btf_shader.h"
#include "btf_fs.h"
#include "btf_common.h"

#include <cjson/cJSON.h>
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define BTF__SHADER_MAX_FILE (1u << 20)

/* ---------------------------------------------------------------- growable text */

/* A malloc'd string being built; owned by the function building it. */
typedef struct btf__str {
    char *p;
    size_t len, cap;
    int oom;
} btf__str;

static void btf__str_add(btf__str *s, const char *t, size_t n)
{
    if (s->oom)
        return;
    if (s->len + n + 1 > s->cap) {
        size_t cap = s->cap ? s->cap : 256;
        while (cap < s->len + n + 1)
            cap *= 2;
        char *p = realloc(s->p, cap);
        if (!p) {
            s->oom = 1;
            return;
        }
        s->p = p;
        s->cap = cap;
    }
    memcpy(s->p + s->len, t, n);
    s->len += n;
    s->p[s->len] = '\0';
}

static void btf__str_cat(btf__str *s, const char *t) { btf__str_add(s, t, strlen(t)); }

static int btf__count_lines(const char *t, size_t n)
{
    int lines = 0;
    for (size_t i = 0; i < n; i++)
        lines += t[i] == '\n';
    return lines;
}

/* ---------------------------------------------------------------- files */

static void btf__shader_dir(const btf_shader_desc *d, char *buf, size_t n)
{
    const char *env = getenv("BTF_SHADERS"), *root = getenv("BTF_ROOT");
    if (d->dir)
        snprintf(buf, n, "%s", d->dir);
    else if (env && *env)
        snprintf(buf, n, "%s", env);
    else if (root && *root)
        snprintf(buf, n, "%s/shaders", root);
    else
        snprintf(buf, n, "shaders");
}

/* Whole file into a malloc'd NUL-terminated buffer, at most BTF__SHADER_MAX_FILE bytes. */
static btf_result btf__read_file(const char *path, char **out, size_t *len, btf_error *err)
{
    btf_result r = btf_fs_read(path, BTF__SHADER_MAX_FILE, out, len, err);
    if (r == BTF_OK && strlen(*out) != *len) {
        free(*out);
        *out = NULL;
        return btf_fail(err, BTF_ERR_FORMAT, "shader: %s contains a NUL byte", path);
    }
    return r;
}

static int btf__plain_name(const char *s)
{
    if (!s || !*s || strlen(s) >= sizeof(((btf_shader_piece *)0)->file) || s[0] == '.')
        return 0;
    for (const char *c = s; *c; c++)
        if (!isalnum((unsigned char)*c) && *c != '_' && *c != '-' && *c != '.')
            return 0;
    return 1;
}

static int btf__ident(const char *s)
{
    if (!s || !(isalpha((unsigned char)*s) || *s == '_'))
        return 0;
    for (const char *c = s; *c; c++)
        if (!isalnum((unsigned char)*c) && *c != '_')
            return 0;
    return 1;
}

/* ---------------------------------------------------------------- assembly */

static btf_result btf__load_manifest(const char *dir, cJSON **out, btf_error *err)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    char *text = NULL;
    size_t len = 0;
    btf_result r = btf__read_file(path, &text, &len, err);
    if (r != BTF_OK)
        return r;
    *out = cJSON_ParseWithLength(text, len);
    free(text);
    if (!*out || !cJSON_IsObject(*out)) {
        cJSON_Delete(*out);
        *out = NULL;
        return btf_fail(err, BTF_ERR_FORMAT, "shader: %s is not a JSON object", path);
    }
    return BTF_OK;
}

static btf_result btf__add_prefix(const cJSON *manifest, const btf_shader_desc *d, btf__str *s, btf_error *err)
{
    const cJSON *prefix = cJSON_GetObjectItemCaseSensitive(manifest, "prefix");
    if (!cJSON_IsArray(prefix) || cJSON_GetArraySize(prefix) < 1)
        return btf_fail(err, BTF_ERR_FORMAT, "shader: manifest.json has no \"prefix\" array");
    const cJSON *line;
    cJSON_ArrayForEach(line, prefix)
    {
        if (!cJSON_IsString(line) || strchr(line->valuestring, '\n'))
            return btf_fail(err, BTF_ERR_FORMAT, "shader: manifest.json prefix entries must be one-line strings");
        btf__str_cat(s, line->valuestring);
        btf__str_cat(s, "\n");
    }
    for (int i = 0; i < d->n_defines; i++) {
        const btf_shader_define *def = &d->defines[i];
        const char *v = def->value ? def->value : "";
        if (!btf__ident(def->name) || strchr(v, '\n') || strchr(v, '\r'))
            return btf_fail(err, BTF_ERR_ARG, "shader: invalid define %d ('%s')", i, def->name ? def->name : "(null)");
        btf__str_cat(s, "#define ");
        btf__str_cat(s, def->name);
        btf__str_cat(s, *v ? " " : "");
        btf__str_cat(s, v);
        btf__str_cat(s, "\n");
    }
    return BTF_OK;
}

static btf_result btf__add_piece(const char *dir, const char *file, btf_shader_source *src, btf__str *s,
                                 btf_error *err)
{
    if (!btf__plain_name(file))
        return btf_fail(err, BTF_ERR_FORMAT, "shader: manifest.json names '%s', not a plain file name", file);
    if (src->n_pieces >= BTF_SHADER_MAX_PIECES)
        return btf_fail(err, BTF_ERR_RANGE, "shader: more than %d files in one stage", BTF_SHADER_MAX_PIECES);
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, file);
    char *text = NULL;
    size_t len = 0;
    btf_result r = btf__read_file(path, &text, &len, err);
    if (r != BTF_OK)
        return r;
    btf__str_cat(s, "// ---- ");
    btf__str_cat(s, file);
    btf__str_cat(s, "\n");
    btf_shader_piece *pc = &src->pieces[src->n_pieces++];
    snprintf(pc->file, sizeof pc->file, "%s", file);
    pc->first_line = btf__count_lines(s->p ? s->p : "", s->len) + 1;
    btf__str_add(s, text, len);
    if (len == 0 || text[len - 1] != '\n')
        btf__str_cat(s, "\n");
    pc->n_lines = btf__count_lines(text, len) + (len > 0 && text[len - 1] != '\n');
    free(text);
    return BTF_OK;
}

static btf_result btf__assemble(const cJSON *manifest, const char *dir, const btf_shader_desc *d,
                                btf_shader_source *src, btf__str *s, btf_error *err)
{
    const char *stage_name = src->stage == BTF_SHADER_VERTEX ? "vertex" : "fragment";
    const cJSON *programs = cJSON_GetObjectItemCaseSensitive(manifest, "programs");
    const cJSON *prog = cJSON_GetObjectItemCaseSensitive(programs, d->program);
    if (!cJSON_IsObject(prog))
        return btf_fail(err, BTF_ERR_MISSING, "shader: program '%s' not in %s/manifest.json", d->program, dir);
    const cJSON *files = cJSON_GetObjectItemCaseSensitive(prog, stage_name);
    if (!cJSON_IsArray(files) || cJSON_GetArraySize(files) < 1)
        return btf_fail(err, BTF_ERR_FORMAT, "shader: program '%s' has no %s file list", d->program, stage_name);
    btf_result r = btf__add_prefix(manifest, d, s, err);
    const cJSON *f;
    cJSON_ArrayForEach(f, files)
    {
        if (r != BTF_OK)
            break;
        if (!cJSON_IsString(f))
            return btf_fail(err, BTF_ERR_FORMAT, "shader: program '%s' %s list holds a non-string", d->program,
                            stage_name);
        r = btf__add_piece(dir, f->valuestring, src, s, err);
    }
    if (r == BTF_OK && s->oom)
        r = btf_fail(err, BTF_ERR_NOMEM, "shader: out of memory assembling '%s'", d->program);
    return r;
}

void btf_shader_source_free(btf_shader_source *s)
{
    if (!s)
        return;
    free(s->text);
    free(s);
}

btf_result btf_shader_assemble(const btf_shader_desc *desc, btf_shader_stage stage, btf_shader_source **out,
                               btf_error *err)
{
    if (!desc || !out || !desc->program || (desc->n_defines > 0 && !desc->defines) || desc->n_defines < 0)
        return btf_fail(err, BTF_ERR_ARG, "shader: invalid arguments");
    if (stage != BTF_SHADER_VERTEX && stage != BTF_SHADER_FRAGMENT)
        return btf_fail(err, BTF_ERR_ARG, "shader: unknown stage %d", (int)stage);
    *out = NULL;
    char dir[900];
    btf__shader_dir(desc, dir, sizeof dir);
    cJSON *manifest = NULL;
    btf_result r = btf__load_manifest(dir, &manifest, err);
    if (r != BTF_OK)
        return r;
    btf_shader_source *src = calloc(1, sizeof *src);
    btf__str s = {0};
    if (!src)
        r = btf_fail(err, BTF_ERR_NOMEM, "shader: out of memory");
    else {
        src->stage = stage;
        r = btf__assemble(manifest, dir, desc, src, &s, err);
    }
    cJSON_Delete(manifest);
    if (r != BTF_OK) {
        free(s.p);
        free(src);
        return r;
    }
    src->text = s.p;
    src->n_lines = btf__count_lines(s.p, s.len);
    *out = src;
    return BTF_OK;
}

int btf_shader_source_line(const btf_shader_source *s, int line, const char **file)
{
    *file = NULL;
    for (int i = 0; s && i < s->n_pieces; i++) {
        const btf_shader_piece *p = &s->pieces[i];
        if (line >= p->first_line && line < p->first_line + p->n_lines) {
            *file = p->file;
            return line - p->first_line + 1;
        }
    }
    return line;
}

/* ---------------------------------------------------------------- error reports */

int btf_shader_log_line(const char *l)
{
    int src = 0, line = 0, col = 0;
    while (*l == ' ' || *l == '\t')
        l++;
    if (!strncmp(l, "ERROR: ", 7) || !strncmp(l, "WARNING: ", 9))
        l = strchr(l, ' ') + 1;
    if (sscanf(l, "%d:%d(%d)", &src, &line, &col) >= 2 && line > 0)
        return line;
    if (sscanf(l, "%d(%d)", &src, &line) == 2 && line > 0)
        return line;
    return 0;
}

/* Appends every log line naming `line` (0: naming no line), each as "^^^ message". */
static void btf__annotate_line(btf__str *s, const char *log, int line)
{
    const char *l = log;
    while (l && *l) {
        const char *end = strchr(l, '\n');
        size_t n = end ? (size_t)(end - l) : strlen(l);
        char buf[1024];
        snprintf(buf, sizeof buf, "%.*s", (int)(n < sizeof buf ? n : sizeof buf - 1), l);
        if (n > 0 && btf_shader_log_line(buf) == line && buf[strspn(buf, " \t\r")] != '\0') {
            btf__str_cat(s, line ? "      ^^^ " : "");
            btf__str_cat(s, buf);
            btf__str_cat(s, "\n");
        }
        l = end ? end + 1 : NULL;
    }
}

char *btf_shader_annotate(const btf_shader_source *src, const char *log)
{
    btf__str s = {0};
    btf__annotate_line(&s, log ? log : "", 0);
    const char *p = src && src->text ? src->text : "";
    for (int line = 1; *p; line++) {
        const char *end = strchr(p, '\n');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        char num[32];
        snprintf(num, sizeof num, "%4d: ", line);
        btf__str_cat(&s, num);
        btf__str_add(&s, p, n);
        btf__str_cat(&s, "\n");
        btf__annotate_line(&s, log ? log : "", line);
        p = end ? end + 1 : p + n;
    }
    if (s.oom) {
        free(s.p);
        return NULL;
    }
    if (!s.p)
        btf__str_cat(&s, "");
    return s.p;
}

/* First log line that carries text, for the one-line error message. */
static void btf__first_message(const char *log, char *buf, size_t n)
{
    const char *l = log + strspn(log, " \t\r\n");
    size_t len = strcspn(l, "\r\n");
    snprintf(buf, n, "%.*s", (int)(len < n ? len : n - 1), l);
}

/* ---------------------------------------------------------------- compile and link */

static char *btf__info_log(btf_gl *gl, GLuint obj, int is_program)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    GLint n = 0;
    if (is_program)
        f->GetProgramiv(obj, GL_INFO_LOG_LENGTH, &n);
    else
        f->GetShaderiv(obj, GL_INFO_LOG_LENGTH, &n);
    char *log = calloc((size_t)(n > 0 ? n : 1) + 1, 1);
    if (log && n > 0) {
        if (is_program)
            f->GetProgramInfoLog(obj, n, NULL, log);
        else
            f->GetShaderInfoLog(obj, n, NULL, log);
    }
    return log;
}

static btf_result btf__compile(btf_gl *gl, const char *prog, const btf_shader_source *src, GLuint *out,
                               char **report, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    const char *stage = src->stage == BTF_SHADER_VERTEX ? "vertex" : "fragment";
    GLuint sh = f->CreateShader(src->stage == BTF_SHADER_VERTEX ? GL_VERTEX_SHADER : GL_FRAGMENT_SHADER);
    const GLchar *text = src->text;
    f->ShaderSource(sh, 1, &text, NULL);
    f->CompileShader(sh);
    GLint ok = 0;
    f->GetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (ok) {
        *out = sh;
        return BTF_OK;
    }
    char *log = btf__info_log(gl, sh, 0);
    f->DeleteShader(sh);
    char first[300] = "";
    btf__first_message(log ? log : "", first, sizeof first);
    const char *file = NULL;
    int line = btf_shader_log_line(first);
    int file_line = btf_shader_source_line(src, line, &file);
    if (report)
        *report = btf_shader_annotate(src, log);
    free(log);
    if (file)
        return btf_fail(err, BTF_ERR_FORMAT, "shader '%s' %s: %s (%s line %d)", prog, stage, first, file, file_line);
    return btf_fail(err, BTF_ERR_FORMAT, "shader '%s' %s: %s", prog, stage, first);
}

static btf_result btf__link(btf_gl *gl, btf_shader_program *p, GLuint vs, GLuint fs, char **report, btf_error *err)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    p->id = f->CreateProgram();
    f->AttachShader(p->id, vs);
    f->AttachShader(p->id, fs);
    f->LinkProgram(p->id);
    GLint ok = 0;
    f->GetProgramiv(p->id, GL_LINK_STATUS, &ok);
    if (ok)
        return btf_gl_check(gl, "linking a program", err);
    char *log = btf__info_log(gl, p->id, 1);
    char first[300] = "";
    btf__first_message(log ? log : "", first, sizeof first);
    if (report)
        *report = log;
    else
        free(log);
    return btf_fail(err, BTF_ERR_FORMAT, "shader '%s': link failed: %s", p->name, first);
}

void btf_shader_program_free(btf_gl *gl, btf_shader_program *p)
{
    if (!p)
        return;
    if (gl && p->id)
        btf_gl_fn(gl)->DeleteProgram(p->id);
    free(p);
}

btf_result btf_shader_build(btf_gl *gl, const btf_shader_desc *desc, btf_shader_program **out, char **report,
                            btf_error *err)
{
    if (!gl || !desc || !out || !desc->program)
        return btf_fail(err, BTF_ERR_ARG, "shader: NULL argument");
    *out = NULL;
    if (report)
        *report = NULL;
    btf_shader_source *vsrc = NULL, *fsrc = NULL;
    btf_result r = btf_shader_assemble(desc, BTF_SHADER_VERTEX, &vsrc, err);
    if (r == BTF_OK)
        r = btf_shader_assemble(desc, BTF_SHADER_FRAGMENT, &fsrc, err);
    GLuint vs = 0, fs = 0;
    if (r == BTF_OK)
        r = btf__compile(gl, desc->program, vsrc, &vs, report, err);
    if (r == BTF_OK)
        r = btf__compile(gl, desc->program, fsrc, &fs, report, err);
    btf_shader_source_free(vsrc);
    btf_shader_source_free(fsrc);
    btf_shader_program *p = NULL;
    if (r == BTF_OK && !(p = calloc(1, sizeof *p)))
        r = btf_fail(err, BTF_ERR_NOMEM, "shader: out of memory");
    if (r == BTF_OK) {
        snprintf(p->name, sizeof p->name, "%s", desc->program);
        r = btf__link(gl, p, vs, fs, report, err);
    }
    const btf_gl_api *f = btf_gl_fn(gl);
    if (vs)
        f->DeleteShader(vs);
    if (fs)
        f->DeleteShader(fs);
    if (r != BTF_OK)
        btf_shader_program_free(gl, p), p = NULL;
    *out = p;
    return r;
}
