// btf_render.frag - shades a surface with the package decoder (btf_dirs.glsl,
// btf_decode.glsl, btf_tone.glsl and btf_light.glsl come before this file). Light and eye are turned
// into the surface's local frame (x = tangent, y = cross(normal, tangent) * w,
// z = normal). The point light's value is the BTF's own (cos(theta_light) included, as
// measured); the environment's is its light sum (doc/lighting.md). Both are made
// linear, scaled by u_exposure, tone mapped and encoded as sRGB. A point light alone
// with exposure 1 and no tone mapping shows the BTF's own values, clamped to 0..1.
// With u_horizon_fade = 1 a light beyond the outermost measured light ring (where
// the decoder holds that ring's values) fades linearly in cos(theta_light) to 0 at
// the horizon and stays 0 below it: no lit back side on curved objects.
uniform vec3 u_camera;   // world position of the eye
uniform vec4 u_light;    // w = 0: direction towards a distant light; w = 1: light position
uniform vec2 u_uv_scale; // material repeats across the surface (set u_btf_wrap = 1 when > 1)
uniform int u_horizon_fade; // 0: decoder value as is; 1: fade (btf render's default)
uniform int u_btf_lod_auto; // 1: lod from screen-space derivatives; 0: u_btf_lod
uniform float u_btf_outer_cos; // cos(theta) of the outermost measured light ring
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;
#ifdef BTF_RENDER_DEBUG
layout(location = 1) out vec4 o_uv;    // (u, v, lod, 0) as decoded
layout(location = 2) out vec4 o_light; // local light direction (not normalised)
layout(location = 3) out vec4 o_view;  // local view direction (not normalised)
#endif

// 1 inside the outermost measured light ring; beyond it cos(theta_l) / cos(theta_outer),
// reaching 0 at the horizon; 0 below the horizon.
float btf_render_horizon(vec3 l)
{
    float len = length(l);
    float c_outer = u_btf_outer_cos;
    if (!(len > 0.0) || !(c_outer > 1e-3))
        return 1.0;
    float c = l.z / len;
    return c >= c_outer ? 1.0 : max(c, 0.0) / c_outer;
}

// Level of detail of uv (after u_uv_scale) at this fragment: log2 of the larger
// screen-space footprint of a pixel in level-0 texels (the GL isotropic rule).
float btf_render_lod(vec2 uv)
{
    vec2 t = uv * vec2(u_btf_size);
    vec2 dx = dFdx(t), dy = dFdy(t);
    return 0.5 * log2(max(max(dot(dx, dx), dot(dy, dy)), 1e-12));
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
    vec2 uv = v_uv * u_uv_scale;
    float lod = btf_render_lod(uv); // outside any branch: derivatives need uniform control flow
    if (u_btf_lod_auto == 0)
        lod = u_btf_lod;
    vec3 pt, env;
    btf_light_decode(uv, l, v, mat3(t, b, n), lod, pt, env);
    if (u_horizon_fade != 0)
        pt *= btf_render_horizon(l);
    vec3 rgb;
    if (!BTF__ENV && u_btf_linear == 0 && u_tone == 0 && u_exposure == 1.0)
        rgb = clamp(pt, 0.0, 1.0); // the measured values as they are
    else {
        vec3 lin = BTF__POINT ? btf_light_linear(pt) : vec3(0.0);
        if (BTF__ENV)
            lin += btf_light_linear(env);
        rgb = btf_tone_srgb(btf_tone_map(u_exposure * lin, u_tone));
    }
    o_color = vec4(rgb, 1.0);
#ifdef BTF_RENDER_DEBUG
    o_uv = vec4(uv, lod, 0.0);
    o_light = vec4(l, 0.0);
    o_view = vec4(v, 0.0);
#endif
}
