/* btfd.h - pieces of the btfd server shared by its main and its protocol callback.
 *
 * btfd_main.c parses the command line, fills a btfd_server and runs the lws
 * event loop; btfd_protocol.c holds the WebSocket callback (btf-stream.v1) and
 * the protocol table, btfd_http.c the HTTP one (/materials, /healthz, /metrics),
 * btfd_ops.c what both use (rescans, draining, the log, the metrics text).
 * Everything runs on the one lws service thread.
 */
#ifndef BTFD_H
#define BTFD_H

#include <libwebsockets.h>
#include <stdint.h>

#include "btfd_library.h"
#include "btfd_ops.h"
#include "btfd_request.h"
#include "btfd_token.h"

#define BTFD_SUBPROTOCOL "btf-stream.v1"
#define BTFD_VHOST "default"        /* the one vhost lws makes from the context's creation info */
#define BTFD_HEADER_BYTES 20        /* binary piece header: 5 x u32 little-endian */
#define BTFD_MAX_SUBS 32            /* subscriptions per connection */
#define BTFD_MAX_QUEUED_TEXT 64     /* queued text replies per connection before it is closed */
#define BTFD_RATE_BURST 256.0       /* messages a client may send at once ... */
#define BTFD_RATE_PER_S 128.0       /* ... and per second after that */

/* Command-line settings; zero fields mean the defaults of btfd_main.c. Value type. */
typedef struct btfd_options {
    const char *library_dir;
    const char *client_dir;  /* mounted at / */
    const char *shaders_dir; /* mounted at /shaders/ */
    const char *bind;        /* interface address, 127.0.0.1 by default */
    int port;                /* 0 picks a free port (printed on stdout) */
    size_t fragment;         /* payload bytes per binary piece */
    int stall_timeout_s;     /* a client with pending data and no progress this long is dropped */
    int rescan_ms;           /* periodic library rescan; 0 disables */
    const char *allow_origin; /* --allow-origin: comma-separated origins, NULL or "*" = any */
    int drain_s;             /* SIGTERM: streams may finish this long before 1001 */
    int verbose;             /* -v count: 1 debug lines, 2 also lws notices */
    const char *token_secret_file; /* --token-secret-file: a private library (btfd_token.h); NULL public */
    const char *make_token;  /* --make-token SCOPE: print a token and exit */
    int ttl_s;               /* --ttl: the made token's lifetime */
} btfd_options;

/* The server: one per process, owned by main, lives for the whole event loop. */
typedef struct btfd_server {
    btfd_options opt;
    btfd_library *lib;
    btfd_token_key key;        /* len 0: a public library */
    struct lws_context *ctx;
    uint8_t *scratch;          /* LWS_PRE + header + fragment: shared send buffer (malloc'd) */
    size_t scratch_len;
    lws_usec_t last_scan_us;   /* rate limit of on-demand rescans */
    lws_sorted_usec_list_t sul_rescan;
    btfd_stats stats;          /* what /metrics reports */
    int draining;              /* SIGTERM arrived: refuse new streams, close idle ones */
    int drain_expired;         /* --drain-seconds passed: close every stream */
    int stop;                  /* end the event loop */
    lws_sorted_usec_list_t sul_drain;
} btfd_server;

/* The HTTP callback (btfd_http.c): /materials, /healthz, /metrics, upgrade checks. */
int btfd_callback_http(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len);
/* Per-transaction size of its user data. */
extern const size_t btfd_http_user_size;

/* http, btf-stream.v1, terminator; main sets the stream's tx_packet_size before use. */
extern struct lws_protocols btfd_protocols[];

/* btfd_publish.c (--publish OUT): the scanned library as files for a static host; 0 ok, 1 failure. */
int btfd_publish(const btfd_options *o, btfd_library *lib, const char *out);

/* btfd_gzip.c: FILE.gz for FILE on the file mounts when the request accepts gzip. */
void btfd_gzip_install(struct lws_context *ctx);

/* btfd_origin.c (--allow-origin). Whether origin (n bytes) is in list (NULL or "*": any). */
int btfd_origin_allowed(const char *list, const char *origin, size_t n);
/* Adds access-control-allow-origin and timing-allow-origin (and vary: Origin for a list)
 * to an HTTP reply; 0 ok. */
int btfd_cors_headers(struct lws *wsi, const char *list, unsigned char **p, unsigned char *end);
/* WebSocket handshake: 0 when its Origin is allowed, else -1 (the caller closes with 1008). */
int btfd_origin_check(struct lws *wsi, const char *list);

#endif
