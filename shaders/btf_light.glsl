// btf_light.glsl - the light of btf_render.frag (doc/lighting.md): the point light and
// the environment light of one fragment in one pass over the texture values. Needs
// btf_dirs.glsl, btf_decode.glsl (it reuses the decoder's taps, texture reads and
// weight sums) and btf_tone.glsl (the lights' uniforms) before it.
//
// Public:  void btf_light_decode(vec2 uv, vec3 light, vec3 view, mat3 frame, float lod,
//                                out vec3 point, out vec3 env)
//            point: btf_decode_lod's value (the package's encoding); env: the light sum
//            S2 of the environment's order-2 quadratic (doc/lighting.md section 3) in
//            the local frame `frame` = [t b n] (world columns)
//          vec3 btf_light_linear(vec3 v)   package encoding -> linear light

uniform highp usampler2DArray u_btf_env_w; // RGBA32UI, texel (j, view), layer h: channel c = slot 4h+c's G_j as
                                           // R (bits 0..10) | G (11..21) | B (22..31), signed around 1024, 1024, 512
uniform vec4 u_btf_env_s[BTF_MAX_CHUNKS / 4]; // per 4 slots: the scale s of G = s (q - m) / (m - 1), m that middle
uniform int u_btf_linear; // 1: the package holds linear light; 0: sRGB-encoded values

// The nine local coefficients E_j (one value per channel) of doc/lighting.md section 3,
// divided by the quantisation's m - 1 (1023, 1023, 511), and in off the sum of E_j m
// (what the unsigned codes add).
void btf_light_env_coeffs(mat3 F, out vec3 e[9], out vec3 off)
{
    mat3 Ft = transpose(F);
    mat3 A = Ft * u_env_a; // column ch: F^T a_ch
    mat3 q0 = Ft * u_env_q[0] * F, q1 = Ft * u_env_q[1] * F, q2 = Ft * u_env_q[2] * F;
    vec3 zz = vec3(q0[2][2], q1[2][2], q2[2][2]);
    e[0] = u_env_c0 + zz;
    e[1] = vec3(A[0][0], A[1][0], A[2][0]);
    e[2] = vec3(A[0][1], A[1][1], A[2][1]);
    e[3] = vec3(A[0][2], A[1][2], A[2][2]);
    e[4] = vec3(q0[0][0], q1[0][0], q2[0][0]) - zz;
    e[5] = vec3(q0[1][1], q1[1][1], q2[1][1]) - zz;
    e[6] = 2.0 * vec3(q0[0][1], q1[0][1], q2[0][1]);
    e[7] = 2.0 * vec3(q0[0][2], q1[0][2], q2[0][2]);
    e[8] = 2.0 * vec3(q0[1][2], q1[1][2], q2[1][2]);
    vec3 sum = vec3(0.0);
    for (int j = 0; j < 9; j++) {
        e[j] /= vec3(1023.0, 1023.0, 511.0);
        sum += e[j];
    }
    off = sum * vec3(1024.0, 1024.0, 512.0);
}

// RGB of slots 4h..4h+3 with texture values T at view vi under the environment: nine
// texels, one per function j, each holding the 4 slots' RGB codes. Slots beyond
// u_btf_chunks count 0 (the point light zeroes their weight grids instead).
vec3 btf_light_env_quad(int h, vec4 T, int vi, vec3 e[9], vec3 off)
{
    T *= u_btf_env_s[h] * vec4(lessThan(ivec4(4 * h) + ivec4(0, 1, 2, 3), ivec4(u_btf_chunks)));
    vec4 r = vec4(-off.r), g = vec4(-off.g), b = vec4(-off.b);
    for (int j = 0; j < 9; j++) {
        uvec4 u = texelFetch(u_btf_env_w, ivec3(j, vi, h), 0);
        r += e[j].r * vec4(u & 2047u);
        g += e[j].g * vec4(u >> 11 & 2047u);
        b += e[j].b * vec4(u >> 22);
    }
    return vec3(dot(T, r), dot(T, g), dot(T, b));
}

// One view sample of both lights (the texture values read once).
#define BTF__LIGHT_QUAD(h)                                                                                       \
    {                                                                                                            \
        vec4 T = u_btf_tq[2 * (h)] + u_btf_tq[2 * (h) + 1] * btf_tex_quad(h, tile, l0, xy0, a0, l1, xy1, a1, f); \
        if (BTF__POINT)                                                                                          \
            pt += btf_quad(h, T, vi, il);                                                                        \
        if (BTF__ENV)                                                                                            \
            en += btf_light_env_quad(h, T, vi, e, off);                                                               \
    }
void btf_light_view_sample(int vi, int b, btf_interp il, vec3 e[9], vec3 off, int l0, ivec4 xy0, vec2 a0, int l1, ivec4 xy1,
                           vec2 a1, float f, out vec3 pt, out vec3 en)
{
    ivec2 tile = btf_divmod(b, u_btf_atlas_cols).yx * u_btf_size;
    pt = vec3(0.0);
    en = vec3(0.0);
#ifdef BTF_QUADS
    BTF__LIGHT_QUAD(0)
#if BTF_QUADS > 1
    BTF__LIGHT_QUAD(1)
#endif
#if BTF_QUADS > 2
    BTF__LIGHT_QUAD(2)
#endif
#if BTF_QUADS > 3
    BTF__LIGHT_QUAD(3)
#endif
#if BTF_QUADS > 4
    BTF__LIGHT_QUAD(4)
#endif
#if BTF_QUADS > 5
    BTF__LIGHT_QUAD(5)
#endif
#if BTF_QUADS > 6
    BTF__LIGHT_QUAD(6)
#endif
#if BTF_QUADS > 7
    BTF__LIGHT_QUAD(7)
#endif
#if BTF_QUADS > 8
    BTF__LIGHT_QUAD(8)
#endif
#if BTF_QUADS > 9
    BTF__LIGHT_QUAD(9)
#endif
#if BTF_QUADS > 10
    BTF__LIGHT_QUAD(10)
#endif
#if BTF_QUADS > 11
    BTF__LIGHT_QUAD(11)
#endif
#if BTF_QUADS > 12
    BTF__LIGHT_QUAD(12)
#endif
#if BTF_QUADS > 13
    BTF__LIGHT_QUAD(13)
#endif
#if BTF_QUADS > 14
    BTF__LIGHT_QUAD(14)
#endif
#if BTF_QUADS > 15
    BTF__LIGHT_QUAD(15)
#endif
#else
    int quads = max((u_btf_chunks + 3) / 4, 1);
    for (int h = 0; h < quads; h++)
        BTF__LIGHT_QUAD(h)
#endif
}

void btf_light_decode(vec2 uv, vec3 light, vec3 view, mat3 frame, float lod, out vec3 point, out vec3 env)
{
    btf_taps t = btf_decode_taps(uv, lod);
    int l0 = t.l0, l1 = t.l1;
    float f = t.f;
    ivec4 xy0 = t.xy0, xy1 = t.xy1;
    vec2 a0 = t.a0, a1 = t.a1;
    btf_interp il;
    if (BTF__POINT && !BTF__FIXED)
        il = btf_dirs_interp_vec(0, light);
    vec3 e[9], off;
    if (BTF__ENV)
        btf_light_env_coeffs(frame, e, off);
    btf_interp iv = btf_dirs_interp_vec(1, view);
    vec3 p, q;
    btf_light_view_sample(iv.idx.x, iv.blk.x, il, e, off, l0, xy0, a0, l1, xy1, a1, f, p, q);
    point = iv.w.x * p;
    env = iv.w.x * q;
    btf_light_view_sample(iv.idx.y, iv.blk.y, il, e, off, l0, xy0, a0, l1, xy1, a1, f, p, q);
    point += iv.w.y * p;
    env += iv.w.y * q;
    btf_light_view_sample(iv.idx.z, iv.blk.z, il, e, off, l0, xy0, a0, l1, xy1, a1, f, p, q);
    point += iv.w.z * p;
    env += iv.w.z * q;
}

vec3 btf_light_linear(vec3 v)
{
    return u_btf_linear != 0 ? max(v, 0.0) : btf_tone_srgb_decode(v);
}
