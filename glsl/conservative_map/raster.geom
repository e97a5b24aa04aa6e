// Conservative rasterization emulated in a geometry shader (Hasselgren, Akenine-Möller, Ohlsson 2005,
// the bounding-box variant): each triangle is clipped against the near plane, fanned into at most two
// triangles, and each is drawn as its 2D bounding box grown by half a texel, so that every texel the
// triangle's box touches gets a fragment. The fragment stage keeps only texels the triangle really
// overlaps (exact triangle/box test) and takes depth from the triangle's own plane.
layout(triangles) in;
layout(triangle_strip, max_vertices = 8) out;

uniform ivec2 u_map_size;

flat out vec2 g_v0;     // the (clipped) triangle in texel coordinates (0 … size)
flat out vec2 g_v1;
flat out vec2 g_v2;
flat out vec3 g_eta;    // nearness η at each vertex (glsl/conservative_map/texel.glsl): affine across the map

vec2 to_texels(vec4 clip) {
    return (clip.xy / clip.w * 0.5 + 0.5) * vec2(u_map_size);
}

// Window depth of a clip-space point: n/z·… for a perspective view, linear for an ortho one; both are
// affine in map space. η = 1 − window depth grows towards the light (0 at the far plane, 1 at the near).
float eta_of(vec4 clip) {
    return 1.0 - (clip.z / clip.w * 0.5 + 0.5);
}

void emit_box(vec4 a, vec4 b, vec4 c) {
    vec2 ta = to_texels(a), tb = to_texels(b), tc = to_texels(c);
    vec2 lo = min(ta, min(tb, tc)) - 0.5 - 1e-3;
    vec2 hi = max(ta, max(tb, tc)) + 0.5 + 1e-3;
    // Nothing outside the map can get a fragment: keep the box's coordinates small.
    lo = clamp(lo, vec2(-1.0), vec2(u_map_size) + 1.0);
    hi = clamp(hi, vec2(-1.0), vec2(u_map_size) + 1.0);
    if (any(greaterThanEqual(lo, hi))) return;
    vec3 eta = vec3(eta_of(a), eta_of(b), eta_of(c));
    vec2 corners[4] = vec2[4](vec2(lo.x, lo.y), vec2(hi.x, lo.y), vec2(lo.x, hi.y), vec2(hi.x, hi.y));
    for (int i = 0; i < 4; ++i) {
        g_v0 = ta; g_v1 = tb; g_v2 = tc; g_eta = eta;
        gl_Position = vec4(corners[i] / vec2(u_map_size) * 2.0 - 1.0, 0.0, 1.0);
        EmitVertex();
    }
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
