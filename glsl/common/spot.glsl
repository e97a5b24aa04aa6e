// Cycles' spot cone (kernel/light/spot.h), shared by the unoccluded irradiance and by techniques that
// weight light samples: a ray leaving the light along `d` is taken to the spot's frame divided by the
// object's scale, then smoothstepped over the blend band inside the cone.
#ifndef SPOT_GLSL
#define SPOT_GLSL
uniform mat3 u_spot_to_local;  // world → spot-local with the object's scale folded in (Cycles' cone shape)
uniform float u_spot_cos_half; // -1 for a light without a cone
uniform float u_spot_smooth;

float spot_attenuation(vec3 d) {
    vec3 dir = normalize(u_spot_to_local * d);
    float c = -dir.z;
    if (c <= u_spot_cos_half) return 0.0;
    float t = c - u_spot_cos_half;
    if (u_spot_smooth > 0.0 && t < u_spot_smooth) return smoothstep(0.0, u_spot_smooth, t);
    return 1.0;
}
#endif
