// Min/max pyramid of the depth map for the lit/umbra classes (structures/lit_umbra.py), starting at a coarse
// level: level 0 of this texture holds the (min, max) of 2^B × 2^B depth texels (u_block = 2^B), read
// straight from the depth map, so the full-resolution copy and its finest levels (most of an HSM's cost,
// GBP06) are never written. Texels beyond the map are neutral, as in backprojection/hsm.comp.
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;
uniform int u_first;            // 1: level 0, reduced from u_depth
uniform int u_block;            // depth texels per level-0 cell side
uniform ivec2 u_map_size;
uniform ivec2 u_dst_size;
layout(rg32f, binding = 0) uniform writeonly image2D u_dst;
layout(rg32f, binding = 1) uniform readonly image2D u_src;  // level l − 1

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_dst_size))) return;
    vec2 mm = vec2(NO_OCCLUDER, -NO_OCCLUDER);
    if (u_first == 1) {
        // 2×2 texels per textureGather where they lie inside the map (a quarter of the fetches), one by one
        // at its edges.
        ivec2 lo = p * u_block, hi = min(lo + u_block, u_map_size);
        vec2 inv = 1.0 / vec2(u_map_size);
        for (int y = lo.y; y < hi.y; y += 2)
            for (int x = lo.x; x < hi.x; x += 2) {
                if (x + 1 < hi.x && y + 1 < hi.y) {
                    vec4 z = textureGather(u_depth, vec2(x + 1, y + 1) * inv);
                    mm = vec2(min(mm.x, min(min(z.x, z.y), min(z.z, z.w))), max(mm.y, max(max(z.x, z.y), max(z.z, z.w))));
                } else {
                    for (int j = y; j < min(y + 2, hi.y); ++j)
                        for (int i = x; i < min(x + 2, hi.x); ++i) {
                            float z = texelFetch(u_depth, ivec2(i, j), 0).r;
                            mm = vec2(min(mm.x, z), max(mm.y, z));
                        }
                }
            }
    } else {
        for (int i = 0; i < 4; ++i) {
            vec2 v = imageLoad(u_src, 2 * p + ivec2(i & 1, i >> 1)).rg;
            mm = vec2(min(mm.x, v.x), max(mm.y, v.y));
        }
    }
    imageStore(u_dst, p, vec4(mm, 0.0, 0.0));
}
