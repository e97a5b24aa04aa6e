// light_footprint (common/light_view.glsl) at arbitrary light-local receiver points, for checking it against a
// ray projection of the light (tests/test_sphere_footprint.py).
#include "common/light_view.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
layout(std430, binding = 1) writeonly buffer Result { vec4 result[]; };   // centre, half box; axes
uniform int u_count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    Footprint f = light_footprint(points[i].xyz);
    result[2 * i] = vec4(f.centre, f.half_box);
    result[2 * i + 1] = vec4(f.axes[0], f.axes[1]);
}
