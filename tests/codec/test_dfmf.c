/* test_dfmf.c - room codec, suite "dfmf": UBO2014 DFMF08FC `.btf`
 * (codec/input/btf_dfmf.c): writer/reader round trips (full rank exact, truncated
 * rank = the optimal one by an independent SVD), files built
 * byte by byte here from the DFMF layout (versions 1..4, half/float/double,
 * colour model 11), and broken files: truncation at every offset, absurd counts,
 * foreign signatures, trailing bytes. */
#include <criterion/criterion.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "btf_io.h"
#include "fixtures.h"
#include "btf_input.h"

/* ------------------------------------------------------------ helpers */

static unsigned rng = 1;
static float rnd(void)
{
    fx_lcg(&rng);
    return (float)((rng >> 8) & 0xffff) / 65535.0f;
}

/* 15 directions: pole, 6 at 30 deg (offset 15), 8 at 60 deg. */
static btf_dirset small_set(void)
{
    return FX_RINGS({0, 1, 0}, {30, 6, 15}, {60, 8, 0});
}

static btf *random_btf(int w, int h, const btf_dirset *lights, const btf_dirset *views)
{
    btf *b = NULL;
    cr_assert_eq(btf_create(w, h, lights, views, BTF_F32, &b, NULL), BTF_OK);
    float *f = b->data;
    for (size_t i = 0; i < b->count; i++)
        f[i] = rnd() * 1.5f - 0.1f; /* HDR-ish, some negative: the format stores any float */
    return b;
}

static void tmp_file(char *buf, size_t n, const char *name)
{
    char dir[256];
    cr_assert(fx_tmpdir(dir, sizeof dir));
    snprintf(buf, n, "%s/%s", dir, name);
}

static void remove_file(const char *path)
{
    unlink(path);
    char dir[512];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash) {
        *slash = '\0';
        rmdir(dir);
    }
}

static double max_abs_diff(const btf *a, const btf *b)
{
    double m = 0.0;
    for (int v = 0; v < a->views.n_dirs; v++)
        for (int l = 0; l < a->lights.n_dirs; l++)
            for (int y = 0; y < a->height; y++)
                for (int x = 0; x < a->width; x++)
                    for (int c = 0; c < 3; c++)
                        m = fmax(m, fabs(btf_get(a, v, l, x, y, c) - btf_get(b, v, l, x, y, c)));
    return m;
}

static void round_trip_full(int w, int h, const btf_dirset *lights, const btf_dirset *views)
{
    btf *b = random_btf(w, h, lights, views), *r = NULL;
    char path[512];
    tmp_file(path, sizeof path, "m.btf");
    btf_error e = {0};
    cr_assert_eq(btf_save_dfmf(b, path, 0, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(btf_load_dfmf(path, NULL, &r, &e), BTF_OK, "%s", e.msg);
    cr_assert(r->width == w && r->height == h && r->storage == BTF_F32);
    cr_expect(btf_dirset_equal(&r->views, views) && btf_dirset_equal(&r->lights, lights));
    /* one factor is the identity: each value is one float times 1.0, exact */
    cr_expect(max_abs_diff(b, r) == 0.0, "max diff %g", max_abs_diff(b, r));
    btf_free(b);
    btf_free(r);
    remove_file(path);
}

/* ------------------------------------------------------------ round trips */

Test(dfmf, full_rank_round_trip_more_rows_than_texels)
{
    btf_dirset d = small_set();
    round_trip_full(6, 4, &d, &d); /* 225 rows, 24 columns */
}

Test(dfmf, full_rank_round_trip_more_texels_than_rows)
{
    btf_ring r[2] = {{0, 1, 0}, {45, 4, 45}};
    btf_dirset d;
    cr_assert_eq(btf_dirset_make(r, 2, &d, NULL), BTF_OK);
    btf_dirset s = small_set();
    round_trip_full(8, 8, &d, &s); /* 5 lights x 15 views = 75 rows, 64 columns; lights != views */
    round_trip_full(16, 8, &d, &d); /* 25 rows, 128 columns */
}

Test(dfmf, full_rank_round_trip_dome151_and_ubo2003)
{
    btf_dirset dome = btf_dirset_dome151(), ubo = btf_dirset_ubo2003();
    round_trip_full(2, 2, &dome, &dome);
    round_trip_full(2, 1, &ubo, &ubo);
}

Test(dfmf, u8_source_and_u8_load)
{
    btf_dirset d = small_set();
    btf *b = NULL, *r = NULL;
    cr_assert_eq(btf_create(4, 4, &d, &d, BTF_U8, &b, NULL), BTF_OK);
    uint8_t *p = b->data;
    for (size_t i = 0; i < b->count; i++)
        p[i] = (uint8_t)(i * 37u);
    char path[512];
    tmp_file(path, sizeof path, "u8.btf");
    cr_assert_eq(btf_save_dfmf(b, path, 0, NULL), BTF_OK);
    btf_load_options o = {0};
    o.storage = BTF_U8;
    cr_assert_eq(btf_load_dfmf(path, &o, &r, NULL), BTF_OK);
    cr_assert_eq(r->storage, BTF_U8);
    cr_expect(memcmp(b->data, r->data, b->count) == 0, "bytes survive byte/255 float storage");
    btf_free(r);
    o.storage = 0;
    o.downsample = 2;
    cr_assert_eq(btf_load_dfmf(path, &o, &r, NULL), BTF_OK);
    cr_expect(r->width == 2 && r->height == 2 && r->storage == BTF_F32);
    double m = 0.25 * (btf_get(b, 3, 4, 2, 0, 1) + btf_get(b, 3, 4, 3, 0, 1) + btf_get(b, 3, 4, 2, 1, 1) +
                       btf_get(b, 3, 4, 3, 1, 1));
    cr_expect(fabs(btf_get(r, 3, 4, 1, 0, 1) - m) < 1e-6);
    btf_free(r);
    btf_free(b);
    remove_file(path);
}

/* Squared Frobenius error of channel c between a and b. */
static double channel_err2(const btf *a, const btf *b, int c)
{
    double s = 0.0;
    for (size_t i = (size_t)c; i < a->count; i += 3) {
        double d = (double)((const float *)a->data)[i] - ((const float *)b->data)[i];
        s += d * d;
    }
    return s;
}

/* Singular values of channel c (rows = view*nL + light, cols = texels) by LAPACK's
 * divide-and-conquer SVD: an independent route to the optimal truncation error. */
static void channel_singular_values(const btf *b, int c, float *sv)
{
    int rows = b->views.n_dirs * b->lights.n_dirs, cols = b->width * b->height;
    float *A = malloc(sizeof(float) * (size_t)rows * cols);
    for (int r = 0; r < rows; r++)
        for (int t = 0; t < cols; t++)
            A[(size_t)t * rows + r] = ((const float *)b->data)[((size_t)r * cols + t) * 3 + c]; /* column-major */
    cr_assert_eq(LAPACKE_sgesdd(LAPACK_COL_MAJOR, 'N', rows, cols, A, rows, sv, NULL, 1, NULL, 1), 0);
    free(A);
}

static void check_truncated(int w, int h, const btf_dirset *d, int k)
{
    btf *b = random_btf(w, h, d, d), *r = NULL;
    char path[512];
    tmp_file(path, sizeof path, "t.btf");
    btf_error e = {0};
    cr_assert_eq(btf_save_dfmf(b, path, k, &e), BTF_OK, "%s", e.msg);
    cr_assert_eq(btf_load_dfmf(path, NULL, &r, &e), BTF_OK, "%s", e.msg);
    int rows = d->n_dirs * d->n_dirs, cols = w * h, m = rows < cols ? rows : cols;
    float *sv = malloc(sizeof(float) * (size_t)m);
    for (int c = 0; c < 3; c++) {
        channel_singular_values(b, c, sv);
        double tail = 0.0, total = 0.0;
        for (int i = 0; i < m; i++) {
            total += (double)sv[i] * sv[i];
            if (i >= k)
                tail += (double)sv[i] * sv[i];
        }
        double got = channel_err2(b, r, c);
        /* Eckart-Young: the best rank-k error is the tail energy. Float Gram
         * matrices lose about 1e-6 of the total energy; allow 1e-4 of it. */
        cr_expect(fabs(got - tail) <= 1e-4 * total, "channel %d: error %g, optimum %g (total %g)", c, got, tail,
                  total);
    }
    free(sv);
    btf_free(b);
    btf_free(r);
    remove_file(path);
}

Test(dfmf, truncated_rank_is_optimal)
{
    btf_dirset d = small_set();
    check_truncated(6, 4, &d, 5);  /* rows 225 > cols 24: Gram of A^T A */
    check_truncated(16, 16, &d, 7); /* rows 225 < cols 256: Gram of A A^T */
}

Test(dfmf, truncated_rank_of_low_rank_data_is_exact)
{
    btf_dirset d = small_set();
    btf *b = NULL, *r = NULL;
    cr_assert_eq(btf_create(8, 8, &d, &d, BTF_F32, &b, NULL), BTF_OK);
    /* rank 2 per channel: a(row) * p(texel) + b(row) * q(texel) */
    float *f = b->data;
    for (int row = 0; row < 225; row++)
        for (int t = 0; t < 64; t++)
            for (int c = 0; c < 3; c++)
                f[((size_t)row * 64 + t) * 3 + c] = sinf(0.1f * row + c) * cosf(0.3f * t) + 0.5f * cosf(0.07f * row * (c + 1)) * sinf(0.2f * t + 1.0f);
    char path[512];
    tmp_file(path, sizeof path, "r2.btf");
    cr_assert_eq(btf_save_dfmf(b, path, 2, NULL), BTF_OK);
    cr_assert_eq(btf_load_dfmf(path, NULL, &r, NULL), BTF_OK);
    /* values of magnitude <= 1.5; float Gram route: ~1e-5 is float precision here */
    cr_expect(max_abs_diff(b, r) < 1e-4, "max diff %g", max_abs_diff(b, r));
    btf_free(b);
    btf_free(r);
    remove_file(path);
}

/* ------------------------------------------------------------ hand-built files */

/* Growable little-endian byte buffer. */
typedef struct bytes {
    uint8_t *p;
    size_t n, cap;
} bytes;

static void put(bytes *b, const void *src, size_t n)
{
    if (b->n + n > b->cap) {
        b->cap = (b->n + n) * 2 + 64;
        b->p = realloc(b->p, b->cap);
    }
    memcpy(b->p + b->n, src, n);
    b->n += n;
}
static void put_u32(bytes *b, uint32_t v)
{
    uint8_t x[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    put(b, x, 4);
}
static void put_f32(bytes *b, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(b, u);
}
static void put_scalar(bytes *b, int ssize, float v)
{
    if (ssize == 4) {
        put_f32(b, v);
    } else if (ssize == 8) {
        double d = v;
        uint64_t u;
        memcpy(&u, &d, 8);
        put_u32(b, (uint32_t)u);
        put_u32(b, (uint32_t)(u >> 32));
    } else { /* half, for values that are exact in half: normal numbers only */
        uint16_t h = 0;
        if (v != 0.0f) {
            int e;
            float m = frexpf(fabsf(v), &e); /* v = m * 2^e, m in [0.5, 1) */
            h = (uint16_t)(((e + 14) << 10) | ((int)lroundf(m * 2048.0f) & 0x3ff));
            if (v < 0)
                h |= 0x8000;
        }
        uint8_t x[2] = {(uint8_t)h, (uint8_t)(h >> 8)};
        put(b, x, 2);
    }
}

/* A file with 1 view (pole) x 2 lights (pole, theta 40 phi 90 deg... a ring of 1),
 * 2 x 1 texels, rank 1: channel c value U[row] * SxV[t]. */
typedef struct hand_spec {
    int version, ssize, model;
    const char *sig;
    int k;              /* 0: rank 1 with hU, hS; else rank k with U and S below */
    const float *U, *S; /* per channel 2 x k (rows x components), then 2 x k (texels x components) */
} hand_spec;

static const float hU[3][2] = {{0.5f, -1.25f}, {2.0f, 0.75f}, {-0.5f, 1.5f}};
static const float hS[3][2] = {{1.0f, 0.25f}, {-0.125f, 0.5f}, {0.375f, 2.0f}};

static bytes hand_file(hand_spec s)
{
    bytes b = {0};
    put(&b, s.sig, strlen(s.sig));
    bytes m = {0};
    put_u32(&m, s.version);
    uint8_t text[240] = {0};
    put(&m, text, 240);
    for (int i = 0; i < 4; i++)
        put_f32(&m, 1.0f);
    if (s.version > 1)
        put_u32(&m, 1);
    if (s.version > 2)
        put_u32(&m, 5), put(&m, "<x/>\n", 5);
    if (s.version > 3) {
        put_u32(&m, 3);
        for (int c = 0; c < 3; c++)
            put_u32(&m, 2), put(&m, "ch", 2);
    }
    put_u32(&b, (uint32_t)(m.n + 4));
    put(&b, m.p, m.n);
    free(m.p);
    put_u32(&b, 1);                              /* views */
    put_f32(&b, 0.0f), put_f32(&b, 0.0f);        /* view 0: pole */
    put_u32(&b, 2);                              /* lights */
    put_f32(&b, 0.0f), put_f32(&b, 0.0f);        /* pole */
    put_f32(&b, 0.6981317f), put_f32(&b, 1.5707964f); /* 40 deg, phi 90 deg */
    put_u32(&b, 2), put_u32(&b, 1);              /* width, height */
    if (s.sig[strlen(s.sig) - 1] == 'R') {
        put_u32(&b, 1);
        for (int i = 0; i < 9; i++)
            put_f32(&b, i % 4 == 0);
    }
    put_u32(&b, s.k ? (uint32_t)s.k : 1u); /* components at most */
    put_u32(&b, (uint32_t)s.model);
    for (int i = 0; i < 12; i++)
        put_f32(&b, 0.0f);
    int k = s.k ? s.k : 1;
    for (int c = 0; c < 3; c++) {
        uint8_t ss = (uint8_t)s.ssize;
        put(&b, &ss, 1);
        put_u32(&b, (uint32_t)k), put_u32(&b, 2), put_u32(&b, 2);
        for (int j = 0; j < k; j++)
            put_scalar(&b, s.ssize, 1.0f);
        for (int i = 0; i < 2 * k; i++)
            put_scalar(&b, s.ssize, s.k ? s.U[c * 2 * k + i] : hU[c][i]);
        for (int i = 0; i < 2 * k; i++)
            put_scalar(&b, s.ssize, s.k ? s.S[c * 2 * k + i] : hS[c][i]);
    }
    return b;
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    unlink(path); /* a fresh inode: rewriting a truncated file makes ext4 flush it on close (slow) */
    fx_write(path, p, n);
}

/* f written to a fresh file (its path into path) and loaded into *b; asserts it loads. */
static void load_hand(const bytes *f, const char *name, char *path, size_t cap, btf **b)
{
    tmp_file(path, cap, name);
    write_bytes(path, f->p, f->n);
    btf_error e = {0};
    cr_assert_eq(btf_load_dfmf(path, NULL, b, &e), BTF_OK, "%s: %s", name, e.msg);
}

static void check_hand(hand_spec s)
{
    bytes f = hand_file(s);
    char path[512];
    tmp_file(path, sizeof path, "hand.btf");
    write_bytes(path, f.p, f.n);
    btf *b = NULL;
    btf_error e = {0};
    cr_assert_eq(btf_load_dfmf(path, NULL, &b, &e), BTF_OK, "v%d s%d m%d %s: %s", s.version, s.ssize, s.model, s.sig,
                 e.msg);
    cr_assert(b->lights.n_dirs == 2 && b->views.n_dirs == 1 && b->width == 2 && b->height == 1);
    float th, ph;
    btf_dirset_angles(&b->lights, 1, &th, &ph);
    cr_expect(fabsf(th - 40.0f) < 1e-3f && fabsf(ph - 90.0f) < 1e-3f, "light 1 at %g %g", th, ph);
    for (int l = 0; l < 2; l++)
        for (int t = 0; t < 2; t++) {
            double ch[3], rgb[3];
            for (int c = 0; c < 3; c++)
                ch[c] = (double)hU[c][l] * hS[c][t];
            if (s.model == 11) { /* colour model 11: log(Y + 1e-5), U and V over (Y + 1e-5) */
                double Y = exp(ch[0]) - 1e-5, U = ch[1] * (Y + 1e-5), V = ch[2] * (Y + 1e-5);
                rgb[0] = Y + 1.13983 * V;
                rgb[1] = Y - 0.39465 * U - 0.5806 * V;
                rgb[2] = Y + 2.03211 * U;
            } else {
                memcpy(rgb, ch, sizeof rgb);
            }
            for (int c = 0; c < 3; c++)
                cr_expect(fabs(btf_get(b, 0, l, t, 0, c) - rgb[c]) < 1e-5 * (1 + fabs(rgb[c])),
                          "l %d t %d c %d: %f vs %f", l, t, c, btf_get(b, 0, l, t, 0, c), rgb[c]);
        }
    btf_free(b);
    free(f.p);
    remove_file(path);
}

/* A square factor decodes as the product whatever it holds: the identity (a
 * full-rank file as btf_save_dfmf writes it, decoded by a copy of the other), and one
 * that is not quite (a permutation, one off-diagonal entry in one channel), either
 * factor, each against the product by hand. */
Test(dfmf, a_square_factor_is_the_identity_only_when_it_is)
{
    static const float M[3 * 4] = {0.25f, -0.5f, 0.75f, 0.125f, 1.5f, 0.5f, -0.25f, 1.0f, 0.5f, 0.5f, -0.75f, 0.25f};
    static const float sq[3][3 * 4] = {
        {1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1},     /* the identity */
        {0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0},     /* rows swapped */
        {1, 0, 0, 1, 1, 0, 0.5f, 1, 1, 0, 0, 1}}; /* channel 1: one off-diagonal entry */
    for (int u = 0; u < 6; u++) {
        const float *U = u < 3 ? sq[u] : M, *S = u < 3 ? M : sq[u - 3];
        bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .sig = "!DFMF08FCR", .k = 2, .U = U, .S = S});
        char path[512];
        btf *b = NULL;
        load_hand(&f, "square.btf", path, sizeof path, &b);
        for (int c = 0; c < 3; c++)
            for (int l = 0; l < 2; l++)
                for (int t = 0; t < 2; t++) {
                    const float *a = U + c * 4, *s = S + c * 4;
                    double want = (double)a[l * 2] * s[t * 2] + (double)a[l * 2 + 1] * s[t * 2 + 1];
                    cr_expect_float_eq(btf_get(b, 0, l, t, 0, c), want, 1e-6, "case %d c %d l %d t %d", u, c, l, t);
                }
        btf_free(b);
        free(f.p);
        remove_file(path);
    }
}

Test(dfmf, hand_built_versions_scalars_and_colour_models)
{
    check_hand((hand_spec){.version = 1, .ssize = 8, .model = 0, .sig = "!DFMF08FCR"});
    check_hand((hand_spec){.version = 2, .ssize = 2, .model = 0, .sig = "!DFMF08FCR"});
    check_hand((hand_spec){.version = 3, .ssize = 4, .model = 11, .sig = "!DFMF08FC"}); /* no rotations */
    check_hand((hand_spec){.version = 4, .ssize = 2, .model = 11, .sig = "!DFMF08FCR"});
}

/* ------------------------------------------------------------ broken files */

/* Loads n bytes written to a scratch file (one per process, removed at exit). */
static char scratch[512];
static void remove_scratch(void) { remove_file(scratch); }

static btf_result load_bytes(const void *p, size_t n, btf_error *e)
{
    if (!scratch[0]) {
        tmp_file(scratch, sizeof scratch, "bad.btf");
        atexit(remove_scratch);
    }
    write_bytes(scratch, p, n);
    btf *b = (btf *)1;
    btf_result r = btf_load_dfmf(scratch, NULL, &b, e);
    if (r != BTF_OK && b != NULL)
        return BTF_OK; /* a failing load must leave *out NULL: report as if it had loaded */
    btf_free(b);
    return r;
}

static void expect_bad(const void *p, size_t n, btf_result want, const char *needle)
{
    btf_error e = {0};
    btf_result r = load_bytes(p, n, &e);
    cr_expect_eq(r, want, "got %s (%s), want %s", btf_result_string(r), e.msg, btf_result_string(want));
    cr_expect(strstr(e.msg, needle) != NULL, "message '%s' lacks '%s'", e.msg, needle);
}

Test(dfmf, truncated_at_every_offset)
{
    bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    btf_error e = {0};
    cr_assert_eq(load_bytes(f.p, f.n, &e), BTF_OK, "%s", e.msg);
    /* one assertion at the end: Criterion assertions are slow in tight loops */
    long bad = -1;
    for (size_t cut = 0; cut < f.n; cut++) {
        e.msg[0] = '\0';
        if (load_bytes(f.p, cut, &e) == BTF_OK || strlen(e.msg) == 0)
            bad = (long)cut;
    }
    cr_expect_eq(bad, -1, "file cut at %ld of %zu loaded or gave no message", bad, f.n);
    /* a written file too, cut at a stride of offsets */
    btf_dirset d = small_set();
    btf *b = random_btf(3, 2, &d, &d);
    char path[512];
    tmp_file(path, sizeof path, "w.btf");
    cr_assert_eq(btf_save_dfmf(b, path, 0, NULL), BTF_OK);
    FILE *fp = fopen(path, "rb");
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    rewind(fp);
    uint8_t *buf = malloc((size_t)n);
    cr_assert_eq(fread(buf, 1, (size_t)n, fp), (size_t)n);
    fclose(fp);
    for (long cut = 0; cut < n; cut += cut < 400 ? 1 : 97)
        if (load_bytes(buf, (size_t)cut, &e) == BTF_OK)
            bad = cut;
    cr_expect_eq(bad, -1, "written file cut at %ld of %ld loaded", bad, n);
    expect_bad(buf, (size_t)n - 1, BTF_ERR_FORMAT, "truncated");
    free(buf);
    btf_free(b);
    remove_file(path);
    free(f.p);
}

Test(dfmf, trailing_bytes_and_foreign_signatures)
{
    bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    put(&f, "x", 1);
    expect_bad(f.p, f.n, BTF_ERR_FORMAT, "trailing");
    static const char *foreign[] = {"!FMF12FCER", "!PVF06FC", "!BDIF06R2!", "!FMF06FCR"};
    for (int i = 0; i < 4; i++) {
        uint8_t buf[64] = {0};
        memcpy(buf, foreign[i], strlen(foreign[i]));
        expect_bad(buf, sizeof buf, BTF_ERR_UNSUPPORTED, foreign[i]);
    }
    expect_bad("hello, world, not a btf", 23, BTF_ERR_FORMAT, "hello, wor");
    expect_bad("", 0, BTF_ERR_FORMAT, "signature");
    btf *b = (btf *)1;
    btf_error e = {0};
    cr_expect_eq(btf_load_dfmf("/nonexistent/x.btf", NULL, &b, &e), BTF_ERR_MISSING);
    cr_expect(strstr(e.msg, "/nonexistent/x.btf") != NULL);
    free(f.p);
}

/* Offsets in hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"}), from the layout:
 * signature 10, size 4, version 4, 240 text, 16 floats, cosine 4, xml 4+5,
 * channels 4 + 3*(4+2) -> views at 309; view 0 theta, phi, light count at 321,
 * 2 lights, width 341, height 345, rotations 349 (+36), components 389, model 393,
 * 12 floats, channel 0 at 445: scalar size, k, rows, cols, S, U... */
enum { OFF_SIZE = 10, OFF_VERSION = 14, OFF_XMLLEN = 278, OFF_NCH = 287, OFF_VIEWS = 309,
       OFF_NLIGHTS = 321, OFF_WIDTH = 341, OFF_HEIGHT = 345, OFF_NROT = 349, OFF_NCOMP = 389,
       OFF_MODEL = 393, OFF_CH0 = 445 };

static void patch_u32(bytes *f, size_t off, uint32_t v)
{
    uint8_t x[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    memcpy(f->p + off, x, 4);
}

static void expect_patched(size_t off, uint32_t v, btf_result want, const char *needle)
{
    bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    patch_u32(&f, off, v);
    expect_bad(f.p, f.n, want, needle);
    free(f.p);
}

Test(dfmf, absurd_header_counts)
{
    /* the offsets are right: the unpatched values read back */
    bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    uint32_t v;
    memcpy(&v, f.p + OFF_VIEWS, 4);
    cr_assert_eq(v, 1u);
    memcpy(&v, f.p + OFF_NLIGHTS, 4);
    cr_assert_eq(v, 2u);
    memcpy(&v, f.p + OFF_NCOMP, 4);
    cr_assert_eq(v, 1u);
    cr_assert_eq(f.p[OFF_CH0], 4);
    free(f.p);
    expect_patched(OFF_SIZE, 12345, BTF_ERR_FORMAT, "header size");
    expect_patched(OFF_VERSION, 7, BTF_ERR_UNSUPPORTED, "version 7");
    expect_patched(OFF_VERSION, 0, BTF_ERR_UNSUPPORTED, "version 0");
    expect_patched(OFF_XMLLEN, 0xfffffff0u, BTF_ERR_FORMAT, "truncated");
    expect_patched(OFF_NCH, 100000, BTF_ERR_RANGE, "channels");
    expect_patched(OFF_VIEWS, 0xffffffffu, BTF_ERR_RANGE, "views");
    expect_patched(OFF_VIEWS, 0, BTF_ERR_RANGE, "views");
    expect_patched(OFF_VIEWS, 2000, BTF_ERR_UNSUPPORTED, "view 1 has 1 lights"); /* reads on into width */
    expect_patched(OFF_NLIGHTS, 1u << 30, BTF_ERR_RANGE, "lights");
    expect_patched(OFF_WIDTH, 1000000, BTF_ERR_RANGE, "size");
    expect_patched(OFF_HEIGHT, 0, BTF_ERR_RANGE, "size");
    expect_patched(OFF_NROT, 0x7fffffffu, BTF_ERR_FORMAT, "truncated");
    expect_patched(OFF_NCOMP, 1000, BTF_ERR_RANGE, "components");
    expect_patched(OFF_MODEL, 5, BTF_ERR_UNSUPPORTED, "colour model 5");
    expect_patched(OFF_CH0 + 1, 2, BTF_ERR_RANGE, "components"); /* channel k > header k */
    expect_patched(OFF_CH0 + 5, 3, BTF_ERR_FORMAT, "channel 0 is 3 x 2");
    expect_patched(OFF_CH0 + 9, 0x40000000u, BTF_ERR_FORMAT, "channel 0 is 2 x 1073741824");
    bytes g = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    g.p[OFF_CH0] = 3;
    expect_bad(g.p, g.n, BTF_ERR_FORMAT, "scalar size 3");
    /* consistent counts whose matrices the file does not hold */
    g.p[OFF_CH0] = 4;
    patch_u32(&g, OFF_WIDTH, 1000);
    patch_u32(&g, OFF_CH0 + 9, 1000);
    expect_bad(g.p, g.n, BTF_ERR_FORMAT, "truncated: channel 0 needs 4012 bytes");
    free(g.p);
}

Test(dfmf, non_ring_directions_and_nan)
{
    /* lights at theta 40: phi 90 and phi 100 -> not equally spaced */
    bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    /* change light 0 (the pole) into theta 40 deg, phi 100 deg */
    size_t light0 = OFF_NLIGHTS + 4;
    float th = 0.6981317f, ph = 1.7453293f;
    memcpy(f.p + light0, &th, 4), memcpy(f.p + light0 + 4, &ph, 4);
    expect_bad(f.p, f.n, BTF_ERR_UNSUPPORTED, "not equally spaced");
    /* same theta and phi twice: not a ring either */
    ph = 1.5707964f;
    memcpy(f.p + light0 + 4, &ph, 4);
    expect_bad(f.p, f.n, BTF_ERR_UNSUPPORTED, "not equally spaced");
    free(f.p);
    /* a NaN factor */
    bytes g = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    float nan = NAN;
    memcpy(g.p + OFF_CH0 + 13 + 4, &nan, 4); /* after the header and S: U[0][0] */
    expect_bad(g.p, g.n, BTF_ERR_NUMERIC, "non-finite");
    free(g.p);
}

Test(dfmf, writer_refuses_bad_arguments)
{
    btf_dirset d = small_set();
    btf *b = random_btf(2, 2, &d, &d);
    btf_error e = {0};
    cr_expect_eq(btf_save_dfmf(b, "/tmp/x.btf", -1, &e), BTF_ERR_ARG);
    cr_expect_eq(btf_save_dfmf(b, "/nonexistent-dir/x.btf", 0, &e), BTF_ERR_IO);
    cr_expect(strstr(e.msg, "/nonexistent-dir/x.btf") != NULL, "%s", e.msg);
    cr_expect_eq(btf_save_dfmf(NULL, "/tmp/x.btf", 0, &e), BTF_ERR_ARG);
    btf_free(b);
}

Test(dfmf, file_order_is_mapped_to_canonical_order)
{
    /* swap the two light directions in the file: the pole becomes file light 1 */
    bytes f = hand_file((hand_spec){.version = 4, .ssize = 4, .model = 0, .sig = "!DFMF08FCR"});
    uint8_t tmp[8];
    memcpy(tmp, f.p + OFF_NLIGHTS + 4, 8);
    memmove(f.p + OFF_NLIGHTS + 4, f.p + OFF_NLIGHTS + 12, 8);
    memcpy(f.p + OFF_NLIGHTS + 12, tmp, 8);
    char path[512];
    btf *b = NULL;
    load_hand(&f, "order.btf", path, sizeof path, &b);
    float th, ph;
    btf_dirset_angles(&b->lights, 0, &th, &ph);
    cr_expect_eq(th, 0.0f, "canonical light 0 is the pole");
    for (int c = 0; c < 3; c++)
        for (int t = 0; t < 2; t++) {
            /* canonical light 0 (pole) is file row 1; canonical light 1 is file row 0 */
            cr_expect(fabsf(btf_get(b, 0, 0, t, 0, c) - hU[c][1] * hS[c][t]) < 1e-6f);
            cr_expect(fabsf(btf_get(b, 0, 1, t, 0, c) - hU[c][0] * hS[c][t]) < 1e-6f);
        }
    btf_free(b);
    free(f.p);
    remove_file(path);
}
