// PCSS (Fernando 2005). For a receiver at depth d and a blocker at depth z, a light of half-size h covers
// h·(1/z − 1/d) in tangent units of a perspective map (similar triangles through the blocker), or
// tan(angle/2)·(d − z) metres for a sun's ortho map. The blocker search uses the widest such region (the
// near plane), the filter the one at the mean blocker depth.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/sampling.glsl"
#include "common/penumbra.glsl"

uniform sampler2D u_depth_map;
uniform vec2 u_light_half;
uniform int u_light_round;
uniform int u_blocker_samples;
uniform int u_filter_samples;
uniform float u_max_radius;     // texels
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;

// Penumbra half-extent in texels (x, y) for a blocker at depth z seen from receiver depth d.
vec2 penumbra_texels(float z, float d) {
    float spread = penumbra_spread_clamped(z, d, u_light_ortho);
    return min(u_light_half * spread / u_texel_tan, vec2(u_max_radius));
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float v = 1.0;
    if (pixel_lit(px)) {
        Receiver r = make_receiver(texelFetch(g_position, px, 0).xyz, texelFetch(g_geometric, px, 0).xyz);
        float d = r.map.z - r.bias;
        float noise = pixel_noise(px);
        // 1. Blocker search over the region the light can be seen through at the near plane.
        vec2 search = max(penumbra_texels(u_light_depth_range.x, d), vec2(0.5));
        float blocker_sum = 0.0;
        int blockers = 0;
        for (int i = 0; i < u_blocker_samples; ++i) {
            vec2 q = r.map.xy + kernel_point(i, u_blocker_samples, u_light_round, noise) * search;
            ivec2 t = ivec2(floor(q));
            if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_map_size))) continue;
            float z = texelFetch(u_depth_map, t, 0).r;
            if (z < receiver_depth_at(r, q)) { blocker_sum += z; ++blockers; }
        }
        if (blockers > 0) {
            // 2. Penumbra size from the mean blocker depth; 3. PCF over it.
            vec2 radius = max(penumbra_texels(blocker_sum / float(blockers), d), vec2(0.5));
            float sum = 0.0;
            for (int i = 0; i < u_filter_samples; ++i) {
                vec2 q = r.map.xy + kernel_point(i, u_filter_samples, u_light_round, 1.0 - noise) * radius;
                sum += map_lit_bilinear(u_depth_map, q, receiver_depth_at(r, q));
            }
            v = sum / float(u_filter_samples);
        }
    }
    imageStore(u_visibility, px, vec4(v));
}
