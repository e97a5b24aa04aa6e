// Conservative rasterization emulated in a geometry shader (Hasselgren, Akenine-Möller, Ohlsson 2005):
// each triangle is clipped against the near plane, fanned into at most two triangles, and each is drawn
// grown by half a texel (pushed-out edges or bounding box, see emit_box), so that every texel the
// triangle touches gets a fragment. The fragment stage keeps only texels the triangle really
// overlaps (exact triangle/box test) and takes depth from the triangle's own plane.
#include "common/light_view.glsl"
#include "conservative_map/texel.glsl"
layout(triangles) in;
layout(triangle_strip, max_vertices = 8) out;

flat out vec2 g_v0;     // the (clipped) triangle in texel coordinates (0 … size)
flat out vec2 g_v1;
flat out vec2 g_v2;
flat out vec3 g_eta;    // nearness η at each vertex (glsl/conservative_map/texel.glsl): affine across the map
flat out vec2 g_grad;   // dη per texel of the triangle's plane (0 for an edge-on triangle)
flat out uint g_codes;  // its two quantised slopes, x in bits 8–15, y in bits 0–7
flat out vec3 g_edge0;  // per edge: unit normal xy and its line's offset; the opposite vertex in g_third.
flat out vec3 g_edge1;  // Only for triangles within a few map sizes (g_fast), else the fragment stage
flat out vec3 g_edge2;  // measures from the near endpoint itself. Three vectors, not a flat mat3: NVIDIA's
flat out vec3 g_third;  // compiler (driver 580, H200) crashed linking a matrix passed from geometry to
flat out int g_fast;    // fragment stage (tests/test_shader_interfaces.py keeps interfaces matrix-free).

vec2 to_texels(vec4 clip) {
    return (clip.xy / clip.w * 0.5 + 0.5) * vec2(u_map_size);
}

// η = 1 − window depth grows towards the light (0 at the far plane, 1 at the near), affine in map space. A
// perspective view takes it from the linear depth (clip.w) itself: 1 − window depth cancels catastrophically
// when the near plane is tiny (casters reaching the light plane set it to 1e-5 of the scene), where η ~ n/z
// and float32's step near 1 is a sizeable share of η: in fuzz 7404 every plane came out 1.4 cm nearer at
// 7 m, beyond a 4 mm bias, and each receiver shadowed itself (tests/test_spsm.py). An ortho view's η is
// linear in its depth: no cancellation.
float eta_of(vec4 clip) {
    if (u_light_ortho == 1) return 1.0 - (clip.z / clip.w * 0.5 + 0.5);
    return eta_from_depth(clip.w);
}

vec2 t_grad;
uint t_codes;
mat3 t_edges;
vec3 t_third;
int t_fast;

void emit_flat(vec2 ta, vec2 tb, vec2 tc, vec3 eta, vec2 p) {
    g_v0 = ta; g_v1 = tb; g_v2 = tc; g_eta = eta; g_grad = t_grad; g_codes = t_codes;
    g_edge0 = t_edges[0]; g_edge1 = t_edges[1]; g_edge2 = t_edges[2]; g_third = t_third; g_fast = t_fast;
    gl_Position = vec4(p / vec2(u_map_size) * 2.0 - 1.0, 0.0, 1.0);
    EmitVertex();
}

// Hasselgren et al.'s two primitives: the triangle with each edge pushed out by half a texel's extent along
// its normal (covers every texel centre whose texel the triangle touches; it overshoots at acute corners),
// or the bounding box grown by half a texel. Whichever has the smaller area is drawn; the fragment stage's
// exact test discards the overshoot either way. (A full-map ground quad drawn as two boxes would shade
// every texel twice.)
void emit_box(vec4 a, vec4 b, vec4 c) {
    vec2 ta = to_texels(a), tb = to_texels(b), tc = to_texels(c);
    vec3 eta = vec3(eta_of(a), eta_of(b), eta_of(c));
    vec2 lo = min(ta, min(tb, tc)) - 0.5 - 1e-3;
    vec2 hi = max(ta, max(tb, tc)) + 0.5 + 1e-3;
    float area2 = cross2(tb - ta, tc - ta);
    vec2 size = vec2(u_map_size);
    // The plane η(x, y) through the three vertices: constant slopes, quantised once (§3.4).
    vec2 e1 = tb - ta, e2 = tc - ta;
    float de1 = eta.y - eta.x, de2 = eta.z - eta.x;
    t_grad = vec2(0.0);
    if (abs(area2) > 1e-9 * (dot(e1, e1) + dot(e2, e2)))
        t_grad = vec2(de1 * e2.y - de2 * e1.y, de2 * e1.x - de1 * e2.x) / area2;
    vec2 s_q = -t_grad / slope_scale();
    t_codes = (quantise_slope(s_q.x) << 8) | quantise_slope(s_q.y);
    bool small_coords = all(lessThan(abs(vec4(ta, tb)), vec4(4.0 * size.xyxy))) &&
                        all(lessThan(abs(tc), 4.0 * size));
    // The separating axes of the exact triangle/texel test, once per triangle.
    t_fast = small_coords ? 1 : 0;
    vec2 tv[3] = vec2[3](ta, tb, tc);
    for (int i = 0; i < 3; ++i) {
        vec2 p = tv[i], q = tv[(i + 1) % 3], r = tv[(i + 2) % 3];
        vec2 e = q - p;
        float len = length(e);
        vec2 axis = len > 1e-12 ? vec2(-e.y, e.x) / len : vec2(0.0);
        t_edges[i] = vec3(axis, dot(axis, p));
        t_third[i] = dot(axis, r);
    }
    if (small_coords && abs(area2) > 1e-6) {
        vec2 v[3] = vec2[3](ta, tb, tc);
        float s = sign(area2);
        vec2 n[3];
        float d[3];
        for (int i = 0; i < 3; ++i) {
            vec2 e = v[(i + 1) % 3] - v[i];
            n[i] = s * vec2(e.y, -e.x) / length(e);            // outward
            d[i] = dot(n[i], v[i]) + 0.5 * (abs(n[i].x) + abs(n[i].y)) + 1e-3;
        }
        vec2 g[3];
        bool ok = true;
        for (int i = 0; i < 3; ++i) {
            int j = (i + 2) % 3;                                // the edge before vertex i
            float det = cross2(n[j], n[i]);
            if (abs(det) < 1e-6) { ok = false; break; }
            g[i] = vec2(d[j] * n[i].y - d[i] * n[j].y, n[j].x * d[i] - n[i].x * d[j]) / det;
        }
        vec2 box = hi - lo;
        if (ok && 0.5 * abs(cross2(g[1] - g[0], g[2] - g[0])) < box.x * box.y) {
            for (int i = 0; i < 3; ++i) emit_flat(ta, tb, tc, eta, g[i]);
            EndPrimitive();
            return;
        }
    }
    // Nothing outside the map can get a fragment: keep the box's coordinates small.
    lo = clamp(lo, vec2(-1.0), size + 1.0);
    hi = clamp(hi, vec2(-1.0), size + 1.0);
    if (any(greaterThanEqual(lo, hi))) return;
    emit_flat(ta, tb, tc, eta, vec2(lo.x, lo.y));
    emit_flat(ta, tb, tc, eta, vec2(hi.x, lo.y));
    emit_flat(ta, tb, tc, eta, vec2(lo.x, hi.y));
    emit_flat(ta, tb, tc, eta, vec2(hi.x, hi.y));
    EndPrimitive();
}

void main() {
    // Sutherland–Hodgman against the near plane z_clip ≥ −w (keeps w > 0 for a perspective view).
    vec4 poly[4];
    int n = 0;
    for (int i = 0; i < 3; ++i) {
        vec4 p = gl_in[i].gl_Position;
        vec4 q = gl_in[(i + 1) % 3].gl_Position;
        float dp = p.z + p.w, dq = q.z + q.w;
        if (dp >= 0.0) poly[n++] = p;
        if ((dp >= 0.0) != (dq >= 0.0)) poly[n++] = mix(p, q, dp / (dp - dq));
    }
    if (n < 3) return;
    for (int i = 0; i < n; ++i) {
        if (!(poly[i].w > 0.0) || any(isnan(poly[i])) || any(isinf(poly[i]))) return;
    }
    emit_box(poly[0], poly[1], poly[2]);
    if (n == 4) emit_box(poly[0], poly[2], poly[3]);
}
