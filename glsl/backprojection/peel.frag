// Depth peeling from the light's centre (Schwarz & Stamminger 2007, §3.2): layer k keeps, per texel, the
// nearest fragment strictly behind layer k-1, so occluders hidden from the centre (the single-silhouette
// case) still become micro-occluders. Used with common/depth.vert (linear depth along the light's -Z).
// Ours: of a closed caster's faces turned away from the centre only those the centre sees nearly edge-on are
// kept. Another point of the light sees such a face on the solid's outline only when the face's plane passes
// between the two points, so the ray from the centre meets it within the light's angular radius α of its
// plane: cos(angle to the normal) ≤ sin α. The rest of the far side lies inside the near side's shadow from
// every light point, and as a layer of its own (a bar's underside right under its top) its coarse
// micro-occluders, shrunk about other centres than the near side's, doubled the occlusion of thin solids.
in float v_depth;
in vec3 v_view;
uniform sampler2D u_prev;       // the previous layer (R32F linear depth, NO_OCCLUDER where empty)
uniform float u_peel_eps;       // relative depth separation between layers
uniform int u_closed = 0;       // 1: a closed caster (cull its far side as above)
uniform int u_far_side = 1;     // 0: cull a closed caster's far side whole (BACKPROJECTION's solid columns
                                // stand for it: structures/solid_exits.py)
#include "common/facing.glsl"
uniform int u_light_ortho;      // 1: a sun (rays along −Z)
uniform float u_light_radius;   // the light's half diagonal: metres, or tan of the half angle for a sun
layout(location = 0) out float f_depth;

void main() {
    vec3 n = cross(dFdx(v_view), dFdy(v_view));     // the face's normal (before any branch: derivatives)
    vec3 ray = u_light_ortho == 1 ? vec3(0.0, 0.0, -1.0) : v_view;
    if (u_closed == 1 && !front_facing()) {
        if (u_far_side == 0) discard;
        float cos_n = abs(dot(n, ray)) / max(length(n) * length(ray), 1e-30);
        float r = u_light_radius;
        float sin_a = u_light_ortho == 1 ? r * inversesqrt(1.0 + r * r) : min(r / max(length(v_view), 1e-30), 1.0);
        if (cos_n > sin_a) discard;
    }
    float prev = texelFetch(u_prev, ivec2(gl_FragCoord.xy), 0).r;
    if (prev >= EMPTY_DEPTH || v_depth <= prev * (1.0 + u_peel_eps)) discard;
    f_depth = v_depth;
}
