// SSM scatter fragment (Atty et al. 2006 §3.4): the fraction of the light this micro-patch hides from the
// receivers of this soft-shadow-map texel, for the nearest (r) and the farthest (g) receiver, added by
// blending. Per-patch values come from the vertex shader; when one receiver fills the texel (nearest =
// farthest) the fraction is computed once.
#include "ssm/patch.glsl"
uniform sampler2D u_near_a;     // ssm/receivers.comp's records of the nearest and the farthest receiver
uniform sampler2D u_near_b;
uniform sampler2D u_near_c;
uniform sampler2D u_far_a;
uniform sampler2D u_far_b;
uniform sampler2D u_far_c;
flat in vec4 v_lohi;        // patch window rectangle: lo.xy, hi.xy
flat in vec3 v_depth;       // zo, 1/zo, object of the patch
flat in vec2 v_patch;       // its occluder texel
#if SSM_FACETS
flat in vec4 v_edges;       // its facet's edge depths (facet_edges)
#endif
layout(location = 0) out vec2 f_occlusion;

// The share of the light this patch hides from the receiver of one record (a, b, c) of this texel, whose
// window centre is t.
float record_occlusion(ivec2 texel, vec4 a, sampler2D b_map, sampler2D c_map, vec2 t, vec2 inv_2h, float tw1) {
    Receiver r = ssm_receiver(a, texelFetch(b_map, texel, 0), texelFetch(c_map, texel, 0).r);
    if (!patch_can_shadow(r, v_patch, v_depth.x)) return 0.0;
#if SSM_SPOT_CLIP
    spot_receiver(r.local);
#endif
    float zr = a.x;
    receiver_eye(r, t, zr);
#if SSM_FACETS
    return facet_occlusion(v_lohi - t.xyxy, v_edges, v_depth.x, zr, inv_2h, t, r.normal);
#else
    return patch_occlusion_fast(v_lohi - t.xyxy, v_depth.x, v_depth.y, zr, inv_2h, tw1, t, r.normal);
#endif
}

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);
    vec4 na = texelFetch(u_near_a, texel, 0);
    f_occlusion = vec2(0.0);
    if (!depth_valid(na.x)) discard;    // no receiver the camera sees in this texel
    vec4 fa = texelFetch(u_far_a, texel, 0);
    vec2 t = map_window(gl_FragCoord.xy);
    vec2 tt = map_texel_window();
    float tw1 = max(tt.x, tt.y);
    vec2 inv_2h = 0.5 / max(u_half, vec2(1e-9));    // metres (tan for a sun): a zero-size light still divides
    float on = record_occlusion(texel, na, u_near_b, u_near_c, t, inv_2h, tw1);
    float of = fa == na ? on : record_occlusion(texel, fa, u_far_b, u_far_c, t, inv_2h, tw1);
    f_occlusion = vec2(on, of);
}
