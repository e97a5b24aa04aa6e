// Backprojection soft shadows (Schwarz & Stamminger, "Bitmask Soft Shadows", 2007; GBP06 as one setting).
//
// Per pixel: the search area is the receiver–light pyramid cut by the depth map's near plane (§2.1), refined
// with an HSM or MSSM (§5); pixels proven fully lit or in umbra stop there. Otherwise every depth-map texel
// (micro-occluder) in the area is unprojected and backprojected from the receiver onto the light plane
// (micropatches with GBP06 gap filling, or microquads, §4) and its occlusion is accumulated as an area
// (GBP06) or OR-ed into an occlusion bitmask of light samples (§3). At most BUDGET² micro-occluders per
// layer: larger areas use a coarser hierarchy level on that level's grid (§5).
//
// Backprojection, light-local frame (light plane z = 0, map looking down −Z from its centre). A point at
// window coordinate t (tangent at unit depth) and depth z seen from a receiver at window coordinate tp and
// depth d lands on the light plane at  x = (t − tp) · z·d/(d − z)  (perspective; from x = p + (q − p)·d/(d−z)
// with q = t·z, p = tp·d). For a sun's ortho map the light is the disk of directions: a point at t metres
// blocks the direction offset (t − tp)/(d − z). Light coordinates are divided by the light's half size, so
// the light is [−1, 1]² and a micropatch (parallel to the light) stays an axis-aligned rectangle.
#include "common/pixel.glsl"
#include "common/light_view.glsl"

#ifndef BITS
#define BITS 16                 // 0: area accumulation only; 8, 16, 32: N×N occlusion bitmask
#endif
#ifndef PRIMITIVE
#define PRIMITIVE 0             // 0 micropatches, 1 microquads
#endif
#ifndef GAP_FILL
#define GAP_FILL 1
#endif
#ifndef REFINE
#define REFINE 2                // 0 none, 1 HSM, 2 MSSM
#endif
#ifndef LAYERS
#define LAYERS 1
#endif
#ifndef TEXTURED
#define TEXTURED 0
#endif
#ifndef WEIGHTED
#define WEIGHTED 0              // 1: each light sample weighted by its unoccluded contribution at the receiver
#endif
#ifndef NEED_AREA
#define NEED_AREA 1
#endif

uniform int u_round;            // disk / ellipse / sphere / sun: samples outside the ellipse never count
uniform int u_delta;            // light without extent: plain hard shadow
uniform int u_budget;           // b: at most b×b micro-occluders per layer
uniform int u_levels;           // hierarchy levels available (0 … u_levels−1)
uniform vec2 u_jitter_x;        // bitmask sample x offset within its column, per row parity (§3)
uniform vec2 u_jitter_y;        // bitmask sample y offset within its row, per column parity
#if BITS > 0
uniform uint u_valid[BITS];     // per bitmask row: samples inside the light's shape
#endif
uniform float u_valid_count;

uniform sampler2D u_depth;      // layer 0 depth map (R32F), for delta lights
uniform sampler2D u_hsm0;       // per layer: min/max pyramid (RG32F, power-of-two padded)
uniform sampler2D u_hsm1;
uniform sampler2D u_hsm2;
uniform sampler2D u_hsm3;
uniform sampler2DArray u_mssm;  // layer 0 multi-scale shadow map (REFINE 2)
uniform int u_mssm_levels;      // MSSM levels stored; coarser ones come from the HSM (§5's hybrid)

layout(r32f, binding = 0) uniform writeonly image2D u_visibility;
layout(rgba32f, binding = 1) uniform writeonly image2D u_info;      // class, level, count, A
#if TEXTURED
uniform sampler2D u_sample_color;   // BITS×BITS: rgb colour of each light sample, a its luminance
layout(rgba32f, binding = 2) uniform writeonly image2D u_rgb;
#endif

const float EMPTY = 1.0e37;

vec2 g_tex;                     // window units per texel (x, y)
vec2 g_tp;                      // receiver's window coordinate
float g_d;                      // receiver depth
Receiver g_r;

// ---- hierarchy access -----------------------------------------------------------------------------------
// (min, max) depth of cell c of level l on the level's own grid (cells of 2^l × 2^l level-0 texels).
vec2 cell_minmax(int layer, int l, ivec2 c) {
#if REFINE == 2
    if (layer == 0 && l < u_mssm_levels) {
        // MSSM: the texel whose centred neighbourhood is exactly this cell (the HSM grid, §5).
        ivec2 t = l == 0 ? c : c * (1 << l) + (1 << (l - 1));
        return texelFetch(u_mssm, ivec3(clamp(t, ivec2(0), u_map_size - 1), l), 0).rg;
    }
#endif
    if (layer == 0) return texelFetch(u_hsm0, c, l).rg;
#if LAYERS > 1
    if (layer == 1) return texelFetch(u_hsm1, c, l).rg;
#endif
#if LAYERS > 2
    if (layer == 2) return texelFetch(u_hsm2, c, l).rg;
#endif
#if LAYERS > 3
    if (layer == 3) return texelFetch(u_hsm3, c, l).rg;
#endif
    return vec2(3.0e38);
}

float cell_depth(int layer, int l, ivec2 c) {
    ivec2 n = (u_map_size + (1 << l) - 1) >> l;
    if (any(lessThan(c, ivec2(0))) || any(greaterThanEqual(c, n))) return 3.0e38;
    return cell_minmax(layer, l, c).x;
}

// ---- search area -----------------------------------------------------------------------------------------
// Half extent (texels) of the pyramid section at occluder depth z: h·(1/z − 1/d) (perspective) or h·(d − z).
vec2 search_half(float z) {
    float s = u_light_ortho == 1 ? max(g_d - z, 0.0) : max(1.0 / max(z, 1e-30) - 1.0 / g_d, 0.0);
    return min(u_light_half * s / g_tex, vec2(1.0e7));
}

// Texel range [lo, hi] (inclusive, level 0) of the search area for occluders no nearer than z; false if
// the area misses the map.
bool search_area(float z, out ivec2 lo, out ivec2 hi) {
    vec2 h = search_half(z);
    vec2 c = clamp(g_r.map.xy, vec2(-2.0e7), vec2(2.0e7));
    lo = ivec2(floor(c - h));
    hi = ivec2(floor(c + h));
    if (any(greaterThanEqual(lo, u_map_size)) || any(lessThan(hi, ivec2(0)))) return false;
    lo = max(lo, ivec2(0));
    hi = min(hi, u_map_size - 1);
    return true;
}

int ceil_log2(int n) {
    return n <= 1 ? 0 : findMSB(n - 1) + 1;
}

// HSM bound (GBP06): the ≤ 2×2 cells of the finest level on which the area spans at most two cells.
vec2 hsm_bound(ivec2 lo, ivec2 hi) {
    int l = 0;
    while (l < u_levels - 1 && any(greaterThan((hi >> l) - (lo >> l), ivec2(1)))) ++l;
    ivec2 a = lo >> l, b = hi >> l;
    vec2 m = vec2(3.0e38, -3.0e38);
    for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x) {
            vec2 v = texelFetch(u_hsm0, ivec2(x, y), l).rg;
            m = vec2(min(m.x, v.x), max(m.y, v.y));
        }
    return m;
}

#if REFINE == 2
vec2 cell_minmax_raw_mssm(ivec2 t, int l) {
    return texelFetch(u_mssm, ivec3(clamp(t, ivec2(0), u_map_size - 1), l), 0).rg;
}
#endif

// Depth range bound over the area (§5). `fine` = 0: one MSSM sample covering it (HSM: the ≤ 2×2 cells of
// the level where it spans at most two); `fine` = 1: four MSSM samples on the corners of the area whose
// (overlapping) neighbourhoods tightly cover it.
vec2 area_bound(ivec2 lo, ivec2 hi, int fine) {
    ivec2 n = hi - lo + 1;
#if REFINE == 2
    int l = min(ceil_log2(max(n.x, n.y)), u_levels - 1);
    if (fine == 0 && l < u_mssm_levels) {
        ivec2 t = l == 0 ? lo : lo + (1 << (l - 1));
        return cell_minmax_raw_mssm(t, l);
    }
    l = min(ceil_log2(max((n.x + 1) / 2, (n.y + 1) / 2)), u_levels - 1);
    if (l >= u_mssm_levels) return hsm_bound(lo, hi);
    ivec2 a = l == 0 ? lo : lo + (1 << (l - 1));
    ivec2 b = l == 0 ? hi : hi + 1 - (1 << (l - 1));
    vec2 m0 = cell_minmax_raw_mssm(a, l), m1 = cell_minmax_raw_mssm(ivec2(b.x, a.y), l);
    vec2 m2 = cell_minmax_raw_mssm(ivec2(a.x, b.y), l), m3 = cell_minmax_raw_mssm(b, l);
    return vec2(min(min(m0.x, m1.x), min(m2.x, m3.x)), max(max(m0.y, m1.y), max(m2.y, m3.y)));
#else
    return hsm_bound(lo, hi);
#endif
}

// ---- occlusion accounting ---------------------------------------------------------------------------------
#if BITS > 0
uint g_occ[BITS];
const uint ROW_MASK = BITS == 32 ? 0xffffffffu : ((1u << BITS) - 1u);

uint bit_range(int k0, int k1) {
    if (k1 <= k0) return 0u;
    uint width = uint(k1 - k0);
    return (width >= 32u ? 0xffffffffu : ((1u << width) - 1u)) << uint(k0);
}

// OR the samples inside [u0, u1) × [v0, v1) (light coordinates in [0, 1]) into the bitmask (§3). Sample
// (column k, row l) sits at ((k + jx[l&1]) / N, (l + jy[k&1]) / N): the regular N×N grid for offsets ½, the
// 8×8 tiling of the 2×2 rotated grid (RGSS) for the jittered 16×16 pattern. Columns are turned into a bit
// range per row parity, rows into a range per column parity (scale, bias and integer conversion).
void set_rect(vec2 a, vec2 b) {
    float N = float(BITS);
    uint cols[2];
    int r0[2], r1[2];
    for (int q = 0; q < 2; ++q) {
        int k0 = int(clamp(ceil(a.x * N - u_jitter_x[q]), 0.0, N));
        int k1 = int(clamp(ceil(b.x * N - u_jitter_x[q]), 0.0, N));
        cols[q] = bit_range(k0, k1);
        r0[q] = int(clamp(ceil(a.y * N - u_jitter_y[q]), 0.0, N));
        r1[q] = int(clamp(ceil(b.y * N - u_jitter_y[q]), 0.0, N));
    }
    const uint EVEN = 0x55555555u & ROW_MASK, ODD = 0xaaaaaaaau & ROW_MASK;
    int lmin = min(r0[0], r0[1]), lmax = max(r1[0], r1[1]);
    for (int l = lmin; l < lmax; ++l) {
        uint sel = ((l >= r0[0] && l < r1[0]) ? EVEN : 0u) | ((l >= r0[1] && l < r1[1]) ? ODD : 0u);
        g_occ[l] |= cols[l & 1] & sel;
    }
}
#endif

float g_area;                   // accumulated occluded fraction of the light (unclamped, GBP06)

// Fraction of the unit disk covered by the rectangle [a, b] (eight-strip midpoint rule over x, exact in y).
float disk_fraction(vec2 a, vec2 b) {
    float x0 = max(a.x, -1.0), x1 = min(b.x, 1.0);
    if (x1 <= x0 || b.y <= -1.0 || a.y >= 1.0) return 0.0;
    float w = (x1 - x0) / 8.0, sum = 0.0;
    for (int i = 0; i < 8; ++i) {
        float s = x0 + (float(i) + 0.5) * w;
        float c = sqrt(max(1.0 - s * s, 0.0));
        sum += max(min(b.y, c) - max(a.y, -c), 0.0);
    }
    return sum * w / 3.14159265;
}

// Rectangle [a, b] in light coordinates ([−1, 1]² = the light's bounding rectangle).
void add_rect(vec2 a, vec2 b) {
#if NEED_AREA
    if (u_round == 1) {
        g_area += disk_fraction(a, b);
    } else {
        vec2 lo = max(a, vec2(-1.0)), hi = min(b, vec2(1.0));
        g_area += max(hi.x - lo.x, 0.0) * max(hi.y - lo.y, 0.0) * 0.25;
    }
#endif
#if BITS > 0
    set_rect(a * 0.5 + 0.5, b * 0.5 + 0.5);
#endif
}

// ---- micro-occluders --------------------------------------------------------------------------------------
float k_of(float z) {
    return u_light_ortho == 1 ? 1.0 / (g_d - z) : z * g_d / (g_d - z);
}

// Is a texel of depth z at map position pos (texels) a micro-occluder for this receiver? Nearer than the
// receiver's own plane there (less the bias) and strictly nearer than the receiver.
bool occludes(float z, vec2 pos) {
    return z < EMPTY && z < receiver_depth_at(g_r, pos) && z < g_d * (1.0 - 1e-6);
}

// A coarse cell (level > 0) holds the minimum depth of its 2^l × 2^l texels; the receiver's own plane
// inside it reaches as near as its nearest corner (1/z is linear over the window), so compare there, or a
// tilted receiver shadows itself from coarse levels (the acne §4 warns about).
bool cell_occludes(float z, vec2 p0, vec2 p1, int l) {
    if (!(z < EMPTY) || !(z < g_d * (1.0 - 1e-6))) return false;
    if (l == 0) return z < receiver_depth_at(g_r, 0.5 * (p0 + p1));
    float m = min(min(receiver_depth_at(g_r, p0), receiver_depth_at(g_r, p1)),
                  min(receiver_depth_at(g_r, vec2(p0.x, p1.y)), receiver_depth_at(g_r, vec2(p1.x, p0.y))));
    return z < m;
}

vec2 window_at(vec2 pos) {
    return u_light_window.xz + pos * g_tex;
}

// Light coordinates of the window point w at depth z (§2.1 backprojection, see the header).
vec2 backproject(vec2 w, float z) {
    return (w - g_tp) * k_of(z) / u_light_half;
}

// Micropatch of cell c (level l): the cell's square at its (minimum) depth, parallel to the light. Gap
// filling (GBP06): when the left (bottom) neighbour is an occluder too, the patch's left (bottom) edge is
// extended to where that neighbour's right (top) edge backprojects, closing the gap between them.
void micropatch(int layer, int l, ivec2 c) {
    float s = float(1 << l);
    float z = cell_depth(layer, l, c);
    vec2 p0 = vec2(c) * s, p1 = min(p0 + s, vec2(u_map_size));
    if (!cell_occludes(z, p0, p1, l)) return;
    vec2 w0 = window_at(p0), w1 = window_at(p1);
    vec2 a = backproject(w0, z), b = backproject(w1, z);
#if GAP_FILL
    float zl = cell_depth(layer, l, c - ivec2(1, 0));
    if (cell_occludes(zl, p0 - vec2(s, 0.0), vec2(p0.x, p1.y), l))
        a.x = min(a.x, (w0.x - g_tp.x) * k_of(zl) / u_light_half.x);
    float zb = cell_depth(layer, l, c - ivec2(0, 1));
    if (cell_occludes(zb, p0 - vec2(0.0, s), vec2(p1.x, p0.y), l))
        a.y = min(a.y, (w0.y - g_tp.y) * k_of(zb) / u_light_half.y);
#endif
    add_rect(a, b);
}

// Microquad (§4) whose corners are the centres of cells c, c+(1,0), c+(0,1), c+(1,1): backprojected only
// when all four are occluders. Area accumulation: the quad with its corners clamped to the light rectangle
// (Fig. 6 left; watertight). Bitmask (and round lights): the axis-aligned rectangle through the midpoints of
// the quad's edges (Fig. 6 right).
void microquad(int layer, int l, ivec2 c) {
    float s = float(1 << l);
    vec2 v[4];
    for (int i = 0; i < 4; ++i) {
        ivec2 ci = c + ivec2(i & 1, i >> 1);
        float z = cell_depth(layer, l, ci);
        vec2 p0 = vec2(ci) * s, p1 = min(p0 + s, vec2(u_map_size));
        vec2 pos = 0.5 * (p0 + p1);
        if (!cell_occludes(z, p0, p1, l)) return;
        v[i] = backproject(window_at(pos), z);
    }
    // v[0] = (0,0), v[1] = (1,0), v[2] = (0,1), v[3] = (1,1)
    vec2 ml = 0.5 * (v[0] + v[2]), mr = 0.5 * (v[1] + v[3]);
    vec2 mb = 0.5 * (v[0] + v[1]), mt = 0.5 * (v[2] + v[3]);
    vec2 a = vec2(min(ml.x, mr.x), min(mb.y, mt.y)), b = vec2(max(ml.x, mr.x), max(mb.y, mt.y));
#if BITS > 0
    set_rect(a * 0.5 + 0.5, b * 0.5 + 0.5);
#endif
#if NEED_AREA
    if (u_round == 1) {
        g_area += disk_fraction(a, b);
    } else {
        vec2 q0 = clamp(v[0], -1.0, 1.0), q1 = clamp(v[1], -1.0, 1.0);
        vec2 q3 = clamp(v[3], -1.0, 1.0), q2 = clamp(v[2], -1.0, 1.0);
        // Shoelace over the loop (0,0) → (1,0) → (1,1) → (0,1).
        float twice = (q0.x * q1.y - q1.x * q0.y) + (q1.x * q3.y - q3.x * q1.y)
                    + (q3.x * q2.y - q2.x * q3.y) + (q2.x * q0.y - q0.x * q2.y);
        g_area += abs(twice) * 0.5 * 0.25;
    }
#endif
}

// ---- main -------------------------------------------------------------------------------------------------
#if WEIGHTED
// Unoccluded contribution of light sample (row l, column k) at the receiver (light_view.glsl's
// light_sample_weight, with the shading normal: zero below the horizon). The sample position mirrors
// sample_positions() in engine/techniques/backprojection.py.
vec3 g_shading;
float sample_weight(int l, int k) {
    float n = float(BITS);
    vec2 q = vec2((float(k) + u_jitter_x[l & 1]) / n, (float(l) + u_jitter_y[k & 1]) / n) * 2.0 - 1.0;
    return light_sample_weight(g_r, g_shading, q);
}
#endif

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    if (!pixel_lit(px)) {
        imageStore(u_visibility, px, vec4(1.0));
        imageStore(u_info, px, vec4(-1.0, 0.0, 0.0, 1.0));
#if TEXTURED
        imageStore(u_rgb, px, vec4(1.0));
#endif
        return;
    }
    g_r = make_receiver(texelFetch(g_position, px, 0).xyz, texelFetch(g_geometric, px, 0).xyz);
#if WEIGHTED
    g_shading = view_direction(texelFetch(g_normal, px, 0).xyz);
#endif
    g_d = g_r.map.z;
    g_tex = (u_light_window.yw - u_light_window.xz) / vec2(u_map_size);
    g_tp = window_coords(g_r.local);
    float d_biased = g_d - g_r.bias;

    float cls = 0.0, level = 0.0, count = 0.0;    // class: 0 lit, 1 umbra, 2 backprojected
    float v = 1.0, a_vis = 1.0;
    vec3 rgb = vec3(1.0);

    if (u_delta == 1) {
        v = map_lit_plane(u_depth, ivec2(floor(g_r.map.xy)), g_r);
        cls = v > 0.5 ? 0.0 : 1.0;
        a_vis = v;
        rgb = vec3(v);
    } else {
        ivec2 lo, hi;
        bool inside = search_area(u_light_depth_range.x, lo, hi);   // pyramid ∩ near plane (§2.1, §5)
        int state = inside ? 2 : 0;
#if REFINE > 0
        // §5: bound the area's depth range, classify, refine the area with z_min, bound again (finer), classify,
        // refine once more before any micro-occluder is touched.
        for (int pass = 0; pass < 2 && state == 2; ++pass) {
            vec2 zr = area_bound(lo, hi, pass);
            // The receiver plane's depth over the area: 1/z is linear in the window, so the corners bound it.
            float plo = d_biased, phi = d_biased;
            for (int i = 0; i < 4; ++i) {
                vec2 corner = vec2((i & 1) == 0 ? lo.x : hi.x + 1, (i >> 1) == 0 ? lo.y : hi.y + 1);
                float pz = receiver_depth_at(g_r, corner);
                plo = min(plo, pz);
                phi = max(phi, pz);
            }
            if (zr.x >= phi || zr.x >= g_d) state = 0;          // nothing nearer than the receiver: lit
            else if (zr.y < plo) state = 1;                     // everything nearer, no gap: umbra
            else if (!search_area(zr.x, lo, hi)) state = 0;
        }
#endif
        if (state == 0) {
            v = 1.0; cls = 0.0; a_vis = 1.0;
        } else if (state == 1) {
            v = 0.0; cls = 1.0; a_vis = 0.0; rgb = vec3(0.0);
        } else {
            cls = 2.0;
            // Budget (§5): the finest level whose grid covers the area with at most b (microquads: b − 1)
            // cells per side; sampling positions stay on that level's grid.
            int extra = PRIMITIVE == 1 ? 1 : 0;
            int l = 0;
            while (l < u_levels - 1 && any(greaterThan((hi >> l) - (lo >> l) + 1 + extra, ivec2(u_budget)))) ++l;
            level = float(l);
            ivec2 c0 = lo >> l, c1 = hi >> l;
            g_area = 0.0;
#if BITS > 0
            for (int i = 0; i < BITS; ++i) g_occ[i] = 0u;
#endif
            for (int layer = 0; layer < LAYERS; ++layer) {
#if PRIMITIVE == 0
                for (int y = c0.y; y <= c1.y; ++y)
                    for (int x = c0.x; x <= c1.x; ++x) micropatch(layer, l, ivec2(x, y));
                count += float((c1.x - c0.x + 1) * (c1.y - c0.y + 1));
#else
                for (int y = c0.y - 1; y <= c1.y; ++y)
                    for (int x = c0.x - 1; x <= c1.x; ++x) microquad(layer, l, ivec2(x, y));
                count += float((c1.x - c0.x + 2) * (c1.y - c0.y + 2));
#endif
            }
            a_vis = 1.0 - g_area;                                // unclamped (drives §3.1 post-filtering)
#if BITS > 0
            // Visibility = unset valid bits / valid bits (§3); samples outside the light's shape never count.
            float lit = 0.0;
            for (int i = 0; i < BITS; ++i) lit += float(bitCount(u_valid[i] & ~g_occ[i]));
            v = lit / u_valid_count;
#if TEXTURED || WEIGHTED
            // Weighted counts: §3.3's coloured light (each sample weighted by the light's colour there) and/or
            // each sample's unoccluded contribution at the receiver.
            vec4 sum_lit = vec4(0.0), sum_all = vec4(0.0);
            for (int i = 0; i < BITS; ++i) {
                uint m = u_valid[i];
                while (m != 0u) {
                    int k = findLSB(m);
                    m &= m - 1u;
#if TEXTURED
                    vec4 w = texelFetch(u_sample_color, ivec2(k, i), 0);
#else
                    vec4 w = vec4(1.0);
#endif
#if WEIGHTED
                    w *= sample_weight(i, k);
#endif
                    sum_all += w;
                    if ((g_occ[i] & (1u << uint(k))) == 0u) sum_lit += w;
                }
            }
            if (sum_all.a > 0.0) v = sum_lit.a / sum_all.a;      // luminance-weighted scalar visibility
#if TEXTURED
            rgb = sum_lit.rgb / max(sum_all.rgb, vec3(1e-30));
#endif
#endif
#else
            v = clamp(a_vis, 0.0, 1.0);                          // GBP06: accumulated area, clamped to 1
#if TEXTURED
            rgb = vec3(v);
#endif
#endif
        }
    }
    imageStore(u_visibility, px, vec4(clamp(v, 0.0, 1.0)));
    imageStore(u_info, px, vec4(cls, level, count, a_vis));
#if TEXTURED
    imageStore(u_rgb, px, vec4(clamp(rgb, 0.0, 1.0), 1.0));
#endif
}
