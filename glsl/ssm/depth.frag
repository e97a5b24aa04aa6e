// SSM occluder / receiver depth maps (Atty et al. 2006, §3.1–3.2, §3.5): linear depth along the light's -Z
// and the object's index, optionally keeping only the faces turned away from the light (the two-pass
// method's second occluder map).
in float v_depth;
uniform int u_back_only = 0;    // 1: keep only back faces (seen from the light centre)
#include "common/facing.glsl"
uniform float u_object = -1.0;  // object index (exact in a float up to 2^24)
layout(location = 0) out vec2 f_depth;

void main() {
    if (u_back_only == 1 && front_facing()) discard;
    f_depth = vec2(v_depth, u_object);
}
