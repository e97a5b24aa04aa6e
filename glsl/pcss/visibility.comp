// PCSS (Fernando 2005). For a receiver at depth d and a blocker at depth z, a light of half-size h covers
// h·(1/z − 1/d) in tangent units of a perspective map (similar triangles through the blocker), or
// tan(angle/2)·(d − z) metres for a sun's ortho map. The blocker search uses the widest such region (the
// near plane), the filter the one at the mean blocker depth.
//
// By the same similar triangles, kernel position k ∈ [-1, 1]² (search or filter) looks along the ray from the
// receiver towards the light point k·h: taps whose point lies below the receiver's horizon carry no light and
// count neither as blockers nor in the filter's mean; the others weigh the irradiance their light point
// carries to the receiver (light_sample_weight), the visibility Cycles measures (see tap_weight). Every texel is
// compared with the receiver's tangent plane (light_view.glsl), so a tilted floor never finds itself.
// The search weighs its taps towards the receiver's own map position (search_tap_density).
// With MIDPOINT (ours, pcss_midpoint) a blocker texel's depth is the middle of the caster along the light
// centre's ray, between its near side (the depth map) and its far side (the nearest back face behind it),
// where that far side still lies above the receiver. A convex solid's outline, which sizes its penumbra, is
// its widest section: for a ball exactly that middle, where the near side put the ball's top and the
// penumbra came out too wide, its core too light (`tilted`). A box's outline from above is its top, which the
// middle moves down (`city`). At 128² against Cycles 1024 spp: tilted 0.035 → 0.021, balls 0.041 → 0.037,
// room 0.015 → 0.013, slab 0.075 → 0.069, contact 0.028 → 0.026; worse: city 0.097 → 0.102, suzanne 0.039 →
// 0.040, grazing 0.030 → 0.031.
// Both kernels use one fixed stratified pattern for every pixel: the result is a smooth function of the
// receiver's position, with no per-pixel noise (a per-pixel rotation turns into salt-and-pepper across the
// penumbra, whose error no later filter removes).
// With EARLY_SKIP, pixels the lit_umbra structure proves fully lit or in umbra take 1 or 0 without either
// kernel: exactly what the kernels would return there (glsl/lit_umbra/classify.comp).
// The blocker search skips texels whose triangle has the receiver and the whole light on one side of its plane
// (the far wall at a room's corner: light_view.glsl facet_clears_receiver), so a pixel with no other blocker
// near it is lit without a filter. The filter does not test them: in both kernels, at 128² on llvmpipe, PCSS
// took 1.3-2.3x its time (plane 53 -> 111 ms) for contact 0.0233 -> 0.0219 and city 0.1040 -> 0.1023; in the
// search alone 1.05-1.6x (the facet map's raster pass, plane 75 ms), fuzz 30118 0.189 over 101 pixels -> 0.123
// over 26 (bound 0.227).
#define FACET_MAP 1
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/sampling.glsl"
#include "common/penumbra.glsl"

uniform sampler2D u_depth_map;
#if MIDPOINT
uniform sampler2D u_back_map;   // structures/depth_map.py: the casters' faces turned away from the light centre
#endif
#if EARLY_SKIP
uniform sampler2D u_classes;    // structures/lit_umbra.py: pixels proven lit or umbra skip both kernels
#endif
uniform int u_blocker_samples;
uniform int u_filter_samples;
uniform float u_max_radius;     // texels: the blocker search's reach
uniform float u_filter_max_radius;
#ifndef BGAIN
#define BGAIN 2.0
#endif  // texels: the filter's
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;

// Texels per metre (tangent, for a sun) of light plane, per axis, for a blocker at depth z seen from receiver
// depth d: a light-plane point q maps to the map offset q·spread(z, d)/texel (the similar triangles above),
// the footprint's reach (|centre| + half_box) held between half a texel and `cap` texels. For a planar light
// q = k·h, so the offset is k times the kernel's clamped half extent clamp(h·spread/texel), as before.
vec2 texels_per_unit(Footprint f, float z, float d, float cap) {
    vec2 extent = abs(f.centre) + f.half_box;
    vec2 reach = extent * (penumbra_spread_clamped(z, d, u_light_ortho) / u_texel_tan);
    return max(min(reach, vec2(cap)), vec2(0.5)) / max(extent, vec2(1e-30));
}

// Whether light-plane point q (a direction (q, 1) in a sun's view) is a point of the light. Always so in the
// sun's own view (the kernel's disk is the light's); a rim view (core.lightview.sun_rim_faces) centres the same
// disk on a point of the sun's edge, and only the directions within the sun's half angle of its axis
// (-u_light_emit) are the sun's.
bool in_light(vec2 q) {
    if (u_light_ortho == 0) return true;
    vec3 d = vec3(q, 1.0);
    float cos_half = inversesqrt(1.0 + u_light_half.x * u_light_half.x);
    return -dot(d, u_light_emit) >= cos_half * length(d) * (1.0 - 1e-5);
}

// A view whose axis is not the light's own: a sun's rim view, an area light's cube face.
bool off_axis_view() {
    return u_light_emit.z > -0.9999;
}

// A sun's view whose axis is not the sun's own: one of its rim views.
bool is_rim_view() {
    return u_light_ortho == 1 && off_axis_view();
}

// Whether all of a planar light's rectangle (its bounding one for a disk) lies above the receiver's horizon.
bool whole_light_above(Receiver r, vec3 n) {
    for (int i = 0; i < 4; ++i) {
        vec2 c = u_light_half * vec2(i % 2 == 0 ? -1.0 : 1.0, i < 2 ? -1.0 : 1.0);
        if (dot(n, vec3(c, 0.0) - r.local) <= 0.0) return false;
    }
    return true;
}

// A tap's weight, 0 below the receiver's horizon. Otherwise the irradiance its light point carries, the
// visibility Cycles measures; an even vote over-weighted the light's far side, which a receiver next to a
// caster sees least of. At 128² against Cycles 1024 spp, vote → weighted: grazing 0.050 → 0.030, cube 0.097 →
// 0.089, suzanne 0.048 → 0.039, balls 0.051 → 0.045, tilted 0.041 → 0.035, plane 0.075 → 0.070; thin, city
// within +0.001; fuzz 10000–10039 mean 0.0346 → 0.0338, none over its bound.
// - Planar light, own view: the light's cosine over squared distance, for the point the tap really looks at
//   (`shrink`: under the caps the taps stand for a smaller light). The receiver's cosine counts only
//   where the whole light is above its horizon: where the horizon cuts the light it put nearly all the weight on
//   the few taps far above it, whose rays PCSS's single blocker depth maps worst (tests/test_rim_views.py's
//   floor seeing a sliver of its light: 0.119 voted, 0.206 with that cosine, 0.117 without).
// - Planar light on a cube face: the kernel spans the light projected onto the face's plane, whose points are
//   not the light's: the plain vote.
// - Sphere light: its footprint reaches further on the far side, where a plane point holds less of its solid
//   angle (tests/test_sphere_footprint.py: vote 0.0224, weighted 0.0167).
// - Sun: its rim views weigh the cos³θ density with the receiver's cosine (tests/test_wide_sun.py); its own view
//   votes: a disk of tangents out to tan 1.5 rad puts few taps where the weight is (the very wide sun of
//   test_wide_sun.py at pcss_max_radius 0.5: 0.060 voted, 0.184 weighted).
float tap_weight(Receiver r, vec3 n, vec2 q, vec2 shrink) {
    if (!in_light(q)) return 0.0;
    float w = light_sample_weight(r, n, q);
    if (w <= 0.0) return 0.0;
    if (u_light_one_sided == 1) {
        if (off_axis_view()) return 1.0;
        // light_sample_weight at the point the tap looks at, the receiver's cosine only where it may count;
        // a tap whose own point q is above the horizon keeps a weight.
        vec2 seen = q * shrink;
        if (whole_light_above(r, n)) return max(light_sample_weight(r, n, seen), 1e-30);
        vec3 to_sample = vec3(seen, 0.0) - r.local;
        float d2 = max(dot(to_sample, to_sample), 1e-30);
        return max(emitter_cosine(to_sample * inversesqrt(d2)) / d2, 1e-30);
    }
    return is_rim_view() || u_light_sphere == 1 ? w : 1.0;
}

// The blocker search's weight for its tap at kernel position k (ours). The taps cover the near plane's
// region evenly, and a caster at depth z can only hide light from the receiver within its own frustum
// cross-section there, a disk of radius spread(z)/spread(near) in kernel units: an even count weighs each
// caster by that disk's area, so casters near the light (wide disks) pull the mean blocker depth towards
// the light, and the penumbra comes out too wide (a sphere's top over its silhouette, a pole's upper end
// over its foot). Weighting by 1/(ε + |k|²) makes a caster's weight grow with the log of its disk's radius
// instead of its square; ε = 0.01 keeps the centre's taps finite. Dividing by each blocker's own spread²
// instead (its share of the light) over-weights casters touching the receiver: city 0.106 → 0.177.
// At 128² against Cycles 1024 spp, even → 1/(ε + |k|²): balls 0.0451 → 0.0412, city 0.1055 → 0.0971,
// contact 0.0305 → 0.0278, slab 0.0860 → 0.0751, room 0.0158 → 0.0151, flattened 0.0044 → 0.0038; the other
// eight scenes within ±0.0002.
float search_tap_density(vec2 k) {
    return 1.0 / (0.01 + dot(k, k));
}

// How much the cap shrank the kernel: its taps at q look along the rays to light points q·shrink.
vec2 cap_shrink(vec2 per_unit, float z, float d) {
    vec2 exact = vec2(penumbra_spread_clamped(z, d, u_light_ortho)) / u_texel_tan;
    return clamp(per_unit / max(exact, vec2(1e-30)), 0.0, 1.0);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float v = 1.0;
#if EARLY_SKIP
    float cls = texelFetch(u_classes, px, 0).r;
    if (cls == float(CLASS_UMBRA)) v = 0.0;
    if (cls == float(CLASS_GATHER) && pixel_lit(px)) {
#else
    if (pixel_lit(px)) {
#endif
        Receiver r = pixel_receiver(px);
        r.bias = slope_scaled_bias(r);      // blockers searched and filtered over a whole region
        vec3 n = view_direction(texelFetch(g_normal, px, 0).xyz);
        float d = r.map.z - r.bias;
        Footprint f = light_footprint(r.local);
        // 1. Blocker search over the region the light can be seen through at the near plane.
        vec2 search = texels_per_unit(f, u_light_depth_range.x, d, u_max_radius);
        vec2 search_shrink = cap_shrink(search, u_light_depth_range.x, d);
        float blocker_sum = 0.0, blocker_weight = 0.0;
        // A rim view's receiver sees the sun through a sliver of the kernel's disk, which few of the pattern's
        // taps may hit: its search also looks along the view's axis, the rim point the view was chosen for
        // (fuzz 7119: mae_shadow 0.23 -> 0.064, the blocker was missed under most of the shadow).
        for (int i = is_rim_view() ? -1 : 0; i < u_blocker_samples; ++i) {
            vec2 k = i < 0 ? vec2(0.0) : kernel_point(i, u_blocker_samples, u_light_round, 0.0);
            vec2 q = light_point(f, k);
            float w = tap_weight(r, n, q, search_shrink) * search_tap_density(k);
            if (w <= 0.0) continue;
            ivec2 t = ivec2(floor(r.map.xy + q * search));
            if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_map_size))) continue;
            float z = texelFetch(u_depth_map, t, 0).r;
            float zr = receiver_depth_at(r, vec2(t) + 0.5);
            if (z < zr && !facet_clears_receiver(r, t, z)) {
#if MIDPOINT
                float back = texelFetch(u_back_map, t, 0).r;
                if (back > z && back < zr) z = 0.5 * (z + back);
#endif
                blocker_sum += w * z; blocker_weight += w;
            }
        }
        if (blocker_weight > 0.0) {
            // 2. Penumbra size from the (weighted) mean blocker depth; 3. weighted PCF over it, under its own
            // cap (pcss_filter_max_radius): a blocker the search found within its reach may cast a penumbra
            // wider than that reach.
            float zb = blocker_sum / blocker_weight;
            vec2 radius = texels_per_unit(f, zb, d, u_filter_max_radius), shrink = cap_shrink(radius, zb, d);
            float sum = 0.0, total = 0.0;
            for (int i = 0; i < u_filter_samples; ++i) {
                vec2 q = light_point(f, kernel_point(i, u_filter_samples, u_light_round, 0.0));
                float w = tap_weight(r, n, q, shrink);
                if (w <= 0.0) continue;
                sum += w * map_lit_bilinear_plane(u_depth_map, r.map.xy + q * radius, r);
                total += w;
            }
            if (total > 0.0) v = sum / total;
        }
    }
    imageStore(u_visibility, px, vec4(v));
}
