// decode_probe.frag - test program (tests/gl/test_gl.c): each fragment decodes the query
// stored in its texels of u_q0 = (light.xyz, u) and u_q1 = (view.xyz, v).
uniform sampler2D u_q0;
uniform sampler2D u_q1;
layout(location = 0) out vec4 o_rgb;

void main()
{
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_q0, p, 0), b = texelFetch(u_q1, p, 0);
    o_rgb = vec4(btf_decode(vec2(a.w, b.w), a.xyz, b.xyz), 1.0);
}
