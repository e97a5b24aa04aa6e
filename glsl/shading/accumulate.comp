// Adds one light's shaded contribution: Combined += albedo/π·E·V, Unshadowed += albedo/π·E,
// and the scalar sums that give the Visibility pass (Σ E·V / Σ E).
#include "common/pixel.glsl"

uniform sampler2D g_albedo;
uniform sampler2D u_visibility;
uniform sampler2D u_visibility_rgb;   // per-channel visibility of a textured light (when u_has_rgb)
uniform int u_has_rgb;
// Share of a shadowed light kept on each pixel where a flattened closed caster shadows itself through its
// coincident faces, as in Cycles (engine/render/pipeline.py _sheet_light); u_sheets 0: none in the frame.
uniform sampler2D u_sheet_light;
uniform int u_sheets;

layout(rgba32f, binding = 0) uniform image2D u_combined;
layout(rgba32f, binding = 1) uniform image2D u_unshadowed;
layout(rg32f, binding = 2) uniform image2D u_visibility_sums;
layout(rgba32f, binding = 3) uniform image2D u_irradiance;     // Σ E, for the Irradiance debug pass

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px) || !pixel_lit(px)) return;
    vec4 e = texelFetch(g_irradiance, px, 0);
    float keep = u_sheets == 1 ? texelFetch(u_sheet_light, px, 0).r : 1.0;
    float v = clamp(texelFetch(u_visibility, px, 0).r, 0.0, 1.0) * keep;
    vec3 radiance = texelFetch(g_albedo, px, 0).rgb * 0.318309886 * e.rgb;
    vec3 v3 = u_has_rgb == 1 ? clamp(texelFetch(u_visibility_rgb, px, 0).rgb, 0.0, 1.0) * keep : vec3(v);
    imageStore(u_combined, px, imageLoad(u_combined, px) + vec4(radiance * v3, 0.0));
    imageStore(u_unshadowed, px, imageLoad(u_unshadowed, px) + vec4(radiance, 0.0));
    imageStore(u_visibility_sums, px, imageLoad(u_visibility_sums, px) + vec4(e.a * v, e.a, 0.0, 0.0));
    imageStore(u_irradiance, px, imageLoad(u_irradiance, px) + vec4(e.rgb, 0.0));
}
