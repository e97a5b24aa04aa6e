// The penumbra-spread relation at arbitrary (z, d) pairs (for checking it against engine/core/light_shape.py).
#include "common/penumbra.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Pairs { vec2 pairs[]; };
layout(std430, binding = 1) writeonly buffer Result { vec2 result[]; };
uniform int u_count;
uniform int u_ortho;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    vec2 zd = pairs[i];
    result[i] = vec2(penumbra_spread(zd.x, zd.y, u_ortho), penumbra_spread_clamped(zd.x, zd.y, u_ortho));
}
