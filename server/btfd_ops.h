/* btfd_ops.h - operating btfd: signals, draining, library rescans, /healthz, /metrics and the log.
 *
 *     btfd_ops_signals(ctx);                 // SIGTERM drains, SIGHUP rescans, SIGINT stops
 *     while (btfd_ops_tick(srv) && lws_service(ctx, 0) >= 0)
 *         ;
 *     btfd_log(srv, BTFD_LOG_INFO, "conn %d: closed", id);
 *
 * The signal handlers only set flags and wake the event loop with
 * lws_cancel_service; btfd_ops_tick, on the service thread, does the work.
 * Draining: the listening socket closes (a new connection is refused, which
 * every proxy retries elsewhere by default); every connection already accepted
 * is served, a handshake or a subscribe that arrives on one during the drain
 * included (/healthz on one answers 503); a stream whose subscriptions are all
 * sent is closed with 1001 (going away), and after --drain-seconds so is every
 * other one; the loop ends when no connection is left (or 2 s after the deadline).
 */
#ifndef BTFD_OPS_H
#define BTFD_OPS_H

#include <libwebsockets.h>
#include <stdint.h>

struct btfd_server;

/* Severity of a log line; -v shows DEBUG, the default stops at INFO. */
typedef enum btfd_log_level { BTFD_LOG_ERROR, BTFD_LOG_WARN, BTFD_LOG_INFO, BTFD_LOG_DEBUG } btfd_log_level;

/* Counters behind /metrics; a value inside btfd_server (lives as long as it),
 * written only on the service thread. */
typedef struct btfd_stats {
    lws_usec_t started_us;
    uint64_t connections_total;   /* stream connections accepted */
    int connections;              /* stream connections open now */
    int sockets;                  /* accepted connections open now, HTTP ones and streams */
    uint64_t subscriptions_total; /* subscriptions accepted */
    int subscriptions;            /* subscriptions open now */
    uint64_t bytes_sent;          /* payload bytes of binary pieces */
    uint64_t chunks_sent;         /* whole chunks sent */
    uint64_t stalls;              /* connections dropped by --stall-timeout */
    uint64_t scan_errors;         /* packages skipped by library scans */
    uint64_t http_requests;       /* HTTP requests on the callback routes */
    uint64_t http_not_modified;   /* of those, answered 304 */
    uint64_t forbidden;           /* subscriptions and file requests refused for their token */
} btfd_stats;

/* One log line on stderr: "2026-01-31T12:00:00.123Z LEVEL btfd: message". */
void btfd_log(const struct btfd_server *srv, btfd_log_level lv, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Installs the SIGTERM, SIGHUP and SIGINT handlers (sigaction) for ctx. */
void btfd_ops_signals(struct lws_context *ctx);

/* Acts on signals that arrived; 0 once the loop should end. */
int btfd_ops_tick(struct btfd_server *srv);

/* Starts draining (what SIGTERM does). */
void btfd_ops_drain(struct btfd_server *srv);

/* 1 when a stream connection should be closed with 1001 now: draining and
 * either done (it subscribed and has nothing left to send) or past the drain
 * deadline. A stream that has not subscribed yet is waited for. */
int btfd_ops_going_away(const struct btfd_server *srv, int idle);

/* Body of /metrics (Prometheus text format 0.0.4), malloc'd; NULL if out of memory. */
char *btfd_ops_metrics(const struct btfd_server *srv);

/* Rescans the library unless one ran in the last 200 ms (force: always); a
 * package the scan skipped is counted and logged (WARN on the first scan). */
void btfd_ops_rescan(struct btfd_server *srv, int force);

#endif
