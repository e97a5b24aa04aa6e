in float v_depth;
layout(location = 0) out float f_depth;
#include "common/clip_sphere.glsl"

#ifdef PEEL
// A layer behind another (Frame.render_depth_layers' `behind`, REFERENCE's soft-falloff samples): only what
// lies behind that layer's depth at this texel, by more than the relative gap that keeps a surface's own
// depth from coming back.
flat in int v_layer;
uniform sampler2DArray u_in_front;
const float PEEL_GAP = 1e-5;
#endif

#if defined(BACK_FACES) || defined(FRONT_FACES)
// The casters' back faces only (seen from the light centre): a solid's far side (structures/depth_map.py);
// or their front faces only: where the light centre's rays enter solids (structures/solid_exits.py).
#include "common/facing.glsl"
#endif

void main() {
#ifdef BACK_FACES
    if (front_facing()) discard;
#endif
#ifdef FRONT_FACES
    if (!front_facing()) discard;
#endif
    if (inside_clip_sphere()) discard;
#ifdef PEEL
    float front = texelFetch(u_in_front, ivec3(gl_FragCoord.xy, v_layer), 0).r;
    if (v_depth <= front + PEEL_GAP * abs(front)) discard;
#endif
    f_depth = v_depth;
}
