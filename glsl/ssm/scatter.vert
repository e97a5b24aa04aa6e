// SSM scatter, rasterised (Atty et al. 2006 §3.3–3.4): one instanced quad per occluder micro-patch covering
// its penumbra extent on the soft-shadow-map plane. The extent (an axis-aligned rectangle, the section of
// the patch's penumbra pyramid, §3.3) is computed by ssm/patches.comp together with the work estimate and
// read here from its storage buffer; the quad is drawn with additive blending.
#include "ssm/patch.glsl"
struct Patch {
    vec4 rect;      // penumbra extent in texels: x0, y0, x1, y1
    vec4 data;      // patch texel i, j; depth zo; object index
};
layout(std430, binding = 0) readonly buffer Patches { Patch patches[]; };
uniform int u_first;            // first patch of this draw (FP16 batching, appendix A)
#if SSM_FACETS
uniform sampler2D u_occluders;  // the occluder map the patches come from (depth, object)
flat out vec4 v_edges;          // 1/depth (perspective) or depth (ortho) of the facet's x0, x1, y0, y1 edges
#endif
flat out vec4 v_lohi;
flat out vec3 v_depth;
flat out vec2 v_patch;         // the patch's occluder texel

void main() {
    Patch p = patches[u_first + gl_InstanceID];
    vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1);
    vec2 pos = mix(p.rect.xy, p.rect.zw, corner);
    v_lohi = patch_window(p.data.xy);
    v_depth = vec3(p.data.z, 1.0 / p.data.z, p.data.w);
    v_patch = p.data.xy;
#if SSM_FACETS
    v_edges = facet_edges(u_occluders, ivec2(p.data.xy), p.data.z, p.data.w);
#endif
    gl_Position = vec4(pos / vec2(u_map_size) * 2.0 - 1.0, 0.0, 1.0);
}
