// Post-filtering of the visibility buffer (Schwarz & Stamminger 2007, §3.1). The bitmask visibility B is
// point-sampled and jumps when a sample bit flips; the unclamped area-accumulation visibility A varies
// smoothly. Per axis, when the central differences of A and B have the same sign and A0 lies between its
// neighbours, B0 takes A0's relative position:  B0' = (A0 − A−1)/(A1 − A−1) · (B1 − B−1) + B−1.
// Of the x and y candidates, the one changing B0 least is kept; no candidate keeps B0.
#include "common/pixel.glsl"

uniform sampler2D u_b;          // R32F: current bitmask visibility
uniform sampler2D u_info;       // RGBA32F: (class, level, count, A); CLASS_UNREACHED where the light does not reach
layout(r32f, binding = 0) uniform writeonly image2D u_out;

bool usable(ivec2 q) {
    return all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, u_image_size)) && texelFetch(u_info, q, 0).r != float(CLASS_UNREACHED);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float b0 = texelFetch(u_b, px, 0).r;
    float result = b0;
    vec4 i0 = texelFetch(u_info, px, 0);
    if (i0.r != float(CLASS_UNREACHED)) {
        float a0 = i0.a;
        float best = 2.0;           // above any candidate change: candidates and B0 lie in [0, 1]
        for (int axis = 0; axis < 2; ++axis) {
            ivec2 step = axis == 0 ? ivec2(1, 0) : ivec2(0, 1);
            ivec2 qm = px - step, qp = px + step;
            if (!usable(qm) || !usable(qp)) continue;
            float am = texelFetch(u_info, qm, 0).a, ap = texelFetch(u_info, qp, 0).a;
            float bm = texelFetch(u_b, qm, 0).r, bp = texelFetch(u_b, qp, 0).r;
            float da = ap - am, db = bp - bm;
            if (da == 0.0 || sign(da) != sign(db)) continue;
            if (a0 < min(am, ap) || a0 > max(am, ap)) continue;
            float cand = (a0 - am) / da * db + bm;
            if (abs(cand - b0) < best) { best = abs(cand - b0); result = cand; }
        }
    }
    imageStore(u_out, px, vec4(clamp(result, 0.0, 1.0)));
}
