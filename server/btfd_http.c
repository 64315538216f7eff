/* btfd_http.c - the HTTP routes of btfd (the lws "http" protocol callback).
 *
 *   /healthz                        200 "ok" while serving, 503 "draining" after SIGTERM
 *   /metrics                        Prometheus text format (btfd_ops_metrics)
 *   /materials, /materials.json     the library list (ETag, short max-age); the second is the
 *                                   name of the file `btfd --publish` writes, so a client asks
 *                                   a btfd and a static host for the same path
 *   /materials/NAME/thumbnail.png   (ETag, short max-age)
 *   /materials/NAME/ETAG/FILE       a package file, immutable while ETAG is current; in a
 *                                   private library with ?token= or ?md5=&expires= (403 else)
 *
 * Names are looked up in the library index and FILE among the package's own
 * file names; no path is ever built from the request. Validators: strong
 * ETags, If-None-Match -> 304; single byte ranges (Range: bytes=, If-Range)
 * on package files and thumbnails. See doc/protocol.md section 1.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "btfd.h"

#define CACHE_IMMUTABLE "public, max-age=31536000, immutable"
#define CACHE_LIST "public, max-age=2"
#define CACHE_THUMB "public, max-age=60"
#define CACHE_NONE "no-store"

/* One HTTP transaction on a callback route; lws allocates it zeroed per
 * connection, it lives from LWS_CALLBACK_HTTP until the reply is written. */
typedef struct btfd_http {
    char *body;           /* malloc'd generated body, or NULL */
    btfd_material *mat;   /* reference held while its bytes are sent */
    const uint8_t *data;  /* what is sent: data[off, end) */
    size_t len, off, end; /* len: the whole representation */
    int status;           /* 200, 206, 304, 404, 416, 503 */
    const char *mime;
    const char *cache;    /* Cache-Control */
    char etag[BTFD_NAME_MAX + 48]; /* quoted strong ETag, "" for none */
    int ranges;           /* Range requests are honoured */
    int cors;             /* access-control-allow-origin: * */
} btfd_http;

const size_t btfd_http_user_size = sizeof(btfd_http);

static btfd_server *server_of(struct lws *wsi)
{
    return (btfd_server *)lws_context_user(lws_get_context(wsi));
}

static void http_clear(btfd_http *h)
{
    free(h->body);
    btfd_material_unref(h->mat);
    memset(h, 0, sizeof *h);
}

/* Takes a generated body (malloc'd; NULL: out of memory -> 500). */
static void set_body(btfd_http *h, char *body, const char *mime)
{
    h->body = body;
    h->status = body ? HTTP_STATUS_OK : HTTP_STATUS_INTERNAL_SERVER_ERROR;
    h->data = (const uint8_t *)body;
    h->len = body ? strlen(body) : 0;
    h->mime = mime;
}

/* Serves bytes of material m (a reference is taken). */
static void set_mapped(btfd_http *h, btfd_material *m, const void *data, size_t len, const char *mime)
{
    h->mat = m;
    btfd_material_ref(m);
    h->status = HTTP_STATUS_OK;
    h->data = data;
    h->len = len;
    h->mime = mime;
}

static void route_list(btfd_server *srv, btfd_http *h)
{
    btfd_ops_rescan(srv, 0);
    char *b = btfd_library_list_body(srv->lib);
    set_body(h, b, "application/json");
    if (b)
        snprintf(h->etag, sizeof h->etag, "\"l%016llx\"", (unsigned long long)btfd_hash64(b, strlen(b)));
    h->cache = CACHE_LIST;
    h->cors = 1;
}

/* Splits "/NAME/REST" (after /materials) into a looked-up material and REST. */
static btfd_material *split_name(const btfd_server *srv, const char *path, const char **rest)
{
    const char *slash = path[0] == '/' ? strchr(path + 1, '/') : NULL;
    size_t n = slash ? (size_t)(slash - path - 1) : 0;
    if (!slash || !btfd_name_valid(path + 1, n))
        return NULL;
    char name[BTFD_NAME_MAX + 1];
    memcpy(name, path + 1, n);
    name[n] = 0;
    *rest = slash + 1;
    return btfd_library_find(srv->lib, name);
}

/* FILE of package m: manifest.json, thumbnail.png or a file its chunks name. */
static int route_file(btfd_http *h, btfd_material *m, const char *file)
{
    if (!strcmp(file, "manifest.json")) {
        set_mapped(h, m, m->manifest, m->manifest_len, "application/json");
    } else if (!strcmp(file, "thumbnail.png") && m->thumb) {
        set_mapped(h, m, m->thumb, m->thumb_size, "image/png");
    } else {
        const btfd_file *f = btfd_material_file(m, file);
        if (!f)
            return HTTP_STATUS_NOT_FOUND;
        set_mapped(h, m, f->data, f->size, "application/octet-stream");
    }
    snprintf(h->etag, sizeof h->etag, "\"%s-%s\"", m->etag, file);
    h->cache = CACHE_IMMUTABLE;
    h->ranges = h->cors = 1;
    return HTTP_STATUS_OK;
}

/* A private library's verdict on a package file request of material m: a token,
 * or the nginx secure_link arguments md5 and expires (btfd_token.h). */
static btfd_token_verdict file_access(btfd_server *srv, struct lws *wsi, const btfd_material *m)
{
    if (!srv->key.len)
        return BTFD_TOKEN_OK;
    char tb[BTFD_TOKEN_MAX + 8], mb[64], eb[48];
    const char *t = lws_get_urlarg_by_name(wsi, "token=", tb, sizeof tb);
    const char *md5 = lws_get_urlarg_by_name(wsi, "md5=", mb, sizeof mb);
    const char *ex = lws_get_urlarg_by_name(wsi, "expires=", eb, sizeof eb);
    int64_t now = (int64_t)time(NULL);
    btfd_token_verdict v = btfd_token_check(&srv->key, t, m->name, now);
    if (v != BTFD_TOKEN_OK && md5)
        v = btfd_token_check_md5(&srv->key, md5, ex, m->name, now);
    return v;
}

/* Path after /materials: the list, a thumbnail, or /NAME/ETAG/FILE (a private
 * library's files need a token: 403 with the reason otherwise). */
static int route_materials(btfd_server *srv, struct lws *wsi, btfd_http *h, const char *path)
{
    if (!path[0] || !strcmp(path, "/")) {
        route_list(srv, h);
        return h->status;
    }
    const char *rest = NULL;
    btfd_material *m = split_name(srv, path, &rest);
    if (!m)
        return HTTP_STATUS_NOT_FOUND;
    if (!strcmp(rest, "thumbnail.png")) {
        if (!m->thumb)
            return HTTP_STATUS_NOT_FOUND;
        set_mapped(h, m, m->thumb, m->thumb_size, "image/png");
        snprintf(h->etag, sizeof h->etag, "\"%s-thumbnail.png\"", m->etag);
        h->cache = CACHE_THUMB;
        h->ranges = h->cors = 1;
        return HTTP_STATUS_OK;
    }
    size_t el = strlen(m->etag);
    if (strncmp(rest, m->etag, el) || rest[el] != '/' || !btfd_name_valid(rest + el + 1, strlen(rest + el + 1)))
        return HTTP_STATUS_NOT_FOUND; /* another (older) etag: that package is gone */
    btfd_token_verdict v = file_access(srv, wsi, m);
    if (v != BTFD_TOKEN_OK) {
        srv->stats.forbidden++;
        char msg[160];
        snprintf(msg, sizeof msg, "%s: %s\n", btfd_token_code(v), btfd_token_text(v));
        set_body(h, strdup(msg), "text/plain; charset=utf-8");
        h->cors = 1;
        return h->body ? HTTP_STATUS_FORBIDDEN : HTTP_STATUS_INTERNAL_SERVER_ERROR;
    }
    return route_file(h, m, rest + el + 1);
}

/* Fills h for uri; returns the status. */
static int route(btfd_server *srv, struct lws *wsi, btfd_http *h, const char *uri)
{
    h->cache = CACHE_NONE;
    if (!strcmp(uri, "/healthz")) {
        set_body(h, strdup(srv->draining ? "draining\n" : "ok\n"), "text/plain");
        return srv->draining ? HTTP_STATUS_SERVICE_UNAVAILABLE : h->status;
    }
    if (!strcmp(uri, "/metrics")) {
        set_body(h, btfd_ops_metrics(srv), "text/plain; version=0.0.4; charset=utf-8");
        return h->status;
    }
    if (!strcmp(uri, "/materials.json"))
        return route_materials(srv, wsi, h, "");
    if (!strncmp(uri, "/materials", 10) && (uri[10] == 0 || uri[10] == '/'))
        return route_materials(srv, wsi, h, uri + 10);
    return HTTP_STATUS_NOT_FOUND;
}

/* Header value into buf ("" when absent or too long). */
static const char *header(struct lws *wsi, enum lws_token_indexes t, char *buf, int n)
{
    if (lws_hdr_total_length(wsi, t) <= 0 || lws_hdr_total_length(wsi, t) >= n || lws_hdr_copy(wsi, buf, n, t) < 0)
        buf[0] = 0;
    return buf;
}

/* 1 when If-None-Match lists our ETag (or is "*"); weak comparison, as RFC 9110 asks. */
static int not_modified(struct lws *wsi, const btfd_http *h)
{
    char inm[512];
    header(wsi, WSI_TOKEN_HTTP_IF_NONE_MATCH, inm, sizeof inm);
    return h->etag[0] && inm[0] && (!strcmp(inm, "*") || strstr(inm, h->etag));
}

/* Parses a single "bytes=A-B" / "bytes=A-" / "bytes=-N" range against len into
 * [*a, *b]; 0 ok, 1 unsatisfiable, -1 not a range we honour (send it all). */
static int parse_range(const char *r, size_t len, size_t *a, size_t *b)
{
    unsigned long long x = 0, y = 0;
    int nx = 0, ny = 0;
    if (strncmp(r, "bytes=", 6) || strchr(r, ','))
        return -1;
    for (r += 6; *r >= '0' && *r <= '9' && nx < 19; nx++)
        x = x * 10 + (unsigned)(*r++ - '0');
    if (*r++ != '-')
        return -1;
    for (; *r >= '0' && *r <= '9' && ny < 19; ny++)
        y = y * 10 + (unsigned)(*r++ - '0');
    if (*r || (!nx && !ny) || (nx && ny && y < x))
        return -1;
    if (!nx) { /* suffix: the last y bytes */
        if (!y || !len)
            return 1;
        *a = y >= len ? 0 : len - (size_t)y;
        *b = len - 1;
        return 0;
    }
    if (x >= len)
        return 1;
    *a = (size_t)x;
    *b = !ny || y >= len ? len - 1 : (size_t)y;
    return 0;
}

/* Applies Range (and If-Range) to h: 206 with h->off/end set, or 416. */
static void apply_range(struct lws *wsi, btfd_http *h)
{
    char r[128], ifr[160];
    h->off = 0;
    h->end = h->len;
    if (!h->ranges || !header(wsi, WSI_TOKEN_HTTP_RANGE, r, sizeof r)[0])
        return;
    if (header(wsi, WSI_TOKEN_HTTP_IF_RANGE, ifr, sizeof ifr)[0] && strcmp(ifr, h->etag))
        return; /* the cache holds another version: send it all */
    size_t a = 0, b = 0;
    int k = parse_range(r, h->len, &a, &b);
    if (k == 1)
        h->status = HTTP_STATUS_REQ_RANGE_NOT_SATISFIABLE;
    else if (k == 0) {
        h->status = HTTP_STATUS_PARTIAL_CONTENT;
        h->off = a;
        h->end = b + 1;
    }
}

static int add_header(struct lws *wsi, const char *name, const char *value, uint8_t **p, uint8_t *end)
{
    return lws_add_http_header_by_name(wsi, (const unsigned char *)name, (const unsigned char *)value,
                                       (int)strlen(value), p, end);
}

/* ETag, Cache-Control, Accept-Ranges, Content-Range and CORS headers of h. */
static int add_cache_headers(struct lws *wsi, const btfd_http *h, uint8_t **p, uint8_t *end)
{
    char cr[96];
    if (h->cache && add_header(wsi, "cache-control:", h->cache, p, end))
        return -1;
    if (h->etag[0] && add_header(wsi, "etag:", h->etag, p, end))
        return -1;
    if (h->ranges && add_header(wsi, "accept-ranges:", "bytes", p, end))
        return -1;
    if (h->status == HTTP_STATUS_PARTIAL_CONTENT)
        snprintf(cr, sizeof cr, "bytes %zu-%zu/%zu", h->off, h->end - 1, h->len);
    else if (h->status == HTTP_STATUS_REQ_RANGE_NOT_SATISFIABLE)
        snprintf(cr, sizeof cr, "bytes */%zu", h->len);
    if ((h->status == HTTP_STATUS_PARTIAL_CONTENT || h->status == HTTP_STATUS_REQ_RANGE_NOT_SATISFIABLE) &&
        add_header(wsi, "content-range:", cr, p, end))
        return -1;
    return h->cors && btfd_cors_headers(wsi, server_of(wsi)->opt.allow_origin, p, end) ? -1 : 0;
}

/* Writes the status line and headers; the body follows from WRITEABLE. */
static int send_headers(struct lws *wsi, btfd_http *h, int head_only)
{
    uint8_t buf[LWS_PRE + 2048], *start = buf + LWS_PRE, *p = start, *end = buf + sizeof buf - 1;
    int bodyless = h->status == HTTP_STATUS_NOT_MODIFIED;
    size_t clen = h->status == HTTP_STATUS_REQ_RANGE_NOT_SATISFIABLE ? 0 : h->end - h->off;
    if (bodyless ? lws_add_http_header_status(wsi, (unsigned)h->status, &p, end)
                 : lws_add_http_common_headers(wsi, (unsigned)h->status, h->mime, clen, &p, end))
        return -1;
    if (add_cache_headers(wsi, h, &p, end) || lws_finalize_write_http_header(wsi, start, &p, end))
        return -1;
    if (bodyless || head_only || !clen) {
        http_clear(h);
        return lws_http_transaction_completed(wsi) ? -1 : 0;
    }
    lws_callback_on_writable(wsi);
    return 0;
}

/* A bodyless error reply; 0, or -1 to close the connection. */
static int reply_status(struct lws *wsi, int status)
{
    if (lws_return_http_status(wsi, (unsigned)status, NULL))
        return -1;
    return lws_http_transaction_completed(wsi) ? -1 : 0;
}

static int http_start(btfd_server *srv, struct lws *wsi, btfd_http *h)
{
    http_clear(h);
    char *uri = NULL;
    int ulen = 0, meth = lws_http_get_uri_and_method(wsi, &uri, &ulen);
    char path[1024];
    if (meth < 0 || ulen <= 0 || ulen >= (int)sizeof path)
        return reply_status(wsi, HTTP_STATUS_NOT_FOUND);
    memcpy(path, uri, (size_t)ulen);
    path[ulen] = 0;
    srv->stats.http_requests++;
    int status = route(srv, wsi, h, path);
    if (status == HTTP_STATUS_NOT_FOUND || status == HTTP_STATUS_INTERNAL_SERVER_ERROR) {
        http_clear(h);
        return reply_status(wsi, status);
    }
    h->status = status;
    h->end = h->len;
    if (status == HTTP_STATUS_OK && not_modified(wsi, h)) {
        h->status = HTTP_STATUS_NOT_MODIFIED;
        srv->stats.http_not_modified++;
    } else if (status == HTTP_STATUS_OK) {
        apply_range(wsi, h);
    }
    return send_headers(wsi, h, meth == LWSHUMETH_HEAD);
}

static int http_write(btfd_server *srv, struct lws *wsi, btfd_http *h)
{
    size_t n = h->end - h->off;
    if (n > srv->opt.fragment)
        n = srv->opt.fragment;
    int last = h->off + n == h->end;
    uint8_t *p = srv->scratch + LWS_PRE;
    memcpy(p, h->data + h->off, n);
    if (lws_write(wsi, p, n, last ? LWS_WRITE_HTTP_FINAL : LWS_WRITE_HTTP) != (int)n)
        return -1;
    h->off += n;
    if (!last) {
        lws_callback_on_writable(wsi);
        return 0;
    }
    http_clear(h);
    return lws_http_transaction_completed(wsi) ? -1 : 0;
}

/* Headers of a file mount's reply: CORS (--allow-origin, btfd_origin.c) and Vary:
 * Accept-Encoding (btfd_gzip.c may have sent FILE.gz); 0 ok. */
static int add_file_headers(struct lws *wsi, void *in)
{
    static const char vary[] = "accept-encoding";
    struct lws_process_html_args *a = in;
    unsigned char *p = (unsigned char *)a->p, *end = p + a->max_len;
    if (btfd_cors_headers(wsi, server_of(wsi)->opt.allow_origin, &p, end) ||
        lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_VARY, (const unsigned char *)vary, (int)sizeof vary - 1,
                                     &p, end))
        return 1;
    a->max_len -= (int)(p - (unsigned char *)a->p);
    a->p = (char *)p;
    return 0;
}

/* Marks a wsi counted in btfd_stats.sockets (its opaque user data). */
static char accepted_mark;

int btfd_callback_http(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    btfd_http *h = user;
    switch (reason) {
    case LWS_CALLBACK_HTTP:
        return http_start(server_of(wsi), wsi, h);
    case LWS_CALLBACK_SERVER_NEW_CLIENT_INSTANTIATED: /* every accepted connection, HTTP or stream */
        lws_set_opaque_user_data(wsi, &accepted_mark);
        server_of(wsi)->stats.sockets++;
        return 0;
    case LWS_CALLBACK_WSI_DESTROY: /* of any wsi: only the accepted ones were counted */
        if (lws_get_opaque_user_data(wsi) == &accepted_mark)
            server_of(wsi)->stats.sockets--;
        return 0;
    case LWS_CALLBACK_ADD_HEADERS: /* file mounts: the client files and the shaders */
        return add_file_headers(wsi, in);
    case LWS_CALLBACK_FILTER_PROTOCOL_CONNECTION:
        return 1; /* a WebSocket that did not ask for btf-stream.v1 lands here: refuse it */
    case LWS_CALLBACK_HTTP_WRITEABLE:
        if (h && h->data && h->off < h->end)
            return http_write(server_of(wsi), wsi, h);
        break;
    case LWS_CALLBACK_HTTP_DROP_PROTOCOL:
    case LWS_CALLBACK_CLOSED_HTTP:
        if (h)
            http_clear(h);
        break;
    default:
        break;
    }
    return lws_callback_http_dummy(wsi, reason, user, in, len);
}
