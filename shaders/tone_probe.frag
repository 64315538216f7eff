// tone_probe.frag - test probe of btf_tone.glsl (tests/gl/test_env.c): pixel x of a
// row holds btf_tone_srgb(btf_tone_map(value, u_probe_op)) for value =
// u_probe_max * x / (width - 1) in every channel but green, which gets half of it.
uniform int u_probe_op;
uniform float u_probe_max;
uniform int u_probe_width;
layout(location = 0) out vec4 o_color;

void main()
{
    float x = u_probe_max * floor(gl_FragCoord.x) / float(u_probe_width - 1);
    vec3 lin = vec3(x, 0.5 * x, x);
    o_color = vec4(btf_tone_srgb(btf_tone_map(lin, u_probe_op)), 1.0);
}
