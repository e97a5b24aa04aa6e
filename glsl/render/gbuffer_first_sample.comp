// The per-pixel G-buffer of an anti-aliased frame: each pixel's first multisample (Schwarz & Stamminger
// 2008, §7: the single sample whose visibility the technique computes).
layout(local_size_x = 8, local_size_y = 8) in;

uniform sampler2DMS ms_position;
uniform sampler2DMS ms_normal;
uniform sampler2DMS ms_geometric;
uniform sampler2DMS ms_albedo;
uniform ivec2 u_image_size;

layout(rgba32f, binding = 0) uniform writeonly image2D u_position;
layout(rgba32f, binding = 1) uniform writeonly image2D u_normal;
layout(rgba32f, binding = 2) uniform writeonly image2D u_geometric;
layout(rgba32f, binding = 3) uniform writeonly image2D u_albedo;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(px, u_image_size))) return;
    imageStore(u_position, px, texelFetch(ms_position, px, 0));
    imageStore(u_normal, px, texelFetch(ms_normal, px, 0));
    imageStore(u_geometric, px, texelFetch(ms_geometric, px, 0));
    imageStore(u_albedo, px, texelFetch(ms_albedo, px, 0));
}
