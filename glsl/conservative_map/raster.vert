// Conservative map: casters to the light's clip space; the geometry stage does the rest.
in vec3 in_position;

uniform mat4 u_light_view_proj;
uniform mat4 u_model = mat4(1.0);

void main() {
    gl_Position = u_light_view_proj * (u_model * vec4(in_position, 1.0));
}
