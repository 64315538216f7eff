/* btfd_request.c - parser for the client's text messages; see btfd_request.h. */
#include "btfd_request.h"

#include <cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define MAX_SAFE_INT 9007199254740991.0 /* 2^53 - 1: largest exact JSON integer */

static btfd_req_status fail(char *why, size_t n, btfd_req_status s, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

static btfd_req_status fail(char *why, size_t n, btfd_req_status s, const char *fmt, ...)
{
    if (why && n) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(why, n, fmt, ap);
        va_end(ap);
    }
    return s;
}

const char *btfd_req_status_code(btfd_req_status s)
{
    switch (s) {
    case BTFD_REQ_OK: return "ok";
    case BTFD_REQ_TOO_LARGE: return "too_large";
    case BTFD_REQ_BAD_JSON: return "bad_json";
    case BTFD_REQ_BAD_TYPE: return "bad_type";
    case BTFD_REQ_UNKNOWN_TYPE: return "unknown_type";
    case BTFD_REQ_BAD_NAME: return "bad_name";
    case BTFD_REQ_BAD_FIELD: return "bad_field";
    }
    return "unknown";
}

btfd_budget btfd_budget_unlimited(void)
{
    btfd_budget b = {-1, -1, -1.0, -1.0, -1.0};
    return b;
}

int btfd_name_valid(const char *name, size_t len)
{
    if (len == 0 || len > BTFD_NAME_MAX || name[0] == '.')
        return 0;
    for (size_t i = 0; i < len; i++) {
        char c = name[i];
        int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                 c == '.' || c == '_' || c == '-';
        if (!ok)
            return 0;
    }
    return 1;
}

/* 1 if buf holds a raw NUL or the JSON escape \u0000 (which cJSON would turn
 * into a silently truncated string). */
static int has_nul(const char *buf, size_t len)
{
    if (memchr(buf, 0, len))
        return 1;
    for (size_t i = 0; i + 6 <= len; i++)
        if (buf[i] == '\\' && (buf[i + 1] == 'u' || buf[i + 1] == 'U') &&
            !memcmp(buf + i + 2, "0000", 4))
            return 1;
    return 0;
}

int btfd_json_int(const cJSON *item, double lo, double hi, int64_t *v)
{
    if (!cJSON_IsNumber(item))
        return 0;
    double d = item->valuedouble;
    if (!isfinite(d) || d != floor(d) || d < lo || d > hi)
        return 0;
    *v = (int64_t)d;
    return 1;
}

static btfd_req_status parse_budget(const cJSON *b, btfd_budget *out, char *why, size_t n)
{
    *out = btfd_budget_unlimited();
    if (!cJSON_IsObject(b))
        return fail(why, n, BTFD_REQ_BAD_FIELD, "\"budget\" must be an object");
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(b, "chunks");
    if (c && !cJSON_IsNull(c) && !btfd_json_int(c, 0, BTFD_CHUNK_MAX, &out->max_chunks))
        return fail(why, n, BTFD_REQ_BAD_FIELD, "budget.chunks must be an integer 0..%d", BTFD_CHUNK_MAX);
    c = cJSON_GetObjectItemCaseSensitive(b, "bytes");
    if (c && !cJSON_IsNull(c) && !btfd_json_int(c, 0, MAX_SAFE_INT, &out->max_bytes))
        return fail(why, n, BTFD_REQ_BAD_FIELD, "budget.bytes must be a non-negative integer");
    c = cJSON_GetObjectItemCaseSensitive(b, "error");
    if (c && !cJSON_IsNull(c)) {
        if (!cJSON_IsNumber(c) || !isfinite(c->valuedouble) || c->valuedouble < 0)
            return fail(why, n, BTFD_REQ_BAD_FIELD, "budget.error must be a number >= 0");
        out->max_error = c->valuedouble;
    }
    c = cJSON_GetObjectItemCaseSensitive(b, "pixels");
    if (c && !cJSON_IsNull(c)) {
        if (!cJSON_IsNumber(c) || !isfinite(c->valuedouble) || c->valuedouble < 0 || c->valuedouble > 1e9)
            return fail(why, n, BTFD_REQ_BAD_FIELD, "budget.pixels must be a number 0..1e9");
        out->pixels = c->valuedouble;
    }
    c = cJSON_GetObjectItemCaseSensitive(b, "threshold");
    if (c && !cJSON_IsNull(c)) {
        if (!cJSON_IsNumber(c) || !isfinite(c->valuedouble) || c->valuedouble < 0)
            return fail(why, n, BTFD_REQ_BAD_FIELD, "budget.threshold must be a number >= 0");
        out->threshold = c->valuedouble;
    }
    return BTFD_REQ_OK;
}

static btfd_req_status parse_have(const cJSON *h, btfd_request *out, char *why, size_t n)
{
    if (!cJSON_IsArray(h))
        return fail(why, n, BTFD_REQ_BAD_FIELD, "\"have\" must be an array of chunk indices");
    int count = cJSON_GetArraySize(h);
    if (count > BTFD_HAVE_MAX)
        return fail(why, n, BTFD_REQ_BAD_FIELD, "\"have\" lists %d chunks (at most %d)", count, BTFD_HAVE_MAX);
    const cJSON *e;
    out->n_have = 0;
    cJSON_ArrayForEach(e, h) {
        int64_t v;
        if (!btfd_json_int(e, 0, BTFD_CHUNK_MAX - 1, &v))
            return fail(why, n, BTFD_REQ_BAD_FIELD, "\"have\"[%d] is not a chunk index 0..%d",
                        out->n_have, BTFD_CHUNK_MAX - 1);
        out->have[out->n_have++] = (uint32_t)v;
    }
    return BTFD_REQ_OK;
}

static btfd_req_status parse_name(const cJSON *root, btfd_request *out, char *why, size_t n)
{
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(root, "material");
    if (!cJSON_IsString(m))
        return fail(why, n, BTFD_REQ_BAD_NAME, "\"material\" must be a string");
    size_t len = strlen(m->valuestring);
    if (!btfd_name_valid(m->valuestring, len))
        return fail(why, n, BTFD_REQ_BAD_NAME,
                    "invalid material name (1..%d characters of A-Z a-z 0-9 . _ -, not starting with '.')",
                    BTFD_NAME_MAX);
    memcpy(out->material, m->valuestring, len + 1);
    return BTFD_REQ_OK;
}

static btfd_req_status parse_type(const cJSON *root, btfd_request *out, char *why, size_t n)
{
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(root, "type");
    if (!cJSON_IsString(t))
        return fail(why, n, BTFD_REQ_BAD_TYPE, "\"type\" must be a string");
    static const struct { const char *name; btfd_req_type type; } types[] = {
        {"list", BTFD_REQ_LIST},         {"subscribe", BTFD_REQ_SUBSCRIBE},
        {"budget", BTFD_REQ_BUDGET},     {"unsubscribe", BTFD_REQ_UNSUBSCRIBE},
        {"ping", BTFD_REQ_PING},         {"ack", BTFD_REQ_ACK},
    };
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (!strcmp(t->valuestring, types[i].name)) {
            out->type = types[i].type;
            return BTFD_REQ_OK;
        }
    return fail(why, n, BTFD_REQ_UNKNOWN_TYPE, "unknown message type (%.40s)", t->valuestring);
}

/* ack: "received" (required) and "window" (optional: 0 or BTFD_WINDOW_MIN..MAX). */
static btfd_req_status parse_ack(const cJSON *root, btfd_request *out, char *why, size_t n)
{
    if (!btfd_json_int(cJSON_GetObjectItemCaseSensitive(root, "received"), 0, MAX_SAFE_INT, &out->received))
        return fail(why, n, BTFD_REQ_BAD_FIELD, "ack.received must be a non-negative integer");
    const cJSON *w = cJSON_GetObjectItemCaseSensitive(root, "window");
    out->window = -1;
    if (w && !cJSON_IsNull(w) &&
        (!btfd_json_int(w, 0, BTFD_WINDOW_MAX, &out->window) || (out->window && out->window < BTFD_WINDOW_MIN)))
        return fail(why, n, BTFD_REQ_BAD_FIELD, "ack.window must be 0 or an integer %d..%d", BTFD_WINDOW_MIN,
                    BTFD_WINDOW_MAX);
    return BTFD_REQ_OK;
}

/* Fields after "type": seq, material, budget, have, etag, manifest_kept, token as the type needs. */
static btfd_req_status parse_fields(const cJSON *root, btfd_request *out, char *why, size_t n)
{
    const cJSON *s = cJSON_GetObjectItemCaseSensitive(root, "seq");
    if (s) {
        if (!btfd_json_int(s, -MAX_SAFE_INT, MAX_SAFE_INT, &out->seq))
            return fail(why, n, BTFD_REQ_BAD_FIELD, "\"seq\" must be an integer");
        out->has_seq = 1;
    }
    if (out->type == BTFD_REQ_ACK)
        return parse_ack(root, out, why, n);
    if (out->type == BTFD_REQ_LIST || out->type == BTFD_REQ_PING)
        return BTFD_REQ_OK;
    btfd_req_status r = parse_name(root, out, why, n);
    if (r != BTFD_REQ_OK || out->type == BTFD_REQ_UNSUBSCRIBE)
        return r;
    const cJSON *b = cJSON_GetObjectItemCaseSensitive(root, "budget");
    if (b && !cJSON_IsNull(b)) {
        if ((r = parse_budget(b, &out->budget, why, n)) != BTFD_REQ_OK)
            return r;
        out->has_budget = 1;
    } else if (out->type == BTFD_REQ_BUDGET) {
        return fail(why, n, BTFD_REQ_BAD_FIELD, "\"budget\" message without a budget object");
    }
    if (out->type != BTFD_REQ_SUBSCRIBE)
        return BTFD_REQ_OK;
    const cJSON *h = cJSON_GetObjectItemCaseSensitive(root, "have");
    if (h && !cJSON_IsNull(h) && (r = parse_have(h, out, why, n)) != BTFD_REQ_OK)
        return r;
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(root, "etag");
    if (e && !cJSON_IsNull(e)) {
        if (!cJSON_IsString(e) || strlen(e->valuestring) > BTFD_ETAG_MAX)
            return fail(why, n, BTFD_REQ_BAD_FIELD, "\"etag\" must be a string of at most %d bytes",
                        BTFD_ETAG_MAX);
        strcpy(out->etag, e->valuestring);
    }
    const cJSON *k = cJSON_GetObjectItemCaseSensitive(root, "manifest_kept");
    if (k && !cJSON_IsNull(k)) {
        if (!cJSON_IsBool(k))
            return fail(why, n, BTFD_REQ_BAD_FIELD, "\"manifest_kept\" must be true or false");
        out->manifest_kept = cJSON_IsTrue(k);
    }
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(root, "token");
    if (t && !cJSON_IsNull(t)) {
        if (!cJSON_IsString(t) || strlen(t->valuestring) > BTFD_REQ_TOKEN_MAX)
            return fail(why, n, BTFD_REQ_BAD_FIELD, "\"token\" must be a string of at most %d bytes",
                        BTFD_REQ_TOKEN_MAX);
        strcpy(out->token, t->valuestring);
    }
    return BTFD_REQ_OK;
}

btfd_req_status btfd_request_parse(const char *buf, size_t len, btfd_request *out,
                                   char *why, size_t why_len)
{
    memset(out, 0, sizeof *out);
    out->budget = btfd_budget_unlimited();
    if (why && why_len)
        why[0] = 0;
    if (len > BTFD_MSG_MAX)
        return fail(why, why_len, BTFD_REQ_TOO_LARGE, "message of %zu bytes (at most %d)", len,
                    BTFD_MSG_MAX);
    if (!buf || len == 0)
        return fail(why, why_len, BTFD_REQ_BAD_JSON, "empty message");
    if (has_nul(buf, len))
        return fail(why, why_len, BTFD_REQ_BAD_JSON, "NUL bytes (raw or \\u0000) are not accepted");
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(buf, len, &end, 0);
    if (!root)
        return fail(why, why_len, BTFD_REQ_BAD_JSON, "malformed JSON near byte %td",
                    end ? end - buf : (ptrdiff_t)0);
    btfd_req_status r;
    for (const char *p = end; p < buf + len; p++)
        if (*p != ' ' && *p != '\t' && *p != '\n' && *p != '\r') {
            r = fail(why, why_len, BTFD_REQ_BAD_JSON, "trailing bytes after the JSON value");
            goto done;
        }
    if (!cJSON_IsObject(root)) {
        r = fail(why, why_len, BTFD_REQ_BAD_JSON, "message must be a JSON object");
        goto done;
    }
    if ((r = parse_type(root, out, why, why_len)) == BTFD_REQ_OK)
        r = parse_fields(root, out, why, why_len);
done:
    cJSON_Delete(root);
    return r;
}
