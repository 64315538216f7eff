/* btf_thesis.c - reader, writer and decoder of the thesis's package format
 * (doc/input-formats.md section 3); btf_import_thesis of btf_io.h. See btf_thesis.h. */
#include "btf_thesis.h"

#include <cJSON.h>
#include <cblas.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_fs.h"
#include "btf_image.h"
#include "btf_io.h"
#include "btf_common.h"
#include "btf_input.h"

#define META_MAX_BYTES (1 << 20)
#define MAX_L_FLOATS ((size_t)1 << 30)

/* ------------------------------------------------------------ quantisation */

static float deq(uint8_t b) { return (float)b * (2.0f / 255.0f) - 1.0f; }

/* Byte for v in [-1, 1] (the caller checks the range). */
static uint8_t quant(float v)
{
    float q = (v + 1.0f) * 127.5f + 0.5f;
    if (q < 0.0f)
        q = 0.0f;
    if (q > 255.0f)
        q = 255.0f;
    return (uint8_t)q;
}

static float sigma_decode(uint8_t hi, uint8_t lo) { return (float)(hi * 100 + lo) / 10.0f; }

/* R.png geometry: pixels per (slot, light, colour) and sigma pixels per block. */
static int groups(const btf_thesis_pkg *p) { return (p->C + 3) / 4; }
static int sigma_px(const btf_thesis_pkg *p) { return (p->C + 1) / 2; }
static size_t weight_pixels(const btf_thesis_pkg *p)
{
    return (size_t)groups(p) * 3u * (size_t)p->N * (size_t)p->k * (size_t)p->nb;
}
static size_t r_pixels(const btf_thesis_pkg *p) { return weight_pixels(p) + (size_t)p->nb * (size_t)sigma_px(p); }

static size_t l_count(const btf_thesis_pkg *p) { return (size_t)p->nb * p->S * p->S * p->C; }
static size_t v_count(const btf_thesis_pkg *p) { return (size_t)p->nb * p->k * p->N * 3u * p->C; }

/* ------------------------------------------------------------ file names */

#define PART_META (-1)
#define PART_R (-2)
#define PATH_MAX_LEN 4096

/* Path of part j of a package (j.png, or PART_META / PART_R) in buf; 0 if it fits. */
static int part_path(char *buf, const char *dir, int j)
{
    int n;
    if (j == PART_META)
        n = snprintf(buf, PATH_MAX_LEN, "%s/meta.json", dir);
    else if (j == PART_R)
        n = snprintf(buf, PATH_MAX_LEN, "%s/R.png", dir);
    else
        n = snprintf(buf, PATH_MAX_LEN, "%s/%d.png", dir, j);
    return n < 0 || n >= PATH_MAX_LEN;
}

/* ------------------------------------------------------------ allocation */

static btf_result check_sizes(int C, int N, int k, int S, btf_error *err)
{
    if (C < 1 || C > BTF_THESIS_MAX_C)
        return btf_fail(err, BTF_ERR_RANGE, "thesis package: numComp %d outside 1..%d", C, BTF_THESIS_MAX_C);
    if (N < 1 || N > BTF_MAX_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "thesis package: numDirections %d outside 1..%d", N, BTF_MAX_DIRS);
    if (k < 1 || k > N)
        return btf_fail(err, BTF_ERR_RANGE, "thesis package: blockSize %d outside 1..%d", k, N);
    if (S < 2 || S > BTF_THESIS_MAX_S || S % 2)
        return btf_fail(err, BTF_ERR_RANGE, "thesis package: imageSize %d not even in 2..%d", S, BTF_THESIS_MAX_S);
    size_t nb = (size_t)(N + k - 1) / (size_t)k;
    if (nb * S * S * C > MAX_L_FLOATS)
        return btf_fail(err, BTF_ERR_RANGE, "thesis package: %zu blocks of %dx%d x %d components too large", nb, S,
                        S, C);
    return BTF_OK;
}

btf_result btf_thesis_alloc(int C, int N, int k, int S, btf_thesis_pkg *p, btf_error *err)
{
    if (!p)
        return btf_fail(err, BTF_ERR_ARG, "btf_thesis_alloc: NULL package");
    memset(p, 0, sizeof *p);
    btf_result r = check_sizes(C, N, k, S, err);
    if (r != BTF_OK)
        return r;
    p->C = C, p->N = N, p->k = k, p->S = S, p->nb = (N + k - 1) / k;
    p->L = calloc(l_count(p), sizeof(float));
    p->V = calloc(v_count(p), sizeof(float));
    p->sigma = calloc((size_t)p->nb * C, sizeof(float));
    if (!p->L || !p->V || !p->sigma) {
        size_t want = l_count(p) + v_count(p) + (size_t)p->nb * C; /* before the free clears the sizes */
        btf_thesis_free(p);
        return btf_fail(err, BTF_ERR_NOMEM, "thesis package: cannot allocate %zu floats", want);
    }
    return BTF_OK;
}

void btf_thesis_free(btf_thesis_pkg *p)
{
    if (p)
        free(p->L), free(p->V), free(p->sigma), memset(p, 0, sizeof *p);
}

/* ------------------------------------------------------------ meta.json */

/* Integer field `key` (a decimal string as the thesis writes it, or a JSON integer). */
static btf_result meta_int(const cJSON *root, const char *key, const char *path, int *out, btf_error *err)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(root, key);
    if (!it)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: missing \"%s\"", path, key);
    if (cJSON_IsNumber(it)) {
        double d = it->valuedouble;
        if (d != floor(d) || d < -1e9 || d > 1e9)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: \"%s\" is not an integer", path, key);
        *out = (int)d;
        return BTF_OK;
    }
    if (!cJSON_IsString(it) || !it->valuestring)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"%s\" is neither a string nor a number", path, key);
    const char *s = it->valuestring;
    char *end = NULL;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end != '\0' || errno || v < -1000000000L || v > 1000000000L)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"%s\" = \"%.40s\" is not an integer", path, key, s);
    *out = (int)v;
    return BTF_OK;
}

static btf_result read_meta(const char *dir, const btf_files *files, btf_thesis_pkg *p, btf_error *err)
{
    char path[PATH_MAX_LEN];
    if (part_path(path, dir, PART_META))
        return btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir);
    char *text = NULL;
    btf_result r = btf_fs_read_with(files, path, META_MAX_BYTES, &text, NULL, err);
    if (r != BTF_OK)
        return r;
    cJSON *root = cJSON_Parse(text);
    free(text);
    if (!root || !cJSON_IsObject(root)) {
        cJSON_Delete(root);
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not a JSON object", path);
    }
    static const char *keys[] = {"numComp", "numDirections", "blockSize", "imageSize", "RSize", "texSize"};
    int v[6] = {0};
    for (int i = 0; i < 6 && r == BTF_OK; i++)
        r = meta_int(root, keys[i], path, &v[i], err);
    cJSON_Delete(root);
    if (r != BTF_OK)
        return r;
    if ((r = check_sizes(v[0], v[1], v[2], v[3], err)) != BTF_OK)
        return r;
    p->C = v[0], p->N = v[1], p->k = v[2], p->S = v[3], p->nb = (v[1] + v[2] - 1) / v[2];
    p->r_size = v[4], p->tex_size = v[5];
    if (p->r_size < 1 || p->r_size > BTF_MAX_SIDE)
        return btf_fail(err, BTF_ERR_RANGE, "%s: RSize %d outside 1..%d", path, p->r_size, BTF_MAX_SIDE);
    if ((size_t)p->r_size * (size_t)p->r_size < r_pixels(p))
        return btf_fail(err, BTF_ERR_RANGE, "%s: RSize %d too small for %zu weight and sigma pixels", path,
                        p->r_size, r_pixels(p));
    if (p->tex_size < 0)
        return btf_fail(err, BTF_ERR_RANGE, "%s: texSize %d negative", path, p->tex_size);
    return BTF_OK;
}

/* ------------------------------------------------------------ PNG parts */

static btf_result read_component(const char *dir, const btf_files *files, btf_thesis_pkg *p, int j, btf_error *err)
{
    char path[PATH_MAX_LEN];
    if (part_path(path, dir, j))
        return btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir);
    uint8_t *px = NULL; /* RGBA8, its size checked before decoding */
    btf_result r = btf_image_read_with(files, path, p->S / 2, (p->S / 2) * p->nb, 4, 0, &px, err);
    if (r != BTF_OK)
        return r;
    size_t n = (size_t)p->nb * p->S * p->S; /* one byte per texel: flat stream */
    for (size_t t = 0; t < n; t++)
        p->L[t * p->C + j] = deq(px[t]);
    free(px);
    return BTF_OK;
}

static btf_result read_weights(const char *dir, const btf_files *files, btf_thesis_pkg *p, btf_error *err)
{
    char path[PATH_MAX_LEN];
    if (part_path(path, dir, PART_R))
        return btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir);
    uint8_t *px = NULL;
    btf_result r = btf_image_read_with(files, path, p->r_size, p->r_size, 4, 0, &px, err);
    if (r != BTF_OK)
        return r;
    int G = groups(p), C = p->C;
    size_t rows = (size_t)p->nb * p->k * p->N * 3u;
    for (size_t row = 0; row < rows; row++)
        for (int j = 0; j < C; j++)
            p->V[row * C + j] = deq(px[(row * G + (size_t)(j / 4)) * 4u + (size_t)(j % 4)]);
    size_t s0 = weight_pixels(p);
    for (int b = 0; b < p->nb; b++)
        for (int j = 0; j < C; j++) {
            const uint8_t *q = px + (s0 + (size_t)b * sigma_px(p) + (size_t)(j / 2)) * 4u + (size_t)(j % 2) * 2u;
            p->sigma[b * C + j] = sigma_decode(q[0], q[1]);
        }
    free(px);
    return BTF_OK;
}

/* Every image the meta.json announces exists with the announced size in its header,
 * and its file is large enough to hold that many pixels (BTF_IMAGE_MAX_PNG_RATIO). */
static btf_result check_parts(const char *dir, const btf_files *files, const btf_thesis_pkg *m, btf_error *err)
{
    char path[PATH_MAX_LEN];
    for (int j = PART_R; j < m->C; j++) {
        if (j == PART_META)
            continue;
        int want_w = j == PART_R ? m->r_size : m->S / 2, want_h = j == PART_R ? m->r_size : (m->S / 2) * m->nb, w, h, ch;
        if (part_path(path, dir, j))
            return btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir);
        long long bytes = btf_fs_size_with(files, path);
        if (bytes < 0)
            return btf_fail(err, BTF_ERR_MISSING, "%s: missing", path);
        btf_result r = btf_image_info_with(files, path, &w, &h, &ch, err);
        if (r != BTF_OK)
            return r;
        if (w != want_w || h != want_h || ch != 4)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: is %dx%d with %d channels, expected %dx%d RGBA", path, w, h, ch,
                            want_w, want_h);
        if ((double)w * h * 4.0 > (double)bytes * BTF_IMAGE_MAX_PNG_RATIO)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: %lld bytes cannot hold %dx%d RGBA pixels", path, bytes, w, h);
    }
    return BTF_OK;
}

btf_result btf_thesis_read(const char *dir, btf_thesis_pkg *p, btf_error *err)
{
    return btf_thesis_read_with(dir, NULL, p, err);
}

btf_result btf_thesis_read_with(const char *dir, const btf_files *files, btf_thesis_pkg *p, btf_error *err)
{
    if (!dir || !p)
        return btf_fail(err, BTF_ERR_ARG, "btf_thesis_read: NULL argument");
    memset(p, 0, sizeof *p);
    btf_thesis_pkg m = {0};
    btf_result r = read_meta(dir, files, &m, err);
    if (r == BTF_OK)
        r = check_parts(dir, files, &m, err); /* before the header's sizes are allocated */
    if (r != BTF_OK)
        return r;
    if ((r = btf_thesis_alloc(m.C, m.N, m.k, m.S, p, err)) != BTF_OK)
        return r;
    p->r_size = m.r_size, p->tex_size = m.tex_size;
    for (int j = 0; j < p->C && r == BTF_OK; j++)
        r = read_component(dir, files, p, j, err);
    if (r == BTF_OK)
        r = read_weights(dir, files, p, err);
    if (r != BTF_OK)
        btf_thesis_free(p);
    return r;
}

/* ------------------------------------------------------------ writer */

static int pow2_at_least(size_t n)
{
    int s = 1;
    while ((size_t)s * (size_t)s < n)
        s *= 2;
    return s;
}

static btf_result check_range(const float *a, size_t n, float lo, float hi, const char *what, int C,
                              btf_error *err)
{
    for (size_t i = 0; i < n; i++)
        if (!(a[i] >= lo && a[i] <= hi))
            return btf_fail(err, BTF_ERR_RANGE, "thesis write: %s value %g (entry %zu, component %zu) outside [%g, %g]",
                            what, (double)a[i], i / (size_t)C, i % (size_t)C, (double)lo, (double)hi);
    return BTF_OK;
}

static btf_result check_pkg(const btf_thesis_pkg *p, btf_error *err)
{
    btf_result r = check_sizes(p->C, p->N, p->k, p->S, err);
    if (r != BTF_OK)
        return r;
    if (p->nb != (p->N + p->k - 1) / p->k || !p->L || !p->V || !p->sigma)
        return btf_fail(err, BTF_ERR_ARG, "thesis write: inconsistent package (nb %d, arrays missing?)", p->nb);
    const float tol = 1e-5f; /* float rounding of values meant to be exactly +-1 */
    if ((r = check_range(p->L, l_count(p), -1.0f - tol, 1.0f + tol, "L", p->C, err)) != BTF_OK)
        return r;
    if ((r = check_range(p->V, v_count(p), -1.0f - tol, 1.0f + tol, "V", p->C, err)) != BTF_OK)
        return r;
    return check_range(p->sigma, (size_t)p->nb * p->C, 0.0f, 2559.94f, "sigma", p->C, err);
}

static btf_result write_component(const char *dir, const btf_thesis_pkg *p, int j, btf_error *err)
{
    size_t n = (size_t)p->nb * p->S * p->S;
    uint8_t *px = malloc(n);
    if (!px)
        return btf_fail(err, BTF_ERR_NOMEM, "thesis write: out of memory");
    for (size_t t = 0; t < n; t++)
        px[t] = quant(p->L[t * p->C + j]);
    char path[PATH_MAX_LEN];
    btf_result r = part_path(path, dir, j) ? btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir)
                                           : btf_image_write_flags(path, p->S / 2, (p->S / 2) * p->nb, 4, 8, px,
                                                                   BTF_IMAGE_PNG_SMALLEST, err);
    free(px);
    return r;
}

static void sigma_encode(float s, uint8_t *hi, uint8_t *lo)
{
    long t = lroundf(s * 10.0f);
    if (t < 0)
        t = 0;
    if (t > 25599)
        t = 25599;
    *hi = (uint8_t)(t / 100);
    *lo = (uint8_t)(t % 100);
}

static btf_result write_weights(const char *dir, const btf_thesis_pkg *p, int r_size, btf_error *err)
{
    size_t npx = (size_t)r_size * (size_t)r_size;
    uint8_t *px = calloc(npx, 4);
    if (!px)
        return btf_fail(err, BTF_ERR_NOMEM, "thesis write: out of memory");
    for (size_t i = r_pixels(p); i < npx; i++)
        px[i * 4 + 3] = 255; /* padding as in the published files: opaque black */
    int G = groups(p), C = p->C;
    size_t rows = (size_t)p->nb * p->k * p->N * 3u;
    for (size_t row = 0; row < rows; row++)
        for (int j = 0; j < C; j++)
            px[(row * G + (size_t)(j / 4)) * 4u + (size_t)(j % 4)] = quant(p->V[row * C + j]);
    size_t s0 = weight_pixels(p);
    for (int b = 0; b < p->nb; b++)
        for (int j = 0; j < C; j++) {
            uint8_t *q = px + (s0 + (size_t)b * sigma_px(p) + (size_t)(j / 2)) * 4u + (size_t)(j % 2) * 2u;
            sigma_encode(p->sigma[b * C + j], &q[0], &q[1]);
        }
    char path[PATH_MAX_LEN];
    btf_result r = part_path(path, dir, PART_R) ? btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir)
                                                : btf_image_write_flags(path, r_size, r_size, 4, 8, px,
                                                                        BTF_IMAGE_PNG_SMALLEST, err);
    free(px);
    return r;
}

static btf_result write_meta(const char *dir, const btf_thesis_pkg *p, int r_size, btf_error *err)
{
    int tex = p->tex_size > 0 ? p->tex_size : pow2_at_least(((size_t)p->C * p->nb * p->S * p->S + 3) / 4);
    int v[6] = {p->C, p->N, tex, p->k, p->S, r_size};
    static const char *keys[] = {"numComp", "numDirections", "texSize", "blockSize", "imageSize", "RSize"};
    cJSON *root = cJSON_CreateObject();
    for (int i = 0; root && i < 6; i++) {
        char num[32];
        snprintf(num, sizeof num, "%d", v[i]);
        if (!cJSON_AddStringToObject(root, keys[i], num)) {
            cJSON_Delete(root);
            root = NULL;
        }
    }
    char *text = root ? cJSON_PrintUnformatted(root) : NULL;
    cJSON_Delete(root);
    if (!text)
        return btf_fail(err, BTF_ERR_NOMEM, "thesis write: cannot build meta.json");
    char path[PATH_MAX_LEN];
    btf_result r = part_path(path, dir, PART_META) ? btf_fail(err, BTF_ERR_ARG, "%s: path too long", dir)
                                                   : btf_fs_write_atomic(path, text, strlen(text), err);
    free(text);
    return r;
}

/* 1 when every entry of dir is a regular file the thesis writer names (meta.json,
 * R.png, N.png, or their temporaries); with need_meta, meta.json must be there. */
/* A regular file named as the thesis writer names them; *ctx counts meta.json. */
static int btf__thesis_file(const char *n, const struct stat *st, void *ctx)
{
    size_t digits = strspn(n, "0123456789");
    *(int *)ctx += !strcmp(n, "meta.json");
    return S_ISREG(st->st_mode) &&
           (!strncmp(n, "meta.json", 9) || !strncmp(n, "R.png", 5) || (digits > 0 && !strncmp(n + digits, ".png", 4)));
}

static int btf__thesis_files_only(const char *dir, int need_meta)
{
    int meta = 0;
    return btf_fs_all_entries(dir, btf__thesis_file, &meta) && (meta || !need_meta);
}
int btf_thesis_owns_dir(const char *dir, void *ctx)
{
    (void)ctx;
    return btf__thesis_files_only(dir, 1);
}

static int btf__thesis_owns_temp(const char *dir, void *ctx)
{
    (void)ctx;
    return btf__thesis_files_only(dir, 0);
}

btf_result btf_thesis_write(const char *dir, const btf_thesis_pkg *p, btf_error *err)
{
    if (!dir || !p)
        return btf_fail(err, BTF_ERR_ARG, "btf_thesis_write: NULL argument");
    btf_result r = check_pkg(p, err);
    if (r != BTF_OK)
        return r;
    int r_size = p->r_size;
    if ((size_t)r_size * (size_t)r_size < r_pixels(p) || r_size > BTF_MAX_SIDE)
        r_size = pow2_at_least(r_pixels(p));
    struct stat st;
    if (stat(dir, &st) == 0 && rmdir(dir) != 0)
        return btf_fail(err, BTF_ERR_IO, "%s: exists and is not an empty directory", dir);
    char tmp[PATH_MAX_LEN - 64];
    r = btf_fs_temp_dir(dir, tmp, sizeof tmp, btf__thesis_owns_temp, NULL, err);
    if (r != BTF_OK)
        return r;
    for (int j = 0; j < p->C && r == BTF_OK; j++)
        r = write_component(tmp, p, j, err);
    if (r == BTF_OK)
        r = write_weights(tmp, p, r_size, err);
    if (r == BTF_OK)
        r = write_meta(tmp, p, r_size, err);
    if (r == BTF_OK)
        r = btf_fs_replace_dir(tmp, dir, NULL, NULL, err); /* only an empty directory is replaced */
    if (r != BTF_OK)
        btf_fs_rmtree(tmp, NULL);
    return r;
}

/* ------------------------------------------------------------ decoding */

void btf_thesis_decode_pixel(const btf_thesis_pkg *p, int view, int light, int x, int y, float rgb[3])
{
    int b = view / p->k, C = p->C;
    const float *l = p->L + (((size_t)b * p->S + (size_t)y) * p->S + (size_t)x) * C;
    const float *s = p->sigma + (size_t)b * C;
    for (int c = 0; c < 3; c++) {
        const float *v = p->V + (((size_t)view * p->N + (size_t)light) * 3u + (size_t)c) * C;
        float acc = 0.0f;
        for (int j = 0; j < C; j++)
            acc += l[j] * s[j] * v[j];
        rgb[c] = acc;
    }
}

void btf_thesis_decode_image(const btf_thesis_pkg *p, int view, int light, float *out)
{
    for (int y = 0; y < p->S; y++)
        for (int x = 0; x < p->S; x++)
            btf_thesis_decode_pixel(p, view, light, x, y, out + ((size_t)y * p->S + (size_t)x) * 3u);
}

/* ------------------------------------------------------------ resampling */

/* Resamples L (nb x S x S x C) to nb x h x w x C by area weighting (separable);
 * for sizes dividing S this is the box filter. Linear, so it commutes with decoding. */
static btf_result resample_l(const btf_thesis_pkg *p, int w, int h, float **out, btf_error *err)
{
    int S = p->S, C = p->C, mx = S / w + 2, my = S / h + 2;
    size_t rowlen = (size_t)w * C;
    int *fx = malloc(sizeof(int) * (size_t)(2 * w + 2 * h));
    float *wx = malloc(sizeof(float) * ((size_t)w * mx + (size_t)h * my));
    float *tmp = malloc(sizeof(float) * (size_t)S * rowlen);
    float *res = calloc((size_t)p->nb * h * rowlen, sizeof(float));
    btf_result r = BTF_OK;
    if (!fx || !wx || !tmp || !res) {
        r = btf_fail(err, BTF_ERR_NOMEM, "thesis import: cannot allocate resampling buffers");
        goto done;
    }
    int *cx = fx + w, *fy = fx + 2 * w, *cy = fy + h;
    float *wy = wx + (size_t)w * mx;
    if (btf_area_weights(S, w, fx, cx, wx, mx) || btf_area_weights(S, h, fy, cy, wy, my)) {
        r = btf_fail(err, BTF_ERR_ARG, "thesis import: bad resampling size %dx%d", w, h);
        goto done;
    }
    for (int b = 0; b < p->nb; b++) {
        const float *src = p->L + (size_t)b * S * S * C;
        memset(tmp, 0, sizeof(float) * (size_t)S * rowlen);
        for (int y = 0; y < S; y++)
            for (int x = 0; x < w; x++)
                for (int s = 0; s < cx[x]; s++)
                    cblas_saxpy(C, wx[x * mx + s], src + ((size_t)y * S + fx[x] + s) * C, 1,
                                tmp + (size_t)y * rowlen + (size_t)x * C, 1);
        float *dst = res + (size_t)b * h * rowlen;
        for (int y = 0; y < h; y++)
            for (int s = 0; s < cy[y]; s++)
                cblas_saxpy((int)rowlen, wy[y * my + s], tmp + (size_t)(fy[y] + s) * rowlen, 1,
                            dst + (size_t)y * rowlen, 1);
    }
done:
    free(fx), free(wx), free(tmp);
    if (r != BTF_OK)
        free(res), res = NULL;
    *out = res;
    return r;
}

/* ------------------------------------------------------------ reconstruction */

/* Texels per sgemm: 3N x 128 outputs (124 KB for N = 81) stay in cache for the
 * scatter, and a call this small runs single-threaded inside OpenBLAS, so the
 * OpenMP workers below do not oversubscribe the cores. */
#define TEXEL_CHUNK 128

/* Writes rows (3N x n texels, row (l*3+c)) of view v into b at texels t0.. */
static void scatter(btf *b, int v, const float *rows, size_t t0, size_t n)
{
    int N = b->lights.n_dirs;
    size_t T = (size_t)b->width * b->height;
    for (int l = 0; l < N; l++) {
        size_t base = (((size_t)v * N + l) * T + t0) * 3u;
        const float *r0 = rows + (size_t)l * 3 * n, *r1 = r0 + n, *r2 = r1 + n;
        if (b->storage == BTF_F32) {
            float *d = (float *)b->data + base;
            for (size_t t = 0; t < n; t++)
                d[3 * t] = r0[t], d[3 * t + 1] = r1[t], d[3 * t + 2] = r2[t];
        } else {
            uint8_t *d = (uint8_t *)b->data + base;
            for (size_t t = 0; t < n; t++)
                d[3 * t] = btf_to_u8(r0[t]), d[3 * t + 1] = btf_to_u8(r1[t]), d[3 * t + 2] = btf_to_u8(r2[t]);
        }
    }
}

/* out = (V rows of view v, scaled by sigma of its block) x L_b^T, chunked over texels. */
static void reconstruct_view(const btf_thesis_pkg *p, const float *Lb, int v, float *wv, float *rows, btf *b)
{
    int C = p->C, M = 3 * p->N, blk = v / p->k;
    const float *V = p->V + (size_t)v * M * C, *sg = p->sigma + (size_t)blk * C;
    for (int r = 0; r < M; r++)
        for (int j = 0; j < C; j++)
            wv[r * C + j] = V[(size_t)r * C + j] * sg[j];
    size_t T = (size_t)b->width * b->height;
    for (size_t t0 = 0; t0 < T; t0 += TEXEL_CHUNK) {
        size_t n = T - t0 < TEXEL_CHUNK ? T - t0 : TEXEL_CHUNK;
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, M, (int)n, C, 1.0f, wv, C, Lb + t0 * C, C, 0.0f, rows,
                    (int)n);
        scatter(b, v, rows, t0, n);
    }
}

/* Reconstructs every view on OpenMP's threads (OMP_NUM_THREADS), one view at a time
 * each (the scatter into the output is memory-bound; BLAS threads alone leave it on
 * one core); 0 when out of memory. */
static int recon_all(const btf_thesis_pkg *p, const float *L, btf *b)
{
    size_t T = (size_t)b->width * b->height;
    int failed = 0;
#pragma omp parallel
    {
        float *wv = malloc(sizeof(float) * 3u * p->N * p->C);
        float *rows = malloc(sizeof(float) * 3u * p->N * TEXEL_CHUNK);
        if (!wv || !rows) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 1)
        for (int v = 0; v < p->N; v++)
            if (wv && rows)
                reconstruct_view(p, L + (size_t)(v / p->k) * T * p->C, v, wv, rows, b);
        free(wv);
        free(rows);
    }
    return !failed;
}

btf_result btf_thesis_reconstruct(const btf_thesis_pkg *p, const btf_dirset *dirs, int width, int height,
                                  btf_storage storage, btf **out, btf_error *err)
{
    if (!p || !out || !p->L)
        return btf_fail(err, BTF_ERR_ARG, "btf_thesis_reconstruct: NULL argument");
    *out = NULL;
    btf_dirset d;
    if (dirs)
        d = *dirs;
    else if (p->N == 81)
        d = btf_dirset_ubo2003();
    else if (p->N == 151)
        d = btf_dirset_dome151();
    else
        return btf_fail(err, BTF_ERR_UNSUPPORTED,
                        "thesis package: no built-in sampling with %d directions (pass one)", p->N);
    if (d.n_dirs != p->N)
        return btf_fail(err, BTF_ERR_ARG, "thesis package has %d directions, sampling has %d", p->N, d.n_dirs);
    int w = width > 0 ? width : p->S, h = height > 0 ? height : p->S;
    btf_result r = btf_create(w, h, &d, &d, storage ? storage : BTF_U8, out, err);
    if (r != BTF_OK)
        return r;
    float *L = p->L;
    if ((w != p->S || h != p->S) && (r = resample_l(p, w, h, &L, err)) != BTF_OK) {
        btf_free(*out), *out = NULL;
        return r;
    }
    if (!recon_all(p, L, *out)) {
        r = btf_fail(err, BTF_ERR_NOMEM, "thesis import: out of memory");
        btf_free(*out), *out = NULL;
    }
    if (L != p->L)
        free(L);
    return r;
}

btf_result btf_import_thesis(const char *dir, const btf_load_options *opt, btf **out, btf_error *err)
{
    if (!dir || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_import_thesis: NULL argument");
    *out = NULL;
    btf_load_options o = opt ? *opt : (btf_load_options){0};
    btf_thesis_pkg p;
    btf_result r = btf_thesis_read(dir, &p, err);
    if (r != BTF_OK)
        return r;
    int w = o.width, h = o.height;
    if (o.downsample > 1) {
        w = w ? w : p.S / o.downsample;
        h = h ? h : p.S / o.downsample;
    }
    if (w < 0 || h < 0 || w > BTF_MAX_SIDE || h > BTF_MAX_SIDE || (o.downsample > 1 && (w < 1 || h < 1))) {
        btf_thesis_free(&p);
        return btf_fail(err, BTF_ERR_ARG, "%s: requested size %dx%d invalid", dir, w, h);
    }
    r = btf_thesis_reconstruct(&p, o.sampling, w, h, o.storage, out, err);
    btf_thesis_free(&p);
    return r;
}
