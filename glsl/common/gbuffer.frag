in vec3 v_position;
in vec3 v_normal;
in vec3 v_albedo;
in float v_depth;

uniform vec3 u_camera_position;
uniform int u_camera_ortho;
uniform vec3 u_camera_forward;
uniform int u_mirrored = 0;     // the model matrix flips handedness, so front faces wind clockwise

layout(location = 0) out vec4 g_position;   // xyz world, w = 1 where covered
layout(location = 1) out vec4 g_normal;     // xyz shading normal facing the viewer, w = camera z-depth
layout(location = 2) out vec4 g_geometric;  // xyz geometric normal facing the viewer
layout(location = 3) out vec4 g_albedo;     // rgb diffuse albedo

void main() {
    vec3 to_eye = u_camera_ortho == 1 ? -u_camera_forward : normalize(u_camera_position - v_position);
    // Geometric normal from screen-space derivatives, turned to the viewer.
    vec3 ng = cross(dFdx(v_position), dFdy(v_position));
    float len = length(ng);
    ng = len > 0.0 ? ng / len : to_eye;
    if (dot(ng, to_eye) < 0.0) ng = -ng;
    // Surfaces are two-sided, as in Cycles: seen from the back, the shading normal flips with the face.
    vec3 ns = normalize(v_normal);
    if (gl_FrontFacing == (u_mirrored == 1)) ns = -ns;
    g_position = vec4(v_position, 1.0);
    g_normal = vec4(ns, v_depth);
    g_geometric = vec4(ng, 0.0);
    g_albedo = vec4(v_albedo, 1.0);
}
