// btf_render.vert - a BTF-textured surface: passes the world position and the
// surface frame to btf_render.frag. The host supplies a mesh (plane, sphere,
// cylinder, ...) with these attributes:
//   a_position  object-space position
//   a_normal    object-space normal (the BTF's local z)
//   a_tangent   xyz: object-space direction of increasing u (the BTF's local x,
//               image columns); w = +1 when v increases with image rows, i.e.
//               cross(normal, tangent) points towards decreasing v (the BTF's local
//               y points towards image row 0, doc/data-model.md section 1), else -1
//   a_uv        texture coordinate, (0, 0) = texel (0, 0) corner, v along rows
// u_model must be rigid plus uniform scale (normals use its 3x3 part).
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec4 a_tangent;
layout(location = 3) in vec2 a_uv;
uniform mat4 u_model;     // object -> world
uniform mat4 u_view_proj; // world -> clip
out vec3 v_world;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;

void main()
{
    vec4 w = u_model * vec4(a_position, 1.0);
    mat3 m = mat3(u_model);
    v_world = w.xyz;
    v_normal = m * a_normal;
    v_tangent = vec4(m * a_tangent.xyz, a_tangent.w);
    v_uv = a_uv;
    gl_Position = u_view_proj * w;
}
