// The multisampled G-buffer of an anti-aliased frame (engine/gpu/multisample.py) and the test that a sample
// repeats its pixel's own fragment.
#ifndef MSAA_SAMPLES
#define MSAA_SAMPLES 4
#endif

uniform sampler2D g_albedo;
uniform sampler2DMS ms_normal;      // xyz shading normal, w camera depth (0 where background)
uniform sampler2DMS ms_albedo;
uniform mat4 u_msaa_inv_view_proj;
uniform vec3 u_msaa_camera_position;
uniform vec3 u_msaa_camera_forward;

// A multisample's world position: multisampled attributes are evaluated at the pixel centre, so the sample
// lies on the camera ray through the centre, at its camera depth (perspective or orthographic alike).
vec3 sample_position(ivec2 px, ivec2 size, float depth) {
    vec2 ndc = (vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0;
    vec4 a = u_msaa_inv_view_proj * vec4(ndc, -1.0, 1.0);
    vec4 b = u_msaa_inv_view_proj * vec4(ndc, 0.0, 1.0);
    vec3 near = a.xyz / a.w, mid = b.xyz / b.w;
    float dn = dot(near - u_msaa_camera_position, u_msaa_camera_forward);
    float dm = dot(mid - u_msaa_camera_position, u_msaa_camera_forward);
    return near + (mid - near) * ((depth - dn) / (dm - dn));
}

// A sample repeats the pixel's own fragment (n0, a0 from the per-pixel G-buffer) when it has the same camera
// depth, normal and albedo: on the centre's ray, equal depth is the same point. The multisampled and the
// single-sample rasterisers interpolate at the same centre but may round differently (llvmpipe does, by
// ~1e-7 relative): equal within float noise counts as the same.
bool same_fragment(vec4 n, vec4 a, vec4 n0, vec4 a0) {
    return n0.w > 0.0 && n.w > 0.0 && abs(n.w - n0.w) <= 1e-5 * n0.w && dot(n.xyz, n0.xyz) >= 0.99999
        && all(lessThanEqual(abs(a.rgb - a0.rgb), vec3(1e-5)));
}
