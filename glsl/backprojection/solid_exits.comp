// Solid exits pyramid (structures/solid_exits.py), RG32F: level 0 holds (exit depth, surface depth) where the
// depth map's surface is a closed caster's entry, (NO_OCCLUDER, 0) elsewhere and in the padding; level l the
// nearest exit and the deepest surface of its 2×2 children. A cell whose nearest exit lies behind its deepest
// surface is solid over that stretch for every one of its texels.
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;      // the depth map (R32F)
uniform sampler2D u_entry;      // nearest front face of the closed casters
uniform sampler2D u_exit;       // nearest back face behind it
uniform float u_eps;            // relative depth within which entry and depth map are the same surface
uniform int u_first;
uniform ivec2 u_map_size;
uniform ivec2 u_dst_size;
layout(rg32f, binding = 0) uniform writeonly image2D u_dst;
layout(rg32f, binding = 1) uniform readonly image2D u_src;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_dst_size))) return;
    vec2 e = vec2(NO_OCCLUDER, 0.0);                // no column: neutral for both
    if (u_first == 1) {
        if (all(lessThan(p, u_map_size))) {
            float z = texelFetch(u_depth, p, 0).r, entry = texelFetch(u_entry, p, 0).r;
            float x = texelFetch(u_exit, p, 0).r;
            if (z < EMPTY_DEPTH && x < EMPTY_DEPTH && entry <= z * (1.0 + u_eps)) e = vec2(x, z);
        }
    } else {
        vec2 a = imageLoad(u_src, 2 * p).rg, b = imageLoad(u_src, 2 * p + ivec2(1, 0)).rg;
        vec2 c = imageLoad(u_src, 2 * p + ivec2(0, 1)).rg, d = imageLoad(u_src, 2 * p + ivec2(1, 1)).rg;
        e = vec2(min(min(a.x, b.x), min(c.x, d.x)), max(max(a.y, b.y), max(c.y, d.y)));
    }
    imageStore(u_dst, p, vec4(e, 0.0, 0.0));
}
