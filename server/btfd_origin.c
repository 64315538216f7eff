/* btfd_origin.c - cross-origin embedding: CORS headers on the public HTTP assets
 * (client files, shaders, /materials, thumbnails) and the Origin check of the
 * WebSocket handshake, both against --allow-origin (doc/protocol.md, section 1). */
#include <string.h>

#include "btfd.h"

int btfd_origin_allowed(const char *list, const char *origin, size_t n)
{
    if (!list || !strcmp(list, "*"))
        return 1;
    for (const char *s = list; *s;) {
        const char *e = strchr(s, ',');
        size_t k = e ? (size_t)(e - s) : strlen(s);
        if (k == n && n && !strncmp(s, origin, n))
            return 1;
        s += k + (e ? 1 : 0);
    }
    return 0;
}

/* The request's Origin header into buf (NUL-terminated); its length, 0 when absent. */
static size_t request_origin(struct lws *wsi, char *buf, size_t n)
{
    int k = lws_hdr_copy(wsi, buf, (int)n, WSI_TOKEN_ORIGIN);
    if (k <= 0) {
        buf[0] = 0;
        return 0;
    }
    return (size_t)k;
}

/* access-control-allow-origin and timing-allow-origin (the page may read the reply's
 * sizes and times in its Resource Timing, e.g. the bytes a gzipped script took) for origin. */
static int allow_origin(struct lws *wsi, const char *origin, int n, unsigned char **p, unsigned char *end)
{
    return lws_add_http_header_by_name(wsi, (const unsigned char *)"access-control-allow-origin:",
                                       (const unsigned char *)origin, n, p, end) ||
           lws_add_http_header_by_name(wsi, (const unsigned char *)"timing-allow-origin:",
                                       (const unsigned char *)origin, n, p, end);
}

int btfd_cors_headers(struct lws *wsi, const char *list, unsigned char **p, unsigned char *end)
{
    static const char vary[] = "Origin";
    if (!list || !strcmp(list, "*"))
        return allow_origin(wsi, "*", 1, p, end);
    char origin[256];
    size_t n = request_origin(wsi, origin, sizeof origin);
    if (lws_add_http_header_by_name(wsi, (const unsigned char *)"vary:", (const unsigned char *)vary,
                                    sizeof vary - 1, p, end))
        return 1;
    if (!n || !btfd_origin_allowed(list, origin, n))
        return 0;
    return allow_origin(wsi, origin, (int)n, p, end);
}

int btfd_origin_check(struct lws *wsi, const char *list)
{
    char origin[256];
    size_t n = request_origin(wsi, origin, sizeof origin);
    return !list || !strcmp(list, "*") || btfd_origin_allowed(list, origin, n) ? 0 : -1;
}
