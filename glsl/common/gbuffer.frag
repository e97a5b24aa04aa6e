in vec3 v_position;
in vec3 v_normal;
in vec3 v_albedo;
in vec2 v_uv;
in float v_depth;

uniform vec3 u_camera_position;
uniform int u_camera_ortho;
uniform vec3 u_camera_forward;
uniform int u_mirrored = 0;     // the model matrix flips handedness, so front faces wind clockwise
// Base-colour image (engine/gpu/geometry.py AlbedoMap): 0 none; 1 repeat, 2 extend, 3 clip (the sampler wraps
// or clamps), 4 mirror (folded here: the sampler clamps).
uniform int u_albedo_map = 0;
uniform int u_albedo_srgb = 0;  // the texture holds sRGB bytes: decode after filtering, as Cycles does
uniform sampler2D u_albedo_texture;

vec3 srgb_to_linear(vec3 c) {   // IEC 61966-2-1 decoding
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(0.04045, c));
}

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
    vec3 albedo = v_albedo;
    if (u_albedo_map != 0) {
        vec2 uv = v_uv;
        if (u_albedo_map == 4) {
            vec2 m = mod(uv, 2.0);
            uv = mix(m, 2.0 - m, step(1.0, m));
        }
        vec3 texel = texture(u_albedo_texture, uv).rgb;
        albedo *= u_albedo_srgb == 1 ? srgb_to_linear(texel) : texel;
    }
    g_albedo = vec4(albedo, 1.0);
}
