// Camera G-buffer: world position, shading normal, albedo per pixel.
in vec3 in_position;
in vec3 in_normal;
in vec3 in_albedo;

uniform mat4 u_view;
uniform mat4 u_view_proj;

out vec3 v_position;
out vec3 v_normal;
out vec3 v_albedo;
out float v_depth;

void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_albedo = in_albedo;
    v_depth = -(u_view * vec4(in_position, 1.0)).z;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
