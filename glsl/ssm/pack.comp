// Nearest and farthest receiver (depth, object) into one RGBA texture: one fetch per scatter fragment.
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_recv_near;
uniform sampler2D u_recv_far;
layout(rgba32f, binding = 0) uniform writeonly image2D u_receivers;
uniform ivec2 u_image_size;

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, u_image_size))) return;
    imageStore(u_receivers, t, vec4(texelFetch(u_recv_near, t, 0).rg, texelFetch(u_recv_far, t, 0).rg));
}
