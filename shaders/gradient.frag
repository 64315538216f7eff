// gradient.frag - writes the fragment's own coordinates (harness test: proves
// the rasterizer, the varyings and the readback orientation).
uniform vec2 u_size;
in vec2 v_uv;
layout(location = 0) out vec4 o_coord;
layout(location = 1) out vec4 o_uv;

void main()
{
    o_coord = vec4(gl_FragCoord.xy / u_size, 0.25, 1.0);
    o_uv = vec4(v_uv, 1.0 - v_uv.x, 0.5);
}
