/* btfd_ops.c - signals, draining, library rescans, /metrics and the log of btfd; see btfd_ops.h. */
#define _GNU_SOURCE /* accept4 */
#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

#include "btfd.h"

#define DRAIN_GRACE_US 2000000 /* after the deadline: closes still unanswered end with the loop */

static volatile sig_atomic_t sig_term, sig_hup, sig_int;
static struct lws_context *volatile sig_ctx;

/* Only flags and a wake-up of the loop (a write to lws's event pipe). */
static void on_signal(int sig)
{
    if (sig == SIGHUP)
        sig_hup = 1;
    else if (sig == SIGTERM)
        sig_term = 1;
    else
        sig_int = 1;
    if (sig_ctx)
        lws_cancel_service(sig_ctx);
}

void btfd_ops_signals(struct lws_context *ctx)
{
    sig_ctx = ctx;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
}

void btfd_log(const btfd_server *srv, btfd_log_level lv, const char *fmt, ...)
{
    static const char *const names[] = {"ERROR", "WARN", "INFO", "DEBUG"};
    if (lv == BTFD_LOG_DEBUG && (!srv || srv->opt.verbose < 1))
        return;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    struct tm tm;
    gmtime_r(&ts.tv_sec, &tm);
    char stamp[40], msg[1024];
    strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &tm);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    fprintf(stderr, "%s.%03dZ %s btfd: %s\n", stamp, (int)(ts.tv_nsec / 1000000), names[lv], msg);
}

/* Log sink of btfd_library_scan for packages it skipped. */
static void scan_error(void *ud, const char *msg)
{
    btfd_server *srv = ud;
    srv->stats.scan_errors++;
    btfd_log(srv, srv->last_scan_us ? BTFD_LOG_DEBUG : BTFD_LOG_WARN, "skipped package: %s", msg);
}

void btfd_ops_rescan(btfd_server *srv, int force)
{
    lws_usec_t now = lws_now_usecs();
    if (!force && srv->last_scan_us && now - srv->last_scan_us < 200000)
        return;
    uint64_t gen = srv->lib->generation;
    btfd_library_scan(srv->lib, scan_error, srv);
    if (gen != srv->lib->generation && srv->last_scan_us)
        btfd_log(srv, BTFD_LOG_INFO, "library now has %d materials (generation %llu)", srv->lib->n,
                 (unsigned long long)srv->lib->generation);
    srv->last_scan_us = now;
}

/* Asks for a WRITEABLE callback on every stream connection. The stream protocol is
 * found by its name, so ops needs no part of btfd_protocol.c (which uses ops). */
static void wake_streams(btfd_server *srv)
{
    struct lws_vhost *vh = lws_get_vhost_by_name(srv->ctx, BTFD_VHOST);
    const struct lws_protocols *p = vh ? lws_vhost_name_to_protocol(vh, BTFD_SUBPROTOCOL) : NULL;
    if (p)
        lws_callback_on_writable_all_protocol_vhost(vh, p);
}

static void drain_timer(lws_sorted_usec_list_t *sul)
{
    btfd_server *srv = lws_container_of(sul, btfd_server, sul_drain);
    if (srv->drain_expired) { /* the grace after the deadline is over too */
        srv->stop = 1;
        lws_cancel_service(srv->ctx);
        return;
    }
    srv->drain_expired = 1;
    btfd_log(srv, BTFD_LOG_INFO, "drain deadline: closing %d connections with 1001",
             srv->stats.connections);
    wake_streams(srv);
    lws_sul_schedule(srv->ctx, 0, &srv->sul_drain, drain_timer, DRAIN_GRACE_US);
}

/* Takes every connection already waiting in a listener's queue and hands it to lws
 * as if lws had accepted it; returns how many. Shutting a listener down resets
 * what is in its queue, and a client (or proxy) sees that as a reset of an
 * established connection, which no proxy retries by default. */
static int adopt_pending(struct lws_vhost *vh, int fd)
{
    int n = 0, flags = fcntl(fd, F_GETFL);
    if (!vh || flags < 0 || fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0)
        return 0;
    for (int c; (c = accept4(fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC)) >= 0;) {
        if (lws_adopt_socket_vhost(vh, c))
            n++; /* on failure lws has closed it */
    }
    return n;
}

/* Stops accepting: every listening socket of the process (btfd has one, lws's)
 * is emptied (adopt_pending), then shut down, so the kernel refuses new
 * connections at once while the ones accepted stay. Found through /proc/self/fd
 * and SO_ACCEPTCONN: lws 4.1 has no call that closes a vhost's listener and keeps
 * the context (its lws_context_deprecate reads the listener after freeing it).
 * Returns the listeners shut; *adopted counts the connections taken from them. */
static int stop_listening(btfd_server *srv, int *adopted)
{
    struct lws_vhost *vh = lws_get_vhost_by_name(srv->ctx, BTFD_VHOST);
    DIR *d = opendir("/proc/self/fd");
    int n = 0;
    *adopted = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        int fd = atoi(e->d_name), on = 0;
        socklen_t len = sizeof on;
        if (e->d_name[0] == '.' || getsockopt(fd, SOL_SOCKET, SO_ACCEPTCONN, &on, &len) != 0 || !on)
            continue;
        *adopted += adopt_pending(vh, fd);
        n += shutdown(fd, SHUT_RDWR) == 0;
    }
    if (d)
        closedir(d);
    return n;
}

void btfd_ops_drain(btfd_server *srv)
{
    if (srv->draining)
        return;
    srv->draining = 1;
    /* the listening socket closes: a new connection is refused, the failure every
     * proxy retries on another server by default; what is already accepted is served */
    int adopted, closed = stop_listening(srv, &adopted);
    btfd_log(srv, BTFD_LOG_INFO, "draining: %s; %d connections (%d taken from the queue), up to %d s",
             closed ? "stopped listening" : "could not stop listening", srv->stats.connections, adopted,
             srv->opt.drain_s);
    lws_sul_schedule(srv->ctx, 0, &srv->sul_drain, drain_timer, (lws_usec_t)srv->opt.drain_s * 1000000);
    wake_streams(srv); /* idle ones go now */
}

int btfd_ops_going_away(const btfd_server *srv, int idle)
{
    return srv->draining && (idle || srv->drain_expired);
}

int btfd_ops_tick(btfd_server *srv)
{
    if (sig_hup) {
        sig_hup = 0;
        btfd_log(srv, BTFD_LOG_INFO, "SIGHUP: rescanning %s", srv->opt.library_dir);
        btfd_ops_rescan(srv, 1);
    }
    if (sig_term) {
        sig_term = 0;
        if (srv->draining)
            srv->stop = 1; /* a second SIGTERM: stop now */
        btfd_ops_drain(srv);
    }
    if (sig_int)
        srv->stop = 1;
    if (srv->draining && srv->stats.connections == 0 && srv->stats.sockets == 0)
        srv->stop = 1; /* nothing accepted is left: every request answered, every stream ended */
    return !srv->stop;
}

/* One sample of /metrics; a table local to btfd_ops_metrics, lives for the call. */
typedef struct metric_row {
    const char *name, *type, *help;
    double v;
} metric_row;

/* Appends the rows as "# HELP", "# TYPE" and sample lines; NULL if out of memory. */
static char *format_rows(const metric_row *rows, size_t n)
{
    size_t cap = 256 * n + 1, at = 0;
    char *b = malloc(cap);
    for (size_t i = 0; b && i < n; i++) {
        const metric_row *r = &rows[i];
        const char *fmt = r->v == (double)(long long)r->v ? "# HELP %s %s\n# TYPE %s %s\n%s %.0f\n"
                                                         : "# HELP %s %s\n# TYPE %s %s\n%s %.3f\n";
        int k = snprintf(b + at, cap - at, fmt, r->name, r->help, r->name, r->type, r->name, r->v);
        if (k > 0 && (size_t)k < cap - at)
            at += (size_t)k;
    }
    return b;
}

char *btfd_ops_metrics(const btfd_server *srv)
{
    const btfd_stats *s = &srv->stats;
    uint64_t lib_bytes = 0;
    for (int i = 0; i < srv->lib->n; i++)
        lib_bytes += srv->lib->items[i]->total_bytes;
    const metric_row rows[] = {
        {"btfd_up_seconds", "gauge", "Seconds since the server started.",
         (double)(lws_now_usecs() - s->started_us) * 1e-6},
        {"btfd_draining", "gauge", "1 while the server drains (SIGTERM), else 0.", srv->draining},
        {"btfd_connections", "gauge", "Stream connections open now.", s->connections},
        {"btfd_connections_total", "counter", "Stream connections accepted.", (double)s->connections_total},
        {"btfd_subscriptions", "gauge", "Subscriptions open now.", s->subscriptions},
        {"btfd_subscriptions_total", "counter", "Subscriptions accepted.", (double)s->subscriptions_total},
        {"btfd_sent_bytes_total", "counter", "Payload bytes of binary pieces sent.", (double)s->bytes_sent},
        {"btfd_sent_chunks_total", "counter", "Whole chunks sent.", (double)s->chunks_sent},
        {"btfd_stalled_drops_total", "counter", "Connections dropped by --stall-timeout.", (double)s->stalls},
        {"btfd_library_materials", "gauge", "Packages in the library index.", srv->lib->n},
        {"btfd_library_bytes", "gauge", "Sum of the indexed packages' file sizes.", (double)lib_bytes},
        {"btfd_library_generation", "gauge", "Changes of the set of packages.", (double)srv->lib->generation},
        {"btfd_scan_errors_total", "counter", "Packages skipped by library scans.", (double)s->scan_errors},
        {"btfd_http_requests_total", "counter", "Requests on /materials, /healthz, /metrics.",
         (double)s->http_requests},
        {"btfd_http_not_modified_total", "counter", "Of those, answered 304 Not Modified.",
         (double)s->http_not_modified},
        {"btfd_forbidden_total", "counter", "Subscriptions and package file requests refused for their token.",
         (double)s->forbidden},
    };
    return format_rows(rows, sizeof rows / sizeof rows[0]);
}
