// Conservative map fragment: keep the texel only if the triangle really overlaps it, write the minimum
// conservative depth (Hasselgren et al. 2005: the plane's nearest value over the texel, clamped to the
// triangle's own depth range) to the depth test and the R32F map, and the 128-bit triangle texel.
#include "common/light_view.glsl"
#include "conservative_map/texel.glsl"

flat in vec2 g_v0;
flat in vec2 g_v1;
flat in vec2 g_v2;
flat in vec3 g_eta;
flat in vec2 g_grad;
flat in uint g_codes;
flat in vec3 g_edge0;     // raster.geom: per edge, its unit normal xy and its line's offset
flat in vec3 g_edge1;
flat in vec3 g_edge2;
flat in vec3 g_third;
flat in int g_fast;

layout(location = 0) out float f_min_depth;     // linear light depth of the minimum conservative depth
layout(location = 1) out uvec4 f_texel;
#ifdef CMAP_FLOAT_SLOPES
layout(location = 2) out vec2 f_slopes;         // ablation only: dη/dx, dη/dy unquantised
#endif


// Separating-axis test of a triangle (texel-relative) against the texel box [−½, ½]²: the box's two axes
// and the three edge normals. Touching counts as overlapping (conservative). A degenerate triangle (a
// segment or a point) is tested as what it is. Each edge is measured from its endpoint nearer the texel
// along its unit direction: a vertex clipped at a near plane close to the light lands ~1e8 texels away, and
// a dot product with it would lose whole texels in float32.
bool overlaps_texel(vec2 a, vec2 b, vec2 c) {
    vec2 lo = min(a, min(b, c)), hi = max(a, max(b, c));
    if (any(greaterThan(lo, vec2(0.5))) || any(lessThan(hi, vec2(-0.5)))) return false;
    vec2 v[3] = vec2[3](a, b, c);
    for (int i = 0; i < 3; ++i) {
        vec2 p = v[i], q = v[(i + 1) % 3], r = v[(i + 2) % 3];
        if (dot(p, p) > dot(q, q)) { vec2 t = p; p = q; q = t; }
        vec2 e = q - p;
        float len = length(e);
        if (!(len > 1e-12)) continue;
        vec2 axis = vec2(-e.y, e.x) / len;
        float base = dot(axis, p);                  // the edge's line, from its near endpoint
        float third = base + dot(axis, r - p);      // the opposite vertex
        float h = 0.5 * (abs(axis.x) + abs(axis.y)) + 1e-5;
        if (min(base, third) > h || max(base, third) < -h) return false;
    }
    return true;
}

// Texel-relative vertices pulled within the fixed-point reach: a far vertex slides along its edge that
// passes nearest the texel (that edge's line, which decides coverage near the texel, is kept).
vec2 pull_in(vec2 v, vec2 a, vec2 b) {
    if (max(abs(v.x), abs(v.y)) <= VERT_REACH) return v;
    vec2 other = abs(cross2(a - v, -v)) / max(length(a - v), 1e-20) <=
                 abs(cross2(b - v, -v)) / max(length(b - v), 1e-20) ? a : b;
    // Liang–Barsky: the part of segment other→v inside the reach box; keep its end nearest v.
    vec2 d = v - other;
    float t0 = 0.0, t1 = 1.0;
    for (int k = 0; k < 2; ++k) {
        if (abs(d[k]) < 1e-20) continue;
        float ta = (-VERT_REACH - other[k]) / d[k], tb = (VERT_REACH - other[k]) / d[k];
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
    return t0 <= t1 ? other + d * t1 : clamp(v, -VERT_REACH, VERT_REACH);
}

// The same test with the axes the geometry stage prepared (triangles within a few map sizes).
bool overlaps_texel_fast(vec2 centre, vec2 a, vec2 b, vec2 c) {
    vec2 lo = min(a, min(b, c)), hi = max(a, max(b, c));
    if (any(greaterThan(lo, vec2(0.5))) || any(lessThan(hi, vec2(-0.5)))) return false;
    for (int i = 0; i < 3; ++i) {
        vec3 edge = i == 0 ? g_edge0 : i == 1 ? g_edge1 : g_edge2;
        vec2 axis = edge.xy;
        float at = dot(axis, centre);
        float base = edge.z - at, third = g_third[i] - at;
        float h = 0.5 * (abs(axis.x) + abs(axis.y)) + 1e-4;
        if (min(base, third) > h || max(base, third) < -h) return false;
    }
    return true;
}

void main() {
    vec2 centre = gl_FragCoord.xy;
    vec2 a = g_v0 - centre, b = g_v1 - centre, c = g_v2 - centre;
    if (!(g_fast == 1 ? overlaps_texel_fast(centre, a, b, c) : overlaps_texel(a, b, c))) discard;

    // The plane's η at the texel centre, from the vertex nearest the texel (far clipped vertices would
    // cancel catastrophically); an edge-on triangle (no gradient) counts at its nearest vertex.
    vec2 grad = g_grad;
    float eta_top = max(g_eta.x, max(g_eta.y, g_eta.z));
    float eta_c = eta_top;
    if (any(notEqual(grad, vec2(0.0)))) {
        vec2 vs[3] = vec2[3](a, b, c);
        int near_i = dot(a, a) <= dot(b, b) ? (dot(a, a) <= dot(c, c) ? 0 : 2) : (dot(b, b) <= dot(c, c) ? 1 : 2);
        eta_c = g_eta[near_i] + dot(grad, -vs[near_i]);
    }
    // Nearest value of the plane over the texel (the corner the gradient points to), never nearer than
    // the triangle itself reaches (an edge-on triangle: its nearest vertex).
    float eta_cons = min(eta_c + 0.5 * (abs(grad.x) + abs(grad.y)), eta_top);
    f_min_depth = depth_from_eta(clamp(eta_cons, 0.0, 1.0));
    // The depth test on linear depth, not 1 − η: near a tiny near plane 1 − η keeps 0.2 % of the depth
    // (raster.geom eta_of), too coarse to tell a surface from one a centimetre behind it.
    gl_FragDepth = clamp((f_min_depth - u_light_depth_range.x) / (u_light_depth_range.y - u_light_depth_range.x),
                         0.0, 1.0);

    float z_c = depth_from_eta(eta_c);
    vec2 pa = pull_in(a, b, c), pb = pull_in(b, c, a), pc = pull_in(c, a, b);
    f_texel = uvec4(pack_vertex(pa), pack_vertex(pb), pack_vertex(pc),
                    pack_depth_slopes(z_c, g_codes));
#ifdef CMAP_FLOAT_SLOPES
    f_slopes = grad;
#endif
}
