// fetch.frag - BENCHMARK ONLY (bench/bench_shader.c, "fetch costs"), not a product
// shader: FETCH_N reads of one kind per fragment, summed so that none is optimised
// away, at addresses that change every 16 pixels (neighbouring fragments mostly read
// the same texel, as the decoder's do). The host defines FETCH_N and FETCH_KIND:
//   0 RGBA8 texelFetch          1 RGBA8 texture() (nearest, normalised coordinates)
//   2 RGBA16UI texelFetch       3 RGBA32UI texelFetch
//   4 R32UI texelFetch          5 vec4 of a uniform block at a per-fragment index
//   6 no read (the loop's own arithmetic)
// Every texture is 256 x 256; u_fu is the integer texture of the kind.
uniform highp sampler2D u_f8;
uniform highp usampler2D u_fu;
layout(std140) uniform fetch_block {
    vec4 u_fb[1024];
};
layout(location = 0) out vec4 o_color;

void main()
{
    ivec2 b = ivec2(gl_FragCoord.xy) / 16;
    vec4 s = vec4(0.0);
    for (int i = 0; i < FETCH_N; i++) {
        ivec2 c = (b * (i + 3) + ivec2(i * 37, i * 11)) & 255;
#if FETCH_KIND == 0
        s += texelFetch(u_f8, c, 0);
#elif FETCH_KIND == 1
        s += texture(u_f8, (vec2(c) + 0.5) / 256.0);
#elif FETCH_KIND == 4
        s += vec4(texelFetch(u_fu, c, 0).x & 255u);
#elif FETCH_KIND == 2 || FETCH_KIND == 3
        s += vec4(texelFetch(u_fu, c, 0) & 255u);
#elif FETCH_KIND == 5
        s += u_fb[(c.x * 7 + c.y) & 1023];
#else
        s += vec4(c.xyxy) * 1.0001;
#endif
    }
    o_color = s * 1e-9;
}
