// The multisampled G-buffer of an anti-aliased frame (engine/gpu/multisample.py) and the test that a sample
// repeats its pixel's own fragment.
#ifndef MSAA_SAMPLES
#define MSAA_SAMPLES 4
#endif

uniform sampler2D g_albedo;
uniform sampler2DMS ms_position;
uniform sampler2DMS ms_normal;
uniform sampler2DMS ms_albedo;

// The multisampled and single-sample rasterisers interpolate the same attributes at the same pixel centre
// but may round differently (llvmpipe does, by ~1e-7 relative): equal within float noise counts as the same.
bool same_fragment(vec4 p, vec4 n, vec4 a, vec4 p0, vec4 n0, vec4 a0) {
    float scale = 1e-5 * max(max(abs(p0.x), abs(p0.y)), max(abs(p0.z), n0.w));
    return p0.w > 0.0 && p.w > 0.0 && all(lessThanEqual(abs(p.xyz - p0.xyz), vec3(scale)))
        && abs(n.w - n0.w) <= 1e-5 * n0.w && dot(n.xyz, n0.xyz) >= 0.99999
        && all(lessThanEqual(abs(a.rgb - a0.rgb), vec3(1e-5)));
}
