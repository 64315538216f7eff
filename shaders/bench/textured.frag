// textured.frag - BENCHMARK ONLY (bench/bench_shader.c): the cheapest surface shader,
// one bilinear texture() fetch at the repeated uv; btf_render.vert's varyings.
uniform sampler2D u_tex;
uniform vec2 u_uv_scale;
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

void main()
{
    o_color = vec4(texture(u_tex, v_uv * u_uv_scale).rgb, 1.0);
}
