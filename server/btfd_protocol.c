/* btfd_protocol.c - the lws callbacks: HTTP /materials and the btf-stream.v1 WebSocket.
 *
 * Sending rules (see doc/protocol.md): text replies go first, in order; then
 * binary pieces of one chunk at a time, chunks chosen across the connection's
 * subscriptions by error reduction per byte. Exactly one lws_write per
 * WRITEABLE callback, from a shared scratch buffer with LWS_PRE headroom, so a
 * connection never holds more than one piece that the kernel did not take.
 */
#include <cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "btf_version.h"
#include "btfd.h"

/* ------------------------------------------------------------------ state */

/* One queued text message: head, then (if body) the shared manifest text and "}".
 * Owned by its connection's queue; freed once sent or when the connection closes. */
typedef struct out_msg {
    struct out_msg *next;
    char *head;          /* malloc'd */
    size_t head_len;
    btfd_material *body; /* reference held while queued, or NULL */
    size_t len;          /* total message length */
} out_msg;

/* One material a connection subscribed to; lives in its connection until
 * unsubscribed or closed. */
typedef struct btfd_sub {
    int mid;              /* id in binary headers, unique within the connection */
    btfd_material *mat;   /* reference held */
    btfd_budget budget;
    int limit;            /* chunks [0, limit) are allowed by the budget */
    uint8_t *have;        /* malloc'd, n_chunks flags: the client holds the chunk */
    int n_have;
    int complete_sent;    /* "complete" queued for the current budget */
    int chunks_sent;
    uint64_t bytes_sent;
} btfd_sub;

/* One of these per connected WebSocket client; lws allocates it zeroed at
 * connection and it lives until LWS_CALLBACK_CLOSED. */
typedef struct btfd_conn {
    struct lws *wsi;
    uint64_t id;                  /* connection number, for the log */
    char peer[100];               /* address (and X-Forwarded-For), for the log */
    lws_usec_t opened_us;
    lws_usec_t armed_us;          /* when the stall timeout was last armed */
    uint64_t chunks_sent, bytes_sent;
    btfd_sub subs[BTFD_MAX_SUBS]; /* in subscription order */
    int n_subs;
    int next_mid;
    out_msg *q_head, *q_tail;     /* text replies not yet (fully) sent */
    int q_count;
    size_t q_off;                 /* bytes of q_head already sent */
    int cur_mid;                  /* chunk being sent: subscription (0 = none) ... */
    int cur_chunk, cur_file;      /* ... chunk and file index ... */
    size_t cur_off;               /* ... and offset in that file */
    char *rx;                     /* malloc'd while a fragmented message is assembled */
    size_t rx_len;
    int rx_active, rx_over;       /* inside a message / message too large */
    double tokens;                /* request rate limit (token bucket) */
    lws_usec_t tokens_us;
    int close_code;               /* nonzero: close at the next WRITEABLE */
    char close_reason[96];
    uint64_t bin_sent;            /* binary message bytes (headers included) sent */
    uint64_t acked;               /* of those, what the client's last ack says it received */
    uint64_t window;              /* 0: no flow control; else at most this much sent and not acked */
} btfd_conn;

static btfd_server *server_of(struct lws *wsi)
{
    return (btfd_server *)lws_context_user(lws_get_context(wsi));
}

/* ------------------------------------------------------------------ text queue */

static void conn_close_later(btfd_conn *c, int code, const char *reason)
{
    if (!c->close_code) {
        c->close_code = code;
        snprintf(c->close_reason, sizeof c->close_reason, "%s", reason);
    }
    lws_callback_on_writable(c->wsi);
}

static void want_write(btfd_server *srv, btfd_conn *c)
{
    lws_callback_on_writable(c->wsi);
    lws_set_timeout(c->wsi, PENDING_TIMEOUT_USER_OK, srv->opt.stall_timeout_s);
    c->armed_us = lws_now_usecs();
}

/* Queues head (malloc'd, ownership taken) and an optional manifest body. */
static void queue_text(btfd_server *srv, btfd_conn *c, char *head, btfd_material *body)
{
    out_msg *m = head ? calloc(1, sizeof *m) : NULL;
    if (!m || c->q_count >= BTFD_MAX_QUEUED_TEXT) {
        free(head);
        free(m);
        conn_close_later(c, LWS_CLOSE_STATUS_POLICY_VIOLATION,
                         m ? "too many unread replies" : "out of memory");
        return;
    }
    m->head = head;
    m->head_len = strlen(head);
    m->body = body;
    btfd_material_ref(body);
    m->len = m->head_len + (body ? body->manifest_len + 1 : 0);
    if (c->q_tail)
        c->q_tail->next = m;
    else
        c->q_head = m;
    c->q_tail = m;
    c->q_count++;
    want_write(srv, c);
}

static void queue_json(btfd_server *srv, btfd_conn *c, cJSON *obj)
{
    char *s = cJSON_PrintUnformatted(obj);
    cJSON_Delete(obj);
    queue_text(srv, c, s, NULL);
}

/* New reply object {"type": type, "seq": rq->seq if given}. */
static cJSON *reply(const char *type, const btfd_request *rq)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "type", type);
    if (rq && rq->has_seq)
        cJSON_AddNumberToObject(o, "seq", (double)rq->seq);
    return o;
}

static void send_error(btfd_server *srv, btfd_conn *c, const btfd_request *rq, const char *code,
                       const char *msg)
{
    cJSON *o = reply("error", rq);
    cJSON_AddStringToObject(o, "code", code);
    cJSON_AddStringToObject(o, "message", msg);
    if (rq && rq->material[0])
        cJSON_AddStringToObject(o, "material", rq->material);
    queue_json(srv, c, o);
    btfd_log(srv, BTFD_LOG_INFO, "conn %llu: error %s: %s", (unsigned long long)c->id, code, msg);
}

static void free_queue(btfd_conn *c)
{
    while (c->q_head) {
        out_msg *m = c->q_head;
        c->q_head = m->next;
        btfd_material_unref(m->body);
        free(m->head);
        free(m);
    }
    c->q_tail = NULL;
    c->q_count = 0;
}

/* Copies bytes [off, off + n) of message m into dst. */
static void msg_copy(const out_msg *m, size_t off, size_t n, uint8_t *dst)
{
    while (n) {
        const char *src;
        size_t avail;
        if (off < m->head_len) {
            src = m->head + off;
            avail = m->head_len - off;
        } else if (off < m->head_len + m->body->manifest_len) {
            src = m->body->manifest + (off - m->head_len);
            avail = m->head_len + m->body->manifest_len - off;
        } else {
            src = "}";
            avail = 1;
        }
        size_t k = avail < n ? avail : n;
        memcpy(dst, src, k);
        dst += k;
        off += k;
        n -= k;
    }
}

/* ------------------------------------------------------------------ budgets and priority */

/* Length of the manifest prefix the budget allows. */
static int budget_limit(const btfd_material *m, const btfd_budget *b)
{
    int limit = m->n_chunks;
    if (b->max_chunks >= 0 && b->max_chunks < limit)
        limit = (int)b->max_chunks;
    if (b->max_bytes >= 0) {
        uint64_t sum = 0;
        for (int i = 0; i < limit; i++)
            if ((sum += m->chunks[i].bytes) > (uint64_t)b->max_bytes) {
                limit = i;
                break;
            }
    }
    if (b->pixels >= 0) {
        int need = btfd_material_lod_limit(m, b->pixels, b->threshold >= 0 ? b->threshold : BTF_LOD_THRESHOLD);
        if (need < limit)
            limit = need;
    }
    if (b->max_error >= 0 && m->metric)
        for (int i = 0; i < limit; i++)
            if (m->chunks[i].error <= b->max_error) {
                limit = i + 1;
                break;
            }
    return limit;
}

/* First allowed chunk the client does not hold, or -1. */
static int sub_next(const btfd_sub *s)
{
    for (int i = 0; i < s->limit; i++)
        if (!s->have[i])
            return i;
    return -1;
}

/* Error reduction per byte of sending chunk i of s: the scene-wide priority.
 * A material the client holds nothing of comes first (its first chunk is a
 * picture on its own); unknown errors count as no reduction. */
static double sub_priority(const btfd_sub *s, int i)
{
    if (s->n_have == 0 || i == 0)
        return INFINITY;
    const btfd_chunk *ch = s->mat->chunks;
    double red = ch[i - 1].error - ch[i].error;
    if (!(red > 0))
        red = 0;
    return red / (double)(ch[i].bytes ? ch[i].bytes : 1);
}

static btfd_sub *find_sub(btfd_conn *c, const char *name, int mid)
{
    for (int i = 0; i < c->n_subs; i++)
        if ((name && !strcmp(c->subs[i].mat->name, name)) || (!name && c->subs[i].mid == mid))
            return &c->subs[i];
    return NULL;
}

/* Queues "complete" once the subscription has nothing more to send under its budget. */
static void check_complete(btfd_server *srv, btfd_conn *c, btfd_sub *s)
{
    if (s->complete_sent || c->cur_mid == s->mid || sub_next(s) >= 0)
        return;
    s->complete_sent = 1;
    cJSON *o = reply("complete", NULL);
    cJSON_AddNumberToObject(o, "mid", s->mid);
    cJSON_AddStringToObject(o, "material", s->mat->name);
    cJSON_AddNumberToObject(o, "limit", s->limit);
    cJSON_AddNumberToObject(o, "held", s->n_have);
    cJSON_AddNumberToObject(o, "chunks_sent", s->chunks_sent);
    cJSON_AddNumberToObject(o, "bytes_sent", (double)s->bytes_sent);
    queue_json(srv, c, o);
}

/* Chooses the next chunk to send; 0 if nothing is allowed and missing. */
static int pick_chunk(btfd_conn *c)
{
    double best = -1;
    for (int k = 0; k < c->n_subs; k++) {
        btfd_sub *s = &c->subs[k];
        int i = sub_next(s);
        if (i < 0)
            continue;
        double p = sub_priority(s, i);
        if (p > best) {
            best = p;
            c->cur_mid = s->mid;
            c->cur_chunk = i;
        }
    }
    c->cur_file = 0;
    c->cur_off = 0;
    return best >= 0;
}

/* ------------------------------------------------------------------ writing */

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* Sends the next frame of the first queued text message. */
static int send_text(btfd_server *srv, btfd_conn *c)
{
    out_msg *m = c->q_head;
    size_t n = m->len - c->q_off;
    if (n > srv->opt.fragment)
        n = srv->opt.fragment;
    uint8_t *p = srv->scratch + LWS_PRE;
    msg_copy(m, c->q_off, n, p);
    int last = c->q_off + n == m->len;
    int flags = lws_write_ws_flags(LWS_WRITE_TEXT, c->q_off == 0, last);
    if (lws_write(c->wsi, p, n, (enum lws_write_protocol)flags) < (int)n)
        return -1;
    c->q_off += n;
    if (last) {
        c->q_head = m->next;
        if (!c->q_head)
            c->q_tail = NULL;
        c->q_count--;
        c->q_off = 0;
        btfd_material_unref(m->body);
        free(m->head);
        free(m);
    }
    return 0;
}

/* Advances past a finished file, and past a finished chunk. */
static void piece_sent(btfd_server *srv, btfd_conn *c, btfd_sub *s)
{
    const btfd_chunk *ch = &s->mat->chunks[c->cur_chunk];
    if (c->cur_off < ch->files[c->cur_file].size)
        return;
    c->cur_off = 0;
    if (++c->cur_file < ch->n_files)
        return;
    s->have[c->cur_chunk] = 1;
    s->n_have++;
    s->chunks_sent++;
    s->bytes_sent += ch->bytes;
    c->chunks_sent++;
    c->bytes_sent += ch->bytes;
    srv->stats.chunks_sent++;
    c->cur_mid = 0;
    check_complete(srv, c, s);
}

/* Sends one binary piece of the current chunk: header + up to fragment bytes. */
static int send_piece(btfd_server *srv, btfd_conn *c)
{
    btfd_sub *s = find_sub(c, NULL, c->cur_mid);
    if (!s) { /* unsubscribed meanwhile */
        c->cur_mid = 0;
        return 0;
    }
    const btfd_file *f = &s->mat->chunks[c->cur_chunk].files[c->cur_file];
    size_t n = f->size - c->cur_off;
    if (n > srv->opt.fragment)
        n = srv->opt.fragment;
    uint8_t *p = srv->scratch + LWS_PRE;
    put_u32(p, (uint32_t)s->mid);
    put_u32(p + 4, (uint32_t)c->cur_chunk);
    put_u32(p + 8, (uint32_t)c->cur_file);
    put_u32(p + 12, (uint32_t)c->cur_off);
    put_u32(p + 16, (uint32_t)f->size);
    if (n)
        memcpy(p + BTFD_HEADER_BYTES, f->data + c->cur_off, n);
    size_t len = BTFD_HEADER_BYTES + n;
    if (lws_write(c->wsi, p, len, LWS_WRITE_BINARY) < (int)len)
        return -1;
    srv->stats.bytes_sent += n;
    c->bin_sent += len;
    c->cur_off += n;
    piece_sent(srv, c, s);
    return 0;
}

/* Closes with the recorded (or given) code and reason; returns -1 for lws. */
static int close_now(btfd_conn *c, int code, const char *reason)
{
    conn_close_later(c, code, reason);
    lws_close_reason(c->wsi, (enum lws_close_status)c->close_code, (unsigned char *)c->close_reason,
                     strlen(c->close_reason));
    return -1;
}

/* 1 while the client's flow-control window is full: as much as it allows is in flight. */
static int window_closed(const btfd_conn *c)
{
    return c->window && c->bin_sent > c->acked && c->bin_sent - c->acked >= c->window;
}

static int on_writeable(btfd_server *srv, btfd_conn *c)
{
    if (c->close_code)
        return close_now(c, c->close_code, c->close_reason);
    if (btfd_ops_going_away(srv, 0))
        return close_now(c, LWS_CLOSE_STATUS_GOINGAWAY, "server draining");
    int r;
    if (c->q_head)
        r = send_text(srv, c);
    else if (window_closed(c))
        return 0; /* the client's next ack reopens it (the stall timeout stays armed) */
    else if (c->cur_mid || pick_chunk(c))
        r = send_piece(srv, c);
    else if (btfd_ops_going_away(srv, c->n_subs > 0)) /* done; one not subscribed yet is waited for */
        return close_now(c, LWS_CLOSE_STATUS_GOINGAWAY, "server draining");
    else {
        lws_set_timeout(c->wsi, NO_PENDING_TIMEOUT, 0); /* idle: nothing to stall on */
        c->armed_us = 0;
        return 0;
    }
    if (r)
        return -1;
    want_write(srv, c);
    return 0;
}

/* ------------------------------------------------------------------ requests */

static void sub_free(btfd_server *srv, btfd_sub *s)
{
    if (s->mat)
        srv->stats.subscriptions--;
    btfd_material_unref(s->mat);
    free(s->have);
    memset(s, 0, sizeof *s);
}

/* Marks the chunks of rq->have as held when the etag matches; -1 on a bad index. */
static int apply_have(btfd_sub *s, const btfd_request *rq)
{
    if (!rq->n_have || strcmp(rq->etag, s->mat->etag))
        return 0;
    for (int i = 0; i < rq->n_have; i++) {
        if (rq->have[i] >= (uint32_t)s->mat->n_chunks)
            return -1;
        if (!s->have[rq->have[i]]) {
            s->have[rq->have[i]] = 1;
            s->n_have++;
        }
    }
    return 1;
}

/* Header of the manifest message, ending in "manifest": so the body follows; whole (no
 * "manifest") when `kept`: a resumed client that holds the manifest of this etag. */
static char *manifest_head(const btfd_sub *s, const btfd_request *rq, int resumed, int kept)
{
    cJSON *o = reply("manifest", rq);
    cJSON_AddNumberToObject(o, "mid", s->mid);
    cJSON_AddStringToObject(o, "material", s->mat->name);
    cJSON_AddStringToObject(o, "etag", s->mat->etag);
    cJSON_AddStringToObject(o, "metric", s->mat->metric ? s->mat->metric : "none");
    cJSON_AddNumberToObject(o, "limit", s->limit);
    cJSON_AddBoolToObject(o, "resumed", resumed);
    cJSON_AddNumberToObject(o, "held", s->n_have);
    char *txt = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    if (!txt || kept)
        return txt;
    size_t n = strlen(txt);
    char *head = malloc(n + 16);
    if (head) {
        memcpy(head, txt, n - 1); /* drop the closing brace */
        strcpy(head + n - 1, ",\"manifest\":");
    }
    free(txt);
    return head;
}

static void do_subscribe(btfd_server *srv, btfd_conn *c, const btfd_request *rq)
{
    btfd_sub *old = find_sub(c, rq->material, 0);
    if (old) {
        char msg[80];
        snprintf(msg, sizeof msg, "already subscribed as mid %d: use \"budget\"", old->mid);
        return send_error(srv, c, rq, "already_subscribed", msg);
    }
    if (c->n_subs >= BTFD_MAX_SUBS)
        return send_error(srv, c, rq, "too_many_subscriptions", "at most 32 subscriptions per connection");
    btfd_token_verdict v = srv->key.len ? btfd_token_check(&srv->key, rq->token, rq->material, (int64_t)time(NULL))
                                        : BTFD_TOKEN_OK;
    if (v != BTFD_TOKEN_OK) {
        srv->stats.forbidden++;
        return send_error(srv, c, rq, btfd_token_code(v), btfd_token_text(v));
    }
    btfd_material *m = btfd_library_find(srv->lib, rq->material);
    if (!m) {
        btfd_ops_rescan(srv, 0);
        m = btfd_library_find(srv->lib, rq->material);
    }
    if (!m)
        return send_error(srv, c, rq, "unknown_material", "no such material in the library");
    btfd_sub *s = &c->subs[c->n_subs];
    s->have = calloc((size_t)m->n_chunks, 1);
    if (!s->have)
        return send_error(srv, c, rq, "internal", "out of memory");
    s->mat = m;
    btfd_material_ref(m);
    srv->stats.subscriptions++;
    int resumed = apply_have(s, rq);
    if (resumed < 0) {
        sub_free(srv, s);
        return send_error(srv, c, rq, "bad_field", "\"have\" names a chunk the material does not have");
    }
    s->mid = ++c->next_mid;
    s->budget = rq->budget;
    s->limit = budget_limit(m, &s->budget);
    c->n_subs++;
    srv->stats.subscriptions_total++;
    btfd_log(srv, BTFD_LOG_DEBUG, "conn %llu: subscribe %s (mid %d, limit %d, %s)", (unsigned long long)c->id,
             m->name, s->mid, s->limit, resumed ? "resumed" : "new");
    int kept = resumed && rq->manifest_kept;
    queue_text(srv, c, manifest_head(s, rq, resumed, kept), kept ? NULL : m);
    check_complete(srv, c, s);
}

static void do_budget(btfd_server *srv, btfd_conn *c, const btfd_request *rq)
{
    btfd_sub *s = find_sub(c, rq->material, 0);
    if (!s)
        return send_error(srv, c, rq, "not_subscribed", "no subscription to this material");
    s->budget = rq->budget;
    s->limit = budget_limit(s->mat, &s->budget);
    s->complete_sent = 0;
    cJSON *o = reply("budget", rq);
    cJSON_AddNumberToObject(o, "mid", s->mid);
    cJSON_AddStringToObject(o, "material", s->mat->name);
    cJSON_AddNumberToObject(o, "limit", s->limit);
    queue_json(srv, c, o);
    check_complete(srv, c, s);
}

static void do_unsubscribe(btfd_server *srv, btfd_conn *c, const btfd_request *rq)
{
    btfd_sub *s = find_sub(c, rq->material, 0);
    if (!s)
        return send_error(srv, c, rq, "not_subscribed", "no subscription to this material");
    cJSON *o = reply("unsubscribed", rq);
    cJSON_AddNumberToObject(o, "mid", s->mid);
    cJSON_AddStringToObject(o, "material", s->mat->name);
    if (c->cur_mid == s->mid)
        c->cur_mid = 0; /* the partial chunk is abandoned */
    sub_free(srv, s);
    int k = (int)(s - c->subs);
    memmove(&c->subs[k], &c->subs[k + 1], (size_t)(c->n_subs - k - 1) * sizeof *s);
    c->n_subs--;
    memset(&c->subs[c->n_subs], 0, sizeof *s);
    queue_json(srv, c, o);
}

static void do_list(btfd_server *srv, btfd_conn *c, const btfd_request *rq)
{
    btfd_ops_rescan(srv, 0);
    char seq[40] = "";
    if (rq->has_seq)
        snprintf(seq, sizeof seq, ",\"seq\":%lld", (long long)rq->seq);
    size_t n = strlen(srv->lib->list_json) + 128;
    char *s = malloc(n);
    if (s)
        snprintf(s, n, "{\"type\":\"list\"%s,\"generation\":%llu,\"materials\":%s}", seq,
                 (unsigned long long)srv->lib->generation, srv->lib->list_json);
    queue_text(srv, c, s, NULL);
}

/* Flow control (doc/protocol.md, "Flow control"): the client says how much of the
 * binary stream it has received and, optionally, how much may be in flight. */
static void do_ack(btfd_server *srv, btfd_conn *c, const btfd_request *rq)
{
    uint64_t r = (uint64_t)rq->received;
    if (r > c->bin_sent)
        r = c->bin_sent; /* never more than was sent */
    if (r > c->acked)
        c->acked = r;
    if (rq->window >= 0)
        c->window = (uint64_t)rq->window;
    want_write(srv, c); /* with nothing to send, the callback disarms the stall timeout again */
}

/* Token bucket: 0 if the client is over its request rate. */
static int rate_ok(btfd_conn *c)
{
    lws_usec_t now = lws_now_usecs();
    c->tokens += (double)(now - c->tokens_us) * 1e-6 * BTFD_RATE_PER_S;
    if (c->tokens > BTFD_RATE_BURST)
        c->tokens = BTFD_RATE_BURST;
    c->tokens_us = now;
    if (c->tokens < 1)
        return 0;
    c->tokens -= 1;
    return 1;
}

static void handle_message(btfd_server *srv, btfd_conn *c, const char *msg, size_t len)
{
    if (!rate_ok(c))
        return conn_close_later(c, LWS_CLOSE_STATUS_POLICY_VIOLATION, "request flood");
    btfd_request rq;
    char why[200];
    btfd_req_status st = btfd_request_parse(msg, len, &rq, why, sizeof why);
    if (st != BTFD_REQ_OK)
        return send_error(srv, c, st == BTFD_REQ_BAD_NAME ? NULL : &rq, btfd_req_status_code(st), why);
    switch (rq.type) {
    case BTFD_REQ_LIST: return do_list(srv, c, &rq);
    case BTFD_REQ_SUBSCRIBE: return do_subscribe(srv, c, &rq);
    case BTFD_REQ_BUDGET: return do_budget(srv, c, &rq);
    case BTFD_REQ_UNSUBSCRIBE: return do_unsubscribe(srv, c, &rq);
    case BTFD_REQ_PING: return queue_json(srv, c, reply("pong", &rq));
    case BTFD_REQ_ACK: return do_ack(srv, c, &rq);
    }
}

/* Assembles a text message from RECEIVE callbacks; handles it when complete. */
static int on_receive(btfd_server *srv, btfd_conn *c, const char *in, size_t len)
{
    if (c->close_code)
        return 0; /* closing (e.g. origin not allowed): nothing more is read */
    if (lws_frame_is_binary(c->wsi)) {
        static const char why[] = "binary frames are not accepted";
        lws_close_reason(c->wsi, LWS_CLOSE_STATUS_UNACCEPTABLE_OPCODE, (unsigned char *)why,
                         sizeof why - 1);
        return -1;
    }
    int done = lws_is_final_fragment(c->wsi) && !lws_remaining_packet_payload(c->wsi);
    if (!c->rx_active && done) {
        handle_message(srv, c, in, len);
        return 0;
    }
    c->rx_active = 1;
    if (!c->rx_over && c->rx_len + len <= BTFD_MSG_MAX) {
        if (!c->rx && !(c->rx = malloc(BTFD_MSG_MAX)))
            return -1;
        memcpy(c->rx + c->rx_len, in, len);
        c->rx_len += len;
    } else {
        c->rx_over = 1;
    }
    if (!done)
        return 0;
    if (c->rx_over) {
        if (!rate_ok(c))
            conn_close_later(c, LWS_CLOSE_STATUS_POLICY_VIOLATION, "request flood");
        else
            send_error(srv, c, NULL, "too_large", "message over 16384 bytes");
    } else {
        handle_message(srv, c, c->rx, c->rx_len);
    }
    free(c->rx);
    c->rx = NULL;
    c->rx_len = 0;
    c->rx_active = c->rx_over = 0;
    return 0;
}

/* "ADDR" or "ADDR via X-Forwarded-For" into c->peer. */
static void record_peer(btfd_conn *c, struct lws *wsi)
{
    char addr[48] = "?", xff[40] = "";
    lws_get_peer_simple(wsi, addr, sizeof addr);
    int n = lws_hdr_total_length(wsi, WSI_TOKEN_X_FORWARDED_FOR);
    if (n > 0 && n < (int)sizeof xff && lws_hdr_copy(wsi, xff, sizeof xff, WSI_TOKEN_X_FORWARDED_FOR) > 0)
        snprintf(c->peer, sizeof c->peer, "%s via %s", xff, addr);
    else
        snprintf(c->peer, sizeof c->peer, "%s", addr);
}

/* Counts a new connection (on_closed uncounts it, whatever its fate). */
static void conn_register(btfd_server *srv, btfd_conn *c, struct lws *wsi)
{
    c->wsi = wsi;
    c->tokens = BTFD_RATE_BURST;
    c->tokens_us = c->opened_us = lws_now_usecs();
    c->id = ++srv->stats.connections_total;
    srv->stats.connections++;
    btfd_log(srv, BTFD_LOG_DEBUG, "conn %llu: open from %s", (unsigned long long)c->id, c->peer);
}

static void on_established(btfd_server *srv, btfd_conn *c, struct lws *wsi)
{
    conn_register(srv, c, wsi);
    cJSON *o = reply("hello", NULL);
    cJSON_AddStringToObject(o, "protocol", BTFD_SUBPROTOCOL);
    cJSON_AddStringToObject(o, "server", "btfd");
    cJSON_AddStringToObject(o, "version", BTF_VERSION);
    cJSON_AddNumberToObject(o, "header_bytes", BTFD_HEADER_BYTES);
    cJSON_AddNumberToObject(o, "fragment", (double)srv->opt.fragment);
    cJSON_AddNumberToObject(o, "max_message", BTFD_MSG_MAX);
    cJSON_AddNumberToObject(o, "max_subscriptions", BTFD_MAX_SUBS);
    queue_json(srv, c, o);
}

/* Why a connection ended, for its log line; counts stall drops. */
static const char *close_cause(btfd_server *srv, const btfd_conn *c, lws_usec_t now)
{
    if (c->close_code)
        return c->close_reason;
    /* the stall timeout fired: armed with data pending and no write since */
    if (c->armed_us && now - c->armed_us >= (lws_usec_t)srv->opt.stall_timeout_s * 1000000 - 100000) {
        srv->stats.stalls++;
        return "stalled: dropped";
    }
    return "closed by the client";
}

static void on_closed(btfd_server *srv, btfd_conn *c)
{
    lws_usec_t now = lws_now_usecs();
    btfd_log(srv, BTFD_LOG_INFO, "conn %llu from %s: %.1f s, %d subscriptions, %llu chunks, %llu bytes; %s",
             (unsigned long long)c->id, c->peer, (double)(now - c->opened_us) * 1e-6, c->next_mid,
             (unsigned long long)c->chunks_sent, (unsigned long long)c->bytes_sent, close_cause(srv, c, now));
    srv->stats.connections--;
    for (int i = 0; i < c->n_subs; i++)
        sub_free(srv, &c->subs[i]);
    c->n_subs = 0;
    free_queue(c);
    free(c->rx);
    c->rx = NULL;
}

static int callback_stream(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
                           size_t len)
{
    btfd_conn *c = user;
    btfd_server *srv = server_of(wsi);
    switch (reason) {
    case LWS_CALLBACK_FILTER_PROTOCOL_CONNECTION:
        record_peer(c, wsi); /* the handshake's headers are gone by ESTABLISHED */
        return 0;
    case LWS_CALLBACK_ESTABLISHED:
        if (btfd_origin_check(wsi, srv->opt.allow_origin)) {
            conn_register(srv, c, wsi);
            conn_close_later(c, LWS_CLOSE_STATUS_POLICY_VIOLATION, "origin not allowed");
            return 0;
        }
        on_established(srv, c, wsi);
        return 0;
    case LWS_CALLBACK_SERVER_WRITEABLE:
        return on_writeable(srv, c);
    case LWS_CALLBACK_RECEIVE:
        return on_receive(srv, c, in, len);
    case LWS_CALLBACK_CLOSED:
        on_closed(srv, c);
        return 0;
    default:
        return 0;
    }
}

/* tx_packet_size of the stream protocol is set by main from --fragment. */
struct lws_protocols btfd_protocols[] = {
    {"http", btfd_callback_http, 0, 0, 0, NULL, 0}, /* main sets btfd_http_user_size */
    {BTFD_SUBPROTOCOL, callback_stream, sizeof(btfd_conn), 4096, 0, NULL, 0},
    {NULL, NULL, 0, 0, 0, NULL, 0},
};
