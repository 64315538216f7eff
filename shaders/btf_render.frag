// btf_render.frag - shades a surface with the package decoder (btf_dirs.glsl and
// btf_decode.glsl come before this file). Light and eye are turned into the
// surface's local frame (x = tangent, y = cross(normal, tangent) * w, z = normal)
// and passed to btf_decode; the result is the BTF's own value (sRGB-encoded,
// cos(theta_light) included, as measured), clamped to 0..1 for display.
uniform vec3 u_camera;   // world position of the eye
uniform vec4 u_light;    // w = 0: direction towards a distant light; w = 1: light position
uniform vec2 u_uv_scale; // material repeats across the surface (set u_btf_wrap = 1 when > 1)
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;
#ifdef BTF_RENDER_DEBUG
layout(location = 1) out vec4 o_uv;    // (u, v, 0, 0) as decoded
layout(location = 2) out vec4 o_light; // local light direction (not normalised)
layout(location = 3) out vec4 o_view;  // local view direction (not normalised)
#endif

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
    o_color = vec4(clamp(btf_decode(uv, l, v), 0.0, 1.0), 1.0);
#ifdef BTF_RENDER_DEBUG
    o_uv = vec4(uv, 0.0, 0.0);
    o_light = vec4(l, 0.0);
    o_view = vec4(v, 0.0);
#endif
}
