/* server_load.c - load generator for bench/bench_server.sh (in a subdirectory
 * so the Makefile's rule for bench/NAME.c skips it; the script builds it, with
 * libwebsockets and cJSON, and -Itests for tests/lws_connect.h).
 *
 *   server_load ws   PORT MATERIAL CLIENTS [STALLED] [PREFIX]
 *   server_load http PORT MATERIAL CLIENTS [PREFIX]
 *
 * ws: one libwebsockets client context multiplexing CLIENTS connections to
 * btfd (subprotocol btf-stream.v1). Each subscribes to MATERIAL with no
 * budget, counts the payload bytes of the binary pieces and closes on
 * "complete". STALLED more connections subscribe too but stop reading
 * (lws_rx_flow_control off) after their first piece; they never finish.
 * http: CLIENTS keep-alive HTTP/1.1 connections (epoll, non-blocking) to a
 * static file server (nginx) with MATERIAL's package under its root: each
 * fetches MATERIAL/manifest.json, then every file of every chunk in manifest
 * order, the same bytes the WebSocket clients get.
 *
 * All connections start at once. Output, one `name value unit` line each,
 * names prefixed by PREFIX: clients, failed, file bytes per client, total
 * seconds, aggregate MB/s (file bytes, 1 MB = 1e6 bytes), time to first chunk
 * (connect start -> chunk 0 complete) median and p99 over the finished clients,
 * and this process's CPU seconds (libwebsockets 4.1's client parses frame
 * payload byte by byte, about 5 ns/byte: with one client process the
 * WebSocket runs are bound by the client, not by btfd; the servers' own CPU
 * seconds, measured by the script, compare the servers).
 * Exits 1 when a client fails or the run exceeds 120 s.
 */
#include <arpa/inet.h>
#include <cJSON.h>
#include <errno.h>
#include <libwebsockets.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "lws_connect.h"

#define RUN_LIMIT_S 120

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* One client of either kind; all live in one array owned by main. */
typedef struct client {
    double t_start, t_first_chunk, t_done;
    long long bytes;  /* file payload bytes received */
    int done, failed, stalled;
    /* ws */
    struct lws *wsi;
    int sent_sub, in_piece;
    char *text;        /* text message being joined (malloc'd) */
    size_t text_len;
    uint8_t hdr[20];   /* piece header being read */
    size_t hdr_got, piece_len;
    int chunk0_files;  /* files of chunk 0, from the manifest */
    /* http */
    int fd, stage, n_files, connected;
    char **files;      /* file names in fetch order (malloc'd) */
    char head[8192];
    size_t head_len;
    long long clen, body_got;
    char *body;        /* manifest body (malloc'd) */
} client;

static client *g_cl;
static int g_n, g_active, g_finished, g_failed;
static const char *g_material;

static void finish(client *c, int failed)
{
    if (c->done)
        return;
    c->done = 1;
    c->failed = failed;
    c->t_done = now_s();
    g_finished++;
    g_failed += failed;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void report(const char *px, double t0, double t1)
{
    double *tt = malloc(sizeof(double) * (size_t)(g_active ? g_active : 1));
    int n = 0;
    long long bytes = 0, per = 0;
    for (int i = 0; i < g_n; i++) {
        client *c = &g_cl[i];
        if (c->stalled)
            continue;
        bytes += c->bytes;
        if (c->done && !c->failed) {
            per = c->bytes;
            if (c->t_first_chunk > 0)
                tt[n++] = (c->t_first_chunk - c->t_start) * 1e3;
        }
    }
    qsort(tt, (size_t)n, sizeof *tt, cmp_d);
    printf("%sclients %d conn\n", px, g_active);
    printf("%sfailed %d conn\n", px, g_failed + (g_active - g_finished));
    printf("%sbytes_per_client %lld B\n", px, per);
    printf("%sseconds %.3f s\n", px, t1 - t0);
    printf("%sthroughput %.1f MB/s\n", px, (double)bytes / 1e6 / (t1 - t0));
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    printf("%sclient_cpu %.2f s\n", px,
           (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + (double)ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6);
    if (n) {
        printf("%sttfc_median %.2f ms\n", px, tt[(n - 1) / 2]);
        printf("%sttfc_p99 %.2f ms\n", px, tt[(int)((n - 1) * 0.99 + 0.5)]);
    }
    free(tt);
}

/* ================================================================ WebSocket (libwebsockets) */

static void ws_text(client *c, const char *in, size_t len, int final)
{
    char *t = realloc(c->text, c->text_len + len + 1);
    if (!t)
        return;
    c->text = t;
    memcpy(t + c->text_len, in, len);
    c->text_len += len;
    t[c->text_len] = 0;
    if (!final)
        return;
    cJSON *j = cJSON_Parse(c->text);
    const char *type = j ? cJSON_GetStringValue(cJSON_GetObjectItem(j, "type")) : NULL;
    if (type && !strcmp(type, "manifest")) {
        cJSON *ch = cJSON_GetArrayItem(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "manifest"), "chunks"), 0);
        c->chunk0_files = cJSON_GetArraySize(cJSON_GetObjectItem(ch, "files"));
    } else if (type && !strcmp(type, "complete")) {
        finish(c, 0);
    } else if (type && !strcmp(type, "error")) {
        fprintf(stderr, "server_load: error message: %s\n", c->text);
        finish(c, 1);
    }
    cJSON_Delete(j);
    c->text_len = 0;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Part of a binary piece: header bytes first, then payload. */
static void ws_binary(client *c, struct lws *wsi, const uint8_t *in, size_t len, int first, int final)
{
    if (first) {
        c->hdr_got = 0;
        c->piece_len = 0;
    }
    size_t h = 0;
    if (c->hdr_got < 20) {
        h = 20 - c->hdr_got < len ? 20 - c->hdr_got : len;
        memcpy(c->hdr + c->hdr_got, in, h);
        c->hdr_got += h;
    }
    c->bytes += (long long)(len - h);
    c->piece_len += len - h;
    if (!final)
        return;
    uint32_t chunk = le32(c->hdr + 4), file = le32(c->hdr + 8), off = le32(c->hdr + 12), total = le32(c->hdr + 16);
    if (chunk == 0 && (int)file == c->chunk0_files - 1 && off + c->piece_len == total && c->t_first_chunk == 0)
        c->t_first_chunk = now_s();
    if (c->stalled)
        lws_rx_flow_control(wsi, 0); /* stop reading: the kernel buffers fill, then the server's */
}

static int ws_callback(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    (void)user;
    client *c = lws_get_opaque_user_data(wsi);
    if (!c)
        return 0;
    switch (reason) {
    case LWS_CALLBACK_CLIENT_CONNECTION_ERROR:
        fprintf(stderr, "server_load: connect failed: %s\n", in ? (char *)in : "?");
        c->wsi = NULL;
        finish(c, 1);
        break;
    case LWS_CALLBACK_CLIENT_ESTABLISHED:
        lws_callback_on_writable(wsi);
        break;
    case LWS_CALLBACK_CLIENT_WRITEABLE:
        if (!c->sent_sub) {
            uint8_t buf[LWS_PRE + 256];
            int n = snprintf((char *)buf + LWS_PRE, 256, "{\"type\":\"subscribe\",\"material\":\"%s\"}", g_material);
            c->sent_sub = 1;
            if (lws_write(wsi, buf + LWS_PRE, (size_t)n, LWS_WRITE_TEXT) < n)
                return -1;
        }
        break;
    case LWS_CALLBACK_CLIENT_RECEIVE: {
        int final = lws_is_final_fragment(wsi);
        if (lws_frame_is_binary(wsi)) {
            int first = !c->in_piece;
            c->in_piece = !final;
            ws_binary(c, wsi, in, len, first, final);
        } else {
            ws_text(c, in, len, final);
        }
        if (c->done && !c->stalled)
            return -1; /* close: we have everything */
        break;
    }
    case LWS_CALLBACK_CLIENT_CLOSED:
        c->wsi = NULL;
        if (!c->done && !c->stalled) /* stalled ones are closed at the end, on purpose */
            fprintf(stderr, "server_load: connection %d closed early\n", (int)(c - g_cl));
        finish(c, 0 == c->done && !c->stalled);
        break;
    default:
        break;
    }
    return 0;
}

static const struct lws_protocols ws_protocols[] = {
    {"bench-client", ws_callback, 0, 65536, 0, NULL, 0},
    {NULL, NULL, 0, 0, 0, NULL, 0},
};

static int run_ws(int port, int n, int stalled, const char *px)
{
    lws_set_log_level(LLL_ERR, NULL);
    struct lws_context_creation_info info;
    memset(&info, 0, sizeof info);
    info.port = CONTEXT_PORT_NO_LISTEN;
    info.protocols = ws_protocols;
    info.pt_serv_buf_size = 262144;
    info.options = LWS_SERVER_OPTION_DISABLE_IPV6;
    struct lws_context *ctx = lws_create_context(&info);
    if (!ctx)
        return 1;
    g_n = n + stalled;
    g_active = n;
    g_cl = calloc((size_t)g_n, sizeof *g_cl);
    /* the stalled ones first, so they hold the server's buffers while the others run */
    for (int i = 0; i < g_n; i++)
        g_cl[i].stalled = i < stalled;
    double t0 = now_s();
    for (int i = 0; i < g_n; i++) {
        client *c = &g_cl[i];
        c->t_start = now_s();
        if (!btf_lws_connect(ctx, port, ws_protocols[0].name, c, &c->wsi) && !c->done)
            finish(c, 1);
        if (i == stalled - 1) /* let the stalled ones fill their pipes before the rest start */
            while (now_s() - c->t_start < 1.0)
                lws_service(ctx, 0);
        if (i == stalled - 1)
            t0 = now_s();
    }
    int active_done = 0;
    while (active_done < n && now_s() - t0 < RUN_LIMIT_S) {
        lws_service(ctx, 0);
        active_done = 0;
        for (int i = stalled; i < g_n; i++)
            active_done += g_cl[i].done;
    }
    double t1 = now_s();
    int stalled_alive = 0;
    for (int i = 0; i < stalled; i++)
        stalled_alive += g_cl[i].wsi != NULL;
    g_finished = active_done;
    g_failed = 0;
    for (int i = stalled; i < g_n; i++)
        g_failed += g_cl[i].failed;
    report(px, t0, t1);
    if (stalled)
        printf("%sstalled_connected_at_end %d conn\n", px, stalled_alive);
    lws_context_destroy(ctx);
    for (int i = 0; i < g_n; i++)
        free(g_cl[i].text);
    int ok = g_failed == 0 && active_done == n;
    free(g_cl);
    return ok ? 0 : 1;
}

/* ================================================================ HTTP (epoll) */

static int http_request(client *c)
{
    char req[600];
    const char *name = c->stage == 0 ? "manifest.json" : c->files[c->stage - 1];
    int n = snprintf(req, sizeof req, "GET /%s/%s HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", g_material, name);
    c->head_len = 0;
    c->clen = -1;
    c->body_got = 0;
    return send(c->fd, req, (size_t)n, MSG_NOSIGNAL) == n ? 0 : -1;
}

/* The manifest arrived: the files of every chunk, in order. */
static int http_manifest(client *c)
{
    cJSON *j = cJSON_Parse(c->body), *ch, *f;
    free(c->body);
    c->body = NULL;
    if (!j)
        return -1;
    int n = 0, k = 0;
    cJSON_ArrayForEach(ch, cJSON_GetObjectItem(j, "chunks")) n += cJSON_GetArraySize(cJSON_GetObjectItem(ch, "files"));
    c->files = calloc((size_t)n + 1, sizeof *c->files);
    cJSON_ArrayForEach(ch, cJSON_GetObjectItem(j, "chunks")) {
        cJSON_ArrayForEach(f, cJSON_GetObjectItem(ch, "files")) c->files[k++] = strdup(f->valuestring);
        if (c->chunk0_files == 0)
            c->chunk0_files = k;
    }
    c->n_files = n;
    cJSON_Delete(j);
    return 0;
}

/* A response is complete: next request, or done. */
static int http_next(client *c)
{
    if (c->stage == 0 && http_manifest(c))
        return -1;
    if (c->stage == c->chunk0_files)
        c->t_first_chunk = now_s();
    if (c->stage == c->n_files) {
        finish(c, 0);
        close(c->fd);
        c->fd = -1;
        return 0;
    }
    c->stage++;
    return http_request(c);
}

/* Consumes received bytes: headers into c->head, body counted (manifest kept). */
static int http_data(client *c, const char *p, size_t n)
{
    while (n) {
        if (c->clen < 0) {
            size_t k = n < sizeof c->head - 1 - c->head_len ? n : sizeof c->head - 1 - c->head_len;
            if (!k)
                return -1;
            memcpy(c->head + c->head_len, p, k);
            c->head_len += k;
            c->head[c->head_len] = 0;
            char *e = strstr(c->head, "\r\n\r\n");
            if (!e) {
                p += k;
                n -= k;
                continue;
            }
            if (strncmp(c->head, "HTTP/1.1 200", 12))
                return -1;
            char *cl = strcasestr(c->head, "content-length:");
            if (!cl || cl > e)
                return -1;
            c->clen = atoll(cl + 15);
            size_t used = (size_t)(e + 4 - c->head) - (c->head_len - k);
            p += used;
            n -= used;
            if (c->stage == 0)
                c->body = malloc((size_t)c->clen + 1);
            if (c->clen == 0 && http_next(c))
                return -1;
            continue;
        }
        size_t k = (long long)n < c->clen - c->body_got ? n : (size_t)(c->clen - c->body_got);
        if (c->stage == 0)
            memcpy(c->body + c->body_got, p, k);
        else
            c->bytes += (long long)k;
        c->body_got += (long long)k;
        p += k;
        n -= k;
        if (c->body_got == c->clen) {
            if (c->stage == 0)
                c->body[c->clen] = 0;
            if (n)
                return -1; /* no pipelining: nothing may follow a response */
            if (http_next(c))
                return -1;
        }
    }
    return 0;
}

static int run_http(int port, int n, const char *px)
{
    static char buf[262144];
    g_n = g_active = n;
    g_cl = calloc((size_t)n, sizeof *g_cl);
    int ep = epoll_create1(0);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    double t0 = now_s();
    for (int i = 0; i < n; i++) {
        client *c = &g_cl[i];
        c->t_start = now_s();
        c->fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
        int one = 1;
        setsockopt(c->fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        if (c->fd < 0 || (connect(c->fd, (struct sockaddr *)&a, sizeof a) && errno != EINPROGRESS)) {
            finish(c, 1);
            continue;
        }
        struct epoll_event ev = {.events = EPOLLIN | EPOLLOUT, .data.ptr = c};
        epoll_ctl(ep, EPOLL_CTL_ADD, c->fd, &ev);
    }
    struct epoll_event evs[256];
    while (g_finished < n && now_s() - t0 < RUN_LIMIT_S) {
        int k = epoll_wait(ep, evs, 256, 1000);
        for (int e = 0; e < k; e++) {
            client *c = evs[e].data.ptr;
            if (c->done)
                continue;
            int bad = (evs[e].events & (EPOLLERR | EPOLLHUP)) && !(evs[e].events & EPOLLIN);
            if (!bad && !c->connected && (evs[e].events & EPOLLOUT)) {
                c->connected = 1;
                struct epoll_event ev = {.events = EPOLLIN, .data.ptr = c};
                epoll_ctl(ep, EPOLL_CTL_MOD, c->fd, &ev);
                bad = http_request(c) != 0;
            }
            while (!bad && !c->done && (evs[e].events & EPOLLIN)) {
                ssize_t r = recv(c->fd, buf, sizeof buf, 0);
                if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
                    break;
                if (r <= 0 || http_data(c, buf, (size_t)r))
                    bad = 1;
            }
            if (bad) {
                fprintf(stderr, "server_load: http client %d failed at stage %d\n", (int)(c - g_cl), c->stage);
                close(c->fd);
                finish(c, 1);
            }
        }
    }
    double t1 = now_s();
    report(px, t0, t1);
    for (int i = 0; i < n; i++) {
        for (int f = 0; g_cl[i].files && f < g_cl[i].n_files; f++)
            free(g_cl[i].files[f]);
        free(g_cl[i].files);
        free(g_cl[i].body);
        if (!g_cl[i].done && g_cl[i].fd >= 0)
            close(g_cl[i].fd);
    }
    close(ep);
    int ok = g_failed == 0 && g_finished == n;
    free(g_cl);
    return ok ? 0 : 1;
}

int main(int argc, char **argv)
{
    if (argc < 5 || (strcmp(argv[1], "ws") && strcmp(argv[1], "http"))) {
        fprintf(stderr, "usage: server_load ws PORT MATERIAL CLIENTS [STALLED] [PREFIX]\n"
                        "       server_load http PORT MATERIAL CLIENTS [PREFIX]\n");
        return 2;
    }
    int port = atoi(argv[2]), n = atoi(argv[4]);
    g_material = argv[3];
    if (!strcmp(argv[1], "ws"))
        return run_ws(port, n, argc > 5 ? atoi(argv[5]) : 0, argc > 6 ? argv[6] : "");
    return run_http(port, n, argc > 5 ? argv[5] : "");
}
