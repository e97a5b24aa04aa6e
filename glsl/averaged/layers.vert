// REFERENCE's layered depth pass: world positions to the geometry shader, which projects them into each
// sample's map (averaged/layers.geom).
in vec3 in_position;

uniform mat4 u_model = mat4(1.0);

out vec4 v_world;

void main() {
    v_world = u_model * vec4(in_position, 1.0);
    gl_Position = v_world;
}
