/* btf_manifest.c - manifest.json of a package: parser, serializer (versions 1, 2 and 3)
 * and the test of whether a directory is a package this project wrote. */
#include "btf_manifest.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "btf_base64.h"
#include "btf_dirtab.h"
#include "btf_fs.h"
#include "btf_common.h"
#include "btf_blocks.h"
#include "btf_lap.h"

/* ---------------------------------------------------------------- parser */

int btf_manifest_valid_name(const char *s)
{
    size_t n = strlen(s);
    if (n == 0 || n >= BTF_PACKAGE_NAME_MAX || !strcmp(s, ".") || !strcmp(s, ".."))
        return 0;
    for (size_t i = 0; i < n; i++) {
        char c = s[i];
        if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
              c == '-'))
            return 0;
    }
    return 1;
}










static int btf__get_int(const cJSON *o, const char *key, int lo, int hi, int *out)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v) || v->valuedouble != floor(v->valuedouble) || v->valuedouble < lo || v->valuedouble > hi)
        return 0;
    *out = (int)v->valuedouble;
    return 1;
}


static btf_result btf__parse_rings(const cJSON *a, const char *what, const char *path, btf_dirset *d,
                                   btf_error *err)
{
    int n = cJSON_GetArraySize(a);
    if (!cJSON_IsArray(a) || n < 1 || n > BTF_MAX_RINGS)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"%s\" has no valid ring list", path, what);
    btf_ring rings[BTF_MAX_RINGS];
    for (int i = 0; i < n; i++) {
        const cJSON *e = cJSON_GetArrayItem(a, i);
        const cJSON *t = cJSON_GetObjectItemCaseSensitive(e, "theta"), *p = cJSON_GetObjectItemCaseSensitive(e, "phi_offset");
        if (!cJSON_IsNumber(t) || !cJSON_IsNumber(p) || !btf__get_int(e, "count", 1, BTF_MAX_DIRS, &rings[i].count))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: %s ring %d is malformed", path, what, i);
        rings[i].theta_deg = (float)t->valuedouble;
        rings[i].phi_offset_deg = (float)p->valuedouble;
    }
    btf_result r = btf_dirset_make(rings, n, d, err);
    if (r != BTF_OK)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s rings invalid", path, what);
    return BTF_OK;
}


/* "triangles": flat list-numbered vertex triples -> the set's table (btf_dirtab_build_list). */
static btf_result btf__parse_tris(const cJSON *a, const btf_dirset *d, const char *what, const char *path,
                                  btf_dirtab **tab, btf_error *err)
{
    int n = cJSON_GetArraySize(a), nt = n / 3;
    if (!cJSON_IsArray(a) || n % 3 != 0 || nt < 1 || nt > 4 * (2 * d->n_dirs + 2))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s \"triangles\" must hold 1..%d vertex triples", path, what,
                        4 * (2 * d->n_dirs + 2));
    int(*tris)[3] = malloc(sizeof(int[3]) * (size_t)nt);
    if (!tris)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    int i = 0;
    for (const cJSON *e = a->child; e && i < n; e = e->next, i++) {
        if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) || e->valuedouble < 0 ||
            e->valuedouble >= 2.0 * d->n_dirs)
            break;
        tris[i / 3][i % 3] = (int)e->valuedouble;
    }
    btf_error inner = {{0}};
    btf_result r = i < n ? btf_fail(err, BTF_ERR_FORMAT, "%s: %s triangle vertex %d is not in 0..%d", path, what, i,
                                    2 * d->n_dirs - 1)
                         : btf_dirtab_build_list(d, (const int(*)[3])tris, nt, tab, &inner);
    if (i == n && r != BTF_OK)
        btf_fail(err, r, "%s: %s: %s", path, what, inner.msg);
    free(tris);
    return r;
}

/* "directions": [{"theta", "phi"}, ...] (index order) -> a list set. */
static btf_result btf__parse_list(const cJSON *a, const char *what, const char *path, btf_dirset *d, btf_error *err)
{
    int n = cJSON_GetArraySize(a);
    if (!cJSON_IsArray(a) || n < 3 || n > BTF_MAX_LIST_DIRS)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"%s\" must list 3..%d directions", path, what, BTF_MAX_LIST_DIRS);
    float(*dirs)[2] = malloc(sizeof(float[2]) * (size_t)n);
    if (!dirs)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    int i = 0;
    for (const cJSON *e = a->child; e && i < n; e = e->next, i++) {
        const cJSON *t = cJSON_GetObjectItemCaseSensitive(e, "theta"), *p = cJSON_GetObjectItemCaseSensitive(e, "phi");
        if (!cJSON_IsNumber(t) || !cJSON_IsNumber(p))
            break;
        dirs[i][0] = (float)t->valuedouble, dirs[i][1] = (float)p->valuedouble;
    }
    btf_error inner = {{0}};
    btf_result r = i < n ? btf_fail(err, BTF_ERR_FORMAT, "%s: %s direction %d is malformed", path, what, i)
                         : btf_dirset_make_list((const float(*)[2])dirs, n, d, &inner);
    if (i == n && r != BTF_OK)
        btf_fail(err, BTF_ERR_FORMAT, "%s: %s: %s", path, what, inner.msg);
    free(dirs);
    return r;
}

/* "lights" / "views": a ring table, or a direction list with its triangles. */
static btf_result btf__parse_dirs(const cJSON *m, const char *what, const char *path, btf_dirset *d,
                                  btf_dirtab **tab, btf_error *err)
{
    const cJSON *o = cJSON_GetObjectItemCaseSensitive(m, what);
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(o, "directions");
    if (!list)
        return btf__parse_rings(cJSON_GetObjectItemCaseSensitive(o, "rings"), what, path, d, err);
    btf_result r = btf__parse_list(list, what, path, d, err);
    const cJSON *tris = cJSON_GetObjectItemCaseSensitive(o, "triangles");
    if (r == BTF_OK && tris)
        r = btf__parse_tris(tris, d, what, path, tab, err);
    return r;
}


static btf_result btf__parse_blocks(const cJSON *m, btf_package *p, const char *path, btf_error *err)
{
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(m, "blocks");
    int nb = cJSON_GetArraySize(a), V = p->views.n_dirs;
    if (!cJSON_IsArray(a) || nb < 1 || nb > V)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"blocks\" must list 1..%d blocks", path, V);
    int *sizes = calloc((size_t)nb, sizeof(int)), *flat = calloc((size_t)V, sizeof(int));
    const int **lists = calloc((size_t)nb, sizeof *lists);
    btf_result r = BTF_OK;
    if (!sizes || !flat || !lists) {
        r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
        goto done;
    }
    int pos = 0;
    for (int b = 0; b < nb && r == BTF_OK; b++) {
        const cJSON *l = cJSON_GetArrayItem(a, b);
        int n = cJSON_GetArraySize(l);
        if (!cJSON_IsArray(l) || n < 1 || pos + n > V) {
            r = btf_fail(err, BTF_ERR_FORMAT, "%s: block %d is not a valid view list", path, b);
            break;
        }
        sizes[b] = n;
        lists[b] = flat + pos;
        for (int i = 0; i < n; i++) {
            const cJSON *v = cJSON_GetArrayItem(l, i);
            if (!cJSON_IsNumber(v) || !(v->valuedouble >= 0 && v->valuedouble < V) ||
                v->valuedouble != floor(v->valuedouble)) {
                r = btf_fail(err, BTF_ERR_FORMAT, "%s: block %d entry %d is not a view index 0..%d", path, b, i, V - 1);
                break;
            }
            flat[pos++] = (int)v->valuedouble;
        }
    }
    if (r == BTF_OK)
        r = btf_blocks_from_lists(V, nb, sizes, lists, &p->blocks, err);
done:
    free(sizes), free(flat), free(lists);
    return r;
}


static btf_result btf__parse_ranges(const cJSON *c, const char *key, int nb, float **out, const char *path, int id,
                                    btf_error *err)
{
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(c, key);
    if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != nb)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"%s\" must have %d entries", path, id, key, nb);
    *out = malloc((size_t)nb * 2 * sizeof(float));
    if (!*out)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    for (int b = 0; b < nb; b++) {
        const cJSON *e = cJSON_GetArrayItem(a, b);
        const cJSON *lo = cJSON_GetArrayItem(e, 0), *st = cJSON_GetArrayItem(e, 1);
        if (cJSON_GetArraySize(e) != 2 || !cJSON_IsNumber(lo) || !cJSON_IsNumber(st) || !isfinite(lo->valuedouble) ||
            !isfinite(st->valuedouble) || st->valuedouble < 0 || fabs(lo->valuedouble) > 1e30 ||
            st->valuedouble > 1e30)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: bad \"%s\" entry %d", path, id, key, b);
        (*out)[2 * b] = (float)lo->valuedouble;
        (*out)[2 * b + 1] = (float)st->valuedouble;
    }
    return BTF_OK;
}




/* Version 2: ranges of component `comp` from the header's "ranges" (one base64
 * string per component of n_blocks x float32 LE {tex_lo, tex_step, wt_lo, wt_step}). */
static btf_result btf__component_ranges(const cJSON *ranges, btf_chunk_info *ci, int nb, const char *path, int id,
                                        btf_error *err)
{
    const cJSON *s = cJSON_GetArrayItem(ranges, ci->component);
    size_t n = (size_t)nb * 16;
    uint8_t *raw = malloc(n);
    ci->tex_range = malloc((size_t)nb * 2 * sizeof(float));
    ci->wt_range = malloc((size_t)nb * 2 * sizeof(float));
    if (!raw || !ci->tex_range || !ci->wt_range) {
        free(raw);
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
    }
    int ok = cJSON_IsString(s) && btf_base64_decode(s->valuestring, raw, n);
    for (int b = 0; ok && b < nb; b++)
        for (int j = 0; j < 4; j++) {
            const uint8_t *q = raw + 16 * b + 4 * j;
            uint32_t u = (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24;
            float x;
            memcpy(&x, &u, sizeof x);
            ok = ok && isfinite(x) && fabsf(x) <= 1e30f && (j % 2 == 0 || x >= 0.0f);
            (j < 2 ? ci->tex_range : ci->wt_range)[2 * b + j % 2] = x;
        }
    free(raw);
    return ok ? BTF_OK
              : btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"ranges\" entry %d is not %zu base64 bytes of finite ranges",
                         path, id, ci->component, n);
}


/* Optional informational numbers of a chunk: finite and within range when present. */
static btf_result btf__chunk_numbers(const cJSON *c, btf_chunk_info *ci, const char *path, int id, btf_error *err)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(c, "bytes");
    if (v && !(cJSON_IsNumber(v) && v->valuedouble >= 0 && v->valuedouble <= (double)BTF_MANIFEST_MAX_CHUNK_BYTES &&
               v->valuedouble == floor(v->valuedouble)))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"bytes\" is not a whole number in 0..%lld", path, id,
                        BTF_MANIFEST_MAX_CHUNK_BYTES);
    ci->bytes = v ? (long long)v->valuedouble : 0;
    struct { const char *k; double *d; } nums[] = {{"rmse", &ci->rmse},         {"lab", &ci->lab},
                                                   {"psnr", &ci->psnr},         {"delta_e76", &ci->delta_e76},
                                                   {"rmse_float", &ci->rmse_float}, {"contrib", &ci->contrib},
                                                   {"rmse_full", &ci->rmse_full}};
    for (size_t i = 0; i < sizeof nums / sizeof nums[0]; i++) {
        v = cJSON_GetObjectItemCaseSensitive(c, nums[i].k);
        if (v && !(cJSON_IsNumber(v) && fabs(v->valuedouble) <= 1e9))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"%s\" is not a number within +-1e9", path, id,
                            nums[i].k);
        if (v)
            *nums[i].d = v->valuedouble;
    }
    if (!cJSON_GetObjectItemCaseSensitive(c, "psnr")) /* version 3 leaves it out: 20 log10(255 / rmse) */
        ci->psnr = ci->rmse > 0.0 ? 20.0 * log10(255.0 / ci->rmse) : 999.0;
    return BTF_OK;
}

/* Version 4: the "predictor" of a residual level (section 12: 18 integers within
 * +-BTF_LAP_PRED_MAX), or the default one when the chunk lists none. */
static btf_result btf__parse_pred(const cJSON *c, const btf_package *p, int id, const char *path, btf_error *err)
{
    btf_chunk_info *ci = &p->chunk[id];
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(c, "predictor");
    ci->pred = btf_lap_pred_default();
    ci->has_pred = a != NULL;
    if (!a)
        return BTF_OK;
    if (!btf_package_chunk_residual(p, id) || !cJSON_IsArray(a) || cJSON_GetArraySize(a) != 3 * BTF_LAP_PRED_N)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"predictor\" is not %d integers of a residual level", path,
                        id, 3 * BTF_LAP_PRED_N);
    for (int k = 0; k < 3 * BTF_LAP_PRED_N; k++) {
        const cJSON *v = cJSON_GetArrayItem(a, k);
        if (!cJSON_IsNumber(v) || v->valuedouble != floor(v->valuedouble) || fabs(v->valuedouble) > BTF_LAP_PRED_MAX)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: \"predictor\" entry %d is not an integer within +-%d",
                            path, id, k, BTF_LAP_PRED_MAX);
        ci->pred.w[k / BTF_LAP_PRED_N][k % BTF_LAP_PRED_N] = (int)v->valuedouble;
    }
    return BTF_OK;
}

/* 1 when the ranges travel in the header's "ranges" (versions 2, 3 and 4), 0 in each
 * chunk (version 1; a version-3 reader takes that form too, which writers before
 * 2026-12-07 wrote). */
static int btf__header_ranges(const btf_package *p)
{
    return btf_package_has_levels(p) || p->version == 3;
}

static btf_result btf__parse_chunk(const cJSON *c, const cJSON *root, btf_package *p, int id, const char *path,
                                   btf_error *err)
{
    const cJSON *ranges = cJSON_GetObjectItemCaseSensitive(root, "ranges");
    btf_chunk_info *ci = &p->chunk[id];
    int cid;
    if (!cJSON_IsObject(c) || !btf__get_int(c, "id", id, id, &cid) ||
        !btf__get_int(c, "component", 0, p->n_comp - 1, &ci->component))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: missing or wrong \"id\"/\"component\"", path, id);
    const cJSON *f = cJSON_GetObjectItemCaseSensitive(c, "files");
    int nf = cJSON_GetArraySize(f);
    if (!cJSON_IsArray(f) || nf < 1 || nf > BTF_PACKAGE_MAX_FILES)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: bad \"files\"", path, id);
    ci->n_files = nf;
    for (int i = 0; i < nf; i++) {
        const cJSON *s = cJSON_GetArrayItem(f, i);
        if (!cJSON_IsString(s) || !btf_manifest_valid_name(s->valuestring))
            return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: file %d has an invalid name", path, id, i);
        snprintf(ci->files[i], BTF_PACKAGE_NAME_MAX, "%s", s->valuestring);
    }
    ci->level = 0;
    if (btf_package_has_levels(p) && !btf__get_int(c, "level", 0, p->n_levels - 1, &ci->level))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: missing or wrong \"level\"", path, id);
    const cJSON *v = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "weights8_step"), ci->component);
    ci->wt8_step = 257.0;
    if (v && (!cJSON_IsNumber(v) || !(v->valuedouble >= 0.0 && v->valuedouble <= 65535.0)))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: chunk %d: bad \"weights8_step\" of component %d", path, id,
                        ci->component);
    if (v && v->valuedouble >= 1.0)
        ci->wt8_step = v->valuedouble;
    btf_result r = btf__chunk_numbers(c, ci, path, id, err);
    if (r == BTF_OK)
        r = btf__parse_pred(c, p, id, path, err);
    if (r != BTF_OK)
        return r;
    if (btf__header_ranges(p) && (ranges || btf_package_has_levels(p)) &&
        !cJSON_GetObjectItemCaseSensitive(c, "tex_range"))
        return btf__component_ranges(ranges, ci, p->blocks->n_blocks, path, id, err);
    r = btf__parse_ranges(c, "tex_range", p->blocks->n_blocks, &ci->tex_range, path, id, err);
    if (r == BTF_OK)
        r = btf__parse_ranges(c, "wt_range", p->blocks->n_blocks, &ci->wt_range, path, id, err);
    return r;
}


/* Version 4 (section 12): each (component, level) at most once, and a residual level
 * only after the same component's next coarser level. */
int btf_package_chunk_residual(const btf_package *p, int i)
{
    const btf_chunk_info *ci = &p->chunk[i];
    if (p->version != 4 || ci->level >= p->n_levels - 1)
        return 0;
    char end[3][24];
    snprintf(end[0], sizeof end[0], "-d%d.png", ci->level);
    snprintf(end[1], sizeof end[1], "-d%d.webp", ci->level); /* section 4: any encoding */
    snprintf(end[2], sizeof end[2], "-d%d.avif", ci->level);
    for (int f = 0; f < ci->n_files; f++)
        for (int x = 0; x < 3; x++) {
            size_t n = strlen(ci->files[f]), e = strlen(end[x]);
            if (strncmp(ci->files[f], "wt-", 3) && n > e && !strcmp(ci->files[f] + n - e, end[x]))
                return 1;
        }
    return 0;
}

static btf_result btf__residual_order(const btf_package *p, const char *path, btf_error *err)
{
    for (int i = 0; i < p->n_chunks; i++) {
        const btf_chunk_info *ci = &p->chunk[i];
        int coarser = !btf_package_chunk_residual(p, i);
        for (int k = 0; k < i; k++) {
            if (p->chunk[k].component != ci->component)
                continue;
            if (p->chunk[k].level == ci->level)
                return btf_fail(err, BTF_ERR_FORMAT, "%s: chunks %d and %d both hold level %d of component %d", path, k,
                                i, ci->level, ci->component);
            coarser |= p->chunk[k].level == ci->level + 1;
        }
        if (!coarser)
            return btf_fail(err, BTF_ERR_FORMAT,
                            "%s: chunk %d (residual level %d of component %d) comes before that component's level %d",
                            path, i, ci->level, ci->component, ci->level + 1);
    }
    return BTF_OK;
}

/* "encoding": absent or "srgb" 0, "linear" 1 (section 3.7); anything else refused. */
static btf_result btf__parse_encoding(const cJSON *m, btf_package *p, const char *path, btf_error *err)
{
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(m, "encoding");
    p->linear = 0;
    if (!e || (cJSON_IsString(e) && !strcmp(e->valuestring, "srgb")))
        return BTF_OK;
    if (cJSON_IsString(e) && !strcmp(e->valuestring, "linear")) {
        p->linear = 1;
        return BTF_OK;
    }
    return btf_fail(err, BTF_ERR_FORMAT, "%s: \"encoding\" must be \"srgb\" or \"linear\"", path);
}

static btf_result btf__parse_header(const cJSON *m, btf_package *p, const char *path, btf_error *err)
{
    const cJSON *fmt = cJSON_GetObjectItemCaseSensitive(m, "format");
    int version;
    if (!cJSON_IsString(fmt) || strcmp(fmt->valuestring, "btf-package") != 0)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"format\" is not \"btf-package\"", path);
    if (!btf__get_int(m, "version", 1, 4, &version))
        return btf_fail(err, BTF_ERR_UNSUPPORTED, "%s: unsupported \"version\" (this reader knows 1, 2, 3 and 4)", path);
    p->version = version;
    p->n_levels = 1;
    btf_result r = btf__parse_encoding(m, p, path, err);
    if (r != BTF_OK)
        return r;
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    snprintf(p->name, sizeof p->name, "%s", cJSON_IsString(name) ? name->valuestring : "");
    if (!btf__get_int(m, "width", 1, BTF_MAX_SIDE, &p->width) || !btf__get_int(m, "height", 1, BTF_MAX_SIDE, &p->height))
        return btf_fail(err, BTF_ERR_RANGE, "%s: \"width\"/\"height\" missing or outside 1..%d", path, BTF_MAX_SIDE);
    r = btf__parse_dirs(m, "lights", path, &p->lights, &p->dirtab[0], err);
    if (r == BTF_OK)
        r = btf__parse_dirs(m, "views", path, &p->views, &p->dirtab[1], err);
    if (r != BTF_OK)
        return r;
    if (!btf__get_int(m, "components", 1, BTF_PACKAGE_MAX_CHUNKS, &p->n_comp) ||
        !btf__get_int(m, "bits", 8, 16, &p->bits) || (p->bits != 8 && p->bits != 16))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"components\" or \"bits\" missing or invalid", path);
    if (!btf__get_int(m, "k", 1, p->views.n_dirs, &p->k))
        p->k = 0;
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(m, "center");
    p->center = cJSON_IsString(c) && !strcmp(c->valuestring, "row") ? BTF_CENTER_ROW : BTF_CENTER_NONE;
    c = cJSON_GetObjectItemCaseSensitive(m, "grouping");
    p->grouping = cJSON_IsString(c) && !strcmp(c->valuestring, "spatial") ? BTF_GROUP_SPATIAL : BTF_GROUP_CONSECUTIVE;
    r = btf__parse_blocks(m, p, path, err);
    if (r != BTF_OK)
        return r;
    const cJSON *at = cJSON_GetObjectItemCaseSensitive(m, "atlas");
    int tw, th, ch, aw, ah;
    if (!btf__get_int(at, "cols", 1, 4096, &p->atlas_cols) || !btf__get_int(at, "rows", 1, 4096, &p->atlas_rows) ||
        !btf__get_int(at, "tile_width", p->width, p->width, &tw) ||
        !btf__get_int(at, "tile_height", p->height, p->height, &th) ||
        !btf__get_int(at, "channels", p->bits == 16 ? 3 : 1, p->bits == 16 ? 3 : 1, &ch) ||
        !btf__get_int(at, "width", p->atlas_cols * tw, p->atlas_cols * tw, &aw) ||
        !btf__get_int(at, "height", p->atlas_rows * th, p->atlas_rows * th, &ah) ||
        (long)p->atlas_cols * p->atlas_rows < p->blocks->n_blocks)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"atlas\" is inconsistent with the size and block count", path);
    if (!btf__get_int(cJSON_GetObjectItemCaseSensitive(m, "error_sample"), "texel_stride", 1, BTF_MAX_SIDE,
                      &p->lab_stride))
        p->lab_stride = 0;
    const cJSON *thr = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(m, "lod"), "threshold");
    p->lod_threshold = cJSON_IsNumber(thr) && thr->valuedouble > 0 && thr->valuedouble <= 1e6 ? thr->valuedouble : 0;
    if (btf_package_has_levels(p) && (!btf__get_int(m, "levels", 1, 15, &p->n_levels) ||
                         p->width % (1 << (p->n_levels - 1)) || p->height % (1 << (p->n_levels - 1))))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"levels\" missing, outside 1..15 or not dividing %dx%d", path,
                        p->width, p->height);
    if (version == 4 && p->bits != 8)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: version 4 (residual levels) needs \"bits\": 8", path);
    return BTF_OK;
}

btf_result btf_manifest_parse(const char *text, const char *path, btf_package *p, btf_error *err)
{
    cJSON *m = cJSON_Parse(text);
    if (!m)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not valid JSON", path);
    btf_result r = btf__parse_header(m, p, path, err);
    const cJSON *chunks = cJSON_GetObjectItemCaseSensitive(m, "chunks");
    int nc = cJSON_GetArraySize(chunks);
    if (r == BTF_OK && (!cJSON_IsArray(chunks) || nc < 1 || nc > BTF_PACKAGE_MAX_CHUNKS))
        r = btf_fail(err, BTF_ERR_FORMAT, "%s: \"chunks\" must list 1..%d chunks", path, BTF_PACKAGE_MAX_CHUNKS);
    if (r == BTF_OK) {
        p->chunk = calloc((size_t)nc, sizeof *p->chunk);
        p->tex = calloc((size_t)nc, sizeof *p->tex);
        p->wt = calloc((size_t)nc, sizeof *p->wt);
        if (!p->chunk || !p->tex || !p->wt)
            r = btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", path);
        else
            p->n_chunks = nc;
    }
    for (int i = 0; r == BTF_OK && i < nc; i++)
        r = btf__parse_chunk(cJSON_GetArrayItem(chunks, i), m, p, i, path, err);
    if (r == BTF_OK && p->version == 4)
        r = btf__residual_order(p, path, err);
    const cJSON *budget = cJSON_GetObjectItemCaseSensitive(m, "budget");
    if (r == BTF_OK && cJSON_IsObject(budget))
        p->budget = cJSON_PrintUnformatted(budget);
    const cJSON *rd = cJSON_GetObjectItemCaseSensitive(m, "rd");
    if (r == BTF_OK && cJSON_IsObject(rd))
        p->rd = cJSON_PrintUnformatted(rd);
    cJSON_Delete(m);
    return r;
}

void btf_manifest_clear(btf_package *p)
{
    for (int i = 0; p->chunk && i < p->n_chunks; i++) {
        free(p->chunk[i].tex_range);
        free(p->chunk[i].wt_range);
    }
    free(p->chunk), free(p->tex), free(p->wt), free(p->budget), free(p->rd);
    btf_blocks_free(p->blocks);
    btf_dirtab_free(p->dirtab[0]);
    btf_dirtab_free(p->dirtab[1]);
    p->chunk = NULL, p->tex = NULL, p->wt = NULL, p->blocks = NULL, p->budget = NULL, p->rd = NULL, p->n_chunks = 0;
    p->dirtab[0] = p->dirtab[1] = NULL;
}

/* ---------------------------------------------------------------- serializer */

/* A list set as "directions" and the "triangles" of tab (or of a table made here). */
static cJSON *btf__list_json(const btf_dirset *d, const btf_dirtab *tab)
{
    cJSON *o = cJSON_CreateObject(), *a = cJSON_AddArrayToObject(o, "directions");
    for (int i = 0; i < d->n_dirs; i++) {
        cJSON *e = cJSON_CreateObject();
        cJSON_AddNumberToObject(e, "theta", d->list[i][0]);
        cJSON_AddNumberToObject(e, "phi", d->list[i][1]);
        cJSON_AddItemToArray(a, e);
    }
    btf_dirtab *own = NULL;
    if (!tab && btf_dirtab_build(d, &own, NULL) == BTF_OK)
        tab = own;
    int nt = tab ? tab->n_tris : 0, (*tris)[3] = nt ? malloc(sizeof(int[3]) * (size_t)nt) : NULL;
    if (tris) {
        btf_dirtab_list_tris(tab, tris, nt);
        cJSON_AddItemToObject(o, "triangles", cJSON_CreateIntArray(&tris[0][0], 3 * nt));
    }
    free(tris);
    btf_dirtab_free(own);
    return o;
}

static cJSON *btf__rings_json(const btf_dirset *d, const btf_dirtab *tab)
{
    if (btf_dirset_is_list(d))
        return btf__list_json(d, tab);
    cJSON *o = cJSON_CreateObject(), *a = cJSON_AddArrayToObject(o, "rings");
    for (int r = 0; r < d->n_rings; r++) {
        cJSON *e = cJSON_CreateObject();
        cJSON_AddNumberToObject(e, "theta", d->rings[r].theta_deg);
        cJSON_AddNumberToObject(e, "count", d->rings[r].count);
        cJSON_AddNumberToObject(e, "phi_offset", d->rings[r].phi_offset_deg);
        cJSON_AddItemToArray(a, e);
    }
    return o;
}

/* A float as the shortest decimal that a reader's double, rounded to float, takes back to
 * it exactly (at most 9 significant digits, against the 17 of the double it widens to). */
static cJSON *btf__f32_json(float x)
{
    char b[32];
    for (int digits = 6; digits <= 9 && isfinite(x); digits++) {
        snprintf(b, sizeof b, "%.*g", digits, (double)x);
        double d = strtod(b, NULL);
        if ((float)d == x)
            return cJSON_CreateNumber(d);
    }
    return cJSON_CreateNumber((double)x);
}

/* Version 1 per-chunk ranges: [[lo, step], ...] per block. */
static cJSON *btf__ranges_json(const float *rg, int n_blocks)
{
    cJSON *a = cJSON_CreateArray();
    for (int b = 0; b < n_blocks; b++) {
        cJSON *p = cJSON_CreateArray();
        cJSON_AddItemToArray(p, btf__f32_json(rg[2 * b]));
        cJSON_AddItemToArray(p, btf__f32_json(rg[2 * b + 1]));
        cJSON_AddItemToArray(a, p);
    }
    return a;
}

/* A chunk's error number as JSON (0 for NaN/Inf): every digit in version 1; as a
 * float32 in version 3 (about 9 characters instead of 17: the manifest travels first,
 * and --max-error and the tests compare these with other measurements); 4
 * significant digits in versions 2 and 4. */
static cJSON *btf__num(const btf_package *p, double x)
{
    char b[32];
    if (!isfinite(x))
        return cJSON_CreateNumber(0.0);
    if (p->version == 1)
        return cJSON_CreateNumber(x);
    if (p->version == 3)
        return btf__f32_json((float)x);
    snprintf(b, sizeof b, "%.4g", x);
    return cJSON_CreateNumber(strtod(b, NULL));
}

/* Format, size, directions, grouping, atlas, weights and error sample: common to both versions. */
static void btf__print_header(const btf_package *p, cJSON *m)
{
    const btf_blocks *bl = p->blocks;
    cJSON_AddStringToObject(m, "format", "btf-package");
    cJSON_AddNumberToObject(m, "version", p->version);
    cJSON_AddStringToObject(m, "name", p->name);
    cJSON_AddNumberToObject(m, "width", p->width);
    cJSON_AddNumberToObject(m, "height", p->height);
    cJSON_AddItemToObject(m, "lights", btf__rings_json(&p->lights, p->dirtab[0]));
    cJSON_AddItemToObject(m, "views", btf__rings_json(&p->views, p->dirtab[1]));
    cJSON_AddNumberToObject(m, "k", p->k);
    cJSON_AddNumberToObject(m, "components", p->n_comp);
    cJSON_AddStringToObject(m, "center", btf_blocks_center_name(p->center));
    cJSON_AddStringToObject(m, "grouping", btf_blocks_grouping_name(p->grouping));
    cJSON_AddNumberToObject(m, "bits", p->bits);
    if (p->linear) /* absent = "srgb": sRGB packages keep their bytes */
        cJSON_AddStringToObject(m, "encoding", "linear");
    cJSON *blocks = cJSON_AddArrayToObject(m, "blocks");
    for (int b = 0; b < bl->n_blocks; b++) {
        cJSON *a = cJSON_CreateArray();
        for (int i = bl->start[b]; i < bl->start[b + 1]; i++)
            cJSON_AddItemToArray(a, cJSON_CreateNumber(bl->views[i]));
        cJSON_AddItemToArray(blocks, a);
    }
    cJSON *at = cJSON_AddObjectToObject(m, "atlas");
    cJSON_AddNumberToObject(at, "cols", p->atlas_cols);
    cJSON_AddNumberToObject(at, "rows", p->atlas_rows);
    cJSON_AddNumberToObject(at, "tile_width", p->width);
    cJSON_AddNumberToObject(at, "tile_height", p->height);
    cJSON_AddNumberToObject(at, "width", p->atlas_cols * p->width);
    cJSON_AddNumberToObject(at, "height", p->atlas_rows * p->height);
    cJSON_AddNumberToObject(at, "channels", p->bits == 16 ? 3 : 1);
    cJSON *wt = cJSON_AddObjectToObject(m, "weights");
    cJSON_AddNumberToObject(wt, "bits", 16);
    cJSON_AddStringToObject(wt, "layout", "view-light-channel");
    cJSON_AddStringToObject(wt, "endian", "little");
    if (p->version == 3)
        cJSON_AddStringToObject(wt, "coding", "zlib-delta-light");
    int s = p->lab_stride > 0 ? p->lab_stride : 1;
    cJSON *es = cJSON_AddObjectToObject(m, "error_sample");
    cJSON_AddNumberToObject(es, "texel_stride", s);
    cJSON_AddNumberToObject(es, "texels", (double)(((p->width + s - 1) / s) * ((p->height + s - 1) / s)));
}

/* First chunk of component c, or -1. */
static int btf__first_of(const btf_package *p, int c)
{
    for (int a = 0; a < p->n_chunks; a++)
        if (p->chunk[a].component == c)
            return a;
    return -1;
}

/* 1 when component c travels with 8-bit weights ("wt-JJ-8.png", or in version 4
 * "wt-JJ-8.webp", in one of its chunks). */
static int btf__has_w8(const btf_package *p, int c)
{
    for (int a = 0; a < p->n_chunks; a++)
        for (int f = 0; p->chunk[a].component == c && f < p->chunk[a].n_files; f++) {
            const char *name = p->chunk[a].files[f];
            size_t n = strlen(name);
            if ((n > 6 && !strcmp(name + n - 6, "-8.png")) || (n > 7 && !strcmp(name + n - 7, "-8.webp")))
                return 1;
        }
    return 0;
}

/* Version 2 "ranges": per component, base64 of n_blocks x float32 LE {tex lo, step, wt lo, step}. */
static cJSON *btf__ranges_b64(const btf_package *p)
{
    int nb = p->blocks->n_blocks;
    cJSON *arr = cJSON_CreateArray();
    uint8_t *raw = malloc((size_t)nb * 16);
    for (int c = 0; arr && raw && c < p->n_comp; c++) {
        int a = btf__first_of(p, c);
        for (int b = 0; a >= 0 && b < nb; b++)
            for (int j = 0; j < 4; j++) {
                float x = (j < 2 ? p->chunk[a].tex_range : p->chunk[a].wt_range)[2 * b + j % 2];
                uint32_t u;
                memcpy(&u, &x, sizeof u);
                for (int t = 0; t < 4; t++)
                    raw[16 * b + 4 * j + t] = (uint8_t)(u >> (8 * t));
            }
        char *e = a >= 0 ? btf_base64_encode(raw, (size_t)nb * 16) : NULL;
        cJSON_AddItemToArray(arr, cJSON_CreateString(e ? e : ""));
        free(e);
    }
    free(raw);
    return arr;
}

/* Version 2 header additions: levels, lod, ranges, weights8_step. */
static void btf__print_levels(const btf_package *p, cJSON *m)
{
    cJSON_AddNumberToObject(m, "levels", p->n_levels);
    cJSON *lod = cJSON_AddObjectToObject(m, "lod");
    cJSON_AddStringToObject(lod, "filter", "box");
    cJSON_AddNumberToObject(lod, "threshold", p->lod_threshold);
    if (p->version == 4) {
        cJSON_AddStringToObject(lod, "residual", "bilinear-cell-sum");
    }
    cJSON_AddItemToObject(m, "ranges", btf__ranges_b64(p));
    cJSON *mult = cJSON_AddArrayToObject(m, "weights8_step");
    for (int c = 0; c < p->n_comp; c++) { /* 0 = no 8-bit weights */
        int a = btf__first_of(p, c);
        cJSON_AddItemToArray(mult, cJSON_CreateNumber(a >= 0 && btf__has_w8(p, c) ? p->chunk[a].wt8_step : 0.0));
    }
}

static cJSON *btf__print_chunk(const btf_package *p, int id)
{
    const btf_chunk_info *ci = &p->chunk[id];
    cJSON *c = cJSON_CreateObject();
    cJSON_AddNumberToObject(c, "id", id);
    cJSON_AddNumberToObject(c, "component", ci->component);
    cJSON *files = cJSON_AddArrayToObject(c, "files");
    for (int f = 0; f < ci->n_files; f++)
        cJSON_AddItemToArray(files, cJSON_CreateString(ci->files[f]));
    cJSON_AddNumberToObject(c, "bytes", (double)ci->bytes);
    cJSON_AddItemToObject(c, "rmse", btf__num(p, ci->rmse));
    if (!btf_package_has_levels(p))
        cJSON_AddItemToObject(c, "lab", btf__num(p, ci->lab));
    if (p->version < 3) /* versions 3 and 4: a reader computes it from rmse */
        cJSON_AddItemToObject(c, "psnr", btf__num(p, ci->psnr));
    if (!btf_package_has_levels(p))
        cJSON_AddItemToObject(c, "delta_e76", btf__num(p, ci->delta_e76));
    if (p->version != 4) /* version 4 leaves out what rmse, the other chunks and the source say */
        cJSON_AddItemToObject(c, "rmse_float", btf__num(p, ci->rmse_float));
    if (!btf__header_ranges(p)) {
        cJSON_AddItemToObject(c, "tex_range", btf__ranges_json(ci->tex_range, p->blocks->n_blocks));
        cJSON_AddItemToObject(c, "wt_range", btf__ranges_json(ci->wt_range, p->blocks->n_blocks));
    }
    if (btf_package_has_levels(p)) {
        cJSON_AddNumberToObject(c, "level", ci->level);
        cJSON_AddItemToObject(c, "contrib", btf__num(p, ci->contrib));
        if (p->version != 4)
            cJSON_AddItemToObject(c, "rmse_full", btf__num(p, ci->rmse_full));
    }
    if (ci->has_pred) {
        cJSON *pr = cJSON_AddArrayToObject(c, "predictor");
        for (int k = 0; k < 3 * BTF_LAP_PRED_N; k++)
            cJSON_AddItemToArray(pr, cJSON_CreateNumber(ci->pred.w[k / BTF_LAP_PRED_N][k % BTF_LAP_PRED_N]));
    }
    return c;
}

char *btf_manifest_print(const btf_package *p, btf_error *err)
{
    cJSON *m = cJSON_CreateObject();
    if (m) {
        btf__print_header(p, m);
        if (btf_package_has_levels(p))
            btf__print_levels(p, m);
        else if (btf__header_ranges(p))
            cJSON_AddItemToObject(m, "ranges", btf__ranges_b64(p));
        cJSON *budget = p->budget ? cJSON_Parse(p->budget) : NULL;
        if (budget)
            cJSON_AddItemToObject(m, "budget", budget);
        cJSON *rd = p->rd ? cJSON_Parse(p->rd) : NULL;
        if (rd)
            cJSON_AddItemToObject(m, "rd", rd);
        cJSON *chunks = cJSON_AddArrayToObject(m, "chunks");
        for (int a = 0; a < p->n_chunks; a++)
            cJSON_AddItemToArray(chunks, btf__print_chunk(p, a));
    }
    /* version 1 stays readable; the others are compact (the manifest travels first) */
    char *s = m ? (p->version != 1 ? cJSON_PrintUnformatted(m) : cJSON_Print(m)) : NULL;
    cJSON_Delete(m);
    if (!s)
        btf_fail(err, BTF_ERR_NOMEM, "package: out of memory (manifest)");
    return s;
}

/* ---------------------------------------------------------------- ownership */

/* 1 when name is manifest.json, thumbnail.png or a file some chunk of p lists. */
static int btf__package_file(const btf_package *p, const char *name)
{
    if (!strcmp(name, "manifest.json") || !strcmp(name, "thumbnail.png"))
        return 1;
    for (int a = 0; a < p->n_chunks; a++)
        for (int f = 0; f < p->chunk[a].n_files; f++)
            if (!strcmp(p->chunk[a].files[f], name))
                return 1;
    return 0;
}

/* A regular file that the package's manifest (ctx) lists (btf_fs_entry_fn). */
static int btf__listed_file(const char *name, const struct stat *st, void *ctx)
{
    return S_ISREG(st->st_mode) && btf__package_file(ctx, name);
}

btf_result btf_manifest_load(const char *dir, btf_package *p, btf_error *err)
{
    return btf_manifest_load_with(dir, NULL, p, err);
}

btf_result btf_manifest_load_with(const char *dir, const btf_files *files, btf_package *p, btf_error *err)
{
    char path[BTF_FS_PATH_MAX + 64], *text = NULL;
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    memset(p, 0, sizeof *p);
    btf_result r = btf_fs_read_with(files, path, BTF_MANIFEST_MAX_BYTES, &text, NULL, err);
    if (r == BTF_OK)
        r = btf_manifest_parse(text, path, p, err);
    free(text);
    return r;
}

int btf_manifest_owns_dir(const char *dir, void *ctx)
{
    (void)ctx;
    btf_package p;
    int ok = btf_manifest_load(dir, &p, NULL) == BTF_OK && btf_fs_all_entries(dir, btf__listed_file, &p);
    btf_manifest_clear(&p);
    return ok;
}

/* 1 when name is one a package writer makes: manifest.json, thumbnail.png,
 * tex-..., wt-..., or one of these with a temporary ".tmp-PID" ending. */
static int btf__writer_file(const char *name, const struct stat *st, void *ctx)
{
    (void)ctx;
    return S_ISREG(st->st_mode) && btf_manifest_valid_name(name) &&
           (!strncmp(name, "manifest.json", 13) || !strncmp(name, "thumbnail.png", 13) || !strncmp(name, "tex-", 4) ||
            !strncmp(name, "wt-", 3));
}
int btf_manifest_owns_temp(const char *dir, void *ctx)
{
    return btf_fs_all_entries(dir, btf__writer_file, ctx);
}