// btf_decode.glsl - PCA package decoder: the GLSL twin of btf_decode
// (codec/btf_decode.c, doc/package-format.md section 6), operation by operation in
// float. Needs btf_dirs.glsl before it. Tested against the CPU decoder on both
// headless backends (tests/test_gl.c).
//
// Public:  vec3 btf_decode_lod(vec2 uv, vec3 light, vec3 view, float lod)
//          vec3 btf_decode(vec2 uv, vec3 light, vec3 view)   (lod = u_btf_lod)
//   uv in [0,1] (u along x = columns, v along y = image rows), light/view in the
//   local frame (z = normal, need not be unit). Result on the byte/255 scale, not
//   clamped. The host fills the uniforms below (C: btf_gl_package_bind).
//
// Textures, all read with texelFetch (no filtering, no float-filter extension);
// slot s = the s-th distinct component of the loaded chunks (version 1: chunk s),
// N = max(u_btf_levels, 1) spatial levels (shaders/README.md, "Spatial levels"):
//   u_btf_tex         layer s, mip level l = texture atlas of slot s at level l, R8
//                     (8-bit package) or RGB8 (16-bit: q = R*256 + G, as in the PNG)
//   u_btf_wt          layer s = weights of slot s, RGB32F, texel (light, view)
//   u_btf_range       RGBA32F, texel (block, s*N + l) = (lo, step, fine, coarse):
//                     T = lo + step * q; [fine, coarse] = loaded levels of slot s
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
uniform int u_btf_chunks;    // slots to use, 1..uploaded (version 1: chunks)
uniform int u_btf_levels;    // spatial levels N (0 or 1: none)
uniform float u_btf_lod;     // lod of btf_decode (0 = finest)
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

// Taps on the tile of level `level`: (W >> level) x (H >> level) texels.
btf_taps btf_texel_taps(vec2 uv, int level)
{
    btf_taps t;
    ivec2 isize = u_btf_size >> level;
    vec2 size = vec2(isize);
    vec2 f = clamp(uv, -1e6, 1e6) * size;
    if (u_btf_filter != 1) {
        t.n = 1;
        t.p[0] = ivec2(btf_wrap_or_clamp(int(floor(f.x)), isize.x), btf_wrap_or_clamp(int(floor(f.y)), isize.y));
        t.p[1] = t.p[2] = t.p[3] = t.p[0];
        t.w = vec4(1.0, 0.0, 0.0, 0.0);
        return t;
    }
    f -= 0.5;
    vec2 f0 = floor(f), a = f - f0;
    int x0 = int(f0.x), y0 = int(f0.y);
    int xs0 = btf_wrap_or_clamp(x0, isize.x), xs1 = btf_wrap_or_clamp(x0 + 1, isize.x);
    int ys0 = btf_wrap_or_clamp(y0, isize.y), ys1 = btf_wrap_or_clamp(y0 + 1, isize.y);
    t.n = 4;
    t.p[0] = ivec2(xs0, ys0);
    t.p[1] = ivec2(xs1, ys0);
    t.p[2] = ivec2(xs0, ys1);
    t.p[3] = ivec2(xs1, ys1);
    t.w = vec4((1.0 - a.x) * (1.0 - a.y), a.x * (1.0 - a.y), (1.0 - a.x) * a.y, a.x * a.y);
    return t;
}

// Quantised value q (0..255 or 0..65535) at atlas pixel p of slot j, mip level l.
float btf_tex_q(int j, ivec2 p, int l)
{
    vec4 s = texelFetch(u_btf_tex, ivec3(p, j), l);
    if (u_btf_bits == 16)
        return round(s.r * 255.0) * 256.0 + round(s.g * 255.0);
    return round(s.r * 255.0);
}

// Filtered, dequantised texture value of slot j at level l with range (lo, step),
// on the atlas tile starting at texel `tile` (of that level).
float btf_tex(int j, int l, vec2 range, ivec2 tile, btf_taps t)
{
    float s = 0.0;
    for (int i = 0; i < 4; i++) {
        if (i >= t.n)
            break;
        s += t.w[i] * (range.x + range.y * btf_tex_q(j, tile + t.p[i], l));
    }
    return s;
}

// Texture value of slot j in block b at `lod`: clamped to the slot's loaded levels
// [fine, coarse], trilinear between floor(lod) and the next level (the twin of
// btf__decode_levels in codec/btf_decode.c). tile0 = the block's level-0 tile origin,
// taps0 = the level-0 taps of uv.
float btf_tex_lod(int j, int b, ivec2 tile0, vec2 uv, btf_taps taps0, float lod)
{
#ifdef BTF_NO_LEVELS
    // optional host define for packages without levels (btf render sets it for
    // version 1): level 0 with a constant mip level, a third less time on llvmpipe
    return btf_tex(j, 0, texelFetch(u_btf_range, ivec2(b, j), 0).xy, tile0, taps0);
#endif
    int n = max(u_btf_levels, 1);
    vec4 r0 = texelFetch(u_btf_range, ivec2(b, j * n), 0);
    float lc = clamp(lod, r0.z, r0.w);
    int l0 = int(floor(lc)), l1 = min(l0 + 1, int(r0.w));
    float f = lc - float(l0);
    float t = 0.0;
    for (int i = 0; i < 2; i++) {
        if (i == 1 && f == 0.0)
            break;
        int l = i == 0 ? l0 : l1;
        // range and taps of level l (level 0: r0 and taps0); a loop, not an if, so
        // that SIMD software rasterisers (llvmpipe) skip it when every lane is at
        // level 0 (version 1 packages)
        vec2 range = r0.xy;
        btf_taps tp = taps0;
        for (int k = 0; k < 1; k++) {
            if (l == 0)
                break;
            range = texelFetch(u_btf_range, ivec2(b, j * n + l), 0).xy;
            tp = btf_texel_taps(uv, l);
        }
        t += (i == 0 ? 1.0 - f : f) * btf_tex(j, l, range, tile0 >> l, tp);
    }
    return t;
}

vec3 btf_decode_lod(vec2 uv, vec3 light, vec3 view, float lod)
{
    btf_taps taps0 = btf_texel_taps(uv, 0);
    btf_interp il = btf_dirs_interp_vec(u_btf_lights, light);
    btf_interp iv = btf_dirs_interp_vec(u_btf_views, view);
    vec3 rgb = vec3(0.0);
    for (int a = 0; a < 3; a++) {
        if (iv.w[a] == 0.0)
            continue;
        int vi = iv.idx[a];
        int b = int(texelFetch(u_btf_view_block, ivec2(vi, 0), 0).r);
        // level-0 atlas tile of block b (column, row), once per view
        ivec2 tile = btf_divmod(b, u_btf_atlas_cols).yx * u_btf_size;
        for (int j = 0; j < BTF_MAX_CHUNKS; j++) {
            if (j >= u_btf_chunks)
                break;
            float t = btf_tex_lod(j, b, tile, uv, taps0, lod);
            vec3 s = vec3(0.0); // sum over the 3 lights of wl * Wt_j[vi][li]
            for (int e = 0; e < 3; e++)
                if (il.w[e] != 0.0)
                    s += il.w[e] * texelFetch(u_btf_wt, ivec3(il.idx[e], vi, j), 0).rgb;
            rgb += iv.w[a] * t * s;
        }
    }
    return rgb;
}

vec3 btf_decode(vec2 uv, vec3 light, vec3 view)
{
    return btf_decode_lod(uv, light, view, u_btf_lod);
}
