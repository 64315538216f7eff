/* ws_client.c - room server (tests): the server tests' blocking WebSocket client on libwebsockets (see ws_client.h).
 *
 * One lws_context per connection (client only, no listener). Outgoing frames
 * wait in a queue and are written from LWS_CALLBACK_CLIENT_WRITEABLE;
 * incoming fragments are joined into whole messages in a queue that
 * wsc_recv pops. Waits run lws_service with a lws_sul timer at the deadline
 * (lws_service itself has no timeout since lws 3.2; the timer's callback
 * runs inside lws_service before it polls, so it wakes the poll with
 * lws_cancel_service).
 */
#include "ws_client.h"

#include <libwebsockets.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#define WSC_SEND_TMO_MS 5000  /* deadline of a send; loopback writes here take microseconds */
#define WSC_OPEN_TMO_MS 5000

/* A frame waiting to be written; buf has LWS_PRE bytes of headroom. Owned by the queue. */
typedef struct wsc_out {
    struct wsc_out *next;
    int flags; /* enum lws_write_protocol */
    size_t len;
    uint8_t *buf;
} wsc_out;

/* A received message waiting for wsc_recv. Owned by the queue. */
typedef struct wsc_in {
    struct wsc_in *next;
    wsc_msg m;
} wsc_in;

/* The connection behind a wsc handle; owned by it, freed by wsc_close. */
struct wsc_conn {
    struct lws_context *ctx;
    struct lws *wsi;
    int state; /* 0 connecting, 1 open, -1 failed or closed */
    char err[200];
    int rcvbuf;
    int corked; /* TCP_CORK set by a batch, cleared when the queue is empty */
    wsc_out *out, *out_tail;
    wsc_in *in, *in_tail;
    uint8_t *cur; /* message being assembled */
    size_t cur_len, cur_cap;
    int cur_op, in_msg;
    int timed_out;
    lws_sorted_usec_list_t sul;
};

void wsc_msg_free(wsc_msg *m)
{
    free(m->data);
    m->data = NULL;
    m->len = 0;
}

static void push_msg(struct wsc_conn *c, int op, uint8_t *data, size_t len, int code)
{
    wsc_in *e = calloc(1, sizeof *e);
    if (!e) {
        free(data);
        return;
    }
    e->m.op = op;
    e->m.data = data;
    e->m.len = len;
    e->m.close_code = code;
    if (c->in_tail)
        c->in_tail->next = e;
    else
        c->in = e;
    c->in_tail = e;
}

/* Appends a received fragment to the message being assembled; queues it when final. */
static void on_receive(struct wsc_conn *c, struct lws *wsi, const void *in, size_t len)
{
    if (!c->in_msg) {
        c->in_msg = 1;
        c->cur_len = 0;
        c->cur_op = lws_frame_is_binary(wsi) ? 2 : 1;
    }
    if (c->cur_len + len + 1 > c->cur_cap) {
        size_t cap = (c->cur_len + len + 1) * 2;
        uint8_t *p = realloc(c->cur, cap);
        if (!p)
            return;
        c->cur = p;
        c->cur_cap = cap;
    }
    if (len)
        memcpy(c->cur + c->cur_len, in, len);
    c->cur_len += len;
    if (!lws_is_final_fragment(wsi))
        return;
    uint8_t *d = malloc(c->cur_len + 1);
    if (d) {
        memcpy(d, c->cur, c->cur_len);
        d[c->cur_len] = 0;
        push_msg(c, c->cur_op, d, c->cur_len, 0);
    }
    c->in_msg = 0;
}

/* A close frame from the server: queued as op 8 with its code and reason. */
static void on_peer_close(struct wsc_conn *c, const uint8_t *in, size_t len)
{
    int code = len >= 2 ? in[0] << 8 | in[1] : 1005;
    size_t n = len >= 2 ? len - 2 : 0;
    uint8_t *d = malloc(n + 1);
    if (!d)
        return;
    if (n)
        memcpy(d, in + 2, n);
    d[n] = 0;
    push_msg(c, 8, d, n, code);
}

static void set_cork(struct wsc_conn *c, int on)
{
    int fd = (int)lws_get_socket_fd(c->wsi);
    if (fd >= 0)
        setsockopt(fd, IPPROTO_TCP, TCP_CORK, &on, sizeof on);
    c->corked = on;
}

/* Writes queued frames while the socket takes them; one lws_write unless the
 * pipe is still free afterwards (a corked batch). */
static int on_writeable(struct wsc_conn *c, struct lws *wsi)
{
    while (c->out) {
        wsc_out *o = c->out;
        if (lws_write(wsi, o->buf + LWS_PRE, o->len, (enum lws_write_protocol)o->flags) < (int)o->len)
            return -1;
        c->out = o->next;
        if (!c->out)
            c->out_tail = NULL;
        free(o->buf);
        free(o);
        if (lws_send_pipe_choked(wsi))
            break;
    }
    if (c->out)
        lws_callback_on_writable(wsi);
    else if (c->corked)
        set_cork(c, 0);
    return 0;
}

static int callback_client(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    (void)user;
    struct wsc_conn *c = lws_context_user(lws_get_context(wsi));
    if (!c)
        return 0;
    switch (reason) {
    case LWS_CALLBACK_CLIENT_CONNECTION_ERROR:
        c->state = -1;
        snprintf(c->err, sizeof c->err, "%s", in ? (const char *)in : "connection error");
        c->wsi = NULL;
        break;
    case LWS_CALLBACK_CLIENT_ESTABLISHED:
        c->state = 1;
        if (c->rcvbuf > 0) {
            int fd = (int)lws_get_socket_fd(wsi);
            setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &c->rcvbuf, sizeof c->rcvbuf);
        }
        break;
    case LWS_CALLBACK_CLIENT_RECEIVE:
        on_receive(c, wsi, in, len);
        break;
    case LWS_CALLBACK_WS_PEER_INITIATED_CLOSE:
        on_peer_close(c, in, len);
        return 0; /* lws echoes the close, then closes */
    case LWS_CALLBACK_CLIENT_WRITEABLE:
        return on_writeable(c, wsi);
    case LWS_CALLBACK_CLIENT_CLOSED:
        c->state = -1;
        c->wsi = NULL;
        break;
    default:
        break;
    }
    return 0;
}

static const struct lws_protocols wsc_protocols[] = {
    {"wsc-test-client", callback_client, 0, 65536, 0, NULL, 0},
    {NULL, NULL, 0, 0, 0, NULL, 0},
};

static void on_deadline(lws_sorted_usec_list_t *sul)
{
    struct wsc_conn *c = lws_container_of(sul, struct wsc_conn, sul);
    c->timed_out = 1;
    lws_cancel_service(c->ctx); /* the sul runs before lws_service's poll: wake it */
}

/* Services the context until done(c) or timeout_ms; returns done(c). */
static int wait_for(struct wsc_conn *c, int (*done)(struct wsc_conn *), int timeout_ms)
{
    c->timed_out = 0;
    lws_sul_schedule(c->ctx, 0, &c->sul, on_deadline, (lws_usec_t)timeout_ms * 1000);
    while (!done(c) && !c->timed_out)
        if (lws_service(c->ctx, 0) < 0)
            break;
    lws_sul_cancel(&c->sul);
    return done(c);
}

static int connected_or_failed(struct wsc_conn *c) { return c->state != 0; }
static int sent_or_closed(struct wsc_conn *c)
{
    return c->state < 0 || (!c->out && c->wsi && !lws_partial_buffered(c->wsi));
}
static int has_msg_or_closed(struct wsc_conn *c) { return c->in || c->state < 0; }

static struct lws_context *make_context(struct wsc_conn *c)
{
    struct lws_context_creation_info info;
    memset(&info, 0, sizeof info);
    info.port = CONTEXT_PORT_NO_LISTEN;
    info.protocols = wsc_protocols;
    info.user = c;
    info.pt_serv_buf_size = 262144; /* read up to 256 KiB per service */
    info.options = LWS_SERVER_OPTION_DISABLE_IPV6;
    return lws_create_context(&info);
}

int wsc_open(wsc *h, int port, const char *protocol, int rcvbuf, char *status, size_t n)
{
    static int log_set;
    if (!log_set) {
        /* failures are reported through status; WSC_LOG=N shows lws's log (lws_set_log_level bits) */
        const char *lv = getenv("WSC_LOG");
        lws_set_log_level(lv ? atoi(lv) : 0, NULL);
        log_set = 1;
    }
    if (status && n)
        status[0] = 0;
    struct wsc_conn *c = calloc(1, sizeof *c);
    h->p = c;
    if (!c)
        return -1;
    c->rcvbuf = rcvbuf;
    if (!(c->ctx = make_context(c))) {
        if (status && n)
            snprintf(status, n, "lws_create_context failed");
        return -1;
    }
    struct lws_client_connect_info ci;
    memset(&ci, 0, sizeof ci);
    ci.context = c->ctx;
    ci.address = "127.0.0.1";
    ci.port = port;
    ci.path = "/stream";
    ci.host = "127.0.0.1";
    ci.origin = "127.0.0.1";
    ci.protocol = protocol;
    ci.local_protocol_name = wsc_protocols[0].name;
    ci.ietf_version_or_minus_one = -1;
    ci.pwsi = &c->wsi;
    if (!lws_client_connect_via_info(&ci) && c->state == 0)
        c->state = -1;
    wait_for(c, connected_or_failed, WSC_OPEN_TMO_MS);
    if (c->state != 1 && status && n)
        snprintf(status, n, "%s", c->err[0] ? c->err : "handshake timed out");
    return c->state == 1 ? 0 : -1;
}

void wsc_close(wsc *h)
{
    struct wsc_conn *c = h->p;
    if (!c)
        return;
    if (c->ctx)
        lws_context_destroy(c->ctx);
    for (wsc_out *o = c->out, *nx; o; o = nx) {
        nx = o->next;
        free(o->buf);
        free(o);
    }
    for (wsc_in *e = c->in, *nx; e; e = nx) {
        nx = e->next;
        free(e->m.data);
        free(e);
    }
    free(c->cur);
    free(c);
    h->p = NULL;
}

/* Queues one frame (copied behind LWS_PRE headroom). */
static int enqueue(struct wsc_conn *c, int flags, const void *data, size_t len)
{
    wsc_out *o = calloc(1, sizeof *o);
    uint8_t *b = malloc(LWS_PRE + len + 1);
    if (!o || !b) {
        free(o);
        free(b);
        return -1;
    }
    if (len)
        memcpy(b + LWS_PRE, data, len);
    o->buf = b;
    o->len = len;
    o->flags = flags;
    if (c->out_tail)
        c->out_tail->next = o;
    else
        c->out = o;
    c->out_tail = o;
    return 0;
}

static int flush(struct wsc_conn *c)
{
    if (c->state != 1 || !c->wsi)
        return -1;
    lws_callback_on_writable(c->wsi);
    return wait_for(c, sent_or_closed, WSC_SEND_TMO_MS) && c->state == 1 ? 0 : -1;
}

int wsc_send_frame(wsc *h, int op, int fin, const void *data, size_t len)
{
    struct wsc_conn *c = h->p;
    if (!c || c->state != 1)
        return -1;
    int flags = op == 2 ? LWS_WRITE_BINARY : op == 0 ? LWS_WRITE_CONTINUATION : LWS_WRITE_TEXT;
    if (!fin)
        flags |= LWS_WRITE_NO_FIN;
    if (enqueue(c, flags, data, len))
        return -1;
    return flush(c);
}

int wsc_send_text(wsc *h, const char *s)
{
    return wsc_send_frame(h, 1, 1, s, strlen(s));
}

int wsc_send_batch(wsc *h, const char *const *msgs, int n)
{
    struct wsc_conn *c = h->p;
    if (!c || c->state != 1 || !c->wsi)
        return -1;
    int bytes = 0;
    for (int i = 0; i < n; i++) {
        if (enqueue(c, LWS_WRITE_TEXT, msgs[i], strlen(msgs[i])))
            return -1;
        bytes += (int)strlen(msgs[i]) + 14;
    }
    /* room for the whole batch, so it is written in one WRITEABLE callback
     * before the server can answer (e.g. close a flood) */
    bytes *= 2;
    setsockopt((int)lws_get_socket_fd(c->wsi), SOL_SOCKET, SO_SNDBUF, &bytes, sizeof bytes);
    set_cork(c, 1);
    return flush(c);
}

int wsc_recv(wsc *h, wsc_msg *m, int timeout_ms)
{
    struct wsc_conn *c = h->p;
    memset(m, 0, sizeof *m);
    if (!c)
        return -1;
    if (!c->in && c->state >= 0)
        wait_for(c, has_msg_or_closed, timeout_ms);
    if (c->in) {
        wsc_in *e = c->in;
        c->in = e->next;
        if (!c->in)
            c->in_tail = NULL;
        *m = e->m;
        free(e);
        return 1;
    }
    if (c->state < 0) {
        m->op = -1;
        return -1;
    }
    return 0;
}
