/* btf_chart.c - the numbers behind `btf chart` (see btf_chart.h): methods, streaming
 * curves, shader timing, Pareto fronts, CSV files. The gnuplot part is in
 * btf_chart_plot.c. */
#include "btf_chart.h"

#include "btf_export.h"
#include "btf_fs.h"
#include "btf_lod.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "btf_render.h"
#include "btf_thesis.h"
#include "btf_common.h"

#include <dirent.h>
#include <math.h>
#include <omp.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>


static void btf__chart_log(const btf_chart_options *o, const char *fmt, ...)
{
    if (!o || !o->log)
        return;
    va_list ap;
    va_start(ap, fmt);
    vfprintf(o->log, fmt, ap);
    va_end(ap);
    fflush(o->log);
}

/* Copies s into dst (size n) keeping only CSV- and file-safe characters. */
static void btf__chart_clean(char *dst, size_t n, const char *s)
{
    size_t i = 0;
    for (; s && s[i] && i + 1 < n; i++) {
        char ch = s[i];
        int keep = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '-' ||
                   ch == '_' || ch == '.' || ch == ' ';
        dst[i] = keep ? ch : '_';
    }
    dst[i] = 0;
}

/* Same for free text (notes): only commas, quotes and line breaks are replaced. */
static void btf__chart_note(char *dst, size_t n, const char *s)
{
    size_t i = 0;
    for (; s && s[i] && i + 1 < n; i++)
        dst[i] = (s[i] == ',' || s[i] == '"' || s[i] == '\n' || s[i] == '\r') ? ';' : s[i];
    dst[i] = 0;
}

/* ---------------------------------------------------------------- containers */

btf_result btf_chart_create(btf_chart **out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "chart: NULL output");
    *out = calloc(1, sizeof **out);
    return *out ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory");
}

void btf_chart_free(btf_chart *c)
{
    if (!c)
        return;
    free(c->rows), free(c->stream), free(c);
}

/* One more zeroed element of size `elem` at the end of a growing array; NULL when out of memory. */
static void *btf__chart_grow(void **items, int *n, int *cap, size_t elem, const char *what, btf_error *err)
{
    if (*n == *cap) {
        int c = *cap ? 2 * *cap : 64;
        void *r = realloc(*items, (size_t)c * elem);
        if (!r) {
            btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory for %d %s", c, what);
            return NULL;
        }
        *items = r, *cap = c;
    }
    void *e = (char *)*items + (size_t)(*n)++ * elem;
    memset(e, 0, elem);
    return e;
}

static btf_chart_row *btf__chart_row_add(btf_chart *c, btf_error *err)
{
    void *items = c->rows;
    btf_chart_row *r = btf__chart_grow(&items, &c->n_rows, &c->cap_rows, sizeof *r, "rows", err);
    c->rows = items;
    if (r)
        r->shader_ms = NAN;
    return r;
}

static btf_chart_stream_row *btf__chart_stream_add(btf_chart *c, btf_error *err)
{
    void *items = c->stream;
    btf_chart_stream_row *r = btf__chart_grow(&items, &c->n_stream, &c->cap_stream, sizeof *r, "streaming rows", err);
    c->stream = items;
    if (r)
        r->lab_manifest = NAN;
    return r;
}

/* Appends one streaming row: what had arrived at `step` (file, printf-style), the bytes
 * received so far and the errors then (lab_manifest NAN where a format has none). */
static btf_result btf__chart_stream_put(btf_chart *c, const char *name, const char *format, int step, long long bytes,
                                        double lab, double lab_manifest, btf_error *err, const char *file, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 9, 10)))
#endif
    ;
static btf_result btf__chart_stream_put(btf_chart *c, const char *name, const char *format, int step, long long bytes,
                                        double lab, double lab_manifest, btf_error *err, const char *file, ...)
{
    btf_chart_stream_row *s = btf__chart_stream_add(c, err);
    if (!s)
        return BTF_ERR_NOMEM;
    btf__chart_clean(s->material, sizeof s->material, name);
    snprintf(s->format, sizeof s->format, "%s", format);
    s->step = step;
    va_list ap;
    va_start(ap, file);
    vsnprintf(s->file, sizeof s->file, file, ap);
    va_end(ap);
    s->bytes = bytes;
    s->lab = lab;
    s->lab_manifest = lab_manifest;
    return BTF_OK;
}

/* ---------------------------------------------------------------- temporary dirs */


static btf_result btf__chart_tmpdir(char *buf, size_t n, btf_error *err)
{
    const char *t = getenv("TMPDIR");
    snprintf(buf, n, "%s/btf-chart-XXXXXX", t && *t ? t : "/tmp");
    if (!mkdtemp(buf))
        return btf_fail(err, BTF_ERR_IO, "chart: cannot create a temporary directory %s", buf);
    return BTF_OK;
}

static long long btf__chart_file_bytes(const char *dir, const char *name)
{
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    struct stat st;
    return stat(path, &st) == 0 ? (long long)st.st_size : -1;
}

/* ---------------------------------------------------------------- whole-BTF error */

/* Produces one decoded (view, light) image, width*height*3 floats, byte/255 scale. */
typedef void (*btf__chart_image_fn)(const void *ctx, const btf *src, int view, int light, float *out);

/* Error of fn's images against src over every (view, light) pair, on `threads`
 * OpenMP threads (0: OpenMP's default, OMP_NUM_THREADS). */
static btf_result btf__chart_error(const btf *src, btf__chart_image_fn fn, const void *ctx, int threads,
                                   btf_metrics *out, btf_error *err)
{
    btf_metrics_acc all = {0};
    int nomem = 0, V = src->views.n_dirs, L = src->lights.n_dirs;
    size_t n = btf_image_samples(src);
#pragma omp parallel num_threads(threads > 0 ? threads : omp_get_max_threads())
    {
        btf_metrics_acc acc = {0};
        float *ref = malloc(n * sizeof *ref), *dec = malloc(n * sizeof *dec);
        if (!ref || !dec) {
#pragma omp atomic write
            nomem = 1;
        }
#pragma omp for schedule(static, 1)
        for (int p = 0; p < V * L; p++)
            if (ref && dec) {
                btf_get_image(src, p / L, p % L, ref);
                fn(ctx, src, p / L, p % L, dec);
                btf_metrics_add(&acc, ref, dec, n / 3);
            }
#pragma omp critical(btf__chart_sum)
        btf_metrics_merge(&all, &acc);
        free(ref);
        free(dec);
    }
    if (nomem)
        return btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory for the error images");
    btf_metrics_finish(&all, out);
    return BTF_OK;
}

static void btf__chart_model_image(const void *ctx, const btf *src, int view, int light, float *out)
{
    const btf_model *m = ctx;
    float lv[3], vv[3];
    btf_dirset_vector(&src->lights, light, lv);
    btf_dirset_vector(&src->views, view, vv);
    for (int y = 0; y < src->height; y++)
        for (int x = 0; x < src->width; x++)
            btf_model_decode(m, x, y, lv, vv, out + 3 * ((size_t)y * src->width + x));
}

/* A package read from disk and how many of its chunks to use. */
typedef struct btf__chart_pkg_ctx {
    const btf_package *p;
    int n;
} btf__chart_pkg_ctx;

static void btf__chart_pkg_image(const void *ctx, const btf *src, int view, int light, float *out)
{
    const btf__chart_pkg_ctx *c = ctx;
    for (int y = 0; y < src->height; y++)
        for (int x = 0; x < src->width; x++)
            btf_package_value(c->p, view, light, x, y, c->n, out + 3 * ((size_t)y * src->width + x));
}

/* The float PCA model (before quantisation) and how many of its components to use. */
typedef struct btf__chart_float_ctx {
    const btf_pca_model *m;
    int n;
} btf__chart_float_ctx;

static void btf__chart_float_image(const void *ctx, const btf *src, int view, int light, float *out)
{
    const btf__chart_float_ctx *c = ctx;
    for (int y = 0; y < src->height; y++)
        for (int x = 0; x < src->width; x++)
            for (int ch = 0; ch < 3; ch++)
                out[3 * ((size_t)y * src->width + x) + ch] = btf_pca_model_value(c->m, view, light, x, y, ch, c->n);
}

static void btf__chart_thesis_image(const void *ctx, const btf *src, int view, int light, float *out)
{
    (void)src;
    btf_thesis_decode_image(ctx, view, light, out);
}

/* ---------------------------------------------------------------- shader timing */

#define BTF__CHART_MAX_SHADER 16

/* ms per frame of each package dirs[i] (i < n), drawn on a plane filling a w x h
 * frame. Frames are taken round-robin over the packages and the fastest of each is
 * kept, so a burst of load from other processes does not favour one package. */
static btf_result btf__chart_shader_time(const char *const *dirs, int n, const btf_chart_options *o, double *ms,
                                         btf_error *err)
{
    int w = o->shader_width > 0 ? o->shader_width : 1280, h = o->shader_height > 0 ? o->shader_height : 720;
    int frames = o->shader_frames > 0 ? o->shader_frames : 3;
    btf_package *p[BTF__CHART_MAX_SHADER] = {0};
    btf_renderer *r[BTF__CHART_MAX_SHADER] = {0};
    btf_gl *gl = NULL;
    btf_gl_target *t = NULL;
    btf_gl_desc gd = {0};
    btf_result res = n >= 1 && n <= BTF__CHART_MAX_SHADER ? btf_gl_create(&gd, &gl, err)
                                                           : btf_fail(err, BTF_ERR_ARG, "chart: %d packages to time", n);
    if (res == BTF_OK)
        res = btf_gl_target_create(gl, w, h, BTF_GL_RGBA8, 1, &t, err);
    btf_render_params rp = btf_render_defaults(BTF_RENDER_PLANE);
    rp.width = w, rp.height = h;
    rp.camera_theta = 0.0f;
    rp.repeat = 4.0f;
    /* the plane's half width 1 fills the frame: dist * tan(fov/2) * aspect < 1 */
    rp.camera_dist = 0.9f / (tanf(rp.fov_deg * 0.5f * 3.14159265f / 180.0f) * ((float)w / (float)h));
    for (int i = 0; res == BTF_OK && i < n; i++) {
        ms[i] = INFINITY;
        res = btf_package_read(dirs[i], 0, &p[i], err);
        if (res == BTF_OK)
            res = btf_renderer_create(gl, p[i], dirs[i], 0, &r[i], err);
        if (res == BTF_OK)
            res = btf_renderer_draw(r[i], &rp, t, err); /* warm-up: shader compile, uploads */
    }
    for (int f = 0; res == BTF_OK && f < frames; f++)
        for (int i = 0; res == BTF_OK && i < n; i++) {
            rp.light_phi += 7.0f; /* a different frame each time, same work */
            double t0 = btf_seconds();
            res = btf_renderer_draw(r[i], &rp, t, err);
            double dt = 1000.0 * (btf_seconds() - t0);
            ms[i] = dt < ms[i] ? dt : ms[i];
        }
    for (int i = 0; i < n && i < BTF__CHART_MAX_SHADER; i++) {
        btf_renderer_free(r[i]);
        btf_package_free(p[i]);
    }
    if (gl)
        btf_gl_target_free(gl, t);
    btf_gl_free(gl);
    return res;
}

/* Times k = 3 packages of src for each component count Cs[i] (i < n) and caches
 * the results in c->shader_ms_by_c (NAN on failure, with c->shader_note). */
static void btf__chart_shader_measure(btf_chart *c, const btf *src, const int *Cs, int n,
                                      const btf_chart_options *o, const char *tmp)
{
    char dirs[BTF__CHART_MAX_SHADER][4200];
    const char *dp[BTF__CHART_MAX_SHADER];
    double ms[BTF__CHART_MAX_SHADER];
    btf_error e = {{0}};
    btf_result r = BTF_OK;
    int made = 0;
    for (int i = 0; r == BTF_OK && i < n; i++, made++) {
        snprintf(dirs[i], sizeof dirs[i], "%s/shader-c%d", tmp, Cs[i]);
        dp[i] = dirs[i];
        btf_pca_options po = {0};
        po.k = 3, po.components = Cs[i];
        btf_package_options ko = {0};
        ko.bits = 8, ko.name = "chart", ko.lab_max_texels = 16;
        r = btf_package_compress(src, &po, &ko, dirs[i], NULL, &e);
    }
    if (r == BTF_OK)
        r = btf__chart_shader_time(dp, n, o, ms, &e);
    for (int i = 0; i < made; i++)
        btf_fs_rmtree(dirs[i], NULL);
    if (r != BTF_OK) {
        btf__chart_note(c->shader_note, sizeof c->shader_note, e.msg);
        btf__chart_log(o, "  shader timing failed: %s\n", e.msg);
    }
    for (int i = 0; i < n; i++) {
        c->shader_ms_by_c[Cs[i]] = r == BTF_OK && isfinite(ms[i]) ? ms[i] : NAN;
        if (r == BTF_OK)
            btf__chart_log(o, "  shader C%d: %.1f ms/frame\n", Cs[i], ms[i]);
    }
}

/* Shader ms/frame for C components (cached; measured alone if not yet). */
static double btf__chart_shader_for(btf_chart *c, const btf *src, int C, const btf_chart_options *o,
                                    const char *tmp)
{
    if (C < 1 || C > 64)
        return NAN;
    if (c->shader_ms_by_c[C] == 0.0)
        btf__chart_shader_measure(c, src, &C, 1, o, tmp);
    return c->shader_ms_by_c[C];
}

/* Measures every component count the PCA settings to run will need, together. */
static void btf__chart_shader_all(btf_chart *c, const btf *src, const btf_chart_options *o, const char *tmp)
{
    const btf_method_setting *set;
    int n = btf_method_registry(&set), Cs[BTF__CHART_MAX_SHADER], nc = 0;
    for (int i = 0; i < n; i++) {
        if ((o->quick && !btf_chart_setting_quick(&set[i])) ||
            (set[i].method != &btf_method_pca && set[i].method != &btf_method_pca_q))
            continue;
        int C = set[i].params.components > 0 ? set[i].params.components : 8, seen = 0;
        for (int j = 0; j < nc; j++)
            seen |= Cs[j] == C;
        if (!seen && C <= 64 && c->shader_ms_by_c[C] == 0.0 && nc < BTF__CHART_MAX_SHADER)
            Cs[nc++] = C;
    }
    if (nc > 0)
        btf__chart_shader_measure(c, src, Cs, nc, o, tmp);
}

/* ---------------------------------------------------------------- methods */

int btf_chart_setting_quick(const btf_method_setting *s)
{
    static const char *const quick[] = {"phong",     "lafortune 1", "pca k1 C8",   "pca k3 C8",
                                        "pca k3 C2", "pca k3 C4",   "pca-q k3 C8", "lpyr L3 C8"};
    for (size_t i = 0; s && i < sizeof quick / sizeof quick[0]; i++)
        if (!strcmp(s->label, quick[i]))
            return 1;
    return 0;
}

static int btf__chart_is_pca(const btf_model *m)
{
    return m->method == &btf_method_pca || m->method == &btf_method_pca_q;
}

/* Runs one setting on src and fills row r. Method failures land in the row. */
static btf_result btf__chart_setting(btf_chart *c, btf_chart_row *row, const btf_method_setting *s, const btf *src,
                                     const btf_chart_options *o, const char *tmp, btf_error *err)
{
    btf__chart_clean(row->label, sizeof row->label, s->label);
    btf__chart_clean(row->family, sizeof row->family, s->family);
    btf__chart_clean(row->method, sizeof row->method, s->method->name);
    btf_model *m = NULL;
    btf_error e = {{0}};
    btf_result r = btf_model_encode(s->method, src, &s->params, &m, &e);
    if (r != BTF_OK) {
        btf__chart_note(row->note, sizeof row->note, e.msg);
        btf__chart_log(o, "  %-16s FAILED: %s\n", s->label, e.msg);
        return r == BTF_ERR_NOMEM ? btf_fail(err, r, "%s", e.msg) : BTF_OK;
    }
    row->k = m->params.k, row->components = m->params.components, row->lobes = m->params.lobes;
    row->levels = m->params.levels, row->decode_levels = m->params.decode_levels;
    row->encode_s = m->seconds;
    row->bytes = (double)btf_model_bytes(m);
    btf_method_cost cost = btf_model_cost(m);
    row->fetches = cost.fetches, row->flops = cost.flops;
    row->n_fallback = m->n_fallback, row->n_unconverged = m->n_unconverged;
    btf_metrics met;
    double t0 = btf_seconds();
    r = btf__chart_error(src, btf__chart_model_image, m, o->threads, &met, err);
    row->decode_s = btf_seconds() - t0;
    if (r == BTF_OK) {
        row->ok = 1;
        row->lab = met.lab_thesis, row->delta_e76 = met.delta_e76, row->rmse = met.rmse;
        if (btf__chart_is_pca(m) && o->shader)
            row->shader_ms = btf__chart_shader_for(c, src, m->params.components, o, tmp);
        if (btf__chart_is_pca(m) && !isfinite(row->shader_ms))
            btf__chart_note(row->note, sizeof row->note,
                            o->shader ? c->shader_note : "shader not timed (run without --no-shader)");
        else if (!btf__chart_is_pca(m))
            btf__chart_note(row->note, sizeof row->note, "no shader variant: cost model only");
        else
            snprintf(row->note, sizeof row->note, "shader: k3 C%d package; %dx%d", m->params.components,
                     o->shader_width > 0 ? o->shader_width : 1280, o->shader_height > 0 ? o->shader_height : 720);
    }
    btf__chart_log(o, "  %-16s %7.2f s  %9.0f B  Lab %6.3f  cost %5.0f+%-6.0f decode %.2f s\n", s->label,
                   row->encode_s, row->bytes, row->lab, row->fetches, row->flops, row->decode_s);
    btf_model_free(m);
    return r;
}

/* ---------------------------------------------------------------- streaming */

/* The float PCA optimum of the package's k at each C, placed at the bytes the package
 * has after C chunks: what quantisation and coding cost at each point of the curve. */
static btf_result btf__chart_stream_float(btf_chart *c, const char *name, const char *format, const btf *src,
                                          const btf_pca_options *po, const btf_package *p, long long bytes,
                                          btf_error *err)
{
    btf_pca_model *m = NULL;
    btf_result r = btf_pca_compress(src, po, NULL, NULL, &m, err);
    for (int i = 0; r == BTF_OK && i < p->n_chunks && i < m->n_comp; i++) {
        btf__chart_float_ctx ctx = {m, i + 1};
        btf_metrics met;
        r = btf__chart_error(src, btf__chart_float_image, &ctx, 0, &met, err);
        bytes += p->chunk[i].bytes;
        if (r == BTF_OK)
            r = btf__chart_stream_put(c, name, format, i + 1, bytes, met.lab_thesis, NAN, err, "float PCA k%d C=%d",
                                      po->k, i + 1);
    }
    btf_pca_model_free(m);
    return r;
}

/* The package of k views per block (C = 8) after each chunk, and the float PCA
 * optimum of the same k: formats "package"/"float" at k = 3, "package-k1"/"float-k1"
 * at k = 1 (PCA-RF), "package-kall"/"float-kall" at k = every view (PCA-BTF). */
static btf_result btf__chart_stream_package(btf_chart *c, const char *name, const btf *src,
                                            const btf_chart_options *o, const char *tmp, int k, btf_error *err)
{
    char dir[4200], fpkg[16], ffloat[16];
    const char *suffix = k == 3 ? "" : k == 1 ? "-k1" : "-kall";
    snprintf(dir, sizeof dir, "%s/package", tmp);
    snprintf(fpkg, sizeof fpkg, "package%s", suffix);
    snprintf(ffloat, sizeof ffloat, "float%s", suffix);
    btf_pca_options po = {0};
    po.k = k, po.components = 8;
    btf_package_options ko = {0};
    ko.bits = 8, ko.name = "chart";
    ko.lab_max_texels = src->width * src->height; /* manifest numbers over every texel */
    btf_package *p = NULL;
    btf_result r = btf_package_compress(src, &po, &ko, dir, NULL, err);
    if (r == BTF_OK)
        r = btf_package_read(dir, 0, &p, err);
    long long bytes = btf__chart_file_bytes(dir, "manifest.json");
    for (int i = 0; r == BTF_OK && i < p->n_chunks; i++) {
        btf__chart_pkg_ctx ctx = {p, i + 1};
        btf_metrics met;
        met.lab_thesis = p->chunk[i].lab;
        if (o->verify_stream)
            r = btf__chart_error(src, btf__chart_pkg_image, &ctx, o->threads, &met, err);
        bytes += p->chunk[i].bytes;
        if (r == BTF_OK)
            r = btf__chart_stream_put(c, name, fpkg, i + 1, bytes, met.lab_thesis, p->chunk[i].lab, err, "%s%s%s",
                                      i == 0 ? "manifest.json " : "", p->chunk[i].files[0],
                                      p->chunk[i].n_files > 1 ? " +weights" : "");
    }
    if (r == BTF_OK)
        r = btf__chart_stream_float(c, name, ffloat, src, &po, p, btf__chart_file_bytes(dir, "manifest.json"), err);
    btf_package_free(p);
    btf_fs_rmtree(dir, NULL);
    return r;
}

/* Prefix n of a package with levels seen at level 0: per component its finest loaded
 * level upsampled to W x H (block-major) and its most precise loaded weights. */
typedef struct btf__chart_lod_ctx {
    const btf_package *p;
    float *tex;        /* C * blocks * W * H */
    const float **wt;  /* C, NULL: component not loaded */
} btf__chart_lod_ctx;

static void btf__chart_lod_image(const void *ctx, const btf *src, int view, int light, float *out)
{
    const btf__chart_lod_ctx *c = ctx;
    const btf_package *p = c->p;
    size_t N = (size_t)src->width * src->height;
    int b = p->blocks->block_of_view[view], L = p->lights.n_dirs;
    memset(out, 0, 3 * N * sizeof *out);
    for (int k = 0; k < p->n_comp; k++) {
        if (!c->wt[k])
            continue;
        const float *t = c->tex + ((size_t)k * p->blocks->n_blocks + b) * N, *w = c->wt[k] + ((size_t)view * L + light) * 3;
        for (size_t i = 0; i < N; i++)
            out[3 * i] += t[i] * w[0], out[3 * i + 1] += t[i] * w[1], out[3 * i + 2] += t[i] * w[2];
    }
}

/* The same package with spatial levels (version 4, btf lod --residual, the default
 * levels), in its chunk order: the error at level 0 after each chunk. */
static btf_result btf__chart_stream_levels(btf_chart *c, const char *name, const btf *src,
                                           const btf_chart_options *o, const char *tmp, btf_error *err)
{
    char v1[4200], dir[4200];
    snprintf(v1, sizeof v1, "%s/levels-v1", tmp);
    snprintf(dir, sizeof dir, "%s/levels", tmp);
    btf_pca_options po = {0};
    po.k = 3, po.components = 8;
    btf_package_options ko = {0};
    ko.bits = 8, ko.name = "chart";
    btf_lod_options lo = {0};
    lo.residual = 1;
    btf_package *p = NULL;
    btf_result r = btf_package_compress(src, &po, &ko, v1, NULL, err);
    if (r == BTF_OK)
        r = btf_lod_build(v1, dir, &lo, NULL, err);
    if (r == BTF_OK)
        r = btf_package_read(dir, 1, &p, err);
    int n = r == BTF_OK ? p->n_chunks : 0;
    size_t N = (size_t)src->width * src->height;
    btf__chart_lod_ctx ctx = {NULL, NULL, NULL};
    if (r == BTF_OK) {
        ctx.tex = calloc((size_t)p->n_comp * p->blocks->n_blocks * N, sizeof(float));
        ctx.wt = calloc((size_t)p->n_comp, sizeof *ctx.wt);
        if (!ctx.tex || !ctx.wt)
            r = btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory");
    }
    btf_package_free(p);
    long long bytes = btf__chart_file_bytes(dir, "manifest.json");
    for (int i = 0; r == BTF_OK && i < n; i++) {
        btf_package *q = NULL; /* the prefix as a client holds it (8-bit weights until the 16-bit ones) */
        r = btf_package_read(dir, i + 1, &q, err);
        for (int k = 0; r == BTF_OK && k < q->n_comp; k++) {
            int j = btf_package_chunk_at(q, i + 1, k, 0);
            ctx.wt[k] = j >= 0 ? q->wt[j] : NULL;
            for (int b = 0; j >= 0 && b < q->blocks->n_blocks; b++)
                for (int y = 0; y < src->height; y++)
                    for (int x = 0; x < src->width; x++)
                        ctx.tex[((size_t)k * q->blocks->n_blocks + b) * N + (size_t)y * src->width + x] =
                            btf_package_texel(q, j, b, x, y);
        }
        ctx.p = q;
        btf_metrics met;
        if (r == BTF_OK)
            r = btf__chart_error(src, btf__chart_lod_image, &ctx, o->threads, &met, err);
        if (r == BTF_OK) {
            bytes += q->chunk[i].bytes;
            r = btf__chart_stream_put(c, name, "levels", i + 1, bytes, met.lab_thesis, NAN, err, "%s%s%s",
                                      i == 0 ? "manifest.json " : "", q->chunk[i].files[0],
                                      q->chunk[i].n_files > 1 ? " +weights" : "");
        }
        btf_package_free(q);
    }
    free(ctx.tex), free(ctx.wt);
    btf_fs_rmtree(dir, NULL);
    btf_fs_rmtree(v1, NULL);
    return r;
}

static btf_result btf__chart_stream_thesis(btf_chart *c, const char *name, const btf *src,
                                           const btf_chart_options *o, const char *tmp, btf_error *err)
{
    char dir[4200];
    snprintf(dir, sizeof dir, "%s/thesis", tmp);
    btf_export_options eo = {0};
    eo.k = 3, eo.components = 8;
    btf_thesis_pkg p = {0};
    btf_error e = {{0}};
    btf_result r = btf_export_thesis(src, &eo, dir, NULL, &e);
    if (r == BTF_OK)
        r = btf_thesis_read(dir, &p, &e);
    if (r != BTF_OK) { /* e.g. a non-square source: the format cannot hold it */
        btf__chart_log(o, "  thesis export skipped: %s\n", e.msg);
        btf_fs_rmtree(dir, NULL);
        return r == BTF_ERR_NOMEM ? btf_fail(err, r, "%s", e.msg) : BTF_OK;
    }
    float *sigma = malloc((size_t)p.nb * (size_t)p.C * sizeof *sigma);
    if (!sigma)
        r = btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory");
    else
        memcpy(sigma, p.sigma, (size_t)p.nb * (size_t)p.C * sizeof *sigma);
    long long bytes = btf__chart_file_bytes(dir, "meta.json") + btf__chart_file_bytes(dir, "R.png");
    for (int j = 0; r == BTF_OK && j < p.C; j++) {
        char file[32];
        snprintf(file, sizeof file, "%d.png", j);
        /* components beyond j not received: their sigma is zero */
        for (int b = 0; b < p.nb; b++)
            for (int i = 0; i < p.C; i++)
                p.sigma[b * p.C + i] = i <= j ? sigma[b * p.C + i] : 0.0f;
        btf_metrics met;
        r = btf__chart_error(src, btf__chart_thesis_image, &p, o->threads, &met, err);
        bytes += btf__chart_file_bytes(dir, file);
        if (r == BTF_OK)
            r = btf__chart_stream_put(c, name, "thesis", j + 1, bytes, met.lab_thesis, NAN, err, "%s%s",
                                      j == 0 ? "meta.json R.png " : "", file);
    }
    free(sigma);
    btf_thesis_free(&p);
    btf_fs_rmtree(dir, NULL);
    return r;
}

btf_result btf_chart_add_material(btf_chart *c, const char *name, const btf *src, const btf_chart_options *opt,
                                  btf_error *err)
{
    if (!c || !name || !src || !src->data)
        return btf_fail(err, BTF_ERR_ARG, "chart: NULL chart, name or source");
    btf_chart_options o = {0};
    if (opt)
        o = *opt;
    btf_result r = btf_check_finite(src, err); /* every method would refuse it */
    if (r != BTF_OK)
        return r;
    char tmp[4096];
    r = btf__chart_tmpdir(tmp, sizeof tmp, err);
    if (r != BTF_OK)
        return r;
    btf__chart_log(&o, "%s: %dx%d texels, %d lights x %d views\n", name, src->width, src->height,
                   src->lights.n_dirs, src->views.n_dirs);
    if (o.shader && !o.no_methods)
        btf__chart_shader_all(c, src, &o, tmp);
    const btf_method_setting *set;
    int n = btf_method_registry(&set);
    for (int i = 0; r == BTF_OK && !o.no_methods && i < n; i++) {
        if (o.quick && !btf_chart_setting_quick(&set[i]))
            continue;
        btf_chart_row *row = btf__chart_row_add(c, err);
        if (!row) {
            r = BTF_ERR_NOMEM;
            break;
        }
        btf__chart_clean(row->material, sizeof row->material, name);
        r = btf__chart_setting(c, row, &set[i], src, &o, tmp, err);
    }
    double t0 = btf_seconds();
    if (r == BTF_OK && !o.no_stream)
        r = btf__chart_stream_package(c, name, src, &o, tmp, 3, err);
    double t1 = btf_seconds();
    for (int i = 0; i < 2 && r == BTF_OK && !o.no_stream && !o.quick; i++) /* PCA-RF and PCA-BTF */
        r = btf__chart_stream_package(c, name, src, &o, tmp, i ? src->views.n_dirs : 1, err);
    double t1k = btf_seconds();
    if (r == BTF_OK && !o.no_stream)
        r = btf__chart_stream_thesis(c, name, src, &o, tmp, err);
    double t2 = btf_seconds();
    if (r == BTF_OK && !o.no_stream)
        r = btf__chart_stream_levels(c, name, src, &o, tmp, err);
    if (r == BTF_OK && !o.no_stream)
        btf__chart_log(&o, "  streaming: package %.1f s, k = 1 and all %.1f s, thesis format %.1f s, package with "
                       "levels %.1f s\n", t1 - t0, t1k - t1, t2 - t1k, btf_seconds() - t2);
    btf_fs_rmtree(tmp, NULL);
    if (r == BTF_OK && !o.no_methods)
        c->n_materials++; /* materials with method rows (for the mean rows) */
    return r;
}

/* ---------------------------------------------------------------- mean rows, Pareto */

void btf_chart_pareto(const double *x, const double *y, int n, int *front)
{
    /* sweep by ascending x (ties: ascending y); a point is on the front when its y is
     * below every y seen at strictly smaller x and it is the lowest y of its x group */
    int *ord = malloc((size_t)(n > 0 ? n : 1) * sizeof *ord);
    for (int i = 0; i < n; i++)
        front[i] = 0;
    if (!ord) { /* quadratic fallback */
        for (int i = 0; i < n; i++) {
            front[i] = isfinite(x[i]) && isfinite(y[i]);
            for (int j = 0; j < n && front[i]; j++)
                if (isfinite(x[j]) && isfinite(y[j]) && x[j] <= x[i] && y[j] <= y[i] && (x[j] < x[i] || y[j] < y[i]))
                    front[i] = 0;
        }
        return;
    }
    int m = 0;
    for (int i = 0; i < n; i++)
        if (isfinite(x[i]) && isfinite(y[i]))
            ord[m++] = i;
    for (int i = 1; i < m; i++) { /* insertion sort: n is a few dozen */
        int v = ord[i], j = i - 1;
        while (j >= 0 && (x[ord[j]] > x[v] || (x[ord[j]] == x[v] && y[ord[j]] > y[v]))) {
            ord[j + 1] = ord[j];
            j--;
        }
        ord[j + 1] = v;
    }
    double best = INFINITY; /* lowest y at strictly smaller x */
    for (int a = 0; a < m;) {
        int b = a;
        while (b < m && x[ord[b]] == x[ord[a]])
            b++;
        double ymin = y[ord[a]];
        for (int i = a; i < b; i++)
            front[ord[i]] = y[ord[i]] == ymin && ymin < best;
        best = ymin < best ? ymin : best;
        a = b;
    }
    free(ord);
}

/* Adds one "mean" row per label that succeeded on every material. */
static btf_result btf__chart_means(btf_chart *c, btf_error *err)
{
    int n0 = c->n_rows;
    for (int i = 0; i < n0; i++) {
        int first = 1, count = 0;
        for (int j = 0; j < i; j++)
            first &= strcmp(c->rows[j].label, c->rows[i].label) != 0;
        if (!first)
            continue;
        btf_chart_row sum;
        memset(&sum, 0, sizeof sum);
        int all_ok = 1, shader_n = 0;
        for (int j = 0; j < n0; j++) {
            const btf_chart_row *r = &c->rows[j];
            if (strcmp(r->label, c->rows[i].label))
                continue;
            count++;
            all_ok &= r->ok;
            sum.encode_s += r->encode_s, sum.decode_s += r->decode_s, sum.lab += r->lab;
            sum.delta_e76 += r->delta_e76, sum.rmse += r->rmse, sum.bytes += r->bytes;
            sum.fetches += r->fetches, sum.flops += r->flops;
            sum.n_fallback += r->n_fallback, sum.n_unconverged += r->n_unconverged;
            if (isfinite(r->shader_ms))
                sum.shader_ms += r->shader_ms, shader_n++;
        }
        if (!all_ok || count != c->n_materials)
            continue;
        btf_chart_row *m = btf__chart_row_add(c, err);
        if (!m)
            return BTF_ERR_NOMEM;
        const btf_chart_row *proto = &c->rows[i];
        *m = *proto;
        snprintf(m->material, sizeof m->material, "mean");
        double k = 1.0 / count;
        m->encode_s = sum.encode_s * k, m->decode_s = sum.decode_s * k, m->lab = sum.lab * k;
        m->delta_e76 = sum.delta_e76 * k, m->rmse = sum.rmse * k, m->bytes = sum.bytes * k;
        m->fetches = sum.fetches * k, m->flops = sum.flops * k;
        m->n_fallback = sum.n_fallback, m->n_unconverged = sum.n_unconverged;
        m->shader_ms = shader_n ? sum.shader_ms / shader_n : NAN;
    }
    return BTF_OK;
}

/* Marks both fronts among the rows of one material. */
static btf_result btf__chart_mark(btf_chart *c, const char *material, btf_error *err)
{
    int n = c->n_rows;
    double *x = malloc((size_t)n * sizeof *x), *b = malloc((size_t)n * sizeof *b), *y = malloc((size_t)n * sizeof *y);
    int *idx = malloc((size_t)n * sizeof *idx), *f = malloc((size_t)n * sizeof *f);
    int m = 0;
    btf_result r = BTF_OK;
    if (!x || !b || !y || !idx || !f) {
        r = btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory");
        goto done;
    }
    for (int i = 0; i < n; i++) {
        btf_chart_row *row = &c->rows[i];
        if (strcmp(row->material, material) || !row->ok)
            continue;
        idx[m] = i, x[m] = row->fetches + row->flops, b[m] = row->bytes, y[m] = row->lab;
        m++;
    }
    btf_chart_pareto(x, y, m, f);
    for (int i = 0; i < m; i++)
        c->rows[idx[i]].pareto_cost = f[i];
    btf_chart_pareto(b, y, m, f);
    for (int i = 0; i < m; i++)
        c->rows[idx[i]].pareto_bytes = f[i];
done:
    free(x), free(b), free(y), free(idx), free(f);
    return r;
}

btf_result btf_chart_finish(btf_chart *c, btf_error *err)
{
    if (!c)
        return btf_fail(err, BTF_ERR_ARG, "chart: NULL chart");
    btf_result r = c->n_materials > 0 ? btf__chart_means(c, err) : BTF_OK;
    for (int i = 0; r == BTF_OK && i < c->n_rows; i++) {
        int first = 1;
        for (int j = 0; j < i && first; j++)
            first = strcmp(c->rows[j].material, c->rows[i].material) != 0;
        if (first)
            r = btf__chart_mark(c, c->rows[i].material, err);
    }
    return r;
}

/* ---------------------------------------------------------------- CSV */

/* "%.6g" or empty for a non-finite value. */
static const char *btf__chart_num(char *buf, size_t n, double v)
{
    if (isfinite(v))
        snprintf(buf, n, "%.6g", v);
    else
        buf[0] = 0;
    return buf;
}

static void btf__chart_csv_rows(const btf_chart *c, FILE *f)
{
    fprintf(f, "material,label,family,method,k,components,lobes,levels,decode_levels,ok,encode_s,decode_s,"
               "lab,delta_e76,rmse,bytes,fetches,flops,cost,shader_ms,pareto_cost,pareto_bytes,n_fallback,"
               "n_unconverged,note\n");
    for (int i = 0; i < c->n_rows; i++) {
        const btf_chart_row *r = &c->rows[i];
        char a[9][32];
        fprintf(f, "%s,%s,%s,%s,%d,%d,%d,%d,%d,%d,%s,%s,%s,%s,%s,%.10g,%.6g,%.6g,%.6g,%s,%d,%d,%d,%d,%s\n",
                r->material, r->label, r->family, r->method, r->k, r->components, r->lobes, r->levels,
                r->decode_levels, r->ok, btf__chart_num(a[0], 32, r->encode_s),
                btf__chart_num(a[1], 32, r->decode_s), btf__chart_num(a[2], 32, r->ok ? r->lab : NAN),
                btf__chart_num(a[3], 32, r->ok ? r->delta_e76 : NAN), btf__chart_num(a[4], 32, r->ok ? r->rmse : NAN),
                r->bytes, r->fetches, r->flops, r->fetches + r->flops, btf__chart_num(a[5], 32, r->shader_ms),
                r->pareto_cost, r->pareto_bytes, r->n_fallback, r->n_unconverged, r->note);
    }
}

static void btf__chart_csv_stream(const btf_chart *c, FILE *f)
{
    fprintf(f, "material,format,step,file,bytes,lab,lab_manifest\n");
    for (int i = 0; i < c->n_stream; i++) {
        const btf_chart_stream_row *s = &c->stream[i];
        char a[2][32];
        fprintf(f, "%s,%s,%d,%s,%lld,%s,%s\n", s->material, s->format, s->step, s->file, s->bytes,
                btf__chart_num(a[0], 32, s->lab), btf__chart_num(a[1], 32, s->lab_manifest));
    }
}

/* Wide table: one line per setting, one encode-time column per material (+ mean). */
static void btf__chart_csv_time(const btf_chart *c, FILE *f)
{
    const char *mats[256];
    int nm = 0;
    for (int i = 0; i < c->n_rows && nm < 256; i++) {
        int seen = 0;
        for (int j = 0; j < nm; j++)
            seen |= !strcmp(mats[j], c->rows[i].material);
        if (!seen)
            mats[nm++] = c->rows[i].material;
    }
    fprintf(f, "label,family");
    for (int j = 0; j < nm; j++)
        fprintf(f, ",%s", mats[j]);
    fprintf(f, "\n");
    for (int i = 0; i < c->n_rows; i++) {
        int first = 1;
        for (int j = 0; j < i && first; j++)
            first = strcmp(c->rows[j].label, c->rows[i].label) != 0;
        if (!first)
            continue;
        fprintf(f, "%s,%s", c->rows[i].label, c->rows[i].family);
        for (int j = 0; j < nm; j++) {
            char a[32] = "";
            for (int k = 0; k < c->n_rows; k++)
                if (!strcmp(c->rows[k].label, c->rows[i].label) && !strcmp(c->rows[k].material, mats[j]) &&
                    c->rows[k].ok)
                    btf__chart_num(a, sizeof a, c->rows[k].encode_s);
            fprintf(f, ",%s", a);
        }
        fprintf(f, "\n");
    }
}

static btf_result btf__chart_csv_file(const btf_chart *c, const char *dir, const char *name,
                                      void (*body)(const btf_chart *, FILE *), btf_error *err)
{
    char path[4096], *text = NULL;
    size_t n = 0;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = open_memstream(&text, &n);
    if (!f)
        return btf_fail(err, BTF_ERR_NOMEM, "chart: out of memory for %s", path);
    body(c, f);
    int bad = ferror(f);
    bad |= fclose(f) != 0;
    btf_result r = bad ? btf_fail(err, BTF_ERR_NOMEM, "chart: cannot format %s", path)
                       : btf_fs_write_atomic(path, text, n, err);
    free(text);
    return r;
}

btf_result btf_chart_write_csv(const btf_chart *c, const char *dir, btf_error *err)
{
    if (!c || !dir)
        return btf_fail(err, BTF_ERR_ARG, "chart: NULL chart or directory");
    btf_result r = btf__chart_csv_file(c, dir, "chart-speed-accuracy.csv", btf__chart_csv_rows, err);
    if (r == BTF_OK)
        r = btf__chart_csv_file(c, dir, "chart-streaming.csv", btf__chart_csv_stream, err);
    if (r == BTF_OK)
        r = btf__chart_csv_file(c, dir, "chart-compress-time.csv", btf__chart_csv_time, err);
    return r;
}
