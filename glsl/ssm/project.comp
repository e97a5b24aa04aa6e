// Projection of the soft shadow map onto the receivers in the camera view (Atty et al. 2006 §3.1, Fig. 3
// last line): V = 1 - occlusion, occlusion read bilinearly from the SSM.
//
// Each SSM texel holds the occlusion for two receivers: the nearest (r) and the farthest (g) receiver
// surface seen through it from the light centre. A pixel takes, per tap, the one whose depth it matches
// (in between: interpolated by depth). A tap whose receivers all lie behind the pixel (by more than the
// tolerance) or beyond the map says nothing about it: the pixel is in front of every receiver there, i.e. it
// is not a receiver (a CASTER-only object) and gets no shadow from that tap. Two-pass (§3.5): the front
// and back-face maps are merged by maximum. Overlapping patches can sum past 1: clamped.
//
// A receiver lit through its own smooth triangle (Receiver.through_surface: the light's centre below its
// triangle, its smooth normal still facing it) takes the hard test of the front occluder map instead, as HARD
// makes it (ours). The scatter back-projects its patches from the shadow ray's lifted start, but only the
// patches whose extents reach the pixel's own texels add to its record, and the terminator lift moves the start
// across the light's rays, several texels away: the patches that hide the start scatter elsewhere. Fuzz 30846
// (a smooth elliptic cylinder's terminator band, a 6.6 cm spot 5.8 m away): starts 2-7 texels off, the
// scatter's V 0.3-1 rising with the offset, Cycles and the hard test 0.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
uniform sampler2D u_ssm_front;
uniform sampler2D u_ssm_back;
uniform sampler2D u_recv_near;
uniform sampler2D u_recv_far;
uniform sampler2D u_occluder;       // the front occluder map (depth, object index)
uniform int u_two_pass;
uniform int u_debug;
uniform sampler2D u_receiver_mask;  // g = 1 where the camera sees a receiver (only with u_has_mask)
uniform int u_has_mask;
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;
layout(r32f, binding = 1) uniform writeonly image2D u_debug_sum;

// Occlusion of the receiver at depth d from one SSM texel; w = 0 when the texel has no receiver there.
float tap(ivec2 t, float d, float tol, out float w) {
    w = 0.0;
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_map_size))) return 0.0;
    float zn = texelFetch(u_recv_near, t, 0).r;
    float zf = texelFetch(u_recv_far, t, 0).r;
    if (!(zn > 0.0 && zn < EMPTY_DEPTH)) return 0.0;
    if (!(zf > 0.0 && zf < EMPTY_DEPTH)) zf = zn;
    if (d < zn - tol || d > zf + tol) return 0.0;
    // Sloped facets (ssm/patch.glsl) sum signed, to the light a caster's outline hides as the receiver sees
    // it, with the sign of the outline's orientation: negative where the receiver sees the lit side of the
    // caster from the light's side (a sheet tilted so that part of a wide light lies behind it). Flat
    // micro-patches sum non-negative.
    vec2 occ = abs(texelFetch(u_ssm_front, t, 0).rg);
    if (u_two_pass == 1) occ = max(occ, abs(texelFetch(u_ssm_back, t, 0).rg));
    w = 1.0;
    // The receiver whose depth the pixel matches best (an occluder 1 cm over the ground is within the
    // tolerance of both); strictly in between: interpolated by depth.
    float a = abs(d - zn), b = abs(d - zf);
    if (min(a, b) <= tol) return a <= b ? occ.r : occ.g;
    return mix(occ.r, occ.g, (d - zn) / max(zf - zn, 1e-30));   // metres: one receiver layer (zf = zn)
}

// The visibility of receiver r read from the soft shadow map (bilinear over the texels' records); `raw`: the
// summed occlusion before clamping (the debug pass), 0 where no tap holds the pixel.
float projected_visibility(Receiver r, out float raw) {
    raw = 0.0;
    // The pixel's own point (r.surface: no lift or normal offset, it is matched against rasterised receiver
    // depths).
    vec3 l = r.surface;
    vec3 m = map_coords(l);
    vec3 n = r.normal;
    vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-l);
    float cos_t = clamp(abs(dot(n, to_light)), 1e-3, 1.0);   // cosine floor: tan_t stays finite
    float tan_t = min(sqrt(1.0 - cos_t * cos_t) / cos_t, 10.0);
    // Depth may drift over a 1.5-texel bilinear footprint on a slope, plus rasterisation slack (1e-4
    // of the depth, metres per metre: float32 rounding of rasterised depths with margin).
    float tol = texel_world(max(m.z, 0.0)) * (1.0 + 1.5 * tan_t) + 1e-4 * m.z;
    vec2 q = m.xy - 0.5;
    ivec2 i = ivec2(floor(q));
    vec2 f = q - vec2(i);
    float w00, w10, w01, w11;
    float o00 = tap(i, m.z, tol, w00);
    float o10 = tap(i + ivec2(1, 0), m.z, tol, w10);
    float o01 = tap(i + ivec2(0, 1), m.z, tol, w01);
    float o11 = tap(i + ivec2(1, 1), m.z, tol, w11);
    // A small floor (1e-3 of a tap's weight, unitless) keeps a valid tap when the bilinear weight falls on
    // an invalid one.
    w00 *= (1.0 - f.x) * (1.0 - f.y) + 1e-3;
    w10 *= f.x * (1.0 - f.y) + 1e-3;
    w01 *= (1.0 - f.x) * f.y + 1e-3;
    w11 *= f.x * f.y + 1e-3;
    float wsum = w00 + w10 + w01 + w11;
    if (!(wsum > 0.0)) return 1.0;
    raw = (o00 * w00 + o10 * w10 + o01 * w01 + o11 * w11) / wsum;
    // Abutting micro-patches tile the light exactly in theory; their float32 sum misses 1 by
    // ~M·1e-7 (3.6e-5 at 256²). Snap that round-off so umbrae are exactly 0 and lit texels 1.
    float occ = clamp(raw, 0.0, 1.0);
    if (occ > 1.0 - 1e-4) occ = 1.0;      // fraction of the light: above the round-off bound
    if (occ < 1e-6) occ = 0.0;            // fraction of the light: below one texel's float32 error
    return 1.0 - occ;
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float v = 1.0, raw = 0.0;
    bool receiver = u_has_mask == 0 || texelFetch(u_receiver_mask, px, 0).g > 0.5;
    if (pixel_lit(px) && receiver) {
        Receiver r = pixel_receiver(px);
        v = r.through_surface ? map_lit_plane(u_occluder, ivec2(floor(r.map.xy)), r) : projected_visibility(r, raw);
    }
    imageStore(u_visibility, px, vec4(v));
    if (u_debug == 1) imageStore(u_debug_sum, px, vec4(raw));
}
