in vec3 v_position;
in vec3 v_normal;
in vec3 v_albedo;
in vec2 v_uv;
in float v_depth;

uniform vec3 u_camera_position;
uniform int u_camera_ortho;
uniform vec3 u_camera_forward;
#include "common/facing.glsl"
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
layout(location = 2) out vec4 g_geometric;  // xyz geometric normal facing the viewer, w = terminator lift
layout(location = 3) out vec4 g_albedo;     // rgb diffuse albedo

#ifdef TERMINATOR_LIFT
in vec3 v_barycentric;
flat in vec3 v_corner[3];
flat in vec3 v_corner_normal[3];

// Cycles' shadow-terminator fix for smooth low-poly surfaces (Hanika 2021, "Hacking the Shadow Terminator",
// as Cycles' shadow_ray_smooth_surface_offset applies it): a shadow ray leaves from the point lifted off the
// flat triangle towards the smooth surface its corner normals describe, by h along the interpolated normal
// n: h from the quadratic patch through the corners, bounded by the corners' tangent planes (the local
// linear envelope). Returns h·|n| with the sign that makes it a distance along the viewer-facing shading
// normal `ns`; 0 on a flat triangle (equal corner normals).
float terminator_lift(vec3 ng, vec3 ns) {
    vec3 V0 = v_corner[0], V1 = v_corner[1], V2 = v_corner[2];
    vec3 N0 = v_corner_normal[0], N1 = v_corner_normal[1], N2 = v_corner_normal[2];
    float w0 = v_barycentric.x, w1 = v_barycentric.y, w2 = v_barycentric.z;
    vec3 P = V0 * w0 + V1 * w1 + V2 * w2;
    vec3 n = N0 * w0 + N1 * w1 + N2 * w2;          // not normalised, as in Cycles
    float a = dot(N2 - N0, V0 - V2);
    float b = dot(N2 - N1, V1 - V2);
    float c = dot(N1 - N0, V1 - V0);
    float h = a * w0 * (w0 - 1.0) + (a + b + c) * w0 * w1 + b * w1 * (w1 - 1.0);
    if (dot(n, ng) > 0.0) {
        float h0 = max(dot(V0 - P, N0) + max(max(dot(V1 - V0, N0), dot(V2 - V0, N0)), 0.0), 0.0);
        float h1 = max(dot(V1 - P, N1) + max(max(dot(V0 - V1, N1), dot(V2 - V1, N1)), 0.0), 0.0);
        float h2 = max(dot(V2 - P, N2) + max(max(dot(V0 - V2, N2), dot(V1 - V2, N2)), 0.0), 0.0);
        h = max(min(min(h0, h1), h2), h * 0.5);
    } else {
        float h0 = max(dot(P - V0, N0) + max(max(dot(V0 - V1, N0), dot(V0 - V2, N0)), 0.0), 0.0);
        float h1 = max(dot(P - V1, N1) + max(max(dot(V1 - V0, N1), dot(V1 - V2, N1)), 0.0), 0.0);
        float h2 = max(dot(P - V2, N2) + max(max(dot(V2 - V0, N2), dot(V2 - V1, N2)), 0.0), 0.0);
        h = min(-min(min(h0, h1), h2), h * 0.5);
    }
    return h * dot(n, ns);          // n·h = (h·(n·ns))·ns: ns is ±n/|n|
}
#endif

void main() {
    vec3 to_eye = u_camera_ortho == 1 ? -u_camera_forward : normalize(u_camera_position - v_position);
    // Geometric normal from screen-space derivatives, turned to the viewer.
    vec3 ng = cross(dFdx(v_position), dFdy(v_position));
    float len = length(ng);
    ng = len > 0.0 ? ng / len : to_eye;
    if (dot(ng, to_eye) < 0.0) ng = -ng;
    // Surfaces are two-sided, as in Cycles: seen from the back, the shading normal flips with the face.
    vec3 ns = normalize(v_normal);
    if (!front_facing()) ns = -ns;
    g_position = vec4(v_position, 1.0);
    g_normal = vec4(ns, v_depth);
#ifdef TERMINATOR_LIFT
    g_geometric = vec4(ng, terminator_lift(ng, ns));
#else
    g_geometric = vec4(ng, 0.0);
#endif
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
