// G-buffer triangles with their corners (world positions and unit corner normals) for the fragment stage,
// which needs the whole triangle for the shadow-terminator lift (gbuffer.frag, TERMINATOR_LIFT); the
// attributes pass through unchanged, plus the fragment's barycentric coordinates.
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;

in vec3 vs_position[];
in vec3 vs_normal[];
in vec3 vs_albedo[];
in vec2 vs_uv[];
in float vs_depth[];

out vec3 v_position;
out vec3 v_normal;
out vec3 v_albedo;
out vec2 v_uv;
out float v_depth;
out vec3 v_barycentric;
flat out vec3 v_corner[3];
flat out vec3 v_corner_normal[3];

void main() {
    vec3 unit_normal[3];
    for (int j = 0; j < 3; ++j) {
        float len = length(vs_normal[j]);
        unit_normal[j] = len > 0.0 ? vs_normal[j] / len : vec3(0.0);
    }
    for (int k = 0; k < 3; ++k) {
        // flat outputs are undefined after EmitVertex: set them for every vertex
        for (int j = 0; j < 3; ++j) {
            v_corner[j] = vs_position[j];
            v_corner_normal[j] = unit_normal[j];
        }
        gl_Position = gl_in[k].gl_Position;
        v_position = vs_position[k];
        v_normal = vs_normal[k];
        v_albedo = vs_albedo[k];
        v_uv = vs_uv[k];
        v_depth = vs_depth[k];
        v_barycentric = vec3(k == 0, k == 1, k == 2);
        EmitVertex();
    }
    EndPrimitive();
}
