/* btf_gen.c - synthetic BTFs: tileable height fields (knit, tiles, stone), soft
 * self-shadowing, parallax/masking by a view-ray march, normalised Blinn-Phong.
 *
 * Cost structure of btf_gen_create: fields once per texel; shadow once per
 * (light, texel); visible point once per (view, texel); then only shading per
 * (view, light, texel). btf_gen_model_eval runs the very same functions for one
 * texel, so it reproduces stored values exactly. */
#include "btf_gen.h"
#include "btf_color.h"
#include "btf_common.h"

#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define GEN_TAN_MAX 8.0f     /* cap on tan(theta) for parallax and shadow length (82.9 deg) */
#define GEN_VIEW_STEP 0.6f   /* horizontal view-march step at the cap, texels */
#define GEN_SHADOW_STEP 0.5f /* shadow-march step, texels */
#define GEN_SHADOW_SOFT 0.08f
#define GEN_AMBIENT 0.1f
#define GEN_T_EPS 1e-5f      /* view march stops when transmittance falls below */

/* Precomputed maps of one material (owned by the caller of btf_gen_model_create, freed by btf_gen_model_free). */
struct btf_gen_model {
    btf_gen_params p;
    int w, h;
    float hmin, hmax; /* relief range, texels */
    int view_steps;   /* depth samples of the view march */
    float *height;    /* w*h, texels */
    float *albedo;    /* w*h*3, linear */
    float *normal;    /* w*h*3, unit, local frame */
    float *expo;      /* w*h, Blinn-Phong exponent */
    float *ks;        /* w*h, specular weight */
};

/* One texel's material description before scaling; stack value. */
typedef struct gen_texel {
    float h;      /* relief 0..1 (normalised later) */
    float rgb[3]; /* linear albedo */
    float rough;  /* 0..1 -> roughness_min..max */
    float spec;   /* 0..1 -> 0..spec_strength */
} gen_texel;

/* The visible point of one (view, texel): bilinear corners and interpolated fields. */
typedef struct gen_point {
    int idx[4];
    float wt[4];
    float albedo[3];
    float n[3];
    float expo, ks;
} gen_point;

/* Constants of one (light, view) pair. */
typedef struct gen_lv {
    int lit;
    float l[3], hv[3];
    float fres;
} gen_lv;

/* ---------------------------------------------------------------- names, params */

static const char *const gen_names[BTF_GEN_KIND_COUNT] = {"knit", "tiles", "stone"};

const char *btf_gen_kind_name(btf_gen_kind kind)
{
    return (unsigned)kind < BTF_GEN_KIND_COUNT ? gen_names[kind] : "unknown";
}

int btf_gen_kind_from_name(const char *name)
{
    return btf_name_index(gen_names, BTF_GEN_KIND_COUNT, name);
}

btf_gen_params btf_gen_defaults(btf_gen_kind kind)
{
    btf_gen_params p = {kind, 1u, 3.0f, 0.04f, 0.5f, 0.85f, 5};
    if (kind == BTF_GEN_TILES) {
        p.height_scale = 1.5f;
        p.spec_strength = 0.11f;
        p.roughness_min = 0.18f;
        p.roughness_max = 0.8f;
        p.repeats = 4;
    } else if (kind == BTF_GEN_STONE) {
        p.height_scale = 4.0f;
        p.spec_strength = 0.03f;
        p.roughness_min = 0.55f;
        p.roughness_max = 0.95f;
        p.repeats = 3;
    }
    return p;
}

static int gen_default_repeats(btf_gen_kind k) { return k == BTF_GEN_KNIT ? 5 : k == BTF_GEN_TILES ? 4 : 3; }

btf_result btf_gen_check_params(const btf_gen_params *p, btf_error *err)
{
    if (!p)
        return btf_fail(err, BTF_ERR_ARG, "gen: params is NULL");
    if ((unsigned)p->kind >= BTF_GEN_KIND_COUNT)
        return btf_fail(err, BTF_ERR_ARG, "gen: unknown material kind %d", (int)p->kind);
    if (!(p->height_scale >= 0.0f && p->height_scale <= 64.0f))
        return btf_fail(err, BTF_ERR_RANGE, "gen: height_scale %g outside 0..64", (double)p->height_scale);
    if (!(p->spec_strength >= 0.0f && p->spec_strength <= 10.0f))
        return btf_fail(err, BTF_ERR_RANGE, "gen: spec_strength %g outside 0..10", (double)p->spec_strength);
    if (!(p->roughness_min >= 0.02f && p->roughness_min <= p->roughness_max && p->roughness_max <= 1.0f))
        return btf_fail(err, BTF_ERR_RANGE, "gen: roughness range %g..%g not within 0.02..1",
                        (double)p->roughness_min, (double)p->roughness_max);
    if (p->repeats < 0 || p->repeats > 256)
        return btf_fail(err, BTF_ERR_RANGE, "gen: repeats %d outside 0..256", p->repeats);
    return BTF_OK;
}

/* ---------------------------------------------------------------- noise */

static uint32_t gen_hash(uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t x = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u ^ (c + 0x165667B1u) * 0xC2B2AE3Du;
    x ^= x >> 16;
    x *= 0x7FEB352Du;
    x ^= x >> 15;
    x *= 0x846CA68Bu;
    x ^= x >> 16;
    return x;
}

static float gen_rand(uint32_t a, uint32_t b, uint32_t c) { return (float)(gen_hash(a, b, c) >> 8) * (1.0f / 16777216.0f); }

static int gen_wrap(long i, int n)
{
    long m = i % n;
    return (int)(m < 0 ? m + n : m);
}

static float gen_fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
static float gen_lerp(float a, float b, float t) { return a + (b - a) * t; }

static float gen_smooth01(float t)
{
    if (!(t > 0.0f))
        return 0.0f;
    if (t >= 1.0f)
        return 1.0f;
    return t * t * (3.0f - 2.0f * t);
}

static float gen_smoothstep(float a, float b, float x) { return gen_smooth01((x - a) / (b - a)); }

/* Value noise in [0,1] on the integer lattice; period per (> 0) or none (per = 0). */
static float gen_vnoise(uint32_t seed, int per, float x, float y)
{
    float fx = floorf(x), fy = floorf(y);
    long ix = (long)fx, iy = (long)fy;
    float tx = gen_fade(x - fx), ty = gen_fade(y - fy);
    long x1 = ix + 1, y1 = iy + 1;
    if (per > 0) {
        ix = gen_wrap(ix, per), x1 = gen_wrap(x1, per);
        iy = gen_wrap(iy, per), y1 = gen_wrap(y1, per);
    }
    float a = gen_rand(seed, (uint32_t)ix, (uint32_t)iy), b = gen_rand(seed, (uint32_t)x1, (uint32_t)iy);
    float c = gen_rand(seed, (uint32_t)ix, (uint32_t)y1), d = gen_rand(seed, (uint32_t)x1, (uint32_t)y1);
    return gen_lerp(gen_lerp(a, b, tx), gen_lerp(c, d, tx), ty);
}

/* Tileable fractal noise on the unit square, in [0,1]; base period per. */
static float gen_fbm(uint32_t seed, int per, int octaves, float gain, float u, float v)
{
    float sum = 0.0f, amp = 1.0f, norm = 0.0f;
    for (int o = 0; o < octaves; o++) {
        int q = per << o;
        sum += amp * gen_vnoise(seed + 101u * (uint32_t)o, q, u * (float)q, v * (float)q);
        norm += amp;
        amp *= gain;
    }
    return sum / norm;
}

/* ---------------------------------------------------------------- materials */

static void gen_palette(uint32_t seed, uint32_t salt, const float (*pal)[3], int n, float out[3])
{
    int i = (int)(gen_hash(seed, salt, 7u) % (uint32_t)n);
    for (int c = 0; c < 3; c++)
        out[c] = pal[i][c] * (0.9f + 0.2f * gen_rand(seed, salt, 11u + (uint32_t)c));
}

/* Height and fibre value of one stockinette leg at cell coords (cu, cv); 0 outside. */
static float gen_knit_leg(uint32_t seed, int nx, int ny, long ci, long cj, int side, float cu, float cv, float *fibre)
{
    uint32_t id = (uint32_t)(gen_wrap(ci, nx) * 2 + side), jd = (uint32_t)gen_wrap(cj, ny);
    float jx = 0.06f * (gen_rand(seed, id, jd) - 0.5f), jy = 0.06f * (gen_rand(seed, jd, id + 9u) - 0.5f);
    float dx = cu - ((float)ci + (side ? 0.72f : 0.28f) + jx), dy = cv - ((float)cj + 0.5f + jy);
    float ang = side ? -0.42f : 0.42f, sa = sinf(ang), ca = cosf(ang);
    float along = (dx * sa + dy * ca) / 0.64f, across = (dx * ca - dy * sa) / 0.21f;
    float r2 = along * along + across * across;
    if (r2 >= 1.0f)
        return 0.0f;
    float f = gen_vnoise(seed ^ (id * 7919u + jd * 104729u), 0, across * 9.0f, along * 1.5f);
    float ply = 0.5f + 0.5f * sinf(6.2831853f * (along * 2.2f + across * 0.9f));
    float tuck = 0.5f + 0.5f * (1.0f - along * along); /* ends dip under the neighbouring loops */
    float brightness = 0.92f + 0.16f * gen_rand(seed, id + 3u, jd + 5u);
    *fibre = f * brightness;
    return sqrtf(1.0f - r2) * tuck * (0.88f + 0.08f * ply + 0.04f * f);
}

static void gen_knit(const btf_gen_params *p, int rep, float u, float v, gen_texel *t)
{
    static const float pal[4][3] = {{0.55f, 0.10f, 0.08f}, {0.66f, 0.58f, 0.44f}, {0.14f, 0.18f, 0.42f},
                                    {0.16f, 0.38f, 0.15f}};
    int nx = rep, ny = (int)lroundf((float)rep * 1.25f);
    float cu = u * (float)nx, cv = v * (float)ny, best = 0.0f, fibre = 0.5f;
    long ci = (long)floorf(cu), cj = (long)floorf(cv);
    for (int dj = -1; dj <= 1; dj++)
        for (int di = -1; di <= 1; di++)
            for (int side = 0; side < 2; side++) {
                float f = 0.5f, hl = gen_knit_leg(p->seed, nx, ny, ci + di, cj + dj, side, cu, cv, &f);
                if (hl > best)
                    best = hl, fibre = f;
            }
    float fuzz = gen_vnoise(p->seed + 77u, nx * 24, u * (float)(nx * 24), v * (float)(nx * 24));
    float base[3];
    gen_palette(p->seed, 1u, pal, 4, base);
    float shade = (0.7f + 0.6f * fibre) * (0.45f + 0.55f * best);
    for (int c = 0; c < 3; c++)
        t->rgb[c] = base[c] * shade * (0.95f + 0.1f * fuzz);
    t->h = best + 0.03f * fuzz;
    t->rough = 0.3f + 0.7f * fibre;
    t->spec = best > 0.0f ? 1.0f : 0.3f;
}

static void gen_tiles(const btf_gen_params *p, int rep, float u, float v, gen_texel *t)
{
    static const float pal[4][3] = {{0.07f, 0.22f, 0.33f}, {0.55f, 0.19f, 0.07f}, {0.70f, 0.70f, 0.65f},
                                    {0.09f, 0.28f, 0.14f}};
    float cu = u * (float)rep, cv = v * (float)rep;
    long ci = (long)floorf(cu), cj = (long)floorf(cv);
    float s = cu - (float)ci, r = cv - (float)cj;
    float e = fminf(fminf(s, 1.0f - s), fminf(r, 1.0f - r));
    float edge = gen_smoothstep(0.035f, 0.08f, e);
    uint32_t ti = (uint32_t)gen_wrap(ci, rep), tj = (uint32_t)gen_wrap(cj, rep);
    float wave = gen_fbm(p->seed + 3u, rep * 2, 3, 0.5f, u, v);
    float grit = gen_vnoise(p->seed + 5u, rep * 32, u * (float)(rep * 32), v * (float)(rep * 32));
    float mott = gen_fbm(p->seed + 9u, rep * 4, 2, 0.5f, u, v);
    float glaze[3], grout[3] = {0.46f, 0.44f, 0.40f};
    gen_palette(p->seed, 2u, pal, 4, glaze);
    float bright = 0.88f + 0.24f * gen_rand(p->seed, ti, tj + 1000u);
    for (int c = 0; c < 3; c++) {
        float tint = 1.0f + 0.14f * (gen_rand(p->seed, ti * 3u + (uint32_t)c, tj + 2000u) - 0.5f);
        float tile = glaze[c] * bright * tint * (0.95f + 0.1f * mott);
        t->rgb[c] = gen_lerp(grout[c] * (0.8f + 0.4f * grit), tile, edge);
    }
    t->h = gen_lerp(0.08f + 0.1f * grit, 0.86f + 0.14f * wave, edge);
    t->rough = gen_lerp(0.85f + 0.15f * grit, 0.08f * mott, edge);
    t->spec = gen_lerp(0.05f, 1.0f, edge);
}

static void gen_stone(const btf_gen_params *p, int rep, float u, float v, gen_texel *t)
{
    static const float pal[3][3] = {{0.56f, 0.53f, 0.48f}, {0.50f, 0.50f, 0.52f}, {0.60f, 0.50f, 0.40f}};
    float f = gen_fbm(p->seed + 21u, rep, 6, 0.55f, u, v);
    float ridge = 1.0f - fabsf(2.0f * gen_fbm(p->seed + 23u, rep * 2, 4, 0.5f, u, v) - 1.0f);
    float m = gen_fbm(p->seed + 25u, rep * 2, 4, 0.5f, u, v);
    float speck = gen_vnoise(p->seed + 27u, rep * 48, u * (float)(rep * 48), v * (float)(rep * 48));
    float hv = 0.7f * f + 0.3f * ridge;
    float light[3], dark[3] = {0.22f, 0.21f, 0.20f};
    gen_palette(p->seed, 3u, pal, 3, light);
    float mix = gen_smoothstep(0.3f, 0.7f, m), spk = 1.0f - 0.55f * gen_smoothstep(0.72f, 0.84f, speck);
    for (int c = 0; c < 3; c++)
        t->rgb[c] = gen_lerp(dark[c], light[c], mix) * spk * (0.75f + 0.25f * hv);
    t->h = hv;
    t->rough = gen_vnoise(p->seed + 29u, rep * 8, u * (float)(rep * 8), v * (float)(rep * 8));
    t->spec = 1.0f;
}

static void gen_material(const btf_gen_params *p, int rep, float u, float v, gen_texel *t)
{
    if (p->kind == BTF_GEN_KNIT)
        gen_knit(p, rep, u, v, t);
    else if (p->kind == BTF_GEN_TILES)
        gen_tiles(p, rep, u, v, t);
    else
        gen_stone(p, rep, u, v, t);
}

#define GEN_SRGB_LUT 4096
static float gen_srgb_lut[GEN_SRGB_LUT + 2];
static pthread_once_t gen_srgb_once = PTHREAD_ONCE_INIT;

static void gen_srgb_init(void)
{
    for (int i = 0; i <= GEN_SRGB_LUT; i++) {
        double x = (double)i / GEN_SRGB_LUT;
        gen_srgb_lut[i] = (float)btf_color_srgb_encode(x);
    }
    gen_srgb_lut[GEN_SRGB_LUT + 1] = 1.0f;
}

/* ---------------------------------------------------------------- model */

void btf_gen_model_free(btf_gen_model *m)
{
    if (!m)
        return;
    free(m->height), free(m->albedo), free(m->normal), free(m->expo), free(m->ks), free(m);
}

/* Fills height (0..1 for now), albedo, expo, ks from the kind's pattern. */
static void gen_fill_fields(btf_gen_model *m)
{
    const btf_gen_params *p = &m->p;
    int rep = p->repeats > 0 ? p->repeats : gen_default_repeats(p->kind);
    for (int y = 0; y < m->h; y++)
        for (int x = 0; x < m->w; x++) {
            size_t i = (size_t)y * (size_t)m->w + (size_t)x;
            gen_texel t;
            gen_material(p, rep, ((float)x + 0.5f) / (float)m->w, ((float)y + 0.5f) / (float)m->h, &t);
            m->height[i] = t.h;
            memcpy(m->albedo + 3 * i, t.rgb, sizeof t.rgb);
            float a = gen_lerp(p->roughness_min, p->roughness_max, gen_smooth01(t.rough));
            m->expo[i] = 2.0f / (a * a) - 2.0f;
            m->ks[i] = p->spec_strength * t.spec;
        }
}

/* Rescales heights to 0..height_scale*sqrt(w*h)/64 texels and derives normals. */
static void gen_fill_relief(btf_gen_model *m)
{
    size_t n = (size_t)m->w * (size_t)m->h;
    float lo = m->height[0], hi = m->height[0];
    for (size_t i = 1; i < n; i++)
        lo = fminf(lo, m->height[i]), hi = fmaxf(hi, m->height[i]);
    float depth = m->p.height_scale * sqrtf((float)m->w * (float)m->h) / 64.0f;
    float k = hi > lo ? depth / (hi - lo) : 0.0f;
    for (size_t i = 0; i < n; i++)
        m->height[i] = (m->height[i] - lo) * k;
    m->hmin = 0.0f;
    m->hmax = hi > lo ? depth : 0.0f;
    for (int y = 0; y < m->h; y++)
        for (int x = 0; x < m->w; x++) {
            const float *H = m->height;
            size_t row = (size_t)y * (size_t)m->w;
            float dc = 0.5f * (H[row + (size_t)gen_wrap(x + 1, m->w)] - H[row + (size_t)gen_wrap(x - 1, m->w)]);
            float dr = 0.5f * (H[(size_t)gen_wrap(y + 1, m->h) * (size_t)m->w + (size_t)x] -
                               H[(size_t)gen_wrap(y - 1, m->h) * (size_t)m->w + (size_t)x]);
            /* local y points towards row 0, so dH/dy_local = -dr */
            float nx = -dc, ny = dr, len = sqrtf(nx * nx + ny * ny + 1.0f);
            float *o = m->normal + 3 * (row + (size_t)x);
            o[0] = nx / len, o[1] = ny / len, o[2] = 1.0f / len;
        }
    int steps = (int)ceilf((m->hmax - m->hmin) * GEN_TAN_MAX / GEN_VIEW_STEP);
    m->view_steps = steps < 8 ? 8 : steps;
}

btf_result btf_gen_model_create(const btf_gen_params *p, int w, int h, btf_gen_model **out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "gen: out is NULL");
    *out = NULL;
    btf_result r = btf_gen_check_params(p, err);
    if (r != BTF_OK)
        return r;
    if (w < 1 || h < 1 || w > BTF_MAX_SIDE || h > BTF_MAX_SIDE)
        return btf_fail(err, BTF_ERR_RANGE, "gen: size %dx%d outside 1..%d", w, h, BTF_MAX_SIDE);
    btf_gen_model *m = calloc(1, sizeof *m);
    size_t n = (size_t)w * (size_t)h;
    if (m) {
        m->p = *p, m->w = w, m->h = h;
        m->height = malloc(n * sizeof(float));
        m->albedo = malloc(3 * n * sizeof(float));
        m->normal = malloc(3 * n * sizeof(float));
        m->expo = malloc(n * sizeof(float));
        m->ks = malloc(n * sizeof(float));
    }
    if (!m || !m->height || !m->albedo || !m->normal || !m->expo || !m->ks) {
        btf_gen_model_free(m);
        return btf_fail(err, BTF_ERR_NOMEM, "gen: no memory for %dx%d fields", w, h);
    }
    pthread_once(&gen_srgb_once, gen_srgb_init);
    gen_fill_fields(m);
    gen_fill_relief(m);
    *out = m;
    return BTF_OK;
}

/* ---------------------------------------------------------------- rendering pieces */

/* Bilinear corners and weights at image coords (c, r), texel centres at integers, wrapping. */
static void gen_bilinear(const btf_gen_model *m, float c, float r, int idx[4], float wt[4])
{
    float fc = floorf(c), fr = floorf(r), tx = c - fc, ty = r - fr;
    int x0 = gen_wrap((long)fc, m->w), x1 = gen_wrap((long)fc + 1, m->w);
    int y0 = gen_wrap((long)fr, m->h), y1 = gen_wrap((long)fr + 1, m->h);
    idx[0] = y0 * m->w + x0, idx[1] = y0 * m->w + x1, idx[2] = y1 * m->w + x0, idx[3] = y1 * m->w + x1;
    wt[0] = (1.0f - tx) * (1.0f - ty), wt[1] = tx * (1.0f - ty), wt[2] = (1.0f - tx) * ty, wt[3] = tx * ty;
}

static float gen_mix4(const float wt[4], float a, float b, float c, float d)
{
    return wt[0] * a + wt[1] * b + wt[2] * c + wt[3] * d;
}

static float gen_height_at(const btf_gen_model *m, float c, float r)
{
    int i[4];
    float wt[4];
    gen_bilinear(m, c, r, i, wt);
    return gen_mix4(wt, m->height[i[0]], m->height[i[1]], m->height[i[2]], m->height[i[3]]);
}

static void gen_point_at(const btf_gen_model *m, float c, float r, gen_point *pt)
{
    gen_bilinear(m, c, r, pt->idx, pt->wt);
    const int *i = pt->idx;
    for (int k = 0; k < 3; k++) {
        pt->albedo[k] = gen_mix4(pt->wt, m->albedo[3 * i[0] + k], m->albedo[3 * i[1] + k], m->albedo[3 * i[2] + k],
                                 m->albedo[3 * i[3] + k]);
        pt->n[k] = gen_mix4(pt->wt, m->normal[3 * i[0] + k], m->normal[3 * i[1] + k], m->normal[3 * i[2] + k],
                            m->normal[3 * i[3] + k]);
    }
    float len = sqrtf(pt->n[0] * pt->n[0] + pt->n[1] * pt->n[1] + pt->n[2] * pt->n[2]);
    for (int k = 0; k < 3; k++)
        pt->n[k] /= len; /* len > 0: all normals have z > 0 */
    pt->expo = gen_mix4(pt->wt, m->expo[i[0]], m->expo[i[1]], m->expo[i[2]], m->expo[i[3]]);
    pt->ks = gen_mix4(pt->wt, m->ks[i[0]], m->ks[i[1]], m->ks[i[2]], m->ks[i[3]]);
}

/* Unit copy of v; 0 if v is zero, tiny or not finite. */
static int gen_unit(const float v[3], float out[3])
{
    double len = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    if (!(len > 1e-20 && len < 1e30))
        return 0;
    for (int k = 0; k < 3; k++)
        out[k] = (float)(v[k] / len);
    return 1;
}

static void gen_prep_light(const float in[3], float l[3])
{
    if (!gen_unit(in, l))
        l[0] = 0.0f, l[1] = 0.0f, l[2] = -1.0f;
}

static void gen_prep_view(const float in[3], float v[3])
{
    if (!gen_unit(in, v)) {
        v[0] = 0.0f, v[1] = 0.0f, v[2] = 1.0f;
        return;
    }
    if (v[2] >= 0.0f)
        return;
    float xy = sqrtf(v[0] * v[0] + v[1] * v[1]);
    if (xy > 0.0f)
        v[0] /= xy, v[1] /= xy;
    else
        v[0] = 1.0f, v[1] = 0.0f;
    v[2] = 0.0f;
}

/* Soft shadow of texel i for unit light l: 1 lit, 0 in shadow or below the horizon. */
static float gen_shadow(const btf_gen_model *m, int i, const float l[3])
{
    if (!(l[2] > 0.0f))
        return 0.0f;
    float lxy = sqrtf(l[0] * l[0] + l[1] * l[1]);
    float ux = lxy > 0.0f ? l[0] / lxy : 1.0f, uy = lxy > 0.0f ? l[1] / lxy : 0.0f;
    float x = (float)(i % m->w), y = (float)(i / m->w), h0 = m->height[i];
    float room = m->hmax - h0, tmax = (m->hmax - m->hmin) * GEN_TAN_MAX, slope = 0.0f;
    for (int k = 1;; k++) {
        float t = (float)k * GEN_SHADOW_STEP;
        if (t > tmax || room <= slope * t)
            break; /* nothing further can rise above the current horizon */
        if (l[2] - lxy * slope <= 0.0f)
            return 0.0f;
        float s = (gen_height_at(m, x + t * ux, y - t * uy) - h0) / t;
        if (s > slope)
            slope = s;
    }
    return gen_smooth01((l[2] - lxy * slope) / GEN_SHADOW_SOFT);
}

/* The point texel (x, y) shows for unit view v (v_z >= 0): a soft first hit of the
 * ray through (x, y) on the base plane with the height field (transmittance-weighted). */
static void gen_visible(const btf_gen_model *m, int x, int y, const float v[3], gen_point *pt)
{
    float vxy = sqrtf(v[0] * v[0] + v[1] * v[1]), range = m->hmax - m->hmin;
    float tn = vxy >= GEN_TAN_MAX * v[2] ? GEN_TAN_MAX : vxy / v[2];
    if (!(tn > 0.0f) || !(range > 0.0f)) {
        gen_point_at(m, (float)x, (float)y, pt);
        return;
    }
    float dc = tn * v[0] / vxy, dr = -tn * v[1] / vxy; /* image shift per unit height, towards the viewer */
    float c0 = (float)x + range * dc, r0 = (float)y + range * dr, dz = range / (float)m->view_steps;
    float trans = 1.0f, pc = 0.0f, pr = 0.0f;
    for (int k = 0; k <= m->view_steps; k++) {
        float d = (float)k * dz, c = c0 - d * dc, r = r0 - d * dr;
        float o = k == m->view_steps ? 1.0f : gen_smooth01((gen_height_at(m, c, r) - (m->hmax - d)) / (2.0f * dz) + 0.5f);
        float a = trans * o;
        pc += a * c, pr += a * r, trans -= a;
        if (trans < GEN_T_EPS) {
            pc += trans * c, pr += trans * r;
            break;
        }
    }
    gen_point_at(m, pc, pr, pt);
}

static void gen_lv_make(const float l[3], const float v[3], gen_lv *q)
{
    q->lit = l[2] > 0.0f;
    float h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    if (!q->lit || !gen_unit(h, q->hv))
        q->hv[0] = 0.0f, q->hv[1] = 0.0f, q->hv[2] = 1.0f;
    memcpy(q->l, l, sizeof q->l);
    float vh = fmaxf(0.0f, v[0] * q->hv[0] + v[1] * q->hv[1] + v[2] * q->hv[2]), f = 1.0f - vh;
    q->fres = 1.0f + 2.0f * f * f * f * f * f;
}

/* sRGB encoding of linear x clamped to 0..1: table of 4097 exact values, linearly
 * interpolated (max deviation from the exact curve 2e-5; continuous). */
static float gen_srgb(float x)
{
    if (!(x > 0.0f))
        return 0.0f;
    if (x >= 1.0f)
        return 1.0f;
    float f = x * (float)GEN_SRGB_LUT;
    int i = (int)f;
    float t = f - (float)i;
    return gen_srgb_lut[i] + t * (gen_srgb_lut[i + 1] - gen_srgb_lut[i]);
}

static void gen_shade(const gen_point *pt, float vis, const gen_lv *q, float rgb[3])
{
    if (!q->lit) {
        rgb[0] = rgb[1] = rgb[2] = 0.0f;
        return;
    }
    const float *n = pt->n;
    float nl = n[0] * q->l[0] + n[1] * q->l[1] + n[2] * q->l[2];
    float nh = n[0] * q->hv[0] + n[1] * q->hv[1] + n[2] * q->hv[2];
    float diff = nl > 0.0f ? nl : 0.0f, spec = 0.0f;
    /* nh^e < exp(-e (1 - nh)): beyond exp(-24) the lobe adds < 1e-6 even at ks 10, e 5000 */
    if (nh > 0.0f && diff > 0.0f && pt->ks > 0.0f && pt->expo * (1.0f - nh) < 24.0f)
        spec = pt->ks * (pt->expo + 8.0f) * 0.125f * powf(nh, pt->expo) * q->fres * diff;
    for (int c = 0; c < 3; c++)
        rgb[c] = gen_srgb(vis * (pt->albedo[c] * diff + spec) + GEN_AMBIENT * pt->albedo[c] * q->l[2]);
}

void btf_gen_model_eval(const btf_gen_model *m, int x, int y, const float light[3], const float view[3], float rgb[3])
{
    float l[3], v[3];
    gen_prep_light(light, l);
    gen_prep_view(view, v);
    x = gen_wrap(x, m->w), y = gen_wrap(y, m->h);
    gen_point pt;
    gen_visible(m, x, y, v, &pt);
    float vis = gen_mix4(pt.wt, gen_shadow(m, pt.idx[0], l), gen_shadow(m, pt.idx[1], l), gen_shadow(m, pt.idx[2], l),
                         gen_shadow(m, pt.idx[3], l));
    gen_lv q;
    gen_lv_make(l, v, &q);
    gen_shade(&pt, vis, &q, rgb);
}

void btf_gen_eval(const btf_gen_params *p, int w, int h, int x, int y, const float light[3], const float view[3],
                  float rgb[3])
{
    btf_gen_model *m = NULL;
    if (btf_gen_model_create(p, w, h, &m, NULL) != BTF_OK) {
        rgb[0] = rgb[1] = rgb[2] = 0.0f;
        return;
    }
    btf_gen_model_eval(m, x, y, light, view, rgb);
    btf_gen_model_free(m);
}

/* ---------------------------------------------------------------- whole BTF */

/* Shared state of one btf_gen_create run; lives on its stack. */
typedef struct gen_job {
    const btf_gen_model *m;
    btf *out;
    float (*ldir)[3], (*vdir)[3]; /* prepared directions */
    float *vis;                   /* n_lights x w*h shadow table */
    int failed;                   /* set by a thread that ran out of memory */
} gen_job;

/* The shadow table, one light per iteration on OpenMP's threads (OMP_NUM_THREADS). */
static void gen_shadow_rows(gen_job *j)
{
    int nl = j->out->lights.n_dirs, n = j->m->w * j->m->h;
#pragma omp parallel for schedule(static, 1)
    for (int l = 0; l < nl; l++)
        for (int i = 0; i < n; i++)
            j->vis[(size_t)l * (size_t)n + (size_t)i] = gen_shadow(j->m, i, j->ldir[l]);
}

/* Stores one image's sample i (byte/255 scale), rounding like btf_set. */
static void gen_store(btf *b, size_t base, size_t i, float v)
{
    if (b->storage == BTF_F32) {
        ((float *)b->data)[base + i] = v;
        return;
    }
    float q = v * 255.0f + 0.5f;
    ((uint8_t *)b->data)[base + i] = (uint8_t)(q > 255.0f ? 255.0f : q); /* v >= 0, never NaN */
}

/* View v's image under light l into j->out's view bv (v, or 0 in a one-view buffer). */
static void gen_light_image(gen_job *j, int v, int bv, int l, const gen_point *pts)
{
    btf *b = j->out;
    size_t n = (size_t)j->m->w * (size_t)j->m->h, base = btf_index(b, bv, l, 0, 0, 0);
    gen_lv q;
    gen_lv_make(j->ldir[l], j->vdir[v], &q);
    const float *vt = j->vis + (size_t)l * n;
    for (size_t i = 0; i < n; i++) {
        const gen_point *pt = &pts[i];
        float rgb[3], vis = gen_mix4(pt->wt, vt[pt->idx[0]], vt[pt->idx[1]], vt[pt->idx[2]], vt[pt->idx[3]]);
        gen_shade(pt, vis, &q, rgb);
        for (int c = 0; c < 3; c++)
            gen_store(b, base, 3 * i + (size_t)c, rgb[c]);
    }
}

/* Every view's images, one view per iteration on OpenMP's threads. */
static void gen_view_images(gen_job *j)
{
    const btf_gen_model *m = j->m;
    btf *b = j->out;
#pragma omp parallel
    {
        gen_point *pts = malloc((size_t)m->w * (size_t)m->h * sizeof *pts);
        if (!pts) {
#pragma omp atomic write
            j->failed = 1;
        }
#pragma omp for schedule(static, 1)
        for (int v = 0; v < b->views.n_dirs; v++) {
            for (int y = 0; pts && y < m->h; y++)
                for (int x = 0; x < m->w; x++)
                    gen_visible(m, x, y, j->vdir[v], &pts[(size_t)y * (size_t)m->w + (size_t)x]);
            for (int l = 0; pts && l < b->lights.n_dirs; l++)
                gen_light_image(j, v, v, l, pts);
        }
        free(pts);
    }
}

static btf_result gen_prepare_dirs(const btf_dirset *d, int is_view, float (**out)[3], btf_error *err)
{
    *out = malloc((size_t)d->n_dirs * sizeof **out);
    if (!*out)
        return btf_fail(err, BTF_ERR_NOMEM, "gen: no memory for %d directions", d->n_dirs);
    for (int i = 0; i < d->n_dirs; i++) {
        float v[3];
        btf_dirset_vector(d, i, v);
        if (is_view)
            gen_prep_view(v, (*out)[i]);
        else
            gen_prep_light(v, (*out)[i]);
    }
    return BTF_OK;
}

static btf_result gen_render(gen_job *j, btf_error *err)
{
    btf *b = j->out;
    size_t n = (size_t)j->m->w * (size_t)j->m->h;
    btf_result r = gen_prepare_dirs(&b->lights, 0, &j->ldir, err);
    if (r == BTF_OK)
        r = gen_prepare_dirs(&b->views, 1, &j->vdir, err);
    if (r != BTF_OK)
        return r;
    j->vis = malloc((size_t)b->lights.n_dirs * n * sizeof(float));
    if (!j->vis)
        return btf_fail(err, BTF_ERR_NOMEM, "gen: no memory for the shadow table (%d lights)", b->lights.n_dirs);
    gen_shadow_rows(j);
    gen_view_images(j);
    if (j->failed)
        return btf_fail(err, BTF_ERR_NOMEM, "gen: no memory for a view's visible points");
    return BTF_OK;
}

btf_result btf_gen_create(const btf_gen_params *p, int w, int h, const btf_dirset *lights, const btf_dirset *views,
                          btf_storage storage, btf **out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "gen: out is NULL");
    *out = NULL;
    if (!lights || !views || lights->n_dirs < 1 || views->n_dirs < 1)
        return btf_fail(err, BTF_ERR_ARG, "gen: empty or missing direction set");
    btf_gen_model *m = NULL;
    btf *b = NULL;
    btf_result r = btf_gen_model_create(p, w, h, &m, err);
    if (r == BTF_OK)
        r = btf_create(w, h, lights, views, storage, &b, err);
    if (r == BTF_OK) {
        gen_job j = {m, b, NULL, NULL, NULL, 0};
        r = gen_render(&j, err);
        free(j.ldir);
        free(j.vdir);
        free(j.vis);
    }
    btf_gen_model_free(m);
    if (r != BTF_OK) {
        btf_free(b);
        return r;
    }
    *out = b;
    return BTF_OK;
}

/* ---------------------------------------------------------------- view by view */

/* A generated material rendered one view per fill; heap, owned by its btf_views
 * (impl), freed by gen_views_close. */
typedef struct gen_views {
    btf_gen_model *m;
    gen_job j;       /* j.out = &one */
    btf one;         /* one view's images (U8), view 0 = the view filled */
    gen_point *pts;  /* the view's visible points */
} gen_views;

static void gen_views_close(btf_views *s)
{
    gen_views *g = s->impl;
    if (!g)
        return;
    btf_gen_model_free(g->m);
    free(g->j.ldir), free(g->j.vdir), free(g->j.vis), free(g->one.data), free(g->pts), free(g);
}

static btf_result gen_views_fill(btf_views *s, int v, float *cols, btf_error *err)
{
    (void)err;
    gen_views *g = s->impl;
    const btf_gen_model *m = g->m;
    int L = s->lights.n_dirs;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < m->h; y++)
        for (int x = 0; x < m->w; x++)
            gen_visible(m, x, y, g->j.vdir[v], &g->pts[(size_t)y * (size_t)m->w + (size_t)x]);
#pragma omp parallel for schedule(dynamic, 1)
    for (int l = 0; l < L; l++)
        gen_light_image(&g->j, v, 0, l, g->pts);
    size_t texels = (size_t)m->w * (size_t)m->h;
    for (int l = 0; l < L; l++)
        btf_views_put_u8((const uint8_t *)g->one.data + (size_t)l * texels * 3u, texels, cols + (size_t)l * 3u * texels);
    return BTF_OK;
}

btf_result btf_gen_views_open(const btf_gen_params *p, int w, int h, const btf_dirset *lights, const btf_dirset *views,
                              btf_views *out, btf_error *err)
{
    if (!out)
        return btf_fail(err, BTF_ERR_ARG, "gen: out is NULL");
    memset(out, 0, sizeof *out);
    if (!lights || !views || lights->n_dirs < 1 || views->n_dirs < 1)
        return btf_fail(err, BTF_ERR_ARG, "gen: empty or missing direction set");
    gen_views *g = calloc(1, sizeof *g);
    if (!g)
        return btf_fail(err, BTF_ERR_NOMEM, "gen: out of memory");
    out->impl = g, out->close = gen_views_close, out->fill = gen_views_fill, out->name = "generated material";
    out->width = w, out->height = h, out->lights = *lights, out->views = *views;
    btf_result r = btf_gen_model_create(p, w, h, &g->m, err);
    size_t texels = (size_t)w * (size_t)h;
    if (r == BTF_OK) {
        g->one = (btf){w, h, *lights, *views, BTF_U8, NULL, (size_t)lights->n_dirs * texels * 3};
        g->one.data = malloc(g->one.count);
        g->pts = malloc(texels * sizeof *g->pts);
        g->j.m = g->m, g->j.out = &g->one;
        if (!g->one.data || !g->pts)
            r = btf_fail(err, BTF_ERR_NOMEM, "gen: out of memory (one view of %d images)", lights->n_dirs);
    }
    if (r == BTF_OK)
        r = gen_prepare_dirs(lights, 0, &g->j.ldir, err);
    if (r == BTF_OK)
        r = gen_prepare_dirs(views, 1, &g->j.vdir, err);
    if (r == BTF_OK && !(g->j.vis = malloc((size_t)lights->n_dirs * texels * sizeof(float))))
        r = btf_fail(err, BTF_ERR_NOMEM, "gen: no memory for the shadow table (%d lights)", lights->n_dirs);
    if (r == BTF_OK)
        gen_shadow_rows(&g->j);
    if (r != BTF_OK)
        btf_views_close(out);
    return r;
}
