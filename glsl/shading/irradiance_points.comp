// Unoccluded irradiance at arbitrary points (for checking the shader against engine/irradiance.py).
#include "shading/irradiance.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
layout(std430, binding = 1) readonly buffer Normals { vec4 normals[]; };
layout(std430, binding = 2) writeonly buffer Result { vec4 result[]; };
layout(std430, binding = 3) readonly buffer Geometric { vec4 geometric[]; };   // geometric normals
uniform int u_count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    result[i] = vec4(light_irradiance(points[i].xyz, normalize(normals[i].xyz), normalize(geometric[i].xyz)), 0.0);
}
