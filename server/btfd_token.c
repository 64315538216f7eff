/* btfd_token.c - signed, expiring access (see btfd_token.h): HMAC-SHA256 tokens
 * and the nginx secure_link MD5 form, through OpenSSL's libcrypto. */
#include "btfd_token.h"
#include "btfd_request.h"

#include <errno.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/md5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "btf_common.h"

btf_result btfd_token_load(const char *path, btfd_token_key *k, btf_error *err)
{
    memset(k, 0, sizeof *k);
    FILE *f = fopen(path, "rb");
    if (!f)
        return btf_fail(err, BTF_ERR_IO, "%s: cannot open the token secret (%s)", path, strerror(errno));
    unsigned char buf[BTFD_TOKEN_SECRET_MAX + 2];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    if (n > 0 && buf[n - 1] == '\n')
        n--;
    if (n > 0 && buf[n - 1] == '\r')
        n--;
    if (n < BTFD_TOKEN_SECRET_MIN || n > BTFD_TOKEN_SECRET_MAX)
        return btf_fail(err, BTF_ERR_FORMAT, "%s: the token secret must be %d to %d bytes (has %zu%s)", path,
                        BTFD_TOKEN_SECRET_MIN, BTFD_TOKEN_SECRET_MAX, n, n > BTFD_TOKEN_SECRET_MAX ? " or more" : "");
    memcpy(k->secret, buf, n);
    k->len = n;
    OPENSSL_cleanse(buf, sizeof buf);
    return BTF_OK;
}

/* Unpadded base64url of n bytes into out (room for 4 * ceil(n / 3) + 1). */
static void b64url(const unsigned char *in, size_t n, char *out)
{
    static const char a[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";
    size_t o = 0;
    for (size_t i = 0; i < n; i += 3) {
        unsigned v = (unsigned)in[i] << 16 | (i + 1 < n ? (unsigned)in[i + 1] << 8 : 0) | (i + 2 < n ? in[i + 2] : 0);
        out[o++] = a[v >> 18 & 63];
        out[o++] = a[v >> 12 & 63];
        if (i + 1 < n)
            out[o++] = a[v >> 6 & 63];
        if (i + 2 < n)
            out[o++] = a[v & 63];
    }
    out[o] = '\0';
}

/* 1 if s is a scope: a material name, or a name prefix (possibly empty) and '*'. */
static int scope_valid(const char *s)
{
    size_t n = strlen(s);
    if (n > 0 && s[n - 1] == '*')
        return n == 1 || btfd_name_valid(s, n - 1);
    return btfd_name_valid(s, n);
}

static int scope_grants(const char *scope, const char *material)
{
    size_t n = strlen(scope);
    if (n > 0 && scope[n - 1] == '*')
        return strncmp(scope, material, n - 1) == 0;
    return strcmp(scope, material) == 0;
}

/* SIG of scope and expires (text) into out (44 bytes). */
static void sign(const btfd_token_key *k, const char *scope, const char *expires, char out[44])
{
    char msg[BTFD_TOKEN_MAX + 32];
    int len = snprintf(msg, sizeof msg, "btf-token-v1:%s:%s", scope, expires);
    unsigned char mac[EVP_MAX_MD_SIZE];
    unsigned mlen = 0;
    HMAC(EVP_sha256(), k->secret, (int)k->len, (const unsigned char *)msg, (size_t)len, mac, &mlen);
    b64url(mac, mlen, out);
}

int btfd_token_make(const btfd_token_key *k, const char *scope, int64_t expires, char *out, size_t n)
{
    char exp[24], sig[44];
    if (!scope_valid(scope) || expires < 0)
        return -1;
    snprintf(exp, sizeof exp, "%lld", (long long)expires);
    sign(k, scope, exp, sig);
    int w = snprintf(out, n, "v1:%s:%s:%s", scope, exp, sig);
    return w > 0 && (size_t)w < n ? 0 : -1;
}

/* Unix seconds of decimal text s (1..18 digits), or -1. */
static int64_t parse_time(const char *s, size_t n)
{
    if (n < 1 || n > 18)
        return -1;
    int64_t v = 0;
    for (size_t i = 0; i < n; i++) {
        if (s[i] < '0' || s[i] > '9')
            return -1;
        v = v * 10 + (s[i] - '0');
    }
    return v;
}

btfd_token_verdict btfd_token_check(const btfd_token_key *k, const char *token, const char *material, int64_t now)
{
    if (!token || !*token)
        return BTFD_TOKEN_MISSING;
    size_t len = strnlen(token, BTFD_TOKEN_MAX);
    if (len >= BTFD_TOKEN_MAX || strncmp(token, "v1:", 3) != 0)
        return BTFD_TOKEN_MALFORMED;
    const char *scope = token + 3, *c1 = strchr(scope, ':'), *c2 = c1 ? strchr(c1 + 1, ':') : NULL;
    if (!c1 || !c2 || strchr(c2 + 1, ':'))
        return BTFD_TOKEN_MALFORMED;
    char sc[BTFD_TOKEN_MAX], exp[24];
    size_t ns = (size_t)(c1 - scope), ne = (size_t)(c2 - c1 - 1);
    if (ns >= sizeof sc || ne >= sizeof exp)
        return BTFD_TOKEN_MALFORMED;
    memcpy(sc, scope, ns), sc[ns] = '\0';
    memcpy(exp, c1 + 1, ne), exp[ne] = '\0';
    int64_t expires = parse_time(exp, ne);
    if (!scope_valid(sc) || expires < 0 || strlen(c2 + 1) != 43)
        return BTFD_TOKEN_MALFORMED;
    char want[44];
    sign(k, sc, exp, want);
    if (CRYPTO_memcmp(want, c2 + 1, 43) != 0)
        return BTFD_TOKEN_SIGNATURE;
    if (expires < now)
        return BTFD_TOKEN_EXPIRED;
    return scope_grants(sc, material) ? BTFD_TOKEN_OK : BTFD_TOKEN_SCOPE;
}

/* The md5 argument of material until expires (text) into out (23 bytes). */
static void sign_md5(const btfd_token_key *k, const char *material, const char *expires, char out[23])
{
    unsigned char d[EVP_MAX_MD_SIZE];
    unsigned dl = 0;
    EVP_MD_CTX *c = EVP_MD_CTX_new();
    EVP_DigestInit_ex(c, EVP_md5(), NULL);
    EVP_DigestUpdate(c, expires, strlen(expires));
    EVP_DigestUpdate(c, "/materials/", 11);
    EVP_DigestUpdate(c, material, strlen(material));
    EVP_DigestUpdate(c, " ", 1);
    EVP_DigestUpdate(c, k->secret, k->len);
    EVP_DigestFinal_ex(c, d, &dl);
    EVP_MD_CTX_free(c);
    b64url(d, dl, out);
}

int btfd_token_make_md5(const btfd_token_key *k, const char *material, int64_t expires, char *out, size_t n)
{
    char exp[24];
    if (n < 23 || expires < 0 || !btfd_name_valid(material, strlen(material)))
        return -1;
    snprintf(exp, sizeof exp, "%lld", (long long)expires);
    sign_md5(k, material, exp, out);
    return 0;
}

btfd_token_verdict btfd_token_check_md5(const btfd_token_key *k, const char *md5, const char *expires,
                                        const char *material, int64_t now)
{
    if (!md5 || !*md5 || !expires || !*expires)
        return BTFD_TOKEN_MISSING;
    int64_t t = parse_time(expires, strlen(expires));
    if (t < 0 || strlen(md5) != 22)
        return BTFD_TOKEN_MALFORMED;
    char want[23];
    sign_md5(k, material, expires, want);
    if (CRYPTO_memcmp(want, md5, 22) != 0)
        return BTFD_TOKEN_SIGNATURE;
    return t < now ? BTFD_TOKEN_EXPIRED : BTFD_TOKEN_OK;
}

const char *btfd_token_code(btfd_token_verdict v)
{
    return v == BTFD_TOKEN_OK ? "ok" : v == BTFD_TOKEN_EXPIRED ? "token_expired" : "forbidden";
}

const char *btfd_token_text(btfd_token_verdict v)
{
    switch (v) {
    case BTFD_TOKEN_OK: return "access granted";
    case BTFD_TOKEN_MISSING: return "this library is private: a token is required";
    case BTFD_TOKEN_MALFORMED: return "the token is not v1:SCOPE:EXPIRES:SIGNATURE";
    case BTFD_TOKEN_EXPIRED: return "the token has expired";
    case BTFD_TOKEN_SCOPE: return "the token is for other materials";
    case BTFD_TOKEN_SIGNATURE: return "the token's signature does not match";
    }
    return "forbidden";
}
