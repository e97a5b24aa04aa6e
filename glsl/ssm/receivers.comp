// SSM's receiver maps, from the receivers the camera sees (deviation from Atty et al. 2006 §3.1, whose
// receiver map is the nearest receiver surface rasterised from the light). Every receiver pixel this light
// reaches goes into the 2×2 texels its bilinear look-up reads, at the depth where its tangent plane meets
// each texel centre's ray; per texel the nearest and the farthest are kept, each with what the scatter needs
// to keep a receiver from shadowing itself: its point and geometric normal as common/light_view.glsl's
// pixel_receiver makes them (the shared tangent-plane rule, receiver_depth_at). A surface the camera does
// not see (the outside of a room around the camera, the top of a box the floor runs through) is no
// receiver here, so it cannot stand in for the receivers behind it.
//
// PASS 0  per pixel and texel: atomic max of the depth's bits (far) and of their complement (near);
//         positive floats order as their bits, and 0 stays "no receiver" in both images
//         and, per pixel, whether the receiver's horizon cuts the light's rectangle (u_cut: 1 if any does),
//         which compiles the scatter's clipped weights in (ssm/patch.glsl weighted_fraction, SSM_HORIZON_CUT)
// PASS 1  the same: the pixel whose depth won a texel writes that texel's records (ties: any one of them)
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/polygon.glsl"
#ifndef PASS
#define PASS 0
#endif
uniform sampler2D u_receiver_mask;  // g = 1 where the camera sees a receiver (only with u_has_mask)
uniform int u_has_mask;
layout(r32ui, binding = 0) uniform uimage2D u_near_bits;   // ~depth bits of the nearest pixel; 0: none
layout(r32ui, binding = 1) uniform uimage2D u_far_bits;    // depth bits of the farthest pixel; 0: none
#if PASS == 0
uniform vec2 u_half;                // the light's half extent (metres, tan for a sun), as the scatter takes it
layout(r32ui, binding = 2) uniform uimage2D u_cut;        // 1×1: 1 once a receiver's horizon cuts the light
#endif
#if PASS == 1
// a: depth (0: no receiver), receiver point (light frame, normal-offset); b: its geometric normal (light
// frame), its slope-scaled bias, negated (less 1) when the receiver is lit through its own surface; c: its
// own surface's plane offset (Receiver.own_plane, for own_surface_blocks).
layout(rgba32f, binding = 2) uniform writeonly image2D u_near_a;
layout(rgba32f, binding = 3) uniform writeonly image2D u_near_b;
layout(rgba32f, binding = 4) uniform writeonly image2D u_far_a;
layout(rgba32f, binding = 5) uniform writeonly image2D u_far_b;
layout(r32f, binding = 6) uniform writeonly image2D u_near_c;
layout(r32f, binding = 7) uniform writeonly image2D u_far_c;
#endif

// Depth along the map ray through texel position `pos` at which the plane through `point` (light frame)
// with normal n meets it, within `reach` of the point's own depth (a plane seen edge-on meets it nowhere
// near). The scatter puts a texel's receiver at the texel centre, as the paper's rasterised map does.
float plane_depth(vec3 point, vec3 n, vec2 pos, float reach) {
    vec2 h = plane_along_map_ray(n, dot(n, point), pos);
    float z0 = -point.z;
    float z = abs(h.x) > 1e-9 ? -h.y / h.x : z0;
    return clamp(z, z0 - reach, z0 + reach);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px) || !pixel_lit(px)) return;
    if (u_has_mask == 1 && texelFetch(u_receiver_mask, px, 0).g <= 0.5) return;
    vec3 p = light_local(texelFetch(g_position, px, 0).xyz);
    vec3 m = map_coords(p);
    if (!(m.z > 0.0 && m.z < EMPTY_DEPTH)) return;
#if PASS == 1
    Receiver r = pixel_receiver(px);
#endif
    vec3 n = mat3(u_light_view) * texelFetch(g_geometric, px, 0).xyz;
    vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-p);
    float cos_t = clamp(abs(dot(n, to_light)), 1e-3, 1.0);   // as ssm/project.comp's depth tolerance
    float reach = texel_world(m.z) * (1.0 + 1.5 * min(sqrt(1.0 - cos_t * cos_t) / cos_t, 10.0));
    // The pixel goes into every texel its bilinear look-up in ssm/project.comp reads, so that each of them
    // holds a receiver range that includes it (a texel no camera pixel falls in would leave a hole).
#if PASS == 0
    // The light's corners relative to the receiver's foot in units of its height (weighted_fraction's frame).
    vec2 t = u_light_ortho == 1 ? vec2(0.0) : p.xy / m.z;
    vec4 corners = vec4(-u_half, u_half) / (u_light_ortho == 1 ? 1.0 : m.z) - t.xyxy;
    if (!rect_above(corners, n)) imageAtomicMax(u_cut, ivec2(0), 1u);
#endif
    ivec2 base = ivec2(floor(m.xy - 0.5));
    for (int k = 0; k < 4; ++k) {
        ivec2 t = base + ivec2(k & 1, k >> 1);
        if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_map_size))) continue;
        float z = plane_depth(p, n, vec2(t) + 0.5, reach);
        if (!(z > 0.0 && z < EMPTY_DEPTH)) continue;
        uint bits = floatBitsToUint(z);
#if PASS == 0
        imageAtomicMax(u_near_bits, t, ~bits);
        imageAtomicMax(u_far_bits, t, bits);
#else
        bool near = ~imageLoad(u_near_bits, t).r == bits, far = imageLoad(u_far_bits, t).r == bits;
        if (!near && !far) continue;
        // The pixel's own (normal-offset) point for the tangent-plane rule: a point moved along the texel
        // centre's ray would leave the plane where `reach` clamps it (a receiver nearly edge-on to the light)
        // and let the receiver's own surface shadow it.
        vec4 a = vec4(z, r.local);
        vec4 b = vec4(r.normal, r.through_surface ? -1.0 - r.bias : r.bias);
        vec4 c = vec4(r.own_plane);
        if (near) { imageStore(u_near_a, t, a); imageStore(u_near_b, t, b); imageStore(u_near_c, t, c); }
        if (far) { imageStore(u_far_a, t, a); imageStore(u_far_b, t, b); imageStore(u_far_c, t, c); }
#endif
    }
}
