/* btf_ubo2003.c - UBO2003 image directories (doc/input-formats.md section 1): loader, writer and view source
 * (btf_load_any and btf_views_open, which pick the reader by the path, are btf_input.c).
 *
 * Loader: scans DIR (flat files and one level of "tvTTT_pvPPP" folders), takes the
 * angles from the last 23 characters of each image stem ("tlTTT_plPPP_tvTTT_pvPPP",
 * separators '_', ' ' or '-'), maps them to the expected sampling within 0.5 degree,
 * checks that every (light, view) pair is present exactly once, then decodes the
 * images on OpenMP threads (OMP_NUM_THREADS) straight into the final buffer, box-filtering each
 * image as it is decoded when a downsampling factor is asked for.
 * Files whose names carry no angles (including a writer's "*.tmp-PID.png") are ignored.
 *
 * Writer: "<prefix>_<NNNNN>_tlTTT_plPPP_tvTTT_pvPPP.<ext>" with NNNNN = light * n_views + view,
 * the numbering of the published UBO2003 files (doc/input-formats.md: "..._00084_tl015_pl000_tv015_pv120"
 * is light 1, view 3); the loader never relies on the number.
 */
#include "btf_fs.h"
#include "btf_image.h"
#include "btf_io.h"
#include "btf_views.h"
#include "btf_common.h"
#include "btf_input.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

/* File angles are whole degrees: half a degree of rounding plus float slack. */
#define BTF__ANGLE_TOL (0.5f + 1e-3f)
#define BTF__ANGLE_CHARS 23 /* strlen("tl000_pl000_tv000_pv000") */

/* ------------------------------------------------------------------ names */

static int btf__is_image_ext(const char *ext)
{
    return !strcasecmp(ext, "png") || !strcasecmp(ext, "jpg") || !strcasecmp(ext, "jpeg");
}

static int btf__is_sep(char c) { return c == '_' || c == ' ' || c == '-'; }

/* Parses "<t0><t1>DDD" at s into *v; 1 on success. */
static int btf__tag3(const char *s, char t0, char t1, int *v)
{
    if ((s[0] | 0x20) != t0 || (s[1] | 0x20) != t1)
        return 0;
    for (int i = 2; i < 5; i++)
        if (s[i] < '0' || s[i] > '9')
            return 0;
    *v = (s[2] - '0') * 100 + (s[3] - '0') * 10 + (s[4] - '0');
    return 1;
}

/* Angles tl, pl, tv, pv of an image file name (basename); 1 if it is a
 * .png/.jpg/.jpeg whose stem ends in the angle pattern, 0 otherwise. */
int btf_ubo2003_name_angles(const char *name, int a[4])
{
    const char *dot = strrchr(name, '.');
    if (!dot || !btf__is_image_ext(dot + 1))
        return 0;
    size_t len = (size_t)(dot - name);
    if (len < BTF__ANGLE_CHARS)
        return 0;
    const char *s = dot - BTF__ANGLE_CHARS;
    return btf__tag3(s, 't', 'l', &a[0]) && btf__is_sep(s[5]) && btf__tag3(s + 6, 'p', 'l', &a[1]) &&
           btf__is_sep(s[11]) && btf__tag3(s + 12, 't', 'v', &a[2]) && btf__is_sep(s[17]) &&
           btf__tag3(s + 18, 'p', 'v', &a[3]);
}

/* A per-view folder name "tvTTT_pvPPP"; 1 if it matches. */
static int btf__parse_folder(const char *name, int *tv, int *pv)
{
    return strlen(name) == 11 && btf__tag3(name, 't', 'v', tv) && btf__is_sep(name[5]) &&
           btf__tag3(name + 6, 'p', 'v', pv);
}

/* ------------------------------------------------------------------ scan */

/* One image file found by the scan; path malloc'd, owned by the btf__scan. */
typedef struct btf__file {
    char *path;
    int a[4]; /* tl, pl, tv, pv of its name */
} btf__file;

/* Everything the scan found; lives for one load call, freed by btf__scan_free.
 * slot[view * n_lights + light] is an index into files or -1. */
typedef struct btf__scan {
    const char *dir;
    const btf_dirset *set;
    btf__file *files; /* malloc'd */
    int n_files, cap;
    int *slot; /* malloc'd, n_slots entries */
    int n_slots;
    int fill; /* missing images may be interpolated (btf_load_options.fill_missing) */
} btf__scan;

static void btf__scan_free(btf__scan *s)
{
    for (int i = 0; i < s->n_files; i++)
        free(s->files[i].path);
    free(s->files);
    free(s->slot);
}

static char *btf__join(const char *a, const char *b)
{
    size_t la = strlen(a), lb = strlen(b);
    char *p = malloc(la + lb + 2);
    if (!p)
        return NULL;
    memcpy(p, a, la);
    size_t k = la;
    if (la && a[la - 1] != '/')
        p[k++] = '/';
    memcpy(p + k, b, lb + 1);
    return p;
}

/* 1 = directory, 0 = regular file, -1 = other or unreadable. */
static int btf__kind(const char *dirpath, const struct dirent *e)
{
    if (e->d_type == DT_DIR)
        return 1;
    if (e->d_type == DT_REG)
        return 0;
    char *p = btf__join(dirpath, e->d_name);
    struct stat st;
    int k = -1;
    if (p && stat(p, &st) == 0)
        k = S_ISDIR(st.st_mode) ? 1 : S_ISREG(st.st_mode) ? 0 : -1;
    free(p);
    return k;
}

/* Registers one image file with parsed angles a; folder_tv/pv >= 0 when inside a view folder. */
static btf_result btf__scan_add(btf__scan *s, const char *dirpath, const char *name, const int a[4], int folder_tv,
                                int folder_pv, btf_error *err)
{
    char *path = btf__join(dirpath, name);
    if (!path)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dirpath);
    btf_result r = BTF_OK;
    if (folder_tv >= 0 && (folder_tv != a[2] || folder_pv != a[3]))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: view angles tv%03d pv%03d differ from its folder tv%03d_pv%03d", path,
                     a[2], a[3], folder_tv, folder_pv);
    else if (s->n_files == s->cap) {
        int cap = s->cap ? s->cap * 2 : 256;
        btf__file *f = cap <= 4 * BTF_MAX_DIRS * BTF_MAX_DIRS ? realloc(s->files, (size_t)cap * sizeof *f) : NULL;
        if (!f)
            r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (or more images than any sampling has)", path);
        else {
            s->files = f;
            s->cap = cap;
        }
    }
    if (r != BTF_OK) {
        free(path);
        return r;
    }
    s->files[s->n_files].path = path;
    memcpy(s->files[s->n_files++].a, a, sizeof s->files[0].a);
    return BTF_OK;
}

/* Scans one directory level; recurses once into "tvTTT_pvPPP" folders when top is set. */
static btf_result btf__scan_dir(btf__scan *s, const char *dirpath, int top, int ftv, int fpv, btf_error *err)
{
    DIR *d = opendir(dirpath);
    if (!d)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot open directory (%s)", dirpath, strerror(errno));
    btf_result r = BTF_OK;
    struct dirent *e;
    while (r == BTF_OK && (e = readdir(d)) != NULL) {
        int a[4], tv, pv;
        if (e->d_name[0] == '.')
            continue;
        int kind = btf__kind(dirpath, e);
        if (kind == 0 && btf_ubo2003_name_angles(e->d_name, a))
            r = btf__scan_add(s, dirpath, e->d_name, a, ftv, fpv, err);
        else if (kind == 1 && top && btf__parse_folder(e->d_name, &tv, &pv)) {
            char *sub = btf__join(dirpath, e->d_name);
            r = sub ? btf__scan_dir(s, sub, 0, tv, pv, err) : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dirpath);
            free(sub);
        }
    }
    closedir(d);
    return r;
}

/* Whole-degree file angles of direction i of d, as the writer names them. */
static void btf__round_angles(const btf_dirset *d, int i, int *theta, int *phi)
{
    float t, p;
    btf_dirset_angles(d, i, &t, &p);
    *theta = (int)lroundf(t);
    *phi = (int)(lroundf(p) % 360);
}

/* 1 when every view has at least one image (what interpolation over lights needs). */
static int btf__views_covered(const btf__scan *s)
{
    int n = s->set->n_dirs;
    for (int v = 0; v < n; v++) {
        int any = 0;
        for (int l = 0; l < n && !any; l++)
            any = s->slot[v * n + l] >= 0;
        if (!any)
            return 0;
    }
    return 1;
}

/* Every (light, view) pair must have exactly one file. */
static btf_result btf__scan_check_complete(const btf__scan *s, btf_error *err)
{
    int n = s->set->n_dirs, missing = 0, first = -1;
    for (int i = 0; i < s->n_slots; i++)
        if (s->slot[i] < 0 && missing++ == 0)
            first = i;
    if (s->n_files == 0)
        return btf_fail(err, BTF_ERR_MISSING,
                        "%s: no UBO2003 images found (names ending in tlTTT_plPPP_tvTTT_pvPPP.jpg or .png)", s->dir);
    if (!missing || (s->fill && btf__views_covered(s)))
        return BTF_OK;
    int tl, pl, tv, pv;
    btf__round_angles(s->set, first % n, &tl, &pl);
    btf__round_angles(s->set, first / n, &tv, &pv);
    return btf_fail(err, BTF_ERR_MISSING,
                    "%s: missing image for light %d x view %d (no file ending in tl%03d_pl%03d_tv%03d_pv%03d); "
                    "%d of %d images absent",
                    s->dir, first % n, first / n, tl, pl, tv, pv, missing, s->n_slots);
}

/* Index of the direction of d whose whole-degree name angles (as the writer rounds
 * them) are (t, p); else the direction within half a degree; -1 if none. names
 * holds d's rounded angles, 2 per direction. */
static int btf__match(const btf_dirset *d, const int *names, int t, int p)
{
    for (int i = 0; i < d->n_dirs; i++)
        if (names[2 * i] == t && (names[2 * i + 1] == p % 360 || (t == 0 && names[2 * i] == 0)))
            return i;
    return btf_dirset_find(d, (float)t, (float)p, BTF__ANGLE_TOL);
}

/* Puts every scanned file in its (view, light) slot of set; the first file that
 * does not fit, a duplicate or a gap is the error. */
static btf_result btf__scan_assign(btf__scan *s, const btf_dirset *set, btf_error *err)
{
    int n = set->n_dirs, *names = malloc((size_t)n * 2 * sizeof *names);
    free(s->slot);
    s->set = set, s->n_slots = n * n;
    s->slot = malloc((size_t)s->n_slots * sizeof *s->slot);
    if (!names || !s->slot) {
        free(names);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", s->dir);
    }
    for (int i = 0; i < n; i++)
        btf__round_angles(set, i, &names[2 * i], &names[2 * i + 1]);
    for (int i = 0; i < s->n_slots; i++)
        s->slot[i] = -1;
    btf_result r = BTF_OK;
    for (int f = 0; r == BTF_OK && f < s->n_files; f++) {
        const int *a = s->files[f].a;
        int light = btf__match(set, names, a[0], a[1]), view = btf__match(set, names, a[2], a[3]);
        if (light < 0 || view < 0)
            r = btf_fail(err, BTF_ERR_RANGE,
                         "%s: %s direction (theta %d, phi %d) is not in the expected sampling (%d directions)",
                         s->files[f].path, light < 0 ? "light" : "view", light < 0 ? a[0] : a[2],
                         light < 0 ? a[1] : a[3], n);
        else if (s->slot[view * n + light] >= 0)
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: duplicate angles (light %d, view %d) also in %s", s->files[f].path,
                         light, view, s->files[s->slot[view * n + light]].path);
        else
            s->slot[view * n + light] = f;
    }
    free(names);
    return r != BTF_OK ? r : btf__scan_check_complete(s, err);
}

/* Scans dir; with set NULL the sampling is inferred: the one built-in set
 * (UBO2003, then the 151-direction dome) every file fits. *chosen = the set used. */
static btf_result btf__scan_run(btf__scan *s, const char *dir, const btf_dirset *set, int fill, btf_dirset *chosen,
                                btf_error *err)
{
    memset(s, 0, sizeof *s);
    s->dir = dir;
    s->fill = fill;
    btf_result r = btf__scan_dir(s, dir, 1, -1, -1, err);
    if (r != BTF_OK || set) {
        if (set)
            *chosen = *set;
        return r != BTF_OK ? r : btf__scan_assign(s, chosen, err);
    }
    btf_dirset known[2] = {btf_dirset_ubo2003(), btf_dirset_dome151()};
    for (int k = 1; k >= 0; k--) { /* UBO2003 last, so its message is the one kept */
        *chosen = known[k];
        r = btf__scan_assign(s, chosen, err);
        if (r == BTF_OK)
            return r;
    }
    return r;
}

/* ------------------------------------------------------------------ decode */

/* Shared state of the decoding threads; lives on the loader's stack for one call. */
typedef struct btf__decode {
    const btf__scan *scan;
    btf *b;
    int slot0; /* image i of b is slot slot0 + i (0: all images; v * n_lights: view v alone) */
    int n;     /* slots to decode: slot0 .. slot0 + n - 1 */
    int factor;
    int w0, h0; /* full-resolution size of every image */
    long long *sat; /* n: samples at 255 in each decoded file */
    btf_result rc; /* first failure (btf__decode_fail) */
    btf_error err;
} btf__decode;

/* floor(x / d) for d >= 1 without a hardware divide: a double estimate, then corrected. */
static inline unsigned long long btf__div(unsigned long long x, unsigned long long d, double inv_d)
{
    unsigned long long q = (unsigned long long)((double)x * inv_d);
    while (q > 0 && q * d > x)
        q--;
    while ((q + 1) * d <= x)
        q++;
    return q;
}

/* Stores one output row from col, the column sums of f input rows (w*f*ch values). */
static void btf__store_row(btf *b, size_t o, const uint32_t *col, int ch, int f)
{
    unsigned long long n = (unsigned long long)f * (unsigned long long)f;
    double inv_2n = 1.0 / (2.0 * (double)n);
    for (int x = 0; x < b->width; x++)
        for (int c = 0; c < 3; c++) {
            const uint32_t *q = col + (size_t)x * (size_t)f * (size_t)ch + (ch < 3 ? 0 : c); /* grey replicates */
            unsigned long long sum = 0;
            for (int dx = 0; dx < f; dx++)
                sum += q[(size_t)dx * (size_t)ch];
            size_t i = o + (size_t)x * 3u + (size_t)c;
            if (b->storage == BTF_U8)
                ((uint8_t *)b->data)[i] = (uint8_t)btf__div(2u * sum + n, 2u * n, inv_2n); /* round half up */
            else
                ((float *)b->data)[i] = (float)sum / ((float)n * 255.0f);
        }
}

/* col[i] += p[i]; fixed-size blocks so that -O2 vectorizes the bulk. */
static void btf__add_row(uint32_t *restrict col, const uint8_t *restrict p, size_t n)
{
    size_t i = 0;
    for (; i + 16 <= n; i += 16)
        for (int k = 0; k < 16; k++)
            col[i + (size_t)k] += p[i + (size_t)k];
    for (; i < n; i++)
        col[i] += p[i];
}

/* Box-filters a decoded (width*f) x (height*f) x ch image into the BTF's image img;
 * RGBA -> RGB, grey (and grey+alpha) -> replicated. col: scratch of width*f*ch sums. */
static void btf__put_image(btf *b, size_t img, const uint8_t *px, int ch, int f, uint32_t *col)
{
    size_t base = img * btf_image_samples(b), w = (size_t)b->width, row = w * (size_t)f * (size_t)ch;
    if (f == 1 && ch == 3 && b->storage == BTF_U8) {
        memcpy((uint8_t *)b->data + base, px, btf_image_samples(b));
        return;
    }
    for (int y = 0; y < b->height; y++) {
        memset(col, 0, row * sizeof *col);
        for (int dy = 0; dy < f; dy++) { /* vertical sums first: contiguous, vectorizes */
            btf__add_row(col, px + ((size_t)y * (size_t)f + (size_t)dy) * row, row);
        }
        btf__store_row(b, base + (size_t)y * w * 3u, col, ch, f);
    }
}

static btf_result btf__decode_one(btf__decode *d, int slot, uint32_t *acc, btf_error *err)
{
    const char *path = d->scan->files[d->scan->slot[slot]].path;
    uint8_t *px = NULL;
    int w, h, ch;
    btf_result r = btf_image_read_u8(path, &w, &h, &ch, &px, err);
    if (r != BTF_OK)
        return r;
    if (w != d->w0 || h != d->h0)
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: image is %dx%d, expected %dx%d like %s", path, w, h, d->w0, d->h0,
                     d->scan->files[0].path);
    else
        btf__put_image(d->b, (size_t)(slot - d->slot0), px, ch, d->factor, acc);
    if (r == BTF_OK) { /* clipped highlights: colour samples at the maximum */
        long long n255 = 0;
        int colour = ch == 2 || ch == 4 ? ch - 1 : ch;
        for (size_t i = 0, n = (size_t)w * (size_t)h; i < n; i++)
            for (int c = 0; c < colour; c++)
                n255 += px[i * (size_t)ch + (size_t)c] == 255;
        d->sat[slot - d->slot0] = n255 * (ch < 3 ? 3 : 1);
    }
    free(px);
    return r;
}

/* Records the first failure of any thread. */
static void btf__decode_fail(btf__decode *d, btf_result r, const btf_error *err)
{
#pragma omp critical(btf__ubo2003_fail)
    if (d->rc == BTF_OK) {
        d->rc = r;
        d->err = *err;
    }
}

/* Decodes every slot on OpenMP's threads (OMP_NUM_THREADS), the first failure kept. */
static btf_result btf__decode_all(btf__decode *d, btf_error *err)
{
    int n = d->n;
#pragma omp parallel
    {
        btf_error e = {{0}};
        uint32_t *acc = malloc((size_t)d->w0 * 4u * sizeof *acc); /* a row of up to 4 channels */
        if (!acc) {
            btf_fail(&e, BTF_ERR_NOMEM, "%s: out of memory", d->scan->dir);
            btf__decode_fail(d, BTF_ERR_NOMEM, &e);
        }
#pragma omp for schedule(dynamic, 4)
        for (int i = 0; i < n; i++) {
            btf_result rc;
#pragma omp atomic read
            rc = d->rc;
            int slot = d->slot0 + i;
            btf_result r = rc == BTF_OK && acc && d->scan->slot[slot] >= 0 ? btf__decode_one(d, slot, acc, &e) : BTF_OK;
            if (r != BTF_OK)
                btf__decode_fail(d, r, &e);
        }
        free(acc);
    }
    if (d->rc != BTF_OK && err)
        *err = d->err;
    return d->rc;
}

/* Spatial factor from opt (downsample, or width/height when they divide the image size). */
static btf_result btf__pick_factor(const btf_load_options *opt, const char *first, int w0, int h0, int *factor,
                                   btf_error *err)
{
    int f = opt && opt->downsample > 1 ? opt->downsample : 1;
    if (opt && (opt->width > BTF_MAX_SIDE || opt->height > BTF_MAX_SIDE))
        return btf_fail(err, BTF_ERR_RANGE, "%s: requested size %dx%d exceeds %d", first, opt->width, opt->height,
                        BTF_MAX_SIDE);
    if (f == 1 && opt && (opt->width > 0 || opt->height > 0)) {
        int ww = opt->width > 0 ? opt->width : opt->height * w0 / h0;
        f = ww > 0 && w0 % ww == 0 ? w0 / ww : 0;
        if (f < 1 || h0 % f || (opt->height > 0 && h0 / f != opt->height))
            return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: cannot reach %dx%d from %dx%d by an integer box filter",
                            first, opt->width, opt->height, w0, h0);
    }
    if (w0 % f || h0 % f)
        return btf_fail(err, BTF_ERR_ARG, "%s: image size %dx%d is not divisible by the downsample factor %d", first,
                        w0, h0, f);
    *factor = f;
    return BTF_OK;
}

/* Checks the directory argument itself. */
static btf_result btf__check_dir(const char *dir, btf_error *err)
{
    struct stat st;
    if (stat(dir, &st) != 0)
        return btf_fail(err, errno == ENOENT ? BTF_ERR_MISSING : BTF_ERR_IO, "%s: %s", dir, strerror(errno));
    if (!S_ISDIR(st.st_mode))
        return btf_fail(err, BTF_ERR_ARG, "%s: not a directory", dir);
    return BTF_OK;
}

/* Missing image (view v, light l) as the inverse-angle-weighted mean of the view's
 * (up to) 3 nearest present lights; the view is image row bv of b (v, or 0 for a
 * one-view buffer). */
static void btf__fill_one(const btf__scan *s, btf *b, int v, int bv, int l, float *acc, float *img)
{
    int n = s->set->n_dirs, best[3] = {-1, -1, -1};
    float dl[3], best_d[3] = {1e9f, 1e9f, 1e9f};
    btf_dirset_vector(s->set, l, dl);
    for (int k = 0; k < n; k++) {
        float dk[3];
        if (s->slot[v * n + k] < 0)
            continue;
        btf_dirset_vector(s->set, k, dk);
        float c = dl[0] * dk[0] + dl[1] * dk[1] + dl[2] * dk[2], d = acosf(c > 1.0f ? 1.0f : c < -1.0f ? -1.0f : c);
        for (int j = 0; j < 3; j++)
            if (d < best_d[j]) {
                for (int m = 2; m > j; m--)
                    best_d[m] = best_d[m - 1], best[m] = best[m - 1];
                best_d[j] = d, best[j] = k;
                break;
            }
    }
    size_t ns = btf_image_samples(b);
    double wsum = 0.0;
    memset(acc, 0, ns * sizeof *acc);
    for (int j = 0; j < 3 && best[j] >= 0; j++) {
        float w = 1.0f / (best_d[j] + 1e-3f);
        btf_get_image(b, bv, best[j], img);
        for (size_t i = 0; i < ns; i++)
            acc[i] += w * img[i];
        wsum += w;
    }
    for (size_t i = 0; i < ns; i++) {
        float x = (float)(acc[i] / wsum);
        size_t at = btf_index(b, bv, l, 0, 0, 0) + i;
        if (b->storage == BTF_F32)
            ((float *)b->data)[at] = x;
        else
            ((uint8_t *)b->data)[at] = (uint8_t)(x <= 0.0f ? 0 : x >= 1.0f ? 255 : lroundf(x * 255.0f));
    }
}

/* Interpolates every missing image of slots slot0 .. slot0 + n_slots - 1 (b's image
 * i is slot slot0 + i); returns how many. */
static int btf__fill_missing(const btf__scan *s, btf *b, int slot0, int n_slots, btf_error *err, btf_result *r)
{
    int n = s->set->n_dirs, filled = 0;
    size_t ns = btf_image_samples(b);
    float *acc = malloc(ns * sizeof *acc), *img = malloc(ns * sizeof *img);
    *r = acc && img ? BTF_OK : btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", s->dir);
    for (int i = slot0; *r == BTF_OK && i < slot0 + n_slots; i++)
        if (s->slot[i] < 0) {
            btf__fill_one(s, b, i / n, (i - slot0) / n, i % n, acc, img);
            filled++;
        }
    free(acc), free(img);
    return filled;
}

void btf_load_report_add(btf_load_report *rep, const char *path, long long samples, long long saturated)
{
    rep->n_samples += samples;
    rep->n_saturated += saturated;
    if (samples > 0 && (double)saturated >= BTF_LOAD_CLIPPED_SHARE * (double)samples)
        rep->n_images_clipped++;
    if (saturated > rep->worst_saturated) {
        rep->worst_saturated = saturated, rep->worst_samples = samples;
        snprintf(rep->worst_file, sizeof rep->worst_file, "%s", path);
    }
}

/* Adds the decoded slots' saturation counts to rep (NULL: none wanted). */
static void btf__report(const btf__decode *d, btf_load_report *rep)
{
    if (!rep)
        return;
    long long samples = (long long)d->w0 * d->h0 * 3;
    for (int i = 0; i < d->n; i++)
        if (d->scan->slot[d->slot0 + i] >= 0)
            btf_load_report_add(rep, d->scan->files[d->scan->slot[d->slot0 + i]].path, samples, d->sat[i]);
}

/* The readers' shared checks of the options and of the directory itself. */
static btf_result btf__check_load(const char *dir, const btf_load_options *opt, btf_error *err)
{
    const btf_dirset *want = opt ? opt->sampling : NULL;
    if (opt && opt->downsample < 0)
        return btf_fail(err, BTF_ERR_ARG, "%s: downsample factor %d is negative", dir, opt->downsample);
    if (want && (want->n_dirs < 1 || want->n_dirs > BTF_MAX_DIRS))
        return btf_fail(err, BTF_ERR_ARG, "%s: sampling has %d directions", dir, want->n_dirs);
    return btf__check_dir(dir, err);
}

btf_result btf_load_ubo2003_dir(const char *dir, const btf_load_options *opt, btf **out, btf_error *err)
{
    if (!dir || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_load_ubo2003_dir: NULL argument");
    *out = NULL;
    const btf_dirset *want = opt ? opt->sampling : NULL;
    btf_storage storage = opt && opt->storage ? opt->storage : BTF_U8;
    if (storage != BTF_U8 && storage != BTF_F32)
        return btf_fail(err, BTF_ERR_ARG, "%s: unknown storage %d", dir, (int)storage);
    btf_result r = btf__check_load(dir, opt, err);
    if (r != BTF_OK)
        return r;
    btf__scan scan;
    btf_dirset set_used, *set = &set_used;
    r = btf__scan_run(&scan, dir, want, opt && opt->fill_missing, set, err);
    btf__decode d;
    memset(&d, 0, sizeof d);
    d.scan = &scan;
    const char *first = r == BTF_OK ? scan.files[0].path : NULL;
    int ch;
    if (r == BTF_OK)
        r = btf_image_info(first, &d.w0, &d.h0, &ch, err);
    if (r == BTF_OK)
        r = btf__pick_factor(opt, first, d.w0, d.h0, &d.factor, err);
    if (r == BTF_OK)
        r = btf_create(d.w0 / d.factor, d.h0 / d.factor, set, set, storage, &d.b, err);
    d.n = r == BTF_OK ? scan.n_slots : 0;
    if (r == BTF_OK && !(d.sat = calloc((size_t)d.n, sizeof *d.sat)))
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    if (r == BTF_OK)
        r = btf__decode_all(&d, err);
    if (r == BTF_OK)
        btf__report(&d, opt ? opt->report : NULL);
    int filled = r == BTF_OK ? btf__fill_missing(&scan, d.b, 0, scan.n_slots, err, &r) : 0;
    if (opt && opt->n_filled)
        *opt->n_filled = filled;
    free(d.sat);
    btf__scan_free(&scan);
    if (r != BTF_OK) {
        btf_free(d.b);
        return r;
    }
    *out = d.b;
    return BTF_OK;
}

/* ------------------------------------------------------------------ view by view */

/* An image directory read view by view; heap, owned by its btf_views (impl),
 * freed by btf__dirviews_close. */
typedef struct btf__dirviews {
    btf__scan scan;
    btf_dirset set;  /* scan.set points here */
    btf__decode d;   /* d.b: one view's images (U8), reused by every fill */
    char *counted;   /* per view: its files are in the report already */
} btf__dirviews;

static void btf__dirviews_close(btf_views *s)
{
    btf__dirviews *dv = s->impl;
    if (!dv)
        return;
    btf__scan_free(&dv->scan);
    if (dv->d.b)
        free(dv->d.b->data);
    free(dv->d.b), free(dv->d.sat), free(dv->counted), free(dv);
}

static btf_result btf__dirviews_fill(btf_views *s, int v, float *cols, btf_error *err)
{
    btf__dirviews *dv = s->impl;
    int L = dv->set.n_dirs;
    dv->d.slot0 = v * L, dv->d.n = L, dv->d.rc = BTF_OK;
    btf_result r = btf__decode_all(&dv->d, err);
    int filled = r == BTF_OK ? btf__fill_missing(&dv->scan, dv->d.b, v * L, L, err, &r) : 0;
    if (r != BTF_OK)
        return r;
    if (!dv->counted[v]) {
        dv->counted[v] = 1;
        s->n_filled += filled;
        btf__report(&dv->d, &s->report);
    }
    size_t texels = (size_t)s->width * (size_t)s->height;
    for (int l = 0; l < L; l++)
        btf_views_put_u8((const uint8_t *)dv->d.b->data + (size_t)l * texels * 3u, texels, cols + (size_t)l * 3u * texels);
    return BTF_OK;
}

/* Every image's header against the first: the size mismatch is found before the work. */
static btf_result btf__check_headers(const btf__scan *scan, int w0, int h0, btf_error *err)
{
    btf_result rc = BTF_OK;
    btf_error first = {{0}};
    int n = scan->n_files;
#pragma omp parallel for schedule(dynamic, 64)
    for (int i = 1; i < n; i++) {
        btf_result seen;
#pragma omp atomic read
        seen = rc;
        if (seen != BTF_OK)
            continue;
        btf_error e = {{0}};
        int w, h, ch;
        btf_result r = btf_image_info(scan->files[i].path, &w, &h, &ch, &e);
        if (r == BTF_OK && (w != w0 || h != h0))
            r = btf_fail(&e, BTF_ERR_FORMAT, "%s: image is %dx%d, expected %dx%d like %s", scan->files[i].path, w, h,
                         w0, h0, scan->files[0].path);
        if (r != BTF_OK) {
#pragma omp critical(btf__ubo2003_fail)
            if (rc == BTF_OK)
                rc = r, first = e;
        }
    }
    if (rc != BTF_OK && err)
        *err = first;
    return rc;
}

btf_result btf_views_open_ubo2003(const char *dir, const btf_load_options *opt, btf_views *out, btf_error *err)
{
    if (!dir || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_views_open_ubo2003: NULL argument");
    memset(out, 0, sizeof *out);
    const btf_dirset *want = opt ? opt->sampling : NULL;
    if (opt && opt->storage && opt->storage != BTF_U8)
        return btf_fail(err, BTF_ERR_ARG, "%s: an image directory is read view by view as bytes only", dir);
    btf_result r = btf__check_load(dir, opt, err);
    if (r != BTF_OK)
        return r;
    btf__dirviews *dv = calloc(1, sizeof *dv);
    if (!dv)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    out->impl = dv, out->close = btf__dirviews_close, out->fill = btf__dirviews_fill, out->name = dir;
    r = btf__scan_run(&dv->scan, dir, want, opt && opt->fill_missing, &dv->set, err);
    dv->scan.set = &dv->set;
    dv->d.scan = &dv->scan;
    const char *first = r == BTF_OK ? dv->scan.files[0].path : NULL;
    int ch, L = dv->set.n_dirs;
    if (r == BTF_OK)
        r = btf_image_info(first, &dv->d.w0, &dv->d.h0, &ch, err);
    if (r == BTF_OK)
        r = btf__pick_factor(opt, first, dv->d.w0, dv->d.h0, &dv->d.factor, err);
    if (r == BTF_OK)
        r = btf__check_headers(&dv->scan, dv->d.w0, dv->d.h0, err);
    if (r == BTF_OK) {
        int w = dv->d.w0 / dv->d.factor, h = dv->d.h0 / dv->d.factor;
        out->width = w, out->height = h, out->lights = dv->set, out->views = dv->set;
        /* one view's images as a BTF whose view 0 is the view being filled */
        dv->d.b = calloc(1, sizeof *dv->d.b);
        if (dv->d.b) {
            *dv->d.b = (btf){w, h, dv->set, dv->set, BTF_U8, NULL, (size_t)L * w * h * 3};
            dv->d.b->data = malloc(dv->d.b->count);
        }
        dv->d.sat = calloc((size_t)L, sizeof *dv->d.sat);
        dv->counted = calloc((size_t)L, 1);
        if (!dv->d.b || !dv->d.b->data || !dv->d.sat || !dv->counted)
            r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (one view of %d images)", dir, L);
    }
    if (r != BTF_OK)
        btf_views_close(out);
    return r;
}

/* ------------------------------------------------------------------ writer */

/* mkdir -p; existing directories are fine. */
static btf_result btf__mkdirs(const char *dir, btf_error *err)
{
    size_t n = strlen(dir);
    char *p = malloc(n + 1);
    if (!p)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", dir);
    memcpy(p, dir, n + 1);
    btf_result r = BTF_OK;
    for (size_t i = 1; i <= n && r == BTF_OK; i++) {
        if (p[i] != '/' && p[i] != '\0')
            continue;
        char keep = p[i];
        p[i] = '\0';
        struct stat st;
        if (mkdir(p, 0777) != 0 && errno != EEXIST)
            r = btf_fail(err, BTF_ERR_IO, "%s: cannot create directory (%s)", p, strerror(errno));
        else if (stat(p, &st) != 0 || !S_ISDIR(st.st_mode))
            r = btf_fail(err, BTF_ERR_IO, "%s: exists and is not a directory", p);
        p[i] = keep;
    }
    free(p);
    return r;
}

/* Refuses sets whose whole-degree names would not map back to the same direction. */
static btf_result btf__check_roundable(const btf_dirset *d, const char *what, btf_error *err)
{
    for (int i = 0; i < d->n_dirs; i++) {
        int t, p;
        btf__round_angles(d, i, &t, &p);
        int j = btf_dirset_find(d, (float)t, (float)p, BTF__ANGLE_TOL);
        if (j != i)
            return btf_fail(err, BTF_ERR_RANGE,
                            "%s direction %d rounds to theta %d phi %d, which names direction %d too: "
                            "the set cannot be written with whole-degree names",
                            what, i, t, p, j);
    }
    return BTF_OK;
}

/* Shared state of the writing threads; lives on the writer's stack for one call. */
typedef struct btf__writer {
    const btf *b;
    const char *dir, *prefix, *ext;
    int total;     /* images to write: b's images 0 .. total - 1 */
    int view0;     /* b's view 0 is view view0 of the material (a one-view buffer), else 0 */
    btf_result rc; /* first failure (under the critical section) */
    btf_error err;
} btf__writer;

static btf_result btf__write_one(btf__writer *w, int img, uint8_t *tmp, btf_error *err)
{
    const btf *b = w->b;
    int nl = b->lights.n_dirs, nv = b->views.n_dirs, light = img % nl, view = w->view0 + img / nl, tl, pl, tv, pv;
    btf__round_angles(&b->lights, light, &tl, &pl);
    btf__round_angles(&b->views, view, &tv, &pv);
    size_t n = strlen(w->dir) + strlen(w->prefix) + strlen(w->ext) + 64;
    char *path = malloc(n);
    if (!path)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", w->dir);
    snprintf(path, n, "%s/%s_%05d_tl%03d_pl%03d_tv%03d_pv%03d.%s", w->dir, w->prefix, light * nv + view, tl, pl, tv, pv, w->ext);
    size_t ns = btf_image_samples(b), base = (size_t)img * ns;
    const uint8_t *px = (const uint8_t *)b->data + base;
    if (b->storage == BTF_F32) {
        const float *f = (const float *)b->data + base;
        for (size_t i = 0; i < ns; i++)
            tmp[i] = btf_to_u8(f[i]);
        px = tmp;
    }
    btf_result r = btf_image_write_unsynced(path, b->width, b->height, 3, 8, px, err);
    free(path);
    return r;
}

/* Writes every image on OpenMP's threads (OMP_NUM_THREADS), the first failure kept. */
static btf_result btf__write_all(btf__writer *w, btf_error *err)
{
#pragma omp parallel
    {
        btf_error e = {{0}};
        uint8_t *tmp = w->b->storage == BTF_F32 ? malloc(btf_image_samples(w->b)) : NULL;
        btf_result r = w->b->storage == BTF_F32 && !tmp ? btf_fail(&e, BTF_ERR_NOMEM, "%s: out of memory", w->dir)
                                                         : BTF_OK;
#pragma omp for schedule(dynamic, 4)
        for (int i = 0; i < w->total; i++) {
            btf_result rc;
#pragma omp atomic read
            rc = w->rc;
            if (r == BTF_OK && rc == BTF_OK)
                r = btf__write_one(w, i, tmp, &e);
        }
        if (r != BTF_OK) {
#pragma omp critical(btf__ubo2003_fail)
            if (w->rc == BTF_OK) {
                w->rc = r;
                w->err = e;
            }
        }
        free(tmp);
    }
    if (w->rc != BTF_OK && err)
        *err = w->err;
    return w->rc;
}

/* The writers' shared start: default prefix and extension, their checks, directions
 * whose names round to whole degrees, the directory made. */
static btf_result btf__save_start(const char *dir, const char **prefix, const char **ext, const btf_dirset *lights,
                                  const btf_dirset *views, btf_error *err)
{
    *prefix = *prefix && **prefix ? *prefix : "btf";
    *ext = *ext && **ext ? *ext : "png";
    if (**ext == '.')
        (*ext)++;
    if (!btf__is_image_ext(*ext))
        return btf_fail(err, BTF_ERR_ARG, "%s: extension \"%s\" is not png, jpg or jpeg", dir, *ext);
    if (strchr(*prefix, '/'))
        return btf_fail(err, BTF_ERR_ARG, "%s: prefix \"%s\" contains '/'", dir, *prefix);
    btf_result r = btf__check_roundable(lights, "light", err);
    if (r == BTF_OK)
        r = btf__check_roundable(views, "view", err);
    return r == BTF_OK ? btf__mkdirs(dir, err) : r;
}

btf_result btf_save_ubo2003_dir(const btf *b, const char *dir, const char *prefix, const char *ext, btf_error *err)
{
    if (!b || !dir || !b->data)
        return btf_fail(err, BTF_ERR_ARG, "btf_save_ubo2003_dir: NULL argument");
    if (b->storage != BTF_U8 && b->storage != BTF_F32)
        return btf_fail(err, BTF_ERR_ARG, "%s: unknown storage %d", dir, (int)b->storage);
    btf_result r = btf__save_start(dir, &prefix, &ext, &b->lights, &b->views, err);
    if (r != BTF_OK)
        return r;
    btf__writer w;
    memset(&w, 0, sizeof w);
    w.b = b;
    w.dir = dir;
    w.prefix = prefix;
    w.ext = ext;
    w.total = b->lights.n_dirs * b->views.n_dirs;
    r = btf__write_all(&w, err);
    return r == BTF_OK ? btf_fs_sync_dir(dir, err) : r; /* the images were written unsynced */
}

btf_result btf_views_save_ubo2003(btf_views *s, const char *dir, const char *prefix, const char *ext,
                                  btf_error *err)
{
    if (!s || !dir || !s->fill)
        return btf_fail(err, BTF_ERR_ARG, "btf_views_save_ubo2003: NULL argument");
    btf_result r = btf__save_start(dir, &prefix, &ext, &s->lights, &s->views, err);
    if (r != BTF_OK)
        return r;
    int L = s->lights.n_dirs;
    size_t texels = (size_t)s->width * (size_t)s->height;
    /* one view's images, F32 (the writer rounds them as btf_save_ubo2003_dir does) */
    btf one = {s->width, s->height, s->lights, s->views, BTF_F32, NULL, (size_t)L * texels * 3};
    float *cols = malloc(btf_views_floats(s) * sizeof(float));
    one.data = malloc(one.count * sizeof(float));
    if (!cols || !one.data)
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory (one view of %d images)", dir, L);
    for (int v = 0; r == BTF_OK && v < s->views.n_dirs; v++) {
        r = btf_views_fill(s, v, cols, err);
        float *px = one.data;
        for (int l = 0; r == BTF_OK && l < L; l++)
            for (size_t t = 0; t < texels; t++)
                for (int c = 0; c < 3; c++)
                    *px++ = cols[((size_t)l * 3 + (size_t)c) * texels + t];
        btf__writer w;
        memset(&w, 0, sizeof w);
        w.b = &one, w.dir = dir, w.prefix = prefix, w.ext = ext, w.total = L, w.view0 = v;
        if (r == BTF_OK)
            r = btf__write_all(&w, err);
    }
    free(cols), free(one.data);
    return r == BTF_OK ? btf_fs_sync_dir(dir, err) : r;
}
