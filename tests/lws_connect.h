/* lws_connect.h - the one client connect of the load programs
 * (bench/load/server_load.c, tests/deploy/resume_clients.c): header only.
 *
 *     btf_lws_connect(ctx, port, "bench-client", client, &client->wsi);
 *
 * Opens ws://127.0.0.1:PORT/stream with subprotocol btf-stream.v1 on a client
 * context; user becomes the connection's opaque user data. Returns what
 * lws_client_connect_via_info returns (NULL: failed at once).
 */
#ifndef BTF_LWS_CONNECT_H
#define BTF_LWS_CONNECT_H

#include <libwebsockets.h>
#include <string.h>

static inline struct lws *btf_lws_connect(struct lws_context *ctx, int port, const char *local_protocol, void *user,
                                          struct lws **pwsi)
{
    struct lws_client_connect_info ci;
    memset(&ci, 0, sizeof ci);
    ci.context = ctx;
    ci.address = "127.0.0.1";
    ci.port = port;
    ci.path = "/stream";
    ci.host = "127.0.0.1";
    ci.origin = "127.0.0.1";
    ci.protocol = "btf-stream.v1";
    ci.local_protocol_name = local_protocol;
    ci.opaque_user_data = user;
    ci.pwsi = pwsi;
    return lws_client_connect_via_info(&ci);
}

#endif
