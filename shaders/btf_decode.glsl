// btf_decode.glsl - PCA package decoder: the GLSL twin of btf_decode
// (codec/btf_decode.c, doc/package-format.md section 6), operation by operation in
// float. Needs btf_dirs.glsl before it. Tested against the CPU decoder on both
// headless backends (tests/test_gl.c).
//
// Public:  vec3 btf_decode(vec2 uv, vec3 light, vec3 view)
//   uv in [0,1] (u along x = columns, v along y = image rows), light/view in the
//   local frame (z = normal, need not be unit). Result on the byte/255 scale, not
//   clamped. The host fills the uniforms below (C: btf_gl_package_bind).
//
// Textures, all read with texelFetch (no filtering, no float-filter extension):
//   u_btf_tex         layer j = component texture atlas of chunk j, R8 (8-bit package)
//                     or RGB8 (16-bit: q = R*256 + G, the bytes as stored in the PNG)
//   u_btf_wt          layer j = weights of chunk j, RGB32F, texel (light, view)
//   u_btf_range       RGBA32F, texel (block, chunk) = (lo, step, -, -): T = lo + step * q
//   u_btf_view_block  RGBA32F, texel (view, 0).r = block of that view

#ifndef BTF_MAX_CHUNKS
#define BTF_MAX_CHUNKS 64
#endif

uniform sampler2DArray u_btf_tex;
uniform sampler2DArray u_btf_wt;
uniform sampler2D u_btf_range;
uniform sampler2D u_btf_view_block;
uniform btf_dirset u_btf_lights;
uniform btf_dirset u_btf_views;
uniform ivec2 u_btf_size;    // W, H texels of the material (= one atlas tile)
uniform int u_btf_atlas_cols;
uniform int u_btf_bits;      // 8 or 16
uniform int u_btf_chunks;    // chunks to use, 1..uploaded
uniform int u_btf_filter;    // 0 nearest, 1 bilinear
uniform int u_btf_wrap;      // 1 tile (indices modulo the size), 0 clamp to the edge

// Up to 4 texels of one tile and their filter weights.
struct btf_taps {
    ivec2 p[4];
    vec4 w;
    int n;
};

int btf_wrap_or_clamp(int i, int n)
{
    return u_btf_wrap != 0 ? btf_divmod(i, n).y : clamp(i, 0, n - 1);
}

btf_taps btf_texel_taps(vec2 uv)
{
    btf_taps t;
    vec2 size = vec2(u_btf_size);
    vec2 f = clamp(uv, -1e6, 1e6) * size;
    if (u_btf_filter != 1) {
        t.n = 1;
        t.p[0] = ivec2(btf_wrap_or_clamp(int(floor(f.x)), u_btf_size.x), btf_wrap_or_clamp(int(floor(f.y)), u_btf_size.y));
        t.p[1] = t.p[2] = t.p[3] = t.p[0];
        t.w = vec4(1.0, 0.0, 0.0, 0.0);
        return t;
    }
    f -= 0.5;
    vec2 f0 = floor(f), a = f - f0;
    int x0 = int(f0.x), y0 = int(f0.y);
    int xs0 = btf_wrap_or_clamp(x0, u_btf_size.x), xs1 = btf_wrap_or_clamp(x0 + 1, u_btf_size.x);
    int ys0 = btf_wrap_or_clamp(y0, u_btf_size.y), ys1 = btf_wrap_or_clamp(y0 + 1, u_btf_size.y);
    t.n = 4;
    t.p[0] = ivec2(xs0, ys0);
    t.p[1] = ivec2(xs1, ys0);
    t.p[2] = ivec2(xs0, ys1);
    t.p[3] = ivec2(xs1, ys1);
    t.w = vec4((1.0 - a.x) * (1.0 - a.y), a.x * (1.0 - a.y), (1.0 - a.x) * a.y, a.x * a.y);
    return t;
}

// Quantised value q (0..255 or 0..65535) at atlas pixel p of chunk j.
float btf_tex_q(int j, ivec2 p)
{
    vec4 s = texelFetch(u_btf_tex, ivec3(p, j), 0);
    if (u_btf_bits == 16)
        return round(s.r * 255.0) * 256.0 + round(s.g * 255.0);
    return round(s.r * 255.0);
}

// Filtered, dequantised texture value of chunk j in block b, whose atlas tile starts
// at texel `tile`.
float btf_tex(int j, int b, ivec2 tile, btf_taps t)
{
    vec2 range = texelFetch(u_btf_range, ivec2(b, j), 0).xy;
    float s = 0.0;
    for (int i = 0; i < 4; i++) {
        if (i >= t.n)
            break;
        s += t.w[i] * (range.x + range.y * btf_tex_q(j, tile + t.p[i]));
    }
    return s;
}

vec3 btf_decode(vec2 uv, vec3 light, vec3 view)
{
    btf_taps taps = btf_texel_taps(uv);
    btf_interp il = btf_dirs_interp_vec(u_btf_lights, light);
    btf_interp iv = btf_dirs_interp_vec(u_btf_views, view);
    vec3 rgb = vec3(0.0);
    for (int a = 0; a < 3; a++) {
        if (iv.w[a] == 0.0)
            continue;
        int vi = iv.idx[a];
        int b = int(texelFetch(u_btf_view_block, ivec2(vi, 0), 0).r);
        // atlas tile of block b (column, row), once per view
        ivec2 tile = btf_divmod(b, u_btf_atlas_cols).yx * u_btf_size;
        for (int j = 0; j < BTF_MAX_CHUNKS; j++) {
            if (j >= u_btf_chunks)
                break;
            float t = btf_tex(j, b, tile, taps);
            vec3 s = vec3(0.0); // sum over the 3 lights of wl * Wt_j[vi][li]
            for (int e = 0; e < 3; e++)
                if (il.w[e] != 0.0)
                    s += il.w[e] * texelFetch(u_btf_wt, ivec3(il.idx[e], vi, j), 0).rgb;
            rgb += iv.w[a] * t * s;
        }
    }
    return rgb;
}
