// Occluder coverage pyramid (ours, for BACKPROJECTION's coarse micro-occluders): level-l texel c describes the
// non-empty texels among level-0 texels [c·2^l, (c+1)·2^l): r = their mean depth, g = their count, b = their
// maximum depth, a = their depth variance (the layout of the microrects' member statistics,
// microrects.comp). From them BACKPROJECTION reads a coarse cell as two clusters, one at the maximum, so that
// a receiver between them learns how much of the cell is nearer than itself.
#include "backprojection/depth_stats.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;      // level 0 source (R32F)
uniform int u_first;            // 1: build level 0 from u_depth
uniform ivec2 u_map_size;
uniform ivec2 u_dst_size;
layout(rgba32f, binding = 0) uniform writeonly image2D u_dst;
layout(rgba32f, binding = 1) uniform readonly image2D u_src;   // level l − 1

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_dst_size))) return;
    vec4 s = NO_STATS;
    if (u_first == 1) {
        if (all(lessThan(p, u_map_size))) s = texel_stats(texelFetch(u_depth, p, 0).r);
    } else {
        for (int i = 0; i < 4; ++i) s = merge_stats(s, imageLoad(u_src, 2 * p + ivec2(i & 1, i >> 1)));
    }
    imageStore(u_dst, p, s);
}
