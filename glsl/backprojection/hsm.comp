// Hierarchical shadow map (GBP06, recalled in Schwarz & Stamminger 2007 §2.1/§5): a min/max mip pyramid.
// Level 0 copies the depth map into a power-of-two padded RG32F texture (padding = (NO_OCCLUDER,
// −NO_OCCLUDER)); level l
// texel c holds the (min, max) of level-0 texels [c·2^l, (c+1)·2^l).
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;      // level 0 source (R32F)
uniform int u_first;            // 1: build level 0 from u_depth
uniform ivec2 u_map_size;       // depth map texels
uniform ivec2 u_dst_size;
layout(rg32f, binding = 0) uniform writeonly image2D u_dst;
layout(rg32f, binding = 1) uniform readonly image2D u_src;  // level l-1

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_dst_size))) return;
    vec2 mm;
    if (u_first == 1) {
        // Padding is neutral for both extrema, so coarse cells that straddle the map's edge bound only
        // the texels inside it (and read as empty, min = NO_OCCLUDER, when wholly outside).
        mm = all(lessThan(p, u_map_size)) ? vec2(texelFetch(u_depth, p, 0).r) : vec2(NO_OCCLUDER, -NO_OCCLUDER);
    } else {
        vec2 a = imageLoad(u_src, 2 * p).rg;
        vec2 b = imageLoad(u_src, 2 * p + ivec2(1, 0)).rg;
        vec2 c = imageLoad(u_src, 2 * p + ivec2(0, 1)).rg;
        vec2 d = imageLoad(u_src, 2 * p + ivec2(1, 1)).rg;
        mm = vec2(min(min(a.x, b.x), min(c.x, d.x)), max(max(a.y, b.y), max(c.y, d.y)));
    }
    imageStore(u_dst, p, vec4(mm, 0.0, 0.0));
}
