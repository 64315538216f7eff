/* btf_export_thesis.c - the project's PCA written in the thesis's package format
 * (doc/input-formats.md section 3). See btf_export.h. */
#include "btf_export.h"

#include "btf_fs.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "btf_fs.h"
#include "btf_common.h"
#include "btf_blocks.h"

#define BTF__H (1.0f / 255.0f) /* half a byte step over [-1, 1] */
#define BTF__S 0.05f           /* half the 0.1 sigma step */
#define BTF__SIGMA_MAX 2559.9f /* largest sigma the two digit pairs hold */
#define BTF__GRID 48           /* quarter octaves searched per scale (a factor 4096) */

const char *btf_thesis_scale_name(btf_thesis_scale s)
{
    return s == BTF_THESIS_SCALE_FIT ? "fit" : "thesis";
}

static float btf__absmax(const float *x, size_t n)
{
    float m = 0.0f;
    for (size_t i = 0; i < n; i++)
        m = fabsf(x[i]) > m ? fabsf(x[i]) : m;
    return m;
}

/* |sigma' - sigma' rounded to 0.1 steps|, as the writer rounds it. */
static double btf__sigma_err(double sp)
{
    return fabs(sp - (double)lround(sp * 10.0) / 10.0);
}

/* Scales (a, c) for one component: U max mu over `rows` texels, V max mv over `cols`
 * weights, singular value s. 0 ok, -1 if no choice keeps sigma' <= BTF__SIGMA_MAX. */
static int btf__choose_scale(btf_thesis_scale mode, double s, float mu, float mv, int rows, int cols, double *a,
                             double *c)
{
    double amax = 1.0 / mu, cmax = 1.0 / mv;
    if (mode != BTF_THESIS_SCALE_FIT) {
        *a = amax < 10.0 ? amax : 10.0;
        *c = 1.0;
        if (s / (*a * *c) > BTF__SIGMA_MAX)
            *c = s / (*a * BTF__SIGMA_MAX) * 1.0001;
        return *c <= cmax ? 0 : -1;
    }
    double best = INFINITY, h2 = (double)BTF__H * BTF__H / 3.0;
    for (int i = 0; i < BTF__GRID; i++)
        for (int m = 0; m < BTF__GRID; m++) {
            double ai = amax * exp2(-0.25 * i), cm = cmax * exp2(-0.25 * m), sp = s / (ai * cm);
            if (sp > BTF__SIGMA_MAX)
                continue;
            double e = ai * cm * btf__sigma_err(sp);
            double f = s * s * h2 * ((double)rows / (ai * ai) + (double)cols / (cm * cm)) + e * e;
            if (f < best)
                best = f, *a = ai, *c = cm;
        }
    return isfinite(best) ? 0 : -1;
}

static btf_result btf__check_source(const btf *src, const btf_export_options *o, btf_error *err)
{
    if (!src || !src->data)
        return btf_fail(err, BTF_ERR_ARG, "export-thesis: no source BTF");
    if (!btf_dirset_equal(&src->lights, &src->views))
        return btf_fail(err, BTF_ERR_UNSUPPORTED,
                        "export-thesis: the thesis format needs the same light and view directions (%d lights, %d views)",
                        src->lights.n_dirs, src->views.n_dirs);
    if (src->width != src->height || src->width % 2 || src->width > BTF_THESIS_MAX_S)
        return btf_fail(err, BTF_ERR_UNSUPPORTED,
                        "export-thesis: the thesis format needs a square texture of even side <= %d, got %dx%d",
                        BTF_THESIS_MAX_S, src->width, src->height);
    if (o->components < 1 || o->components > BTF_THESIS_MAX_C)
        return btf_fail(err, BTF_ERR_RANGE, "components C = %d: the thesis format holds 1..%d", o->components,
                        BTF_THESIS_MAX_C);
    if (o->scale < BTF_THESIS_SCALE_DEFAULT || o->scale > BTF_THESIS_SCALE_FIT)
        return btf_fail(err, BTF_ERR_ARG, "export-thesis: unknown scaling %d", (int)o->scale);
    return BTF_OK;
}

/* Copies block b of the model into p with the chosen scales. */
static btf_result btf__export_block(const btf_pca_model *m, int b, btf_thesis_scale mode, btf_thesis_pkg *p,
                                    btf_error *err)
{
    const btf_blocks *bl = m->blocks;
    const btf_pca_block *blk = &m->block[b];
    int C = p->C, N = p->N, S = p->S, n_in = bl->start[b + 1] - bl->start[b];
    for (int i = 0; i < n_in; i++)
        if (bl->views[bl->start[b] + i] != b * p->k + i)
            return btf_fail(err, BTF_ERR_ARG, "export-thesis: block %d is not k consecutive views", b);
    float *L = p->L + (size_t)b * S * S * C;
    for (int j = 0; j < C; j++) {
        const float *t = blk->t + (size_t)j * blk->rows, *w = blk->w + (size_t)j * blk->cols;
        double s = j == 0 ? 1.0 : blk->sigma[j], a = 1.0, c = 1.0;
        if (j > 0 && s > 0.0) {
            float mu = btf__absmax(t, (size_t)blk->rows), mv = btf__absmax(w, (size_t)blk->cols) / (float)s;
            if (!(mu > 0.0f) || !(mv > 0.0f) ||
                btf__choose_scale(mode, s, mu, mv, blk->rows, blk->cols, &a, &c) != 0)
                return btf_fail(err, BTF_ERR_RANGE,
                                "export-thesis: block %d component %d: singular value %g does not fit the format's "
                                "sigma <= %g",
                                b, j, s, (double)BTF__SIGMA_MAX);
        } else if (j > 0) {
            a = c = 0.0; /* rank-deficient: a zero component */
        }
        if (j == 0 && btf__absmax(t, (size_t)blk->rows) > 1.0f + 1e-5f)
            return btf_fail(err, BTF_ERR_RANGE, "export-thesis: block %d has a texel mean %g outside [-1, 1]", b,
                            (double)btf__absmax(t, (size_t)blk->rows));
        float fa = (float)a, fv = j == 0 ? 1.0f : (float)(c / s);
        for (int r = 0; r < blk->rows; r++) {
            float v = t[r] * fa;
            L[(size_t)r * C + j] = v > 1.0f ? 1.0f : v < -1.0f ? -1.0f : v;
        }
        for (int col = 0; col < blk->cols; col++) {
            int pos = col / (3 * N), rest = col % (3 * N); /* rest = light*3 + channel */
            float v = w[col] * fv;
            p->V[(((size_t)(b * p->k + pos) * N) * 3 + (size_t)rest) * C + j] = v > 1.0f ? 1.0f : v < -1.0f ? -1.0f : v;
        }
        p->sigma[(size_t)b * C + j] = j == 0 ? 1.0f : a > 0.0 ? (float)(s / (a * c)) : 0.0f;
    }
    return BTF_OK;
}

btf_result btf_export_thesis_model(const btf *src, const btf_export_options *opt, btf_thesis_pkg *out,
                                   btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "btf_export_thesis_model: NULL output");
    memset(out, 0, sizeof *out);
    btf_export_options o = {0};
    if (opt)
        o = *opt;
    o.k = o.k ? o.k : 3;
    o.components = o.components ? o.components : 8;
    btf_result r = btf__check_source(src, &o, err);
    if (r != BTF_OK)
        return r;
    btf_pca_options po = {0};
    po.k = o.k, po.components = o.components, po.method = o.method;
    po.grouping = BTF_GROUP_CONSECUTIVE, po.center = BTF_CENTER_ROW;
    po.clipped = BTF_CLIPPED_KEEP; /* the thesis method fits the samples as stored */
    po.rounding = BTF_ROUNDING_KEEP; /* and keeps every component */
    btf_pca_model *m = NULL;
    if ((r = btf_pca_compress(src, &po, NULL, NULL, &m, err)) != BTF_OK)
        return r;
    r = btf_thesis_alloc(o.components, src->views.n_dirs, o.k, src->width, out, err);
    for (int b = 0; r == BTF_OK && b < m->blocks->n_blocks; b++)
        r = btf__export_block(m, b, o.scale, out, err);
    btf_pca_model_free(m);
    if (r != BTF_OK)
        btf_thesis_free(out);
    return r;
}

float btf_export_thesis_bound(const btf_thesis_pkg *p, int view, int light, int x, int y)
{
    int b = view / p->k, C = p->C;
    const float *l = p->L + (((size_t)b * p->S + (size_t)y) * p->S + (size_t)x) * C;
    const float *s = p->sigma + (size_t)b * C;
    float worst = 0.0f;
    for (int c = 0; c < 3; c++) {
        const float *v = p->V + (((size_t)view * p->N + (size_t)light) * 3u + (size_t)c) * C;
        float acc = 0.0f;
        for (int j = 0; j < C; j++) {
            float al = fabsf(l[j]), av = fabsf(v[j]);
            acc += (al + BTF__H) * (s[j] + BTF__S) * (av + BTF__H) - al * s[j] * av;
        }
        worst = acc > worst ? acc : worst;
    }
    return worst;
}

long long btf_dir_bytes(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    long long total = 0;
    struct dirent *e;
    char path[4200];
    struct stat st;
    while ((e = readdir(d)) != NULL) {
        int n = snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (n > 0 && (size_t)n < sizeof path && stat(path, &st) == 0 && S_ISREG(st.st_mode))
            total += (long long)st.st_size;
    }
    closedir(d);
    return total;
}

/* Writes p to dir; an existing thesis package (meta.json and its images, nothing
 * else) is replaced only after the new one is complete, atomically. */
static btf_result btf__write_replacing(const char *dir, const btf_thesis_pkg *p, btf_error *err)
{
    char fresh[BTF_FS_PATH_MAX + 32];
    btf_result r = btf_fs_replaceable(dir, btf_thesis_owns_dir, NULL, err);
    if (r != BTF_OK)
        return r;
    snprintf(fresh, sizeof fresh, "%s.new-%ld", dir, (long)getpid());
    btf_fs_rmtree(fresh, NULL); /* this pid's own leftover */
    r = btf_thesis_write(fresh, p, err);
    if (r == BTF_OK)
        r = btf_fs_replace_dir(fresh, dir, btf_thesis_owns_dir, NULL, err);
    if (r != BTF_OK)
        btf_fs_rmtree(fresh, NULL);
    return r;
}

btf_result btf_export_thesis(const btf *src, const btf_export_options *opt, const char *dir,
                             btf_export_stats *stats, btf_error *err)
{
    if (!dir || !*dir || strlen(dir) > 4000)
        return btf_fail(err, BTF_ERR_ARG, "export-thesis: no or over-long output directory");
    double t0 = btf_seconds();
    btf_thesis_pkg p;
    btf_result r = btf_export_thesis_model(src, opt, &p, err);
    if (r != BTF_OK)
        return r;
    double t1 = btf_seconds();
    r = btf__write_replacing(dir, &p, err);
    btf_thesis_free(&p);
    if (stats) {
        stats->seconds_pca = t1 - t0;
        stats->seconds_write = btf_seconds() - t1;
        stats->bytes = r == BTF_OK ? btf_dir_bytes(dir) : 0;
    }
    return r;
}
