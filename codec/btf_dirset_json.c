/* btf_dirset_json.c - direction sets from a small JSON ring table (cJSON).
 *
 * Format (doc/data-model.md):
 *     {"rings": [{"theta": 0, "count": 1, "phi_offset": 0},
 *                {"theta": 15, "count": 6, "phi_offset": 0}, ...]}
 * theta in degrees (0..90, strictly ascending), count an integer 1..2048,
 * phi_offset in degrees (any finite value, wrapped to 0..360). Every ring must
 * give exactly these three keys; other top-level keys (e.g. "name") are ignored.
 */
#include "btf.h"
#include "btf_fs.h"

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

static btf_result btf__ring_number(const cJSON *ring, const char *key, const char *name, int r, double *v,
                                   btf_error *err)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(ring, key);
    if (!it)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d: missing key \"%s\"", name, r, key);
    if (!cJSON_IsNumber(it))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d: \"%s\" must be a number", name, r, key);
    if (!isfinite(it->valuedouble))
        return btf_fail(err, BTF_ERR_RANGE, "%s: ring %d: \"%s\" is not finite", name, r, key);
    *v = it->valuedouble;
    return BTF_OK;
}

/* Rejects unknown and duplicated keys in one ring object (catches typos). */
static btf_result btf__ring_keys(const cJSON *ring, const char *name, int r, btf_error *err)
{
    static const char *const keys[3] = {"theta", "count", "phi_offset"};
    int seen[3] = {0, 0, 0};
    for (const cJSON *c = ring->child; c; c = c->next) {
        int k = 0;
        while (k < 3 && (!c->string || strcmp(c->string, keys[k]) != 0))
            k++;
        if (k == 3)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d: unknown key \"%s\" (expected theta, count, phi_offset)",
                            name, r, c->string ? c->string : "");
        if (seen[k]++)
            return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d: duplicate key \"%s\"", name, r, keys[k]);
    }
    return BTF_OK;
}

static btf_result btf__parse_ring(const cJSON *ring, const char *name, int r, btf_ring *out, btf_error *err)
{
    if (!cJSON_IsObject(ring))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: ring %d is not an object", name, r);
    btf_result rc = btf__ring_keys(ring, name, r, err);
    double theta = 0, count = 0, off = 0;
    if (rc == BTF_OK)
        rc = btf__ring_number(ring, "theta", name, r, &theta, err);
    if (rc == BTF_OK)
        rc = btf__ring_number(ring, "count", name, r, &count, err);
    if (rc == BTF_OK)
        rc = btf__ring_number(ring, "phi_offset", name, r, &off, err);
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

static btf_result btf__parse_root(const cJSON *root, const char *name, btf_dirset *out, btf_error *err)
{
    if (!cJSON_IsObject(root))
        return btf_fail(err, BTF_ERR_FORMAT, "%s: top level must be an object with key \"rings\"", name);
    const cJSON *rings = cJSON_GetObjectItemCaseSensitive(root, "rings");
    if (!rings)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: missing key \"rings\"", name);
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
