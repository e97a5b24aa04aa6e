// Shadow-map depth pass: linear distance along the light's -Z axis.
in vec3 in_position;

uniform mat4 u_light_view;
uniform mat4 u_light_view_proj;

out float v_depth;

void main() {
    v_depth = -(u_light_view * vec4(in_position, 1.0)).z;
    gl_Position = u_light_view_proj * vec4(in_position, 1.0);
}
