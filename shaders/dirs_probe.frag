// dirs_probe.frag - test program (tests/gl/test_gl.c): each fragment reads one direction
// from its texel of u_dirs and writes btf_dirs_interp_vec's indices and weights for
// set 0 (the lights of btf_dirs_block).
uniform sampler2D u_dirs; // RGBA32F: (theta_deg, phi_deg, -, -), or a vector (x, y, z, -) when u_vector != 0
uniform int u_vector;
layout(location = 0) out vec4 o_idx;
layout(location = 1) out vec4 o_w;

void main()
{
    vec4 q = texelFetch(u_dirs, ivec2(gl_FragCoord.xy), 0);
    // angles as btf_dirset_interp takes them: NaN theta = 0, clamped to [0, 90]; NaN/Inf phi = 0
    float t = q.x == q.x ? clamp(q.x, 0.0, 90.0) : 0.0, p = isnan(q.y) || isinf(q.y) ? 0.0 : q.y;
    btf_interp r = btf_dirs_interp_vec(0, u_vector != 0 ? q.xyz : btf_dirs_vec(t, p));
    o_idx = vec4(r.idx, 0.0);
    o_w = vec4(r.w, 0.0);
}
