// Which covered pixels this light reaches, reduced on the GPU to what the pipeline needs on the CPU: their
// count and the world-space box around them (engine/render/pipeline.py _lit_bounds). A few bytes come back
// instead of the whole irradiance image.
// Floats are compared as order-preserving unsigned integers (sign bit flipped for positives, all bits for
// negatives), so atomicMin/atomicMax on uints give the exact float32 minimum and maximum.
#include "common/pixel.glsl"

layout(std430, binding = 0) buffer LitBounds {
    uint count;
    uint lo[3];     // encoded minimum x, y, z
    uint hi[3];     // encoded maximum x, y, z
} result;

shared uint s_count;
shared uint s_lo[3];
shared uint s_hi[3];

uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : (u | 0x80000000u);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (gl_LocalInvocationIndex == 0u) {
        s_count = 0u;
        for (int i = 0; i < 3; ++i) { s_lo[i] = 0xFFFFFFFFu; s_hi[i] = 0u; }
    }
    barrier();
    if (pixel_in_image(px) && pixel_lit(px)) {
        vec3 p = texelFetch(g_position, px, 0).xyz;
        atomicAdd(s_count, 1u);
        for (int i = 0; i < 3; ++i) {
            uint u = ordered(p[i]);
            atomicMin(s_lo[i], u);
            atomicMax(s_hi[i], u);
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && s_count > 0u) {    // one global update per work group
        atomicAdd(result.count, s_count);
        for (int i = 0; i < 3; ++i) {
            atomicMin(result.lo[i], s_lo[i]);
            atomicMax(result.hi[i], s_hi[i]);
        }
    }
}
