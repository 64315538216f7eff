/* btf_gl_fixed.c - per-draw light blend of the BTF_FIXED_LIGHT decoder (see btf_gl_fixed.h). */
#include "btf_gl_fixed.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "btf_common.h"
#include "btf_dirtab.h"

static const float btf__qmax[3] = {2047.0f, 2047.0f, 1023.0f};

/* The light's three samples, interpolated as btf_decode does (the package's table, else
 * the ring walk over the same triangles). */
static btf_interp btf__light_interp(const btf_gl_package *g, const float light[3])
{
    const btf_dirtab *t = g->src->dirtab[0];
    return t ? btf_dirtab_interp_vec(t, light) : btf_dirset_interp_vec(&g->lights, light);
}

btf_result btf_gl_fixed_create(btf_gl *gl, const btf_gl_package *g, btf_gl_fixed **out, btf_error *err)
{
    if (!gl || !g || !out)
        return btf_fail(err, BTF_ERR_ARG, "gl fixed light: NULL argument");
    *out = NULL;
    btf_gl_fixed *x = calloc(1, sizeof *x);
    if (!x)
        return btf_fail(err, BTF_ERR_NOMEM, "gl fixed light: out of memory");
    x->n_views = g->views.n_dirs;
    x->quads = (g->n_chunks + 3) / 4;
    x->codes = calloc((size_t)x->n_views * x->quads * 4, sizeof(uint32_t));
    x->lq = calloc((size_t)x->quads * 24, sizeof(float));
    if (!x->codes || !x->lq) {
        btf_gl_fixed_free(gl, x);
        return btf_fail(err, BTF_ERR_NOMEM, "gl fixed light: out of memory");
    }
    const btf_gl_api *f = btf_gl_fn(gl);
    GLint was = 0; /* the caller's binding on the active unit is kept */
    f->GetIntegerv(GL_TEXTURE_BINDING_2D, &was);
    f->GenTextures(1, &x->tex);
    f->BindTexture(GL_TEXTURE_2D, x->tex);
    f->TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32UI, x->n_views, x->quads, 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT, NULL);
    f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    f->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    f->BindTexture(GL_TEXTURE_2D, (GLuint)was);
    btf_result r = btf_gl_check(gl, "allocating the per-draw light weights", err);
    if (r != BTF_OK) {
        btf_gl_fixed_free(gl, x);
        return r;
    }
    *out = x;
    return BTF_OK;
}

void btf_gl_fixed_free(btf_gl *gl, btf_gl_fixed *x)
{
    if (!x)
        return;
    btf_gl_texture_free(gl, x->tex);
    free(x->codes);
    free(x->lq);
    free(x);
}

/* Slot s, channel c: the blended weights of every view into w (n_views), their range. */
static void btf__blend_channel(const btf_gl_package *g, btf_interp il, int s, int c, double *w, double *lo,
                               double *hi)
{
    *lo = 1e300, *hi = -1e300;
    for (int v = 0; v < g->views.n_dirs; v++) {
        double sum = 0.0;
        for (int e = 0; e < 3; e++)
            if (il.w[e] != 0.0f)
                sum += (double)il.w[e] * btf_gl_package_weight(g, s, il.idx[e], v, c);
        w[v] = sum;
        *lo = sum < *lo ? sum : *lo;
        *hi = sum > *hi ? sum : *hi;
    }
}

/* Slot s's three channels onto their per-draw grids, into x->codes and x->lq. */
static void btf__pack_slot(btf_gl_fixed *x, const btf_gl_package *g, btf_interp il, int s, double *w)
{
    static const int shift[3] = {0, 11, 22};
    for (int c = 0; c < 3; c++) {
        double lo, hi;
        btf__blend_channel(g, il, s, c, w, &lo, &hi);
        float flo = (float)lo, step = hi > lo ? (float)((hi - lo) / btf__qmax[c]) : 0.0f;
        x->lq[(s / 4) * 24 + c * 4 + s % 4] = flo;
        x->lq[(s / 4) * 24 + 12 + c * 4 + s % 4] = step;
        for (int v = 0; v < x->n_views; v++) {
            double q = step > 0.0f ? rint((w[v] - flo) / step) : 0.0; /* nearest on the grid the GPU reads */
            q = q < 0.0 ? 0.0 : q > btf__qmax[c] ? btf__qmax[c] : q;
            x->codes[((size_t)(s / 4) * x->n_views + v) * 4 + s % 4] |= (uint32_t)q << shift[c];
        }
    }
}

void btf_gl_fixed_blend(btf_gl_fixed *x, const btf_gl_package *g, const float light[3], int n_chunks)
{
    memset(x->codes, 0, (size_t)x->n_views * x->quads * 4 * sizeof(uint32_t));
    memset(x->lq, 0, (size_t)x->quads * 24 * sizeof(float));
    double *w = malloc((size_t)x->n_views * sizeof *w);
    int slots = btf_gl_package_slots(g, n_chunks);
    btf_interp il = btf__light_interp(g, light);
    for (int s = 0; w && s < slots; s++)
        btf__pack_slot(x, g, il, s, w);
    x->slots = w ? slots : 0;
    free(w);
    memcpy(x->light, light, sizeof x->light);
}

btf_result btf_gl_fixed_update(btf_gl *gl, btf_gl_fixed *x, const btf_gl_package *g, const float light[3],
                               int n_chunks, btf_error *err)
{
    if (!gl || !x || !g || !light)
        return btf_fail(err, BTF_ERR_ARG, "gl fixed light: NULL argument");
    int slots = btf_gl_package_slots(g, n_chunks);
    if (x->slots == slots && !memcmp(x->light, light, sizeof x->light))
        return BTF_OK;
    btf_gl_fixed_blend(x, g, light, n_chunks);
    if (!x->slots)
        return btf_fail(err, BTF_ERR_NOMEM, "gl fixed light: out of memory");
    const btf_gl_api *f = btf_gl_fn(gl);
    GLint was = 0;
    f->GetIntegerv(GL_TEXTURE_BINDING_2D, &was);
    f->BindTexture(GL_TEXTURE_2D, x->tex);
    f->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    f->TexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, x->n_views, x->quads, GL_RGBA_INTEGER, GL_UNSIGNED_INT, x->codes);
    f->BindTexture(GL_TEXTURE_2D, (GLuint)was);
    return btf_gl_check(gl, "uploading the per-draw light weights", err);
}

void btf_gl_fixed_bind(btf_gl *gl, const btf_gl_fixed *x, const btf_shader_program *prog, int unit)
{
    const btf_gl_api *f = btf_gl_fn(gl);
    GLint loc = f->GetUniformLocation(prog->id, "u_btf_lw");
    if (loc < 0)
        return;
    f->ActiveTexture((GLenum)(GL_TEXTURE0 + unit));
    f->BindTexture(GL_TEXTURE_2D, x->tex);
    f->Uniform1i(loc, unit);
    GLint lq = f->GetUniformLocation(prog->id, "u_btf_lq");
    if (lq >= 0)
        f->Uniform4fv(lq, 6 * x->quads, x->lq);
}

void btf_gl_fixed_quant_error(const btf_gl_fixed *x, const btf_gl_package *g, double *worst, double *rms)
{
    btf_gl_package_quant_error(g, worst, rms);
    double ew = 0.0, ev = 0.0; /* the largest channel's added worst case and variance */
    for (int c = 0; c < 3; c++) {
        double e = 0.0, v = 0.0;
        for (int s = 0; s < x->slots; s++) {
            const float *tq = g->tq + (s / 4) * 8;
            double tlo = tq[s % 4], tst = tq[4 + s % 4], dl = x->lq[(s / 4) * 24 + 12 + c * 4 + s % 4];
            double tmax = fmax(fabs(tlo), fabs(tlo + 65535.0 * tst));
            e += tmax * dl / 2 + tst * dl / 4;
            v += g->ms[4 * s] * dl * dl / 12.0;
        }
        ew = fmax(ew, e);
        ev = fmax(ev, v);
    }
    *worst += ew;
    *rms = sqrt(*rms * *rms + ev);
}
