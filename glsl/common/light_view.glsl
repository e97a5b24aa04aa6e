// Shared by every shadow-map technique: where a world point falls in the light's map, and the bias that
// keeps a surface from shadowing itself. Uniforms are filled from engine/lightview.py LightView.uniforms().
uniform mat4 u_light_view;
uniform vec4 u_light_window;      // x0, x1, y0, y1: tangents at unit depth, or metres for an ortho view
uniform int u_light_ortho;
uniform vec2 u_light_depth_range; // near, far
uniform ivec2 u_map_size;
uniform float u_texel_tan;        // window units per texel
uniform float u_bias;             // texels, scaled by the receiver's slope
uniform float u_normal_offset;    // texels along the geometric normal

vec3 light_local(vec3 p) {
    return (u_light_view * vec4(p, 1.0)).xyz;
}

// Window coordinates of a light-local point: tangents (perspective) or metres (ortho).
vec2 window_coords(vec3 l) {
    float depth = max(-l.z, 1e-30);
    return u_light_ortho == 1 ? l.xy : l.xy / depth;
}

// Map texel coordinates (0 … size) and linear depth of a light-local point.
vec3 map_coords(vec3 l) {
    vec2 w = window_coords(l);
    vec2 uv = (w - u_light_window.xz) / (u_light_window.yw - u_light_window.xz);
    return vec3(uv * vec2(u_map_size), -l.z);
}

// World size of one texel at a given depth.
float texel_world(float depth) {
    return u_light_ortho == 1 ? u_texel_tan : u_texel_tan * depth;
}

// Receiver in light space, pushed off its surface along the geometric normal (normal-offset bias); also
// returns the slope-scaled depth bias to subtract before comparing with the map.
vec3 biased_receiver(vec3 p, vec3 ng, out float depth_bias) {
    vec3 l = light_local(p);
    vec3 n = mat3(u_light_view) * ng;
    vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-l);
    float cos_t = clamp(abs(dot(n, to_light)), 1e-3, 1.0);
    float tan_t = min(sqrt(1.0 - cos_t * cos_t) / cos_t, 10.0);
    float texel = texel_world(max(-l.z, 0.0));
    l += n * (u_normal_offset * texel);
    depth_bias = u_bias * texel * (0.5 + tan_t);
    return l;
}

// Hard comparison against one texel: 1 lit, 0 shadowed. Outside the map counts as lit.
float map_lit(sampler2D map, ivec2 texel, float receiver_depth) {
    if (any(lessThan(texel, ivec2(0))) || any(greaterThanEqual(texel, u_map_size))) return 1.0;
    return texelFetch(map, texel, 0).r < receiver_depth ? 0.0 : 1.0;
}

// Bilinear percentage-closer comparison at a fractional texel position.
float map_lit_bilinear(sampler2D map, vec2 pos, float receiver_depth) {
    vec2 p = pos - 0.5;
    ivec2 i = ivec2(floor(p));
    vec2 f = p - vec2(i);
    float a = map_lit(map, i, receiver_depth);
    float b = map_lit(map, i + ivec2(1, 0), receiver_depth);
    float c = map_lit(map, i + ivec2(0, 1), receiver_depth);
    float d = map_lit(map, i + ivec2(1, 1), receiver_depth);
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}
