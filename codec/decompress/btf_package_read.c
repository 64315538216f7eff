/* btf_package_read.c - package reader: manifest, chunk files (headers checked
 * before decoding), level addressing and direct reconstruction. Format:
 * doc/package-format.md; manifest text: btf_manifest.c; decoder: btf_decode.c. */
#include "btf_package.h"
#include "btf_dirtab.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_color.h"
#include "btf_fs.h"
#include "btf_image.h"
#include "btf_lod.h"
#include "btf_manifest.h"
#include "btf_webp.h"
#include "btf_wtz.h"
#include "btf_common.h"
#include "btf_read.h"
#include "btf_lap.h"

/* ---------------------------------------------------------------- chunk files */

/* Every file is read through a btf_files (btf.h; NULL: the disk) under its path
 * "DIR/NAME", which the messages name. */

/* The file of chunk ci ending in ext; weights = 1: only names starting "wt-", 0: only others, -1: any. */
static const char *btf__chunk_file(const btf_chunk_info *ci, const char *ext, int weights)
{
    for (int i = 0; i < ci->n_files; i++) {
        size_t n = strlen(ci->files[i]), e = strlen(ext);
        if (n > e && !strcmp(ci->files[i] + n - e, ext) &&
            (weights < 0 || !strncmp(ci->files[i], "wt-", 3) == !!weights))
            return ci->files[i];
    }
    return NULL;
}


/* Version 4's wt-JJ-8.webp at path into a new *px (V*L*3 bytes, malloc'd): an RGB WebP
 * of L x V pixels (lossless, or lossy: its decode), pixel (l, v) holding index
 * (v*L + l)*3 + c as sample c. */
static btf_result btf__read_w8_webp(const btf_files *fs, const char *path, int L, int V, uint8_t **px,
                                    btf_error *err)
{
    size_t n = (size_t)V * L * 3, max = btf_wtz_max_bytes(V, L), nz = 0;
    char *z = NULL;
    *px = malloc(n);
    btf_result r = *px ? btf_fs_read_with(fs, path, max, &z, &nz, err) : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    if (r == BTF_OK)
        r = btf_webp_decode_rgb((const uint8_t *)z, nz, path, L, V, *px, err);
    free(z);
    if (r != BTF_OK)
        free(*px), *px = NULL;
    return r;
}

/* Coarse weights (doc/package-format.md section 5.2): an 8-bit grey PNG of 3L x V
 * pixels, or in version 4 an RGB WebP of L x V (wt-JJ-8.webp), Wt = lo +
 * wt8_step * step * q with the 16-bit [lo, step]. */
static btf_result btf__load_weights8(btf_package *p, const btf_files *fs, const char *dir, int i, const char *wf,
                                     float *wt, btf_error *err)
{
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    char path[4200];
    uint8_t *px = NULL;
    snprintf(path, sizeof path, "%s/%s", dir, wf);
    size_t nf = strlen(wf);
    btf_result r = p->version == 4 && nf > 7 && !strcmp(wf + nf - 7, "-8.webp")
                       ? btf__read_w8_webp(fs, path, L, V, &px, err)
                       : btf_image_read_with(fs, path, 3 * L, V, 1, 0, &px, err);
    if (r != BTF_OK)
        return r;
    for (size_t k = 0; k < (size_t)V * L * 3; k++) {
        const float *rg = p->chunk[i].wt_range + 2 * p->blocks->block_of_view[k / (3 * (size_t)L)];
        wt[k] = rg[0] + (float)p->chunk[i].wt8_step * rg[1] * (float)px[k];
    }
    if (p->version == 4 && (p->w8q || (p->w8q = calloc((size_t)p->n_chunks, sizeof *p->w8q)))) {
        p->w8q[i] = px; /* the component's wt-JJ-r.z is a residual over these */
        return BTF_OK;
    }
    free(px);
    return p->version == 4 ? btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path) : BTF_OK;
}


/* A weights file of coding kind (BTF_WTZ_*; a btf_wtz stream of rows x cols x 3
 * values, or a wt-JJ.webp) at path into a new *q (malloc'd, the caller frees it), the
 * file size checked against the stream's bound before reading; prev: NULL, or the
 * views' predecessors of wt-JJ.pz (btf_wtz_decode_kind). */
static btf_result btf__read_wtz(const btf_files *fs, const char *path, int kind, int rows, int cols, const int *prev,
                                uint16_t **q, btf_error *err)
{
    size_t n = (size_t)rows * cols * 3, max = btf_wtz_max_bytes(rows, cols);
    *q = NULL;
    long long sz = btf_fs_size_with(fs, path);
    if (sz < 0)
        return btf_fail(err, BTF_ERR_MISSING, "%s: missing", path);
    if (sz < 1 || (unsigned long long)sz > max)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %lld bytes, expected 1..%zu", path, sz, max);
    char *z = NULL;
    size_t nz = 0;
    uint16_t *v = malloc(n * sizeof *v);
    btf_result r = v ? btf_fs_read_with(fs, path, max, &z, &nz, err)
                     : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    if (r == BTF_OK)
        r = btf_wtz_decode_kind(kind, (const uint8_t *)z, nz, rows, cols, prev, v, path, err);
    free(z);
    if (r != BTF_OK)
        free(v);
    else
        *q = v;
    return r;
}

/* Versions 3 and 4: wt-JJ.z (doc/package-format.md section 9.3) or wt-JJ.pz (section
 * 5.4); version 3: wt-JJ.webp (section 5.5). kind: BTF_WTZ_*. */
static btf_result btf__load_weights_z(const btf_package *p, const btf_files *fs, const char *path, int i, int kind,
                                      float *wt, btf_error *err)
{
    int L = p->lights.n_dirs, V = p->views.n_dirs, pred = kind == BTF_WTZ_PZ;
    size_t nwt = (size_t)V * L * 3;
    uint16_t *q = NULL;
    int *prev = pred ? malloc((size_t)V * sizeof *prev) : NULL;
    if (pred && !prev)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    if (prev)
        btf_wtz_prev_views(p->blocks->block_of_view, V, prev);
    btf_result r = btf__read_wtz(fs, path, kind, V, L, prev, &q, err);
    free(prev);
    for (size_t k = 0; r == BTF_OK && k < nwt; k++)
        wt[k] = btf_package_dequant(p->chunk[i].wt_range + 2 * p->blocks->block_of_view[k / (3 * (size_t)L)], q[k]);
    free(q);
    return r;
}


/* Version 4: wt-JJ-r.z (doc/package-format.md section 5.3), the 16-bit weights as a
 * btf_wtz stream (one light per "view") of r = (q16 - s_c q8) mod 65536 over the
 * component's 8-bit weights, which an earlier chunk carried. */
static btf_result btf__load_weights_r(const btf_package *p, const btf_files *fs, const char *path, int i, float *wt,
                                      btf_error *err)
{
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    size_t nwt = (size_t)V * L * 3;
    const uint8_t *q8 = NULL;
    for (int e = 0; e < i && !q8; e++)
        if (p->chunk[e].component == p->chunk[i].component && p->w8q && p->w8q[e])
            q8 = p->w8q[e];
    if (!q8)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: residual weights, but no earlier chunk of component %d carries its 8-bit weights",
                        path, p->chunk[i].component);
    uint16_t *q = NULL;
    btf_result r = btf__read_wtz(fs, path, BTF_WTZ_Z, V * L, 1, NULL, &q, err);
    unsigned sc = (unsigned)p->chunk[i].wt8_step;
    for (size_t k = 0; r == BTF_OK && k < nwt; k++)
        wt[k] = btf_package_dequant(p->chunk[i].wt_range + 2 * p->blocks->block_of_view[k / (3 * (size_t)L)],
                                    (sc * q8[k] + q[k]) & 0xFFFFu);
    free(q);
    return r;
}

/* The file at path when it holds exactly n bytes (malloc'd into *file, the caller frees it). */
static btf_result btf__read_exact(const btf_files *fs, const char *path, size_t n, char **file, btf_error *err)
{
    size_t got = 0;
    long long sz = btf_fs_size_with(fs, path);
    *file = NULL;
    if (sz < 0)
        return btf_fail(err, BTF_ERR_MISSING, "%s: missing", path);
    if (sz != (long long)n)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %lld bytes, expected %zu", path, sz, n);
    btf_result r = btf_fs_read_with(fs, path, n, file, &got, err);
    if (r == BTF_OK && got != n) { /* it changed between the two looks */
        free(*file), *file = NULL;
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %zu bytes, expected %zu", path, got, n);
    }
    return r;
}

/* Weights of chunk i (dequantised) from its .bin (or version 3 .z) file into wt (V*L*3 floats). */
static btf_result btf__load_weights(const btf_package *p, const btf_files *fs, const char *dir, int i, const char *wf,
                                    float *wt, btf_error *err)
{
    const btf_chunk_info *ci = &p->chunk[i];
    int L = p->lights.n_dirs, V = p->views.n_dirs;
    size_t nwt = (size_t)V * L * 3;
    char path[4200], *file = NULL;
    snprintf(path, sizeof path, "%s/%s", dir, wf);
    size_t nf = strlen(wf);
    if (p->version == 3 && nf > 5 && !strcmp(wf + nf - 5, ".webp"))
        return btf__load_weights_z(p, fs, path, i, BTF_WTZ_WEBP, wt, err);
    if (p->version >= 3 && nf > 3 && !strcmp(wf + nf - 3, ".pz"))
        return btf__load_weights_z(p, fs, path, i, BTF_WTZ_PZ, wt, err);
    if (p->version == 3 || (p->version == 4 && nf > 2 && !strcmp(wf + nf - 2, ".z") &&
                            !(nf > 4 && !strcmp(wf + nf - 4, "-r.z"))))
        return btf__load_weights_z(p, fs, path, i, BTF_WTZ_Z, wt, err); /* version 4 may carry version 3's wt-JJ.z (section 5.3) */
    if (p->version == 4 && nf > 2 && !strcmp(wf + nf - 2, ".z"))
        return btf__load_weights_r(p, fs, path, i, wt, err);
    btf_result r = btf__read_exact(fs, path, 2 * nwt, &file, err);
    if (r != BTF_OK)
        return r;
    const uint8_t *raw = (const uint8_t *)file;
    for (size_t k = 0; k < nwt; k++) {
        int v = (int)(k / (3 * (size_t)L));
        wt[k] = btf_package_dequant(ci->wt_range + 2 * p->blocks->block_of_view[v], (unsigned)raw[2 * k] | ((unsigned)raw[2 * k + 1] << 8));
    }
    free(file);
    return BTF_OK;
}


/* Version 2: a chunk without weights reuses the latest weights of its component. */
static btf_result btf__shared_weights(const btf_package *p, int i, float *wt, btf_error *err)
{
    for (int e = i - 1; e >= 0; e--)
        if (p->chunk[e].component == p->chunk[i].component && p->wt[e]) {
            memcpy(wt, p->wt[e], (size_t)p->views.n_dirs * p->lights.n_dirs * 3 * sizeof(float));
            return BTF_OK;
        }
    return btf_fail(err, BTF_ERR_FORMAT, "chunk %d lists no .bin weights and no earlier chunk of component %d does",
                    i, p->chunk[i].component);
}


/* Version 4 (doc/package-format.md section 4.4): chunk i's atlas bytes *px, a residual
 * when its level is not the coarsest, replaced by the level they reconstruct over the
 * bytes of the component's next coarser level (an earlier chunk, already loaded),
 * On failure *px is the caller's to free (NULL when freed here). */
static btf_result btf__residual_level(btf_package *p, int i, const char *path, uint8_t **px, btf_error *err)
{
    const btf_chunk_info *ci = &p->chunk[i];
    if (!p->q8 && !(p->q8 = calloc((size_t)p->n_chunks, sizeof *p->q8)))
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    int l = ci->level;
    if (!btf_package_chunk_residual(p, i))
        return BTF_OK;
    int aw = p->atlas_cols * (p->width >> l), ah = p->atlas_rows * (p->height >> l), e = -1;
    for (int k = 0; k < i && e < 0; k++)
        if (p->chunk[k].component == ci->component && p->chunk[k].level == l + 1 && p->q8[k])
            e = k;
    if (e < 0) {
        free(*px);
        *px = NULL;
        return btf_fail(err, BTF_ERR_FORMAT, "%s: residual of level %d of component %d, but level %d of it is not loaded before",
                        path, l, ci->component, l + 1);
    }
    uint8_t *fine = malloc((size_t)aw * ah);
    btf_result r = fine ? btf_lap_decode(*px, p->q8[e], aw, ah, p->width >> l, p->height >> l, &ci->pred, fine, err)
                        : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    free(*px);
    *px = r == BTF_OK ? fine : NULL;
    if (r != BTF_OK)
        free(fine);
    return r;
}


/* Loads chunk i's texture (its level's size) and weights (dequantised). */
static btf_result btf__load_chunk(btf_package *p, const btf_files *fs, const char *dir, int i, btf_error *err)
{
    const btf_chunk_info *ci = &p->chunk[i];
    const char *tf = btf__chunk_file(ci, ".png", 0);
    if (!tf)
        tf = btf__chunk_file(ci, ".webp", 0); /* versions 3 and 4: a WebP (section 4) */
    if (!tf)
        tf = btf__chunk_file(ci, ".avif", 0); /* versions 3 and 4: an AVIF (section 4) */
    const char *wf = p->version == 3 ? btf__chunk_file(ci, ".z", 1) : btf__chunk_file(ci, ".bin", -1);
    if (!wf && p->version == 4)
        wf = btf__chunk_file(ci, ".z", 1);
    if (!wf && p->version >= 3)
        wf = btf__chunk_file(ci, ".pz", 1); /* versions 3 and 4: wt-JJ.pz (section 5.4) */
    if (!wf && p->version == 3)
        wf = btf__chunk_file(ci, ".webp", 1); /* version 3: wt-JJ.webp (section 5.5) */
    const char *w8 = btf_package_has_levels(p) && !wf ? btf__chunk_file(ci, ".png", 1) : NULL;
    if (!w8 && p->version == 4 && !wf)
        w8 = btf__chunk_file(ci, "-8.webp", 1); /* version 4: wt-JJ-8.webp (section 5.2) */
    char path[4200];
    if (!tf || (!wf && !btf_package_has_levels(p)))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d lists no .png, .webp or .avif texture or no %s weights", dir, i,
                        p->version == 3 ? "wt-*.z, wt-*.pz or wt-*.webp" : ".bin");
    int nb = p->blocks->n_blocks, W = p->width >> ci->level, H = p->height >> ci->level;
    int ch = p->bits == 16 ? 3 : 1, w = p->atlas_cols * W;
    uint8_t *px = NULL;
    snprintf(path, sizeof path, "%s/%s", dir, tf);
    btf_result r = btf_image_read_with(fs, path, w, p->atlas_rows * H, ch, 1, &px, err); /* a grey WebP as one */
    if (r != BTF_OK)
        return r;
    if (p->version == 4 && (r = btf__residual_level(p, i, path, &px, err)) != BTF_OK) {
        free(px); /* the caller's on failure (NULL when already freed) */
        return r;
    }
    float *tex = malloc((size_t)nb * W * H * sizeof(float));
    float *wt = malloc((size_t)p->views.n_dirs * p->lights.n_dirs * 3 * sizeof(float));
    if (!tex || !wt) {
        free(px), free(tex), free(wt);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    }
    for (int b = 0; b < nb; b++) {
        const float *rg = ci->tex_range + 2 * b;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                const uint8_t *q = px + ((size_t)((b / p->atlas_cols) * H + y) * w + (size_t)((b % p->atlas_cols) * W + x)) * ch;
                unsigned v = p->bits == 16 ? (unsigned)q[0] * 256u + q[1] : q[0];
                tex[((size_t)b * H + y) * W + x] = btf_package_dequant(rg, v);
            }
    }
    if (p->version == 4)
        p->q8[i] = px; /* the next finer level's residual is over these bytes */
    else
        free(px);
    r = wf ? btf__load_weights(p, fs, dir, i, wf, wt, err)
       : w8 ? btf__load_weights8(p, fs, dir, i, w8, wt, err)
            : btf__shared_weights(p, i, wt, err);
    if (r != BTF_OK) {
        free(tex), free(wt);
        if (p->q8)
            free(p->q8[i]), p->q8[i] = NULL;
        if (p->w8q)
            free(p->w8q[i]), p->w8q[i] = NULL;
        return r;
    }
    for (int e = 0; wf && e < i; e++) /* finer weights replace the coarse ones of earlier levels */
        if (p->chunk[e].component == ci->component)
            memcpy(p->wt[e], wt, (size_t)p->views.n_dirs * p->lights.n_dirs * 3 * sizeof(float));
    p->tex[i] = tex;
    p->wt[i] = wt;
    p->n_loaded = i + 1;
    return BTF_OK;
}


static int btf__chunk_present(const btf_package *p, const btf_files *fs, const char *dir, int i)
{
    char path[4200];
    for (int f = 0; f < p->chunk[i].n_files; f++) {
        snprintf(path, sizeof path, "%s/%s", dir, p->chunk[i].files[f]);
        if (btf_fs_size_with(fs, path) < 0)
            return 0;
    }
    return 1;
}


void btf_package_free(btf_package *p)
{
    if (!p)
        return;
    for (int i = 0; i < p->n_loaded; i++) {
        free(p->tex[i]);
        free(p->wt[i]);
    }
    for (int i = 0; i < p->n_chunks; i++) {
        if (p->q8)
            free(p->q8[i]);
        if (p->w8q)
            free(p->w8q[i]);
    }
    free(p->q8), free(p->w8q);
    btf_manifest_clear(p); /* and the direction tables */
    free(p);
}

btf_result btf_package_read(const char *dir, int n, btf_package **out, btf_error *err)
{
    return btf_package_read_with(dir, n, NULL, out, err);
}

btf_result btf_package_read_with(const char *dir, int n, const btf_files *files, btf_package **out, btf_error *err)
{
    return btf_package_read_opts(dir, n, files, NULL, out, err);
}

/* The direction tables the reader adds (those the manifest's triangles did not
 * give), unless o asks for none. */
static btf_result btf__read_dirtabs(btf_package *p, const btf_package_read_options *o, btf_error *err)
{
    btf_result r = BTF_OK;
    if (o && o->no_dirtab)
        return BTF_OK;
    if (!p->dirtab[0]) /* the decoder's direction tables, as the GPU gets them */
        r = btf_dirtab_build(&p->lights, &p->dirtab[0], err);
    if (r == BTF_OK && !p->dirtab[1])
        r = btf_dirtab_build(&p->views, &p->dirtab[1], err);
    return r;
}

btf_result btf_package_read_opts(const char *dir, int n, const btf_files *files, const btf_package_read_options *o,
                                 btf_package **out, btf_error *err)
{
    *out = NULL;
    if (!dir || strlen(dir) > 4000)
        return btf_fail(err, BTF_ERR_ARG, "package: no directory");
    btf_package *p = calloc(1, sizeof *p);
    if (!p)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    btf_result r = btf_manifest_load_with(dir, files, p, err);
    int nc = p->n_chunks;
    if (r == BTF_OK && n > nc)
        r = btf_fail(err, BTF_ERR_RANGE, "%s: %d chunks requested, the package has %d", dir, n, nc);
    int want = n == 0 ? nc : n;
    if (n < 0) {
        want = 0;
        while (r == BTF_OK && want < nc && btf__chunk_present(p, files, dir, want))
            want++;
        if (r == BTF_OK && want == 0)
            r = btf_fail(err, BTF_ERR_MISSING, "%s: the files of chunk 0 are missing", dir);
    }
    for (int i = 0; r == BTF_OK && i < want; i++)
        r = btf__load_chunk(p, files, dir, i, err);
    if (r == BTF_OK)
        r = btf__read_dirtabs(p, o, err);
    if (r != BTF_OK) {
        btf_package_free(p);
        return r;
    }
    *out = p;
    return BTF_OK;
}


/* ---------------------------------------------------------------- levels */

int btf_package_chunk_at(const btf_package *p, int n, int component, int level)
{
    if (n <= 0 || n > p->n_loaded)
        n = p->n_loaded;
    int best = -1, bd = 1 << 30;
    for (int i = 0; i < n; i++) {
        if (p->chunk[i].component != component)
            continue;
        int d = p->chunk[i].level - level;
        int score = d <= 0 ? -2 * d : 2 * d + 1; /* nearest; ties go to the finer level */
        if (score < bd)
            bd = score, best = i;
    }
    return best;
}

/* Bilinear value of a tile of w x h texels at continuous texel coordinate (fx, fy)
 * (texel centres at integers), clamped to the tile. */
static float btf__bilin(const float *tile, int w, int h, float fx, float fy)
{
    float x0f = floorf(fx), y0f = floorf(fy), ax = fx - x0f, ay = fy - y0f;
    int x0 = (int)x0f, y0 = (int)y0f;
    int xa = x0 < 0 ? 0 : x0 >= w ? w - 1 : x0, xb = x0 + 1 < 0 ? 0 : x0 + 1 >= w ? w - 1 : x0 + 1;
    int ya = y0 < 0 ? 0 : y0 >= h ? h - 1 : y0, yb = y0 + 1 < 0 ? 0 : y0 + 1 >= h ? h - 1 : y0 + 1;
    return (1.0f - ay) * ((1.0f - ax) * tile[(size_t)ya * w + xa] + ax * tile[(size_t)ya * w + xb]) +
           ay * ((1.0f - ax) * tile[(size_t)yb * w + xa] + ax * tile[(size_t)yb * w + xb]);
}

/* Level-l texel coordinate of the centre of level-0 texel x. */
static float btf__centre(int x, int l)
{
    return ((float)x + 0.5f) / (float)(1 << l) - 0.5f;
}

float btf_package_level_sample(const float *tile, int l, int w, int h, int x, int y)
{
    if (l == 0)
        return tile[(size_t)y * w + x];
    return btf__bilin(tile, w, h, btf__centre(x, l), btf__centre(y, l));
}

float btf_package_texel(const btf_package *p, int i, int b, int x, int y)
{
    int l = p->chunk[i].level, w = p->width >> l, h = p->height >> l;
    return btf_package_level_sample(p->tex[i] + (size_t)b * w * h, l, w, h, x, y);
}

/* ---------------------------------------------------------------- reconstruction */

void btf_package_to_source(const btf_package *p, float *v, size_t n)
{
    if (p->linear)
        btf_color_srgb_encode_n(v, n);
}

void btf_package_value(const btf_package *p, int view, int light, int x, int y, int n, float rgb[3])
{
    if (n <= 0 || n > p->n_loaded)
        n = p->n_loaded;
    int b = p->blocks->block_of_view[view];
    size_t ti = ((size_t)b * p->height + y) * p->width + x, wi = ((size_t)view * p->lights.n_dirs + light) * 3;
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    for (int j = 0; j < n; j++) {
        /* version 2: each component once, at its finest loaded level (upsampled) */
        if (p->n_levels > 1 && btf_package_chunk_at(p, n, p->chunk[j].component, 0) != j)
            continue;
        float t = p->n_levels > 1 ? btf_package_texel(p, j, b, x, y) : p->tex[j][ti];
        rgb[0] += t * p->wt[j][wi];
        rgb[1] += t * p->wt[j][wi + 1];
        rgb[2] += t * p->wt[j][wi + 2];
    }
    btf_package_to_source(p, rgb, 3);
}


btf_result btf_package_reconstruct(const btf_package *p, int n, btf **out, btf_error *err)
{
    btf *b = NULL;
    btf_result r = btf_create(p->width, p->height, &p->lights, &p->views, BTF_F32, &b, err);
    if (r != BTF_OK)
        return r;
    float *d = b->data;
    for (int v = 0; v < p->views.n_dirs; v++)
        for (int l = 0; l < p->lights.n_dirs; l++)
            for (int y = 0; y < p->height; y++)
                for (int x = 0; x < p->width; x++)
                    btf_package_value(p, v, l, x, y, n, d + btf_index(b, v, l, x, y, 0));
    *out = b;
    return BTF_OK;
}
