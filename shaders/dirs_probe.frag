// dirs_probe.frag - test program (tests/test_gl.c): each fragment reads one direction
// from its texel of u_dirs and writes btf_dirs_interp's indices and weights.
uniform sampler2D u_dirs; // RGBA32F: (theta_deg, phi_deg, -, -), or a vector (x, y, z, -) when u_vector != 0
uniform int u_vector;
uniform btf_dirset u_set;
layout(location = 0) out vec4 o_idx;
layout(location = 1) out vec4 o_w;

void main()
{
    vec4 q = texelFetch(u_dirs, ivec2(gl_FragCoord.xy), 0);
    btf_interp r;
    if (u_vector != 0)
        r = btf_dirs_interp_vec(u_set, q.xyz);
    else
        r = btf_dirs_interp(u_set, q.x, q.y);
    o_idx = vec4(r.idx, 0.0);
    o_w = vec4(r.w, 0.0);
}
