// Conservative lit/umbra classification of each pixel a light reaches (structures/lit_umbra.py), so that a
// gather (PCSS's blocker search and filter, REFERENCE's per-sample look-ups) can skip it.
//
// The rays from a receiver to the points of the light cross the light view inside the receiver–light pyramid
// (Schwarz & Stamminger 2007 §2.1, the area BACKPROJECTION searches): at occluder depth z its section is the
// receiver's window position ± h·(1/z − 1/d) (common/penumbra.glsl); the widest section, at the near plane,
// holds them all. A light point off the view's z = 0 plane by up to ρ (a sphere light's ball, an area light
// seen through a cube face) widens it: from a point s at depth −s.z the section is tp ± (|s.xy| + |tp|·ρ)·
// (d − z)/(z·(d − ρ)), i.e. h grows to (h + |tp|·ρ)·d/(d − ρ). The min/max pyramid of the depth map
// (GBP06) bounds the depths over that area cell by cell (at most CELLS² cells), each cell against the tangent
// plane's own extremes over it:
//   LIT    everything there lies on or below the receiver's tangent plane, or beyond the receiver, with a
//          slack for the differing bias and normal offset of REFERENCE's per-sample maps: no tap, of any
//          kernel or any sample map, can find a blocker, so the gather would return exactly 1;
//   UMBRA  the whole area lies inside the map and everything there is nearer than the plane (less the
//          bias and the slack), and every point of the light lies above the receiver's geometric tangent
//          plane and has a positive weight: every tap is a blocker, so the gather would return exactly 0.
// Everything else is left to the gather (CLASS_GATHER). The tangent plane is the receiver-plane test of
// receiver_depth_at (common/light_view.glsl), so a tilted floor does not hide its own pixels from LIT — only
// within a cell: cells much wider than the plane's depth change per texel × slack stay GATHER.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/penumbra.glsl"

uniform sampler2D u_pyramid;        // RG32F min/max mip pyramid of the depth map (lit_umbra/reduce.comp):
uniform int u_levels;               // its level l holds cells of 2^(l + u_base) texels
uniform int u_base;
uniform float u_light_depth_extent; // ρ (metres; 0 for a sun's ortho view)
uniform float u_margin;             // texels added to the area on each side (kernel taps, bilinear footprint)
uniform float u_slack;              // depth slack, in texels at the receiver scaled by its slope
uniform int u_passes;               // 1: the area at the near plane only; more: narrowed to the least depth
uniform float u_cap;                // texels: the most the area's half extent may reach (a technique's cap)
uniform float u_umbra_cap;          // texels: the same for the gather's widest kernel (PCSS's filter), ≥ u_cap
uniform float u_texel_ratio;        // the largest texel of the gather's maps over this map's (1: this map)
layout(r32f, binding = 0) uniform writeonly image2D u_class;

// The tangent plane's depth (receiver_depth_at, capped at the receiver, bias added back) at its largest
// (`upper`) or least over the texel box [lo, hi + 1): a monotone function of a quantity affine in the map
// position (the ray's dot product with the normal), so one corner, picked by the normal's signs, holds it.
float plane_extreme(Receiver r, vec2 lo, vec2 hi, bool upper) {
    bvec2 far_side = upper ? greaterThanEqual(r.normal.xy, vec2(0.0)) : lessThan(r.normal.xy, vec2(0.0));
    vec2 corner = vec2(far_side.x ? hi.x : lo.x, far_side.y ? hi.y : lo.y);
    return receiver_depth_at(r, corner) + r.bias;
}

// Cell by cell over texels [lo, hi] (clamped to the map), on the finest pyramid level where the box spans at
// most CELLS cells per axis: whether every cell's least depth lies at or beyond the plane's largest depth
// over the cell plus `slack` (x: lit), by how much every cell's greatest depth lies nearer than the plane's
// least (y: umbra where it exceeds the gap; ≤ 0 once a cell fails) and, with `whole`, the least depth (z).
// Without `whole` it stops at the first cell that rules out both.
const int CELLS = 4;
vec3 cell_test(Receiver r, ivec2 lo, ivec2 hi, bool plane, float d, float slack, bool whole) {
    int l = u_base;
    while (l < u_base + u_levels - 1 && any(greaterThanEqual((hi >> l) - (lo >> l), ivec2(CELLS)))) ++l;
    bool lit = true;
    float umbra = plane ? NO_OCCLUDER : 0.0;
    float zmin = NO_OCCLUDER;
    for (int y = lo.y >> l; y <= hi.y >> l; ++y)
        for (int x = lo.x >> l; x <= hi.x >> l; ++x) {
            vec2 m = texelFetch(u_pyramid, ivec2(x, y), l - u_base).rg;
            zmin = min(zmin, m.x);
            if (!lit && umbra <= 0.0) {
                if (whole) continue;
                return vec3(0.0, umbra, zmin);
            }
            vec2 a = vec2(max(ivec2(x, y) << l, lo)), b = vec2(min(((ivec2(x, y) + 1) << l) - 1, hi) + 1);
            if (lit) lit = m.x >= (plane ? plane_extreme(r, a, b, true) : d) + slack;
            if (umbra > 0.0) umbra = min(umbra, plane_extreme(r, a, b, false) - m.y);
        }
    return vec3(lit ? 1.0 : 0.0, umbra, zmin);
}

// Whether every point of the light (the box ±h × ±ρ in the view's frame; a sun: directions (k·h, 1)) lies
// strictly above the plane through r with normal `normal`, by `eps` metres (a direction: its cosine above
// `eps`); `tan_max` gets the largest tangent of the angle between the normal and a ray to the light. Both the
// side and the angle are extreme at a corner: the points within an angle of the normal form a convex cone.
bool light_above(Receiver r, vec3 normal, float eps, out float tan_max) {
    tan_max = 0.0;
    for (int i = 0; i < 8; ++i) {
        vec2 k = vec2((i & 1) == 0 ? -1.0 : 1.0, (i & 2) == 0 ? -1.0 : 1.0);
        float z = (i & 4) == 0 ? -u_light_depth_extent : u_light_depth_extent;
        vec3 ray = u_light_ortho == 1 ? vec3(k * u_light_half, 1.0) : vec3(k * u_light_half, z) - r.local;
        float side = u_light_ortho == 1 ? dot(normal, normalize(ray)) : dot(normal, ray);
        if (side <= eps) return false;
        float c = dot(normal, normalize(ray));
        tan_max = max(tan_max, sqrt(max(1.0 - c * c, 0.0)) / c);
    }
    return true;
}

// Whether every kernel position k ∈ [-1, 1]² carries light (light_sample_weight > 0 at its light_point): its
// zero set is the intersection of half-planes in k (light_point is affine in k), so the four corners decide.
bool light_weighted(Receiver r, vec3 n) {
    Footprint f = light_footprint(r.local);
    for (int i = 0; i < 4; ++i)
        if (light_sample_weight(r, n, light_point(f, vec2((i & 1) == 0 ? -1.0 : 1.0, (i & 2) == 0 ? -1.0 : 1.0)))
                <= 0.0)
            return false;
    return true;
}

// Umbra (given every cell nearer than the plane by `margin`) needs every light point above the geometric
// tangent plane (below it a sample map's plane test counts nothing as a blocker) and carrying weight (PCSS's
// kernels skip weightless taps), and a margin beyond the largest bias and normal offset any of the gather's
// maps applies: texels up to u_texel_ratio times this one's (a ball sample's map nearer or farther by ρ), at
// the light's most oblique ray.
bool umbra_gap(Receiver r, ivec2 px, float d, float rho, float slack, float tan_t, float margin) {
    float tan_max = 0.0;
    if (!light_above(r, r.normal, u_light_ortho == 1 ? 1e-4 : slack, tan_max)) return false;
    if (!light_weighted(r, view_direction(texelFetch(g_normal, px, 0).xyz))) return false;
    float tw = u_texel_ratio * texel_world(d) * (d + rho) / d;
    tan_max = min(max(tan_max, tan_t), 10.0);
    return margin > r.bias + u_bias * tw * (0.5 + tan_max) + 2.0 * u_normal_offset * tw * (1.0 + tan_max) + slack;
}

float classify(ivec2 px) {
    vec4 geometric = texelFetch(g_geometric, px, 0);
    Receiver r = make_receiver(texelFetch(g_position, px, 0).xyz, geometric.xyz);
    // The gathers' shadow rays leave a smooth triangle lifted towards the light (make_lit_receiver): past
    // blockers within the lift of the surface, so the unlifted point's umbra proves nothing for them. Its
    // lit holds, the lifted point's tangent plane lying higher still.
    bool lifted = u_terminator_offset > 0.0 && geometric.w != 0.0;
    float d = r.map.z;
    float rho = u_light_ortho == 1 ? 0.0 : u_light_depth_extent;
    if (!(d > 1.001 * rho) || !(d > 0.0)) return float(CLASS_GATHER);   // a receiver within the light's depth
    // Slack: the slope-scaled bias of make_receiver, for the bias and offset of any map of about this texel
    vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-r.local);
    float cos_t = clamp(abs(dot(r.normal, to_light)), 1e-3, 1.0);
    float tan_t = min(sqrt(1.0 - cos_t * cos_t) / cos_t, 10.0);
    float slack = u_slack * texel_world(d) * (1.0 + tan_t);
    // The search area, widened for light points off the z = 0 plane, capped, and grown by the margin. With
    // u_passes > 1 it narrows to the section at the least depth found, as BACKPROJECTION does (§5): nothing
    // nearer lies in it, so no ray to the light meets an occluder outside that section.
    vec2 tp = window_coords(r.local);
    vec2 h = (u_light_half + abs(tp) * rho) * (d / (d - rho));
    vec2 c = clamp(r.map.xy, vec2(-2.0e7), vec2(2.0e7));
    bool centre_above = centre_above_plane(r);
    float z = u_light_depth_range.x;
    for (int pass = 0; pass < u_passes; ++pass) {
        vec2 reach = h * penumbra_spread_clamped(z, d, u_light_ortho) / u_texel_tan;
        vec2 half_ = min(reach, vec2(u_cap)) + u_margin;
        ivec2 lo = ivec2(floor(c - half_)), hi = ivec2(floor(c + half_));
        if (any(greaterThanEqual(lo, u_map_size)) || any(lessThan(hi, ivec2(0)))) return float(CLASS_LIT);
        bool inside = all(greaterThanEqual(lo, ivec2(0))) && all(lessThan(hi, u_map_size));
        // Where the light's centre lies on or below the tangent plane, some light points may still lie above
        // it: only the receiver's depth bounds what can shadow it.
        vec3 t = cell_test(r, max(lo, ivec2(0)), min(hi, u_map_size - 1), centre_above, d, slack,
                           pass + 1 < u_passes);
        if (t.x > 0.0) return float(CLASS_LIT);
        // A search that finds nothing leaves the pixel lit, but a kernel reaching past the search (PCSS's
        // filter) must find nothing but blockers over all of its reach for the pixel to be in umbra.
        vec2 wide = min(reach, vec2(u_umbra_cap)) + u_margin;
        if (t.y > 0.0 && any(greaterThan(wide, half_))) {
            lo = ivec2(floor(c - wide));
            hi = ivec2(floor(c + wide));
            inside = all(greaterThanEqual(lo, ivec2(0))) && all(lessThan(hi, u_map_size));
            if (inside) t.y = cell_test(r, lo, hi, centre_above, d, slack, false).y;
        }
        if (t.y > 0.0 && inside && !lifted && umbra_gap(r, px, d, rho, slack, tan_t, t.y)) return float(CLASS_UMBRA);
        vec2 zr = t.zz;
        if (!(zr.x > z)) break;         // nothing to narrow
        z = zr.x;
    }
    return float(CLASS_GATHER);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    imageStore(u_class, px, vec4(pixel_lit(px) ? classify(px) : float(CLASS_UNREACHED)));
}
