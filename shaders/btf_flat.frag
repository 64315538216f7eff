// btf_flat.frag - a model's part that no BTF is bound to, in its glTF base colour:
// Lambert under the light plus a constant ambient (u_flat_ambient of full light),
// encoded to sRGB like the BTF's own values. Same vertex stage as the BTF parts
// (btf_render.vert), so both draw into one depth buffer alike.
uniform vec4 u_light;        // w = 0: direction towards a distant light; w = 1: light position
uniform vec4 u_base_color;   // glTF baseColorFactor, linear RGBA (alpha unused)
uniform float u_flat_ambient; // 0..1
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

vec3 btf_flat_srgb(vec3 c)
{
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main()
{
    vec3 n = normalize(v_normal);
    vec3 L = normalize(u_light.w == 0.0 ? u_light.xyz : u_light.xyz - v_world);
    float k = u_flat_ambient + (1.0 - u_flat_ambient) * max(dot(n, L), 0.0);
    o_color = vec4(btf_flat_srgb(clamp(u_base_color.rgb * k, 0.0, 1.0)), 1.0);
}
