// Layered depth pass (Frame.render_depth_layers): world positions to the geometry shader, which projects
// them into each view's layer (common/depth_layers.geom).
in vec3 in_position;

uniform mat4 u_model = mat4(1.0);

out vec4 v_world;

void main() {
    v_world = u_model * vec4(in_position, 1.0);
    gl_Position = v_world;
}
