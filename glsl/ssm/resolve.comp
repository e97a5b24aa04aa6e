// Fixed-point atomic sums → float soft shadow map (compute scatter only).
layout(local_size_x = 8, local_size_y = 8) in;
layout(r32ui, binding = 1) uniform readonly uimage2D u_sum_near;
layout(r32ui, binding = 2) uniform readonly uimage2D u_sum_far;
layout(rg32f, binding = 3) uniform writeonly image2D u_ssm;
uniform ivec2 u_image_size;

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, u_image_size))) return;
    // The sums are signed (sloped facets subtract): the bits as two's complement.
    vec2 v = vec2(ivec2(imageLoad(u_sum_near, t).r, imageLoad(u_sum_far, t).r)) / FIXED_POINT;
    imageStore(u_ssm, t, vec4(v, 0.0, 0.0));
}
