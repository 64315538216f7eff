// btf_flat.frag - a model's part that no BTF is bound to, in its glTF base colour:
// under the point light Lambert plus a constant ambient (u_flat_ambient of full
// light), under the environment Lambert under its quadratic (btf_tone_irradiance);
// then exposure, tone mapping and sRGB as the BTF parts get them (btf_tone.glsl comes
// before this file). Same vertex stage as the BTF parts (btf_render.vert), so both
// draw into one depth buffer alike.
uniform vec4 u_light;        // w = 0: direction towards a distant light; w = 1: light position
uniform vec4 u_base_color;   // glTF baseColorFactor, linear RGBA (alpha unused)
uniform float u_flat_ambient; // 0..1
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

void main()
{
    vec3 n = normalize(v_normal);
    vec3 L = normalize(u_light.w == 0.0 ? u_light.xyz : u_light.xyz - v_world);
    vec3 lin = vec3(0.0);
    if (BTF__POINT)
        lin += u_base_color.rgb * (u_flat_ambient + (1.0 - u_flat_ambient) * max(dot(n, L), 0.0));
    if (BTF__ENV)
        lin += u_base_color.rgb * btf_tone_irradiance(n);
    if (BTF__ENV || u_tone != 0 || u_exposure != 1.0)
        lin = btf_tone_map(u_exposure * lin, u_tone);
    o_color = vec4(btf_tone_srgb(lin), 1.0);
}
