// Averaged shadow maps (REFERENCE): adds a batch of hard shadow maps (layers of one texture array, each
// rendered from one sample point of the light) to running sums, in sample order.
// Each sample is weighted by its unoccluded contribution at the pixel (cosines over squared distance), so
// the average converges to the irradiance-weighted visibility that Cycles' shadowed/unshadowed ratio gives;
// a spot's samples also carry its cone.
#define LIGHT_VIEW_PER_LAYER
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/spot.glsl"

uniform sampler2DArray u_depth_maps;
#if PEELED > 0
// The next caster surfaces behind each texel of u_depth_maps (depth peeling, NO_OCCLUDER where none): PEELED
// of them
uniform sampler2DArray u_depth_maps_1;
#endif
#if PEELED > 1
uniform sampler2DArray u_depth_maps_2;
#endif
// SIDE_ALL, or for a true sphere light SIDE_OUTSIDE (maps without the casters inside it: Cycles' rays end on
// its surface) or SIDE_INSIDE (samples on its surface, every caster), or for a soft-falloff light whose ball
// holds geometry SIDE_BEYOND_DISK (beyond_disk_weight): the receivers this set serves.
uniform int u_side;
#if FACETS
// The plane normal of the triangle each texel of u_depth_maps holds (Frame.render_facet_layers)
uniform sampler2DArray u_facet_maps;
#endif
struct Sample {
    mat4 view;
    vec4 window;
    vec4 range_tan_ortho;   // near, far, texel tan, ortho (0/1)
    ivec4 size;             // map size (xy); z: 1 where the view is clamped (lightview.fit: some receivers off it)
    vec4 position;          // world position of the sample (perspective views)
    vec4 emit;              // light's emission axis (world); a sun's: this sample's direction; w: the sample's
                            // weight against a uniform one (1/pdf, techniques/averaged.py near_area_samples)
};
layout(std430, binding = 1) readonly buffer Samples { Sample samples[]; };
uniform int u_count;
// The light's smallest half extent: metres, or for a sun the tangent of its half angle; 0 for a point-like
// light (every caster's penumbra is then under a texel)
uniform float u_light_extent;
uniform vec4 u_sphere_inside;     // a true sphere light's centre and r² (r² = -1 for any other light)
// A soft-falloff point or spot light (Cycles' disk of radius r at the centre, facing each receiver): the axis
// of the disk the samples lie on (0 when they fill the ball) and r; r = -1 for any other light.
uniform vec4 u_soft_disk;
uniform int u_weight_mode;        // WEIGHT_NONE, WEIGHT_AREA (both cosines), WEIGHT_SPHERE (receiver cosine), WEIGHT_SUN
layout(rgba32f, binding = 0) uniform image2D u_sums;   // Σ w·v, Σ w, Σ v, count
// Σ w²: with Σ w, the pixel's effective sample count (Σ w)² / Σ w² (Kish), which decides whether the light gets
// more samples (techniques/averaged.py more_samples)
layout(r32f, binding = 2) uniform image2D u_square_weights;
#if EARLY_SKIP
uniform sampler2D u_classes;      // structures/lit_umbra.py: pixels proven lit or umbra need no sample
#endif

// Where the ray from p towards `to_light` meets Cycles' disk facing p: its distance from p, or -1 where it
// misses the disk (or p is the centre).
float facing_disk_distance(vec3 p, vec3 to_light) {
    vec3 m = p - u_sphere_inside.xyz;
    float d = length(m);
    float cos_facing = d > 0.0 ? -dot(to_light, m) / d : 0.0;
    if (cos_facing <= 0.0) return -1.0;
    vec3 on_disk = m + to_light * (d / cos_facing);
    return dot(on_disk, on_disk) > u_soft_disk.w * u_soft_disk.w * 1.0001 ? -1.0 : d / cos_facing;
}

// The chord of the light's ball along the ray from p towards `to_light`: its middle's distance from p and
// its half length squared (≤ 0 where the ray misses the ball).
vec2 ball_chord(vec3 p, vec3 to_light) {
    vec3 m = p - u_sphere_inside.xyz;
    float t_mid = -dot(m, to_light);
    return vec2(t_mid, u_soft_disk.w * u_soft_disk.w - max(dot(m, m) - t_mid * t_mid, 0.0));
}

// Cycles' soft falloff samples the disk through the light centre facing p (kernel/light/point.h and spot.h,
// the "oriented disk"): per unit of solid angle its integrand is the receiver's cosine over the directions
// that meet that disk; a sample whose ray misses it weighs nothing. The caller's weight is the receiver's
// cosine over d² (d² = `d2`, to the sample); this is the factor that makes it the receiver's cosine over the
// samples' density in solid angle seen from p. Samples on a disk across the view's axis: that disk's cosine
// (its density per solid angle ∝ cosθ/d²). Samples filling the ball (averaged.projected_disk_ball, density
// ∝ 1/√(L² − s²) at s along a chord of half length L from its middle, t_mid from p): their density along
// the ray's direction is ∫ ρ t² dt over the chord, π(t_mid² + L²/2), so the factor is d²/(t_mid² + L²/2).
// Far from the light (d ≫ r) both come to ~1 over d²; at d ~ r they decide the weights (fuzz 63: a 2.2 m
// spot 2.4 m away). The ball took the facing disk's cosine before, exact only far away: a 1 m light 1.3 m over
// the floor (tests/test_sphere_light_samples.py), 0.033 -> 0.025 with the ball's samples.
float soft_disk_weight(vec3 p, vec3 to_light, float d2) {
    if (p == u_sphere_inside.xyz) return 1.0;
    if (facing_disk_distance(p, to_light) < 0.0) return 0.0;
    if (dot(u_soft_disk.xyz, u_soft_disk.xyz) > 0.0) return abs(dot(to_light, u_soft_disk.xyz));
    vec2 chord = ball_chord(p, to_light);
    return d2 / max(chord.x * chord.x + 0.5 * max(chord.y, 0.0), 1e-30);
}

// SIDE_BEYOND_DISK: a soft-falloff light whose ball holds geometry, or with receivers within a few radii
// (averaged.NEAR_BALL). A ball sample's ray from p meets Cycles' disk facing p at some point D, but ends at the
// sample: where the sample lies short of the disk the map cannot see the casters between it and D, and where
// it lies beyond, its map sees casters behind the disk, which Cycles' ray never reaches (the walls of a room
// the ball reaches through). Only samples beyond the disk serve p here, and the test looks past every surface
// between the sample and D (the peeled layers, `stored_beyond`). Their density along the ray is the ball's
// beyond D, so each weighs the receiver's cosine over its direction's density in solid angle from p,
// q = ∫ ρ t² dt over the chord's part beyond D (ρ as in soft_disk_weight): the factor on the caller's weight
// (the receiver's cosine over d² = `d2`) is d²/q. Then Σ w·v / Σ w converges to the receiver-cosine-weighted
// visibility over the directions that meet the disk, the integrand of Cycles' soft falloff. Near receivers
// with nothing in the ball gain too: the ball points on their side of the centre see them nearly edge-on.
// Returns 0 for a sample short of p's disk or whose ray misses it, and D's distance along the ray in `t_disk`.
float beyond_disk_weight(vec3 p, vec3 to_light, vec3 sample_at, float d2, out float t_disk) {
    t_disk = facing_disk_distance(p, to_light);
    vec3 c = u_sphere_inside.xyz;
    if (t_disk < 0.0 || dot(sample_at - c, p - c) >= 0.0) return 0.0;
    vec2 chord = ball_chord(p, to_light);
    if (chord.y <= 0.0) return 0.0;
    float t_mid = chord.x, half2 = chord.y, half_chord = sqrt(half2);
    float s = clamp(t_disk - t_mid, -half_chord, half_chord);
    // ∫ from s to L of (s' + t_mid)² / √(L² − s'²) ds'
    float q = (t_mid * t_mid + 0.5 * half2) * (1.5707963 - asin(s / half_chord))
            + (2.0 * t_mid + 0.5 * s) * sqrt(max(half2 - s * s, 0.0));
    return d2 / max(q, 1e-30 * half2 * half_chord);
}

// The nearest caster depth at texel t of sample i's map beyond depth `from` (below every depth: the map's own).
// With PEELED the peeled layers behind it; a texel with every layer short of `from` counts as lit.
float stored_beyond(ivec2 t, int i, float from) {
    float z = texelFetch(u_depth_maps, ivec3(t, i), 0).r;
#if PEELED > 0
    if (z <= from) z = texelFetch(u_depth_maps_1, ivec3(t, i), 0).r;
#endif
#if PEELED > 1
    if (z <= from) z = texelFetch(u_depth_maps_2, ivec3(t, i), 0).r;
#endif
#if PEELED > 0
    if (z <= from) z = NO_OCCLUDER;
#endif
    return z;
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px) || !pixel_lit(px)) return;
#if EARLY_SKIP
    if (texelFetch(u_classes, px, 0).r != float(CLASS_GATHER)) return;
#endif
    vec3 p = texelFetch(g_position, px, 0).xyz;
    vec4 geometric = texelFetch(g_geometric, px, 0);
    vec3 ng = geometric.xyz;
    float lift = geometric.w;
    vec3 n = texelFetch(g_normal, px, 0).xyz;
    vec4 sums = imageLoad(u_sums, px);
    float square_weights = imageLoad(u_square_weights, px).r;
    vec3 from_centre = p - u_sphere_inside.xyz;
    bool inside_sphere = dot(from_centre, from_centre) <= u_sphere_inside.w;
    if ((u_side == SIDE_OUTSIDE && inside_sphere) || (u_side == SIDE_INSIDE && !inside_sphere)) return;
    for (int i = 0; i < u_count; ++i) {
        Sample s = samples[i];
        u_light_view = s.view;
        u_light_window = s.window;
        u_light_depth_range = s.range_tan_ortho.xy;
        u_texel_tan = s.range_tan_ortho.z;
        u_light_ortho = int(s.range_tan_ortho.w);
        u_map_size = s.size.xy;
        // the sample's direction, and its unoccluded contribution at p
        vec3 to_light;
        float w = 1.0;
        float from = -NO_OCCLUDER;      // depths up to this in the maps are not between p and the light
        if (u_weight_mode == WEIGHT_SUN) {
            to_light = -s.emit.xyz;
            // sun sample (uniform over the cone): its radiance is constant, so only the receiver's cosine counts
            w = max(dot(n, to_light), 0.0);
        } else {
            vec3 to_sample = s.position.xyz - p;
            float d2 = max(dot(to_sample, to_sample), 1e-30);   // m²: a receiver on the sample point
            to_light = to_sample * inversesqrt(d2);
            if (u_weight_mode != WEIGHT_NONE) {
                w = max(dot(n, to_light), 0.0) / d2;
                if (u_weight_mode == WEIGHT_AREA) w *= max(dot(-to_light, s.emit.xyz), 0.0) * s.emit.w;
                // A spot's cone applies per ray: a sample whose ray to p leaves the cone carries nothing (a wide
                // spot's disk reaches p only from its footprint; see shading/irradiance.glsl). Inside a true
                // sphere Cycles applies no cone.
                if (u_spot_cos_half > -1.0 && !inside_sphere) w *= spot_attenuation(-to_light);
                if (u_side == SIDE_BEYOND_DISK) {
                    // a sample that does not serve p, or lies below its horizon, is not counted at all
                    float t_disk;
                    float beyond = beyond_disk_weight(p, to_light, s.position.xyz, d2, t_disk);
                    if (beyond <= 0.0 || dot(n, to_light) <= 0.0) continue;
                    w *= beyond;
                    from = -(s.view * vec4(p + to_light * t_disk, 1.0)).z;
                } else if (u_soft_disk.w > 0.0) w *= soft_disk_weight(p, to_light, d2);
                if (u_side == SIDE_INSIDE) {
                    // uniform points of the surface seen from inside: dω = cosθ_surface·dA/d²; a spot's sphere
                    // is one-sided for BSDF rays (those towards its centre), which MIS weighs as much again
                    // (shading/irradiance.glsl, E = πL(3 + cosθ)/4)
                    w *= abs(dot(to_light, normalize(s.position.xyz - u_sphere_inside.xyz)));
                    if (u_spot_cos_half > -1.0 && dot(to_light, -from_centre) > 0.0) w *= 2.0;
                }
            }
        }
        Receiver r = make_lit_receiver(p, ng, n, lift, to_light);
        // Each texel is compared with the receiver's plane at that texel's centre (receiver_depth_at), exact for
        // the receiver's own triangle, so the slope-scaled part of the bias (a tilted surface's depth across a
        // texel) is not needed here; at grazing light it reached 10 texels and hid a caster 1.3 cm from the
        // receiver (fuzz 8207: a cylinder through a flat-shaded ball, n·l 0.03). The constant part stays.
        r.bias = u_bias * receiver_texel(p, r.start) * 0.5;
        // Two texels decide: the one the shadow ray's own start falls in, for casters far enough from the
        // receiver that their penumbra spans more than a fifth of a texel (`contact`: the light's extent seen
        // over the distance), and the one the normal offset moves the look-up to, for nearer casters. Far
        // casters' edges land on the N sample maps at N sub-texel offsets, which average out, so the start's
        // texel is right on average; the offset's texel moves them by the offset times tan θ along a
        // receiver at angle θ to the light (11 × 0.5 texel at n·l = 0.09), most of a narrow penumbra (fuzz
        // 9166: a huge smooth Suzanne's own creases lit too much, mae_shadow 0.057; tests/test_grazing_offset.py).
        // A caster whose penumbra is under a fifth of a texel (one touching the receiver, any caster of a
        // point-like light) is one hard edge in every map: there the offset's texel, looking from above the
        // surface, keeps a caster at the receiver's foot from being missed by a texel ray that runs under it
        // into the receiver's own plane (tests/test_grazing_contact.py), and a crease's neighbouring face
        // from shadowing it. The fifth: 9166's monkey (tests/test_grazing_offset.py) with a penumbra limit of
        // a texel, half a texel, a fifth: mae_shadow 0.042, 0.039, 0.028.
        float extent_over_distance = u_light_ortho == 1 ? u_light_extent
                                                        : u_light_extent / max(distance(s.position.xyz, p), 1e-30);
        // a caster Δ in front of the receiver casts a penumbra 2·extent·Δ/d wide: under a fifth of a texel
        // while Δ < contact
        float contact = 0.1 * texel_world(max(r.map.z, 0.0)) / max(extent_over_distance, 1e-30);
        vec2 offset_at = r.map.xy;
        r.map.xy = map_coords(r.start).xy;
        ivec2 t = ivec2(floor(r.map.xy));
        float v = 1.0;              // outside the map counts as lit (map_lit)
        bool in_map = all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, u_map_size));
        ivec2 to = ivec2(floor(offset_at));
        bool offset_in_map = all(greaterThanEqual(to, ivec2(0))) && all(lessThan(to, u_map_size));
        // A surface sample whose view a receiver inside the sphere is behind, or off, cannot test it: left
        // out, as counting it lit brightens every receiver the surface surrounds (each such view looks towards
        // the centre, so only receivers almost in the sample's tangent plane, of little weight, fall off it)
        if (u_side == SIDE_INSIDE && !(offset_in_map && r.local.z < 0.0)) continue;
        // Off a clamped view (one whose ±80° window could not hold its receivers) a receiver may still be
        // shadowed: that sample cannot test it and is left out. A point light's view whose receivers span a
        // floor to the horizon keeps the pixels inside the centre's window, while the windows from points of
        // a wide light miss those near its edge (fuzz 29050: a 0.83 m light, floor pixels off 120 of 256
        // sample maps, lit where a cylinder shades them).
        if (s.size.z != 0 && !in_map && !offset_in_map) continue;
        // A receiver aimed into its own smooth triangle is lit off the map too: the sample views hold the
        // lifted starts (Technique.fits_sample_views), so it is off only where its window, cut to the part of
        // the receivers a caster can shadow, leaves it out, and then its own object is no caster there either.
        // (Taking it as stopped there darkened a wide spot's whole sliver of such pixels that Cycles lights:
        // fuzz seed 1071, 19 pixels at 1.0, tests/test_own_surface.py.)
        if (in_map) {
            float stored = stored_beyond(t, i, from);
            vec2 centre = vec2(t) + 0.5;
            float depth = receiver_depth_at(r, centre);
            if (stored < depth && depth - stored >= contact) v = 0.0;
#if FACETS
            // What the bias leaves lit, the plane of the nearest surface's triangle decides (facet_separates)
            if (v > 0.0 && from <= -NO_OCCLUDER
                && facet_separates(r, texelFetch(u_facet_maps, ivec3(t, i), 0).xyz, centre, stored)) v = 0.0;
#endif
        }
        if (v > 0.0 && offset_in_map) {
            float stored = stored_beyond(to, i, from);
            vec2 centre = vec2(to) + 0.5;
            float depth = receiver_depth_at(r, centre);
            if ((stored < depth && depth - stored < contact) || own_surface_blocks(r, stored, centre)) v = 0.0;
        }
        sums += vec4(w * v, w, v, 1.0);
        square_weights += w * w;
    }
    imageStore(u_sums, px, sums);
    imageStore(u_square_weights, px, vec4(square_weights));
}
