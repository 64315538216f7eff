/* btf_dirset_json.c - direction sets from a small JSON file (cJSON): a ring table
 * or an explicit direction list.
 *
 * Formats (doc/data-model.md):
 *     {"rings": [{"theta": 0, "count": 1, "phi_offset": 0},
 *                {"theta": 15, "count": 6, "phi_offset": 0}, ...]}
 * theta in degrees (0..90, strictly ascending), count an integer 1..2048,
 * phi_offset in degrees (any finite value, wrapped to 0..360). Every ring must
 * give exactly these three keys.
 *     {"directions": [{"theta": 12.5, "phi": 40.0}, ...]}
 * degrees, index order as listed, 3..1024 entries of exactly these two keys.
 * A file has one of "rings" and "directions"; other top-level keys (e.g. "name")
 * are ignored.
 */
#include "btf.h"
#include "btf_fs.h"
#include "btf_common.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Files larger than this are refused before reading (a ring table is < 4 KiB). */
#define BTF__DIRSET_JSON_MAX (1u << 20)

/* Parses a ring table from text (len bytes, need not be NUL-terminated); name
 * is used in messages. Not yet declared in btf.h (see the helper's report). */
btf_result btf_dirset_parse_json(const char *text, size_t len, const char *name, btf_dirset *out, btf_error *err);

/* Number `key` of entry r of a "rings" or "directions" array (what: "ring", "direction"). */
static btf_result btf__ring_number(const cJSON *ring, const char *key, const char *what, const char *name, int r,
                                   double *v, btf_error *err)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(ring, key);
    if (!it)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s %d: missing key \"%s\"", name, what, r, key);
    if (!cJSON_IsNumber(it))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: %s %d: \"%s\" must be a number", name, what, r, key);
    if (!isfinite(it->valuedouble))
        return btf_fail(err, BTF_ERR_RANGE, "%s: %s %d: \"%s\" is not finite", name, what, r, key);
    *v = it->valuedouble;
    return BTF_OK;
}

/* Rejects unknown and duplicated keys in one ring or direction object (catches
 * typos); keys[0..nk-1] are the allowed ones, what says "ring" or "direction". */
static btf_result btf__entry_keys(const cJSON *ring, const char *const *keys, int nk, const char *what,
                                  const char *name, int r, btf_error *err)
{
    int seen[3] = {0, 0, 0};
    for (const cJSON *c = ring->child; c; c = c->next) {
        int k = 0;
        while (k < nk && (!c->string || strcmp(c->string, keys[k]) != 0))
            k++;
        if (k == nk)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: %s %d: unknown key \"%s\" (expected %s, %s%s%s)", name, what, r,
                            c->string ? c->string : "", keys[0], keys[1], nk > 2 ? ", " : "", nk > 2 ? keys[2] : "");
        if (seen[k]++)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: %s %d: duplicate key \"%s\"", name, what, r, keys[k]);
    }
    return BTF_OK;
}

static btf_result btf__parse_ring(const cJSON *ring, const char *name, int r, btf_ring *out, btf_error *err)
{
    if (!cJSON_IsObject(ring))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d is not an object", name, r);
    static const char *const keys[3] = {"theta", "count", "phi_offset"};
    btf_result rc = btf__entry_keys(ring, keys, 3, "ring", name, r, err);
    double theta = 0, count = 0, off = 0;
    if (rc == BTF_OK)
        rc = btf__ring_number(ring, "theta", "ring", name, r, &theta, err);
    if (rc == BTF_OK)
        rc = btf__ring_number(ring, "count", "ring", name, r, &count, err);
    if (rc == BTF_OK)
        rc = btf__ring_number(ring, "phi_offset", "ring", name, r, &off, err);
    if (rc != BTF_OK)
        return rc;
    if (theta < 0.0 || theta > 90.0)
        return btf_fail(err, BTF_ERR_RANGE, "%s: ring %d: theta %g outside 0..90", name, r, theta);
    if (count != floor(count))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d: count %g is not an integer", name, r, count);
    if (count < 1.0 || count > (double)BTF_MAX_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "%s: ring %d: count %g outside 1..%d", name, r, count, BTF_MAX_DIRS);
    if (fabs(off) > 1e6)
        return btf_fail(err, BTF_ERR_RANGE, "%s: ring %d: phi_offset %g is absurd", name, r, off);
    out->theta_deg = (float)theta;
    out->count = (int)count;
    out->phi_offset_deg = (float)off;
    return BTF_OK;
}

/* {"directions": [{"theta", "phi"}, ...]} into a list set. */
static btf_result btf__parse_list(const cJSON *list, const char *name, btf_dirset *out, btf_error *err)
{
    if (!cJSON_IsArray(list))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"directions\" must be an array", name);
    int n = cJSON_GetArraySize(list);
    if (n < 3 || n > BTF_MAX_LIST_DIRS)
        return btf_fail(err, BTF_ERR_RANGE, "%s: %d directions, expected 3..%d", name, n, BTF_MAX_LIST_DIRS);
    float(*tab)[2] = malloc(sizeof(float[2]) * BTF_MAX_LIST_DIRS);
    if (!tab)
        return btf_fail(err, BTF_ERR_NOMEM, "%s: out of memory", name);
    static const char *const keys[2] = {"theta", "phi"};
    btf_result rc = BTF_OK;
    int i = 0;
    for (const cJSON *it = list->child; it && i < n && rc == BTF_OK; it = it->next, i++) {
        double t = 0, p = 0;
        if (!cJSON_IsObject(it))
            rc = btf_fail(err, BTF_ERR_FORMAT, "%s: direction %d is not an object", name, i);
        if (rc == BTF_OK)
            rc = btf__entry_keys(it, keys, 2, "direction", name, i, err);
        if (rc == BTF_OK)
            rc = btf__ring_number(it, "theta", "direction", name, i, &t, err);
        if (rc == BTF_OK)
            rc = btf__ring_number(it, "phi", "direction", name, i, &p, err);
        if (rc == BTF_OK && (t < 0.0 || t > 90.0 || fabs(p) > 1e6))
            rc = btf_fail(err, BTF_ERR_RANGE, "%s: direction %d: theta %g outside 0..90 or phi %g absurd", name, i, t, p);
        tab[i][0] = (float)t, tab[i][1] = (float)p;
    }
    btf_error inner = {{0}};
    if (rc == BTF_OK && (rc = btf_dirset_make_list((const float(*)[2])tab, n, out, &inner)) != BTF_OK)
        btf_fail(err, rc, "%s: %s", name, inner.msg);
    free(tab);
    return rc;
}

static btf_result btf__parse_root(const cJSON *root, const char *name, btf_dirset *out, btf_error *err)
{
    if (!cJSON_IsObject(root))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: top level must be an object with key \"rings\" or \"directions\"",
                        name);
    const cJSON *rings = cJSON_GetObjectItemCaseSensitive(root, "rings");
    const cJSON *list = cJSON_GetObjectItemCaseSensitive(root, "directions");
    if (rings && list)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: give \"rings\" or \"directions\", not both", name);
    if (list)
        return btf__parse_list(list, name, out, err);
    if (!rings)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: missing key \"rings\" (or \"directions\")", name);
    if (!cJSON_IsArray(rings))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: \"rings\" must be an array", name);
    int n = cJSON_GetArraySize(rings);
    if (n < 1 || n > BTF_MAX_RINGS)
        return btf_fail(err, BTF_ERR_RANGE, "%s: %d rings, expected 1..%d", name, n, BTF_MAX_RINGS);
    btf_ring table[BTF_MAX_RINGS];
    int r = 0;
    for (const cJSON *it = rings->child; it && r < n; it = it->next, r++) {
        btf_result rc = btf__parse_ring(it, name, r, &table[r], err);
        if (rc != BTF_OK)
            return rc;
    }
    btf_error inner = {{0}};
    btf_result rc = btf_dirset_make(table, n, out, &inner);
    if (rc != BTF_OK)
        return btf_fail(err, rc, "%s: %s", name, inner.msg);
    return BTF_OK;
}

btf_result btf_dirset_parse_json(const char *text, size_t len, const char *name, btf_dirset *out, btf_error *err)
{
    if (!name)
        name = "direction set JSON";
    if (!text || !out)
        return btf_fail(err, BTF_ERR_ARG, "%s: NULL argument", name);
    if (len == 0)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: empty input, expected {\"rings\": [...]}", name);
    if (len > BTF__DIRSET_JSON_MAX)
        return btf_fail(err, BTF_ERR_RANGE, "%s: %zu bytes, more than the %u allowed", name, len,
                        BTF__DIRSET_JSON_MAX);
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(text, len, &end, 0);
    if (!root) {
        size_t at = end && end >= text && end <= text + len ? (size_t)(end - text) : 0;
        return btf_fail(err, BTF_ERR_FORMAT, "%s: not valid JSON (error near byte %zu)", name, at);
    }
    while (end && end < text + len && (*end == ' ' || *end == '\n' || *end == '\r' || *end == '\t'))
        end++;
    btf_result rc;
    if (end && end < text + len && *end != '\0')
        rc = btf_fail(err, BTF_ERR_FORMAT, "%s: trailing data after the JSON value (byte %zu)", name,
                      (size_t)(end - text));
    else
        rc = btf__parse_root(root, name, out, err);
    cJSON_Delete(root);
    return rc;
}

/* Reads a whole small file into a malloc'd buffer (caller frees). */
static btf_result btf__read_small(const char *path, char **buf, size_t *len, btf_error *err)
{
    return btf_fs_read(path, BTF__DIRSET_JSON_MAX, buf, len, err);
}

btf_result btf_dirset_load_json(const char *path, btf_dirset *out, btf_error *err)
{
    if (!path || !out)
        return btf_fail(err, BTF_ERR_ARG, "btf_dirset_load_json: NULL argument");
    char *buf = NULL;
    size_t len = 0;
    btf_result rc = btf__read_small(path, &buf, &len, err);
    if (rc != BTF_OK)
        return rc;
    rc = btf_dirset_parse_json(buf, len, path, out, err);
    free(buf);
    return rc;
}
