// The nearest back face of a closed caster behind its nearest front face (structures/solid_exits.py): where
// the light centre's ray leaves the solid it entered. Used with common/depth.vert.
in float v_depth;
uniform sampler2D u_entry;      // nearest front face of the closed casters (R32F, NO_OCCLUDER where none)
uniform float u_eps;            // relative gap behind the entry (its own face re-rasterised)
#include "common/facing.glsl"
layout(location = 0) out float f_depth;

void main() {
    if (front_facing()) discard;
    float entry = texelFetch(u_entry, ivec2(gl_FragCoord.xy), 0).r;
    if (v_depth <= entry * (1.0 + u_eps)) discard;
    f_depth = v_depth;
}
