// Averaged shadow maps (REFERENCE): adds one hard shadow map, rendered from one sample point of the light,
// to running sums.
// Each sample is weighted by its unoccluded contribution at the pixel (cosines over squared distance), so
// the average converges to the irradiance-weighted visibility that Cycles' shadowed/unshadowed ratio gives;
// a spot's samples also carry its cone.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/spot.glsl"

uniform sampler2D u_depth_map;
uniform vec3 u_sample_position;   // world position of the sample (perspective views)
uniform vec3 u_emit_dir;          // light's emission axis (world); a sun's: this sample's direction
uniform vec4 u_sphere_inside;     // a true sphere light's centre and r² (r² = -1 for any other light)
uniform int u_weight_mode;        // WEIGHT_NONE, WEIGHT_AREA (both cosines), WEIGHT_SPHERE (receiver cosine), WEIGHT_SUN
layout(rgba32f, binding = 0) uniform image2D u_sums;   // Σ w·v, Σ w, Σ v, count

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px) || !pixel_lit(px)) return;
    vec3 p = texelFetch(g_position, px, 0).xyz;
    Receiver r = make_receiver(p, texelFetch(g_geometric, px, 0).xyz);
    float v = map_lit_plane(u_depth_map, ivec2(floor(r.map.xy)), r);
    float w = 1.0;
    if (u_weight_mode == WEIGHT_SUN) {
        // sun sample (uniform over the cone): its radiance is constant, so only the receiver's cosine counts
        w = max(dot(texelFetch(g_normal, px, 0).xyz, -u_emit_dir), 0.0);
    } else if (u_weight_mode != WEIGHT_NONE) {
        vec3 to_sample = u_sample_position - p;
        float d2 = max(dot(to_sample, to_sample), 1e-30);   // m²: a receiver on the sample point
        vec3 dir = to_sample * inversesqrt(d2);
        w = max(dot(texelFetch(g_normal, px, 0).xyz, dir), 0.0) / d2;
        if (u_weight_mode == WEIGHT_AREA) w *= max(dot(-dir, u_emit_dir), 0.0);
        // A spot's cone applies per ray: a sample whose ray to p leaves the cone carries nothing (a wide
        // spot's disk reaches p only from its footprint; see shading/irradiance.glsl).
        // Inside a true sphere Cycles applies no cone (u_sphere_inside: centre and r², r² < 0 otherwise).
        vec3 from_centre = p - u_sphere_inside.xyz;
        bool inside = dot(from_centre, from_centre) <= u_sphere_inside.w;
        if (u_spot_cos_half > -1.0 && !inside) w *= spot_attenuation(-dir);
    }
    imageStore(u_sums, px, imageLoad(u_sums, px) + vec4(w * v, w, v, 1.0));
}
