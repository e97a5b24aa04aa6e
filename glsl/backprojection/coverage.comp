// Occluder coverage pyramid (ours, for BACKPROJECTION's coarse micro-occluders): level-l texel c describes the
// non-empty texels among level-0 texels [c·2^l, (c+1)·2^l): r = their mean depth, g = their count, b = their
// maximum depth, a = their depth variance (the layout of the microrects' member statistics,
// microrects.comp). From them BACKPROJECTION reads a coarse cell as two clusters, one at the maximum, so that
// a receiver between them learns how much of the cell is nearer than itself.
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;      // level 0 source (R32F)
uniform int u_first;            // 1: build level 0 from u_depth
uniform ivec2 u_map_size;
uniform ivec2 u_dst_size;
layout(rgba32f, binding = 0) uniform writeonly image2D u_dst;
layout(rgba32f, binding = 1) uniform readonly image2D u_src;   // level l − 1

const vec4 NONE = vec4(0.0, 0.0, -NO_OCCLUDER, 0.0);

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_dst_size))) return;
    vec4 s = NONE;
    if (u_first == 1) {
        float z = all(lessThan(p, u_map_size)) ? texelFetch(u_depth, p, 0).r : NO_OCCLUDER;
        if (z < EMPTY_DEPTH) s = vec4(z, 1.0, z, 0.0);
    } else {
        vec4 q[4];
        float count = 0.0, sum = 0.0;
        for (int i = 0; i < 4; ++i) {
            q[i] = imageLoad(u_src, 2 * p + ivec2(i & 1, i >> 1));
            count += q[i].g;
            sum += q[i].r * q[i].g;
            s.b = max(s.b, q[i].b);
        }
        s.g = count;
        if (count > 0.0) {
            // Variances merged about the common mean (stable where the depths are large and their spread small).
            s.r = sum / count;
            float m2 = 0.0;
            for (int i = 0; i < 4; ++i) m2 += q[i].g * (q[i].a + (q[i].r - s.r) * (q[i].r - s.r));
            s.a = m2 / count;
        }
    }
    imageStore(u_dst, p, s);
}
