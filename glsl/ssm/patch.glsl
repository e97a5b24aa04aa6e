// One occluder micro-patch and the fraction of the light it hides from a receiver (Atty et al. 2006).
//
// Frame: the light-view eye sits at the light's centre, the light lies in the plane depth = 0, and the
// occluder map is axis-aligned with the light (§3.2). Window coordinates are tangents at unit depth
// (perspective) or metres (ortho view of a sun). A micro-patch is the occluder-map texel [lo, hi] (window
// units) moved to its depth zo, parallel to the light (§3.2, Fig. 4).
//
// §3.4, back-projection: seen from a receiver at window position t and depth zr, a patch point at window
// position u projects onto the light plane at  x = (u - t) / s,  with the "spread"
//     s = 1/zo - 1/zr     (perspective: x = zr·zo·(u - t)/(zr - zo), similar triangles through the patch)
//     s = zr - zo         (sun: a direction tangent (u - t)/(zr - zo))
// so the patch covers the axis-aligned rectangle [(lo - t)/s, (hi - t)/s] of the light, whose half extent
// is h (metres, or tan(angle/2) for a sun). Normalising the light to [0, 1]² (the paper's MOV_SAT / SUB /
// MUL trick) the hidden fraction is the product of the two clamped interval lengths.
#include "common/penumbra.glsl"
// light_view.glsl: the SSM view's window and size (u_light_window, u_map_size), the receiver rule
#include "common/light_view.glsl"
#include "common/polygon.glsl"
#include "common/disk.glsl"
#ifndef SSM_HORIZON_CUT
#define SSM_HORIZON_CUT 0               // 1: some receiver's horizon cuts the light (see weighted_fraction)
#endif
#ifndef SSM_WEIGHTED
#define SSM_WEIGHTED 0                  // 1: occlusion weighted by irradiance (see weighted_fraction)
#endif
#ifndef SSM_ROUND
#define SSM_ROUND 0                     // 1: a round light (see light_share)
#endif
#define ROUND_WEIGHT_SPAN 0.5           // weighted_fraction clips to a round light up to this half extent / zr
uniform vec2 u_half;                // light half extent (of the bounding rectangle, for round lights)
uniform int u_ortho;
uniform float u_bias_texels;        // relative depth gap: a patch occludes only if zo < zr·(1 − u_bias_texels)
uniform int u_receiver_normal;      // 1: weights take the receiver's normal (a planar emitter; weighted_fraction)

// The share of the light that the overlap `ab` (normalised light coordinates [0, 1]², possibly with swapped
// sides: signed, for facets) covers. A round light (SSM_ROUND: a disk or ellipse area light, a sun in its own
// view) is the ellipse inscribed in its rectangle, which is the unit disk once [0, 1]² is mapped to [-1, 1]².
// Ours: the paper treats lights as rectangles, whose corners hold 21 % of the area, so a sliver across the
// middle of the light hid only π/4 of its share of the disk: a thin caster's penumbra came out too light.
float light_share(vec4 ab) {
#if SSM_ROUND
    return disk_share(ab * 2.0 - 1.0);
#else
    return (ab.z - ab.x) * (ab.w - ab.y);
#endif
}

#ifndef SSM_SPOT_CLIP
#define SSM_SPOT_CLIP 0                 // 1: a spot's cone clips each receiver's view of its ball (spot_share)
#endif
#if SSM_SPOT_CLIP
// Ours, as PCSS and BACKPROJECTION have it (common/light_view.glsl light_footprint): under a spot's cone
// narrower than its ball a receiver sees only the part of the ball whose rays to it lie inside the cone, a
// disk far smaller than the ball's square (fuzz 30111: a 1.4 m ball behind a 5.4° cone). spot_receiver sets
// that disk for the receiver at hand; a patch whose back-projection onto the light plane is x (metres: window
// offsets over the spread, x0, y0, x1, y1) then hides the share of the disk it covers, taken as uniform (the
// cone's blend across so small a disk left out).
Footprint g_spot;
bool g_spot_clipped = false;

void spot_receiver(vec3 local) {
    g_spot = light_footprint(local);
    g_spot_clipped = g_spot.cone_clipped;
}

float spot_share(vec4 x) {
    // the lens of cone and ball can shrink to a point where their rims touch: a zero radius still divides
    return disk_share((x - g_spot.centre.xyxy) / max(g_spot.half_box.xyxy, vec4(1e-12)));
}
#endif

bool depth_valid(float z) {
    return z > 0.0 && z < EMPTY_DEPTH;
}

// The window rectangle (x0, y0, x1, y1) of the micro-patch of occluder texel `patch_texel`.
vec4 patch_window(vec2 patch_texel) {
    vec2 lo = map_window(patch_texel);
    return vec4(lo, lo + map_texel_window());
}

// A receiver of one soft-shadow-map texel, from the records of ssm/receivers.comp (a: depth, point; b:
// normal, bias with the through-surface flag as its sign; c: its own plane).
Receiver ssm_receiver(vec4 a, vec4 b, float c) {
    Receiver r;
    r.local = a.yzw;
    r.normal = b.xyz;
    r.map = vec3(0.0, 0.0, -a.w);       // only its depth is read (receiver_depth_at)
    r.through_surface = b.w < 0.0;
    r.bias = r.through_surface ? -b.w - 1.0 : b.w;
    r.own_plane = c;
    return r;
}

// Where a receiver's micro-patches are back-projected from (§3.4): the texel's window centre `t` at the
// depth `zr` where the receiver's plane crosses that texel's ray, as the paper's receiver map has it;
// for a receiver lit through its own smooth triangle, the lifted start of its shadow ray. Which of its own
// surface's patches stop that ray depends on where the ray crosses its own plane (own_surface_blocks),
// and seen from a point on that plane every own patch lies edge-on.
void receiver_eye(Receiver r, inout vec2 t, inout float zr) {
    if (!r.through_surface) return;
    t = window_coords(r.local);
    zr = -r.local.z;
}

// Whether the micro-patch of occluder texel `patch_texel` (depth zo) can shadow receiver r at all. Every
// object is both occluder and receiver in general scenes, so instead of the paper's split (§1, §6) the
// shared tangent-plane rule decides: nothing on or below the receiver's tangent plane (its own surface, a
// convex object's far side) hides any light above that plane, tested at the patch's centre with the
// receiver's slope-scaled bias (common/light_view.glsl receiver_depth_at).
bool patch_can_shadow(Receiver r, vec2 patch_texel, float zo) {
    if (zo < receiver_depth_at(r, patch_texel + 0.5)) return true;
    // A receiver aimed through its own smooth triangle: the shadow-map techniques' rule for it, its own
    // surface (or anything nearer) where the patch's ray crosses its plane stops the ray.
    if (r.through_surface) return own_surface_blocks(r, zo, patch_texel + 0.5);
    // With the light's centre on or below the plane the shared rule lets nothing count (every ray from the
    // centre meets the receiver from below), but part of an area light or a wide sun may still be above it,
    // and a patch above the plane, between it and the receiver, hides some of that part: above the plane
    // along the patch's ray.
    if (centre_above_plane(r)) return false;   // the shared rule decided
    // Above the plane by more than the bias at the patch's depth (beyond the crossing, for a ray rising
    // through the plane), and in front of the receiver.
    vec2 h = plane_along_map_ray(r.normal, dot(r.normal, r.local), patch_texel + 0.5);
    return h.x * (zo - r.bias) + h.y > 0.0 && zo < -r.local.z - r.bias;
}

#if SSM_WEIGHTED
// Irradiance weighting (our addition; the paper counts the plain area). The share of the light's irradiance
// that a rectangle of the light plane carries to a receiver facing the light, at height zr over its foot
// point: the form factor of a parallel rectangle, F(corner a, b) = a/√(1+a²)·atan(b/√(1+a²)) + b/√(1+b²)·
// atan(a/√(1+b²)) with a, b in units of zr (the differential-area-to-parallel-rectangle form factor, up to a
// constant), odd in each argument, so any rectangle is four signed corners.
float ff_corner(float a, float b) {
    float ra = inversesqrt(1.0 + a * a), rb = inversesqrt(1.0 + b * b);
    return a * ra * atan(b * ra) + b * rb * atan(a * rb);
}

float ff_rect(vec4 r) {          // x0, y0, x1, y1
    return ff_corner(r.z, r.w) - ff_corner(r.x, r.w) - ff_corner(r.z, r.y) + ff_corner(r.x, r.y);
}

// The same for a receiver of normal n (light-view frame) that the whole light lies above: the integrand gains
// the receiver's cosine, n·(a, b, 1)/(1 + a² + b²)², linear in n. Its a-term integrates to
// -atan(b/√(1+a²))/√(1+a²) (twice the corner function, as ff_corner is), the b-term likewise.
float tilted_corner(float a, float b, vec3 n) {
    float ra = inversesqrt(1.0 + a * a), rb = inversesqrt(1.0 + b * b);
    return n.z * (a * ra * atan(b * ra) + b * rb * atan(a * rb)) - n.x * ra * atan(b * ra) - n.y * rb * atan(a * rb);
}

float tilted_rect(vec4 r, vec3 n) {
    return tilted_corner(r.z, r.w, n) - tilted_corner(r.x, r.w, n) - tilted_corner(r.z, r.y, n)
         + tilted_corner(r.x, r.y, n);
}

// The irradiance (up to a constant) that rectangle r (x0, y0, x1, y1 in units of the height over its foot, as
// tilted_rect's) carries to a receiver of normal n from its part above the receiver's horizon: Lambert's edge
// formula (common/polygon.glsl) over the rectangle clipped to that part, written out edge by edge for the
// scatter's inner loop: clipped_polygon_sum's loop and vertex array cost balls' scatter 3.6 -> 6.2 s on
// llvmpipe, for the same result. Signed as the rectangle's orientation, for facets.
#define HORIZON_EMIT(p) { vec3 q = (p); if (have) sum += edge_term(prev, q, n); else { first = q; have = true; } prev = q; }
#define HORIZON_EDGE(a, b) { float ha = dot(n, a), hb = dot(n, b); if ((ha >= 0.0) != (hb >= 0.0)) HORIZON_EMIT(a + (b - a) * (ha / (ha - hb))) if (hb >= 0.0) HORIZON_EMIT(b) }
float rect_above_horizon(vec4 r, vec3 n) {
    vec3 v0 = vec3(r.xy, 1.0), v1 = vec3(r.z, r.y, 1.0), v2 = vec3(r.zw, 1.0), v3 = vec3(r.x, r.w, 1.0);
    float sum = 0.0;
    vec3 first = vec3(0.0), prev = vec3(0.0);
    bool have = false;
    HORIZON_EDGE(v3, v0) HORIZON_EDGE(v0, v1) HORIZON_EDGE(v1, v2) HORIZON_EDGE(v2, v3)
    if (have) sum += edge_term(prev, first, n);
    return (r.z - r.x) * (r.w - r.y) < 0.0 ? -abs(sum) : abs(sum);
}

// Hidden share of the light's irradiance at a receiver at window position t, depth zr, normal n, for the
// overlap `ab` (normalised light coordinates [0, 1]²). A sun's light coordinates are direction tangents about
// its axis, the same for every receiver: a direction (x, y, 1) stands for the solid angle cos³θ dx dy and the
// receiver's cosine weighs it by n·(x, y, 1)/|(x, y, 1)| more, the same integrand at unit height over the axis
// (foot t = 0, zr = 1). Where the receiver's horizon cuts the light (a corner at or below it) the linear form
// would count light below the horizon negatively: there both shares are of the light's part above the horizon
// (rect_above_horizon; balls 0.043 -> 0.039, city 0.151 -> 0.142). A sphere light's receiver is taken as
// facing the light, as before: its rectangle stands for a ball rather than a planar emitter (the normal's terms
// are not measured there). At 128² against Cycles 1024 spp, facing → own normal: grazing (the ground sees the
// light 85° off its normal) 0.038 → 0.009, tilted 0.0079 → 0.0057, contact 0.0093 → 0.0073; no built-in
// scene worse by more than 0.0001.
float weighted_fraction(vec4 ab, vec2 t, float zr, vec3 n) {
    if (u_ortho == 1) {
        t = vec2(0.0);
        zr = 1.0;
    }
    vec2 h = max(u_half, vec2(1e-9));      // metres (tan for a sun): a zero-size light still divides
    // A light narrower than 0.05 zr (about 3°) takes its plain area share: the weights hardly vary over it, and
    // the form factors of its rectangles, corners that agree to first order, cancel to float32 noise of either
    // sign (fuzz 1104, a 2.4 mm sphere light on the walls of a room around it: that noise clamped at 0 left the
    // walls unshadowed, 0.001; let through once facets allowed negative shares, 0.056; the plain share 0.043,
    // what the uniform weighting gives).
    if (max(h.x, h.y) < 0.05 * zr) return light_share(ab);
    vec4 rect = (ab - 0.5) * 2.0 * h.xyxy / zr - t.xyxy;      // overlap, relative to the foot, in units of zr
    vec4 light = vec4(-h, h) / zr - t.xyxy;
    bool above = rect_above(light, n);
    float total, part;
#if SSM_HORIZON_CUT
    if (u_receiver_normal == 1 && !above) {
        // The horizon cuts the light: only its part above carries irradiance, and it is what the patches over
        // the tangent plane (patch_can_shadow) hide. Both shares are of that part, weighed by the receiver's
        // cosine, so a receiver that sees a wide light only in part is in umbra when that part is hidden.
        total = rect_above_horizon(light, n);
        part = rect_above_horizon(rect, n);
    } else
#endif
    {
        bool tilted = u_receiver_normal == 1 && above;
        total = tilted ? tilted_rect(light, n) : ff_rect(light);
        part = tilted ? tilted_rect(rect, n) : ff_rect(rect);
    }
    // A round light: the weights over the rectangle scaled by the share of its area inside the light's disk,
    // which stands in for the share of its weight there (the exact clipped form factor costs a polygon per
    // patch) where the weights vary little over the light: up to a half extent of ROUND_WEIGHT_SPAN·zr, over
    // which a facing receiver's weight falls to 0.64. A wider light keeps its rectangle here: over a 2-3 rad
    // sun the weight sits near the axis and the area share overweighs central patches by up to 4/π (fuzz
    // 14026: 0.012 with the rectangle, 0.021 clipped).
    bool clip = SSM_ROUND == 1 && max(h.x, h.y) <= ROUND_WEIGHT_SPAN * zr;
    float area = (ab.z - ab.x) * (ab.w - ab.y), plain = clip ? light_share(ab) : area;
    if (!(total > 0.0)) return plain;
    if (clip) part *= plain / area;
    return clamp(part / total, -1.0, 1.0);      // signed: facets
}
#endif

// Lean form for the scatter's inner loop: d = (lo - t, hi - t) in window units, inv_zo = 1/zo, inv_2h =
// 1/(2h), texel_world_1 = world size of a texel at unit depth (perspective) or its size (ortho).
float patch_occlusion_fast(vec4 d, float zo, float inv_zo, float zr, vec2 inv_2h, float texel_world_1, vec2 t,
                           vec3 n) {
    // The receiver's own surface is kept out by patch_can_shadow; this only guards the spread's sign.
    if (!(zr > 0.0 && zr < EMPTY_DEPTH) || zo >= zr * (1.0 - u_bias_texels)) return 0.0;
    float s = u_ortho == 1 ? zr - zo : inv_zo - 1.0 / zr;     // penumbra_spread, 1/zo hoisted per patch
#if SSM_SPOT_CLIP
    if (g_spot_clipped) return spot_share(d / s);
#endif
    vec2 k = inv_2h / s;
    vec4 ab = clamp(vec4(0.5) + d * k.xyxy, 0.0, 1.0);
    vec2 w = ab.zw - ab.xy;
#if SSM_WEIGHTED
    if (w.x > 0.0 && w.y > 0.0) return weighted_fraction(ab, t, zr, n);
#endif
    return light_share(ab);
}

#ifndef SSM_FACETS
#define SSM_FACETS 0                    // 1: sloped facets in place of flat micro-patches (facet_occlusion)
#endif
uniform float u_facet_slope;        // texels of depth per texel below which two neighbours are one surface

// Sloped facets (ours; the paper's micro-patches are flat, §3.2). A flat patch at its texel's depth leaves gaps
// to a neighbour at another depth and overlaps it elsewhere, as seen from any receiver but the light's centre:
// over a surface the light sees obliquely (a ball's flank) the summed patches over-darken the penumbra, since
// the receiver sees that surface fold over itself. A facet instead spans its texel between edge depths shared
// with its neighbours on the same surface, so along each axis neighbouring facets meet on the light, and one
// that the receiver sees from behind (back-projected with its sides swapped) counts negatively: summed along a
// row they give the stretch of light between the row's two outline points (a telescoping sum).
//
// Depth of the edge between texel ij and its neighbour ij + step: halfway to the neighbour's depth where both
// are one surface (the same object, depths within u_facet_slope texel widths), else the texel's own.
float edge_depth(sampler2D occluders, ivec2 ij, ivec2 step, float z, float object) {
    ivec2 n = ij + step;
    if (any(lessThan(n, ivec2(0))) || any(greaterThanEqual(n, u_map_size))) return z;
    vec2 d = texelFetch(occluders, n, 0).xy;
    if (!depth_valid(d.x) || d.y != object) return z;
    if (abs(d.x - z) > u_facet_slope * texel_world(max(d.x, z))) return z;
    return 0.5 * (z + d.x);
}

// The four edge depths of texel ij's facet (x0, x1, y0, y1), as 1/z in a perspective view and z in a sun's.
vec4 facet_edges(sampler2D occluders, ivec2 ij, float z, float object) {
    vec4 e = vec4(edge_depth(occluders, ij, ivec2(-1, 0), z, object), edge_depth(occluders, ij, ivec2(1, 0), z, object),
                  edge_depth(occluders, ij, ivec2(0, -1), z, object), edge_depth(occluders, ij, ivec2(0, 1), z, object));
    return u_ortho == 1 ? e : 1.0 / e;
}

// Signed share of the light a facet hides from a receiver at window position t, depth zr: its sides
// d = (x0, y0, x1, y1) - t (window units) back-projected from their own edge depths (facet_edges). 0, as for
// a flat patch (patch_occlusion_fast), unless the patch's own depth zo is strictly in front of the receiver.
float facet_occlusion(vec4 d, vec4 edges, float zo, float zr, vec2 inv_2h, vec2 t, vec3 n) {
    if (!(zr > 0.0 && zr < EMPTY_DEPTH) || zo >= zr * (1.0 - u_bias_texels)) return 0.0;
    vec4 s = u_ortho == 1 ? zr - edges : edges - 1.0 / zr;       // each side's penumbra_spread
    if (any(lessThanEqual(s, vec4(0.0)))) return 0.0;
#if SSM_SPOT_CLIP
    if (g_spot_clipped) return spot_share(d / s.xzyw);
#endif
    vec4 ab = clamp(vec4(0.5) + d * (inv_2h.xyxy / s.xzyw), 0.0, 1.0);
    vec2 w = ab.zw - ab.xy;                 // negative along an axis where the receiver sees the facet from behind
#if SSM_WEIGHTED
    if (w.x != 0.0 && w.y != 0.0) return weighted_fraction(ab, t, zr, n);     // ff_rect is odd: signed too
#endif
    return light_share(ab);
}

// Fraction of the light hidden by the patch of texel `patch` at depth zo from a receiver at window
// position t, depth zr (receiver_eye). 0 when the patch is not strictly in front of the receiver.
float patch_occlusion(vec2 patch_texel, float zo, vec2 t, float zr, vec3 n) {
    if (!depth_valid(zr)) return 0.0;
    if (zo >= zr * (1.0 - u_bias_texels)) return 0.0;
    float s = penumbra_spread(zo, zr, u_ortho);
    if (!(s > 0.0)) return 0.0;
#if SSM_SPOT_CLIP
    if (g_spot_clipped) return spot_share((patch_window(patch_texel) - t.xyxy) / s);
#endif
    // Light [-h, h] → [0, 1]:  a = 1/2 + (lo - t) / (2 h s).  Clamping keeps the infinities finite.
    vec2 k = 1.0 / (2.0 * max(u_half, vec2(1e-9)) * s);    // 1e-9 as in weighted_fraction
    vec4 ab = clamp(vec4(0.5) + (patch_window(patch_texel) - t.xyxy) * k.xyxy, 0.0, 1.0);
    vec2 w = ab.zw - ab.xy;
#if SSM_WEIGHTED
    if (w.x > 0.0 && w.y > 0.0) return weighted_fraction(ab, t, zr, n);
#endif
    return light_share(ab);
}
