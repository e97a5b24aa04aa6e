// PVSM's low-resolution search map (§4 step 3, §5.2 step 2): each texel the minimum depth of a block×block
// block of the source map, so that no occluder of the finer map is lost (the conservative property the paper
// gets from conservative rasterisation, as far as the source map holds it).
#include "common/pixel.glsl"

uniform sampler2D u_src;        // R32F linear light depth (NO_OCCLUDER where empty)
uniform ivec2 u_src_size;
uniform int u_block;
layout(r32f, binding = 0) uniform writeonly image2D u_dst;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(p)) return;
    float z = NO_OCCLUDER;
    for (int j = 0; j < u_block; ++j)
        for (int i = 0; i < u_block; ++i) {
            ivec2 t = p * u_block + ivec2(i, j);
            if (all(lessThan(t, u_src_size))) z = min(z, texelFetch(u_src, t, 0).r);
        }
    imageStore(u_dst, p, vec4(z));
}
