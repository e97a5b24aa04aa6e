// Averaged shadow maps (REFERENCE): weighted mean of the accumulated samples (plain mean where every weight
// was zero).
#include "common/pixel.glsl"

uniform sampler2D u_sums;
#if EARLY_SKIP
uniform sampler2D u_classes;      // pixels proven lit (1) or umbra (0) accumulated nothing
#endif
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    vec4 s = texelFetch(u_sums, px, 0);
    float v = s.y > 0.0 ? s.x / s.y : (s.w > 0.0 ? s.z / s.w : 1.0);
#if EARLY_SKIP
    float cls = texelFetch(u_classes, px, 0).r;
    if (cls == float(CLASS_LIT)) v = 1.0;
    if (cls == float(CLASS_UMBRA)) v = 0.0;
#endif
    imageStore(u_visibility, px, vec4(clamp(v, 0.0, 1.0)));
}
