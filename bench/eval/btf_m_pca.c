/* btf_m_pca.c - "pca" and "pca-q": adapters from the method interface to the
 * project's k-view block PCA (btf_pca.h) and its package (btf_package.h).
 * "pca" keeps the float model (bytes = float32 textures + weights); "pca-q" writes
 * an 8-bit package into a private temporary directory, reads it back and removes the
 * directory (bytes = the package's chunk files): what a client receives. */
#include "btf_method.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_package.h"
#include "btf_fs.h"
#include "btf_common.h"
#include "btf_decode.h"
#include "btf_blocks.h"

/* Clamps k to the view count and C to what the smallest block allows. */
static btf_result btf__pca_opts(const btf *src, btf_method_params *p, btf_pca_options *o, btf_error *err)
{
    int V = src->views.n_dirs;
    memset(o, 0, sizeof *o);
    if (p->k <= 0)
        p->k = 3;
    if (p->components <= 0)
        p->components = 8;
    o->k = p->k > V ? V : p->k;
    btf_blocks *bl = NULL;
    btf_result r = btf_blocks_group(&src->views, o->k, BTF_GROUP_DEFAULT, &bl, err);
    if (r != BTF_OK)
        return r;
    int smallest = V;
    for (int b = 0; b < bl->n_blocks; b++) {
        int n = bl->start[b + 1] - bl->start[b];
        smallest = n < smallest ? n : smallest;
    }
    btf_blocks_free(bl);
    long mn = (long)src->width * src->height, cols = 3L * src->lights.n_dirs * smallest;
    mn = cols < mn ? cols : mn;
    o->components = p->components > mn ? (int)mn : p->components;
    return BTF_OK;
}

static void btf__pca_free(void *impl)
{
    btf_pca_model_free(impl);
}

static btf_result btf__pca_encode(const btf *src, btf_model *m, btf_error *err)
{
    btf_pca_options o;
    btf_result r = btf__pca_opts(src, &m->params, &o, err);
    btf_pca_model *pm = NULL;
    if (r == BTF_OK)
        r = btf_pca_compress(src, &o, NULL, NULL, &pm, err);
    if (r == BTF_OK)
        m->impl = pm;
    return r;
}

static void btf__pca_decode(const btf_model *m, int x, int y, const float light[3], const float view[3],
                            float rgb[3])
{
    const btf_pca_model *pm = m->impl;
    btf_interp il = btf_dirset_interp_vec(&pm->lights, light);
    btf_interp iv = btf_dirset_interp_vec(&pm->views, view);
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    for (int a = 0; a < 3; a++)
        for (int e = 0; e < 3; e++) {
            float w = iv.w[a] * il.w[e];
            if (w == 0.0f)
                continue;
            for (int c = 0; c < 3; c++)
                rgb[c] += w * btf_pca_model_value(pm, iv.idx[a], il.idx[e], x, y, c, pm->n_comp);
        }
}

static size_t btf__pca_bytes(const btf_model *m)
{
    const btf_pca_model *pm = m->impl;
    size_t n = 0;
    for (int b = 0; b < pm->blocks->n_blocks; b++)
        n += ((size_t)pm->block[b].rows + pm->block[b].cols) * pm->block[b].n_comp * sizeof(float);
    return n;
}

static void btf__pca_cost(const btf_model *m, btf_method_cost *out)
{
    const btf_pca_model *pm = m->impl;
    /* up to 3 views: C textures each, and 3 lights x 3 channels x C weights */
    out->fetches = 3 * pm->n_comp * (1 + 9);
    out->flops = 3 * pm->n_comp * 2 * 9 + 200; /* + two interpolation walks */
}

const btf_method btf_method_pca = {
    "pca", "k-view block PCA (the project's codec), float model", 1,
    btf__pca_encode, btf__pca_decode, btf__pca_bytes, btf__pca_cost, btf__pca_free,
};

/* ---------------------------------------------------------------- pca-q */


static void btf__pkg_free(void *impl)
{
    btf_package_free(impl);
}

static btf_result btf__pkg_encode(const btf *src, btf_model *m, btf_error *err)
{
    btf_pca_options o;
    btf_result r = btf__pca_opts(src, &m->params, &o, err);
    if (r != BTF_OK)
        return r;
    const char *tmp = getenv("TMPDIR");
    char base[4096], out[4200];
    snprintf(base, sizeof base, "%s/btf-method-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(base))
        return btf_fail(err, BTF_ERR_IO, "pca-q: cannot create a temporary directory under %s",
                        tmp && *tmp ? tmp : "/tmp");
    snprintf(out, sizeof out, "%s/pkg", base);
    btf_package_options ko = {0};
    ko.bits = 8;
    ko.name = "method";
    btf_package *p = NULL;
    r = btf_package_compress(src, &o, &ko, out, NULL, err);
    if (r == BTF_OK)
        r = btf_package_read(out, 0, &p, err);
    btf_fs_rmtree(out, NULL);
    btf_fs_rmtree(base, NULL);
    if (r == BTF_OK)
        m->impl = p;
    return r;
}

static void btf__pkg_decode(const btf_model *m, int x, int y, const float light[3], const float view[3],
                            float rgb[3])
{
    const btf_package *p = m->impl;
    btf_decode_options o = {0};
    o.filter = BTF_FILTER_NEAREST;
    btf_decode(p, ((float)x + 0.5f) / (float)p->width, ((float)y + 0.5f) / (float)p->height, light, view, &o, rgb);
}

static size_t btf__pkg_bytes(const btf_model *m)
{
    const btf_package *p = m->impl;
    long long n = 0;
    for (int i = 0; i < p->n_chunks; i++)
        n += p->chunk[i].bytes;
    return (size_t)n;
}

static void btf__pkg_cost(const btf_model *m, btf_method_cost *out)
{
    const btf_package *p = m->impl;
    out->fetches = 3 * p->n_comp * (1 + 9);
    out->flops = 3 * p->n_comp * 2 * 9 + 200;
}

const btf_method btf_method_pca_q = {
    "pca-q", "k-view block PCA written as an 8-bit package and read back", 1,
    btf__pkg_encode, btf__pkg_decode, btf__pkg_bytes, btf__pkg_cost, btf__pkg_free,
};
