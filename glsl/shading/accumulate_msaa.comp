// accumulate.comp for an anti-aliased frame (Schwarz & Stamminger 2008, §7, single visibility sample): the
// technique computed one visibility per pixel, on the per-pixel G-buffer (the pixel centre, or the first
// multisample: engine/gpu/multisample.py); here every multisample is
// shaded with its own position, normal and albedo, and the pixel gets the mean over its samples.
// A sample's visibility is its pixel's when its camera depth is within u_aa_depth_threshold (τ, relative) of
// the pixel's own; otherwise that of the pixel among itself and its 4-neighbours whose own depth is
// closest to the sample's, as the paper's visibility interpolation picks it (§7, Fig. 9).
// The Visibility pass sums stay per pixel (the pixel's own sample), as in accumulate.comp.
#include "common/pixel.glsl"
#include "shading/irradiance.glsl"

#ifndef MSAA_SAMPLES
#define MSAA_SAMPLES 4
#endif

uniform sampler2D g_albedo;
uniform sampler2D u_visibility;
uniform sampler2D u_visibility_rgb;
uniform int u_has_rgb;
uniform sampler2DMS ms_position;
uniform sampler2DMS ms_normal;
uniform sampler2DMS ms_albedo;
uniform float u_aa_depth_threshold;

layout(rgba32f, binding = 0) uniform image2D u_combined;
layout(rgba32f, binding = 1) uniform image2D u_unshadowed;
layout(rg32f, binding = 2) uniform image2D u_visibility_sums;
layout(rgba32f, binding = 3) uniform image2D u_irradiance;

vec3 visibility_at(ivec2 q) {
    float v = clamp(texelFetch(u_visibility, q, 0).r, 0.0, 1.0);
    return u_has_rgb == 1 ? clamp(texelFetch(u_visibility_rgb, q, 0).rgb, 0.0, 1.0) : vec3(v);
}

// The pixel (px or a 4-neighbour) with a visibility for this light whose depth is closest to `depth`; a
// sample with no such pixel around it (a sliver no pixel's own sample lies on) is taken as unshadowed.
vec3 closest_visibility(ivec2 px, float depth) {
    const ivec2 around[5] = ivec2[5](ivec2(0, 0), ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1));
    float best = 1.0 / 0.0;
    ivec2 pick = ivec2(-1);
    for (int i = 0; i < 5; ++i) {
        ivec2 q = px + around[i];
        if (any(lessThan(q, ivec2(0))) || !pixel_in_image(q) || !pixel_lit(q)) continue;
        float d = abs(texelFetch(g_normal, q, 0).w - depth);
        if (d < best) { best = d; pick = q; }
    }
    return pick.x < 0 ? vec3(1.0) : visibility_at(pick);
}

// A multisample that repeats the pixel's own fragment. The multisampled and single-sample rasterisers
// interpolate the same attributes at the same pixel centre but may round differently (llvmpipe does, by
// ~1e-7 relative): equal within float noise counts as the same.
bool same_fragment(vec4 p, vec4 n, vec4 a, vec4 p0, vec4 n0, vec4 a0) {
    float scale = 1e-5 * max(max(abs(p0.x), abs(p0.y)), max(abs(p0.z), n0.w));
    return p0.w > 0.0 && all(lessThanEqual(abs(p.xyz - p0.xyz), vec3(scale)))
        && abs(n.w - n0.w) <= 1e-5 * n0.w && dot(n.xyz, n0.xyz) >= 0.99999
        && all(lessThanEqual(abs(a.rgb - a0.rgb), vec3(1e-5)));
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    bool own_lit = pixel_lit(px);
    // The pixel's own sample, whose visibility the technique computed (the per-pixel G-buffer).
    vec4 p0 = texelFetch(g_position, px, 0);
    vec4 n0 = texelFetch(g_normal, px, 0);
    vec4 a0 = texelFetch(g_albedo, px, 0);
    vec3 own_v = own_lit ? visibility_at(px) : vec3(1.0);
    // Samples of the pixel's own fragment repeat its values: counted, shaded once (and 4·x/4 is x exactly,
    // so an interior pixel gets the result of a frame without anti-aliasing).
    float repeats = 0.0;
    vec3 first_radiance = vec3(0.0), first_e = vec3(0.0);
    vec3 combined = vec3(0.0), unshadowed = vec3(0.0), irradiance = vec3(0.0);
    if (own_lit) {
        vec4 e = texelFetch(g_irradiance, px, 0);
        first_e = e.rgb;
        first_radiance = a0.rgb * 0.318309886 * e.rgb;
        imageStore(u_visibility_sums, px, imageLoad(u_visibility_sums, px) + vec4(e.a * own_v.r, e.a, 0.0, 0.0));
    }
    for (int s = 0; s < MSAA_SAMPLES; ++s) {
        vec4 p = texelFetch(ms_position, px, s);
        if (p.w <= 0.0) continue;                   // background: no light
        vec4 n = texelFetch(ms_normal, px, s);
        vec4 a = texelFetch(ms_albedo, px, s);
        if (same_fragment(p, n, a, p0, n0, a0)) { repeats += 1.0; continue; }
        vec4 e = receiver_irradiance(p.xyz, n.xyz);
        if (e.a <= 0.0) continue;
        bool same = own_lit && abs(n.w - n0.w) <= u_aa_depth_threshold * n0.w;
        vec3 v = same ? own_v : closest_visibility(px, n.w);
        vec3 radiance = a.rgb * 0.318309886 * e.rgb;
        combined += radiance * v;
        unshadowed += radiance;
        irradiance += e.rgb;
    }
    const float share = 1.0 / float(MSAA_SAMPLES);
    combined = (repeats * (first_radiance * own_v) + combined) * share;
    unshadowed = (repeats * first_radiance + unshadowed) * share;
    irradiance = (repeats * first_e + irradiance) * share;
    imageStore(u_combined, px, imageLoad(u_combined, px) + vec4(combined, 0.0));
    imageStore(u_unshadowed, px, imageLoad(u_unshadowed, px) + vec4(unshadowed, 0.0));
    imageStore(u_irradiance, px, imageLoad(u_irradiance, px) + vec4(irradiance, 0.0));
}
