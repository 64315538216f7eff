// thesis.frag - BENCHMARK ONLY (bench/bench_shader.c), not a product shader: the
// 2015 thesis's decoder (its sections 4.4 and 5.3) as a baseline, written in
// its WebGL1 style (texture() with normalised coordinates, nearest filtering, no
// texelFetch) and with "8-bit everything":
//   - direction lookup: two precomputed 512x512 RGBA8 maps per direction set,
//     azimuthal-equidistant over the hemisphere (map point = 0.5 + 0.5 * (theta/90) *
//     (cos phi, sin phi)): u_*_idx RGB = the 3 measured direction indices, u_*_w RGB
//     = their 3 barycentric weights (8-bit, renormalised here);
//   - texture L: RGBA8, 4 components per texel ("four components into one pixel"),
//     texel (x + g*W, y + b*H) = components 4g..4g+3 of block b at texel (x, y);
//   - texture R: RGBA8, 4 components per texel, texel (((l*3 + c)*G + g), v) =
//     weights of components 4g..4g+3 for view v, light l, channel c;
//   - one global 8-bit range per component (u_tlo/u_tstep, u_wlo/u_wstep: the
//     thesis's single scaling factor per matrix, per component here).
// Uses btf_render.vert's varyings and the same surface frame as btf_render.frag.
uniform vec3 u_camera;
uniform vec4 u_light;
uniform vec2 u_uv_scale;
uniform sampler2D u_light_idx;
uniform sampler2D u_light_w;
uniform sampler2D u_view_idx;
uniform sampler2D u_view_w;
uniform sampler2D u_L;
uniform sampler2D u_R;
uniform ivec2 u_size;     // W, H
uniform vec2 u_L_size;    // texture L size in texels
uniform vec2 u_R_size;    // texture R size in texels
uniform int u_groups;     // G = ceil(C / 4)
uniform int u_view_block[256];
uniform vec4 u_tlo[4], u_tstep[4], u_wlo[4], u_wstep[4]; // per component, 4 per vec4
uniform vec4 u_cmask[4];  // 1 for components < C
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

vec2 thesis_map_coord(vec3 d)
{
    float r = length(d.xy);
    float theta = min(atan(r, d.z), 1.5707963);
    vec2 dir = r > 0.0 ? d.xy / r : vec2(1.0, 0.0);
    return 0.5 + (theta / 3.14159265) * dir;
}

void main()
{
    vec3 n = normalize(v_normal);
    vec3 t = normalize(v_tangent.xyz - n * dot(n, v_tangent.xyz));
    vec3 b = cross(n, t) * v_tangent.w;
    vec3 L = u_light.w == 0.0 ? u_light.xyz : u_light.xyz - v_world;
    vec3 V = u_camera - v_world;
    vec3 l = vec3(dot(L, t), dot(L, b), dot(L, n));
    vec3 v = vec3(dot(V, t), dot(V, b), dot(V, n));
    vec2 ml = thesis_map_coord(l), mv = thesis_map_coord(v);
    ivec3 li = ivec3(texture(u_light_idx, ml).rgb * 255.0 + 0.5);
    vec3 lw = texture(u_light_w, ml).rgb;
    ivec3 vi = ivec3(texture(u_view_idx, mv).rgb * 255.0 + 0.5);
    vec3 vw = texture(u_view_w, mv).rgb;
    lw /= max(lw.x + lw.y + lw.z, 1e-6);
    vw /= max(vw.x + vw.y + vw.z, 1e-6);
    vec2 f = fract(v_uv * u_uv_scale) * vec2(u_size);
    vec2 texel = min(floor(f), vec2(u_size) - 1.0) + 0.5;
    vec3 rgb = vec3(0.0);
    for (int a = 0; a < 3; a++) {
        int blk = u_view_block[vi[a]];
        for (int g = 0; g < 4; g++) {
            if (g >= u_groups)
                break;
            vec2 pl = (texel + vec2(float(g * u_size.x), float(blk * u_size.y))) / u_L_size;
            vec4 T = (u_tlo[g] + u_tstep[g] * (texture(u_L, pl) * 255.0)) * u_cmask[g];
            for (int e = 0; e < 3; e++) {
                float w = vw[a] * lw[e];
                float row = (float(vi[a]) + 0.5) / u_R_size.y;
                float col0 = float((li[e] * 3) * u_groups + g) + 0.5;
                vec4 wr = u_wlo[g] + u_wstep[g] * (texture(u_R, vec2(col0 / u_R_size.x, row)) * 255.0);
                vec4 wg = u_wlo[g] + u_wstep[g] * (texture(u_R, vec2((col0 + float(u_groups)) / u_R_size.x, row)) * 255.0);
                vec4 wb = u_wlo[g] + u_wstep[g] * (texture(u_R, vec2((col0 + float(2 * u_groups)) / u_R_size.x, row)) * 255.0);
                rgb += w * vec3(dot(T, wr), dot(T, wg), dot(T, wb));
            }
        }
    }
    o_color = vec4(clamp(rgb, 0.0, 1.0), 1.0);
}
