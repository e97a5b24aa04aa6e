// Copy one R32F image into another of the same size on the GPU (no readback).
#include "common/pixel.glsl"

uniform sampler2D u_src;
layout(r32f, binding = 0) uniform writeonly image2D u_dst;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    imageStore(u_dst, px, texelFetch(u_src, px, 0));
}
