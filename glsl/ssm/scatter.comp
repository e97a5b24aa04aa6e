// SSM scatter as a compute pass (the alternative to instanced quads): one invocation per micro-patch loops
// over its penumbra extent and adds the hidden fraction, in fixed point (1/FIXED_POINT units), with integer image
// atomics — exact and order-independent, but serial per patch. A patch's texels are numbered row by row
// and one dispatch adds [u_chunk · u_chunk_size, …) of them: a large rectangle (a patch near a big light
// covers the whole map) would pass llvmpipe's loop limit in one (engine/gpu/loops.py).
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
uniform sampler2D u_far_a;
uniform sampler2D u_far_b;
uniform int u_count;
uniform int u_chunk;
uniform int u_chunk_size;

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
        vec2 centre = vec2(texel) + 0.5;
        vec4 na = texelFetch(u_near_a, texel, 0), fa = texelFetch(u_far_a, texel, 0);
        float on = depth_valid(na.x) && patch_can_shadow(ssm_receiver(na, texelFetch(u_near_b, texel, 0)),
                                                         p.data.xy, p.data.z)
                 ? patch_occlusion(p.data.xy, p.data.z, centre, na.x) : 0.0;
        float of = depth_valid(fa.x) && patch_can_shadow(ssm_receiver(fa, texelFetch(u_far_b, texel, 0)),
                                                         p.data.xy, p.data.z)
                 ? patch_occlusion(p.data.xy, p.data.z, centre, fa.x) : 0.0;
        if (on > 0.0) imageAtomicAdd(u_sum_near, texel, uint(on * FIXED_POINT + 0.5));
        if (of > 0.0) imageAtomicAdd(u_sum_far, texel, uint(of * FIXED_POINT + 0.5));
        if (++texel.x == hi.x) texel = ivec2(lo.x, texel.y + 1);
    }
}
