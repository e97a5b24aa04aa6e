// LOQ map smoothing (Schwarz & Stamminger 2008, §4.2, pass 2): one direction of a separable 11×11 bilateral
// filter of the fractional level ℓ. From the centre the kernel walks outwards and stops at the first pixel
// that needs no backprojection (ℓ < 0) or lies across a depth discontinuity of the camera's view (relative
// camera-depth jump above u_depth_jump: the screen-space edges the paper's bilateral filter respects), so
// levels never leak between surfaces or into lit/umbra regions. The second (vertical)
// pass applies the budget guard: the smoothed ℓ never falls more than one level below the pixel's own.
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_src;        // r: ℓ (current), g: camera depth, b: the pixel's own ℓ (pass 1)
uniform ivec2 u_image_size;
uniform ivec2 u_dir;            // (1, 0) or (0, 1)
uniform int u_guard;            // 1: last pass, apply the guard
uniform float u_depth_jump;
layout(rgba32f, binding = 0) uniform writeonly image2D u_dst;

const int RADIUS = 5;           // 11 taps
const float SIGMA = 3.0;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(px, u_image_size))) return;
    vec4 c = texelFetch(u_src, px, 0);
    if (c.r < 0.0) {
        imageStore(u_dst, px, c);
        return;
    }
    float sum = c.r, wsum = 1.0;
    for (int side = -1; side <= 1; side += 2) {
        for (int k = 1; k <= RADIUS; ++k) {
            ivec2 q = px + u_dir * (side * k);
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, u_image_size))) break;
            vec4 n = texelFetch(u_src, q, 0);
            if (n.r < 0.0 || abs(n.g - c.g) > u_depth_jump * max(c.g, n.g)) break;
            float w = exp(-0.5 * float(k * k) / (SIGMA * SIGMA));
            sum += w * n.r;
            wsum += w;
        }
    }
    float ell = sum / wsum;
    if (u_guard == 1) ell = max(ell, c.b - 1.0);
    imageStore(u_dst, px, vec4(ell, c.g, c.b, 0.0));
}
