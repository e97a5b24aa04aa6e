// Once per anti-aliased frame: the pixels whose multisamples do not all repeat the pixel's own fragment
// (for a background pixel: are not all background), appended to a list. Elsewhere shading one sample is
// shading them all; only these get accumulate_msaa.comp's per-sample shading.
#include "common/pixel.glsl"
#include "render/msaa_samples.glsl"

layout(std430, binding = 0) buffer Edges { uint edge_count; uint pad[3]; ivec2 edge_pixels[]; };

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    vec4 p0 = texelFetch(g_position, px, 0);
    vec4 n0 = texelFetch(g_normal, px, 0);
    vec4 a0 = texelFetch(g_albedo, px, 0);
    bool uniform_pixel = true;
    for (int s = 0; s < MSAA_SAMPLES; ++s) {
        vec4 p = texelFetch(ms_position, px, s);
        bool same = p0.w > 0.0 ? same_fragment(p, texelFetch(ms_normal, px, s), texelFetch(ms_albedo, px, s),
                                               p0, n0, a0)
                               : p.w <= 0.0;
        uniform_pixel = uniform_pixel && same;
    }
    if (!uniform_pixel) edge_pixels[atomicAdd(edge_count, 1u)] = px;
}
