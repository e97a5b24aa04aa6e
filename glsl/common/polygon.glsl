// Lambert's edge formula for a convex polygon of constant radiance seen from a receiver of normal n:
//     E = L/2 · |Σ_i θ_i · n·ĝ_i|,  θ_i = angle between v_i and v_{i+1},  ĝ_i = normalize(v_i × v_{i+1}),
// over the polygon clipped to the receiver's upper hemisphere (vertices relative to the receiver). The
// unoccluded irradiance of every extended light (shading/irradiance.glsl) and SSM's share of a light that the
// receiver's horizon cuts (ssm/patch.glsl weighted_fraction) both use it.
#ifndef POLYGON_GLSL
#define POLYGON_GLSL

// One edge's term θ · n·(a×b)/|a×b|. θ/sinθ comes from the rational fit of Hill & Heitz ("Real-Time Area
// Lighting: a Journey from Research to Production", SIGGRAPH 2016 course, §"integrating edges"): far
// cheaper than atan on a software rasteriser, relative error below 1e-3 over the whole range.
float edge_term(vec3 a, vec3 b, vec3 n) {
    float la = length(a), lb = length(b);
    if (la <= 1e-30 || lb <= 1e-30) return 0.0;
    vec3 ua = a / la, ub = b / lb;
    float x = clamp(dot(ua, ub), -1.0, 1.0);
    float y = abs(x);
    float fit = (0.8543985 + (0.4965155 + 0.0145206 * y) * y) / (3.4175940 + (4.1616724 + y) * y);
    float theta_over_sin = 6.28318530718 * (x > 0.0 ? fit : 0.5 * inversesqrt(max(1.0 - x * x, 1e-7)) - fit);
    return theta_over_sin * dot(n, cross(ua, ub));
}

vec3 polygon_vertex(int i, vec3 center, vec3 u, vec3 v, int sides) {
    if (sides == 4) {
        // corners (-1,-1), (1,-1), (1,1), (-1,1)
        float sx = (i == 1 || i == 2) ? 1.0 : -1.0;
        float sy = (i >= 2) ? 1.0 : -1.0;
        return center + sx * u + sy * v;
    }
    // Regular N-gon scaled so its area equals the ellipse's: k² · N/2 · sin(2π/N) = π.
    float k = sqrt(6.28318530718 / (float(sides) * sin(6.28318530718 / float(sides))));
    float phi = 6.28318530718 * float(i) / float(sides);
    return center + k * (cos(phi) * u + sin(phi) * v);
}

// Σ of Lambert edge terms over the polygon clipped to n·v ≥ 0; vertices relative to the receiver.
float clipped_polygon_sum(vec3 center, vec3 u, vec3 v, int sides, vec3 n) {
    // Usually the whole light is above the receiver's horizon: sum the edges directly.
    bool above = true;
    for (int i = 0; i < sides; ++i) {
        if (dot(n, polygon_vertex(i, center, u, v, sides)) < 0.0) { above = false; break; }
    }
    if (above) {
        float direct = 0.0;
        vec3 a = polygon_vertex(sides - 1, center, u, v, sides);
        for (int i = 0; i < sides; ++i) {
            vec3 b = polygon_vertex(i, center, u, v, sides);
            direct += edge_term(a, b, n);
            a = b;
        }
        return abs(direct);
    }
    // Otherwise clip (Sutherland–Hodgman against the tangent plane), summing edges as they come out.
    float sum = 0.0;
    vec3 first = vec3(0.0), prev = vec3(0.0);
    bool have = false;
    vec3 a = polygon_vertex(sides - 1, center, u, v, sides);
    float ha = dot(n, a);
    for (int i = 0; i < sides; ++i) {
        vec3 b = polygon_vertex(i, center, u, v, sides);
        float hb = dot(n, b);
        vec3 out_pts[2];
        int count = 0;
        if ((ha >= 0.0) != (hb >= 0.0)) {
            out_pts[count++] = a + (b - a) * (ha / (ha - hb));   // the edge crosses the horizon
        }
        if (hb >= 0.0) out_pts[count++] = b;
        for (int k = 0; k < count; ++k) {
            if (have) sum += edge_term(prev, out_pts[k], n); else { first = out_pts[k]; have = true; }
            prev = out_pts[k];
        }
        a = b;
        ha = hb;
    }
    if (have) sum += edge_term(prev, first, n);
    return abs(sum);
}

// Whether rectangle r (x0, y0, x1, y1) in the plane z = 1 lies wholly above the plane through the origin with
// normal n: SSM's light seen from a receiver at its foot (ssm/patch.glsl weighted_fraction, ssm/receivers.comp).
bool rect_above(vec4 r, vec3 n) {
    return dot(n, vec3(r.xy, 1.0)) > 0.0 && dot(n, vec3(r.zy, 1.0)) > 0.0
        && dot(n, vec3(r.xw, 1.0)) > 0.0 && dot(n, vec3(r.zw, 1.0)) > 0.0;
}

#endif
