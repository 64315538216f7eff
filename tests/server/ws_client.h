/* ws_client.h - room server (tests): a blocking WebSocket client for the server tests, built on
 * libwebsockets' client API (lws_client_connect_via_info + a client protocol
 * callback). Implementation in ws_client.c.
 *
 * Each connection owns its own lws_context, so a test can stop servicing one
 * connection (a client that stops reading: nothing is read from its socket
 * while the test does not call wsc_* on it) while others keep going. All
 * framing, masking and the handshake (Sec-WebSocket-Key/Accept) are done by
 * libwebsockets. What a polite client never sends (binary frames, invalid
 * UTF-8, oversized or fragmented messages, floods) goes through lws_write with
 * the matching LWS_WRITE_* flags; libwebsockets does not validate outgoing
 * frames, so no hand-written framing is needed.
 * Every wait has a deadline, so a broken server fails a test instead of hanging it.
 */
#ifndef BTF_WS_CLIENT_H
#define BTF_WS_CLIENT_H

#include <stddef.h>
#include <stdint.h>

/* One received message; data malloc'd and NUL-terminated (free with
 * wsc_msg_free). op: 1 text, 2 binary, 8 close (close_code, reason in data),
 * -1 connection ended without (further) messages. */
typedef struct wsc_msg {
    int op;
    uint8_t *data;
    size_t len;
    int close_code;
} wsc_msg;

struct wsc_conn;

/* One client connection (a handle to its lws context and state); owned by the
 * test, opened with wsc_open, released with wsc_close. */
typedef struct wsc {
    struct wsc_conn *p;
} wsc;

/* Opens ws://127.0.0.1:port/stream asking for the given subprotocol (NULL:
 * none). rcvbuf > 0 shrinks the socket's receive buffer once connected.
 * 0 on success; otherwise -1 and lws's reason (e.g. the handshake failure)
 * in status. c must be wsc_close'd either way. */
int wsc_open(wsc *c, int port, const char *protocol, int rcvbuf, char *status, size_t n);

/* Closes the connection and frees everything (c->p may be NULL). */
void wsc_close(wsc *c);

/* Sends one WebSocket frame through lws_write: op 1 text, 2 binary, 0
 * continuation; fin 0 leaves the message open (LWS_WRITE_NO_FIN). Returns 0
 * once libwebsockets has handed every byte to the kernel, -1 if the
 * connection ended or the deadline passed. */
int wsc_send_frame(wsc *c, int op, int fin, const void *data, size_t len);

/* One whole text message. */
int wsc_send_text(wsc *c, const char *s);

/* Several text messages written back to back with the socket corked
 * (TCP_CORK), so the server receives them in one read. */
int wsc_send_batch(wsc *c, const char *const *msgs, int n);

/* Next complete message within timeout_ms (fragments joined by lws; pings
 * answered by lws): 1 got one, 0 timeout, -1 connection ended (m->op = -1). */
int wsc_recv(wsc *c, wsc_msg *m, int timeout_ms);

void wsc_msg_free(wsc_msg *m);

#endif
