// btf_decode.glsl - PCA package decoder: the GLSL twin of btf_decode
// (codec/decompress/btf_decode.c, doc/package-format.md section 6) on the packed GPU layout of
// shaders/README.md ("GPU layout"). Needs btf_dirs.glsl before it. Tested against the
// CPU decoder on both headless backends (tests/gl/test_gl.c, tests/gl/test_lod_gl.c).
//
// Public:  vec3 btf_decode_lod(vec2 uv, vec3 light, vec3 view, float lod)
//          vec3 btf_decode(vec2 uv, vec3 light, vec3 view)   (lod = u_btf_lod)
//   uv in [0,1] (u along x = columns, v along y = image rows), light/view in the
//   local frame (z = normal, need not be unit). Result on the byte/255 scale, not
//   clamped. The host fills the uniforms below (C: btf_gl_package_bind).
//
// Textures (texelFetch only: no filtering, no float textures, WebGL2 core formats);
// slot s = the s-th distinct component of the loaded chunks (version 1: chunk s):
//   u_btf_tex  RGBA16UI array, layer h, mip level l: atlas of slots 4h..4h+3 at level l,
//              channel c = slot 4h+c as a 16-bit value q;
//              T_s = u_btf_tq[2h].[s-4h] + u_btf_tq[2h+1].[s-4h] * q (h = s / 4). A level a
//              slot has not loaded holds its nearest loaded level (finer levels: the
//              coarse texel repeated; coarser: the finer texel at the centre). Paired
//              (levels and nearest taps, BTF__PAIRED below) RGBA32UI: q in bits 0..15,
//              and in bits 16..31 the q of texel p / 2 of level l + 1 (0 at the top level)
//   u_btf_wt   RGBA32UI array, layer h = slots 4h..4h+3, texel (light, view): channel c =
//              slot 4h+c as R (bits 0..10) | G (11..21) | B (22..31);
//              W = u_btf_wq[6h + ch] + u_btf_wq[6h + 3 + ch] * q per colour channel ch
//   The view's block: btf_interp.blk (bits 12.. of the view vertex's .w in btf_dirs_block).
// Per fragment: 2 direction texels, then per view sample (3): one u_btf_tex texel per
// 4 slots (4 bilinear, twice between two levels; nearest: one for both levels) and per
// light sample (3) one u_btf_wt texel per 4 slots: 2 + 3 * (ceil(C/4) + 3 ceil(C/4)) = 2 + 12 ceil(C/4) texels, nearest;
// with BTF_FIXED_LIGHT (below) no light lookup and one u_btf_lw texel per view sample
// and 4 slots: 1 + 6 ceil(C/4).

#ifndef BTF_MAX_CHUNKS
#define BTF_MAX_CHUNKS 64
#endif

uniform highp usampler2DArray u_btf_tex;
uniform highp usampler2DArray u_btf_wt;
uniform vec4 u_btf_tq[BTF_MAX_CHUNKS / 2];     // per 4 slots: lo, step of T
uniform vec4 u_btf_wq[BTF_MAX_CHUNKS / 4 * 6]; // per 4 slots: lo R, G, B, step R, G, B of W
uniform ivec2 u_btf_size;    // W, H texels of the material (= one atlas tile)
uniform int u_btf_atlas_cols;
uniform int u_btf_chunks;    // slots to use, 1..uploaded (version 1: chunks)
uniform int u_btf_levels;    // spatial levels N (0 or 1: none)
uniform float u_btf_lod;     // lod of btf_decode (0 = finest)
uniform int u_btf_filter;    // 0 nearest, 1 bilinear
uniform int u_btf_wrap;      // 1 tile (indices modulo the size), 0 clamp to the edge

// Host specialisation: BTF_FILTER (0 nearest, 1 bilinear) and BTF_LEVELS (0: level 0
// only, 1: the level blend) fix at compile time what u_btf_filter / u_btf_levels
// otherwise choose at run time. SIMD software rasterisers (llvmpipe) run both sides
// of every branch and every loop at least once, whatever the condition, so a program
// compiled for the package and filter skips the work it cannot need.
#ifdef BTF_FILTER
#define BTF__BILINEAR (BTF_FILTER == 1)
#else
#define BTF__BILINEAR (u_btf_filter == 1)
#endif
#ifdef BTF_LEVELS
#define BTF__LEVELS (BTF_LEVELS == 1)
#else
#define BTF__LEVELS (u_btf_levels > 1)
#endif
// Paired levels (shaders/README.md, "GPU layout"): the hosts lay u_btf_tex out as
// RGBA32UI, each level's texel with the next coarser level's beside it, exactly where
// the level blend runs on nearest taps (btf_tex_quad reads one texel for both levels);
// with bilinear taps, or without levels, it stays RGBA16UI.
#define BTF__PAIRED (BTF__LEVELS && !BTF__BILINEAR)

// Host specialisation BTF_FIXED_LIGHT (1): the light has one local direction at every
// fragment of the draw (a distant light on a flat surface), so the host blends each
// slot's weights over the light's three samples once per draw (C: btf_gl_fixed_update)
// into u_btf_lw, texel (view, h) = slots 4h..4h+3 as R (bits 0..10) | G (11..21) |
// B (22..31) on per-draw grids (u_btf_lq[6h + k]: lo of R, G, B; [6h + 3 + k]: steps),
// and the decoder reads one weight texel per view sample and layer instead of three,
// and looks no light direction up (the `light` arguments are ignored).
#if defined(BTF_FIXED_LIGHT) && BTF_FIXED_LIGHT == 1
#define BTF__FIXED true
uniform highp usampler2D u_btf_lw;
uniform vec4 u_btf_lq[BTF_MAX_CHUNKS / 4 * 6];
#else
#define BTF__FIXED false
#endif

// (floor(a / n), a - n * floor(a / n)) for n > 0 and |a| < 2^24: the quotient in
// float (GPU division may be off by one ulp, the two corrections fix that), because
// integer division runs one lane at a time on CPU rasterizers (llvmpipe), and GLSL ES
// leaves % of negative operands undefined.
ivec2 btf_divmod(int a, int n)
{
    int q = int(floor(float(a) / float(n)));
    int m = a - n * q;
    q -= m < 0 ? 1 : 0;
    m += m < 0 ? n : 0;
    q += m >= n ? 1 : 0;
    m -= m >= n ? n : 0;
    return ivec2(q, clamp(m, 0, n - 1)); // in range even where |a| >= 2^24 is inexact
}

int btf_wrap_or_clamp(int i, int n)
{
    return u_btf_wrap != 0 ? btf_divmod(i, n).y : clamp(i, 0, n - 1);
}

// Texel columns and rows on the tile of level `level`, (W >> level) x (H >> level)
// texels: (x0, x1, y0, y1) of the bilinear footprint (nearest: x0 = x1, y0 = y1), and
// in a the bilinear fractions.
ivec4 btf_texel_taps(vec2 uv, int level, out vec2 a)
{
    ivec2 isize = u_btf_size >> level;
    vec2 f = clamp(uv, -1e6, 1e6) * vec2(isize);
    if (!BTF__BILINEAR) {
        a = vec2(0.0);
        ivec2 p = ivec2(floor(f));
        p = ivec2(btf_wrap_or_clamp(p.x, isize.x), btf_wrap_or_clamp(p.y, isize.y));
        return p.xxyy;
    }
    f -= 0.5;
    vec2 f0 = floor(f);
    a = f - f0;
    int x0 = int(f0.x), y0 = int(f0.y);
    return ivec4(btf_wrap_or_clamp(x0, isize.x), btf_wrap_or_clamp(x0 + 1, isize.x), btf_wrap_or_clamp(y0, isize.y),
                 btf_wrap_or_clamp(y0 + 1, isize.y));
}

// 16-bit values of slots 4h..4h+3 at texel p of level l (not paired: btf_tex_quad reads
// paired texels itself).
vec4 btf_tex4(int h, int l, ivec2 p)
{
    return vec4(texelFetch(u_btf_tex, ivec3(p, h), l));
}

// One level's filtered value of slots 4h..4h+3 on the tile of block origin `tile`
// (level 0) (nearest: tap 0 only).
vec4 btf_tex_level(int h, int l, ivec2 tile, ivec4 xy, vec2 a)
{
    ivec2 t = tile >> l;
    vec4 q = btf_tex4(h, l, t + xy.xz);
    if (BTF__BILINEAR)
        q = (1.0 - a.y) * ((1.0 - a.x) * q + a.x * btf_tex4(h, l, t + xy.yz)) +
            a.y * ((1.0 - a.x) * btf_tex4(h, l, t + xy.xw) + a.x * btf_tex4(h, l, t + xy.yw));
    return q;
}

// Filtered values of slots 4h..4h+3 on the tile of block origin `tile` (level 0):
// level l0 with weight 1 - f and level l1 = l0 + 1 (l0 at the top, f = 0) with weight
// f. Paired, texel p of level l holds in its high halves texel p / 2 of level l + 1,
// the nearest tap of l1 where p is that of l0 (2^(N-1) divides the tile's sides), so
// one read serves both levels; bilinear taps read each level's own four texels.
vec4 btf_tex_quad(int h, ivec2 tile, int l0, ivec4 xy0, vec2 a0, int l1, ivec4 xy1, vec2 a1, float f)
{
    if (BTF__PAIRED) {
        uvec4 u = texelFetch(u_btf_tex, ivec3((tile >> l0) + xy0.xz, h), l0);
        return mix(vec4(u & 65535u), vec4(u >> 16), f);
    }
    vec4 q = btf_tex_level(h, l0, tile, xy0, a0);
    if (BTF__LEVELS)
        q = mix(q, btf_tex_level(h, l1, tile, xy1, a1), f);
    return q;
}

// RGB of the 4 slots 4h..4h+3 with texture values T at view vi: the three light
// samples' weights interpolated as integers and dequantised once (the light
// weights sum to 1: lo + step * sum(w q) = sum(w (lo + step q))).
vec3 btf_quad(int h, vec4 T, int vi, btf_interp il)
{
#if defined(BTF_FIXED_LIGHT) && BTF_FIXED_LIGHT == 1
    uvec4 u = texelFetch(u_btf_lw, ivec2(vi, h), 0);
    vec4 wr = u_btf_lq[6 * h] + u_btf_lq[6 * h + 3] * vec4(u & 2047u);
    vec4 wg = u_btf_lq[6 * h + 1] + u_btf_lq[6 * h + 4] * vec4(u >> 11 & 2047u);
    vec4 wb = u_btf_lq[6 * h + 2] + u_btf_lq[6 * h + 5] * vec4(u >> 22);
#else
    uvec4 u0 = texelFetch(u_btf_wt, ivec3(il.idx.x, vi, h), 0);
    uvec4 u1 = texelFetch(u_btf_wt, ivec3(il.idx.y, vi, h), 0);
    uvec4 u2 = texelFetch(u_btf_wt, ivec3(il.idx.z, vi, h), 0);
    vec4 qr = il.w.x * vec4(u0 & 2047u) + il.w.y * vec4(u1 & 2047u) + il.w.z * vec4(u2 & 2047u);
    vec4 qg = il.w.x * vec4(u0 >> 11 & 2047u) + il.w.y * vec4(u1 >> 11 & 2047u) + il.w.z * vec4(u2 >> 11 & 2047u);
    vec4 qb = il.w.x * vec4(u0 >> 22) + il.w.y * vec4(u1 >> 22) + il.w.z * vec4(u2 >> 22);
    vec4 wr = u_btf_wq[6 * h] + u_btf_wq[6 * h + 3] * qr;
    vec4 wg = u_btf_wq[6 * h + 1] + u_btf_wq[6 * h + 4] * qg;
    vec4 wb = u_btf_wq[6 * h + 2] + u_btf_wq[6 * h + 5] * qb;
#endif
    return vec3(dot(T, wr), dot(T, wg), dot(T, wb));
}

// One view sample: view vi of block b, every slot in use. With BTF_QUADS
// (host specialisation: the number of 4-slot layers in use, 1..16) the layers are
// written out with constant indices; without it, a loop (a SIMD software rasteriser
// gathers a uniform array lane by lane when the index is a loop variable, and runs
// a loop's body at least once).
#define BTF__QUAD(h) btf_quad(h, u_btf_tq[2 * (h)] + u_btf_tq[2 * (h) + 1] * btf_tex_quad(h, tile, l0, xy0, a0, l1, xy1, a1, f), vi, il)
vec3 btf_view_sample(int vi, int b, btf_interp il, int l0, ivec4 xy0, vec2 a0, int l1, ivec4 xy1, vec2 a1, float f)
{
    ivec2 tile = btf_divmod(b, u_btf_atlas_cols).yx * u_btf_size; // level-0 tile of block b
#ifdef BTF_QUADS
    vec3 s = BTF__QUAD(0);
#if BTF_QUADS > 1
    s += BTF__QUAD(1);
#endif
#if BTF_QUADS > 2
    s += BTF__QUAD(2);
#endif
#if BTF_QUADS > 3
    s += BTF__QUAD(3);
#endif
#if BTF_QUADS > 4
    s += BTF__QUAD(4);
#endif
#if BTF_QUADS > 5
    s += BTF__QUAD(5);
#endif
#if BTF_QUADS > 6
    s += BTF__QUAD(6);
#endif
#if BTF_QUADS > 7
    s += BTF__QUAD(7);
#endif
#if BTF_QUADS > 8
    s += BTF__QUAD(8);
#endif
#if BTF_QUADS > 9
    s += BTF__QUAD(9);
#endif
#if BTF_QUADS > 10
    s += BTF__QUAD(10);
#endif
#if BTF_QUADS > 11
    s += BTF__QUAD(11);
#endif
#if BTF_QUADS > 12
    s += BTF__QUAD(12);
#endif
#if BTF_QUADS > 13
    s += BTF__QUAD(13);
#endif
#if BTF_QUADS > 14
    s += BTF__QUAD(14);
#endif
#if BTF_QUADS > 15
    s += BTF__QUAD(15);
#endif
#else
    vec3 s = vec3(0.0);
    int quads = max((u_btf_chunks + 3) / 4, 1);
    for (int h = 0; h < quads; h++)
        s += BTF__QUAD(h);
#endif
    return s;
}

// The spatial taps of uv at lod: levels l0 and l1 (lod clamped to [0, N-1], trilinear
// between floor(lod) and the next) with weight 1 - f and f, their texels and fractions.
struct btf_taps {
    int l0, l1;
    float f;
    ivec4 xy0, xy1;
    vec2 a0, a1;
};

btf_taps btf_decode_taps(vec2 uv, float lod)
{
    btf_taps t;
    int top = BTF__LEVELS ? max(u_btf_levels, 1) - 1 : 0;
    float lc = clamp(lod, 0.0, float(top));
    t.l0 = int(floor(lc));
    t.l1 = min(t.l0 + 1, top);
    t.f = lc - float(t.l0);
    t.xy0 = btf_texel_taps(uv, t.l0, t.a0);
    t.xy1 = btf_texel_taps(uv, t.l1, t.a1);
    return t;
}

vec3 btf_decode_lod(vec2 uv, vec3 light, vec3 view, float lod)
{
    btf_taps t = btf_decode_taps(uv, lod);
    int l0 = t.l0, l1 = t.l1;
    float f = t.f;
    ivec4 xy0 = t.xy0, xy1 = t.xy1;
    vec2 a0 = t.a0, a1 = t.a1;
    btf_interp il;
    if (!BTF__FIXED)
        il = btf_dirs_interp_vec(0, light);
    btf_interp iv = btf_dirs_interp_vec(1, view);
    vec3 rgb = iv.w.x * btf_view_sample(iv.idx.x, iv.blk.x, il, l0, xy0, a0, l1, xy1, a1, f);
    rgb += iv.w.y * btf_view_sample(iv.idx.y, iv.blk.y, il, l0, xy0, a0, l1, xy1, a1, f);
    rgb += iv.w.z * btf_view_sample(iv.idx.z, iv.blk.z, il, l0, xy0, a0, l1, xy1, a1, f);
    return rgb;
}

vec3 btf_decode(vec2 uv, vec3 light, vec3 view)
{
    return btf_decode_lod(uv, light, view, u_btf_lod);
}
