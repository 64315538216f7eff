/* btf_dfmf.c - UBO2014 DFMF08FC `.btf` reader and writer (doc/input-formats.md section 2).
 *
 * Reader: signature "!DFMF08FC" optionally followed by "R" (rotations stored;
 * a 10th byte 'R' is taken as that flag), header versions 1..4, direction lists
 * that form rings (grouped by theta, equally spaced in phi) become ring sets,
 * others an explicit list set in file order (btf_dirset_make_list), scalars of 2 (half), 4 or 8 bytes, colour models
 * 0 (plain RGB: the three channels are R, G, B) and 11 (log-YUV as in the spec).
 * The colour mean/transform fields, the RGB scale and the cosine flag are read but
 * not applied (their meaning is unconfirmed). Every count is bounded before
 * allocating, and every matrix against the bytes the file really has (fstat).
 *
 * Writer: "!DFMF08FCR" with 0 rotations, version 4 header with channels R, G, B,
 * colour model 0, float32 scalars, directions in canonical order. Full rank stores
 * the data exactly (one factor is the identity); a truncated rank uses the Gram
 * matrix of the smaller side (cblas_ssyrk) and LAPACKE_ssyevr for its top
 * eigenpairs: the best rank-K approximation in the Frobenius norm. A factor that is
 * exactly the identity is decoded as a copy of the other (the same floats).
 */
#include <cblas.h>
#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_fs.h"
#include "btf_io.h"
#include "btf_views.h"
#include "btf_common.h"
#include "btf_input.h"

#define SIG "!DFMF08FC"
#define SIG_LEN 9
#define MAX_CHANNELS 16
#define MAX_NAME 4096
#define EPS_YUV 1e-5f

/* ------------------------------------------------------------ reading primitives */

/* One open file being parsed; lives for one btf_load_dfmf call. */
typedef struct dfmf_reader {
    FILE *f;
    const char *path;
    uint64_t size, pos; /* file size (fstat) and current offset */
    btf_error *err;
    uint64_t max_factors, factors; /* bound on the factor bytes held (0 = none), bytes so far */
} dfmf_reader;

static btf_result rd_bytes(dfmf_reader *r, void *buf, size_t n, const char *what)
{
    if (n > r->size - r->pos)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: truncated: %s needs %zu bytes at offset %llu, %llu left",
                        r->path, what, n, (unsigned long long)r->pos, (unsigned long long)(r->size - r->pos));
    if (n && fread(buf, 1, n, r->f) != n)
        return btf_fail(r->err, BTF_ERR_IO, "%s: read error at offset %llu (%s)", r->path,
                        (unsigned long long)r->pos, what);
    r->pos += n;
    return BTF_OK;
}

static btf_result rd_skip(dfmf_reader *r, uint64_t n, const char *what)
{
    if (n > r->size - r->pos)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: truncated: %s needs %llu bytes at offset %llu, %llu left",
                        r->path, what, (unsigned long long)n, (unsigned long long)r->pos,
                        (unsigned long long)(r->size - r->pos));
    if (fseeko(r->f, (off_t)(r->pos + n), SEEK_SET) != 0)
        return btf_fail(r->err, BTF_ERR_IO, "%s: seek failed (%s)", r->path, what);
    r->pos += n;
    return BTF_OK;
}

static uint32_t le32(const uint8_t *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static btf_result rd_u32(dfmf_reader *r, uint32_t *v, const char *what)
{
    uint8_t b[4];
    btf_result res = rd_bytes(r, b, 4, what);
    *v = res == BTF_OK ? le32(b) : 0;
    return res;
}

static float f32_of(uint32_t u)
{
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static btf_result rd_f32(dfmf_reader *r, float *v, int n, const char *what)
{
    for (int i = 0; i < n; i++) {
        uint32_t u;
        btf_result res = rd_u32(r, &u, what);
        if (res != BTF_OK)
            return res;
        v[i] = f32_of(u);
    }
    return BTF_OK;
}

/* IEEE half to float (subnormals, infinities and NaN included). */
static float half_to_float(uint16_t h)
{
    uint32_t sign = (uint32_t)(h >> 15) << 31, e = (h >> 10) & 0x1f, m = h & 0x3ff;
    float v;
    if (e == 0)
        v = ldexpf((float)m, -24);
    else if (e == 31)
        v = m ? NAN : INFINITY;
    else
        v = ldexpf((float)(m | 0x400), (int)e - 25);
    return sign ? -v : v;
}

/* Reads n scalars of `ssize` bytes (2, 4, 8) into floats, in bounded chunks. */
static btf_result rd_scalars(dfmf_reader *r, int ssize, size_t n, float *dst, const char *what)
{
    uint8_t buf[8192];
    size_t per = sizeof buf / (size_t)ssize;
    for (size_t i = 0; i < n; i += per) {
        size_t m = n - i < per ? n - i : per;
        btf_result res = rd_bytes(r, buf, m * (size_t)ssize, what);
        if (res != BTF_OK)
            return res;
        for (size_t j = 0; j < m; j++) {
            const uint8_t *b = buf + j * (size_t)ssize;
            if (ssize == 2) {
                dst[i + j] = half_to_float((uint16_t)(b[0] | b[1] << 8));
            } else if (ssize == 4) {
                dst[i + j] = f32_of(le32(b));
            } else {
                uint64_t u = (uint64_t)le32(b) | (uint64_t)le32(b + 4) << 32;
                double d;
                memcpy(&d, &u, 8);
                dst[i + j] = (float)d;
            }
            if (!isfinite(dst[i + j]))
                return btf_fail(r->err, BTF_ERR_NUMERIC, "%s: non-finite value in %s (entry %zu)", r->path, what,
                                i + j);
        }
    }
    return BTF_OK;
}

/* ------------------------------------------------------------ header */

/* What the header says; lives on the loader's stack. */
typedef struct dfmf_header {
    int rotations;
    uint32_t version, channels, width, height, n_components;
    int32_t color_model;
    int n_views, n_lights;
    float view_dir[BTF_MAX_DIRS][2], light_dir[BTF_MAX_DIRS][2]; /* theta, phi radians, file order */
} dfmf_header;

static btf_result check_signature(dfmf_reader *r, dfmf_header *h)
{
    char sig[11] = {0};
    size_t n = r->size < 10 ? (size_t)r->size : 10;
    btf_result res = rd_bytes(r, sig, n, "signature");
    if (res != BTF_OK)
        return res;
    if (n >= SIG_LEN && memcmp(sig, SIG, SIG_LEN) == 0) {
        h->rotations = n == 10 && sig[9] == 'R';
        if (h->rotations)
            return BTF_OK;
        if (fseeko(r->f, SIG_LEN, SEEK_SET) != 0)
            return btf_fail(r->err, BTF_ERR_IO, "%s: seek failed", r->path);
        r->pos = SIG_LEN;
        return BTF_OK;
    }
    static const char *known[] = {"!FMF12FCER", "!FMF06FCR", "!FMF06FC", "!PVF06FCR", "!PVF06FC", "!BDIF06R2!"};
    for (size_t i = 0; i < sizeof known / sizeof known[0]; i++)
        if (n >= strlen(known[i]) && memcmp(sig, known[i], strlen(known[i])) == 0)
            return btf_fail(r->err, BTF_ERR_UNSUPPORTED,
                            "%s: signature \"%s\" is a Bonn BTF format this library does not read (only " SIG "[R])",
                            r->path, known[i]);
    char shown[41] = {0};
    for (size_t i = 0; i < n; i++)
        shown[i] = sig[i] >= 32 && sig[i] < 127 ? sig[i] : '?';
    return btf_fail(r->err, BTF_ERR_FORMAT, "%s: not a DFMF08FC file (signature \"%s\")", r->path, shown);
}

static btf_result read_meta_block(dfmf_reader *r, dfmf_header *h)
{
    uint64_t start = r->pos;
    uint32_t size, u;
    btf_result res = rd_u32(r, &size, "header size");
    if (res == BTF_OK)
        res = rd_u32(r, &h->version, "version");
    if (res != BTF_OK)
        return res;
    if (h->version < 1 || h->version > 4)
        return btf_fail(r->err, BTF_ERR_UNSUPPORTED, "%s: header version %u (only 1..4 are known)", r->path,
                        h->version);
    float f[4];
    if ((res = rd_skip(r, 240, "setup strings")) != BTF_OK || (res = rd_f32(r, f, 4, "ppmm/rgb scale")) != BTF_OK)
        return res;
    if (h->version > 1 && (res = rd_u32(r, &u, "cosine flag")) != BTF_OK)
        return res;
    if (h->version > 2 && ((res = rd_u32(r, &u, "XML length")) != BTF_OK || (res = rd_skip(r, u, "XML")) != BTF_OK))
        return res;
    h->channels = 3;
    if (h->version > 3) {
        if ((res = rd_u32(r, &h->channels, "channel count")) != BTF_OK)
            return res;
        if (h->channels < 1 || h->channels > MAX_CHANNELS)
            return btf_fail(r->err, BTF_ERR_RANGE, "%s: %u channels (1..%d allowed)", r->path, h->channels,
                            MAX_CHANNELS);
        for (uint32_t c = 0; c < h->channels; c++) {
            if ((res = rd_u32(r, &u, "channel name length")) != BTF_OK)
                return res;
            if (u > MAX_NAME)
                return btf_fail(r->err, BTF_ERR_RANGE, "%s: channel %u name length %u too long", r->path, c, u);
            if ((res = rd_skip(r, u, "channel name")) != BTF_OK)
                return res;
        }
    }
    if (r->pos - start != size)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: header size field %u but %llu header bytes read", r->path, size,
                        (unsigned long long)(r->pos - start));
    return BTF_OK;
}

static btf_result read_directions(dfmf_reader *r, dfmf_header *h)
{
    uint32_t nv, nl = 0, u;
    btf_result res = rd_u32(r, &nv, "view count");
    if (res != BTF_OK)
        return res;
    if (nv < 1 || nv > BTF_MAX_DIRS)
        return btf_fail(r->err, BTF_ERR_RANGE, "%s: %u views (1..%d allowed)", r->path, nv, BTF_MAX_DIRS);
    for (uint32_t v = 0; v < nv; v++) {
        if ((res = rd_f32(r, h->view_dir[v], 2, "view direction")) != BTF_OK ||
            (res = rd_u32(r, &u, "light count")) != BTF_OK)
            return res;
        if (u < 1 || u > BTF_MAX_DIRS)
            return btf_fail(r->err, BTF_ERR_RANGE, "%s: view %u has %u lights (1..%d allowed)", r->path, v, u,
                            BTF_MAX_DIRS);
        if (v == 0) {
            nl = u;
            for (uint32_t l = 0; l < nl && res == BTF_OK; l++)
                res = rd_f32(r, h->light_dir[l], 2, "light direction");
        } else if (u != nl) {
            return btf_fail(r->err, BTF_ERR_UNSUPPORTED, "%s: view %u has %u lights, view 0 has %u", r->path, v, u,
                            nl);
        } else {
            res = rd_skip(r, (uint64_t)u * 8u, "light directions");
        }
        if (res != BTF_OK)
            return res;
    }
    h->n_views = (int)nv, h->n_lights = (int)nl;
    if ((res = rd_u32(r, &h->width, "width")) != BTF_OK || (res = rd_u32(r, &h->height, "height")) != BTF_OK)
        return res;
    if (h->width < 1 || h->height < 1 || h->width > BTF_MAX_SIDE || h->height > BTF_MAX_SIDE)
        return btf_fail(r->err, BTF_ERR_RANGE, "%s: size %ux%u outside 1..%d", r->path, h->width, h->height,
                        BTF_MAX_SIDE);
    if (h->rotations) {
        if ((res = rd_u32(r, &u, "rotation count")) != BTF_OK)
            return res;
        if ((res = rd_skip(r, (uint64_t)u * 36u, "rotations")) != BTF_OK)
            return res;
    }
    return BTF_OK;
}

static btf_result read_color_block(dfmf_reader *r, dfmf_header *h)
{
    float f[12];
    uint32_t u;
    btf_result res = rd_u32(r, &h->n_components, "component count");
    if (res == BTF_OK)
        res = rd_u32(r, &u, "colour model");
    if (res == BTF_OK)
        res = rd_f32(r, f, 12, "colour mean/transform");
    if (res != BTF_OK)
        return res;
    h->color_model = (int32_t)u;
    if (h->color_model != 0 && h->color_model != 11)
        return btf_fail(r->err, BTF_ERR_UNSUPPORTED, "%s: colour model %d (only 0 = RGB and 11 = log-YUV)", r->path,
                        (int)h->color_model);
    if (h->channels != 3)
        return btf_fail(r->err, BTF_ERR_UNSUPPORTED, "%s: %u channels (colour model %d needs 3)", r->path,
                        h->channels, (int)h->color_model);
    uint64_t rows = (uint64_t)h->n_views * (uint64_t)h->n_lights;
    if (h->n_components > rows)
        return btf_fail(r->err, BTF_ERR_RANGE, "%s: %u components exceed the %llu rows", r->path, h->n_components,
                        (unsigned long long)rows);
    return BTF_OK;
}

/* ------------------------------------------------------------ directions -> rings */

static float snap(double deg) { return (float)(round(deg * 1000.0) / 1000.0); }

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Builds a ring set from (theta, phi) radians and maps file index -> canonical index. */
static btf_result make_rings(const float (*dir)[2], int n, int strict, const char *what, const char *path,
                             btf_dirset *out, int *map, btf_error *err)
{
    const float tol = 0.01f; /* degrees; float radians carry ~1e-5 deg */
    float *th = malloc(sizeof(float) * (size_t)n * 2), *ph = th ? th + n : NULL;
    if (!th)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    for (int i = 0; i < n; i++) {
        th[i] = snap(dir[i][0] * (180.0 / M_PI));
        double p = fmod(dir[i][1] * (180.0 / M_PI), 360.0);
        ph[i] = snap(p < 0 ? p + 360.0 : p);
        if (!isfinite(th[i]) || !isfinite(ph[i]) || th[i] < -tol || th[i] > 90.0f + tol) {
            double bad = th[i];
            free(th);
            return btf_fail(err, BTF_ERR_RANGE, "%s: %s direction %d has theta %g deg", path, what, i, bad);
        }
    }
    btf_ring rings[BTF_MAX_RINGS] = {{0}};
    int nr = 0, used = 0;
    btf_result res = BTF_OK;
    float *ring_phi = malloc(sizeof(float) * (size_t)n);
    while (res == BTF_OK && ring_phi && used < n) {
        float t = INFINITY; /* next smallest theta not yet assigned */
        for (int i = 0; i < n; i++)
            if (th[i] < t && (nr == 0 || th[i] > rings[nr - 1].theta_deg + tol))
                t = th[i];
        int m = 0;
        for (int i = 0; i < n; i++)
            if (fabsf(th[i] - t) <= tol)
                ring_phi[m++] = ph[i];
        if (m == 0 || used + m > n) { /* thetas closer than tol to two rings */
            res = btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: %s directions near theta %g do not form rings", path, what,
                           (double)t);
            break;
        }
        if (nr == BTF_MAX_RINGS) {
            res = btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: %s directions form more than %d rings", path, what,
                           BTF_MAX_RINGS);
            break;
        }
        if (strict && m == 1 && t > tol) { /* one direction off the pole: rather a list */
            res = btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: %s direction at theta %g is alone on its ring", path, what,
                           (double)t);
            break;
        }
        qsort(ring_phi, (size_t)m, sizeof(float), cmp_float);
        for (int i = 1; i < m && res == BTF_OK; i++)
            if (fabsf(ring_phi[i] - ring_phi[0] - (float)i * 360.0f / (float)m) > tol)
                res = btf_fail(err, BTF_ERR_UNSUPPORTED,
                               "%s: %s directions at theta %g are not equally spaced in phi (%d on the ring): "
                               "not a ring sampling",
                               path, what, (double)t, m);
        rings[nr++] = (btf_ring){t < 0 ? 0.0f : t, m, ring_phi[0]};
        used += m;
    }
    free(ring_phi);
    if (res == BTF_OK && used < n)
        res = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    if (res == BTF_OK)
        res = btf_dirset_make(rings, nr, out, err);
    for (int i = 0; i < n && res == BTF_OK; i++) {
        map[i] = btf_dirset_find(out, th[i] < 0 ? 0.0f : th[i], ph[i], tol);
        if (map[i] < 0)
            res = btf_fail(err, BTF_ERR_FORMAT, "%s: %s direction %d not found in its ring", path, what, i);
        for (int j = 0; j < i && res == BTF_OK; j++)
            if (map[j] == map[i])
                res = btf_fail(err, BTF_ERR_FORMAT, "%s: %s directions %d and %d coincide", path, what, j, i);
    }
    free(th);
    return res;
}

/* A list set of the file's directions in file order. */
static btf_result make_list(const float (*dir)[2], int n, btf_dirset *out, int *map, btf_error *err)
{
    if (n > BTF_MAX_LIST_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "%d directions are more than a list holds (%d)", n, BTF_MAX_LIST_DIRS);
    float(*deg)[2] = malloc(sizeof(float[2]) * (size_t)(n > 0 ? n : 1));
    if (!deg)
        return btf_fail(err, BTF_ERR_NOMEM, "out of memory");
    for (int i = 0; i < n; i++) {
        deg[i][0] = fmaxf((float)(dir[i][0] * (180.0 / M_PI)), 0.0f);
        deg[i][1] = (float)(dir[i][1] * (180.0 / M_PI));
        map[i] = i;
    }
    btf_result res = btf_dirset_make_list((const float(*)[2])deg, n, out, err);
    free(deg);
    return res;
}

/* A ring set when the directions form rings (no direction alone on a ring off the
 * pole), else a list set in file order; rings with lone directions when no list fits. */
static btf_result make_dirset(const float (*dir)[2], int n, const char *what, const char *path, btf_dirset *out,
                              int *map, btf_error *err)
{
    btf_error ring_err = {{0}}, list_err = {{0}};
    btf_result res = make_rings(dir, n, 1, what, path, out, map, &ring_err);
    if (res == BTF_ERR_UNSUPPORTED && make_list(dir, n, out, map, &list_err) == BTF_OK)
        return BTF_OK;
    if (res == BTF_ERR_UNSUPPORTED && make_rings(dir, n, 0, what, path, out, map, NULL) == BTF_OK)
        return BTF_OK;
    if (res == BTF_ERR_UNSUPPORTED)
        return btf_fail(err, res, "%s; as a direction list: %s", ring_err.msg, list_err.msg);
    return res == BTF_OK ? BTF_OK : btf_fail(err, res, "%s", ring_err.msg);
}

/* ------------------------------------------------------------ channel matrices */

/* One channel's factors as floats; malloc'd, lives for one load. */
typedef struct dfmf_channel {
    int k;      /* components */
    float *U;   /* rows x k, row-major */
    float *SxV; /* cols x k, row-major */
    /* 1: U (or SxV) is the identity, as btf_save_dfmf writes a full rank */
    int u_identity, sxv_identity;
} dfmf_channel;

/* 1 when M (rows x k) is the identity. */
static int is_identity(const float *M, uint32_t rows, int k)
{
    if ((uint32_t)k != rows)
        return 0;
    for (size_t i = 0; i < rows; i++)
        for (size_t j = 0; j < (size_t)k; j++)
            if (M[i * k + j] != (i == j ? 1.0f : 0.0f))
                return 0;
    return 1;
}

static btf_result read_channel(dfmf_reader *r, const dfmf_header *h, int c, dfmf_channel *ch)
{
    uint8_t ssize;
    uint32_t k, rows, cols;
    btf_result res = rd_bytes(r, &ssize, 1, "scalar size");
    if (res == BTF_OK)
        res = rd_u32(r, &k, "channel components");
    if (res == BTF_OK)
        res = rd_u32(r, &rows, "channel rows");
    if (res == BTF_OK)
        res = rd_u32(r, &cols, "channel columns");
    if (res != BTF_OK)
        return res;
    if (ssize != 2 && ssize != 4 && ssize != 8)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: channel %d scalar size %u (2, 4 or 8 expected)", r->path, c,
                        ssize);
    uint64_t want_rows = (uint64_t)h->n_views * (uint64_t)h->n_lights, want_cols = (uint64_t)h->width * h->height;
    if (rows != want_rows || cols != want_cols)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: channel %d is %u x %u, expected %llu x %llu", r->path, c, rows,
                        cols, (unsigned long long)want_rows, (unsigned long long)want_cols);
    if (k == 0)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: channel %d has 0 components (at least 1 needed)", r->path, c);
    if (k > h->n_components)
        return btf_fail(r->err, BTF_ERR_RANGE, "%s: channel %d has %u components, header says at most %u", r->path,
                        c, k, h->n_components);
    uint64_t bytes = (uint64_t)k * (1u + (uint64_t)rows + cols) * ssize;
    if (bytes > r->size - r->pos)
        return btf_fail(r->err, BTF_ERR_FORMAT, "%s: truncated: channel %d needs %llu bytes at offset %llu, %llu left",
                        r->path, c, (unsigned long long)bytes, (unsigned long long)r->pos,
                        (unsigned long long)(r->size - r->pos));
    ch->k = (int)k;
    r->factors += (uint64_t)k * ((uint64_t)rows + cols) * sizeof(float);
    if (r->max_factors && r->factors > r->max_factors)
        return btf_fail(r->err, BTF_ERR_RANGE,
                        "%s: the factors (rank %u, %u x %u per channel) need %.0f MB as floats, more than the %.0f MB "
                        "a view-by-view read holds",
                        r->path, k, rows, cols, (double)r->factors / 1e6, (double)r->max_factors / 1e6);
    if ((res = rd_skip(r, (uint64_t)k * ssize, "singular values")) != BTF_OK)
        return res;
    ch->U = malloc(sizeof(float) * ((size_t)rows * k + 1));
    ch->SxV = malloc(sizeof(float) * ((size_t)cols * k + 1));
    if (!ch->U || !ch->SxV)
        return btf_fail(r->err, BTF_ERR_NOMEM, "%s: cannot allocate channel %d factors", r->path, c);
    res = rd_scalars(r, ssize, (size_t)rows * k, ch->U, "U");
    if (res == BTF_OK)
        res = rd_scalars(r, ssize, (size_t)cols * k, ch->SxV, "SxV");
    ch->u_identity = res == BTF_OK && is_identity(ch->U, rows, ch->k);
    ch->sxv_identity = res == BTF_OK && !ch->u_identity && is_identity(ch->SxV, cols, ch->k);
    return res;
}

/* ------------------------------------------------------------ decoding */

/* Converts the three channel values of one texel to RGB by the colour model. */
static void to_rgb(int model, float a, float b, float c, float rgb[3])
{
    if (model == 0) {
        rgb[0] = a, rgb[1] = b, rgb[2] = c;
        return;
    }
    float Y = expf(a) - EPS_YUV, U = b * (Y + EPS_YUV), V = c * (Y + EPS_YUV);
    rgb[0] = Y + 1.13983f * V;
    rgb[1] = Y - 0.39465f * U - 0.5806f * V;
    rgb[2] = Y + 2.03211f * U;
}

/* Rows r0..r0+n of every channel (n x T each, into buf + c*n*T): the one product
 * both the whole-file loader and the view-by-view reader compute, on the same row
 * chunks (decode_chunk_rows), so both give the same floats. */
static void decode_rows(const dfmf_header *h, const dfmf_channel *ch, int r0, int n, float *buf)
{
    size_t T = (size_t)h->width * h->height;
    for (int c = 0; c < 3; c++) {
        float *o = buf + (size_t)c * n * T;
        if (ch[c].k == 0) {
            memset(o, 0, sizeof(float) * (size_t)n * T);
        } else if (ch[c].u_identity) { /* rows r0.. of SxV^T: the product's floats, without its work */
            for (size_t t = 0; t < T; t++) {
                const float *s = ch[c].SxV + t * (size_t)ch[c].k + r0;
                for (int i = 0; i < n; i++)
                    o[(size_t)i * T + t] = s[i];
            }
        } else if (ch[c].sxv_identity) { /* rows r0.. of U, likewise */
            memcpy(o, ch[c].U + (size_t)r0 * T, sizeof(float) * (size_t)n * T);
        } else {
            cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, n, (int)T, ch[c].k, 1.0f,
                        ch[c].U + (size_t)r0 * ch[c].k, ch[c].k, ch[c].SxV, ch[c].k, 0.0f, o, (int)T);
        }
    }
}

/* Rows per decoded chunk: about 2^20 samples per channel. */
static int decode_chunk_rows(const dfmf_header *h)
{
    size_t T = (size_t)h->width * h->height;
    int rows = h->n_views * h->n_lights, chunk = (int)((1u << 20) / T);
    return chunk < 1 ? 1 : chunk > rows ? rows : chunk;
}

/* Row i of a decoded chunk of n rows (buf) into b's image (v, l). */
static void store_row(const dfmf_header *h, const float *buf, int n, int i, int v, int l, btf *b)
{
    size_t T = (size_t)h->width * h->height;
    const float *a = buf + (size_t)i * T, *bb = a + (size_t)n * T, *cc = bb + (size_t)n * T;
    size_t base = btf_index(b, v, l, 0, 0, 0);
    for (size_t t = 0; t < T; t++) {
        float rgb[3];
        to_rgb(h->color_model, a[t], bb[t], cc[t], rgb);
        if (b->storage == BTF_F32) {
            float *d = (float *)b->data + base + 3 * t;
            d[0] = rgb[0], d[1] = rgb[1], d[2] = rgb[2];
        } else {
            uint8_t *d = (uint8_t *)b->data + base + 3 * t;
            d[0] = btf_to_u8(rgb[0]), d[1] = btf_to_u8(rgb[1]), d[2] = btf_to_u8(rgb[2]);
        }
    }
}

static btf_result decode_all(const dfmf_header *h, const dfmf_channel *ch, const int *vmap, const int *lmap,
                             btf *b, const char *path, btf_error *err)
{
    size_t T = (size_t)h->width * h->height;
    int rows = h->n_views * h->n_lights, chunk = decode_chunk_rows(h);
    float *buf = malloc(sizeof(float) * 3u * (size_t)chunk * T);
    if (!buf)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    for (int r0 = 0; r0 < rows; r0 += chunk) {
        int n = rows - r0 < chunk ? rows - r0 : chunk;
        decode_rows(h, ch, r0, n, buf);
        for (int i = 0; i < n; i++)
            store_row(h, buf, n, i, vmap[(r0 + i) / h->n_lights], lmap[(r0 + i) % h->n_lights], b);
    }
    free(buf);
    return b->storage == BTF_F32 ? btf_check_finite(b, err) : BTF_OK;
}

/* ------------------------------------------------------------ loader */

/* Parses everything up to the matrices; fills the direction sets and maps. */
static btf_result read_header(dfmf_reader *r, dfmf_header *h, btf_dirset *views, btf_dirset *lights, int *vmap,
                              int *lmap)
{
    btf_result res = check_signature(r, h);
    if (res == BTF_OK)
        res = read_meta_block(r, h);
    if (res == BTF_OK)
        res = read_directions(r, h);
    if (res == BTF_OK)
        res = read_color_block(r, h);
    if (res == BTF_OK)
        res = make_dirset((const float(*)[2])h->view_dir, h->n_views, "view", r->path, views, vmap, r->err);
    if (res == BTF_OK)
        res = make_dirset((const float(*)[2])h->light_dir, h->n_lights, "light", r->path, lights, lmap, r->err);
    return res;
}

#define BTF_DFMF_MAX_EXPANSION 65536 /* decoded bytes per file byte, at most */

/* The decoded BTF may be at most BTF_DFMF_MAX_EXPANSION times the file's size (a
 * rank-k factorisation expands by about rows*cols / (k*(rows+cols))): a small file
 * cannot make the loader allocate gigabytes. */
static btf_result check_expansion(const dfmf_reader *r, const dfmf_header *h, btf_storage st)
{
    double samples = (double)h->n_views * h->n_lights * h->width * h->height * 3.0;
    double bytes = samples * (st == BTF_U8 ? 1.0 : 4.0), limit = (double)r->size * BTF_DFMF_MAX_EXPANSION;
    if (bytes > limit)
        return btf_fail(r->err, BTF_ERR_RANGE,
                        "%s: %u x %u texels x %u x %u directions would decode to %.0f MB from a %llu-byte file "
                        "(more than %d times its size)",
                        r->path, h->width, h->height, h->n_views, h->n_lights, bytes / 1e6,
                        (unsigned long long)r->size, BTF_DFMF_MAX_EXPANSION);
    return BTF_OK;
}

static btf_result load_open(dfmf_reader *r, const btf_load_options *o, btf **out)
{
    dfmf_header *h = calloc(1, sizeof *h);
    int *map = malloc(sizeof(int) * 2 * BTF_MAX_DIRS);
    dfmf_channel ch[3] = {{0}};
    btf_dirset views, lights;
    btf_result res = h && map ? read_header(r, h, &views, &lights, map, map + BTF_MAX_DIRS)
                              : btf_fail(r->err, BTF_ERR_NOMEM, "%s: out of memory", r->path);
    for (int c = 0; c < 3 && res == BTF_OK; c++)
        res = read_channel(r, h, c, &ch[c]);
    if (res == BTF_OK && r->pos != r->size)
        res = btf_fail(r->err, BTF_ERR_FORMAT, "%s: %llu trailing bytes after the last channel (offset %llu)",
                       r->path, (unsigned long long)(r->size - r->pos), (unsigned long long)r->pos);
    btf_storage st = o->storage == BTF_U8 ? BTF_U8 : BTF_F32;
    if (res == BTF_OK)
        res = check_expansion(r, h, st);
    if (res == BTF_OK)
        res = btf_create((int)h->width, (int)h->height, &lights, &views, st, out, r->err);
    if (res == BTF_OK)
        res = decode_all(h, ch, map, map + BTF_MAX_DIRS, *out, r->path, r->err);
    if (res != BTF_OK)
        btf_free(*out), *out = NULL;
    for (int c = 0; c < 3; c++)
        free(ch[c].U), free(ch[c].SxV);
    free(h), free(map);
    return res;
}

/* Opens path for reading and gives its size; a missing file, or not a regular one, is an error. */
static btf_result dfmf_open(const char *path, FILE **out, uint64_t *size, btf_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: cannot open (%s)", path,
                        strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(f);
        return btf_fail(err, BTF_ERR_IO, "%s: not a regular file", path);
    }
    *out = f;
    *size = (uint64_t)st.st_size;
    return BTF_OK;
}

btf_result btf_load_dfmf(const char *path, const btf_load_options *opt, btf **out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_load_dfmf: NULL argument");
    *out = NULL;
    btf_load_options o = opt ? *opt : (btf_load_options){0};
    FILE *f = NULL;
    uint64_t size = 0;
    btf_result opened = dfmf_open(path, &f, &size, err);
    if (opened != BTF_OK)
        return opened;
    dfmf_reader r = {f, path, size, 0, err, 0, 0};
    btf_result res = load_open(&r, &o, out);
    fclose(f);
    if (res == BTF_OK && o.downsample > 1) {
        btf *small = NULL;
        res = btf_downsample(*out, o.downsample, &small, err);
        btf_free(*out);
        *out = small;
    }
    return res;
}

/* ------------------------------------------------------------ view by view */

/* A DFMF file read view by view: its factors in memory, one view decoded per fill;
 * heap, owned by its btf_views (impl), freed by dfmf_views_close. */
typedef struct dfmf_views {
    dfmf_header *h;
    dfmf_channel ch[3];
    int *map;        /* file view -> canonical (BTF_MAX_DIRS), then file light -> canonical */
    int *file_view;  /* canonical view -> file view */
    btf_storage st;  /* BTF_F32 (as btf_load_dfmf decodes) or BTF_U8 (rounded like it) */
    int chunk;       /* rows per decoded chunk (decode_chunk_rows) */
    int cur;         /* chunk held in buf, -1 none */
    float *buf;      /* 3 x chunk x texels: the decoded chunk */
    btf one;         /* one view's samples in the loader's layout (view 0 = the view filled) */
} dfmf_views;

static void dfmf_views_close(btf_views *s)
{
    dfmf_views *d = s->impl;
    if (!d)
        return;
    for (int c = 0; c < 3; c++)
        free(d->ch[c].U), free(d->ch[c].SxV);
    free(d->h), free(d->map), free(d->file_view), free(d->buf), free(d->one.data), free(d);
}

static btf_result dfmf_views_fill(btf_views *s, int v, float *cols, btf_error *err)
{
    dfmf_views *d = s->impl;
    int fv = d->file_view[v], L = d->h->n_lights;
    size_t T = (size_t)s->width * (size_t)s->height;
    int rows = d->h->n_views * L;
    for (int i = 0; i < L; i++) { /* the loader's chunks, decoded once each while views go by in order */
        int r = fv * L + i, c = r / d->chunk, n = rows - c * d->chunk < d->chunk ? rows - c * d->chunk : d->chunk;
        if (c != d->cur) {
            decode_rows(d->h, d->ch, c * d->chunk, n, d->buf);
            d->cur = c;
        }
        store_row(d->h, d->buf, n, r - c * d->chunk, 0, d->map[BTF_MAX_DIRS + i], &d->one); /* view 0 of one */
    }
    for (int l = 0; l < L; l++) {
        float *c0 = cols + (size_t)l * 3u * T;
        size_t base = btf_index(&d->one, 0, l, 0, 0, 0);
        if (d->st == BTF_U8) {
            btf_views_put_u8((const uint8_t *)d->one.data + base, T, c0);
            continue;
        }
        const float *p = (const float *)d->one.data + base;
        for (size_t t = 0; t < T; t++, p += 3)
            for (int c = 0; c < 3; c++) {
                if (!isfinite(p[c]))
                    return btf_fail(err, BTF_ERR_NUMERIC, "%s: view %d light %d texel %zu decodes to a non-finite value",
                                    s->name, v, l, t);
                c0[(size_t)c * T + t] = p[c];
            }
    }
    return BTF_OK;
}

btf_result btf_views_open_dfmf(const char *path, const btf_load_options *opt, btf_views *out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_views_open_dfmf: NULL argument");
    memset(out, 0, sizeof *out);
    if (opt && opt->downsample > 1)
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: a .btf file is read view by view without --downsample", path);
    FILE *f = NULL;
    uint64_t size = 0;
    btf_result opened = dfmf_open(path, &f, &size, err);
    if (opened != BTF_OK)
        return opened;
    dfmf_reader r = {f, path, size, 0, err, BTF_VIEWS_MAX_FACTOR_BYTES, 0};
    dfmf_views *d = calloc(1, sizeof *d);
    btf_result res = d ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    if (d) {
        out->impl = d, out->close = dfmf_views_close, out->fill = dfmf_views_fill, out->name = path;
        d->h = calloc(1, sizeof *d->h);
        d->map = malloc(sizeof(int) * 2 * BTF_MAX_DIRS);
        d->file_view = malloc(sizeof(int) * BTF_MAX_DIRS);
        if (!d->h || !d->map || !d->file_view)
            res = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    }
    btf_dirset views, lights;
    if (res == BTF_OK)
        res = read_header(&r, d->h, &views, &lights, d->map, d->map + BTF_MAX_DIRS);
    for (int c = 0; c < 3 && res == BTF_OK; c++)
        res = read_channel(&r, d->h, c, &d->ch[c]);
    if (res == BTF_OK && r.pos != r.size)
        res = btf_fail(err, BTF_ERR_FORMAT, "%s: %llu trailing bytes after the last channel (offset %llu)", path,
                       (unsigned long long)(r.size - r.pos), (unsigned long long)r.pos);
    fclose(f);
    if (res == BTF_OK) {
        dfmf_header *h = d->h;
        for (int i = 0; i < h->n_views; i++)
            d->file_view[d->map[i]] = i;
        d->st = opt && opt->storage == BTF_U8 ? BTF_U8 : BTF_F32;
        size_t T = (size_t)h->width * h->height;
        d->one = (btf){(int)h->width, (int)h->height, lights, views, d->st, NULL, (size_t)h->n_lights * T * 3};
        d->chunk = decode_chunk_rows(h), d->cur = -1;
        d->buf = malloc(sizeof(float) * 3u * (size_t)d->chunk * T);
        d->one.data = malloc(d->one.count * (d->st == BTF_U8 ? 1 : sizeof(float)));
        if (!d->buf || !d->one.data)
            res = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (one view)", path);
        out->width = (int)h->width, out->height = (int)h->height, out->lights = lights, out->views = views;
    }
    if (res != BTF_OK)
        btf_views_close(out);
    return res;
}

/* ------------------------------------------------------------ writer */

/* Output file being written; lives for one btf_save_dfmf call. */
typedef struct dfmf_writer {
    FILE *f;
    int failed;
} dfmf_writer;

static void wr_bytes(dfmf_writer *w, const void *p, size_t n)
{
    if (!w->failed && n && fwrite(p, 1, n, w->f) != n)
        w->failed = 1;
}

static void wr_u32(dfmf_writer *w, uint32_t v)
{
    uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    wr_bytes(w, b, 4);
}

static void wr_f32(dfmf_writer *w, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    wr_u32(w, u);
}

static void wr_dirs(dfmf_writer *w, const btf_dirset *d, int i)
{
    float t, p;
    btf_dirset_angles(d, i, &t, &p);
    wr_f32(w, (float)(t * (M_PI / 180.0)));
    wr_f32(w, (float)(p * (M_PI / 180.0)));
}

static void write_header(dfmf_writer *w, const btf *b, int k)
{
    static const char names[3][2] = {"R", "G", "B"};
    char text[240] = "btf-stream (written by btf_save_dfmf)";
    uint32_t size = 4 + 4 + 240 + 4 + 12 + 4 + 4 + 4 + 3 * (4 + 1);
    wr_bytes(w, "!DFMF08FCR", 10);
    wr_u32(w, size);
    wr_u32(w, 4);
    wr_bytes(w, text, sizeof text); /* setup, sensor, light source: 3 x 80 bytes */
    float ones[4] = {0.0f, 1.0f, 1.0f, 1.0f}; /* ppmm unknown, RGB scale 1 */
    for (int i = 0; i < 4; i++)
        wr_f32(w, ones[i]);
    wr_u32(w, 1); /* cosine factor included, as in measured images */
    wr_u32(w, 0); /* no XML */
    wr_u32(w, 3);
    for (int c = 0; c < 3; c++)
        wr_u32(w, 1), wr_bytes(w, names[c], 1);
    wr_u32(w, (uint32_t)b->views.n_dirs);
    for (int v = 0; v < b->views.n_dirs; v++) {
        wr_dirs(w, &b->views, v);
        wr_u32(w, (uint32_t)b->lights.n_dirs);
        for (int l = 0; l < b->lights.n_dirs; l++)
            wr_dirs(w, &b->lights, l);
    }
    wr_u32(w, (uint32_t)b->width);
    wr_u32(w, (uint32_t)b->height);
    wr_u32(w, 0); /* rotations */
    wr_u32(w, (uint32_t)k);
    wr_u32(w, 0); /* colour model 0: plain RGB */
    for (int i = 0; i < 12; i++)
        wr_f32(w, i >= 3 && (i - 3) % 4 == 0 ? 1.0f : 0.0f); /* mean 0, identity */
}

/* n floats, little-endian, through a buffer (files reach gigabytes). */
static void wr_floats(dfmf_writer *w, const float *a, size_t n)
{
    uint8_t buf[16384];
    for (size_t i = 0; i < n;) {
        size_t m = 0;
        for (; i < n && m + 4 <= sizeof buf; i++, m += 4) {
            uint32_t u;
            memcpy(&u, &a[i], 4);
            buf[m] = (uint8_t)u, buf[m + 1] = (uint8_t)(u >> 8), buf[m + 2] = (uint8_t)(u >> 16),
            buf[m + 3] = (uint8_t)(u >> 24);
        }
        wr_bytes(w, buf, m);
    }
}

/* Channel c of b as a rows x cols matrix (row = view*nL + light, col = texel). */
static void channel_matrix(const btf *b, int c, float *A)
{
    size_t rows = (size_t)b->views.n_dirs * b->lights.n_dirs, T = (size_t)b->width * b->height;
    for (size_t r = 0; r < rows; r++)
        for (size_t t = 0; t < T; t++) {
            size_t i = (r * T + t) * 3u + (size_t)c;
            A[r * T + t] = b->storage == BTF_U8 ? ((const uint8_t *)b->data)[i] * (1.0f / 255.0f)
                                                : ((const float *)b->data)[i];
        }
}

/* Full rank: whichever factor is square is the identity; exact. */
static void write_full(dfmf_writer *w, const float *A, size_t rows, size_t cols)
{
    size_t k = rows < cols ? rows : cols;
    float *row = calloc(k, sizeof(float));
    if (!row) {
        w->failed = 2;
        return;
    }
    for (size_t i = 0; i < k; i++)
        wr_f32(w, 1.0f); /* S */
    for (size_t r = 0; r < rows; r++) { /* U */
        if (rows <= cols) {
            memset(row, 0, k * sizeof(float));
            row[r] = 1.0f;
            wr_floats(w, row, k);
        } else {
            wr_floats(w, A + r * cols, k);
        }
    }
    for (size_t t = 0; t < cols; t++) { /* SxV */
        if (rows <= cols) {
            for (size_t i = 0; i < k; i++)
                row[i] = A[i * cols + t];
        } else {
            memset(row, 0, k * sizeof(float));
            row[t] = 1.0f;
        }
        wr_floats(w, row, k);
    }
    free(row);
}

/* Top-k eigenpairs of the n x n Gram matrix G (row-major upper = column-major
 * lower), descending, eigenvectors column-major in Z (n x k). */
static int top_eigen(float *G, int n, int k, float *wv, float *Z)
{
    int m = 0;
    int *isuppz = malloc(sizeof(int) * 2u * (size_t)k);
    float *wall = malloc(sizeof(float) * (size_t)n);
    if (!isuppz || !wall) {
        free(isuppz), free(wall);
        return -1;
    }
    lapack_int info = LAPACKE_ssyevr(LAPACK_COL_MAJOR, 'V', 'I', 'L', n, G, n, 0.0f, 0.0f, n - k + 1, n, 0.0f, &m,
                                     wall, Z, n, isuppz);
    free(isuppz);
    if (info != 0 || m != k) {
        free(wall);
        return -1;
    }
    for (int i = 0; i < k / 2; i++) { /* ascending -> descending */
        float t = wall[i];
        wall[i] = wall[k - 1 - i], wall[k - 1 - i] = t;
        for (int r = 0; r < n; r++) {
            float z = Z[(size_t)i * n + r];
            Z[(size_t)i * n + r] = Z[(size_t)(k - 1 - i) * n + r], Z[(size_t)(k - 1 - i) * n + r] = z;
        }
    }
    for (int i = 0; i < k; i++)
        wv[i] = wall[i] > 0.0f ? sqrtf(wall[i]) : 0.0f;
    free(wall);
    return 0;
}

/* Truncated rank k by the Gram route on the smaller side of A (rows x cols). */
static btf_result write_truncated(dfmf_writer *w, const float *A, int rows, int cols, int k, const char *path,
                                  btf_error *err)
{
    int small = rows <= cols, n = small ? rows : cols;
    float *G = malloc(sizeof(float) * (size_t)n * n), *Z = malloc(sizeof(float) * (size_t)n * k);
    float *P = malloc(sizeof(float) * (size_t)(small ? cols : rows) * k), *s = malloc(sizeof(float) * (size_t)k);
    btf_result res = BTF_OK;
    if (!G || !Z || !P || !s) {
        res = btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate the %dx%d Gram matrix", path, n, n);
        goto done;
    }
    cblas_ssyrk(CblasRowMajor, CblasUpper, small ? CblasNoTrans : CblasTrans, n, small ? cols : rows, 1.0f, A, cols,
                0.0f, G, n);
    if (top_eigen(G, n, k, s, Z) != 0) {
        res = btf_fail(err, BTF_ERR_NUMERIC, "%s: eigen decomposition of the Gram matrix failed", path);
        goto done;
    }
    /* Z is column-major (n x k), i.e. a row-major k x n matrix used transposed.
     * small: U = Z (rows x k), SxV = A^T Z. else: P = A Z (rows x k), U = P / s, SxV = Z s. */
    int other = small ? cols : rows;
    cblas_sgemm(CblasRowMajor, small ? CblasTrans : CblasNoTrans, CblasTrans, other, k, n, 1.0f, A, cols, Z, n,
                0.0f, P, k);
    wr_floats(w, s, (size_t)k);
    for (int r = 0; r < rows; r++) {
        for (int i = 0; i < k; i++)
            G[i] = small ? Z[(size_t)i * n + r] : (s[i] > 1e-30f ? P[(size_t)r * k + i] / s[i] : 0.0f);
        wr_floats(w, G, (size_t)k); /* G (n*n >= k floats) reused as a row buffer */
    }
    for (int t = 0; t < cols; t++) {
        for (int i = 0; i < k; i++)
            G[i] = small ? P[(size_t)t * k + i] : Z[(size_t)i * n + t] * s[i];
        wr_floats(w, G, (size_t)k);
    }
done:
    free(G), free(Z), free(P), free(s);
    return res;
}


/* An existing path may be replaced only when it is a .btf file (its signature says
 * so): the writer never overwrites a file it did not write. */
static btf_result check_replaceable(const char *path, btf_error *err)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return BTF_OK;
    char sig[9] = {0};
    FILE *f = S_ISREG(st.st_mode) ? fopen(path, "rb") : NULL;
    size_t n = f ? fread(sig, 1, sizeof sig, f) : 0;
    if (f)
        fclose(f);
    if (st.st_size == 0 || (n == sizeof sig && !memcmp(sig, "!DFMF08FC", 9)))
        return BTF_OK;
    return btf_fail(err, BTF_ERR_IO, "%s: exists and is not a DFMF .btf file; not replaced", path);
}

btf_result btf_save_dfmf(const btf *b, const char *path, int components, btf_error *err)
{
    if (!b || !path || !b->data)
        return btf_fail(err, BTF_ERR_ARG, "btf_save_dfmf: NULL argument");
    size_t rows = (size_t)b->views.n_dirs * b->lights.n_dirs, cols = (size_t)b->width * b->height;
    size_t full = rows < cols ? rows : cols;
    if (components < 0)
        return btf_fail(err, BTF_ERR_ARG, "%s: %d components", path, components);
    if (rows > UINT32_MAX || cols > UINT32_MAX || rows * cols > ((size_t)1 << 31))
        return btf_fail(err, BTF_ERR_RANGE, "%s: %zu x %zu matrix too large for the writer", path, rows, cols);
    int k = components == 0 || (size_t)components >= full ? (int)full : components;
    btf_result ours = check_replaceable(path, err);
    if (ours != BTF_OK)
        return ours;
    char tmp[4200];
    int n = snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    if (n < 0 || (size_t)n >= sizeof tmp)
        return btf_fail(err, BTF_ERR_ARG, "%s: path too long", path);
    float *A = malloc(sizeof(float) * rows * cols);
    dfmf_writer w = {fopen(tmp, "wb"), 0};
    btf_result res = BTF_OK;
    if (!A || !w.f) {
        res = !A ? btf_fail(err, BTF_ERR_NOMEM, "%s: cannot allocate %zu x %zu floats", path, rows, cols)
                 : btf_fail(err, BTF_ERR_IO, "%s: cannot create (%s)", tmp, strerror(errno));
        goto done;
    }
    write_header(&w, b, k);
    for (int c = 0; c < 3 && res == BTF_OK && !w.failed; c++) {
        uint8_t ssize = 4;
        wr_bytes(&w, &ssize, 1);
        wr_u32(&w, (uint32_t)k), wr_u32(&w, (uint32_t)rows), wr_u32(&w, (uint32_t)cols);
        channel_matrix(b, c, A);
        if ((size_t)k == full)
            write_full(&w, A, rows, cols);
        else
            res = write_truncated(&w, A, (int)rows, (int)cols, k, path, err);
    }
    if (fclose(w.f) != 0 && !w.failed)
        w.failed = 1;
    w.f = NULL;
    if (res == BTF_OK && w.failed)
        res = btf_fail(err, w.failed == 2 ? BTF_ERR_NOMEM : BTF_ERR_IO, "%s: write failed", tmp);
    if (res == BTF_OK)
        res = btf_fs_commit_file(tmp, path, err); /* fsync, rename, fsync of the directory */
done:
    if (w.f)
        fclose(w.f);
    if (res != BTF_OK)
        unlink(tmp);
    free(A);
    return res;
}
