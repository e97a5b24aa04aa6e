// Multi-scale shadow map (Schwarz & Stamminger 2007, §5, Fig. 7): every level keeps the depth map's
// resolution; texel x of level l holds the (min, max) depth over the 2^l × 2^l neighbourhood centred on it,
// [x − 2^(l−1), x + 2^(l−1) − 1] per axis (level 0: the texel itself). Level l combines four level l−1 texels:
// offsets {−1, 0} for l = 1 and {−2^(l−2), +2^(l−2)} for l ≥ 2. Reads clamp to the edge (§5: the region is
// clamped to the depth map), so overlapping regions only repeat extrema.
//
// FROM_HSM (the Y shadow map's MSSM part, Schwarz & Stamminger 2008 §6): level 0 is HSM level u_base (read
// from the pyramid, not stored again) and array layer k − 1 holds level k.
#ifndef FROM_HSM
#define FROM_HSM 0
#endif
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;
uniform int u_level;            // level to build; 0 copies the depth map
uniform ivec2 u_map_size;
#if FROM_HSM
uniform sampler2D u_hsm;        // the HSM pyramid
uniform int u_base;             // its level the MSSM part starts from (n − 1)
#endif
layout(rg32f, binding = 0) uniform writeonly image2DArray u_dst;
layout(rg32f, binding = 1) uniform readonly image2DArray u_src;

vec2 src(ivec2 t) {
    t = clamp(t, ivec2(0), u_map_size - 1);
#if FROM_HSM
    if (u_level == 1) return texelFetch(u_hsm, t, u_base).rg;
    return imageLoad(u_src, ivec3(t, u_level - 2)).rg;
#else
    return imageLoad(u_src, ivec3(t, u_level - 1)).rg;
#endif
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_map_size))) return;
    vec2 mm;
    if (u_level == 0) {
        mm = vec2(texelFetch(u_depth, p, 0).r);
    } else {
        int lo = u_level == 1 ? -1 : -(1 << (u_level - 2));
        int hi = u_level == 1 ? 0 : (1 << (u_level - 2));
        vec2 a = src(p + ivec2(lo, lo)), b = src(p + ivec2(hi, lo));
        vec2 c = src(p + ivec2(lo, hi)), d = src(p + ivec2(hi, hi));
        mm = vec2(min(min(a.x, b.x), min(c.x, d.x)), max(max(a.y, b.y), max(c.y, d.y)));
    }
    imageStore(u_dst, ivec3(p, u_level - FROM_HSM), vec4(mm, 0.0, 0.0));
}
