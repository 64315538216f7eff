/* btfd_token.h - signed, expiring access to a private library (doc/deploy.md,
 * "Private libraries").
 *
 *     btfd_token_key k;
 *     if (btfd_token_load("/etc/btfd/secret", &k, &err) != BTF_OK) ...
 *     char t[BTFD_TOKEN_MAX];
 *     btfd_token_make(&k, "knit", time(NULL) + 3600, t, sizeof t);     // a page owner's backend
 *     btfd_token_verdict v = btfd_token_check(&k, t, "knit", time(NULL)); // btfd
 *
 * A token is "v1:SCOPE:EXPIRES:SIG": SCOPE a material name, or a name prefix ending
 * in '*' ("shoes-*"; "*" alone: every material); EXPIRES unix seconds; SIG the
 * unpadded base64url of HMAC-SHA256(secret, "btf-token-v1:SCOPE:EXPIRES"). The
 * nginx form (ngx_http_secure_link_module, whose stock build has MD5 only) signs
 * one material's files: md5 = unpadded base64url of MD5(EXPIRES "/materials/" NAME
 * " " secret), sent as ?md5=..&expires=.. so nginx in front can check the same URL.
 * Signatures are compared in constant time. Pure functions: no I/O but _load.
 */
#ifndef BTFD_TOKEN_H
#define BTFD_TOKEN_H

#include <stddef.h>
#include <stdint.h>

#include "btf.h"

#define BTFD_TOKEN_MAX 256        /* longest token, bytes (with its NUL) */
#define BTFD_TOKEN_SECRET_MIN 16  /* shortest secret, bytes */
#define BTFD_TOKEN_SECRET_MAX 256 /* longest secret, bytes */

/* The shared secret; owned by the server, lives for the process. */
typedef struct btfd_token_key {
    unsigned char secret[BTFD_TOKEN_SECRET_MAX];
    size_t len; /* 0: no key (the library is public) */
} btfd_token_key;

typedef enum btfd_token_verdict {
    BTFD_TOKEN_OK = 0,
    BTFD_TOKEN_MISSING,   /* no token given */
    BTFD_TOKEN_MALFORMED, /* not v1:SCOPE:EXPIRES:SIG */
    BTFD_TOKEN_EXPIRED,   /* EXPIRES is past */
    BTFD_TOKEN_SCOPE,     /* signed for other materials */
    BTFD_TOKEN_SIGNATURE  /* not signed with this secret (tampered or foreign) */
} btfd_token_verdict;

/* Reads the secret from a file (the whole file less one trailing newline);
 * BTFD_TOKEN_SECRET_MIN..MAX bytes, else BTF_ERR_FORMAT. */
btf_result btfd_token_load(const char *path, btfd_token_key *k, btf_error *err);
/* A token for scope until expires into out; 0, or -1 if scope is no valid scope or
 * out is too small. */
int btfd_token_make(const btfd_token_key *k, const char *scope, int64_t expires, char *out, size_t n);
/* Whether token grants material at time now. */
btfd_token_verdict btfd_token_check(const btfd_token_key *k, const char *token, const char *material, int64_t now);
/* The nginx form for material's files until expires: the md5 argument into out
 * (23 bytes with its NUL); 0, or -1 if n is too small. */
int btfd_token_make_md5(const btfd_token_key *k, const char *material, int64_t expires, char *out, size_t n);
/* Whether md5 and expires (the query arguments, as text) grant material at now. */
btfd_token_verdict btfd_token_check_md5(const btfd_token_key *k, const char *md5, const char *expires,
                                        const char *material, int64_t now);
/* A short stable code ("expired", "forbidden", ...) and a sentence for a verdict. */
const char *btfd_token_code(btfd_token_verdict v);
const char *btfd_token_text(btfd_token_verdict v);

#endif
