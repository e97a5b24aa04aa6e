// Unoccluded irradiance of one light at every covered pixel: rgb, and its scalar weight in alpha.
#include "common/pixel.glsl"
#include "shading/irradiance.glsl"

layout(rgba32f, binding = 0) uniform writeonly image2D u_out;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    vec4 p = texelFetch(g_position, px, 0);
    imageStore(u_out, px, p.w > 0.0 ? receiver_irradiance(p.xyz, texelFetch(g_normal, px, 0).xyz,
                                                                normalize(texelFetch(g_geometric, px, 0).xyz)) : vec4(0.0));
}
