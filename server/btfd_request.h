/* btfd_request.h - parser for the client's text messages (btf-stream.v1).
 *
 * Usage:
 *     btfd_request rq;
 *     char why[160];
 *     btfd_req_status s = btfd_request_parse(text, len, &rq, why, sizeof why);
 *     if (s != BTFD_REQ_OK) send_error(btfd_req_status_code(s), why);
 *
 * A pure function: no I/O, no globals, no allocation that outlives the call.
 * It validates shape and ranges only; whether a material exists is decided by
 * the caller's library index (names are never used as paths).
 * Limitations: messages over BTFD_MSG_MAX bytes, raw or escaped NUL bytes and
 * non-object roots are refused; unknown keys are ignored (forward compatible).
 */
#ifndef BTFD_REQUEST_H
#define BTFD_REQUEST_H

#include <stddef.h>
#include <stdint.h>

#define BTFD_MSG_MAX 16384   /* largest accepted client message, bytes */
#define BTFD_NAME_MAX 128    /* longest material name, bytes */
#define BTFD_HAVE_MAX 1024   /* most chunk indices in one "have" list */
#define BTFD_CHUNK_MAX 65536 /* chunk indices are below this */
#define BTFD_ETAG_MAX 64     /* longest etag string */
#define BTFD_REQ_TOKEN_MAX 255 /* longest "token" string (btfd_token.h) */
#define BTFD_WINDOW_MIN 16384        /* smallest flow-control window a client may set, bytes */
#define BTFD_WINDOW_MAX (1 << 30)    /* largest */

typedef enum btfd_req_type {
    BTFD_REQ_LIST = 1,    /* {"type":"list"}: rescan (rate limited) and list the library */
    BTFD_REQ_SUBSCRIBE,   /* {"type":"subscribe","material":..,"budget":{..},"have":[..],"etag":..,"manifest_kept":..,"token":..} */
    BTFD_REQ_BUDGET,      /* {"type":"budget","material":..,"budget":{..}} */
    BTFD_REQ_UNSUBSCRIBE, /* {"type":"unsubscribe","material":..} */
    BTFD_REQ_PING,        /* {"type":"ping"}: answered with {"type":"pong"} */
    BTFD_REQ_ACK          /* {"type":"ack","received":R,"window":W}: flow control, no reply */
} btfd_req_type;

typedef enum btfd_req_status {
    BTFD_REQ_OK = 0,
    BTFD_REQ_TOO_LARGE,    /* over BTFD_MSG_MAX */
    BTFD_REQ_BAD_JSON,     /* not JSON, not an object, or contains NUL */
    BTFD_REQ_BAD_TYPE,     /* "type" missing or not a string */
    BTFD_REQ_UNKNOWN_TYPE, /* "type" is a string this version does not know */
    BTFD_REQ_BAD_NAME,     /* "material" missing, empty, too long or not [A-Za-z0-9._-] */
    BTFD_REQ_BAD_FIELD     /* budget / have / etag / seq of the wrong type or range */
} btfd_req_status;

/* Per-material budget: a prefix of the manifest's chunk order. Value type.
 * -1 (or a negative error) means "no limit" for that field. */
typedef struct btfd_budget {
    int64_t max_chunks; /* send at most this many chunks (0 pauses the stream) */
    int64_t max_bytes;  /* send chunks while the running total stays within this */
    double max_error;   /* stop after the first chunk whose error is <= this */
    double pixels;      /* device pixels one repeat of the material spans in the view (-1: none):
                           the chunks that view needs (btf_lod_select of width / pixels) */
    double threshold;   /* with pixels: visibility threshold (-1: BTF_LOD_THRESHOLD) */
} btfd_budget;

/* One parsed message; caller-owned value (about 4.5 KiB), valid until reused. */
typedef struct btfd_request {
    btfd_req_type type;
    int has_seq;
    int64_t seq;                      /* client's correlation number, echoed back */
    char material[BTFD_NAME_MAX + 1]; /* validated name, "" for list/ping */
    int has_budget;
    btfd_budget budget;               /* all "no limit" when has_budget is 0 */
    int n_have;
    uint32_t have[BTFD_HAVE_MAX];     /* chunk indices the client already holds */
    char etag[BTFD_ETAG_MAX + 1];     /* etag of the manifest the "have" refers to */
    int manifest_kept;                /* subscribe: the client holds the manifest of etag (omit it when resumed) */
    char token[BTFD_REQ_TOKEN_MAX + 1]; /* subscribe: the access token of a private library, "" none */
    int64_t received;                 /* ack: binary message bytes received on the connection */
    int64_t window;                   /* ack: 0 no window, else the most unacknowledged bytes; -1 unchanged */
} btfd_request;

/* Parses one text message of len bytes (need not be NUL-terminated). On
 * failure fills why (if non-NULL) with a human-readable reason. */
btfd_req_status btfd_request_parse(const char *buf, size_t len, btfd_request *out,
                                   char *why, size_t why_len);

/* Stable machine-readable code of a status, e.g. "bad_json". */
const char *btfd_req_status_code(btfd_req_status s);

/* 1 if name is a valid material name (1..BTFD_NAME_MAX of [A-Za-z0-9._-], not starting with '.'). */
int btfd_name_valid(const char *name, size_t len);

/* 1 and the value in *v when item is an integer JSON number in [lo, hi], else 0. */
struct cJSON;
int btfd_json_int(const struct cJSON *item, double lo, double hi, int64_t *v);

/* The budget with every limit off. */
btfd_budget btfd_budget_unlimited(void);

#endif
