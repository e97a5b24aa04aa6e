// Shadow-map depth pass: linear distance along the light's -Z axis.
in vec3 in_position;

uniform mat4 u_light_view;
uniform mat4 u_light_view_proj;
uniform mat4 u_model = mat4(1.0);

out float v_depth;
out vec3 v_view;                // light-view position (peeling reads how the light centre sees the face)

void main() {
    vec4 world = u_model * vec4(in_position, 1.0);
    v_view = (u_light_view * world).xyz;
    v_depth = -v_view.z;
    gl_Position = u_light_view_proj * world;
}
