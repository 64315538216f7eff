/* test_server.c - room server, suite "server": the btfd streaming server, as a real process on a loopback port.
 *
 * Each test writes a small fake library (manifests + files of pseudo-random
 * bytes) into a temp dir, starts $BTF_BUILD/btfd on a free port (--port 0; the
 * port is read from its first stdout line; the binary is looked up next to
 * the test binary, then in $BTF_BUILD, then in build/) and talks to it with the
 * libwebsockets client of ws_client.h (one lws context per connection, so a
 * test can stop reading one of them). Received bytes are compared
 * with the package files on disk; orders and limits are recomputed here from
 * the manifests, following doc/protocol.md. The server must exit 0 on SIGTERM
 * (under `make asan` that includes "no leaks").
 * When BTF_BUILD is unset and build/btfd does not exist the suite is skipped;
 * when BTF_BUILD is set (by the Makefile) a missing binary is a failure.
 */
#include <criterion/criterion.h>
#include <cjson/cJSON.h>
#include <arpa/inet.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include "btf_version.h"
#include "fixtures.h"
#include "ws_client.h"

#define TMO 5000 /* ms: every wait in these tests; loopback transfers here take well under 1 s */

/* ---------------------------------------------------------------- files */

/* Pseudo-random bytes (xorshift32), so a shifted or swapped piece cannot match. */
static void fill_random(uint8_t *b, size_t n, uint32_t seed)
{
    uint32_t x = seed * 2654435761u + 1;
    for (size_t i = 0; i < n; i++)
        b[i] = (uint8_t)fx_xorshift32(&x);
}

/* Writes root as dir/manifest.json and frees it. */
static void write_manifest(const char *dir, cJSON *root)
{
    char path[700];
    char *txt = cJSON_Print(root);
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    fx_write(path, txt, strlen(txt));
    free(txt);
    cJSON_Delete(root);
}

/* Writes package lib/name (through a .tmp-<pid> directory and a rename) with
 * n_chunks chunks of fpc files each; sizes[c * fpc + f] bytes per file; lab[c]
 * (rmse = 1.5 lab). Returns the total bytes. */
static size_t make_pkg(const char *lib, const char *name, int n_chunks, int fpc, const size_t *sizes,
                       const double *lab)
{
    char tmp[512], dst[512], path[700];
    snprintf(tmp, sizeof tmp, "%s/%s.tmp-%d", lib, name, (int)getpid());
    snprintf(dst, sizeof dst, "%s/%s", lib, name);
    cr_assert_eq(mkdir(tmp, 0755), 0, "mkdir %s", tmp);
    cJSON *root = cJSON_CreateObject(), *chunks = cJSON_CreateArray();
    cJSON_AddStringToObject(root, "format", "btf-package");
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddStringToObject(root, "name", name);
    cJSON_AddNumberToObject(root, "width", 16);
    cJSON_AddNumberToObject(root, "height", 16);
    size_t total = 0;
    for (int c = 0; c < n_chunks; c++) {
        cJSON *jc = cJSON_CreateObject(), *files = cJSON_CreateArray();
        size_t bytes = 0;
        for (int f = 0; f < fpc; f++) {
            char fname[64];
            snprintf(fname, sizeof fname, "c%d_f%d.bin", c, f);
            size_t n = sizes[c * fpc + f];
            uint8_t *b = malloc(n + 1);
            fill_random(b, n, (uint32_t)(c * 131 + f * 7 + strlen(name) * 1009 + (uint8_t)name[0]));
            snprintf(path, sizeof path, "%s/%s", tmp, fname);
            fx_write(path, b, n);
            free(b);
            cJSON_AddItemToArray(files, cJSON_CreateString(fname));
            bytes += n;
        }
        char id[16];
        snprintf(id, sizeof id, "k%d", c);
        cJSON_AddStringToObject(jc, "id", id);
        cJSON_AddItemToObject(jc, "files", files);
        cJSON_AddNumberToObject(jc, "bytes", (double)bytes);
        cJSON_AddNumberToObject(jc, "rmse", lab[c] * 1.5);
        cJSON_AddNumberToObject(jc, "lab", lab[c]);
        cJSON_AddItemToArray(chunks, jc);
        total += bytes;
    }
    cJSON_AddItemToObject(root, "chunks", chunks);
    write_manifest(tmp, root);
    cr_assert_eq(rename(tmp, dst), 0, "rename %s", tmp);
    return total;
}

/* Package with n_chunks chunks of one file of `bytes` bytes each, lab 100/(c+1). */
static size_t make_simple(const char *lib, const char *name, int n_chunks, size_t bytes)
{
    size_t sizes[64];
    double lab[64];
    for (int c = 0; c < n_chunks; c++) {
        sizes[c] = bytes + (size_t)c * 13;
        lab[c] = 100.0 / (c + 1);
    }
    return make_pkg(lib, name, n_chunks, 1, sizes, lab);
}

/* ---------------------------------------------------------------- the server process */

/* A running btfd; owned by the test, stopped with srv_stop. */
typedef struct srv {
    pid_t pid;
    int port;
} srv;

static pid_t g_pid; /* the server of the running test, killed by the suite's fini if a test fails */
static const char *g_stderr; /* when set, the next srv_start sends btfd's stderr to this file */

/* Path of a program built next to this test binary (make asan runs
 * build-asan/run_tests), else in $BTF_BUILD, else in build/. */
static void btfd_binary(char *buf, size_t n, const char *prog)
{
    char exe[400];
    ssize_t k = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (k > 0) {
        exe[k] = 0;
        char *slash = strrchr(exe, '/');
        if (slash) {
            *slash = 0;
            snprintf(buf, n, "%s/%s", exe, prog);
            if (access(buf, X_OK) == 0)
                return;
        }
    }
    const char *b = getenv("BTF_BUILD");
    snprintf(buf, n, "%s/%s", b ? b : "build", prog);
    if (access(buf, X_OK) != 0) {
        if (b)
            cr_assert_fail("%s is missing: build it with `make build` (server/build.mk)", buf);
        else
            cr_skip_test("%s not built (set BTF_BUILD or include server/build.mk)", buf);
    }
}

/* Starts btfd on lib with optional extra arguments (NULL-terminated). */
static void srv_start(srv *s, const char *lib, const char *const *extra)
{
    char bin[512];
    btfd_binary(bin, sizeof bin, "btfd");
    const char *argv[32] = {bin, "--library", lib, "--port", "0", "--rescan-ms", "0"};
    int argc = 7;
    for (int i = 0; extra && extra[i] && argc < 30; i++)
        argv[argc++] = extra[i];
    argv[argc] = NULL;
    int fds[2];
    cr_assert_eq(pipe(fds), 0);
    s->pid = fork();
    cr_assert_geq(s->pid, 0);
    g_pid = s->pid;
    if (s->pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL); /* never outlive a crashed test */
        dup2(fds[1], 1);
        close(fds[0]);
        close(fds[1]);
        int efd = g_stderr ? open(g_stderr, O_WRONLY | O_CREAT | O_TRUNC, 0644) : -1;
        if (efd >= 0)
            dup2(efd, 2);
        execv(bin, (char *const *)argv);
        _exit(127);
    }
    close(fds[1]);
    char line[512] = "";
    size_t len = 0;
    long long deadline = fx_now_ms() + TMO;
    while (!strchr(line, '\n') && len < sizeof line - 1 && fx_now_ms() < deadline) {
        struct pollfd p = {fds[0], POLLIN, 0};
        if (poll(&p, 1, 100) <= 0)
            continue;
        ssize_t k = read(fds[0], line + len, sizeof line - 1 - len);
        if (k <= 0)
            break;
        len += (size_t)k;
        line[len] = 0;
    }
    close(fds[0]);
    const char *at = strstr(line, "http://127.0.0.1:");
    cr_assert_not_null(at, "btfd did not report its port: \"%s\"", line);
    s->port = atoi(at + 17);
    cr_assert_gt(s->port, 0);
}

/* Waits up to ms for btfd to exit by itself; its exit status, or -1 (then it is killed). */
static int srv_wait_exit(srv *s, int ms)
{
    int status = 0;
    long long deadline = fx_now_ms() + ms;
    pid_t r;
    while ((r = waitpid(s->pid, &status, WNOHANG)) == 0 && fx_now_ms() < deadline)
        usleep(10000);
    if (r == 0) {
        kill(s->pid, SIGKILL);
        waitpid(s->pid, &status, 0);
        return -1;
    }
    g_pid = 0;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/* SIGTERM, then expects a clean exit (status 0) within the timeout. */
static void srv_stop(srv *s)
{
    kill(s->pid, SIGTERM);
    int rc = srv_wait_exit(s, TMO);
    cr_assert_neq(rc, -1, "btfd did not stop on SIGTERM");
    cr_expect_eq(rc, 0, "btfd exit status %d", rc);
}

static void open_ws(wsc *c, const srv *s)
{
    char st[128];
    cr_assert_eq(wsc_open(c, s->port, "btf-stream.v1", 0, st, sizeof st), 0, "handshake: %s", st);
}

/* Next text message as JSON (skipping nothing); asserts one arrives. */
static cJSON *recv_json(wsc *c)
{
    wsc_msg m;
    cr_assert_eq(wsc_recv(c, &m, TMO), 1, "no message");
    cr_assert_eq(m.op, 1, "expected text, got op %d (%.*s)", m.op, (int)m.len, m.data);
    cJSON *j = cJSON_Parse((char *)m.data);
    cr_assert_not_null(j, "server sent invalid JSON: %s", m.data);
    wsc_msg_free(&m);
    return j;
}

static const char *jstr(const cJSON *o, const char *k)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsString(v) ? v->valuestring : "";
}

static double jnum(const cJSON *o, const char *k)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

/* Text message of the given type (others of type "hello" are skipped). */
static cJSON *expect_type(wsc *c, const char *type)
{
    for (;;) {
        cJSON *j = recv_json(c);
        if (!strcmp(jstr(j, "type"), "hello") && strcmp(type, "hello")) {
            cJSON_Delete(j);
            continue;
        }
        cr_assert_str_eq(jstr(j, "type"), type, "got %s", cJSON_PrintUnformatted(j));
        return j;
    }
}

static void expect_error(wsc *c, const char *code)
{
    cJSON *j = expect_type(c, "error");
    cr_expect_str_eq(jstr(j, "code"), code, "message: %s", jstr(j, "message"));
    cr_expect_gt(strlen(jstr(j, "message")), 0);
    cJSON_Delete(j);
}

/* ---------------------------------------------------------------- stream checker */

#define MAXC 64
#define MAXF 4

/* What one subscription has received, checked against the package on disk. */
typedef struct mstate {
    int mid;
    char name[130];
    char etag[40];
    int n_chunks, limit, resumed, held;
    int n_files[MAXC];
    uint8_t *data[MAXC][MAXF]; /* the files as on disk when the manifest arrived */
    size_t size[MAXC][MAXF];
    size_t got[MAXC][MAXF];
    int done[MAXC];
    double lab[MAXC];
    size_t bytes[MAXC];
    cJSON *manifest;
} mstate;

/* Everything received on one connection. */
typedef struct stream {
    const char *lib;
    int n;
    mstate m[48];
    int order_mid[512], order_chunk[512]; /* chunks in completion order */
    int n_order;
    int completes, errors;
    int cur_mid, cur_chunk; /* chunk whose pieces are arriving (0 = none) */
    size_t max_piece;
    cJSON *last_complete;
} stream;

static mstate *by_mid(stream *st, int mid)
{
    for (int i = 0; i < st->n; i++)
        if (st->m[i].mid == mid)
            return &st->m[i];
    return NULL;
}

static mstate *by_name(stream *st, const char *name)
{
    for (int i = 0; i < st->n; i++)
        if (!strcmp(st->m[i].name, name))
            return &st->m[i];
    return NULL;
}

/* A manifest message: the embedded manifest must equal manifest.json on disk. */
static void on_manifest(stream *st, cJSON *j)
{
    mstate *m = by_name(st, jstr(j, "material"));
    if (!m) {
        cr_assert_lt(st->n, 48);
        m = &st->m[st->n++];
        memset(m, 0, sizeof *m);
    } else {
        cJSON_Delete(m->manifest);
    }
    snprintf(m->name, sizeof m->name, "%s", jstr(j, "material"));
    snprintf(m->etag, sizeof m->etag, "%s", jstr(j, "etag"));
    m->mid = (int)jnum(j, "mid");
    m->limit = (int)jnum(j, "limit");
    m->held = (int)jnum(j, "held");
    m->resumed = cJSON_IsTrue(cJSON_GetObjectItem(j, "resumed"));
    m->manifest = cJSON_DetachItemFromObject(j, "manifest");
    char path[700];
    snprintf(path, sizeof path, "%s/%s/manifest.json", st->lib, m->name);
    size_t n;
    uint8_t *txt = (uint8_t *)fx_read(path, &n);
    cr_assert_not_null(txt);
    cJSON *disk = cJSON_Parse((char *)txt);
    cr_assert(cJSON_Compare(disk, m->manifest, 1), "manifest of %s differs from the file", m->name);
    free(txt);
    cJSON_Delete(disk);
    const cJSON *chunks = cJSON_GetObjectItem(m->manifest, "chunks"), *c;
    m->n_chunks = 0;
    cJSON_ArrayForEach(c, chunks) {
        int ci = m->n_chunks++;
        cr_assert_lt(ci, MAXC);
        m->lab[ci] = jnum(c, "lab");
        const cJSON *f;
        m->n_files[ci] = 0;
        m->bytes[ci] = 0;
        cJSON_ArrayForEach(f, cJSON_GetObjectItem(c, "files")) {
            int fi = m->n_files[ci]++;
            snprintf(path, sizeof path, "%s/%s/%s", st->lib, m->name, f->valuestring);
            free(m->data[ci][fi]);
            m->data[ci][fi] = (uint8_t *)fx_read(path, &m->size[ci][fi]);
            cr_assert_not_null(m->data[ci][fi], "%s", path);
            m->bytes[ci] += m->size[ci][fi];
        }
    }
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* A binary piece: must continue the current chunk in file order, byte-exact. */
static void on_piece(stream *st, const uint8_t *p, size_t len)
{
    cr_assert_geq(len, 20, "piece without a header");
    int mid = (int)le32(p), chunk = (int)le32(p + 4), file = (int)le32(p + 8);
    size_t off = le32(p + 12), total = le32(p + 16), n = len - 20;
    if (n > st->max_piece)
        st->max_piece = n;
    mstate *m = by_mid(st, mid);
    cr_assert_not_null(m, "piece for mid %d before its manifest", mid);
    cr_assert_lt(chunk, m->n_chunks);
    cr_assert_lt(file, m->n_files[chunk]);
    cr_assert(!m->done[chunk], "chunk %d of %s sent twice", chunk, m->name);
    if (st->cur_mid != mid || st->cur_chunk != chunk) {
        cr_assert_eq(st->cur_mid, 0, "chunk %d of mid %d interrupted", st->cur_chunk, st->cur_mid);
        st->cur_mid = mid;
        st->cur_chunk = chunk;
    }
    for (int f = 0; f < file; f++)
        cr_assert_eq(m->got[chunk][f], m->size[chunk][f], "file %d before file %d finished", file, f);
    cr_assert_eq(total, m->size[chunk][file], "total of %s chunk %d file %d", m->name, chunk, file);
    cr_assert_eq(off, m->got[chunk][file], "offset of %s chunk %d file %d", m->name, chunk, file);
    cr_assert_leq(off + n, total);
    cr_assert(n == 0 || !memcmp(p + 20, m->data[chunk][file] + off, n), "bytes of %s chunk %d file %d differ at %zu",
              m->name, chunk, file, off);
    m->got[chunk][file] += n;
    for (int f = 0; f < m->n_files[chunk]; f++)
        if (m->got[chunk][f] != m->size[chunk][f] || (m->size[chunk][f] == 0 && f > file))
            return;
    m->done[chunk] = 1;
    st->cur_mid = 0;
    cr_assert_lt(st->n_order, 512);
    st->order_mid[st->n_order] = mid;
    st->order_chunk[st->n_order++] = chunk;
}

/* Processes messages until `completes` "complete" messages have arrived in total. */
static void run_until_complete(wsc *c, stream *st, int completes)
{
    while (st->completes < completes) {
        wsc_msg msg;
        int r = wsc_recv(c, &msg, TMO);
        cr_assert_eq(r, 1, "stream stalled after %d chunks (%d/%d complete)", st->n_order, st->completes,
                     completes);
        cr_assert(msg.op == 1 || msg.op == 2, "unexpected op %d (%.*s)", msg.op, (int)msg.len, msg.data);
        if (msg.op == 2) {
            on_piece(st, msg.data, msg.len);
        } else {
            cJSON *j = cJSON_Parse((char *)msg.data);
            cr_assert_not_null(j);
            const char *t = jstr(j, "type");
            if (!strcmp(t, "manifest"))
                on_manifest(st, j);
            else if (!strcmp(t, "complete")) {
                st->completes++;
                cr_expect_eq(st->cur_mid, 0, "complete in the middle of a chunk");
                cJSON_Delete(st->last_complete);
                st->last_complete = cJSON_Duplicate(j, 1);
            } else if (!strcmp(t, "error"))
                st->errors++;
            cJSON_Delete(j);
        }
        wsc_msg_free(&msg);
    }
}

static void stream_free(stream *st)
{
    for (int i = 0; i < st->n; i++) {
        cJSON_Delete(st->m[i].manifest);
        for (int c = 0; c < MAXC; c++)
            for (int f = 0; f < MAXF; f++)
                free(st->m[i].data[c][f]);
    }
    cJSON_Delete(st->last_complete);
}

/* No further message within ms. */
static void expect_silence(wsc *c, int ms)
{
    wsc_msg m;
    int r = wsc_recv(c, &m, ms);
    cr_expect_eq(r, 0, "unexpected message op %d: %.*s", m.op, (int)(m.len > 200 ? 200 : m.len),
                 m.op == 1 ? (char *)m.data : "");
    wsc_msg_free(&m);
}

/* ---------------------------------------------------------------- raw HTTP */

/* Plain TCP connection to 127.0.0.1:port, -1 on failure. */
static int tcp_connect(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

/* Case-insensitive strstr (strcasestr is a GNU extension). */
static const char *find_nocase(const char *h, const char *n)
{
    for (size_t k = strlen(n); *h; h++)
        if (!strncasecmp(h, n, k))
            return h;
    return NULL;
}

/* GET path with HTTP/1.1 (Connection: close; the paths are deliberately odd,
 * so they are sent verbatim) and extra request header lines (each ending in
 * \r\n, or NULL); returns the status (0: no reply), body malloc'd into *body
 * (*blen bytes), and the response head into head (if not NULL). A path
 * "HEAD /x" sends HEAD /x. */
static int http_req(int port, const char *path, const char *extra, char *head, size_t hn, uint8_t **body,
                    size_t *blen)
{
    int fd = tcp_connect(port);
    cr_assert_geq(fd, 0);
    char req[1024];
    int head_only = !strncmp(path, "HEAD ", 5); /* "HEAD /path": a HEAD request */
    int n = snprintf(req, sizeof req, "%s %s HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n%s\r\n",
                     head_only ? "HEAD" : "GET", path + (head_only ? 5 : 0), extra ? extra : "");
    cr_assert_eq(send(fd, req, (size_t)n, MSG_NOSIGNAL), n);
    long long deadline = fx_now_ms() + TMO;
    size_t len = 0, cap = 65536, h = 0, clen = (size_t)-1; /* h: header length, 0 until seen */
    char *buf = malloc(cap + 1);
    for (;;) {
        buf[len] = 0;
        const char *e = h ? NULL : strstr(buf, "\r\n\r\n");
        if (e) {
            h = (size_t)(e + 4 - buf);
            const char *cl = find_nocase(buf, "content-length:");
            if (cl && cl < e)
                clen = strtoul(cl + 15, NULL, 10);
        }
        if (h && clen != (size_t)-1 && len >= h + clen)
            break;
        struct pollfd p = {fd, POLLIN, 0};
        long long left = deadline - fx_now_ms();
        if (left <= 0 || poll(&p, 1, (int)left) <= 0)
            break;
        if (cap - len < 4096)
            buf = realloc(buf, (cap *= 2) + 1);
        ssize_t k = recv(fd, buf + len, cap - len, 0);
        if (k <= 0)
            break;
        len += (size_t)k;
    }
    close(fd);
    int status = h ? atoi(buf + 9) : 0;
    if (head)
        snprintf(head, hn, "%.*s", (int)h, buf);
    *blen = h ? len - h : 0;
    *body = malloc(*blen + 1);
    memcpy(*body, buf + h, *blen);
    (*body)[*blen] = 0;
    free(buf);
    return status;
}

static int http_get(int port, const char *path, uint8_t **body, size_t *blen)
{
    return http_req(port, path, NULL, NULL, 0, body, blen);
}

/* Checks the Prometheus text format: comment lines "# HELP name text" and
 * "# TYPE name counter|gauge", samples "name value", nothing else. */
static void metrics_well_formed(const char *text)
{
    const char *line = text;
    while (*line) {
        const char *nl = strchr(line, '\n');
        cr_assert_not_null(nl, "metrics end without a newline");
        char l[512], name[128], type[32];
        snprintf(l, sizeof l, "%.*s", (int)(nl - line), line);
        double v;
        char extra;
        if (!strncmp(l, "# HELP ", 7))
            cr_expect(strchr(l + 7, ' '), "HELP line without text: %s", l);
        else if (!strncmp(l, "# TYPE ", 7))
            cr_expect(sscanf(l + 7, "%127s %31s", name, type) == 2 && (!strcmp(type, "counter") || !strcmp(type, "gauge")),
                      "bad TYPE line: %s", l);
        else
            cr_expect(sscanf(l, "%127[a-zA-Z0-9_:] %lf%c", name, &v, &extra) == 2 && strlen(name) < strlen(l),
                      "bad sample line: %s", l);
        line = nl + 1;
    }
}

/* Value of the sample `name` in a /metrics body (NAN if absent), which must
 * follow its own # HELP and # TYPE lines. */
static double metric_of(const char *text, const char *name)
{
    char help[160], type[160], key[160];
    snprintf(help, sizeof help, "# HELP %s ", name);
    snprintf(type, sizeof type, "# TYPE %s ", name);
    snprintf(key, sizeof key, "\n%s ", name);
    const char *h = strstr(text, help), *t = strstr(text, type), *v = strstr(text, key);
    if (!v)
        return NAN;
    cr_expect(h && t && h < t && t < v, "%s lacks HELP and TYPE before its sample", name);
    return strtod(v + strlen(key), NULL);
}

/* One metric of a running btfd, from GET /metrics. */
static double metric(const srv *s, const char *name)
{
    uint8_t *body;
    size_t n;
    char head[4096];
    cr_assert_eq(http_req(s->port, "/metrics", NULL, head, sizeof head, &body, &n), 200);
    cr_expect(find_nocase(head, "content-type: text/plain; version=0.0.4"), "%s", head);
    double v = metric_of((char *)body, name);
    free(body);
    return v;
}

/* ================================================================ tests */

static char g_lib[320], g_root[256];

static void lib_setup(void)
{
    cr_assert(fx_tmpdir(g_root, sizeof g_root));
    snprintf(g_lib, sizeof g_lib, "%s/lib", g_root);
    cr_assert_eq(mkdir(g_lib, 0755), 0);
    srand((unsigned)getpid());
}

static void lib_teardown(void)
{
    if (g_pid > 0) {
        kill(g_pid, SIGKILL);
        waitpid(g_pid, NULL, 0);
    }
    cr_assert_eq(fx_rmtree(g_root), 0);
}

TestSuite(server, .init = lib_setup, .fini = lib_teardown, .timeout = 60);

Test(server, list_over_http_and_websocket_skips_non_packages)
{
    size_t ta = make_simple(g_lib, "alpha", 3, 1000);
    make_simple(g_lib, "beta", 2, 500);
    make_simple(g_lib, "gamma", 1, 10);
    char p[600], q[700];
    snprintf(p, sizeof p, "%s/gamma", g_lib);
    snprintf(q, sizeof q, "%s/gamma.tmp-42", g_lib); /* a package being written */
    cr_assert_eq(rename(p, q), 0);
    make_simple(g_lib, "delta", 1, 10);
    snprintf(p, sizeof p, "%s/delta", g_lib);
    snprintf(q, sizeof q, "%s/delta.old-7", g_lib); /* a package being replaced */
    cr_assert_eq(rename(p, q), 0);
    make_simple(g_lib, "hidden", 1, 10);
    snprintf(p, sizeof p, "%s/hidden", g_lib);
    snprintf(q, sizeof q, "%s/.hidden", g_lib);
    cr_assert_eq(rename(p, q), 0);
    uint8_t thumb[3000];
    fill_random(thumb, sizeof thumb, 77);
    snprintf(p, sizeof p, "%s/beta/thumbnail.png", g_lib);
    fx_write(p, thumb, sizeof thumb);
    const char *broken[][2] = {
        {"nomanifest", NULL},
        {"badjson", "{\"format\":\"btf-package\",\"version\":1,"},
        {"wrongformat", "{\"format\":\"other\",\"version\":1,\"chunks\":[{\"files\":[\"a\"]}]}"},
        {"wrongversion", "{\"format\":\"btf-package\",\"version\":5,\"chunks\":[{\"files\":[\"a\"]}]}"},
        {"missingfile", "{\"format\":\"btf-package\",\"version\":1,\"chunks\":[{\"files\":[\"nope.bin\"]}]}"},
        {"escapingfile", "{\"format\":\"btf-package\",\"version\":1,\"chunks\":[{\"files\":[\"../alpha/c0_f0.bin\"]}]}"},
        {"nochunks", "{\"format\":\"btf-package\",\"version\":1,\"chunks\":[]}"},
        {"bad name", "{\"format\":\"btf-package\",\"version\":1,\"chunks\":[{\"files\":[\"a\"]}]}"},
    };
    for (size_t i = 0; i < sizeof broken / sizeof broken[0]; i++) {
        snprintf(p, sizeof p, "%s/%s", g_lib, broken[i][0]);
        cr_assert_eq(mkdir(p, 0755), 0);
        snprintf(q, sizeof q, "%s/a", p);
        fx_write(q, "xyz", 3);
        if (broken[i][1]) {
            snprintf(q, sizeof q, "%s/manifest.json", p);
            fx_write(q, broken[i][1], strlen(broken[i][1]));
        }
    }
    srv s;
    srv_start(&s, g_lib, NULL);
    uint8_t *body;
    size_t blen;
    cr_assert_eq(http_get(s.port, "/materials", &body, &blen), 200);
    cJSON *j = cJSON_Parse((char *)body);
    cr_assert_not_null(j, "%s", body);
    free(body);
    const cJSON *mats = cJSON_GetObjectItem(j, "materials");
    cr_assert_eq(cJSON_GetArraySize(mats), 2, "%s", cJSON_PrintUnformatted(mats));
    const cJSON *a = cJSON_GetArrayItem(mats, 0), *b = cJSON_GetArrayItem(mats, 1);
    cr_expect_str_eq(jstr(a, "name"), "alpha");
    cr_expect_str_eq(jstr(b, "name"), "beta");
    cr_expect_eq(jnum(a, "chunks"), 3);
    cr_expect_eq(jnum(a, "bytes"), (double)ta);
    cr_expect_eq(jnum(a, "width"), 16);
    cr_expect_eq(jnum(a, "error"), 100.0 / 3, "final error = last chunk's lab");
    cr_expect(cJSON_IsNull(cJSON_GetObjectItem(a, "thumbnail")));
    cr_expect_str_eq(jstr(b, "thumbnail"), "/materials/beta/thumbnail.png");
    cJSON_Delete(j);
    /* /materials.json (the file btfd --publish writes) answers the same body */
    uint8_t *again;
    size_t alen;
    cr_assert_eq(http_get(s.port, "/materials", &body, &blen), 200);
    cr_assert_eq(http_get(s.port, "/materials.json", &again, &alen), 200);
    cr_expect(alen == blen && !memcmp(again, body, blen), "/materials.json differs from /materials");
    free(body);
    free(again);

    cr_assert_eq(http_get(s.port, "/materials/beta/thumbnail.png", &body, &blen), 200);
    cr_expect(blen == sizeof thumb && !memcmp(body, thumb, blen), "thumbnail bytes differ");
    free(body);
    /* lws folds "/../" segments before routing: whatever it makes of this, the
     * answer is the indexed thumbnail or nothing, never a file outside the index */
    int st0 = http_get(s.port, "/materials/../beta/thumbnail.png", &body, &blen);
    cr_expect(st0 == 404 || (st0 == 200 && blen == sizeof thumb && !memcmp(body, thumb, blen)), "got %d", st0);
    free(body);
    const char *missing[] = {"/materials/alpha/thumbnail.png", "/materials/nosuch/thumbnail.png",
                             "/materials/.beta/thumbnail.png", "/materials/beta/manifest.json",
                             "/materials/beta/c0_f0.bin", "/materials/beta", "/materials/beta%00/thumbnail.png"};
    for (size_t i = 0; i < sizeof missing / sizeof missing[0]; i++) {
        int st = http_get(s.port, missing[i], &body, &blen);
        cr_expect(st == 404 || st == 403 || st == 400 || st == 0, "%s gave %d", missing[i], st);
        free(body);
    }

    wsc c;
    open_ws(&c, &s);
    cJSON *hello = expect_type(&c, "hello");
    cr_expect_str_eq(jstr(hello, "protocol"), "btf-stream.v1");
    cr_expect_str_eq(jstr(hello, "version"), BTF_VERSION);
    cr_expect_eq(jnum(hello, "header_bytes"), 20);
    cJSON_Delete(hello);
    wsc_send_text(&c, "{\"type\":\"list\",\"seq\":7}");
    j = expect_type(&c, "list");
    cr_expect_eq(jnum(j, "seq"), 7);
    mats = cJSON_GetObjectItem(j, "materials");
    cr_expect_eq(cJSON_GetArraySize(mats), 2);
    cr_expect_str_eq(jstr(cJSON_GetArrayItem(mats, 1), "name"), "beta");
    cJSON_Delete(j);
    /* the name of a skipped directory is not a material */
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"gamma.tmp-42\"}");
    expect_error(&c, "unknown_material");
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"missingfile\"}");
    expect_error(&c, "unknown_material");
    wsc_close(&c);
    srv_stop(&s);
}

/* The test's --client and --shaders directories (300 bytes each), created empty. */
static void mount_dirs(char *client, char *shaders)
{
    snprintf(client, 300, "%s/client", g_root);
    snprintf(shaders, 300, "%s/shaders", g_root);
    cr_assert_eq(mkdir(client, 0755), 0);
    cr_assert_eq(mkdir(shaders, 0755), 0);
}

Test(server, http_mounts_serve_client_and_shaders)
{
    char client[300], shaders[300];
    mount_dirs(client, shaders);
    fx_put_text(client, "index.html", "<p>hello-client</p>\n");
    fx_put_text(shaders, "decode.glsl", "vec3 decode() { return vec3(0.); }\n");
    srv s;
    const char *extra[] = {"--client", client, "--shaders", shaders, NULL};
    srv_start(&s, g_lib, extra);
    uint8_t *body;
    size_t n;
    cr_expect_eq(http_get(s.port, "/", &body, &n), 200);
    cr_expect(strstr((char *)body, "hello-client"), "%s", body);
    free(body);
    cr_expect_eq(http_get(s.port, "/shaders/decode.glsl", &body, &n), 200);
    cr_expect(n == 35 && !memcmp(body, "vec3 decode()", 13), "%s", body);
    free(body);
    cr_expect_eq(http_get(s.port, "/shaders/../../etc/passwd", &body, &n) != 200, 1);
    free(body);
    /* glTF models beside the pages: a .glb, a .gltf and its buffer, with their types */
    static const char *model[3][2] = {{"m.glb", "model/gltf-binary"}, {"m.gltf", "model/gltf+json"},
                                      {"m.bin", "application/octet-stream"}};
    for (int i = 0; i < 3; i++) {
        char head[2048], path[64], want[96];
        fx_put_text(client, model[i][0], "glTF");
        snprintf(path, sizeof path, "/%s", model[i][0]);
        snprintf(want, sizeof want, "content-type: %s", model[i][1]);
        cr_expect_eq(http_req(s.port, path, NULL, head, sizeof head, &body, &n), 200, "%s", path);
        cr_expect(find_nocase(head, want), "%s: %s", path, head);
        free(body);
    }
    srv_stop(&s);
}

/* Whether the n bytes at h contain the string k (memmem is a GNU extension). */
static int has_bytes(const char *h, size_t n, const char *k)
{
    size_t m = strlen(k);
    for (size_t i = 0; i + m <= n; i++)
        if (!memcmp(h + i, k, m))
            return 1;
    return 0;
}

/* Sends req on the connected socket fd and collects what arrives for up to ms (or
 * until the server closes, or until `until` appears); returns the bytes (malloc'd,
 * NUL-terminated), their count in *len. fd stays open. */
static char *fd_exchange(int fd, const char *req, int ms, const char *until, size_t *len)
{
    cr_assert_eq(send(fd, req, strlen(req), MSG_NOSIGNAL), (ssize_t)strlen(req));
    size_t n = 0, cap = 1 << 16;
    char *buf = malloc(cap + 1);
    buf[0] = 0;
    long long deadline = fx_now_ms() + ms;
    for (;;) {
        struct pollfd p = {fd, POLLIN, 0};
        long long left = deadline - fx_now_ms();
        if (left <= 0 || poll(&p, 1, (int)left) <= 0)
            break;
        ssize_t k = recv(fd, buf + n, cap - n, 0);
        if (k <= 0)
            break;
        n += (size_t)k;
        buf[n] = 0;
        if (until && has_bytes(buf, n, until))
            break;
    }
    *len = n;
    return buf;
}

/* fd_exchange on a new connection to port, closed afterwards. */
static char *raw_exchange(int port, const char *req, int ms, const char *until, size_t *len)
{
    int fd = tcp_connect(port);
    cr_assert_geq(fd, 0);
    char *buf = fd_exchange(fd, req, ms, until, len);
    close(fd);
    return buf;
}

/* GET path with an Origin header; returns the reply's headers and body. */
static char *get_with_origin(int port, const char *path, const char *origin)
{
    char req[512];
    snprintf(req, sizeof req, "GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\nOrigin: %s\r\nConnection: close\r\n\r\n",
             path, origin);
    size_t n;
    return raw_exchange(port, req, TMO, NULL, &n);
}

/* A WebSocket handshake from origin; returns what the server answered within 1 s. */
static char *ws_from_origin(int port, const char *origin, size_t *n)
{
    char req[512];
    snprintf(req, sizeof req,
             "GET /stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
             "Sec-WebSocket-Protocol: btf-stream.v1\r\nOrigin: %s\r\n\r\n", origin);
    return raw_exchange(port, req, 1000, "\"hello\"", n);
}

Test(server, cross_origin_headers_and_websocket_origin_check)
{
    make_simple(g_lib, "alpha", 2, 1000);
    char client[300], shaders[300];
    mount_dirs(client, shaders);
    fx_put_text(client, "index.html", "<p>page</p>\n");
    fx_put_text(client, "btf-viewer.js", "export {};\n");
    fx_put_text(shaders, "manifest.json", "{}\n");
    srv s;
    const char *root[] = {"--client", client, "--shaders", shaders, NULL};
    srv_start(&s, g_lib, root); /* default: any origin */
    const char *paths[] = {"/btf-viewer.js", "/shaders/manifest.json", "/materials"};
    for (int i = 0; i < 3; i++) {
        char *r = get_with_origin(s.port, paths[i], "http://other.example:9");
        cr_expect(!strncmp(r, "HTTP/1.1 200", 12) && find_nocase(r, "access-control-allow-origin: *\r\n"),
                  "%s: %.400s", paths[i], r);
        free(r);
    }
    char *r = get_with_origin(s.port, "/", "http://other.example:9");
    cr_expect(find_nocase(r, "content-security-policy:") && find_nocase(r, "frame-ancestors 'none'"),
              "btfd's own page keeps its CSP: %.600s", r);
    free(r);
    srv_stop(&s);

    const char *list[] = {"--client", client, "--shaders", shaders, "--allow-origin",
                          "http://a.example,http://b.example:8000", NULL};
    srv_start(&s, g_lib, list);
    r = get_with_origin(s.port, "/btf-viewer.js", "http://b.example:8000");
    cr_expect(find_nocase(r, "access-control-allow-origin: http://b.example:8000\r\n") &&
              find_nocase(r, "vary: Origin"), "%.600s", r);
    free(r);
    r = get_with_origin(s.port, "/materials", "http://evil.example");
    cr_expect(!find_nocase(r, "access-control-allow-origin"), "no CORS for others: %.600s", r);
    free(r);
    size_t n;
    r = ws_from_origin(s.port, "http://a.example", &n);
    cr_expect(strstr(r, " 101 ") && has_bytes(r, n, "\"hello\""), "allowed origin streams: %.300s", r);
    free(r);
    r = ws_from_origin(s.port, "http://evil.example", &n);
    const char *body = strstr(r, "\r\n\r\n");
    /* the close frame: 0x88, length, status 1008 (0x03f0) big-endian, reason */
    cr_expect(body && (uint8_t)body[4] == 0x88 && (uint8_t)body[6] == 0x03 && (uint8_t)body[7] == 0xf0 &&
              has_bytes(r, n, "origin not allowed") && !has_bytes(r, n, "\"hello\""),
              "other origins are closed with 1008: %zu bytes", n);
    free(r);
    r = ws_from_origin(s.port, "http://b.example:8000", &n);
    cr_expect(has_bytes(r, n, "\"hello\""), "the server still streams to allowed origins: %.300s", r);
    free(r);
    srv_stop(&s);
}

Test(server, stream_every_chunk_in_order_byte_exact)
{
    /* 4 chunks x 2 files: some files span several fragments (128 KiB default), one is empty */
    const size_t sizes[] = {150000, 70000, 65536, 0, 1, 131073, 90000, 12345};
    const double lab[] = {9, 5, 3, 2};
    size_t total = make_pkg(g_lib, "alpha", 4, 2, sizes, lab);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    cJSON *hello = expect_type(&c, "hello");
    size_t fragment = (size_t)jnum(hello, "fragment");
    cJSON_Delete(hello);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"seq\":3}");
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 1);
    cr_assert_eq(st.n, 1);
    cr_expect_eq(st.m[0].limit, 4);
    cr_assert_eq(st.n_order, 4, "every chunk arrives");
    for (int i = 0; i < 4; i++)
        cr_expect_eq(st.order_chunk[i], i, "chunk %d arrived as #%d", st.order_chunk[i], i);
    cr_expect_leq(st.max_piece, fragment, "pieces stay within the advertised fragment");
    cr_expect_eq(st.max_piece, fragment, "large files are split at the fragment size");
    cr_expect_eq(jnum(st.last_complete, "bytes_sent"), (double)total);
    cr_expect_eq(jnum(st.last_complete, "chunks_sent"), 4);
    expect_silence(&c, 150);
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

/* A version-2 package (doc/package-format.md section 9.2): (component, level)
 * chunks with `level`/`contrib` and `rmse` but no `lab`. The server streams it
 * like version 1 and ranks it by rmse. */
Test(server, version2_package_streams_with_rmse_metric)
{
    char dir[400], path[500];
    snprintf(dir, sizeof dir, "%s/knit2", g_lib);
    cr_assert_eq(mkdir(dir, 0755), 0);
    const char *files[] = {"wt-00-8.png", "tex-00-l1.png", "tex-00.png", "wt-00.bin"};
    const size_t sizes[] = {700, 300, 1200, 900};
    for (int i = 0; i < 4; i++) {
        uint8_t b[1200];
        fill_random(b, sizes[i], (uint32_t)(i + 11));
        snprintf(path, sizeof path, "%s/%s", dir, files[i]);
        fx_write(path, b, sizes[i]);
    }
    const char *man = "{\"format\":\"btf-package\",\"version\":2,\"levels\":2,\"width\":16,\"height\":16,"
                      "\"chunks\":[{\"files\":[\"wt-00-8.png\",\"tex-00-l1.png\"],\"component\":0,\"level\":1,"
                      "\"contrib\":5,\"rmse\":7.5},"
                      "{\"files\":[\"tex-00.png\",\"wt-00.bin\"],\"component\":0,\"level\":0,"
                      "\"contrib\":2,\"rmse\":2.5}]}";
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    fx_write(path, man, strlen(man));
    srv s;
    srv_start(&s, g_lib, NULL);
    uint8_t *body;
    size_t blen;
    cr_assert_eq(http_get(s.port, "/materials", &body, &blen), 200);
    cJSON *j = cJSON_Parse((char *)body);
    cr_assert_not_null(j, "%s", body);
    free(body);
    const cJSON *mats = cJSON_GetObjectItem(j, "materials");
    cr_assert_eq(cJSON_GetArraySize(mats), 1, "the v2 package is listed");
    const cJSON *a = cJSON_GetArrayItem(mats, 0);
    cr_expect_str_eq(jstr(a, "metric"), "rmse", "no lab in v2: rmse ranks the chunks");
    cr_expect_eq(jnum(a, "error"), 2.5);
    cr_expect_eq(jnum(a, "bytes"), (double)(700 + 300 + 1200 + 900));
    cJSON_Delete(j);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    /* a budget of the coarse chunk only, then everything */
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"knit2\",\"budget\":{\"chunks\":1}}");
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 1);
    cr_assert_eq(st.n_order, 1, "only the budgeted coarse chunk");
    cr_expect_eq(jnum(st.last_complete, "bytes_sent"), 1000.0);
    wsc_send_text(&c, "{\"type\":\"budget\",\"material\":\"knit2\",\"budget\":{}}");
    run_until_complete(&c, &st, 2);
    cr_expect_eq(st.n_order, 2, "the level-0 chunk follows when the budget grows");
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

/* The order doc/protocol.md promises: first every material's first chunk (in
 * subscription order), then repeatedly the next allowed chunk with the largest
 * (error before - error after) / bytes, ties to the earlier subscription. */
static int expected_order(const mstate *const *m, int n, int *out_mat, int *out_chunk)
{
    int next[8] = {0}, count = 0;
    for (;;) {
        int best = -1;
        double bp = -1;
        for (int k = 0; k < n; k++) {
            int i = next[k];
            if (i >= m[k]->limit)
                continue;
            double p = i == 0 ? INFINITY : fmax(m[k]->lab[i - 1] - m[k]->lab[i], 0) / (double)m[k]->bytes[i];
            if (p > bp) {
                bp = p;
                best = k;
            }
        }
        if (best < 0)
            return count;
        out_mat[count] = best;
        out_chunk[count++] = next[best]++;
    }
}

Test(server, two_materials_interleave_by_error_reduction_per_byte)
{
    const size_t sa[] = {10000, 10000, 10000, 10000}, sb[] = {5000, 5000, 5000, 5000};
    const double la[] = {20, 10, 8, 7.5}, lb[] = {30, 12, 11.2, 11.1};
    make_pkg(g_lib, "alpha", 4, 1, sa, la);
    make_pkg(g_lib, "beta", 4, 1, sb, lb);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    const char *msgs[] = {"{\"type\":\"subscribe\",\"material\":\"alpha\"}",
                          "{\"type\":\"subscribe\",\"material\":\"beta\"}"};
    wsc_send_batch(&c, msgs, 2); /* one write: the server sees both before sending */
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 2);
    const mstate *ms[2] = {by_name(&st, "alpha"), by_name(&st, "beta")};
    cr_assert(ms[0] && ms[1]);
    int em[16], ec[16];
    int n = expected_order(ms, 2, em, ec);
    cr_assert_eq(n, 8);
    cr_assert_eq(st.n_order, 8);
    int interleaved = 0;
    for (int i = 0; i < n; i++) {
        cr_expect_eq(st.order_mid[i], ms[em[i]]->mid, "#%d: mid %d chunk %d, expected %s chunk %d", i,
                     st.order_mid[i], st.order_chunk[i], ms[em[i]]->name, ec[i]);
        cr_expect_eq(st.order_chunk[i], ec[i]);
        interleaved += i > 0 && st.order_mid[i] != st.order_mid[i - 1];
    }
    cr_expect_geq(interleaved, 4, "the materials alternate, not one after the other");
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

Test(server, budgets_limit_chunks_bytes_and_error_and_can_change)
{
    const size_t sz[] = {10000, 10000, 10000, 10000, 10000, 10000};
    const double lab[] = {50, 30, 20, 15, 12, 10};
    make_pkg(g_lib, "pc", 6, 1, sz, lab);
    make_pkg(g_lib, "pb", 6, 1, sz, lab);
    make_pkg(g_lib, "pe", 6, 1, sz, lab);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    const char *msgs[] = {
        "{\"type\":\"subscribe\",\"material\":\"pc\",\"budget\":{\"chunks\":2}}",
        "{\"type\":\"subscribe\",\"material\":\"pb\",\"budget\":{\"bytes\":25000}}",
        "{\"type\":\"subscribe\",\"material\":\"pe\",\"budget\":{\"error\":16}}",
    };
    wsc_send_batch(&c, msgs, 3);
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 3);
    mstate *pc = by_name(&st, "pc"), *pb = by_name(&st, "pb"), *pe = by_name(&st, "pe");
    cr_assert(pc && pb && pe);
    /* limits recomputed from the budgets: 2 chunks; 2 x 10000 <= 25000 < 3 x 10000;
     * the first chunk whose lab <= 16 is #3 (lab 15) -> 4 chunks */
    cr_expect_eq(pc->limit, 2);
    cr_expect_eq(pb->limit, 2);
    cr_expect_eq(pe->limit, 4);
    for (int i = 0; i < 6; i++) {
        cr_expect_eq(pc->done[i], i < 2, "pc chunk %d", i);
        cr_expect_eq(pb->done[i], i < 2, "pb chunk %d", i);
        cr_expect_eq(pe->done[i], i < 4, "pe chunk %d", i);
    }
    expect_silence(&c, 150);
    /* raise: only the missing chunks 2..4 come */
    wsc_send_text(&c, "{\"type\":\"budget\",\"material\":\"pc\",\"budget\":{\"chunks\":5},\"seq\":9}");
    int before = st.n_order;
    run_until_complete(&c, &st, 4);
    cr_expect_eq(st.n_order - before, 3);
    for (int i = 0; i < 6; i++)
        cr_expect_eq(pc->done[i], i < 5, "pc chunk %d after raising", i);
    /* lower and pause: acknowledged, nothing sent */
    wsc_send_text(&c, "{\"type\":\"budget\",\"material\":\"pb\",\"budget\":{\"chunks\":0}}");
    cJSON *ack = expect_type(&c, "budget");
    cr_expect_eq(jnum(ack, "limit"), 0);
    cJSON_Delete(ack);
    cJSON_Delete(expect_type(&c, "complete"));
    expect_silence(&c, 150);
    /* unsubscribe: acknowledged; a budget for it is then an error */
    wsc_send_text(&c, "{\"type\":\"unsubscribe\",\"material\":\"pe\"}");
    cJSON *u = expect_type(&c, "unsubscribed");
    cr_expect_eq(jnum(u, "mid"), pe->mid);
    cJSON_Delete(u);
    wsc_send_text(&c, "{\"type\":\"budget\",\"material\":\"pe\",\"budget\":{}}");
    expect_error(&c, "not_subscribed");
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

/* Binary bytes (headers included) that arrive within ms, fed to the stream checker;
 * text messages are handled as run_until_complete does. */
static size_t drain_for(wsc *c, stream *st, int ms)
{
    size_t bin = 0;
    long long end = fx_now_ms() + ms;
    for (;;) {
        long long left = end - fx_now_ms();
        wsc_msg msg;
        if (left <= 0 || wsc_recv(c, &msg, (int)left) != 1)
            return bin;
        if (msg.op == 2) {
            on_piece(st, msg.data, msg.len);
            bin += msg.len;
        } else if (msg.op == 1) {
            cJSON *j = cJSON_Parse((char *)msg.data);
            if (j && !strcmp(jstr(j, "type"), "manifest"))
                on_manifest(st, j);
            else if (j && !strcmp(jstr(j, "type"), "complete"))
                st->completes++;
            cJSON_Delete(j);
        }
        wsc_msg_free(&msg);
    }
}

static void send_ack(wsc *c, size_t received, long window)
{
    char msg[96];
    if (window >= 0)
        snprintf(msg, sizeof msg, "{\"type\":\"ack\",\"received\":%zu,\"window\":%ld}", received, window);
    else
        snprintf(msg, sizeof msg, "{\"type\":\"ack\",\"received\":%zu}", received);
    cr_assert_eq(wsc_send_text(c, msg), 0);
}

/* A client's window bounds what is in flight: with no ack nothing past the window
 * (plus the piece that crossed it) is sent; each ack lets as much again follow,
 * and the stream still arrives whole and in order. */
Test(server, flow_window_bounds_what_is_in_flight)
{
    const size_t chunk = 100000, frag = 16384, window = 65536;
    make_simple(g_lib, "big", 6, chunk);
    const char *extra[] = {"--fragment", "16384", NULL};
    srv s;
    srv_start(&s, g_lib, extra);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    send_ack(&c, 0, (long)window);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"big\"}");
    stream st = {.lib = g_lib};
    size_t got = drain_for(&c, &st, 400), total = got;
    cr_assert_gt(got, 0, "the window lets the first pieces through");
    cr_assert_leq(got, window + frag + 20, "unacknowledged: %zu bytes in flight, window %zu", got, window);
    cr_assert_eq(drain_for(&c, &st, 200), 0, "nothing more until the client acknowledges");
    int acks = 0;
    while (st.completes < 1 && acks < 100) {
        send_ack(&c, total, -1);
        acks++;
        got = drain_for(&c, &st, 150);
        cr_assert_leq(got, window + frag + 20, "after an ack: %zu bytes", got);
        total += got;
    }
    cr_assert_eq(st.completes, 1, "complete after %d acks", acks);
    mstate *m = by_name(&st, "big");
    for (int i = 0; i < 6; i++)
        cr_expect(m->done[i], "chunk %d arrived whole", i);
    cr_expect_geq(acks, (int)(6 * chunk / (window + frag + 20)), "the window, not the link, paced the stream");
    /* window 0 turns flow control off: a second material streams without acks */
    make_simple(g_lib, "big2", 3, chunk);
    send_ack(&c, total, 0);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"big2\"}");
    run_until_complete(&c, &st, 2);
    /* malformed acks are refused and the connection stays */
    wsc_send_text(&c, "{\"type\":\"ack\"}");
    expect_error(&c, "bad_field");
    wsc_send_text(&c, "{\"type\":\"ack\",\"received\":0,\"window\":100}");
    expect_error(&c, "bad_field");
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

/* The next text message of the given type; pieces and other replies are skipped. */
static cJSON *skip_to(wsc *c, const char *type)
{
    for (;;) {
        wsc_msg msg;
        cr_assert_eq(wsc_recv(c, &msg, TMO), 1, "no %s reply", type);
        cJSON *j = msg.op == 1 ? cJSON_Parse((char *)msg.data) : NULL;
        wsc_msg_free(&msg);
        if (j && !strcmp(jstr(j, "type"), type))
            return j;
        cJSON_Delete(j);
    }
}

/* The limit of the reply to a budget for material "lv". */
static int budget_reply_limit(wsc *c, const char *budget)
{
    char msg[256];
    snprintf(msg, sizeof msg, "{\"type\":\"budget\",\"material\":\"lv\",\"budget\":%s}", budget);
    cr_assert_eq(wsc_send_text(c, msg), 0);
    cJSON *r = skip_to(c, "budget");
    int limit = (int)jnum(r, "limit");
    cJSON_Delete(r);
    return limit;
}

/* budget.pixels: the server picks the prefix the view needs by the rule of
 * doc/package-format.md section 7.4, at width / pixels texels per pixel (the manifest's
 * width is 16). Expected limits worked out by hand below. */
Test(server, footprint_budget_selects_the_chunks_a_view_needs)
{
    char dir[400], path[500];
    snprintf(dir, sizeof dir, "%s/lv", g_lib);
    cr_assert_eq(mkdir(dir, 0755), 0);
    /* chunk: component, level, contrib (RMS on 0..255 of the component at that level) */
    const int comp[] = {0, 1, 2, 0, 1, 2}, lev[] = {1, 1, 1, 0, 0, 0};
    const double contrib[] = {9, 3, 0.5, 8, 0.4, 2};
    cJSON *root = cJSON_CreateObject(), *chunks = cJSON_CreateArray();
    cJSON_AddStringToObject(root, "format", "btf-package");
    cJSON_AddNumberToObject(root, "version", 2);
    cJSON_AddNumberToObject(root, "levels", 2);
    cJSON_AddNumberToObject(root, "width", 16);
    cJSON_AddNumberToObject(root, "height", 16);
    for (int i = 0; i < 6; i++) {
        char f[32];
        snprintf(f, sizeof f, "c%d.bin", i);
        snprintf(path, sizeof path, "%s/%s", dir, f);
        fx_write(path, "0123456789", 10);
        cJSON *jc = cJSON_CreateObject(), *files = cJSON_CreateArray();
        cJSON_AddItemToArray(files, cJSON_CreateString(f));
        cJSON_AddItemToObject(jc, "files", files);
        cJSON_AddNumberToObject(jc, "component", comp[i]);
        cJSON_AddNumberToObject(jc, "level", lev[i]);
        cJSON_AddNumberToObject(jc, "contrib", contrib[i]);
        cJSON_AddNumberToObject(jc, "rmse", 10 - i);
        cJSON_AddItemToArray(chunks, jc);
    }
    cJSON_AddItemToObject(root, "chunks", chunks);
    write_manifest(dir, root);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    /* 8 pixels, 2 texels per pixel: level 1; component 0 always, 1 (contrib 3 >= 1), not 2
     * (0.5): chunks 0 and 1 */
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"lv\",\"budget\":{\"pixels\":8}}");
    cJSON *m = expect_type(&c, "manifest");
    cr_expect_eq(jnum(m, "limit"), 2);
    cJSON_Delete(m);
    /* 16 pixels, 1 texel per pixel: level 0; component 1 hidden (0.4), 2 shown (2): chunks
     * 0, 2, 3, 5 */
    cr_expect_eq(budget_reply_limit(&c, "{\"pixels\":16}"), 6);
    /* threshold 5 at level 0: only component 0 (chunks 0 and 3) */
    cr_expect_eq(budget_reply_limit(&c, "{\"pixels\":16,\"threshold\":5}"), 4);
    /* with other limits the smallest prefix wins; off screen nothing */
    cr_expect_eq(budget_reply_limit(&c, "{\"pixels\":16,\"chunks\":3}"), 3);
    cr_expect_eq(budget_reply_limit(&c, "{\"pixels\":0}"), 0);
    wsc_send_text(&c, "{\"type\":\"budget\",\"material\":\"lv\",\"budget\":{\"pixels\":-1}}");
    cJSON *e = skip_to(&c, "error");
    cr_expect_str_eq(jstr(e, "code"), "bad_field");
    cJSON_Delete(e);
    wsc_close(&c);
    srv_stop(&s);
}

Test(server, resume_after_reconnect_sends_only_missing_chunks)
{
    const size_t sz[] = {70000, 3000, 4000, 5000, 6000};
    const double lab[] = {9, 7, 5, 4, 3};
    make_pkg(g_lib, "alpha", 5, 1, sz, lab);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"budget\":{\"chunks\":2}}");
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 1);
    cr_assert_eq(st.n_order, 2);
    char etag[40];
    snprintf(etag, sizeof etag, "%s", st.m[0].etag);
    cr_assert_eq(strlen(etag), 16);
    stream_free(&st);
    wsc_close(&c);

    /* reconnect holding chunks 0 and 1 */
    open_ws(&c, &s);
    char msg[300];
    snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"have\":[0,1],\"etag\":\"%s\"}", etag);
    wsc_send_text(&c, msg);
    stream st2 = {.lib = g_lib};
    run_until_complete(&c, &st2, 1);
    cr_expect(st2.m[0].resumed);
    cr_expect_eq(st2.m[0].held, 2);
    cr_assert_eq(st2.n_order, 3, "only the 3 missing chunks");
    for (int i = 0; i < 3; i++)
        cr_expect_eq(st2.order_chunk[i], i + 2);
    stream_free(&st2);
    wsc_close(&c);

    /* the same with "manifest_kept": the manifest message comes without the manifest;
     * with a stale etag it comes whole (the client's copy is of another package) */
    for (int stale = 0; stale < 2; stale++) {
        open_ws(&c, &s);
        snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"have\":[0,1],\"etag\":\"%s\","
                 "\"manifest_kept\":true,\"budget\":{\"chunks\":2}}", stale ? "0000000000000000" : etag);
        wsc_send_text(&c, msg);
        cJSON *mj = expect_type(&c, "manifest");
        cr_expect_eq(cJSON_IsTrue(cJSON_GetObjectItem(mj, "resumed")), !stale);
        cr_expect_eq(cJSON_HasObjectItem(mj, "manifest"), stale, "stale %d: %s", stale, cJSON_PrintUnformatted(mj));
        cr_expect_str_eq(jstr(mj, "etag"), etag);
        cJSON_Delete(mj);
        wsc_close(&c);
    }
    open_ws(&c, &s);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"manifest_kept\":1}");
    expect_error(&c, "bad_field");
    wsc_close(&c);

    /* a stale etag: "have" is ignored and everything comes again */
    open_ws(&c, &s);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"have\":[0,1],\"etag\":\"0000000000000000\"}");
    stream st3 = {.lib = g_lib};
    run_until_complete(&c, &st3, 1);
    cr_expect(!st3.m[0].resumed);
    cr_expect_eq(st3.n_order, 5);
    stream_free(&st3);
    /* an index the material does not have */
    snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"alpha\",\"have\":[99],\"etag\":\"%s\"}", etag);
    wsc_send_text(&c, "{\"type\":\"unsubscribe\",\"material\":\"alpha\"}");
    cJSON_Delete(expect_type(&c, "unsubscribed"));
    wsc_send_text(&c, msg);
    expect_error(&c, "bad_field");
    wsc_close(&c);
    srv_stop(&s);
}

Test(server, bad_messages_get_error_frames_and_the_connection_stays)
{
    make_simple(g_lib, "alpha", 2, 3000);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    char longname[400] = "{\"type\":\"subscribe\",\"material\":\"";
    memset(longname + strlen(longname), 'a', 200);
    strcat(longname, "\"}");
    const char *cases[][2] = {
        {"{bad", "bad_json"},
        {"[1,2]", "bad_json"},
        {"{\"type\":\"list\"} trailing", "bad_json"},
        {"{\"type\":42}", "bad_type"},
        {"{\"kind\":\"list\"}", "bad_type"},
        {"{\"type\":\"explode\"}", "unknown_type"},
        {"{\"type\":\"subscribe\",\"material\":\"../alpha\"}", "bad_name"},
        {"{\"type\":\"subscribe\",\"material\":\"/etc/passwd\"}", "bad_name"},
        {"{\"type\":\"subscribe\",\"material\":\"..\"}", "bad_name"},
        {"{\"type\":\"subscribe\",\"material\":\"\"}", "bad_name"},
        {"{\"type\":\"subscribe\",\"material\":7}", "bad_name"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\\u0000/../x\"}", "bad_json"},
        {longname, "bad_name"},
        {"{\"type\":\"subscribe\",\"material\":\"nosuch\"}", "unknown_material"},
        {"{\"type\":\"budget\",\"material\":\"alpha\",\"budget\":{\"chunks\":1}}", "not_subscribed"},
        {"{\"type\":\"unsubscribe\",\"material\":\"alpha\"}", "not_subscribed"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\",\"budget\":{\"chunks\":-1}}", "bad_field"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\",\"budget\":{\"bytes\":1.5}}", "bad_field"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\",\"budget\":{\"error\":\"low\"}}", "bad_field"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\",\"budget\":[]}", "bad_field"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\",\"have\":\"all\"}", "bad_field"},
        {"{\"type\":\"subscribe\",\"material\":\"alpha\",\"have\":[-1]}", "bad_field"},
        {"{\"type\":\"list\",\"seq\":\"x\"}", "bad_field"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        wsc_send_text(&c, cases[i][0]);
        expect_error(&c, cases[i][1]);
    }
    /* a raw NUL byte inside the text */
    wsc_send_frame(&c, 1, 1, "{\"type\":\"list\"}\0", 16);
    expect_error(&c, "bad_json");
    /* oversized: one frame, and the same split over three fragments */
    size_t big = 20000;
    char *huge = malloc(big + 1);
    memset(huge, ' ', big);
    memcpy(huge, "{\"type\":\"ping\",\"pad\":\"", 22);
    memcpy(huge + big - 2, "\"}", 2);
    huge[big] = 0;
    wsc_send_text(&c, huge);
    expect_error(&c, "too_large");
    wsc_send_frame(&c, 1, 0, huge, 8000);
    wsc_send_frame(&c, 0, 0, huge + 8000, 8000);
    wsc_send_frame(&c, 0, 1, huge + 16000, big - 16000);
    expect_error(&c, "too_large");
    free(huge);
    /* a valid message in two fragments works */
    wsc_send_frame(&c, 1, 0, "{\"type\":\"pi", 11);
    wsc_send_frame(&c, 0, 1, "ng\",\"seq\":5}", 12);
    cJSON *pong = expect_type(&c, "pong");
    cr_expect_eq(jnum(pong, "seq"), 5);
    cJSON_Delete(pong);
    /* still fully usable, and a second subscribe is refused */
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\"}");
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 1);
    cr_expect_eq(st.n_order, 2);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\"}");
    expect_error(&c, "already_subscribed");
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

/* Reads until the server closes; returns the close code (-1: EOF without a close frame). */
static int wait_close(wsc *c, char *reason, size_t n)
{
    for (;;) {
        wsc_msg m;
        int r = wsc_recv(c, &m, TMO);
        cr_assert_neq(r, 0, "server did not close the connection");
        if (r < 0)
            return -1;
        if (m.op == 8) {
            snprintf(reason, n, "%s", (char *)m.data);
            wsc_msg_free(&m);
            return m.close_code;
        }
        wsc_msg_free(&m);
    }
}

/* A client with a 128 KiB receive buffer subscribed to material, which the
 * test then does not read (nothing services its lws context meanwhile). */
static void open_slow(wsc *c, const srv *s, const char *material)
{
    char st[128], msg[200];
    cr_assert_eq(wsc_open(c, s->port, "btf-stream.v1", 131072, st, sizeof st), 0, "%s", st);
    snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"%s\"}", material);
    wsc_send_text(c, msg);
}

/* Reads what a connection still gets until it ends (close frame or EOF);
 * returns the payload bytes of the binary pieces. Fails if it stays open. */
static size_t read_until_closed(wsc *c)
{
    size_t got = 0;
    for (;;) {
        wsc_msg m;
        int r = wsc_recv(c, &m, TMO);
        cr_assert_neq(r, 0, "the connection was not closed");
        if (r < 0 || m.op == 8)
            break;
        if (m.op == 2)
            got += m.len - 20;
        wsc_msg_free(&m);
    }
    return got;
}

static void expect_healthy(const srv *s)
{
    wsc c;
    open_ws(&c, s);
    wsc_send_text(&c, "{\"type\":\"ping\",\"seq\":1}");
    cJSON_Delete(expect_type(&c, "pong"));
    wsc_close(&c);
}

Test(server, binary_frames_and_bad_utf8_close_with_a_reason_others_unaffected)
{
    make_simple(g_lib, "alpha", 2, 3000);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc other;
    open_ws(&other, &s);
    cJSON_Delete(expect_type(&other, "hello"));
    wsc c;
    open_ws(&c, &s);
    wsc_send_frame(&c, 2, 1, "\x01\x02\x03", 3);
    char reason[128];
    cr_expect_eq(wait_close(&c, reason, sizeof reason), 1003);
    cr_expect(strstr(reason, "binary"), "reason: %s", reason);
    wsc_close(&c);
    open_ws(&c, &s);
    wsc_send_frame(&c, 1, 1, "{\"type\":\"\xff\xfe\"}", 13);
    int code = wait_close(&c, reason, sizeof reason);
    cr_expect(code == 1007 || code == 1002, "invalid UTF-8 closes with 1007, got %d", code);
    wsc_close(&c);
    /* the other connection streams as if nothing happened */
    wsc_send_text(&other, "{\"type\":\"subscribe\",\"material\":\"alpha\"}");
    stream st = {.lib = g_lib};
    run_until_complete(&other, &st, 1);
    cr_expect_eq(st.n_order, 2);
    stream_free(&st);
    wsc_close(&other);
    srv_stop(&s);
}

Test(server, unknown_or_missing_subprotocol_is_refused)
{
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    char st[128];
    cr_expect_neq(wsc_open(&c, s.port, "btf-stream.v0", 0, st, sizeof st), 0, "v0 accepted: %s", st);
    wsc_close(&c);
    cr_expect_neq(wsc_open(&c, s.port, NULL, 0, st, sizeof st), 0, "no subprotocol accepted: %s", st);
    wsc_close(&c);
    expect_healthy(&s);
    srv_stop(&s);
}

Test(server, request_and_subscribe_floods_are_bounded)
{
    for (int i = 0; i < 40; i++) {
        char name[16];
        snprintf(name, sizeof name, "m%02d", i);
        make_simple(g_lib, name, 1, 100);
    }
    srv s;
    srv_start(&s, g_lib, NULL);
    /* 40 subscriptions at once: 32 accepted, the rest refused with an error */
    wsc c;
    open_ws(&c, &s);
    const char *msgs[40];
    char buf[40][80];
    for (int i = 0; i < 40; i++) {
        snprintf(buf[i], sizeof buf[i], "{\"type\":\"subscribe\",\"material\":\"m%02d\"}", i);
        msgs[i] = buf[i];
    }
    wsc_send_batch(&c, msgs, 40);
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 32);
    cr_expect_eq(st.n, 32, "32 manifests");
    cr_expect_eq(st.errors, 8, "8 too_many_subscriptions errors");
    cr_expect_eq(st.n_order, 32);
    stream_free(&st);
    wsc_close(&c);

    /* 1000 pings (4x the burst allowance) in one corked write, without
     * reading a reply: closed with a reason. 1000 x 21 bytes stays below half
     * of the initial loopback window, so the kernel holds all of them until
     * the batch is written; with more, the server could close (and reset)
     * the connection while the client is still writing, and libwebsockets
     * drops a connection whose write fails without reading the close frame. */
    open_ws(&c, &s);
    enum { N_PINGS = 1000 };
    const char **pings = malloc(N_PINGS * sizeof *pings);
    for (int i = 0; i < N_PINGS; i++)
        pings[i] = "{\"type\":\"ping\"}";
    wsc_send_batch(&c, pings, N_PINGS);
    free(pings);
    char reason[128];
    cr_expect_eq(wait_close(&c, reason, sizeof reason), 1008);
    cr_expect(strlen(reason) > 0, "close without a reason");
    wsc_close(&c);
    expect_healthy(&s);
    srv_stop(&s);
}

Test(server, stalled_client_is_dropped_and_others_keep_streaming)
{
    size_t sizes[4] = {6u << 20, 6u << 20, 6u << 20, 6u << 20};
    const double lab[] = {4, 3, 2, 1};
    size_t total = make_pkg(g_lib, "big", 4, 1, sizes, lab);
    srv s;
    const char *extra[] = {"--stall-timeout", "1", NULL};
    srv_start(&s, g_lib, extra);
    /* the slow client has its own lws context, which nothing services until
     * the drain below: nothing is read from its socket. Its receive buffer is
     * fixed at 128 KiB (no autotuning; kernel + server buffers stay far below
     * the 24 MiB package), yet above the loopback MSS so the drain is not
     * held up by small-window avoidance. */
    wsc slow;
    open_slow(&slow, &s, "big");
    usleep(300000);
    /* meanwhile another client gets the whole package */
    wsc fast;
    open_ws(&fast, &s);
    wsc_send_text(&fast, "{\"type\":\"subscribe\",\"material\":\"big\"}");
    stream sf = {.lib = g_lib};
    long long t0 = fx_now_ms();
    run_until_complete(&fast, &sf, 1);
    cr_expect_eq(sf.n_order, 4);
    cr_expect_lt(fx_now_ms() - t0, 3000, "the stalled client slowed the other one down");
    stream_free(&sf);
    wsc_close(&fast);
    sleep(3); /* > stall timeout + lws's 1 s timer granularity */
    /* now drain: the connection must end before the package is complete */
    size_t got = read_until_closed(&slow);
    cr_expect_lt(got, total, "received %zu of %zu bytes", got, total);
    wsc_close(&slow);
    expect_healthy(&s);
    cr_expect_eq(metric(&s, "btfd_stalled_drops_total"), 1, "the drop is counted as a stall");
    srv_stop(&s);
}

Test(server, packages_added_later_appear_and_removed_ones_finish_streaming)
{
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc c;
    open_ws(&c, &s);
    cJSON_Delete(expect_type(&c, "hello"));
    wsc_send_text(&c, "{\"type\":\"list\"}");
    cJSON *j = expect_type(&c, "list");
    cr_expect_eq(cJSON_GetArraySize(cJSON_GetObjectItem(j, "materials")), 0);
    cJSON_Delete(j);
    /* a package being written (temp name) is not listed ... */
    make_simple(g_lib, "late", 3, 40000);
    char p[600], q[600];
    snprintf(p, sizeof p, "%s/late", g_lib);
    snprintf(q, sizeof q, "%s/late.tmp-99", g_lib);
    cr_assert_eq(rename(p, q), 0);
    usleep(250000); /* on-demand rescans are rate limited to one per 200 ms */
    wsc_send_text(&c, "{\"type\":\"list\"}");
    j = expect_type(&c, "list");
    cr_expect_eq(cJSON_GetArraySize(cJSON_GetObjectItem(j, "materials")), 0);
    cJSON_Delete(j);
    /* ... and appears once renamed into place, without a restart */
    cr_assert_eq(rename(q, p), 0);
    usleep(250000);
    wsc_send_text(&c, "{\"type\":\"list\"}");
    j = expect_type(&c, "list");
    cr_expect_eq(cJSON_GetArraySize(cJSON_GetObjectItem(j, "materials")), 1);
    cJSON_Delete(j);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"late\",\"budget\":{\"chunks\":1}}");
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 1); /* st now holds the files as they were on disk */
    /* removed from the library while subscribed: the stream still completes */
    cr_assert_eq(fx_rmtree(p), 0);
    usleep(250000);
    wsc_send_text(&c, "{\"type\":\"list\"}");
    j = expect_type(&c, "list");
    cr_expect_eq(cJSON_GetArraySize(cJSON_GetObjectItem(j, "materials")), 0);
    cJSON_Delete(j);
    wsc_send_text(&c, "{\"type\":\"budget\",\"material\":\"late\",\"budget\":{}}");
    run_until_complete(&c, &st, 2);
    cr_expect_eq(st.n_order, 3, "all 3 chunks, byte-exact, after the package was deleted");
    stream_free(&st);
    wsc_close(&c);
    srv_stop(&s);
}

/* Runs a built program with arguments; returns its exit status (-1 if it did not exit). */
static int run_prog(const char *prog, const char *const *args, char *out, size_t n)
{
    char bin[512];
    btfd_binary(bin, sizeof bin, prog);
    const char *argv[16] = {bin};
    int argc = 1;
    for (int i = 0; args[i] && argc < 15; i++)
        argv[argc++] = args[i];
    argv[argc] = NULL;
    int fds[2];
    cr_assert_eq(pipe(fds), 0);
    pid_t pid = fork();
    if (pid == 0) {
        dup2(fds[1], 1);
        dup2(fds[1], 2);
        close(fds[0]);
        close(fds[1]);
        execv(bin, (char *const *)argv);
        _exit(127);
    }
    close(fds[1]);
    size_t len = 0;
    ssize_t k;
    while (len < n - 1 && (k = read(fds[0], out + len, n - 1 - len)) > 0)
        len += (size_t)k;
    out[len] = 0;
    close(fds[0]);
    int status;
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

Test(server, command_line_errors)
{
    char out[4096];
    const char *none[] = {NULL};
    cr_expect_eq(run_prog("btfd", none, out, sizeof out), 2, "%s", out);
    cr_expect(strstr(out, "--library"), "%s", out);
    const char *badport[] = {"--library", g_lib, "--port", "http", NULL};
    cr_expect_eq(run_prog("btfd", badport, out, sizeof out), 2, "%s", out);
    const char *nolib[] = {"--library", "/nonexistent/btf-library", "--port", "0", NULL};
    cr_expect_eq(run_prog("btfd", nolib, out, sizeof out), 1, "%s", out);
    cr_expect(strstr(out, "/nonexistent/btf-library"), "message names the directory: %s", out);
}

Test(server, fuzz_corpus_replays_through_the_request_parser)
{
    char corpus[600], out[4096];
    const char *root = getenv("BTF_ROOT");
    snprintf(corpus, sizeof corpus, "%s/fuzz/corpus/request", root ? root : ".");
    const char *args[] = {corpus, NULL};
    cr_expect_eq(run_prog("fuzz_request_replay", args, out, sizeof out), 0, "%s", out);
    const char *n = strstr(out, "replay: ");
    cr_assert_not_null(n, "%s", out);
    cr_expect_geq(atoi(n + 8), 20, "the saved corpus has inputs: %s", out);
}

/* ================================================================ operations: health, metrics, signals, log */

/* Polls metric name until it equals want (TMO); returns the last value. */
static double metric_becomes(const srv *s, const char *name, double want)
{
    double v = NAN;
    for (long long end = fx_now_ms() + TMO; fx_now_ms() < end; usleep(20000))
        if ((v = metric(s, name)) == want)
            break;
    return v;
}

Test(server, healthz_and_metrics_follow_streams_and_scans)
{
    size_t total = make_simple(g_lib, "alpha", 3, 20000);
    srv s;
    srv_start(&s, g_lib, NULL);
    uint8_t *body;
    size_t n;
    cr_expect_eq(http_get(s.port, "/healthz", &body, &n), 200);
    cr_expect_str_eq((char *)body, "ok\n");
    free(body);
    cr_assert_eq(http_get(s.port, "/metrics", &body, &n), 200);
    metrics_well_formed((char *)body);
    free(body);
    cr_expect_eq(metric(&s, "btfd_connections_total"), 0);
    cr_expect_eq(metric(&s, "btfd_library_materials"), 1);
    cr_expect_eq(metric(&s, "btfd_library_bytes"), (double)total);
    cr_expect_eq(metric(&s, "btfd_draining"), 0);
    wsc c;
    open_ws(&c, &s);
    wsc_send_text(&c, "{\"type\":\"subscribe\",\"material\":\"alpha\"}");
    stream st = {.lib = g_lib};
    run_until_complete(&c, &st, 1);
    cr_expect_eq(metric(&s, "btfd_connections"), 1);
    cr_expect_eq(metric(&s, "btfd_connections_total"), 1);
    cr_expect_eq(metric(&s, "btfd_subscriptions"), 1);
    cr_expect_eq(metric(&s, "btfd_subscriptions_total"), 1);
    cr_expect_eq(metric(&s, "btfd_sent_chunks_total"), 3);
    cr_expect_eq(metric(&s, "btfd_sent_bytes_total"), (double)total);
    cr_expect_eq(metric(&s, "btfd_stalled_drops_total"), 0);
    stream_free(&st);
    wsc_close(&c);
    cr_expect_eq(metric_becomes(&s, "btfd_connections", 0), 0);
    cr_expect_eq(metric(&s, "btfd_subscriptions"), 0);
    /* a broken package: the next scan counts it */
    char p[600];
    snprintf(p, sizeof p, "%s/broken", g_lib);
    cr_assert_eq(mkdir(p, 0755), 0);
    snprintf(p, sizeof p, "%s/broken/manifest.json", g_lib);
    fx_write(p, "{\"format\":", 10);
    double before = metric(&s, "btfd_scan_errors_total");
    usleep(250000); /* on-demand rescans are rate limited to one per 200 ms */
    cr_expect_eq(http_get(s.port, "/materials", &body, &n), 200);
    free(body);
    cr_expect_eq(metric(&s, "btfd_scan_errors_total"), before + 1);
    srv_stop(&s);
}

/* SIGTERM: the listening socket closes at once (a new connection is refused, the
 * failure every proxy retries elsewhere); what was accepted before is served to the
 * end: a finished stream goes away with 1001, a busy one completes first, one that
 * subscribes during the drain is served, and an HTTP request or a WebSocket
 * handshake arriving on a connection accepted before is answered. */
/* A WebSocket handshake asking for the stream subprotocol, as a browser sends it. */
static const char UPGRADE_REQ[] =
    "GET /stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
    "Sec-WebSocket-Protocol: btf-stream.v1\r\n\r\n";

Test(server, sigterm_stops_listening_and_serves_what_was_accepted)
{
    size_t sizes[4] = {3u << 20, 3u << 20, 3u << 20, 3u << 20};
    const double lab[] = {4, 3, 2, 1};
    make_pkg(g_lib, "big", 4, 1, sizes, lab);
    make_simple(g_lib, "small", 2, 1000);
    srv s;
    srv_start(&s, g_lib, NULL);
    wsc idle, busy, quiet;
    open_ws(&idle, &s);
    wsc_send_text(&idle, "{\"type\":\"subscribe\",\"material\":\"small\"}");
    stream si = {.lib = g_lib};
    run_until_complete(&idle, &si, 1);
    char st_[128];
    cr_assert_eq(wsc_open(&busy, s.port, "btf-stream.v1", 131072, st_, sizeof st_), 0, "%s", st_);
    wsc_send_text(&busy, "{\"type\":\"subscribe\",\"material\":\"big\",\"budget\":{\"chunks\":1}}");
    stream sb = {.lib = g_lib};
    run_until_complete(&busy, &sb, 1);
    open_ws(&quiet, &s); /* handshake done, no subscribe yet */
    int http = tcp_connect(s.port), upgrade = tcp_connect(s.port); /* accepted, nothing sent yet */
    cr_assert(http >= 0 && upgrade >= 0);
    wsc_send_text(&busy, "{\"type\":\"budget\",\"material\":\"big\",\"budget\":{}}");
    usleep(200000); /* the server is now sending chunk 1 into a full socket */
    kill(s.pid, SIGTERM);
    char reason[128];
    cr_expect_eq(wait_close(&idle, reason, sizeof reason), 1001, "a finished stream goes away at once");
    wsc_close(&idle);
    /* a new connection is refused: nothing listens any more */
    int late = -1;
    for (int k = 0; k < 50 && (late = tcp_connect(s.port)) >= 0; k++) {
        close(late);
        usleep(20000);
    }
    cr_expect_lt(late, 0, "btfd still accepts connections while draining");
    /* requests on connections accepted before the drain are answered */
    size_t rn;
    char *r = fd_exchange(http, "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n", TMO,
                          "draining\n", &rn);
    cr_expect(strstr(r, " 503 ") && strstr(r, "draining"), "healthz during the drain: %s", r);
    free(r), close(http);
    r = fd_exchange(upgrade, UPGRADE_REQ, TMO, "\r\n\r\n", &rn);
    cr_expect(!strncmp(r, "HTTP/1.1 101", 12), "a handshake on an accepted connection: %s", r);
    free(r), close(upgrade);
    /* a stream that subscribes during the drain is served to its end */
    wsc_send_text(&quiet, "{\"type\":\"subscribe\",\"material\":\"small\"}");
    stream sq = {.lib = g_lib};
    run_until_complete(&quiet, &sq, 1);
    cr_expect_eq(wait_close(&quiet, reason, sizeof reason), 1001);
    wsc_close(&quiet);
    /* the busy stream completes, byte-exact, then goes away */
    run_until_complete(&busy, &sb, 2);
    cr_expect_eq(sb.n_order, 4);
    cr_expect_eq(wait_close(&busy, reason, sizeof reason), 1001);
    stream_free(&si);
    stream_free(&sb);
    stream_free(&sq);
    wsc_close(&busy);
    cr_expect_eq(srv_wait_exit(&s, TMO), 0, "btfd exits once the last stream is gone");
}

/* Waits until the kernel reports pid stopped (state T), so nothing it does races what follows. */
static void wait_stopped(pid_t pid)
{
    char path[64], st[512];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    for (int k = 0; k < 500; k++) {
        FILE *f = fopen(path, "r");
        size_t n = f ? fread(st, 1, sizeof st - 1, f) : 0;
        if (f)
            fclose(f);
        st[n] = 0;
        const char *paren = strrchr(st, ')');
        if (paren && paren[1] == ' ' && paren[2] == 'T')
            return;
        usleep(2000);
    }
    cr_assert_fail("btfd (pid %d) did not stop on SIGSTOP", (int)pid);
}

/* Connections the kernel completed but btfd had not accepted yet when SIGTERM came:
 * shutting the listener down would reset them (a proxy sees an established
 * connection reset, which it does not retry), so the drain takes them first. btfd
 * is stopped while they connect, so the drain runs before its loop could accept. */
Test(server, sigterm_serves_connections_still_in_the_listen_queue)
{
    make_simple(g_lib, "small", 2, 1000);
    srv s;
    const char *extra[] = {"--drain-seconds", "5", NULL};
    srv_start(&s, g_lib, extra);
    enum { N = 6 };
    int fd[N + 1];
    kill(s.pid, SIGSTOP);
    wait_stopped(s.pid);
    for (int i = 0; i <= N; i++) { /* the handshakes complete in the kernel; btfd sleeps */
        fd[i] = tcp_connect(s.port);
        cr_assert_geq(fd[i], 0);
    }
    kill(s.pid, SIGTERM);
    kill(s.pid, SIGCONT);
    size_t rn;
    for (int i = 0; i < N; i++) {
        char *r = fd_exchange(fd[i], UPGRADE_REQ, TMO, "\r\n\r\n", &rn);
        cr_expect(!strncmp(r, "HTTP/1.1 101", 12), "queued connection %d: \"%s\"", i, r);
        free(r);
    }
    char *r = fd_exchange(fd[N], "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n",
                          TMO, "draining\n", &rn);
    cr_expect(strstr(r, " 503 ") && strstr(r, "draining"), "healthz on a queued connection: \"%s\"", r);
    free(r);
    int late = tcp_connect(s.port);
    cr_expect_lt(late, 0, "btfd still accepts connections while draining");
    if (late >= 0)
        close(late);
    for (int i = 0; i <= N; i++)
        close(fd[i]);
    cr_expect_eq(srv_wait_exit(&s, TMO), 0, "btfd exits once the queued connections are gone");
}

Test(server, drain_deadline_closes_streams_that_do_not_finish)
{
    size_t sizes[2] = {8u << 20, 8u << 20};
    const double lab[] = {2, 1};
    size_t total = make_pkg(g_lib, "big", 2, 1, sizes, lab);
    srv s;
    const char *extra[] = {"--drain-seconds", "1", NULL};
    srv_start(&s, g_lib, extra);
    wsc slow;
    open_slow(&slow, &s, "big");
    usleep(200000);
    long long t0 = fx_now_ms();
    kill(s.pid, SIGTERM);
    cr_expect_eq(srv_wait_exit(&s, TMO), 0);
    long long dt = fx_now_ms() - t0;
    cr_expect(dt >= 900 && dt < 4000, "stopped %lld ms after SIGTERM (drain 1 s)", dt);
    size_t got = read_until_closed(&slow);
    cr_expect_lt(got, total);
    wsc_close(&slow);
}

Test(server, sighup_rescans_the_library)
{
    srv s;
    srv_start(&s, g_lib, NULL); /* --rescan-ms 0: no periodic rescans */
    cr_expect_eq(metric(&s, "btfd_library_materials"), 0);
    make_simple(g_lib, "late", 2, 100);
    usleep(300000);
    cr_expect_eq(metric(&s, "btfd_library_materials"), 0, "/metrics does not rescan");
    kill(s.pid, SIGHUP);
    cr_expect_eq(metric_becomes(&s, "btfd_library_materials", 1), 1, "SIGHUP did not rescan");
    expect_healthy(&s);
    srv_stop(&s);
}

/* 1 if line starts "YYYY-MM-DDTHH:MM:SS.mmmZ LEVEL btfd: " with a known level. */
static int log_line_ok(const char *line)
{
    int y, mo, d, h, mi, se, ms;
    char lv[8];
    return sscanf(line, "%4d-%2d-%2dT%2d:%2d:%2d.%3dZ %7s btfd: ", &y, &mo, &d, &h, &mi, &se, &ms, lv) == 8 &&
           y >= 2024 && (!strcmp(lv, "INFO") || !strcmp(lv, "WARN") || !strcmp(lv, "ERROR") || !strcmp(lv, "DEBUG"));
}

Test(server, one_timestamped_log_line_per_connection_and_error)
{
    make_simple(g_lib, "alpha", 2, 1000);
    char log[400];
    snprintf(log, sizeof log, "%s/btfd.log", g_root);
    g_stderr = log;
    srv s;
    srv_start(&s, g_lib, NULL);
    g_stderr = NULL;
    for (int i = 0; i < 2; i++) {
        wsc c;
        open_ws(&c, &s);
        wsc_send_text(&c, i ? "{\"type\":\"subscribe\",\"material\":\"nosuch\"}" : "{\"type\":\"ping\"}");
        cJSON_Delete(expect_type(&c, i ? "error" : "pong"));
        wsc_close(&c);
    }
    srv_stop(&s);
    size_t n;
    char *text = fx_read(log, &n);
    cr_assert_not_null(text);
    int conns = 0, errors = 0, lines = 0;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        lines++;
        cr_expect(log_line_ok(line), "not a log line: %s", line);
        cr_expect(!strstr(line, " DEBUG "), "debug line without -v: %s", line);
        conns += strstr(line, "INFO btfd: conn ") && strstr(line, " from 127.0.0.1: ") != NULL;
        errors += strstr(line, "error unknown_material") != NULL;
    }
    cr_expect_eq(conns, 2, "one line per connection (%d lines)", lines);
    cr_expect_eq(errors, 1, "one line per error");
    free(text);
}

/* ================================================================ HTTP caching: immutable package files */

/* Value of response header name (lower case, with the colon) into buf; "" if absent. */
static const char *resp_header(const char *head, const char *name, char *buf, size_t n)
{
    const char *h = find_nocase(head, name);
    buf[0] = 0;
    if (h) {
        h += strlen(name);
        while (*h == ' ')
            h++;
        snprintf(buf, n, "%.*s", (int)strcspn(h, "\r\n"), h);
    }
    return buf;
}

/* The list's "files" base of material name ("/materials/NAME/ETAG/"). */
static void files_base(int port, const char *name, char *base, size_t n)
{
    uint8_t *body;
    size_t len;
    cr_assert_eq(http_get(port, "/materials", &body, &len), 200);
    cJSON *j = cJSON_Parse((char *)body);
    free(body);
    const cJSON *m;
    base[0] = 0;
    cJSON_ArrayForEach(m, cJSON_GetObjectItem(j, "materials"))
        if (!strcmp(jstr(m, "name"), name))
            snprintf(base, n, "%s", jstr(m, "files"));
    cJSON_Delete(j);
    cr_assert(base[0], "no files base for %s", name);
}

Test(server, package_files_are_immutable_with_strong_etags_and_byte_ranges)
{
    const size_t sizes[] = {150000, 7000, 0};
    const double lab[] = {9, 5, 3};
    make_pkg(g_lib, "alpha", 3, 1, sizes, lab);
    srv s;
    srv_start(&s, g_lib, NULL);
    char base[300], url[400], head[4096], v[200], etag[200], hdr[300];
    files_base(s.port, "alpha", base, sizeof base);
    uint8_t *body, *disk;
    size_t n, dn;
    for (int c = 0; c < 3; c++) {
        snprintf(url, sizeof url, "%sc%d_f0.bin", base, c);
        cr_assert_eq(http_req(s.port, url, NULL, head, sizeof head, &body, &n), 200, "%s", url);
        char path[700];
        snprintf(path, sizeof path, "%s/alpha/c%d_f0.bin", g_lib, c);
        disk = (uint8_t *)fx_read(path, &dn);
        cr_expect(n == dn && !memcmp(body, disk, n), "%s: %zu bytes, file has %zu", url, n, dn);
        free(disk);
        free(body);
        cr_expect_str_eq(resp_header(head, "cache-control:", v, sizeof v), "public, max-age=31536000, immutable");
        resp_header(head, "etag:", etag, sizeof etag);
        cr_expect(etag[0] == '"' && etag[strlen(etag) - 1] == '"' && strncmp(etag, "W/", 2), "strong etag: %s", etag);
        snprintf(hdr, sizeof hdr, "If-None-Match: %s\r\n", etag);
        cr_expect_eq(http_req(s.port, url, hdr, head, sizeof head, &body, &n), 304, "revalidation of %s", url);
        cr_expect_eq(n, 0);
        free(body);
    }
    /* HEAD: the headers of a GET, no body */
    snprintf(url, sizeof url, "HEAD %sc0_f0.bin", base);
    cr_expect_eq(http_req(s.port, url, NULL, head, sizeof head, &body, &n), 200);
    cr_expect_str_eq(resp_header(head, "content-length:", v, sizeof v), "150000");
    cr_expect_str_eq(resp_header(head, "cache-control:", v, sizeof v), "public, max-age=31536000, immutable");
    cr_expect_eq(n, 0, "HEAD sent a body");
    free(body);
    /* the manifest too, byte for byte */
    snprintf(url, sizeof url, "%smanifest.json", base);
    cr_expect_eq(http_get(s.port, url, &body, &n), 200);
    char mpath[700];
    snprintf(mpath, sizeof mpath, "%s/alpha/manifest.json", g_lib);
    disk = (uint8_t *)fx_read(mpath, &dn);
    cr_expect(n == dn && !memcmp(body, disk, n), "manifest differs");
    free(disk);
    free(body);
    /* byte ranges: a middle, a suffix, an open end; beyond the end 416; If-Range of another version: all */
    snprintf(url, sizeof url, "%sc0_f0.bin", base);
    char path0[700];
    snprintf(path0, sizeof path0, "%s/alpha/c0_f0.bin", g_lib);
    disk = (uint8_t *)fx_read(path0, &dn);
    struct { const char *range; size_t a, b; } rs[] = {{"bytes=100-199", 100, 199}, {"bytes=-10", 149990, 149999},
                                                       {"bytes=149000-", 149000, 149999}, {"bytes=0-999999", 0, 149999}};
    for (size_t i = 0; i < sizeof rs / sizeof rs[0]; i++) {
        snprintf(hdr, sizeof hdr, "Range: %s\r\n", rs[i].range);
        cr_expect_eq(http_req(s.port, url, hdr, head, sizeof head, &body, &n), 206, "%s", rs[i].range);
        char want[80];
        snprintf(want, sizeof want, "bytes %zu-%zu/150000", rs[i].a, rs[i].b);
        cr_expect_str_eq(resp_header(head, "content-range:", v, sizeof v), want);
        cr_expect(n == rs[i].b - rs[i].a + 1 && !memcmp(body, disk + rs[i].a, n), "%s: bytes differ", rs[i].range);
        free(body);
    }
    cr_expect_eq(http_req(s.port, url, "Range: bytes=150000-\r\n", head, sizeof head, &body, &n), 416);
    cr_expect_str_eq(resp_header(head, "content-range:", v, sizeof v), "bytes */150000");
    free(body);
    cr_expect_eq(http_req(s.port, url, "Range: bytes=0-9\r\nIf-Range: \"other\"\r\n", head, sizeof head, &body, &n), 200);
    cr_expect_eq(n, 150000);
    free(body);
    free(disk);
    /* not this package's current etag, not its file, not a name in the index: 404 */
    const char *bad[] = {"/materials/alpha/0123456789abcdef/c0_f0.bin", "/materials/alpha/c0_f0.bin", "/materials/nosuch/x/y"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        cr_expect_eq(http_get(s.port, bad[i], &body, &n), 404, "%s", bad[i]);
        free(body);
    }
    const char *tails[] = {"nosuch.bin", "..%2fbeta%2fc0_f0.bin", "../../alpha/manifest.json", ".hidden"};
    for (size_t i = 0; i < sizeof tails / sizeof tails[0]; i++) {
        snprintf(url, sizeof url, "%s%s", base, tails[i]);
        int st = http_get(s.port, url, &body, &n);
        cr_expect(st == 404 || st == 400 || st == 403 || (st == 200 && strstr(tails[i], "manifest")), "%s gave %d", url, st);
        free(body);
    }
    /* a replaced package: the old URLs are gone, the new ones work */
    char old[400];
    snprintf(old, sizeof old, "%sc1_f0.bin", base);
    char dir[600];
    snprintf(dir, sizeof dir, "%s/alpha", g_lib);
    cr_assert_eq(fx_rmtree(dir), 0);
    const double lab2[] = {8, 4, 2};
    make_pkg(g_lib, "alpha", 3, 1, sizes, lab2);
    usleep(250000);
    char base2[300];
    files_base(s.port, "alpha", base2, sizeof base2);
    cr_expect_str_neq(base, base2);
    cr_expect_eq(http_get(s.port, old, &body, &n), 404, "old etag still served");
    free(body);
    snprintf(url, sizeof url, "%sc1_f0.bin", base2);
    cr_expect_eq(http_get(s.port, url, &body, &n), 200);
    free(body);
    srv_stop(&s);
}

/* src gzipped by zlib (a gzip member, as `gzip` writes it); malloc'd, its size in *n. */
static uint8_t *gzip_bytes(const char *src, size_t len, size_t *n)
{
    z_stream z = {0};
    cr_assert_eq(deflateInit2(&z, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    size_t cap = deflateBound(&z, (uLong)len) + 32;
    uint8_t *out = malloc(cap);
    z.next_in = (Bytef *)src, z.avail_in = (uInt)len, z.next_out = out, z.avail_out = (uInt)cap;
    cr_assert_eq(deflate(&z, Z_FINISH), Z_STREAM_END);
    *n = z.total_out;
    deflateEnd(&z);
    return out;
}

/* A file mount sends FILE.gz (its bytes as they are, Content-Encoding: gzip) to a request
 * that accepts gzip and FILE to every other; both say Vary: Accept-Encoding and
 * revalidate by their own ETags; a .gz older than its FILE, or without one, is not sent. */
Test(server, client_files_go_gzipped_to_a_browser_that_accepts_gzip)
{
    char client[300], shaders[300], text[4096] = "", head[4096], v[200], path[600];
    mount_dirs(client, shaders);
    for (int i = 0; i < 100; i++) /* 100 lines of script, compressible as a bundle is */
        snprintf(text + strlen(text), sizeof text - strlen(text), "export const v%d = %d;\n", i, i * i);
    size_t len = strlen(text), gzn, stale_n;
    uint8_t *gz = gzip_bytes(text, len, &gzn), *stale = gzip_bytes("export {};\n", 11, &stale_n), *body;
    fx_put_text(client, "app.js", text);
    snprintf(path, sizeof path, "%s/app.js.gz", client);
    fx_write(path, gz, gzn);
    fx_put_text(client, "old.js", "export const fresh = 1;\n");
    snprintf(path, sizeof path, "%s/old.js.gz", client);
    fx_write(path, stale, stale_n);
    struct timespec past[2] = {{1000000000, 0}, {1000000000, 0}}; /* 2001: older than old.js */
    cr_assert_eq(utimensat(AT_FDCWD, path, past, 0), 0);
    snprintf(path, sizeof path, "%s/only.js.gz", client);
    fx_write(path, stale, stale_n);
    srv s;
    const char *extra[] = {"--client", client, "--shaders", shaders, NULL};
    srv_start(&s, g_lib, extra);
    size_t n;
    cr_assert_eq(http_req(s.port, "/app.js", "Accept-Encoding: gzip, deflate, br\r\n", head, sizeof head, &body, &n), 200);
    cr_expect(n == gzn && !memcmp(body, gz, n), "the .gz as it is: %zu of %zu bytes", n, gzn);
    cr_expect_str_eq(resp_header(head, "content-encoding:", v, sizeof v), "gzip");
    cr_expect(find_nocase(head, "content-type: text/javascript"), "the type of app.js: %s", head);
    cr_expect(find_nocase(head, "vary: accept-encoding"), "%s", head);
    char etag_gz[200], hdr[300];
    resp_header(head, "etag:", etag_gz, sizeof etag_gz);
    free(body);
    snprintf(hdr, sizeof hdr, "Accept-Encoding: gzip\r\nIf-None-Match: %s\r\n", etag_gz);
    cr_expect_eq(http_req(s.port, "/app.js", hdr, head, sizeof head, &body, &n), 304, "revalidates: %s", head);
    free(body);
    const char *plain[] = {NULL, "Accept-Encoding: br, deflate\r\n", "Accept-Encoding: identity\r\n"};
    for (int i = 0; i < 3; i++) {
        cr_assert_eq(http_req(s.port, "/app.js", plain[i], head, sizeof head, &body, &n), 200);
        cr_expect(n == len && !memcmp(body, text, n), "%s: the file itself", plain[i] ? plain[i] : "no header");
        cr_expect(!find_nocase(head, "content-encoding"), "%s", head);
        cr_expect(find_nocase(head, "vary: accept-encoding"), "%s", head);
        cr_expect_str_neq(resp_header(head, "etag:", v, sizeof v), etag_gz, "each form has its own etag");
        free(body);
    }
    cr_assert_eq(http_req(s.port, "/old.js", "Accept-Encoding: gzip\r\n", head, sizeof head, &body, &n), 200);
    cr_expect(strstr((char *)body, "fresh") && !find_nocase(head, "content-encoding"), "a stale .gz: %s", body);
    free(body);
    cr_expect_eq(http_req(s.port, "/only.js", "Accept-Encoding: gzip\r\n", head, sizeof head, &body, &n), 404);
    free(body);
    free(gz);
    free(stale);
    srv_stop(&s);
}

Test(server, list_thumbnails_and_client_files_revalidate_by_etag)
{
    make_simple(g_lib, "alpha", 2, 100);
    char p[600];
    snprintf(p, sizeof p, "%s/alpha/thumbnail.png", g_lib);
    fx_write(p, "not really a png", 16);
    char client[300];
    snprintf(client, sizeof client, "%s/client", g_root);
    cr_assert_eq(mkdir(client, 0755), 0);
    snprintf(p, sizeof p, "%s/index.html", client);
    fx_write(p, "<p>hi</p>\n", 10);
    srv s;
    const char *extra[] = {"--client", client, NULL};
    srv_start(&s, g_lib, extra);
    const char *urls[] = {"/materials", "/materials/alpha/thumbnail.png", "/"};
    for (size_t i = 0; i < 3; i++) {
        char head[4096], etag[200], cc[200], hdr[300];
        uint8_t *body;
        size_t n;
        cr_assert_eq(http_req(s.port, urls[i], NULL, head, sizeof head, &body, &n), 200, "%s", urls[i]);
        free(body);
        resp_header(head, "etag:", etag, sizeof etag);
        resp_header(head, "cache-control:", cc, sizeof cc);
        cr_expect(etag[0], "%s has no etag", urls[i]);
        cr_expect(!strstr(cc, "no-store") && !strstr(cc, "immutable") && strstr(cc, "max-age="), "%s: %s", urls[i], cc);
        snprintf(hdr, sizeof hdr, "If-None-Match: %s\r\n", etag);
        cr_expect_eq(http_req(s.port, urls[i], hdr, head, sizeof head, &body, &n), 304, "%s", urls[i]);
        free(body);
        cr_expect_eq(http_req(s.port, urls[i], "If-None-Match: \"other\"\r\n", head, sizeof head, &body, &n), 200);
        free(body);
    }
    /* a new package changes the list's etag */
    char head[4096], e1[200], e2[200];
    uint8_t *body;
    size_t n;
    http_req(s.port, "/materials", NULL, head, sizeof head, &body, &n);
    free(body);
    resp_header(head, "etag:", e1, sizeof e1);
    make_simple(g_lib, "beta", 1, 100);
    usleep(250000);
    http_req(s.port, "/materials", NULL, head, sizeof head, &body, &n);
    free(body);
    cr_expect_str_neq(e1, resp_header(head, "etag:", e2, sizeof e2));
    cr_expect_gt(metric(&s, "btfd_http_not_modified_total"), 0);
    srv_stop(&s);
}

/* ---------------------------------------------------------------- private libraries */

/* A token or the nginx md5 argument computed by Python's hmac and hashlib (apart from
 * btfd's OpenSSL code): kind "token" -> v1:SCOPE:EXPIRES:SIG, "md5" -> the md5 argument
 * of material SCOPE; secret from the file. */
static void py_sign(const char *kind, const char *secret_file, const char *scope, long long expires, char *out,
                    size_t n)
{
    char cmd[1200];
    snprintf(cmd, sizeof cmd,
             "python3 -c 'import base64,hashlib,hmac,sys\n"
             "k=open(sys.argv[1],\"rb\").read().rstrip(b\"\\n\")\n"
             "b=lambda d: base64.urlsafe_b64encode(d).rstrip(b\"=\").decode()\n"
             "s,e=sys.argv[3],sys.argv[4]\n"
             "if sys.argv[2]==\"token\": print(\"v1:%%s:%%s:%%s\"%%(s,e,b(hmac.new(k,(\"btf-token-v1:%%s:%%s\"%%(s,e)).encode(),hashlib.sha256).digest())))\n"
             "else: print(b(hashlib.md5(e.encode()+b\"/materials/\"+s.encode()+b\" \"+k).digest()))' %s %s '%s' %lld",
             secret_file, kind, scope, expires);
    FILE *p = popen(cmd, "r");
    cr_assert(p);
    cr_assert(fgets(out, (int)n, p), "python3 printed nothing");
    pclose(p);
    out[strcspn(out, "\n")] = 0;
}

/* Subscribes to name with token (NULL: none) on a fresh connection; the reply's type
 * and, for an error, its code into code. */
static void subscribe_with(const srv *s, const char *name, const char *token, char *type, char *code)
{
    wsc c;
    open_ws(&c, s);
    char msg[600];
    if (token)
        snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"%s\",\"token\":\"%s\"}", name, token);
    else
        snprintf(msg, sizeof msg, "{\"type\":\"subscribe\",\"material\":\"%s\"}", name);
    cr_assert_eq(wsc_send_text(&c, msg), 0);
    cJSON *j = recv_json(&c);
    while (!strcmp(jstr(j, "type"), "hello")) {
        cJSON_Delete(j);
        j = recv_json(&c);
    }
    strcpy(type, jstr(j, "type"));
    strcpy(code, jstr(j, "code"));
    cJSON_Delete(j);
    wsc_close(&c);
}

/* A private library (--token-secret-file): the list and thumbnails stay public; a
 * subscription and every package file need a token signed with the secret for that
 * material (or a prefix scope), unexpired; tokens made by Python here (not by btfd),
 * and the nginx secure_link form of the files. Missing, expired, tampered, foreign
 * and other-scope tokens get clear refusals (error frames, 403 with the reason), the
 * connection stays usable, and btfd_forbidden_total counts them. --make-token makes
 * the same token as Python. The secret never appears on a command line. */
Test(server, private_library_needs_signed_unexpired_tokens)
{
    const size_t sizes[] = {5000, 3000, 0};
    const double lab[] = {5, 3, 0};
    make_pkg(g_lib, "shoe-red", 2, 1, sizes, lab);
    make_pkg(g_lib, "bag", 2, 1, sizes, lab);
    char secret[400], foreign[400];
    snprintf(secret, sizeof secret, "%s/secret", g_root);
    snprintf(foreign, sizeof foreign, "%s/foreign", g_root);
    fx_write(secret, "correct horse battery staple 42\n", 32);
    fx_write(foreign, "another secret of thirty bytes!", 31);
    const char *extra[] = {"--token-secret-file", secret, NULL};
    srv s;
    srv_start(&s, g_lib, extra);
    long long now = (long long)time(NULL);
    char good[300], prefix[300], expired[300], other[300], alien[300], tampered[300], type[64], code[64];
    py_sign("token", secret, "shoe-red", now + 600, good, sizeof good);
    py_sign("token", secret, "shoe-*", now + 600, prefix, sizeof prefix);
    py_sign("token", secret, "shoe-red", now - 5, expired, sizeof expired);
    py_sign("token", secret, "bag", now + 600, other, sizeof other);
    py_sign("token", foreign, "shoe-red", now + 600, alien, sizeof alien);
    strcpy(tampered, good);
    tampered[strlen(tampered) - 3] ^= 1; /* one bit of the signature */

    subscribe_with(&s, "shoe-red", good, type, code);
    cr_expect_str_eq(type, "manifest", "a good token: %s %s", type, code);
    subscribe_with(&s, "shoe-red", prefix, type, code);
    cr_expect_str_eq(type, "manifest", "a prefix token: %s %s", type, code);
    const char *bad[5] = {NULL, expired, other, alien, tampered};
    const char *want[5] = {"forbidden", "token_expired", "forbidden", "forbidden", "forbidden"};
    for (int i = 0; i < 5; i++) {
        subscribe_with(&s, "shoe-red", bad[i], type, code);
        cr_expect_str_eq(type, "error", "case %d: %s", i, type);
        cr_expect_str_eq(code, want[i], "case %d", i);
    }

    /* HTTP: the list is public, a file needs ?token= or the nginx form */
    char base[300], url[900], md5[64], md5_old[64];
    files_base(s.port, "shoe-red", base, sizeof base);
    uint8_t *body;
    size_t n;
    snprintf(url, sizeof url, "%smanifest.json", base);
    cr_expect_eq(http_get(s.port, url, &body, &n), 403, "a private file without a token");
    cr_expect(strstr((char *)body, "token"), "the 403 says why: %s", body);
    free(body);
    snprintf(url, sizeof url, "%smanifest.json?token=%s", base, good);
    cr_expect_eq(http_get(s.port, url, &body, &n), 200, "with the token");
    free(body);
    snprintf(url, sizeof url, "%smanifest.json?token=%s", base, other);
    cr_expect_eq(http_get(s.port, url, &body, &n), 403, "another material's token");
    free(body);
    py_sign("md5", secret, "shoe-red", now + 600, md5, sizeof md5);
    py_sign("md5", secret, "shoe-red", now - 5, md5_old, sizeof md5_old);
    snprintf(url, sizeof url, "%smanifest.json?md5=%s&expires=%lld", base, md5, now + 600);
    cr_expect_eq(http_get(s.port, url, &body, &n), 200, "the nginx form");
    free(body);
    snprintf(url, sizeof url, "%smanifest.json?md5=%s&expires=%lld", base, md5, now + 601);
    cr_expect_eq(http_get(s.port, url, &body, &n), 403, "the nginx form with another expiry");
    free(body);
    snprintf(url, sizeof url, "%smanifest.json?md5=%s&expires=%lld", base, md5_old, now - 5);
    cr_expect_eq(http_get(s.port, url, &body, &n), 403, "an expired nginx form");
    cr_expect(strstr((char *)body, "expired"), "%s", body);
    free(body);
    cr_expect_geq(metric(&s, "btfd_forbidden_total"), 9);
    srv_stop(&s);

    /* --make-token: the same token Python makes for the same second */
    char out[600];
    const char *args[] = {"--token-secret-file", secret, "--make-token", "shoe-red", "--ttl", "100", NULL};
    long long t0 = (long long)time(NULL);
    cr_assert_eq(run_prog("btfd", args, out, sizeof out), 0, "%s", out);
    char want_tok[300], want_md5[64];
    py_sign("token", secret, "shoe-red", t0 + 100, want_tok, sizeof want_tok);
    py_sign("md5", secret, "shoe-red", t0 + 100, want_md5, sizeof want_md5);
    if (time(NULL) == t0) { /* the same second: the same expiry */
        cr_expect(strstr(out, want_tok), "btfd made %s, Python %s", out, want_tok);
        cr_expect(strstr(out, want_md5), "btfd made %s, Python %s", out, want_md5);
    }
    const char *short_secret[] = {"--token-secret-file", foreign, "--make-token", "no/such", NULL};
    cr_expect_eq(run_prog("btfd", short_secret, out, sizeof out), 2, "a bad scope: %s", out);
    fx_write(foreign, "short", 5);
    const char *tiny[] = {"--token-secret-file", foreign, "--make-token", "bag", NULL};
    cr_expect_eq(run_prog("btfd", tiny, out, sizeof out), 1, "a 5-byte secret: %s", out);
    cr_expect(strstr(out, "16"), "%s", out);
}
