// Camera G-buffer: world position, shading normal, albedo per pixel.
#ifdef TERMINATOR_LIFT
// common/gbuffer.geom sits between this stage and the fragment stage and passes these on.
#define v_position vs_position
#define v_normal vs_normal
#define v_albedo vs_albedo
#define v_uv vs_uv
#define v_depth vs_depth
#endif
in vec3 in_position;
in vec3 in_normal;
in vec3 in_albedo;
in vec2 in_uv;                             // texture coordinates (draws without a texture leave it unbound)

uniform mat4 u_view;
uniform mat4 u_view_proj;
uniform mat4 u_model = mat4(1.0);          // object → world (identity for world-space geometry)
uniform mat3 u_normal_matrix = mat3(1.0);

out vec3 v_position;
out vec3 v_normal;
out vec3 v_albedo;
out vec2 v_uv;
out float v_depth;

void main() {
    vec4 world = u_model * vec4(in_position, 1.0);
    v_position = world.xyz;
    v_normal = u_normal_matrix * in_normal;
    v_albedo = in_albedo;
    v_uv = in_uv;
    v_depth = -(u_view * world).z;
    gl_Position = u_view_proj * world;
}
