// Shadow-map depth pass: linear distance along the light's -Z axis.
in vec3 in_position;

uniform mat4 u_light_view;
uniform mat4 u_light_view_proj;
uniform mat4 u_model = mat4(1.0);

out float v_depth;

void main() {
    vec4 world = u_model * vec4(in_position, 1.0);
    v_depth = -(u_light_view * world).z;
    gl_Position = u_light_view_proj * world;
}
