/* resume_clients.c - many btf-stream.v1 clients that survive a server going away
 * (run by tests/deploy_test.sh; built by server/build.mk as $(BUILD)/resume_clients).
 *
 *   resume_clients PORT MATERIAL LIBDIR CLIENTS [KILL_PID KILL_AT [STEP_MS [KILL|TERM|RAW]]]
 *
 * One libwebsockets client context multiplexes CLIENTS connections to
 * ws://127.0.0.1:PORT/stream (nginx in front of several btfd). Each client
 * streams MATERIAL one chunk at a time (budget {"chunks": held + 1}, raised
 * STEP_MS after each "complete", default 20), so every stream is still
 * running when KILL_PID gets SIGKILL (or SIGTERM: a draining btfd, whose
 * clients get 1001), once KILL_AT (0..1) of all chunks have arrived. A client
 * whose connection ends before it holds every chunk drops
 * its partial chunk and reconnects after a backoff (50 ms doubling up to 1 s,
 * plus up to as much again of random jitter), then subscribes with its etag
 * and the list of chunks it holds ("have").
 *
 * The client's own bookkeeping is the test: every piece is compared with the
 * package file in LIBDIR/MATERIAL at its offset; a chunk must arrive whole and
 * at most once per client (a piece of a held chunk is a duplicate); a resumed
 * subscription must say "resumed": true. Prints `name value` lines and exits 0
 * only when every client holds every chunk, nothing came twice, no byte
 * differed and (with KILL_PID) the kill happened and some client resumed.
 * Every run ends within RUN_LIMIT_S.
 *
 * RAW: clients as an operator's own would be, with no retry: each connects once,
 * subscribes to every chunk at once and counts as complete only if it receives
 * them all on that one connection; the connects are spread evenly over STEP_MS
 * milliseconds and KILL_PID gets SIGTERM KILL_AT seconds after the first one.
 * Exits 0 only when every client completed.
 */
#include <cJSON.h>
#include <libwebsockets.h>

#include "btf_fs.h"
#include "lws_connect.h"
#include "btf_common.h"
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define RUN_LIMIT_S 60
#define MAX_CHUNKS 256
#define MAX_FILES 64

/* The package as on disk; one, read at start, lives for the run. */
typedef struct pkg {
    char *manifest_text;
    cJSON *manifest;
    int n_chunks;
    int n_files[MAX_CHUNKS];
    uint8_t *data[MAX_CHUNKS][MAX_FILES]; /* malloc'd file contents */
    size_t size[MAX_CHUNKS][MAX_FILES];
} pkg;

/* One client; all live in one array owned by main, for the whole run. */
typedef struct client {
    struct lws *wsi;
    lws_sorted_usec_list_t sul; /* reconnect backoff or the next budget step */
    int idx, attempts, reconnects, resumes, done, opened;
    char etag[80];
    uint8_t have[MAX_CHUNKS];
    int held;
    char out[8192];             /* the next text message to send, "" when none */
    char *text;                 /* text message being joined (malloc'd) */
    size_t text_len;
    int in_msg, msg_binary;
    uint8_t hdr[20];            /* piece header being read */
    size_t hdr_got, pos;        /* header bytes, payload bytes of this piece so far */
    int cur_chunk;              /* chunk whose pieces arrive, -1 none */
    double t_start, t_first;
} client;

static pkg g_pkg;
static client *g_cl;
static int g_n, g_port, g_step_ms = 20, g_kill_pid, g_kill_sig = SIGKILL, g_raw;
static double g_kill_at = -1;
static const char *g_mat;
static struct lws_context *g_ctx;
static long long g_delivered, g_dups, g_bad_bytes, g_not_resumed, g_goaway, g_killed, g_lost;
static unsigned g_seed = 12345;

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Whole file (codec/common/btf_fs.h), NULL if unreadable. */
static uint8_t *slurp(const char *path, size_t *n)
{
    char *text = NULL;
    return btf_fs_read(path, (size_t)1 << 31, &text, n, NULL) == BTF_OK ? (uint8_t *)text : NULL;
}

/* Reads LIBDIR/MATERIAL: the manifest and every file its chunks name. */
static int load_pkg(const char *lib, const char *mat)
{
    char path[4096];
    size_t n;
    snprintf(path, sizeof path, "%s/%s/manifest.json", lib, mat);
    g_pkg.manifest_text = (char *)slurp(path, &n);
    g_pkg.manifest = g_pkg.manifest_text ? cJSON_Parse(g_pkg.manifest_text) : NULL;
    const cJSON *ch, *f;
    cJSON_ArrayForEach(ch, cJSON_GetObjectItem(g_pkg.manifest, "chunks")) {
        int c = g_pkg.n_chunks++;
        if (c >= MAX_CHUNKS)
            return -1;
        cJSON_ArrayForEach(f, cJSON_GetObjectItem(ch, "files")) {
            int k = g_pkg.n_files[c]++;
            snprintf(path, sizeof path, "%s/%s/%s", lib, mat, cJSON_GetStringValue(f));
            if (k >= MAX_FILES || !(g_pkg.data[c][k] = slurp(path, &g_pkg.size[c][k])))
                return -1;
        }
    }
    return g_pkg.n_chunks > 0 ? 0 : -1;
}

static void connect_client(client *c);

static void send_text(client *c, const char *s)
{
    snprintf(c->out, sizeof c->out, "%s", s);
    if (c->wsi)
        lws_callback_on_writable(c->wsi);
}

/* subscribe (with etag and have when resuming) for held + 1 chunks. */
static void subscribe(client *c)
{
    char msg[8192];
    int n = g_raw ? snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"%s\",\"budget\":{}", g_mat)
                  : snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"%s\",\"budget\":{\"chunks\":%d}",
                             g_mat, c->held + 1);
    if (c->held) {
        n += snprintf(msg + n, sizeof msg - (size_t)n, ",\"etag\":\"%s\",\"have\":[", c->etag);
        for (int i = 0, k = 0; i < g_pkg.n_chunks; i++)
            if (c->have[i])
                n += snprintf(msg + n, sizeof msg - (size_t)n, "%s%d", k++ ? "," : "", i);
        n += snprintf(msg + n, sizeof msg - (size_t)n, "]");
    }
    snprintf(msg + n, sizeof msg - (size_t)n, "}");
    send_text(c, msg);
}

static void step_timer(lws_sorted_usec_list_t *sul)
{
    client *c = lws_container_of(sul, client, sul);
    if (!c->wsi)
        return;
    char msg[256];
    snprintf(msg, sizeof msg, "{\"type\":\"budget\",\"material\":\"%s\",\"budget\":{\"chunks\":%d}}", g_mat,
             c->held + 1);
    send_text(c, msg);
}

static void reconnect_timer(lws_sorted_usec_list_t *sul)
{
    connect_client(lws_container_of(sul, client, sul));
}

/* The connection ended early: drop the partial chunk, come back after backoff + jitter. */
static void lost(client *c)
{
    c->wsi = NULL;
    c->cur_chunk = -1;
    c->in_msg = 0;
    c->text_len = 0;
    if (c->done)
        return;
    if (g_raw) { /* no retry: this client failed */
        c->done = 1;
        g_lost++;
        return;
    }
    int base = 50 << (c->attempts < 5 ? c->attempts : 5);
    if (base > 1000)
        base = 1000;
    c->attempts++;
    c->reconnects++;
    int ms = base + (int)(rand_r(&g_seed) % (unsigned)(base + 1));
    lws_sul_schedule(g_ctx, 0, &c->sul, reconnect_timer, (lws_usec_t)ms * 1000);
}

/* Kills the server under test once KILL_AT of all chunks have arrived. */
static void maybe_kill(void)
{
    if (g_raw)
        return; /* by time, in run_clients */
    if (g_kill_pid > 0 && !g_killed && g_delivered >= g_kill_at * g_n * g_pkg.n_chunks) {
        kill(g_kill_pid, g_kill_sig);
        g_killed = g_delivered;
    }
}

static void on_manifest(client *c, const cJSON *j)
{
    int resumed = cJSON_IsTrue(cJSON_GetObjectItem(j, "resumed"));
    cJSON *disk = g_pkg.manifest;
    if (!cJSON_Compare(disk, cJSON_GetObjectItem(j, "manifest"), 1))
        g_bad_bytes++;
    if (c->held && !resumed)
        g_not_resumed++;
    c->resumes += c->held && resumed;
    snprintf(c->etag, sizeof c->etag, "%s", cJSON_GetStringValue(cJSON_GetObjectItem(j, "etag")));
    c->attempts = 0;
}

static int on_text(client *c)
{
    cJSON *j = cJSON_Parse(c->text);
    const char *type = cJSON_GetStringValue(cJSON_GetObjectItem(j, "type"));
    int r = 0;
    if (type && !strcmp(type, "manifest"))
        on_manifest(c, j);
    else if (type && !strcmp(type, "complete")) {
        if (c->held == g_pkg.n_chunks) {
            c->done = 1;
            r = -1; /* everything here: close */
        } else {
            lws_sul_schedule(g_ctx, 0, &c->sul, step_timer, (lws_usec_t)g_step_ms * 1000);
        }
    } else if (type && !strcmp(type, "error")) {
        fprintf(stderr, "resume_clients: client %d: %s\n", c->idx, c->text);
        g_bad_bytes++;
    }
    cJSON_Delete(j);
    return r;
}

/* A piece's header is complete: check where it goes. */
static void piece_header(client *c)
{
    uint32_t chunk = le32(c->hdr + 4);
    if (chunk >= (uint32_t)g_pkg.n_chunks || le32(c->hdr + 8) >= (uint32_t)g_pkg.n_files[chunk]) {
        g_bad_bytes++;
        return;
    }
    if (c->have[chunk] && c->cur_chunk != (int)chunk)
        g_dups++; /* a chunk this client already holds */
    c->cur_chunk = (int)chunk;
}

/* Payload bytes of the current piece: compared with the file on disk. */
static void piece_payload(client *c, const uint8_t *p, size_t n)
{
    uint32_t chunk = le32(c->hdr + 4), file = le32(c->hdr + 8), off = le32(c->hdr + 12);
    if (chunk >= (uint32_t)g_pkg.n_chunks || file >= (uint32_t)g_pkg.n_files[chunk])
        return;
    size_t at = off + c->pos;
    if (at + n > g_pkg.size[chunk][file] || memcmp(g_pkg.data[chunk][file] + at, p, n))
        g_bad_bytes++;
    c->pos += n;
}

/* The piece ended: the chunk is complete after its last file's last byte. */
static void piece_end(client *c)
{
    uint32_t chunk = le32(c->hdr + 4), file = le32(c->hdr + 8), off = le32(c->hdr + 12), total = le32(c->hdr + 16);
    if (chunk >= (uint32_t)g_pkg.n_chunks || total != g_pkg.size[chunk][file < MAX_FILES ? file : 0])
        return;
    if ((int)file != g_pkg.n_files[chunk] - 1 || off + c->pos != total)
        return;
    c->cur_chunk = -1;
    if (c->have[chunk]) {
        g_dups++; /* counted once more, not held twice */
        return;
    }
    c->have[chunk] = 1;
    c->held++;
    if (chunk == 0 && !c->t_first)
        c->t_first = btf_seconds();
    g_delivered++;
    maybe_kill();
}

static void on_binary(client *c, const uint8_t *in, size_t len, int first, int final)
{
    if (first)
        c->hdr_got = c->pos = 0;
    if (c->hdr_got < 20) {
        size_t h = 20 - c->hdr_got < len ? 20 - c->hdr_got : len;
        memcpy(c->hdr + c->hdr_got, in, h);
        c->hdr_got += h;
        in += h;
        len -= h;
        if (c->hdr_got == 20)
            piece_header(c);
    }
    if (c->hdr_got == 20 && len)
        piece_payload(c, in, len);
    if (final && c->hdr_got == 20)
        piece_end(c);
}

static int on_receive(client *c, struct lws *wsi, const void *in, size_t len)
{
    int first = !c->in_msg, final = lws_is_final_fragment(wsi);
    if (first)
        c->msg_binary = lws_frame_is_binary(wsi);
    c->in_msg = !final;
    if (c->msg_binary) {
        on_binary(c, in, len, first, final);
        return 0;
    }
    char *t = realloc(c->text, (first ? 0 : c->text_len) + len + 1);
    if (!t)
        return -1;
    c->text = t;
    if (first)
        c->text_len = 0;
    memcpy(t + c->text_len, in, len);
    c->text_len += len;
    t[c->text_len] = 0;
    return final ? on_text(c) : 0;
}

static int on_writeable(client *c, struct lws *wsi)
{
    if (!c->out[0])
        return 0;
    uint8_t buf[LWS_PRE + sizeof c->out];
    size_t n = strlen(c->out);
    memcpy(buf + LWS_PRE, c->out, n);
    c->out[0] = 0;
    return lws_write(wsi, buf + LWS_PRE, n, LWS_WRITE_TEXT) < (int)n ? -1 : 0;
}

static int callback(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    (void)user;
    client *c = lws_get_opaque_user_data(wsi);
    if (!c)
        return 0;
    switch (reason) {
    case LWS_CALLBACK_CLIENT_CONNECTION_ERROR:
        if (g_raw) /* a raw client fails here for good: say why (lws's reason, or the proxy's reply) */
            fprintf(stderr, "resume_clients: client %d: connection error: %.*s\n", c->idx, in ? (int)len : 4,
                    in ? (const char *)in : "none");
        lost(c);
        break;
    case LWS_CALLBACK_CLIENT_CLOSED:
        if (g_raw && !c->done)
            fprintf(stderr, "resume_clients: client %d: closed after %d of %d chunks\n", c->idx, c->held,
                    g_pkg.n_chunks);
        lost(c);
        break;
    case LWS_CALLBACK_CLIENT_ESTABLISHED:
        c->opened++;
        subscribe(c);
        break;
    case LWS_CALLBACK_CLIENT_RECEIVE:
        return on_receive(c, wsi, in, len);
    case LWS_CALLBACK_WS_PEER_INITIATED_CLOSE:
        if (len >= 2 && (((const uint8_t *)in)[0] << 8 | ((const uint8_t *)in)[1]) == 1001)
            g_goaway++;
        break;
    case LWS_CALLBACK_CLIENT_WRITEABLE:
        return on_writeable(c, wsi);
    default:
        break;
    }
    return 0;
}

static const struct lws_protocols protocols[] = {
    {"resume-client", callback, 0, 65536, 0, NULL, 0},
    {NULL, NULL, 0, 0, 0, NULL, 0},
};

static void connect_client(client *c)
{
    if (!btf_lws_connect(g_ctx, g_port, protocols[0].name, c, &c->wsi) && !c->wsi)
        lost(c);
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The summary lines; returns the number of clients that hold every chunk. */
static int report(double secs)
{
    int done = 0, moved = 0, resumed = 0, nt = 0;
    long long reconnects = 0;
    double *tt = calloc(g_n > 0 && g_n < 1000000 ? (size_t)g_n : 1, sizeof *tt);
    for (int i = 0; i < g_n; i++) {
        done += g_cl[i].held == g_pkg.n_chunks;
        moved += g_cl[i].reconnects > 0;
        resumed += g_cl[i].resumes > 0;
        reconnects += g_cl[i].reconnects;
        if (g_cl[i].t_first > 0 && tt)
            tt[nt++] = (g_cl[i].t_first - g_cl[i].t_start) * 1e3;
    }
    printf("clients %d\ncomplete_clients %d\nchunks_delivered %lld\nchunks_expected %lld\n", g_n, done, g_delivered,
           (long long)g_n * g_pkg.n_chunks);
    printf("duplicate_chunks %lld\nbad_bytes %lld\nnot_resumed %lld\n", g_dups, g_bad_bytes, g_not_resumed);
    printf("clients_reconnected %d\nclients_resumed %d\nreconnects %lld\ngoaway_1001 %lld\n", moved, resumed,
           reconnects, g_goaway);
    printf("killed_at_chunks %lld\nclients_lost %lld\nseconds %.2f\n", g_killed, g_lost, secs);
    for (int i = 0, shown = 0; i < g_n && shown < 5; i++)
        if (g_cl[i].held < g_pkg.n_chunks && ++shown)
            fprintf(stderr, "resume_clients: client %d holds %d of %d chunks, %s, %d reconnects\n", i, g_cl[i].held,
                    g_pkg.n_chunks, g_cl[i].wsi ? "connected" : "not connected", g_cl[i].reconnects);
    if (tt && nt) {
        qsort(tt, (size_t)nt, sizeof *tt, cmp_d);
        printf("ttfc_median_ms %.1f\n", tt[(nt - 1) / 2]);
    }
    free(tt);
    return done;
}

/* The command line into the globals; 0, or 2 on a usage error. */
static int parse_args(int argc, char **argv)
{
    if (argc != 5 && (argc < 7 || argc > 9)) {
        fprintf(stderr, "usage: resume_clients PORT MATERIAL LIBDIR CLIENTS\n"
                        "                      [KILL_PID KILL_AT [STEP_MS [KILL|TERM|RAW]]]\n");
        return 2;
    }
    g_port = atoi(argv[1]);
    g_mat = argv[2];
    g_n = atoi(argv[4]);
    if (argc >= 7) {
        g_kill_pid = atoi(argv[5]);
        g_kill_at = atof(argv[6]);
    }
    if (argc >= 8)
        g_step_ms = atoi(argv[7]);
    if (argc == 9)
        g_kill_sig = strcmp(argv[8], "TERM") && strcmp(argv[8], "RAW") ? SIGKILL : SIGTERM;
    g_raw = argc == 9 && !strcmp(argv[8], "RAW");
    if (g_n < 1 || g_n >= 1000000 || load_pkg(argv[3], g_mat)) {
        fprintf(stderr, "resume_clients: cannot read %s/%s or bad CLIENTS\n", argv[3], g_mat);
        return 2;
    }
    return 0;
}

/* Starts every client and services them until all hold every chunk or RUN_LIMIT_S. */
static double run_clients(void)
{
    double t0 = btf_seconds();
    for (int i = 0; i < g_n; i++) {
        g_cl[i].idx = i;
        g_cl[i].cur_chunk = -1;
        g_cl[i].t_start = btf_seconds();
        if (g_raw && g_step_ms > 0) /* spread: client i connects i / n of STEP_MS in */
            lws_sul_schedule(g_ctx, 0, &g_cl[i].sul, reconnect_timer,
                             (lws_usec_t)((double)g_step_ms * 1000.0 * i / g_n));
        else
            connect_client(&g_cl[i]);
    }
    int done = 0;
    while (done + g_lost < g_n && btf_seconds() - t0 < RUN_LIMIT_S) {
        lws_service(g_ctx, 0);
        if (g_raw && g_kill_pid > 0 && !g_killed && btf_seconds() - t0 >= g_kill_at) {
            kill(g_kill_pid, g_kill_sig);
            g_killed = g_delivered > 0 ? g_delivered : 1;
        }
        done = 0;
        for (int i = 0; i < g_n; i++)
            done += g_cl[i].held == g_pkg.n_chunks;
    }
    return btf_seconds() - t0;
}

int main(int argc, char **argv)
{
    if (parse_args(argc, argv))
        return 2;
    lws_set_log_level(LLL_ERR, NULL);
    struct lws_context_creation_info info;
    memset(&info, 0, sizeof info);
    info.port = CONTEXT_PORT_NO_LISTEN;
    info.protocols = protocols;
    info.options = LWS_SERVER_OPTION_DISABLE_IPV6;
    g_cl = calloc((size_t)g_n, sizeof *g_cl);
    if (!g_cl || !(g_ctx = lws_create_context(&info)))
        return 1;
    int complete = report(run_clients()), moved = 0;
    for (int i = 0; i < g_n; i++)
        moved += g_cl[i].resumes > 0;
    lws_context_destroy(g_ctx);
    int ok = complete == g_n && g_delivered == (long long)g_n * g_pkg.n_chunks && !g_dups && !g_bad_bytes &&
             !g_not_resumed && (g_kill_pid <= 0 || (g_killed && (g_raw || moved > 0)));
    for (int i = 0; i < g_n; i++)
        free(g_cl[i].text);
    free(g_cl);
    printf("result %s\n", ok ? "ok" : "FAILED");
    return ok ? 0 : 1;
}
