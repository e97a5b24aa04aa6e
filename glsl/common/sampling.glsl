// Sample patterns for kernels over a light's shape: square (R2 low-discrepancy set) or round (Vogel
// golden-angle disk), rotated/offset per pixel by interleaved gradient noise so the pattern's structure
// turns into fine noise instead of banding.

float pixel_noise(ivec2 px) {
    return fract(52.9829189 * fract(dot(vec2(px), vec2(0.06711056, 0.00583715))));
}

// Point i of n in [-1, 1]², covering the square (round = 0) or the unit disk (round = 1).
vec2 kernel_point(int i, int n, int round_shape, float noise) {
    if (round_shape == 1) {
        float r = sqrt((float(i) + 0.5) / float(n));
        float phi = float(i) * 2.39996323 + noise * 6.28318530718;
        return r * vec2(cos(phi), sin(phi));
    }
    // R2 sequence (Roberts 2018) with a per-pixel toroidal shift.
    vec2 q = fract(vec2(0.5) + float(i) * vec2(0.7548776662, 0.5698402910) + noise);
    return q * 2.0 - 1.0;
}
