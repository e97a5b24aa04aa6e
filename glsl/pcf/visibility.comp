// PCF: mean of bilinear comparisons on a regular taps×taps grid spanning ±radius texels, each texel against the
// receiver's plane unless the facet it holds faces both the receiver and the light (FACET_MAP).
#define FACET_MAP 1
#define FACET_FILTER 1
#include "common/pixel.glsl"
#include "common/light_view.glsl"

uniform sampler2D u_depth_map;
uniform float u_radius;
uniform int u_taps;
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float v = 1.0;
    if (pixel_lit(px)) {
        Receiver r = pixel_receiver(px);
        float step_size = u_taps > 1 ? 2.0 * u_radius / float(u_taps - 1) : 0.0;
        float sum = 0.0;
        for (int j = 0; j < u_taps; ++j)
            for (int i = 0; i < u_taps; ++i) {
                vec2 offset = (vec2(i, j) - 0.5 * float(u_taps - 1)) * step_size;
                vec2 q = r.map.xy + offset;
                sum += map_lit_bilinear_plane(u_depth_map, q, r);
            }
        v = sum / float(u_taps * u_taps);
    }
    imageStore(u_visibility, px, vec4(v));
}
