/* btfd_main.c - command line and event loop of the btfd streaming server.
 *
 *     btfd --library DIR [--port N] [--bind ADDR] [--client DIR] [--shaders DIR]
 *     btfd --library DIR --publish OUT [--client DIR]     (the library as static files, then exit)
 *
 * Serves the client page (HTTP file mount on /, shaders on /shaders/; an
 * installed btfd defaults to the installed copies, see default_dirs), the
 * library list (GET /materials) and the btf-stream.v1 WebSocket. The protocol
 * logic lives in btfd_protocol.c; see server/README.md and doc/protocol.md.
 */
#include <getopt.h>
#include <time.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "btf_version.h"
#include "btfd.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: btfd --library DIR [options]\n"
            "  --library DIR        directory of packages (read-only)\n"
            "  --port N             TCP port (default 8080; 0 picks a free one)\n"
            "  --bind ADDR          interface address (default 127.0.0.1)\n"
            "  --client DIR         client files served at / (default: PREFIX/share/btf-stream/client\n"
            "                       for an installed PREFIX/bin/btfd, else client)\n"
            "  --shaders DIR        shader files served at /shaders/ (default: the installed\n"
            "                       PREFIX/share/btf-stream/shaders, else shaders)\n"
            "  --fragment BYTES     payload bytes per binary piece (4096..1048576, default 131072)\n"
            "  --stall-timeout S    drop a client that takes no data for S seconds (default 20)\n"
            "  --rescan-ms MS       rescan the library every MS ms (default 2000, 0 = only on request)\n"
            "  --drain-seconds S    on SIGTERM let streams finish for S seconds, then close them\n"
            "                       with 1001 going-away (default 10)\n"
            "  --allow-origin LIST  origins (comma-separated, e.g. https://a.example) allowed to embed:\n"
            "                       CORS on the client, shaders and /materials, and the WebSocket\n"
            "                       handshake's Origin check (default *: any origin)\n"
            "  --no-csp             do not add the security headers (CSP) to HTTP replies\n"
            "  --publish OUT        serve nothing: write what the HTTP routes answer into the folder OUT\n"
            "                       for a static host (OUT/materials.json, OUT/materials/NAME/..., the\n"
            "                       --client folder's scripts), then exit (`btf library publish`)\n"
            "  -v, --verbose        debug log lines (subscriptions, skipped packages on rescans);\n"
            "                       -vv also libwebsockets' warnings and notices\n"
            "  --token-secret-file F  a private library: package files and streams need a token\n"
            "                       signed with the secret in F (16..256 bytes; doc/deploy.md)\n"
            "  --make-token SCOPE   print a token for SCOPE (a material, or a name prefix and *)\n"
            "                       signed with --token-secret-file, valid --ttl S seconds\n"
            "                       (default 3600), and for a material the nginx secure_link\n"
            "                       arguments of its files; then exit\n"
            "  --version            print \"btfd VERSION\" and exit\n"
            "Signals: SIGTERM drains (see --drain-seconds), SIGHUP rescans the library, SIGINT stops.\n"
            "Routes: / (client), /shaders/, /materials (also /materials.json), /materials/NAME/ETAG/FILE,\n"
            "/healthz, /metrics, "
            "and the btf-stream.v1 WebSocket (doc/protocol.md).\n"
            "Exit status: 0 ok, 1 failure, 2 usage error.\n");
}

/* Integer option value in [lo, hi]; exits 2 when it is not one. */
static long int_arg(const char *opt, const char *s, long lo, long hi)
{
    char *end;
    long v = strtol(s, &end, 10);
    if (*s == 0 || *end || v < lo || v > hi) {
        fprintf(stderr, "btfd: %s wants an integer in %ld..%ld, got \"%s\"\n", opt, lo, hi, s);
        exit(2);
    }
    return v;
}

static void parse_args(int argc, char **argv, btfd_options *o, int *csp, const char **publish)
{
    static const struct option longs[] = {
        {"library", 1, 0, 'l'},  {"port", 1, 0, 'p'},      {"bind", 1, 0, 'b'},
        {"client", 1, 0, 'c'},   {"shaders", 1, 0, 's'},   {"fragment", 1, 0, 'f'},
        {"stall-timeout", 1, 0, 't'}, {"rescan-ms", 1, 0, 'r'}, {"no-csp", 0, 0, 'n'},
        {"drain-seconds", 1, 0, 'd'}, {"allow-origin", 1, 0, 'a'}, {"verbose", 0, 0, 'v'},
        {"help", 0, 0, 'h'},          {"version", 0, 0, 'V'},         {"publish", 1, 0, 'P'},  {"token-secret-file", 1, 0, 'k'},
        {"make-token", 1, 0, 'm'},    {"ttl", 1, 0, 'T'},
        {0, 0, 0, 0},
    };
    int ch;
    while ((ch = getopt_long(argc, argv, "vh", longs, NULL)) != -1) {
        switch (ch) {
        case 'l': o->library_dir = optarg; break;
        case 'p': o->port = (int)int_arg("--port", optarg, 0, 65535); break;
        case 'b': o->bind = optarg; break;
        case 'c': o->client_dir = optarg; break;
        case 's': o->shaders_dir = optarg; break;
        case 'f': o->fragment = (size_t)int_arg("--fragment", optarg, 4096, 1 << 20); break;
        case 't': o->stall_timeout_s = (int)int_arg("--stall-timeout", optarg, 1, 3600); break;
        case 'r': o->rescan_ms = (int)int_arg("--rescan-ms", optarg, 0, 3600000); break;
        case 'n': *csp = 0; break;
        case 'd': o->drain_s = (int)int_arg("--drain-seconds", optarg, 0, 3600); break;
        case 'a': o->allow_origin = optarg; break;
        case 'k': o->token_secret_file = optarg; break;
        case 'm': o->make_token = optarg; break;
        case 'T': o->ttl_s = (int)int_arg("--ttl", optarg, 1, 400 * 86400); break;
        case 'v': o->verbose++; break;
        case 'P': *publish = optarg; break;
        case 'h': usage(stdout); exit(0);
        case 'V': printf("btfd %s\n", BTF_VERSION); exit(0);
        default: usage(stderr); exit(2);
        }
    }
    if (o->make_token && !o->token_secret_file) {
        fprintf(stderr, "btfd: --make-token needs --token-secret-file\n");
        exit(2);
    }
    if (optind < argc || (!o->library_dir && !o->make_token)) {
        fprintf(stderr, optind < argc ? "btfd: unexpected argument \"%s\"\n" : "btfd: --library is required%s\n",
                optind < argc ? argv[optind] : "");
        usage(stderr);
        exit(2);
    }
}

/* Defaults of --client and --shaders: PREFIX/share/btf-stream/{client,shaders}
 * when this executable is PREFIX/bin/btfd (readlink /proc/self/exe) and that
 * client folder exists, i.e. btfd was installed by `make install`; otherwise
 * client/ and shaders/ of the source tree, relative to the current directory. */
static void default_dirs(btfd_options *o)
{
    static char client[PATH_MAX], shaders[PATH_MAX];
    char exe[PATH_MAX];
    struct stat st;
    o->client_dir = "client";
    o->shaders_dir = "shaders";
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return;
    exe[n] = 0;
    char *name = strrchr(exe, '/');
    if (!name || name - exe < 4 || strcmp(name, "/btfd") != 0 || strncmp(name - 4, "/bin", 4) != 0)
        return;
    name[-4] = 0; /* exe is now PREFIX */
    if (snprintf(client, sizeof client, "%s/share/btf-stream/client", exe) >= (int)sizeof client ||
        snprintf(shaders, sizeof shaders, "%s/share/btf-stream/shaders", exe) >= (int)sizeof shaders ||
        stat(client, &st) != 0 || !S_ISDIR(st.st_mode))
        return;
    o->client_dir = client;
    o->shaders_dir = shaders;
}

/* More file descriptors for thousands of connections (soft limit up to the hard one). */
static void raise_fd_limit(void)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < rl.rlim_max) {
        rl.rlim_cur = rl.rlim_max > 65536 ? 65536 : rl.rlim_max;
        setrlimit(RLIMIT_NOFILE, &rl);
    }
}

static void rescan_timer(lws_sorted_usec_list_t *sul)
{
    btfd_server *srv = lws_container_of(sul, btfd_server, sul_rescan);
    btfd_ops_rescan(srv, 1);
    lws_sul_schedule(srv->ctx, 0, &srv->sul_rescan, rescan_timer, (lws_usec_t)srv->opt.rescan_ms * 1000);
}

static const struct lws_protocol_vhost_options mime_extra[] = {
    {&mime_extra[1], NULL, ".glsl", "text/plain"},
    {&mime_extra[2], NULL, ".vert", "text/plain"},
    {&mime_extra[3], NULL, ".frag", "text/plain"},
    {&mime_extra[4], NULL, ".mjs", "text/javascript"},
    {&mime_extra[5], NULL, ".json", "application/json"},
    {&mime_extra[6], NULL, ".svg", "image/svg+xml"},
    {&mime_extra[7], NULL, ".webp", "image/webp"},
    {&mime_extra[8], NULL, ".avif", "image/avif"},
    {&mime_extra[9], NULL, ".glb", "model/gltf-binary"},
    {&mime_extra[10], NULL, ".gltf", "model/gltf+json"},
    {&mime_extra[11], NULL, ".bin", "application/octet-stream"}, /* a .gltf's buffers */
    {NULL, NULL, ".wasm", "application/wasm"},
};

#define N_MOUNTS 6

/* A callback mount of the "http" protocol (btfd_http.c routes by the full URI). */
static void callback_mount(struct lws_http_mount *m, const char *point)
{
    m->mountpoint = point;
    m->mountpoint_len = (unsigned char)strlen(point);
    m->protocol = "http";
    m->origin_protocol = LWSMPRO_CALLBACK;
}

/* A file mount whose files are revalidated by ETag (lws: If-None-Match -> 304). */
static void file_mount(struct lws_http_mount *m, const char *point, const char *dir)
{
    m->mountpoint = point;
    m->mountpoint_len = (unsigned char)strlen(point);
    m->origin = dir;
    m->origin_protocol = LWSMPRO_FILE;
    m->protocol = "http"; /* LWS_CALLBACK_ADD_HEADERS: CORS (btfd_http.c, btfd_origin.c) */
    m->extra_mimetypes = mime_extra;
    m->cache_max_age = 1;
    m->cache_reusable = 1;
    m->cache_revalidate = 1;
}

/* Mounts: /materials, /healthz, /metrics, /materials.json (callbacks), /shaders/ and / (files). */
static void make_mounts(const btfd_options *o, struct lws_http_mount m[N_MOUNTS])
{
    memset(m, 0, N_MOUNTS * sizeof *m);
    callback_mount(&m[0], "/materials");
    callback_mount(&m[1], "/healthz");
    callback_mount(&m[2], "/metrics");
    callback_mount(&m[3], "/materials.json");
    file_mount(&m[4], "/shaders", o->shaders_dir);
    file_mount(&m[5], "/", o->client_dir);
    m[5].def = "index.html";
    for (int i = 0; i + 1 < N_MOUNTS; i++)
        m[i].mount_next = &m[i + 1];
}

static struct lws_context *make_context(btfd_server *srv, const struct lws_http_mount *mounts, int csp)
{
    struct lws_context_creation_info info;
    memset(&info, 0, sizeof info);
    info.port = srv->opt.port;
    info.iface = srv->opt.bind;
    info.protocols = btfd_protocols;
    info.mounts = mounts;
    info.user = srv;
    info.options = LWS_SERVER_OPTION_VALIDATE_UTF8 | LWS_SERVER_OPTION_DISABLE_IPV6;
    if (csp)
        info.options |= LWS_SERVER_OPTION_HTTP_HEADERS_SECURITY_BEST_PRACTICES_ENFORCE;
    info.timeout_secs = 30;
    return lws_create_context(&info);
}

/* The defaults of every option (usage() lists them). */
static void default_options(btfd_options *o)
{
    o->port = 8080;
    o->bind = "127.0.0.1";
    default_dirs(o);
    o->fragment = 131072;
    o->stall_timeout_s = 20;
    o->rescan_ms = 2000;
    o->drain_s = 10;
}

/* --make-token: the token, and for one material the nginx form; the exit code. */
static int print_token(const btfd_token_key *k, const char *scope, int ttl)
{
    char t[BTFD_TOKEN_MAX], md5[32];
    int64_t expires = (int64_t)time(NULL) + ttl;
    if (btfd_token_make(k, scope, expires, t, sizeof t) != 0) {
        fprintf(stderr, "btfd: \"%s\" is no scope (a material name, or a name prefix and *)\n", scope);
        return 2;
    }
    printf("%s\n", t);
    if (btfd_token_make_md5(k, scope, expires, md5, sizeof md5) == 0)
        printf("md5=%s&expires=%lld\n", md5, (long long)expires);
    return 0;
}

/* Log sink of the publishing scan: a skipped package is named on stderr. */
static void publish_skipped(void *ud, const char *msg)
{
    (void)ud;
    fprintf(stderr, "btfd: skipped package: %s\n", msg);
}

/* --publish OUT: one scan of the library, its files into OUT (btfd_publish.c), exit status. */
static int publish_main(const btfd_options *o, const char *out)
{
    btf_error err = {0};
    btfd_library *lib = NULL;
    if (btfd_library_open(o->library_dir, &lib, &err) != BTF_OK) {
        fprintf(stderr, "btfd: %s\n", err.msg);
        return 1;
    }
    int rc = btfd_library_scan(lib, publish_skipped, NULL) == BTF_OK ? btfd_publish(o, lib, out) : 1;
    btfd_library_free(lib);
    return rc;
}

int main(int argc, char **argv)
{
    btfd_server srv;
    memset(&srv, 0, sizeof srv);
    btfd_options *o = &srv.opt;
    default_options(o);
    int csp = 1;
    const char *publish = NULL;
    parse_args(argc, argv, o, &csp, &publish);
    if (publish)
        return publish_main(o, publish);
    lws_set_log_level(o->verbose >= 2 ? LLL_ERR | LLL_WARN | LLL_NOTICE : LLL_ERR, NULL);
    srv.stats.started_us = lws_now_usecs();
    raise_fd_limit();

    btf_error err = {0};
    if (o->token_secret_file && btfd_token_load(o->token_secret_file, &srv.key, &err) != BTF_OK) {
        fprintf(stderr, "btfd: %s\n", err.msg);
        return 1;
    }
    if (o->make_token)
        return print_token(&srv.key, o->make_token, o->ttl_s > 0 ? o->ttl_s : 3600);
    if (btfd_library_open(o->library_dir, &srv.lib, &err) != BTF_OK) {
        fprintf(stderr, "btfd: %s\n", err.msg);
        return 1;
    }
    btfd_ops_rescan(&srv, 1);
    srv.scratch_len = LWS_PRE + BTFD_HEADER_BYTES + o->fragment;
    srv.scratch = malloc(srv.scratch_len);
    btfd_protocols[0].per_session_data_size = btfd_http_user_size;
    btfd_protocols[1].tx_packet_size = BTFD_HEADER_BYTES + o->fragment + 16;
    struct lws_http_mount mounts[N_MOUNTS];
    make_mounts(o, mounts);
    if (srv.scratch)
        srv.ctx = make_context(&srv, mounts, csp);
    if (!srv.ctx) {
        fprintf(stderr, "btfd: cannot listen on %s:%d\n", o->bind, o->port);
        free(srv.scratch);
        btfd_library_free(srv.lib);
        return 1;
    }
    btfd_gzip_install(srv.ctx);
    btfd_ops_signals(srv.ctx);
    int port = lws_get_vhost_listen_port(lws_get_vhost_by_name(srv.ctx, BTFD_VHOST));
    printf("btfd: listening on http://%s:%d/ (%d materials from %s)\n", o->bind, port, srv.lib->n,
           o->library_dir);
    fflush(stdout);
    if (o->rescan_ms > 0)
        lws_sul_schedule(srv.ctx, 0, &srv.sul_rescan, rescan_timer, (lws_usec_t)o->rescan_ms * 1000);

    while (btfd_ops_tick(&srv) && lws_service(srv.ctx, 0) >= 0)
        ;

    lws_context_destroy(srv.ctx);
    btfd_log(&srv, BTFD_LOG_INFO, "stopped after %llu connections, %llu payload bytes sent",
             (unsigned long long)srv.stats.connections_total, (unsigned long long)srv.stats.bytes_sent);
    btfd_library_free(srv.lib);
    free(srv.scratch);
    return 0;
}
