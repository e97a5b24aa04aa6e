// Per-sample shading at the edge pixels of an anti-aliased frame (Schwarz & Stamminger 2008, §7, single
// visibility sample), run after accumulate.comp for each light over msaa_classify.comp's list: the
// technique computed one visibility per pixel, on the per-pixel G-buffer (the pixel centre, or the first
// multisample: engine/gpu/multisample.py), and accumulate.comp added that sample's shading; here every
// multisample is shaded with its own position, normal and albedo, and the pixel gets the mean over its
// samples instead.
// A sample's visibility is its pixel's when its camera depth is within u_aa_depth_threshold (τ, relative) of
// the pixel's own; otherwise that of the pixel among itself and its 4-neighbours whose own depth is
// closest to the sample's, as the paper's visibility interpolation picks it (§7, Fig. 9).
// The Visibility pass sums stay accumulate.comp's, per pixel (the pixel's own sample).
#include "common/pixel.glsl"
#include "shading/irradiance.glsl"
#include "render/msaa_samples.glsl"

uniform sampler2D u_visibility;
uniform sampler2D u_visibility_rgb;
uniform int u_has_rgb;
uniform sampler2D u_sheet_light;    // as in accumulate.comp
uniform int u_sheets;
uniform float u_aa_depth_threshold;
uniform uint u_edge_count;
layout(std430, binding = 0) readonly buffer Edges { uint edge_count; uint pad[3]; ivec2 edge_pixels[]; };

layout(rgba32f, binding = 0) uniform image2D u_combined;
layout(rgba32f, binding = 1) uniform image2D u_unshadowed;
layout(rgba32f, binding = 3) uniform image2D u_irradiance;

vec3 visibility_at(ivec2 q) {
    float keep = u_sheets == 1 ? texelFetch(u_sheet_light, q, 0).r : 1.0;
    float v = clamp(texelFetch(u_visibility, q, 0).r, 0.0, 1.0) * keep;
    return u_has_rgb == 1 ? clamp(texelFetch(u_visibility_rgb, q, 0).rgb, 0.0, 1.0) * keep : vec3(v);
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

void main() {
    uint index = gl_WorkGroupID.x * 64u + gl_LocalInvocationIndex;
    if (index >= u_edge_count) return;
    ivec2 px = edge_pixels[index];
    bool own_lit = pixel_lit(px);
    // The pixel's own sample, whose visibility the technique computed (the per-pixel G-buffer), and which
    // accumulate.comp has just added.
    vec4 n0 = texelFetch(g_normal, px, 0);
    vec4 a0 = texelFetch(g_albedo, px, 0);
    vec4 e0 = own_lit ? texelFetch(g_irradiance, px, 0) : vec4(0.0);
    vec3 own_v = own_lit ? visibility_at(px) : vec3(1.0);
    vec3 own_radiance = a0.rgb * 0.318309886 * e0.rgb;
    // Samples of the pixel's own fragment repeat its values: counted, shaded once.
    float repeats = 0.0;
    vec3 combined = vec3(0.0), unshadowed = vec3(0.0), irradiance = vec3(0.0);
    for (int s = 0; s < MSAA_SAMPLES; ++s) {
        vec4 n = texelFetch(ms_normal, px, s);
        if (n.w <= 0.0) continue;                   // background: no light
        vec4 a = texelFetch(ms_albedo, px, s);
        if (same_fragment(n, a, n0, a0)) { repeats += 1.0; continue; }
        // The multisampled G-buffer keeps no geometric normal (engine/gpu/multisample.py): another fragment's
        // sample is shaded without the smooth-normal band (irradiance.glsl band_loss).
        vec4 e = receiver_irradiance(sample_position(px, u_image_size, n.w), n.xyz, n.xyz);
        if (e.a <= 0.0) continue;
        bool same = own_lit && abs(n.w - n0.w) <= u_aa_depth_threshold * n0.w;
        vec3 v = same ? own_v : closest_visibility(px, n.w);
        vec3 radiance = a.rgb * 0.318309886 * e.rgb;
        combined += radiance * v;
        unshadowed += radiance;
        irradiance += e.rgb;
    }
    // The mean over the samples, in place of the own sample's value.
    const float share = 1.0 / float(MSAA_SAMPLES);
    float rest = repeats * share - 1.0;
    imageStore(u_combined, px, imageLoad(u_combined, px) + vec4(rest * (own_radiance * own_v) + combined * share, 0.0));
    imageStore(u_unshadowed, px, imageLoad(u_unshadowed, px) + vec4(rest * own_radiance + unshadowed * share, 0.0));
    imageStore(u_irradiance, px, imageLoad(u_irradiance, px) + vec4(rest * e0.rgb + irradiance * share, 0.0));
}
