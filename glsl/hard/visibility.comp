// HARD: one nearest-texel comparison against the depth map from the light centre (against the receiver's
// tangent plane at that texel: a receiver facing away from the centre gets no shadow from this map).
#include "common/pixel.glsl"
#include "common/light_view.glsl"

uniform sampler2D u_depth_map;
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float v = 1.0;
    if (pixel_lit(px)) {
        Receiver r = pixel_receiver(px);
        v = map_lit_plane(u_depth_map, ivec2(floor(r.map.xy)), r);
    }
    imageStore(u_visibility, px, vec4(v));
}
