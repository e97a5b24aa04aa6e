// SSM scatter fragment (Atty et al. 2006 §3.4): the fraction of the light this micro-patch hides from the
// receivers of this soft-shadow-map texel, for the nearest (r) and the farthest (g) receiver, added by
// blending. Per-patch values come from the vertex shader; when one receiver fills the texel (nearest =
// farthest) the fraction is computed once.
#include "ssm/patch.glsl"
uniform sampler2D u_near_a;     // ssm/receivers.comp's records of the nearest and the farthest receiver
uniform sampler2D u_near_b;
uniform sampler2D u_far_a;
uniform sampler2D u_far_b;
flat in vec4 v_lohi;        // patch window rectangle: lo.xy, hi.xy
flat in vec3 v_depth;       // zo, 1/zo, object of the patch
flat in vec2 v_patch;       // its occluder texel
layout(location = 0) out vec2 f_occlusion;

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);
    vec4 na = texelFetch(u_near_a, texel, 0);
    f_occlusion = vec2(0.0);
    if (!depth_valid(na.x)) discard;    // no receiver the camera sees in this texel
    vec4 fa = texelFetch(u_far_a, texel, 0);
    vec2 t = map_window(gl_FragCoord.xy);
    vec4 d = v_lohi - t.xyxy;
    vec2 tt = map_texel_window();
    float tw1 = max(tt.x, tt.y);
    vec2 inv_2h = 0.5 / max(u_half, vec2(1e-9));    // metres (tan for a sun): a zero-size light still divides
    float on = patch_can_shadow(ssm_receiver(na, texelFetch(u_near_b, texel, 0)), v_patch, v_depth.x)
             ? patch_occlusion_fast(d, v_depth.x, v_depth.y, na.x, inv_2h, tw1, t) : 0.0;
    float of = fa == na ? on
             : patch_can_shadow(ssm_receiver(fa, texelFetch(u_far_b, texel, 0)), v_patch, v_depth.x)
             ? patch_occlusion_fast(d, v_depth.x, v_depth.y, fa.x, inv_2h, tw1, t) : 0.0;
    f_occlusion = vec2(on, of);
}
