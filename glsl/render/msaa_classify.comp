// Once per anti-aliased frame: the pixels whose multisamples do not all repeat the pixel's own fragment
// (for a background pixel: are not all background), appended to a list. Elsewhere shading one sample is
// shading them all; only these get accumulate_msaa.comp's per-sample shading.
#include "common/pixel.glsl"
#include "render/msaa_samples.glsl"

layout(std430, binding = 0) buffer Edges { uint edge_count; uint pad[3]; ivec2 edge_pixels[]; };

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    vec4 n0 = texelFetch(g_normal, px, 0);
    vec4 a0 = texelFetch(g_albedo, px, 0);
    bool covered = texelFetch(g_position, px, 0).w > 0.0;
    bool uniform_pixel = true;
    for (int s = 0; s < MSAA_SAMPLES; ++s) {
        vec4 n = texelFetch(ms_normal, px, s);
        uniform_pixel = uniform_pixel && (covered ? same_fragment(n, texelFetch(ms_albedo, px, s), n0, a0)
                                                  : n.w <= 0.0);
    }
    if (!uniform_pixel) edge_pixels[atomicAdd(edge_count, 1u)] = px;
}
