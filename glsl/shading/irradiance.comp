// Unoccluded irradiance of one light at every covered pixel: rgb, and its scalar weight in alpha.
#include "common/pixel.glsl"
#include "shading/irradiance.glsl"

layout(rgba32f, binding = 0) uniform writeonly image2D u_out;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    vec4 p = texelFetch(g_position, px, 0);
    vec3 e = vec3(0.0);
    if (p.w > 0.0) {
        e = light_irradiance(p.xyz, texelFetch(g_normal, px, 0).xyz);
        e = max(e, vec3(0.0));
        if (any(isnan(e)) || any(isinf(e))) e = vec3(0.0);
    }
    imageStore(u_out, px, vec4(e, dot(e, vec3(1.0 / 3.0))));
}
