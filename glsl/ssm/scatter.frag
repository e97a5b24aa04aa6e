// SSM scatter fragment (Atty et al. 2006 §3.4): the fraction of the light this micro-patch hides from the
// receivers of this soft-shadow-map texel, for the nearest (r) and the farthest (g) receiver, added by
// blending. Per-patch values come from the vertex shader; when one receiver fills the texel (nearest =
// farthest) the fraction is computed once.
#include "ssm/patch.glsl"
uniform sampler2D u_receivers;   // nearest receiver depth, its object; farthest receiver depth, its object
flat in vec4 v_lohi;        // patch window rectangle: lo.xy, hi.xy
flat in vec3 v_depth;       // zo, 1/zo, object of the patch
layout(location = 0) out vec2 f_occlusion;

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);
    vec2 t = ssm_window(gl_FragCoord.xy);
    vec4 d = v_lohi - t.xyxy;
    vec2 tt = ssm_texel_tan();
    float tw1 = max(tt.x, tt.y);
    vec2 inv_2h = 0.5 / max(u_half, vec2(1e-9));    // metres (tan for a sun): a zero-size light still divides
    vec4 z = texelFetch(u_receivers, texel, 0);
    // An object does not shadow itself (the caster/receiver split applied per object).
    float on = z.y == v_depth.z ? 0.0 : patch_occlusion_fast(d, v_depth.x, v_depth.y, z.x, inv_2h, tw1, t);
    float of = z.w == v_depth.z ? 0.0 : z.z == z.x ? on
             : patch_occlusion_fast(d, v_depth.x, v_depth.y, z.z, inv_2h, tw1, t);
    f_occlusion = vec2(on, of);
}
