// nn.frag - BENCHMARK ONLY (bench/bench_shader.c), not a product shader: the small
// nonlinear decoder of bench/bench_nn.c (doc/performance.md section 11) evaluated per
// fragment, to measure what it would cost the renderer:
//     rgb = W3 relu(W2 relu(W1 [z, l.xy, v.xy, h.xy] + b1) + b2) + b3
// with l, v the unit light and view directions in the surface frame, h their half
// vector, z the texel's NN_Z latent values (NN_Z a multiple of 4) and NN_H hidden
// units per layer (a multiple of 4). The host defines NN_Z, NN_H and NN_TEXW.
//   - u_lat: RGBA8, W x (H * NN_Z / 4): texel (x, y + q H) holds latents 4q..4q+3 of
//     texel (x, y), each lo + step * byte (u_lat_lo[q], u_lat_step[q]);
//   - u_w: RGBA32F, NN_TEXW texels a row, the parameters as one list of vec4 (the
//     list's index i at texel (i % NN_TEXW, i / NN_TEXW)): W1 (unit i's NN_K1 vec4,
//     the input padded with two zeros), b1 (NN_G vec4), W2 (unit i's NN_G vec4),
//     b2, W3 (3 rows of NN_G vec4), b3 (one vec4, xyz).
// Nearest texel at the repeated uv, as thesis.frag; the output clamped to 0..1.
uniform vec3 u_camera;
uniform vec4 u_light;
uniform vec2 u_uv_scale;
uniform sampler2D u_lat;
uniform sampler2D u_w;
uniform ivec2 u_size; // W, H of the material
uniform vec4 u_lat_lo[NN_Z / 4], u_lat_step[NN_Z / 4];
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

#define NN_K1 (NN_Z / 4 + 2)
#define NN_G (NN_H / 4)
#define NN_W1 0
#define NN_B1 (NN_W1 + NN_H * NN_K1)
#define NN_W2 (NN_B1 + NN_G)
#define NN_B2 (NN_W2 + NN_H * NN_G)
#define NN_W3 (NN_B2 + NN_G)
#define NN_B3 (NN_W3 + 3 * NN_G)
#define NN_NX (NN_K1 > NN_G ? NN_K1 : NN_G)

vec4 nn_w(int i)
{
    return texelFetch(u_w, ivec2(i % NN_TEXW, i / NN_TEXW), 0);
}

// 4 units 4g..4g+3 of a layer: bias + weights (unit u's n vec4 from w0 + u n) . x
vec4 nn_units(int w0, int b0, int g, int n, vec4 x[NN_NX])
{
    vec4 a = nn_w(b0 + g);
    for (int k = 0; k < n; k++) {
        int i = w0 + 4 * g * n + k;
        a += vec4(dot(nn_w(i), x[k]), dot(nn_w(i + n), x[k]), dot(nn_w(i + 2 * n), x[k]), dot(nn_w(i + 3 * n), x[k]));
    }
    return max(a, 0.0);
}

void main()
{
    vec3 n = normalize(v_normal);
    vec3 t = normalize(v_tangent.xyz - n * dot(n, v_tangent.xyz));
    vec3 b = cross(n, t) * v_tangent.w;
    vec3 L = u_light.w == 0.0 ? u_light.xyz : u_light.xyz - v_world;
    vec3 V = u_camera - v_world;
    vec3 l = normalize(vec3(dot(L, t), dot(L, b), dot(L, n)));
    vec3 v = normalize(vec3(dot(V, t), dot(V, b), dot(V, n)));
    vec3 h = normalize(l + v);
    vec2 f = fract(v_uv * u_uv_scale) * vec2(u_size);
    ivec2 texel = ivec2(min(floor(f), vec2(u_size) - 1.0));
    vec4 x[NN_NX], y[NN_NX];
    for (int q = 0; q < NN_Z / 4; q++)
        x[q] = u_lat_lo[q] + u_lat_step[q] * (texelFetch(u_lat, texel + ivec2(0, q * u_size.y), 0) * 255.0);
    x[NN_Z / 4] = vec4(l.xy, v.xy);
    x[NN_Z / 4 + 1] = vec4(h.xy, 0.0, 0.0);
    for (int g = 0; g < NN_G; g++)
        y[g] = nn_units(NN_W1, NN_B1, g, NN_K1, x);
    for (int g = 0; g < NN_G; g++)
        x[g] = nn_units(NN_W2, NN_B2, g, NN_G, y);
    vec3 rgb = nn_w(NN_B3).xyz;
    for (int k = 0; k < NN_G; k++)
        rgb += vec3(dot(nn_w(NN_W3 + k), x[k]), dot(nn_w(NN_W3 + NN_G + k), x[k]), dot(nn_w(NN_W3 + 2 * NN_G + k), x[k]));
    o_color = vec4(clamp(rgb, 0.0, 1.0), 1.0);
}
