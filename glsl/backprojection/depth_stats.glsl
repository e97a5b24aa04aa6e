// Depth statistics of a set of non-empty depth-map texels (BACKPROJECTION's coverage, ours): vec4(mean depth,
// texel count, maximum depth, depth variance). Shared by the coverage pyramid (coverage.comp) and the
// microrects' member chain (microrects.comp); visibility.comp's cover() reads them.
const vec4 NO_STATS = vec4(0.0, 0.0, -NO_OCCLUDER, 0.0);

vec4 texel_stats(float z) {
    return z < EMPTY_DEPTH ? vec4(z, 1.0, z, 0.0) : NO_STATS;
}

// The union of two sets: counts add, means weigh by count, variances merge about the common mean (stable
// where depths are large and their spread small, unlike a running mean of squares).
vec4 merge_stats(vec4 a, vec4 b) {
    float n = a.g + b.g;
    if (n <= 0.0) return NO_STATS;
    float mean = (a.r * a.g + b.r * b.g) / n;
    float m2 = a.g * (a.a + (a.r - mean) * (a.r - mean)) + b.g * (b.a + (b.r - mean) * (b.r - mean));
    return vec4(mean, n, max(a.b, b.b), m2 / n);
}
