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

// A receiver as the shadow-map techniques see it: its light-local position pushed off the surface along
// the geometric normal (normal-offset bias), that normal in light space, its map coordinates (texels,
// depth) and the slope-scaled depth bias to subtract before comparing with the map.
struct Receiver {
    vec3 local;
    vec3 normal;
    vec3 map;
    float bias;
};

Receiver make_receiver(vec3 p, vec3 ng) {
    Receiver r;
    vec3 l = light_local(p);
    r.normal = mat3(u_light_view) * ng;
    vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-l);
    float cos_t = clamp(abs(dot(r.normal, to_light)), 1e-3, 1.0);
    float tan_t = min(sqrt(1.0 - cos_t * cos_t) / cos_t, 10.0);
    float texel = texel_world(max(-l.z, 0.0));
    r.local = l + r.normal * (u_normal_offset * texel);
    r.map = map_coords(r.local);
    r.bias = u_bias * texel * (0.5 + tan_t);
    return r;
}

// Depth of the receiver's own plane under a map position, less the bias: what a texel there must be
// nearer than to shadow the receiver. Following the plane instead of using the centre depth keeps a flat
// receiver from shadowing itself across a wide kernel (receiver-plane depth bias).
float receiver_depth_at(Receiver r, vec2 map_pos) {
    vec2 w = u_light_window.xz + map_pos / vec2(u_map_size) * (u_light_window.yw - u_light_window.xz);
    float np = dot(r.normal, r.local);
    float z = r.map.z;
    // The eye (light centre) above the receiver's plane and this texel's ray meeting the plane in front:
    // everything on the ray past the plane lies below the receiver's tangent plane, and no point there can
    // stand between the receiver and any part of the light above that plane (the only part that lights
    // it). So the plane's depth is a hard upper limit there, however close to the eye it comes.
    bool eye_above = false;
    if (u_light_ortho == 1) {
        if (abs(r.normal.z) > 1e-4) z = (r.normal.x * w.x + r.normal.y * w.y - np) / r.normal.z;
        eye_above = r.normal.z > 1e-4;
    } else {
        float den = r.normal.x * w.x + r.normal.y * w.y - r.normal.z;
        if (abs(den) > 1e-6 && np / den > 0.0) z = np / den;
        eye_above = np < 0.0 && den < -1e-6;     // 1e-6: den is a tangent-space dot product, unitless
    }
    // Far from the centre a steep plane can run away: never trust it beyond twice the centre's distance,
    // nor (where the eye is below the plane or the ray misses it) nearer than half of it.
    z = eye_above ? min(z, 2.0 * r.map.z) : clamp(z, 0.5 * r.map.z, 2.0 * r.map.z);
    return z - r.bias;
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
