/* bench_lossy.c - lossy WebP for the component textures (issue 36 item 2, first idea),
 * measured against the default package (version 3: rate-distortion steps, lossless
 * WebP textures, deflated weights; btf_package_compress with rd = 1, k 3, C 8).
 *
 * Per material (one PCA, k 3, C 8, shared by all its packages):
 *   1. the default package at tex_noise T (LOSSY_NOISES; default 0.25 0.35 0.5 0.7 1
 *      1.4 2 2.8 4 5.6 8, at 128 texels a side and more 0.25 0.5 1 2 4 8 16; 0.5 is
 *      `btf compress`'s): bytes (chunk files + manifest) and CIELab error (the thesis's
 *      lab_mae as `btf eval` computes it: every chunk decoded, btf_metrics against the
 *      source over every (view, light) pair; at 128 texels a side and more on every
 *      LOSSY_STRIDE-th texel in x and y, default 3, with the T = 0.5 package also
 *      scored on every texel by btf eval's own path); the thesis format (k 3, C 8)
 *      as the reference, scored the same way;
 *   2. the textures of a package with full-range 8-bit steps (tex_noise 0.01), each
 *      component's atlas a lossy WebP at every quality of a ladder (libwebp, method 6,
 *      sns 0, filter 0, the grey written as the Y plane, U = V = 128): its bytes, its
 *      added squared error (sum over blocks of |step (q' - q)|^2 |W_j|^2, the unit of
 *      btf_rd.h's lambda) and its decoded atlas (R, as the browser client takes it);
 *   3. lossy variants: the weights (files and values) and manifest of the default
 *      package at T, every texture lossy, at one uniform quality or per component by
 *      one Lagrange multiplier over the measured ladders (equal slope), lambda swept
 *      around the default's own (its manifest's "rd" lambda; "one lambda": exactly
 *      it); each scored like the defaults;
 *   4. per default point: the bytes of the lossy variants' lower envelope at its
 *      CIELab error and the envelope's error at its bytes (log bytes linear in the
 *      error between the envelope's points); the same at the thesis format's error.
 * Then what it costs: the ladder's encoding time, libwebp's decoding time per atlas
 * (lossy against the default's lossless files), and whether the C reader takes a
 * lossy texture (printed; it does since the reader takes lossy WebP). LOSSY_STUDY=1 (default) first compares
 * encoder settings on the first material (sns, filter, method, the Y table, sharp
 * YUV, target_PSNR); LOSSY_DUMP=DIR writes its files for bench/lossy_browser.mjs.
 *
 * Materials: LOSSY_MATERIALS="NAME=SPEC ..." with SPEC gen:KIND:SIZE:SEED,
 * jpg:KIND:SIZE:SEED (generated, written as JPEG images and read back) or DIR@SIZE
 * (a thesis package or anything btf_load_any reads, at SIZE); default: tiles, knit,
 * stone, a JPEG stone at 64x64, the thesis wool and corduroy at 64x64 (when
 * $BTF_SHARED/data has them), tiles and the two thesis materials at 256x256; seeds
 * no test uses. About 45 minutes on the 2-core test machine (a 256x256 material 6-8
 * minutes, 8 GB peak: the thesis format's float decode).
 * LOSSY_TMP (default /tmp/btf-bench-lossy) holds the packages while a material runs.
 * Output: `name value unit` lines and `#` table rows (bench/run.sh: results/lossy.txt).
 */
#include "btf.h"
#include "btf_gen.h"
#include "btf_io.h"
#include "btf_metrics.h"
#include "btf_package.h"
#include "btf_pca.h"
#include "btf_blocks.h"
#include "btf_common.h"
#include "btf_fs.h"
#include "btf_compress.h"
#include "btf_export.h"
#include "btf_source.h"
#include "btf_webp.h"

#include <cjson/cJSON.h>
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <webp/decode.h>
#include <webp/encode.h>

#include "bench_util.h"

#define LOSSY_MAX_T 12  /* default packages per material */
#define LOSSY_MAX_Q 16  /* qualities on the ladder */
#define LOSSY_MAX_PTS 512
#define LOSSY_K 3
#define LOSSY_C 8
#define LOSSY_FINE 0.01f /* tex_noise of the package the lossy textures start from */

static const int g_quality[] = {0, 10, 20, 35, 50, 60, 70, 78, 85, 90, 94, 97, 100};
static const int g_uniform[] = {50, 70, 85, 94, 100};
#define LOSSY_NQ ((int)(sizeof g_quality / sizeof g_quality[0]))
#define LOSSY_NU ((int)(sizeof g_uniform / sizeof g_uniform[0]))
#define LOSSY_NL 9 /* lambdas: the default's times 2^-4 .. 2^4 */

/* Encoder settings of one lossy WebP variant; plain value (static tables and copies). */
typedef struct lossy_cfg {
    const char *name;
    int method, sns, filter, autofilter, sharp;
    int ytable;        /* 1: Y plane written from the q -> Y table (U = V = 128); 0: WebPPictureImportRGB */
    float target_psnr; /* > 0: libwebp's target_PSNR search (pass 6) instead of the quality */
} lossy_cfg;

/* The settings the variants use (the study's winner on the materials measured). */
static const lossy_cfg g_cfg = {"m6-sns0-f0-ytab", 6, 0, 0, 0, 0, 1, 0.0f};

/* The reference of the CIELab error: the source at a texel subsample, RGB and Lab per
 * (view, light) image; owned by one material's run (labref_free). */
typedef struct labref {
    const btf *src;
    int stride, n_sub, n_img;
    int *texel;       /* n_sub texel indices y * W + x */
    float *rgb, *lab; /* n_img x n_sub x 3 */
} labref;

/* A package read back, with what the variants need of it; owned by one material's
 * run (pkg_clear). */
typedef struct pkg {
    float noise;
    btf_package *p;
    long long bytes, manifest_bytes, wt_bytes, tex_bytes;
    double lab, secs, lambda;
    int chunk_of[LOSSY_C]; /* chunk index of component c */
    char dir[1100];
} pkg;

/* The lossy ladder of one material: per component and quality the file, its bytes, the
 * squared error it adds and its decoded atlas; owned by one run (ladder_free). */
typedef struct ladder {
    int C, nq, nb, W, H, cols, aw, ah;
    long long bytes[LOSSY_C][LOSSY_MAX_Q];
    double d[LOSSY_C][LOSSY_MAX_Q];
    double sse[LOSSY_C][LOSSY_MAX_Q];    /* sum over the used texels of (q' - q)^2 */
    uint8_t *file[LOSSY_C][LOSSY_MAX_Q]; /* the WebP files (malloc'd) */
    uint8_t *dec[LOSSY_C][LOSSY_MAX_Q];  /* decoded atlases aw x ah (malloc'd; NULL in the study) */
    uint8_t *fine[LOSSY_C];              /* the full-range atlases (malloc'd) */
    float *range[LOSSY_C];               /* nb x {lo, step} of the fine atlases (malloc'd) */
    double w2[LOSSY_C][64 * 64];         /* |W_c[b]|^2 per block (nb <= 4096) */
    double enc_cpu, dec_cpu;             /* seconds over the ladder */
    long long n_enc, pixels_rg;          /* encodes; decoded pixels with R != G */
} ladder;

/* One measured variant: bytes and CIELab, what made it; plain value. */
typedef struct point {
    double bytes, lab;
    float wnoise;  /* the default package whose weights it has */
    int kind;      /* 0 uniform quality, 1 lambda, 2 the default's own lambda */
    double param;  /* quality or lambda */
    int q[LOSSY_C]; /* per component its rung (index into g_quality) */
} point;

static char g_tmp[1024];

/* CPU seconds of the calling thread (the ladder's encodes run two at a time). */
static double cpu_thread_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static int env_int(const char *name, int def)
{
    const char *s = getenv(name);
    return s && *s ? atoi(s) : def;
}

static int fail(const char *what, const btf_error *err)
{
    fprintf(stderr, "bench_lossy: %s: %s\n", what, err->msg);
    return 1;
}

/* ---------------------------------------------------------------- materials */

/* jpg:KIND:SIZE:SEED: generated, written as JPEG images into g_tmp and read back. */
static btf_result load_jpg(const char *spec, btf **out, btf_error *err)
{
    char kind[32];
    int size = 0;
    unsigned seed = 0;
    if (sscanf(spec, "jpg:%31[a-z]:%d:%u", kind, &size, &seed) != 3 || btf_gen_kind_from_name(kind) < 0)
        return btf_fail(err, BTF_ERR_ARG, "%s: expected jpg:KIND:SIZE:SEED", spec);
    btf_gen_params gp = btf_gen_defaults((btf_gen_kind)btf_gen_kind_from_name(kind));
    gp.seed = seed;
    btf_dirset d = btf_dirset_ubo2003();
    btf *b = NULL;
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/jpg-src", g_tmp);
    btf_result r = btf_gen_create(&gp, size, size, &d, &d, BTF_U8, &b, err);
    if (r == BTF_OK)
        r = btf_save_ubo2003_dir(b, dir, "GenJpg", "jpg", err);
    btf_free(b);
    btf_load_options o = {0};
    if (r == BTF_OK)
        r = btf_load_any(dir, &o, out, err);
    btf_fs_rmtree(dir, NULL);
    return r;
}

/* The source a SPEC names (see the header). */
static btf_result load_material(const char *spec, btf **out, btf_error *err)
{
    if (!strncmp(spec, "jpg:", 4))
        return load_jpg(spec, out, err);
    const char *at = strrchr(spec, '@');
    if (strncmp(spec, "gen:", 4) && at) {
        char dir[1024];
        snprintf(dir, sizeof dir, "%.*s", (int)(at - spec), spec);
        btf_load_options o = {0};
        o.width = o.height = atoi(at + 1);
        return btf_load_any(dir, &o, out, err);
    }
    return btf_source_load(spec, NULL, out, err);
}

/* ---------------------------------------------------------------- CIELab error */

static void labref_free(labref *r)
{
    free(r->texel), free(r->rgb), free(r->lab);
    memset(r, 0, sizeof *r);
}

/* The source's samples at every stride-th texel, and their Lab, image by image. */
static int labref_init(labref *r, const btf *src, int stride)
{
    memset(r, 0, sizeof *r);
    r->src = src, r->stride = stride;
    r->n_img = src->views.n_dirs * src->lights.n_dirs;
    int sw = (src->width + stride - 1) / stride, sh = (src->height + stride - 1) / stride;
    r->n_sub = sw * sh;
    size_t n = (size_t)r->n_img * r->n_sub * 3;
    r->texel = malloc(sizeof(int) * (size_t)r->n_sub);
    r->rgb = malloc(n * sizeof(float)), r->lab = malloc(n * sizeof(float));
    if (!r->texel || !r->rgb || !r->lab)
        return -1;
    for (int y = 0, i = 0; y < src->height; y += stride)
        for (int x = 0; x < src->width; x += stride)
            r->texel[i++] = y * src->width + x;
#pragma omp parallel
    {
        float *img = malloc(btf_image_samples(src) * sizeof(float));
#pragma omp for schedule(static)
        for (int i = 0; i < r->n_img; i++) {
            float *dst = r->rgb + (size_t)i * r->n_sub * 3;
            btf_get_image(src, i / src->lights.n_dirs, i % src->lights.n_dirs, img);
            for (int s = 0; s < r->n_sub; s++)
                memcpy(dst + 3 * s, img + 3 * (size_t)r->texel[s], 3 * sizeof(float));
            btf_metrics_lab(dst, (size_t)r->n_sub, r->lab + (size_t)i * r->n_sub * 3);
        }
        free(img);
    }
    return 0;
}

/* One image's decode at the subsample: components order[0..C-1], texture tex[c]
 * (nb x W x H), weights wt[c] (V x L x 3), summed in that order as btf_package_value. */
static void lab_image(const labref *r, const btf_blocks *bl, int C, const int *order, float *const *tex,
                      float *const *wt, int img, float *test)
{
    int L = r->src->lights.n_dirs, v = img / L, l = img % L, b = bl->block_of_view[v];
    size_t plane = (size_t)r->src->width * r->src->height, wi = ((size_t)v * L + l) * 3;
    for (int s = 0; s < r->n_sub; s++) {
        float rgb[3] = {0.0f, 0.0f, 0.0f};
        for (int a = 0; a < C; a++) {
            int c = order[a];
            float t = tex[c][(size_t)b * plane + (size_t)r->texel[s]];
            rgb[0] += t * wt[c][wi], rgb[1] += t * wt[c][wi + 1], rgb[2] += t * wt[c][wi + 2];
        }
        memcpy(test + 3 * s, rgb, sizeof rgb);
    }
}

/* CIELab error (btf_metrics.lab_thesis) of a model against r. */
static double lab_eval(const labref *r, const btf_blocks *bl, int C, const int *order, float *const *tex,
                       float *const *wt)
{
    btf_metrics_acc *acc = calloc((size_t)r->n_img, sizeof *acc);
    if (!acc)
        return NAN;
#pragma omp parallel
    {
        float *test = malloc((size_t)r->n_sub * 3 * sizeof(float));
#pragma omp for schedule(static)
        for (int i = 0; i < r->n_img; i++) {
            lab_image(r, bl, C, order, tex, wt, i, test);
            size_t o = (size_t)i * r->n_sub * 3;
            btf_metrics_add_lab(&acc[i], r->rgb + o, r->lab + o, test, (size_t)r->n_sub);
        }
        free(test);
    }
    btf_metrics_acc all = {0};
    for (int i = 0; i < r->n_img; i++)
        btf_metrics_merge(&all, &acc[i]);
    free(acc);
    btf_metrics m;
    btf_metrics_finish(&all, &m);
    return m.lab_thesis;
}

/* ---------------------------------------------------------------- packages */

static void pkg_clear(pkg *k)
{
    btf_package_free(k->p);
    if (k->dir[0])
        btf_fs_rmtree(k->dir, NULL);
    memset(k, 0, sizeof *k);
}

/* The "rd" record's lambda (0 when absent). */
static double rd_lambda(const btf_package *p)
{
    cJSON *j = p->rd ? cJSON_Parse(p->rd) : NULL;
    cJSON *l = j ? cJSON_GetObjectItemCaseSensitive(j, "lambda") : NULL;
    double v = cJSON_IsNumber(l) ? l->valuedouble : 0.0;
    cJSON_Delete(j);
    return v;
}

/* Bytes of the package's files by kind (texture, weights), its manifest and in all. */
static void pkg_bytes(pkg *k)
{
    char path[1300];
    snprintf(path, sizeof path, "%s/manifest.json", k->dir);
    k->manifest_bytes = btf_fs_size(path);
    k->wt_bytes = k->tex_bytes = 0;
    for (int i = 0; i < k->p->n_chunks; i++)
        for (int f = 0; f < k->p->chunk[i].n_files; f++) {
            const char *n = k->p->chunk[i].files[f];
            snprintf(path, sizeof path, "%s/%s", k->dir, n);
            *(strncmp(n, "tex-", 4) ? &k->wt_bytes : &k->tex_bytes) += btf_fs_size(path);
        }
    k->bytes = k->manifest_bytes + k->wt_bytes + k->tex_bytes;
}

/* The package's components in stream order, and each component's chunk. */
static void pkg_order(const pkg *k, int *order)
{
    for (int i = 0; i < k->p->n_chunks; i++)
        order[i] = k->p->chunk[i].component;
}

/* Compresses src as the default would (version 3: rd, k 3, C 8, 8 bits; no thumbnail)
 * with tex_noise noise, the PCA model shared through *model (one PCA for all of a
 * material's packages), reads it back, counts its bytes and its CIELab error on r. */
static int pkg_make(const btf *src, const labref *r, float noise, btf_pca_model **model, const char *tag, pkg *k)
{
    memset(k, 0, sizeof *k);
    k->noise = noise;
    snprintf(k->dir, sizeof k->dir, "%s/%s", g_tmp, tag);
    btf_pca_options po = {0};
    po.k = LOSSY_K, po.components = LOSSY_C;
    btf_package_options ko = {0};
    ko.bits = 8, ko.tex_noise = noise, ko.rd = 1;
    btf_package_channel ch = {0};
    ch.rd_model = model;
    btf_error err = {0};
    double t0 = now_s();
    if (btf_package_compress_with(src, &po, &ko, &ch, k->dir, NULL, &err) != BTF_OK)
        return fail("compress", &err);
    k->secs = now_s() - t0;
    if (btf_package_read(k->dir, 0, &k->p, &err) != BTF_OK)
        return fail("read", &err);
    if (k->p->n_chunks != LOSSY_C || k->p->n_levels != 1 || k->p->linear)
        return fprintf(stderr, "bench_lossy: %s: unexpected package\n", k->dir), 1;
    for (int i = 0; i < LOSSY_C; i++)
        k->chunk_of[k->p->chunk[i].component] = i;
    pkg_bytes(k);
    k->lambda = rd_lambda(k->p);
    int order[LOSSY_C];
    pkg_order(k, order);
    float *tex[LOSSY_C], *wt[LOSSY_C];
    for (int c = 0; c < LOSSY_C; c++)
        tex[c] = k->p->tex[k->chunk_of[c]], wt[c] = k->p->wt[k->chunk_of[c]];
    k->lab = lab_eval(r, k->p->blocks, LOSSY_C, order, tex, wt);
    return 0;
}

/* btf eval's own path (btf_package_reconstruct + btf_compare) on the package: a check of
 * lab_eval at stride 1. */
static double eval_reference(const btf *src, const pkg *k)
{
    btf *rec = NULL;
    btf_error err = {0};
    btf_metrics m = {0};
    if (btf_package_reconstruct(k->p, 0, &rec, &err) != BTF_OK || btf_compare(src, rec, NULL, &m, &err) != BTF_OK)
        m.lab_thesis = NAN;
    btf_free(rec);
    return m.lab_thesis;
}

/* ---------------------------------------------------------------- lossy WebP */

/* The q -> Y table of the library's lossy encoder (btf_webp_y_of_q). */
static void y_table(uint8_t tab[256])
{
    for (int q = 0; q < 256; q++)
        tab[q] = (uint8_t)btf_webp_y_of_q(q);
}

/* pic as YUV 4:2:0: Y from the table, U = V = 128. 0 on failure. */
static int import_ytable(WebPPicture *pic, const uint8_t *grey, int w, int h)
{
    static uint8_t tab[256];
    static int ready;
    if (!ready) /* filled before the threads start (study and ladder call it once first) */
        y_table(tab), ready = 1;
    pic->use_argb = 0, pic->colorspace = WEBP_YUV420;
    if (!WebPPictureAlloc(pic))
        return 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            pic->y[(size_t)y * pic->y_stride + x] = tab[grey[(size_t)y * w + x]];
    for (int y = 0; y < (h + 1) / 2; y++) {
        memset(pic->u + (size_t)y * pic->uv_stride, 128, (size_t)(w + 1) / 2);
        memset(pic->v + (size_t)y * pic->uv_stride, 128, (size_t)(w + 1) / 2);
    }
    return 1;
}

/* pic from grey replicated into RGB (libwebp's own RGB -> YUV). 0 on failure. */
static int import_rgb(WebPPicture *pic, const uint8_t *grey, int w, int h)
{
    uint8_t *rgb = malloc((size_t)w * h * 3);
    if (!rgb)
        return 0;
    for (size_t i = 0; i < (size_t)w * h; i++)
        rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = grey[i];
    pic->use_argb = 1; /* converted to YUV by WebPEncode, as the config says (sharp YUV or not) */
    int ok = WebPPictureImportRGB(pic, rgb, 3 * w);
    free(rgb);
    return ok;
}

/* 1 when cfg is the library's lossy encoder (btf_webp_encode_grey_lossy). */
static int cfg_is_library(const lossy_cfg *cfg)
{
    return cfg->method == 6 && cfg->sns == 0 && cfg->filter == 0 && !cfg->autofilter && !cfg->sharp && cfg->ytable &&
           !(cfg->target_psnr > 0.0f);
}

/* Encodes grey (w x h) as a lossy WebP at quality q with cfg (the library's encoder
 * when cfg is its settings and q a whole number); *out malloc'd. 0 on failure. */
static int webp_lossy(const uint8_t *grey, int w, int h, const lossy_cfg *cfg, float q, uint8_t **out, size_t *n)
{
    if (cfg_is_library(cfg) && q == rintf(q)) {
        btf_error err = {0};
        return btf_webp_encode_grey_lossy(grey, w, h, (int)q, out, n, &err) == BTF_OK;
    }
    WebPConfig c;
    WebPPicture pic;
    if (!WebPConfigInit(&c) || !WebPPictureInit(&pic))
        return 0;
    c.quality = q, c.method = cfg->method, c.sns_strength = cfg->sns, c.filter_strength = cfg->filter;
    c.autofilter = cfg->autofilter, c.use_sharp_yuv = cfg->sharp;
    if (cfg->target_psnr > 0.0f)
        c.target_PSNR = cfg->target_psnr, c.pass = 6;
    pic.width = w, pic.height = h;
    int ok = cfg->ytable ? import_ytable(&pic, grey, w, h) : import_rgb(&pic, grey, w, h);
    WebPMemoryWriter mw;
    WebPMemoryWriterInit(&mw);
    pic.writer = WebPMemoryWrite, pic.custom_ptr = &mw;
    ok = ok && WebPEncode(&c, &pic);
    WebPPictureFree(&pic);
    *out = ok ? malloc(mw.size) : NULL;
    if (*out)
        memcpy(*out, mw.mem, mw.size), *n = mw.size;
    WebPMemoryWriterClear(&mw);
    return *out != NULL;
}

/* Decodes a WebP into grey (its R, as the browser's client takes it); counts the
 * pixels whose G differs from R into *rg. 0 on failure. */
static int webp_grey(const uint8_t *file, size_t n, int w, int h, uint8_t *grey, long long *rg)
{
    int dw = 0, dh = 0;
    uint8_t *rgb = WebPDecodeRGB(file, n, &dw, &dh);
    if (!rgb || dw != w || dh != h) {
        WebPFree(rgb);
        return 0;
    }
    for (size_t i = 0; i < (size_t)w * h; i++) {
        grey[i] = rgb[3 * i];
        *rg += rgb[3 * i + 1] != rgb[3 * i] || rgb[3 * i + 2] != rgb[3 * i];
    }
    WebPFree(rgb);
    return 1;
}

/* ---------------------------------------------------------------- the ladder */

static void ladder_free(ladder *g)
{
    for (int c = 0; c < LOSSY_C; c++) {
        free(g->fine[c]), free(g->range[c]);
        for (int i = 0; i < LOSSY_MAX_Q; i++)
            free(g->file[c][i]), free(g->dec[c][i]);
    }
    free(g);
}

/* Component c's full-range atlas from the version-1 package (q recovered from its
 * dequantised texels); unused tiles hold the used ones' mean (flat: nearly free). */
static int ladder_fine(ladder *g, const pkg *f, int c)
{
    const btf_chunk_info *ci = &f->p->chunk[f->chunk_of[c]];
    const float *t = f->p->tex[f->chunk_of[c]];
    g->fine[c] = calloc((size_t)g->aw * g->ah, 1);
    g->range[c] = malloc(sizeof(float) * 2 * (size_t)g->nb);
    if (!g->fine[c] || !g->range[c])
        return -1;
    memcpy(g->range[c], ci->tex_range, sizeof(float) * 2 * (size_t)g->nb);
    double sum = 0.0;
    for (int b = 0; b < g->nb; b++) {
        const float *rg = ci->tex_range + 2 * b;
        for (int y = 0; y < g->H; y++)
            for (int x = 0; x < g->W; x++) {
                float v = t[((size_t)b * g->H + y) * g->W + x];
                float qf = rg[1] > 0.0f ? rintf((v - rg[0]) / rg[1]) : 0.0f;
                uint8_t q = qf <= 0.0f ? 0 : qf >= 255.0f ? 255 : (uint8_t)qf;
                g->fine[c][(size_t)((b / g->cols) * g->H + y) * g->aw + (size_t)((b % g->cols) * g->W + x)] = q;
                sum += q;
            }
    }
    uint8_t mean = (uint8_t)lrint(sum / ((double)g->nb * g->W * g->H));
    for (int b = g->nb; b < g->cols * (g->ah / g->H); b++)
        for (int y = 0; y < g->H; y++)
            memset(g->fine[c] + (size_t)((b / g->cols) * g->H + y) * g->aw + (size_t)(b % g->cols) * g->W, mean,
                   (size_t)g->W);
    return 0;
}

/* |W_c[b]|^2 of every block from the version-1 package's 16-bit weights. */
static void ladder_w2(ladder *g, const pkg *f, int c)
{
    const btf_package *p = f->p;
    const float *wt = p->wt[f->chunk_of[c]];
    int L = p->lights.n_dirs;
    for (int b = 0; b < g->nb; b++) {
        double s = 0.0;
        for (int i = p->blocks->start[b]; i < p->blocks->start[b + 1]; i++)
            for (int j = 0; j < 3 * L; j++) {
                double w = wt[(size_t)p->blocks->views[i] * 3 * L + j];
                s += w * w;
            }
        g->w2[c][b] = s;
    }
}

/* The squared error (byte/255 scale, every sample) that dec adds to component c; the
 * atlas's own (q units, used tiles) into *sse. */
static double ladder_dist(const ladder *g, int c, const uint8_t *dec, double *sse)
{
    double d = 0.0;
    *sse = 0.0;
    for (int b = 0; b < g->nb; b++) {
        double s = 0.0, st = g->range[c][2 * b + 1];
        for (int y = 0; y < g->H; y++) {
            size_t o = (size_t)((b / g->cols) * g->H + y) * g->aw + (size_t)(b % g->cols) * g->W;
            for (int x = 0; x < g->W; x++) {
                double e = (double)dec[o + x] - (double)g->fine[c][o + x];
                s += e * e;
            }
        }
        d += s * st * st * g->w2[c][b];
        *sse += s;
    }
    return d;
}

static ladder *ladder_new(const pkg *f)
{
    ladder *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    const btf_package *p = f->p;
    g->C = LOSSY_C, g->nb = p->blocks->n_blocks, g->W = p->width, g->H = p->height, g->cols = p->atlas_cols;
    g->aw = p->atlas_cols * p->width, g->ah = p->atlas_rows * p->height;
    if (g->nb > 64 * 64) {
        free(g);
        return NULL;
    }
    for (int c = 0; c < LOSSY_C; c++) {
        if (ladder_fine(g, f, c)) {
            ladder_free(g);
            return NULL;
        }
        ladder_w2(g, f, c);
    }
    return g;
}

/* Encodes, decodes and measures rung (c, i) at quality q with cfg; keep: the decoded
 * atlas stays. 0 ok. */
static int ladder_rung(ladder *g, const lossy_cfg *cfg, int c, int i, float q, int keep)
{
    size_t n = 0;
    uint8_t *dec = malloc((size_t)g->aw * g->ah);
    long long rg = 0;
    double t0 = cpu_thread_s();
    int ok = dec && webp_lossy(g->fine[c], g->aw, g->ah, cfg, q, &g->file[c][i], &n);
    double t1 = cpu_thread_s();
    ok = ok && webp_grey(g->file[c][i], n, g->aw, g->ah, dec, &rg);
    double t2 = cpu_thread_s();
    if (!ok) {
        free(dec);
        return -1;
    }
    g->bytes[c][i] = (long long)n, g->d[c][i] = ladder_dist(g, c, dec, &g->sse[c][i]);
#pragma omp critical
    {
        g->enc_cpu += t1 - t0, g->dec_cpu += t2 - t1, g->n_enc++, g->pixels_rg += rg;
    }
    if (keep)
        g->dec[c][i] = dec;
    else
        free(dec);
    return 0;
}

/* Every component at every quality of qs (n of them) with cfg. 0 ok. */
static int ladder_run(ladder *g, const lossy_cfg *cfg, const int *qs, int n, int keep)
{
    int bad = 0;
    g->nq = n;
    if (cfg->ytable) { /* import_ytable's table filled here, before the threads */
        WebPPicture pic;
        WebPPictureInit(&pic);
        pic.width = pic.height = 16;
        uint8_t z[256] = {0};
        import_ytable(&pic, z, 16, 16);
        WebPPictureFree(&pic);
    }
#pragma omp parallel for schedule(dynamic) reduction(| : bad)
    for (int k = 0; k < g->C * n; k++)
        bad |= ladder_rung(g, cfg, k / n, k % n, (float)qs[k % n], keep) != 0;
    return bad ? -1 : 0;
}

/* Frees the rungs' files and decodes (for a second run with other settings). */
static void ladder_reset(ladder *g)
{
    for (int c = 0; c < LOSSY_C; c++)
        for (int i = 0; i < LOSSY_MAX_Q; i++) {
            free(g->file[c][i]), free(g->dec[c][i]);
            g->file[c][i] = g->dec[c][i] = NULL;
        }
    g->enc_cpu = g->dec_cpu = 0.0, g->n_enc = g->pixels_rg = 0;
}

/* ---------------------------------------------------------------- allocations */

/* Per component the rung minimising D + lambda R. */
static void alloc_lambda(const ladder *g, double lambda, int *q)
{
    for (int c = 0; c < g->C; c++) {
        int best = 0;
        for (int i = 1; i < g->nq; i++)
            if (g->d[c][i] + lambda * (double)g->bytes[c][i] < g->d[c][best] + lambda * (double)g->bytes[c][best])
                best = i;
        q[c] = best;
    }
}

/* Rung index of quality v on the ladder (-1 if absent). */
static int rung_of(int v)
{
    for (int i = 0; i < LOSSY_NQ; i++)
        if (g_quality[i] == v)
            return i;
    return -1;
}

/* Bytes and CIELab of the package with w's weights and the textures at rungs q. */
static point variant_eval(const ladder *g, const labref *r, const pkg *w, const int *q, float **tex)
{
    point pt = {0};
    pt.wnoise = w->noise;
    memcpy(pt.q, q, sizeof pt.q);
    pt.bytes = (double)(w->manifest_bytes + w->wt_bytes);
    float *wt[LOSSY_C];
    for (int c = 0; c < g->C; c++) {
        const uint8_t *dec = g->dec[c][q[c]];
        pt.bytes += (double)g->bytes[c][q[c]];
        wt[c] = w->p->wt[w->chunk_of[c]];
        for (int b = 0; b < g->nb; b++) {
            const float *rg = g->range[c] + 2 * b;
            for (int y = 0; y < g->H; y++)
                for (int x = 0; x < g->W; x++) {
                    uint8_t v = dec[(size_t)((b / g->cols) * g->H + y) * g->aw + (size_t)((b % g->cols) * g->W + x)];
                    tex[c][((size_t)b * g->H + y) * g->W + x] = btf_package_dequant(rg, v);
                }
        }
    }
    int order[LOSSY_C];
    pkg_order(w, order);
    pt.lab = lab_eval(r, w->p->blocks, g->C, order, tex, wt);
    return pt;
}

/* ---------------------------------------------------------------- curves */

static int cmp_bytes(const void *a, const void *b)
{
    const point *x = a, *y = b;
    return x->bytes < y->bytes ? -1 : x->bytes > y->bytes ? 1 : (x->lab > y->lab) - (x->lab < y->lab);
}

/* The lower envelope of pts (copied into fr): by bytes, each with less error than every
 * point with fewer bytes. Its length. */
static int front(const point *pts, int n, point *fr)
{
    point *s = malloc(sizeof(point) * (size_t)(n ? n : 1));
    if (!s)
        return 0;
    memcpy(s, pts, sizeof(point) * (size_t)n);
    qsort(s, (size_t)n, sizeof *s, cmp_bytes);
    int m = 0;
    for (int i = 0; i < n; i++)
        if (!m || s[i].lab < fr[m - 1].lab)
            fr[m++] = s[i];
    free(s);
    return m;
}

/* Bytes on the envelope at error lab (log bytes linear in error between its points);
 * NAN when its least error is above lab; -b when even its fewest bytes b have less. */
static double bytes_at(const point *fr, int m, double lab)
{
    if (m < 1 || lab < fr[m - 1].lab)
        return NAN;
    if (lab >= fr[0].lab)
        return -fr[0].bytes;
    for (int i = 0; i + 1 < m; i++)
        if (lab <= fr[i].lab && lab >= fr[i + 1].lab) {
            double t = (fr[i].lab - lab) / (fr[i].lab - fr[i + 1].lab);
            return exp(log(fr[i].bytes) + t * (log(fr[i + 1].bytes) - log(fr[i].bytes)));
        }
    return NAN;
}

/* Error on the envelope at bytes (linear in log bytes); NAN below its fewest bytes;
 * minus its last point's error (a bound: no more) above its most. */
static double lab_at(const point *fr, int m, double bytes)
{
    if (m < 1 || bytes < fr[0].bytes)
        return NAN;
    for (int i = 0; i + 1 < m; i++)
        if (bytes >= fr[i].bytes && bytes <= fr[i + 1].bytes) {
            double t = (log(bytes) - log(fr[i].bytes)) / (log(fr[i + 1].bytes) - log(fr[i].bytes));
            return fr[i].lab + t * (fr[i + 1].lab - fr[i].lab);
        }
    return -fr[m - 1].lab;
}

/* ---------------------------------------------------------------- the study */

/* Total bytes of the Lagrangian envelope of g's ladders at total added error D
 * (log bytes linear in log D between the lambdas' points); NAN outside. */
static double study_bytes_at(const ladder *g, double D)
{
    double pb = NAN, pd = NAN;
    for (int e = -30; e <= 100; e++) { /* lambda from 1e4 down: D falls */
        int q[LOSSY_C];
        alloc_lambda(g, 1e4 * pow(2.0, -e * 0.5), q);
        double b = 0.0, d = 0.0;
        for (int c = 0; c < g->C; c++)
            b += (double)g->bytes[c][q[c]], d += g->d[c][q[c]];
        if (d <= D && pd >= D && pd > d)
            return exp(log(pb) + (log(D) - log(pd)) / (log(d) - log(pd)) * (log(b) - log(pb)));
        pb = b, pd = d;
    }
    return NAN;
}

/* The q -> Y mapping's own error: RMS of decoded R - q over q uniform, both imports. */
static void study_ymap(void)
{
    uint8_t tab[256];
    y_table(tab);
    double et = 0.0, er = 0.0;
    for (int q = 0; q < 256; q++) {
        int yr = (16839 * q + 33059 * q + 6420 * q + (1 << 15) + (16 << 16)) >> 16; /* VP8RGBToY */
        double a = btf_webp_r_of_y(tab[q]) - q, b = btf_webp_r_of_y(yr) - q;
        et += a * a, er += b * b;
    }
    printf("lossy_ymap_table_rms %.3f q\n", sqrt(et / 256));
    printf("lossy_ymap_rgb_import_rms %.3f q\n", sqrt(er / 256));
}

/* Bytes of component 0's quality ladder (rungs 0..nq-1) at atlas error sse (log
 * bytes linear in log sse); NAN outside. */
static double ladder_bytes_at_sse(const ladder *g, double sse)
{
    for (int i = 0; i + 1 < g->nq; i++) {
        double a = g->sse[0][i], b = g->sse[0][i + 1];
        if (sse <= a && sse >= b && a > b)
            return exp(log((double)g->bytes[0][i]) +
                       (log(sse) - log(a)) / (log(b) - log(a)) * (log((double)g->bytes[0][i + 1]) - log((double)g->bytes[0][i])));
    }
    return NAN;
}

/* target_PSNR (pass 6) on component 0: the PSNR it reaches (atlas q against decoded,
 * used tiles), its bytes beside the quality ladder's at that error, its time. */
static void study_psnr(ladder *g, const char *mat)
{
    static const float targets[] = {34.0f, 40.0f, 46.0f};
    lossy_cfg cfg = g_cfg;
    const int slot = LOSSY_MAX_Q - 1;
    ladder_reset(g);
    g->nq = LOSSY_NQ;
    for (int i = 0; i < LOSSY_NQ; i++)
        if (ladder_rung(g, &g_cfg, 0, i, (float)g_quality[i], 0))
            return;
    double per = g->enc_cpu / (double)g->n_enc, n = (double)g->nb * g->W * g->H;
    for (int t = 0; t < 3; t++) {
        cfg.target_psnr = targets[t];
        double c0 = g->enc_cpu;
        if (ladder_rung(g, &cfg, 0, slot, 75.0f, 0))
            return;
        double secs = g->enc_cpu - c0, sse = g->sse[0][slot], lb = ladder_bytes_at_sse(g, sse);
        printf("lossy_study_%s_target_psnr%.0f_reached %.2f dB\n", mat, targets[t], 10 * log10(255.0 * 255.0 * n / sse));
        printf("lossy_study_%s_target_psnr%.0f_bytes %lld B\n", mat, targets[t], g->bytes[0][slot]);
        printf("# study %s: target_PSNR %.0f: reached %.2f dB (q units) in %lld B, %.0f ms; the quality ladder at that error %.0f B (%.3fx), %.0f ms an encode\n",
               mat, targets[t], 10 * log10(255.0 * 255.0 * n / sse), g->bytes[0][slot], 1e3 * secs, lb,
               (double)g->bytes[0][slot] / lb, 1e3 * per);
    }
}

/* Encoder settings compared on one material's ladders: total bytes at equal added error. */
static int run_study(const pkg *f, const char *mat)
{
    static const lossy_cfg cfgs[] = {
        {"m6-default", 6, 50, 60, 0, 0, 0, 0.0f},    {"m6-sharpyuv", 6, 50, 60, 0, 1, 0, 0.0f},
        {"m6-sns0", 6, 0, 60, 0, 0, 0, 0.0f},        {"m6-sns0-auto", 6, 0, 60, 1, 0, 0, 0.0f},
        {"m6-sns0-f0", 6, 0, 0, 0, 0, 0, 0.0f},      {"m6-sns0-f0-ytab", 6, 0, 0, 0, 0, 1, 0.0f},
        {"m4-sns0-f0-ytab", 4, 0, 0, 0, 0, 1, 0.0f}, {"m2-sns0-f0-ytab", 2, 0, 0, 0, 0, 1, 0.0f},
    };
    enum { NCFG = sizeof cfgs / sizeof cfgs[0] };
    ladder *g = ladder_new(f);
    if (!g)
        return 1;
    study_ymap();
    double ref[3] = {NAN, NAN, NAN}, base[3] = {NAN, NAN, NAN};
    printf("# study %s: settings | bytes at the added error of m6-default at quality 50 / 85 / 97 (ratio) | encode ms per atlas\n", mat);
    for (int k = 0; k < NCFG; k++) {
        ladder_reset(g);
        double t0 = now_s();
        if (ladder_run(g, &cfgs[k], g_quality, LOSSY_NQ, 0)) {
            ladder_free(g);
            return 1;
        }
        double wall = now_s() - t0;
        if (k == 0)
            for (int j = 0; j < 3; j++) {
                int i = rung_of(j == 0 ? 50 : j == 1 ? 85 : 97);
                ref[j] = 0.0;
                for (int c = 0; c < g->C; c++)
                    ref[j] += g->d[c][i];
            }
        double b0 = study_bytes_at(g, ref[0]), b1 = study_bytes_at(g, ref[1]), b2 = study_bytes_at(g, ref[2]);
        if (k == 0)
            base[0] = b0, base[1] = b1, base[2] = b2;
        double ms = 1e3 * g->enc_cpu / (double)g->n_enc;
        printf("lossy_study_%s_%s_bytes_q50 %.0f B\nlossy_study_%s_%s_bytes_q85 %.0f B\nlossy_study_%s_%s_bytes_q97 %.0f B\n",
               mat, cfgs[k].name, b0, mat, cfgs[k].name, b1, mat, cfgs[k].name, b2);
        printf("lossy_study_%s_%s_encode_ms %.1f ms\n", mat, cfgs[k].name, ms);
        printf("# study %s: %s | %.0f (%.3fx) / %.0f (%.3fx) / %.0f (%.3fx) | %.1f ms (wall %.1f s for %lld encodes)\n", mat,
               cfgs[k].name, b0, b0 / base[0], b1, b1 / base[1], b2, b2 / base[2], ms, wall, g->n_enc);
    }
    study_psnr(g, mat);
    ladder_free(g);
    return 0;
}

/* ---------------------------------------------------------------- one material */

/* Every variant with the weights of default package w: uniform qualities, then the
 * lambdas around w's own. Appends to pts; returns how many. */
static int variants_of(const ladder *g, const labref *r, const pkg *w, float **tex, point *pts)
{
    int n = 0, q[LOSSY_C];
    for (int u = 0; u < LOSSY_NU; u++) {
        for (int c = 0; c < g->C; c++)
            q[c] = rung_of(g_uniform[u]);
        pts[n] = variant_eval(g, r, w, q, tex);
        pts[n].kind = 0, pts[n++].param = g_uniform[u];
    }
    for (int e = -(LOSSY_NL / 2); e <= LOSSY_NL / 2; e++) {
        double lambda = w->lambda * pow(2.0, e);
        alloc_lambda(g, lambda, q);
        pts[n] = variant_eval(g, r, w, q, tex);
        pts[n].kind = e == 0 ? 2 : 1, pts[n++].param = lambda;
    }
    return n;
}

/* Prints one variant (what made it, its rungs). */
static void print_point(const char *mat, const char *what, const point *pt)
{
    printf("# %s %s: weights of T %.2g, %s %.4g: %.0f B, Lab %.4f, qualities", mat, what, pt->wnoise,
           pt->kind == 0 ? "quality" : "lambda", pt->param, pt->bytes, pt->lab);
    for (int c = 0; c < LOSSY_C; c++)
        printf(" %d", g_quality[pt->q[c]]);
    printf("\n");
}

/* The table rows: per default point the lossy envelope's bytes at its error and
 * error at its bytes. */
static void report(const char *mat, int side, const pkg *def, int nt, const point *fr, int m, const point *own,
                   int mo)
{
    printf("# %s %dx%d | T | default bytes / Lab | lossy bytes at equal Lab (ratio) | lossy Lab at equal bytes (ratio) | one-lambda lossy bytes at equal Lab (ratio)\n",
           mat, side, side);
    for (int t = 0; t < nt; t++) {
        double b = bytes_at(fr, m, def[t].lab), l = lab_at(fr, m, (double)def[t].bytes);
        double bo = bytes_at(own, mo, def[t].lab);
        printf("lossy_%s_t%g_default_bytes %lld B\nlossy_%s_t%g_default_lab %.4f lab\n", mat, def[t].noise,
               def[t].bytes, mat, def[t].noise, def[t].lab);
        printf("lossy_%s_t%g_lossy_bytes %.0f B\nlossy_%s_t%g_lossy_bytes_ratio %.3f x\n", mat, def[t].noise, b, mat,
               def[t].noise, b / (double)def[t].bytes);
        printf("lossy_%s_t%g_lossy_lab %.4f lab\nlossy_%s_t%g_lossy_lab_ratio %.3f x\n", mat, def[t].noise, l, mat,
               def[t].noise, l / def[t].lab);
        printf("# %s %dx%d | %g | %lld / %.4f | %s%.0f (%.3fx) | %s%.4f (%.3fx) | %s%.0f (%.3fx)\n", mat, side, side,
               def[t].noise, def[t].bytes, def[t].lab, b < 0 ? "<= " : "", fabs(b), fabs(b) / (double)def[t].bytes,
               l < 0 ? "<= " : "", fabs(l), fabs(l) / def[t].lab, bo < 0 ? "<= " : "", fabs(bo),
               fabs(bo) / (double)def[t].bytes);
    }
}

/* At the thesis format's error (the goal: its error at a fifth of its bytes):
 * the bytes of the default curve, of the lossy envelope and of the one-lambda variants. */
static void report_thesis(const char *mat, long long tb, double tl, const pkg *def, int nt, const point *fr, int m,
                          const point *own, int mo)
{
    point dp[LOSSY_MAX_T], dfr[LOSSY_MAX_T];
    for (int t = 0; t < nt; t++) {
        memset(&dp[t], 0, sizeof dp[t]);
        dp[t].bytes = (double)def[t].bytes, dp[t].lab = def[t].lab;
    }
    int dm = front(dp, nt, dfr);
    double bd = bytes_at(dfr, dm, tl), bl = bytes_at(fr, m, tl), bo = bytes_at(own, mo, tl);
    printf("lossy_%s_at_thesis_lab_default_bytes %.0f B\nlossy_%s_at_thesis_lab_lossy_bytes %.0f B\n", mat, bd, mat, bl);
    printf("lossy_%s_at_thesis_lab_default_ratio %.3f x\nlossy_%s_at_thesis_lab_lossy_ratio %.3f x\n", mat,
           bd / (double)tb, mat, bl / (double)tb);
    printf("# %s at the thesis format's error | thesis %lld B / Lab %.4f | default %s%.0f B (%.3fx the thesis's) | lossy %s%.0f B (%.3fx; %.3fx the default's) | one-lambda lossy %s%.0f B (%.3fx)\n",
           mat, tb, tl, bd < 0 ? "<= " : "", fabs(bd), fabs(bd) / (double)tb, bl < 0 ? "<= " : "", fabs(bl),
           fabs(bl) / (double)tb, fabs(bl) / fabs(bd), bo < 0 ? "<= " : "", fabs(bo), fabs(bo) / (double)tb);
}

/* libwebp decode time per atlas: the lossy files at rungs q, the default's lossless
 * tex-JJ.webp files (reps each). */
static void decode_cost(const char *mat, const ladder *g, const pkg *def, const int *q)
{
    const int reps = 5;
    uint8_t *grey = malloc((size_t)g->aw * g->ah);
    long long rg = 0;
    double lossy = 0.0, lossless = 0.0;
    for (int c = 0; grey && c < g->C; c++) {
        double t0 = now_s();
        for (int k = 0; k < reps; k++)
            webp_grey(g->file[c][q[c]], (size_t)g->bytes[c][q[c]], g->aw, g->ah, grey, &rg);
        lossy += now_s() - t0;
        char path[1300];
        snprintf(path, sizeof path, "%s/tex-%02d.webp", def->dir, c);
        char *buf = NULL;
        size_t n = 0;
        btf_error err = {0};
        if (btf_fs_read(path, (size_t)1 << 30, &buf, &n, &err) != BTF_OK)
            continue;
        t0 = now_s();
        for (int k = 0; k < reps; k++)
            webp_grey((const uint8_t *)buf, n, g->aw, g->ah, grey, &rg);
        lossless += now_s() - t0;
        free(buf);
    }
    free(grey);
    double mp = (double)g->aw * g->ah * 1e-6;
    printf("lossy_%s_decode_lossy_ms %.2f ms\nlossy_%s_decode_lossless_ms %.2f ms\n", mat,
           1e3 * lossy / (reps * g->C), mat, 1e3 * lossless / (reps * g->C));
    printf("# %s: decode per %dx%d atlas (libwebp, WebPDecodeRGB, one thread): lossy %.2f ms (%.0f Mpixel/s), lossless (the default's) %.2f ms (%.0f Mpixel/s)\n",
           mat, g->aw, g->ah, 1e3 * lossy / (reps * g->C), mp * reps * g->C / lossy, 1e3 * lossless / (reps * g->C),
           mp * reps * g->C / lossless);
}

/* The C reader on a default package whose tex-00.webp is replaced by a lossy one. */
static void reader_check(const char *mat, const ladder *g, const pkg *def, const int *q)
{
    char path[1300];
    snprintf(path, sizeof path, "%s/tex-00.webp", def->dir);
    btf_error err = {0};
    if (btf_fs_write_atomic(path, g->file[0][q[0]], (size_t)g->bytes[0][q[0]], &err) != BTF_OK)
        return;
    btf_package *p = NULL;
    btf_result r = btf_package_read(def->dir, 0, &p, &err);
    printf("# %s: btf_package_read with a lossy tex-00.webp: %s%s\n", mat, r == BTF_OK ? "read" : "refused: ",
           r == BTF_OK ? "" : err.msg);
    printf("lossy_%s_c_reader_accepts %d bool\n", mat, r == BTF_OK);
    btf_package_free(p);
}

/* CIELab error of a whole BTF against r (its subsample), as lab_eval scores a package. */
static double lab_of_btf(const labref *r, const btf *test)
{
    btf_metrics_acc *acc = calloc((size_t)r->n_img, sizeof *acc);
    if (!acc)
        return NAN;
#pragma omp parallel
    {
        float *img = malloc(btf_image_samples(test) * sizeof(float)), *sub = malloc((size_t)r->n_sub * 3 * sizeof(float));
#pragma omp for schedule(static)
        for (int i = 0; i < r->n_img; i++) {
            btf_get_image(test, i / test->lights.n_dirs, i % test->lights.n_dirs, img);
            for (int s = 0; s < r->n_sub; s++)
                memcpy(sub + 3 * s, img + 3 * (size_t)r->texel[s], 3 * sizeof(float));
            size_t o = (size_t)i * r->n_sub * 3;
            btf_metrics_add_lab(&acc[i], r->rgb + o, r->lab + o, sub, (size_t)r->n_sub);
        }
        free(img), free(sub);
    }
    btf_metrics_acc all = {0};
    for (int i = 0; i < r->n_img; i++)
        all.sum_lab += acc[i].sum_lab, all.pixels += acc[i].pixels;
    free(acc);
    return all.pixels ? all.sum_lab / (double)all.pixels : NAN;
}

/* The thesis format of the material (btf export-thesis --k 3 --components 8): its
 * bytes and its CIELab error on r, the reference (*bytes 0 on failure). */
static void thesis_ref(const btf *src, const labref *r, const char *mat, long long *bytes, double *lab)
{
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/thesis", g_tmp);
    btf_export_options eo = {0};
    eo.k = LOSSY_K, eo.components = LOSSY_C;
    btf_export_stats es;
    btf_thesis_pkg p;
    btf *dec = NULL;
    btf_error err = {0};
    *bytes = 0, *lab = NAN;
    if (btf_export_thesis(src, &eo, dir, &es, &err) != BTF_OK || btf_thesis_read(dir, &p, &err) != BTF_OK) {
        fail("thesis format", &err);
        return;
    }
    if (btf_thesis_reconstruct(&p, &src->views, src->width, src->height, BTF_F32, &dec, &err) == BTF_OK)
        *bytes = es.bytes, *lab = lab_of_btf(r, dec);
    btf_thesis_free(&p);
    btf_free(dec);
    btf_fs_rmtree(dir, NULL);
    printf("lossy_%s_thesis_bytes %lld B\nlossy_%s_thesis_lab %.4f lab\n", mat, *bytes, mat, *lab);
}

/* Step 1: the default packages (and the stride-1 check of the first at 64x64). */
static int make_defaults(const btf *src, const labref *r, const char *mat, btf_pca_model **model, pkg *def, int *nt)
{
    const char *s = getenv("LOSSY_NOISES");
    char list[256];
    snprintf(list, sizeof list, "%s", s && *s ? s : src->width >= 128 ? "0.25 0.5 1 2 4 8 16" : "0.25 0.35 0.5 0.7 1 1.4 2 2.8 4 5.6 8");
    *nt = 0;
    for (char *tok = strtok(list, " "); tok && *nt < LOSSY_MAX_T; tok = strtok(NULL, " ")) {
        char tag[64];
        snprintf(tag, sizeof tag, "default-%s", tok);
        if (pkg_make(src, r, (float)atof(tok), model, tag, &def[*nt]))
            return 1;
        const pkg *k = &def[(*nt)++];
        fprintf(stderr, "bench_lossy: %s T %g: %lld B, Lab %.4f, %.1f s\n", mat, k->noise, k->bytes, k->lab, k->secs);
        printf("lossy_%s_t%g_default_compress_s %.2f s\n", mat, k->noise, k->secs);
        printf("# %s default T %g: %lld B (textures %lld, weights %lld, manifest %lld), Lab %.4f, lambda %.3g, compress %.1f s\n",
               mat, k->noise, k->bytes, k->tex_bytes, k->wt_bytes, k->manifest_bytes, k->lab, k->lambda, k->secs);
    }
    const pkg *k = &def[0]; /* the default's tex_noise, when measured */
    for (int t = 0; t < *nt; t++)
        k = def[t].noise == 0.5f ? &def[t] : k;
    double full = eval_reference(src, k);
    printf("lossy_%s_t%g_lab_btf_eval %.6f lab\n", mat, k->noise, full);
    printf("# %s T %g: CIELab by btf eval's path (every texel) %.6f, by the bench's (every %d-th texel in x and y) %.6f\n",
           mat, k->noise, full, r->stride, k->lab);
    return 0;
}

/* Step 2-4 on the ladder: every variant, the envelopes, the table. */
static int measure_variants(const char *mat, int side, const ladder *g, const labref *r, const pkg *def, int nt,
                            long long tb, double tl)
{
    point *pts = malloc(sizeof(point) * LOSSY_MAX_PTS), *fr = malloc(sizeof(point) * LOSSY_MAX_PTS);
    point *own = malloc(sizeof(point) * LOSSY_MAX_T), *ofr = malloc(sizeof(point) * LOSSY_MAX_T);
    float *tex[LOSSY_C] = {0};
    size_t nt_tex = (size_t)g->nb * g->W * g->H;
    int n = 0, ok = pts && fr && own && ofr;
    for (int c = 0; c < LOSSY_C; c++)
        ok = ok && (tex[c] = malloc(nt_tex * sizeof(float))) != NULL;
    for (int t = 0; ok && t < nt; t++) {
        int k = variants_of(g, r, &def[t], tex, pts + n);
        for (int i = 0; i < k; i++)
            if (pts[n + i].kind == 2)
                own[t] = pts[n + i];
        n += k;
    }
    if (ok) {
        int m = front(pts, n, fr), mo = front(own, nt, ofr);
        for (int i = 0; i < m; i++)
            print_point(mat, "envelope", &fr[i]);
        for (int t = 0; t < nt; t++)
            print_point(mat, "one lambda", &own[t]);
        report(mat, side, def, nt, fr, m, ofr, mo);
        if (tb > 0)
            report_thesis(mat, tb, tl, def, nt, fr, m, ofr, mo);
        decode_cost(mat, g, &def[0], fr[m - 1].q);
        reader_check(mat, g, &def[nt - 1], fr[m - 1].q);
    }
    for (int c = 0; c < LOSSY_C; c++)
        free(tex[c]);
    free(pts), free(fr), free(own), free(ofr);
    return ok ? 0 : 1;
}

/* The lossy ladder's cost beside the lossless WebP encode of the same atlases. */
static void encode_cost(const char *mat, const ladder *g, double wall)
{
    double t0 = cpu_s();
    for (int c = 0; c < g->C; c++) {
        uint8_t *out = NULL;
        size_t n = 0;
        btf_error err = {0};
        btf_webp_encode_grey(g->fine[c], g->aw, g->ah, &out, &n, &err);
        free(out);
    }
    double lossless = (cpu_s() - t0) / g->C;
    printf("lossy_%s_ladder_s %.2f s\nlossy_%s_encode_lossy_ms %.1f ms\nlossy_%s_encode_lossless_ms %.1f ms\n", mat,
           wall, mat, 1e3 * g->enc_cpu / (double)g->n_enc, mat, 1e3 * lossless);
    printf("# %s: ladder %lld lossy encodes (%s) in %.1f s wall; per %dx%d atlas %.1f ms lossy, %.1f ms lossless (preset 3); decoded pixels with G != R: %lld of %.0f\n",
           mat, g->n_enc, g_cfg.name, wall, g->aw, g->ah, 1e3 * g->enc_cpu / (double)g->n_enc, 1e3 * lossless,
           g->pixels_rg, (double)g->n_enc * g->aw * g->ah);
}

/* Blocks x components of k whose texture step is the full range's, (max - lo) / 255
 * (within 0.1%): the fine package's steps are meant to be all of them. */
static int full_range_blocks(const pkg *k)
{
    int n = 0, nb = k->p->blocks->n_blocks;
    size_t plane = (size_t)k->p->width * k->p->height;
    for (int i = 0; i < k->p->n_chunks; i++)
        for (int b = 0; b < nb; b++) {
            const float *t = k->p->tex[i] + (size_t)b * plane, *rg = k->p->chunk[i].tex_range + 2 * b;
            float hi = t[0];
            for (size_t x = 1; x < plane; x++)
                hi = t[x] > hi ? t[x] : hi;
            n += rg[1] <= 1.001f * (hi - rg[0]) / 255.0f + 1e-12f;
        }
    return n;
}

/* LOSSY_DUMP=DIR: component 0's lossy files at three qualities and libwebp's decode
 * of each (its R, raw bytes) for bench/lossy_browser.mjs, which decodes them in
 * Chromium as the client does. */
static void dump_files(const ladder *g)
{
    const char *dir = getenv("LOSSY_DUMP");
    static const int qs[] = {20, 70, 100};
    if (!dir || !*dir || mkdir(dir, 0755) != 0)
        return;
    uint8_t *grey = malloc((size_t)g->aw * g->ah);
    for (int k = 0; grey && k < 3; k++) {
        int i = rung_of(qs[k]);
        long long rg = 0;
        char path[1200];
        btf_error err = {0};
        snprintf(path, sizeof path, "%s/q%d.webp", dir, qs[k]);
        btf_fs_write_atomic(path, g->file[0][i], (size_t)g->bytes[0][i], &err);
        webp_grey(g->file[0][i], (size_t)g->bytes[0][i], g->aw, g->ah, grey, &rg);
        snprintf(path, sizeof path, "%s/q%d.grey", dir, qs[k]);
        btf_fs_write_atomic(path, grey, (size_t)g->aw * g->ah, &err);
    }
    free(grey);
    fprintf(stderr, "bench_lossy: wrote %s/q{20,70,100}.webp and .grey (%dx%d)\n", dir, g->aw, g->ah);
}

static int run_material(const char *name, const char *spec, int study)
{
    btf *src = NULL;
    btf_error err = {0};
    double t0 = now_s();
    if (load_material(spec, &src, &err) != BTF_OK)
        return fail(spec, &err);
    fprintf(stderr, "bench_lossy: %s (%s): %dx%d loaded in %.1f s\n", name, spec, src->width, src->height, now_s() - t0);
    int stride = src->width >= 128 ? env_int("LOSSY_STRIDE", 3) : 1, nt = 0, rc = 1;
    labref r;
    pkg def[LOSSY_MAX_T], fine;
    memset(def, 0, sizeof def), memset(&fine, 0, sizeof fine);
    ladder *g = NULL;
    btf_pca_model *model = NULL;
    long long tb = 0;
    double tl = NAN;
    printf("lossy_%s_lab_texel_stride %d texels\n", name, stride);
    if (labref_init(&r, src, stride) || make_defaults(src, &r, name, &model, def, &nt) ||
        pkg_make(src, &r, LOSSY_FINE, &model, "fine", &fine))
        goto done;
    thesis_ref(src, &r, name, &tb, &tl);
    printf("# %s fine (tex_noise %g: full-range 8-bit textures in %d of %d blocks x components): %lld B, Lab %.4f\n",
           name, LOSSY_FINE, full_range_blocks(&fine), fine.p->blocks->n_blocks * LOSSY_C, fine.bytes, fine.lab);
    if (study && run_study(&fine, name))
        goto done;
    if (!(g = ladder_new(&fine)))
        goto done;
    double t_ladder = now_s();
    if (ladder_run(g, &g_cfg, g_quality, LOSSY_NQ, 1))
        goto done;
    encode_cost(name, g, now_s() - t_ladder);
    if (study)
        dump_files(g);
    rc = measure_variants(name, src->width, g, &r, def, nt, tb, tl);
done:
    if (g)
        ladder_free(g);
    for (int t = 0; t < LOSSY_MAX_T; t++)
        pkg_clear(&def[t]);
    pkg_clear(&fine);
    btf_pca_model_free(model);
    labref_free(&r);
    btf_free(src);
    return rc;
}

/* Appends " wool64=BASE/wool@64 corduroy64=..." (side 64) for the thesis materials
 * present under base; *k the text's length so far. */
static void add_thesis(char *buf, size_t n, int *k, const char *base, int side)
{
    static const char *mats[2] = {"wool", "corduroy"};
    for (int i = 0; i < 2 && *k > 0 && (size_t)*k < n; i++) {
        char meta[1200];
        struct stat st;
        snprintf(meta, sizeof meta, "%s/%s/meta.json", base, mats[i]);
        if (stat(meta, &st) == 0)
            *k += snprintf(buf + *k, n - (size_t)*k, " %s%d=%s/%s@%d", mats[i], side, base, mats[i], side);
    }
}

/* The default materials: generated ones with seeds no test uses, the thesis's when present. */
static void default_materials(char *buf, size_t n)
{
    const char *shared = getenv("BTF_SHARED");
    char base[1100];
    snprintf(base, sizeof base, "%s/data/thesis-ubo2003", shared && *shared ? shared : "../shared");
    int k = snprintf(buf, n, "tiles64=gen:tiles:64:3621 knit64=gen:knit:64:3622 stone64=gen:stone:64:3623 "
                             "stonejpg64=jpg:stone:64:3624");
    add_thesis(buf, n, &k, base, 64);
    if (k > 0 && (size_t)k < n)
        k += snprintf(buf + k, n - (size_t)k, " tiles256=gen:tiles:256:3631");
    add_thesis(buf, n, &k, base, 256);
}

int main(void)
{
    double t0 = now_s();
    const char *tmp = getenv("LOSSY_TMP");
    snprintf(g_tmp, sizeof g_tmp, "%s", tmp && *tmp ? tmp : "/tmp/btf-bench-lossy");
    mkdir(g_tmp, 0755);
    char list[4096];
    const char *m = getenv("LOSSY_MATERIALS");
    if (m && *m)
        snprintf(list, sizeof list, "%s", m);
    else
        default_materials(list, sizeof list);
    int rc = 0, study = env_int("LOSSY_STUDY", 1), first = 1;
    char *save = NULL;
    for (char *tok = strtok_r(list, " ", &save); tok; tok = strtok_r(NULL, " ", &save), first = 0) {
        char *eq = strchr(tok, '=');
        if (!eq) {
            fprintf(stderr, "bench_lossy: %s: expected NAME=SPEC\n", tok);
            return 2;
        }
        *eq = '\0';
        rc |= run_material(tok, eq + 1, study && first);
        fflush(stdout);
    }
    printf("lossy_wall_s %.1f s\n", now_s() - t0);
    return rc;
}
