// btf_three.vert - btf_render.vert for three.js (client/three/btf-material.js, a
// RawShaderMaterial of WebGLRenderer): the same outputs for btf_render.frag from three's
// attribute names and matrices. Per vertex:
//   position, normal  object space
//   tangent           xyz: direction of increasing uv.x; w: three's handedness (cross(normal,
//                     tangent) * w points along increasing uv.y: BufferGeometry.computeTangents,
//                     BufferGeometryUtils.computeMikkTSpaceTangents, glTF's TANGENT)
//   uv                three's texture coordinate
// u_flip_y = 1 (three's Texture.flipY, its own geometries): image row 0 of the material at
// uv.y = 1, so the BTF's v is 1 - uv.y and its local y (towards row 0) is three's
// bitangent. u_flip_y = 0 (a glTF model, whose textures three does not flip): v = uv.y,
// and glTF's bitangent already points towards row 0 (the glTF convention).
// Normals take the inverse transpose of modelMatrix (any affine transform).
in vec3 position;
in vec3 normal;
in vec4 tangent;
in vec2 uv;
uniform mat4 modelMatrix;      // object -> world (three sets it)
uniform mat4 viewMatrix;       // world -> camera (three sets it)
uniform mat4 projectionMatrix; // camera -> clip (three sets it)
uniform int u_flip_y;
out vec3 v_world;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;

void main()
{
    vec4 w = modelMatrix * vec4(position, 1.0);
    mat3 m = mat3(modelMatrix);
    v_world = w.xyz;
    v_normal = transpose(inverse(m)) * normal;
    v_tangent = vec4(m * tangent.xyz, tangent.w);
    v_uv = u_flip_y == 1 ? vec2(uv.x, 1.0 - uv.y) : uv;
    gl_Position = projectionMatrix * viewMatrix * w;
}
