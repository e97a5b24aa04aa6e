// SSM scatter as a compute pass (the alternative to instanced quads): one invocation per micro-patch loops
// over its penumbra extent and adds the hidden fraction, in signed fixed point (1/FIXED_POINT units), with
// integer image atomics — exact and order-independent, but serial per patch. A patch's texels are numbered
// row by row and one dispatch adds [u_chunk · u_chunk_size, …) of them: a large rectangle (a patch near a big
// light covers the whole map) would pass llvmpipe's loop limit in one (engine/gpu/loops.py).
#include "ssm/patch.glsl"
layout(local_size_x = 64) in;
struct Patch {
    vec4 rect;
    vec4 data;
};
layout(std430, binding = 0) readonly buffer Patches { Patch patches[]; };
layout(r32ui, binding = 1) uniform uimage2D u_sum_near;
layout(r32ui, binding = 2) uniform uimage2D u_sum_far;
uniform sampler2D u_near_a;     // ssm/receivers.comp's records of the nearest and the farthest receiver
uniform sampler2D u_near_b;
uniform sampler2D u_near_c;
uniform sampler2D u_far_a;
uniform sampler2D u_far_b;
uniform sampler2D u_far_c;
#if SSM_FACETS
uniform sampler2D u_occluders;  // the occluder map the patches come from (depth, object)
#endif
uniform int u_count;
uniform int u_chunk;
uniform int u_chunk_size;

// The share of the light patch p hides from the receiver of one record (a, b, c) of `texel`.
float record_occlusion(Patch p, ivec2 texel, vec4 a, sampler2D b_map, sampler2D c_map) {
    if (!depth_valid(a.x)) return 0.0;
    Receiver r = ssm_receiver(a, texelFetch(b_map, texel, 0), texelFetch(c_map, texel, 0).r);
    if (!patch_can_shadow(r, p.data.xy, p.data.z)) return 0.0;
#if SSM_SPOT_CLIP
    spot_receiver(r.local);
#endif
    vec2 t = map_window(vec2(texel) + 0.5);
    float zr = a.x;
    receiver_eye(r, t, zr);
#if SSM_FACETS
    return facet_occlusion(patch_window(p.data.xy) - t.xyxy,
                           facet_edges(u_occluders, ivec2(p.data.xy), p.data.z, p.data.w), p.data.z, zr,
                           0.5 / max(u_half, vec2(1e-9)), t, r.normal);
#else
    return patch_occlusion(p.data.xy, p.data.z, t, zr, r.normal);
#endif
}

void main() {
    int index = int(gl_GlobalInvocationID.x);
    if (index >= u_count) return;
    Patch p = patches[index];
    // Texel centres inside the rectangle, as the rasteriser would pick them.
    ivec2 lo = ivec2(ceil(p.rect.xy - 0.5));
    ivec2 hi = ivec2(ceil(p.rect.zw - 0.5));
    ivec2 n = max(hi - lo, ivec2(0));
    int count = n.x * n.y;
    int k0 = min(u_chunk * u_chunk_size, count), k1 = min(k0 + u_chunk_size, count);
    ivec2 texel = lo + ivec2(k0 % max(n.x, 1), k0 / max(n.x, 1));
    for (int k = k0; k < k1; ++k) {
        float on = record_occlusion(p, texel, texelFetch(u_near_a, texel, 0), u_near_b, u_near_c);
        float of = record_occlusion(p, texel, texelFetch(u_far_a, texel, 0), u_far_b, u_far_c);
        // Signed (a facet seen from behind subtracts): two's complement, which uint addition wraps exactly.
        if (on != 0.0) imageAtomicAdd(u_sum_near, texel, uint(int(round(on * FIXED_POINT))));
        if (of != 0.0) imageAtomicAdd(u_sum_far, texel, uint(int(round(of * FIXED_POINT))));
        if (++texel.x == hi.x) texel = ivec2(lo.x, texel.y + 1);
    }
}
