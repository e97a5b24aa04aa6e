// Facet layers (Frame.render_facet_layers): for each texel of a layered depth map, the plane normal of the
// triangle whose depth it kept, in that layer's view frame (not oriented; (0, 0, 0) where empty). Drawn after
// the depth layers with the same triangles: a fragment writes only where its depth is the one its layer kept.
in float v_depth;
flat in int v_layer;
flat in vec3 v_facet;
// the casters render_depth_layers left out
#include "common/clip_sphere.glsl"
uniform sampler2DArray u_depths;
layout(location = 0) out vec4 f_normal;
// relative: the depth a triangle gives a texel is interpolated the same way in both passes, so it matches
// to float rounding; coincident faces may both match, and either plane serves
const float FACET_MATCH = 1e-6;

void main() {
    if (inside_clip_sphere()) discard;
    float kept = texelFetch(u_depths, ivec3(gl_FragCoord.xy, v_layer), 0).r;
    if (abs(v_depth - kept) > FACET_MATCH * abs(kept)) discard;
    f_normal = vec4(v_facet, 0.0);
}
