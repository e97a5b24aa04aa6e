// Backprojection soft shadows (Schwarz & Stamminger, "Bitmask Soft Shadows", 2007; GBP06 as one setting).
//
// Per pixel: the search area is the receiver–light pyramid cut by the depth map's near plane (§2.1), refined
// with an HSM or MSSM (§5); pixels proven fully lit or in umbra stop there. Otherwise every depth-map texel
// (micro-occluder) in the area is unprojected and backprojected from the receiver onto the light plane
// (micropatches with GBP06 gap filling, or microquads, §4) and its occlusion is accumulated as an area
// (GBP06) or OR-ed into an occlusion bitmask of light samples (§3). At most BUDGET² micro-occluders per
// layer: larger areas use a coarser hierarchy level on that level's grid (§5).
//
// Quality scalability (Schwarz & Stamminger 2008): the budget b_mo(x, y) may vary over the image (§4.2); with
// LOQ = LOQ_WRITE this program only classifies and writes each pixel's fractional level ℓ into the LOQ map
// (pass 1), loq.comp smooths it (pass 2), and LOQ = LOQ_BLEND gathers at ⌊ℓ⌋ and ⌈ℓ⌉ and blends (pass 3).
// Microrects (§5.2) come from their own mip chains (structures/microrects.py); the YSM (§6) is the HSM's
// first n levels plus an MSSM built from HSM level n−1; GROW (§6) grows the queried area to the support of
// the micro-occluders of the level it will use, so that no pixel is proven lit more precisely than that
// level can shade it.
//
// Backprojection, light-local frame (light plane z = 0, map looking down −Z from its centre). A point at
// window coordinate t (tangent at unit depth) and depth z seen from a receiver at window coordinate tp and
// depth d lands on the light plane at  x = (t − tp) · z·d/(d − z)  (perspective; from x = p + (q − p)·d/(d−z)
// with q = t·z, p = tp·d). For a sun's ortho map the light is the disk of directions: a point at t metres
// blocks the direction offset (t − tp)/(d − z). Light coordinates are divided by the light's half size, so
// the light is [−1, 1]² and a micropatch (parallel to the light) stays an axis-aligned rectangle.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "common/penumbra.glsl"
#include "common/disk.glsl"

#ifndef BITS
#define BITS 16                 // 0: area accumulation only; 8, 16, 32: N×N occlusion bitmask
#endif
#ifndef PRIMITIVE
#define PRIMITIVE PRIMITIVE_MICROPATCH   // or PRIMITIVE_MICROQUAD
#endif
#ifndef GAP_FILL
#define GAP_FILL 1
#endif
#ifndef REFINE
#define REFINE REFINE_MSSM      // REFINE_NONE, REFINE_HSM or REFINE_MSSM
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
#ifndef LOQ
#define LOQ LOQ_INTEGER
#endif
#ifndef GROW
#define GROW 0
#endif
#ifndef REFIT
#define REFIT REFIT_NONE       // REFIT_EXTENT/MEAN/DEPTH: coarse micro-occluders refitted (see refit)
#endif
#ifndef COVERAGE
#define COVERAGE 0              // 1: coarse micro-occluders shrunk to their occluding share (see cover)
#endif
#ifndef SPLIT
#define SPLIT 0                 // 1: coarse micro-occluders that backproject large are split (see gather_range)
#endif
#ifndef REFIT_ITERATIONS
#define REFIT_ITERATIONS 0      // loop iterations the coarse refit costs a micro-occluder (see part_iterations)
#endif
#ifndef COLUMNS
#define COLUMNS 0               // 1: micro-occluders of closed casters reach to the solid's exit (solid_column)
#endif
#ifndef CHUNKED
#define CHUNKED 0               // 1: the gather is split over several dispatches (see gather_range)
#endif

uniform int u_round;            // disk / ellipse / sphere / sun: samples outside the ellipse never count
uniform int u_delta;            // light without extent: plain hard shadow
uniform float u_budget;         // b: at most b×b micro-occluders per layer (the budget map's centre value)
uniform float u_budget_border;  // BUDGET_BORDER: b at the left and right image borders
uniform int u_budget_mode;      // BUDGET_UNIFORM, BUDGET_BORDER, BUDGET_UNBOUNDED (b = ∞: level 0 always) or
                                // BUDGET_IMPORTANCE
uniform float u_budget_low;     // BUDGET_IMPORTANCE: b where the importance is 0 (u_budget where it is 1)
uniform sampler2D u_importance_image;    // BUDGET_IMPORTANCE: per pixel, the budget image's grey value…
uniform sampler2D u_importance_objects;  // …and the importance of the object seen there
uniform int u_force_level;      // ≥ 0: every pixel gathers at this level (the study's forced coarse levels)
uniform int u_levels;           // hierarchy levels available (0 … u_levels−1)
#ifndef MULTI_JITTER
#define MULTI_JITTER 0          // 1: the multi-jittered patterns (BITMASK_16MJ, BITMASK_32MJ), see rect_span
#endif
uniform vec2 u_jitter_x;        // bitmask sample x offset within its column, per row parity (§3)
uniform vec2 u_jitter_y;        // bitmask sample y offset within its row, per column parity
#if BITS > 0
uniform uint u_valid[BITS];     // per bitmask row: samples inside the light's shape
#endif
#if SPLIT
uniform float u_split;          // a coarse micro-occluder wider on the light than this share of it is split
uniform int u_split_extra;      // at most this many finer micro-occluders per pixel and gather from splits
#endif

uniform sampler2D u_depth;      // layer 0 depth map (R32F), for delta lights
uniform sampler2D u_hsm0;       // per layer: min/max pyramid (RG32F, power-of-two padded)
uniform sampler2D u_hsm1;
uniform sampler2D u_hsm2;
uniform sampler2D u_hsm3;
uniform sampler2DArray u_mssm;  // layer 0 multi-scale shadow map (REFINE_MSSM)
uniform int u_mssm_levels;      // MSSM levels stored; coarser ones come from the HSM (§5's hybrid)
uniform sampler2DArray u_ysm;   // REFINE_YSM: MSSM part built from HSM level u_ysm_base, its levels 1 … K
uniform int u_ysm_base;         // n − 1
uniform int u_ysm_levels;       // K (array layer k − 1 holds MSSM level k)
uniform ivec2 u_ysm_size;       // resolution of the MSSM part (HSM level n − 1)
#if PRIMITIVE == PRIMITIVE_MICRORECT
uniform sampler2D u_mr_depth0;  // per layer: microrect depth (R32F) and extent (RGBA32F: x0, y0, x1, y1 in
uniform sampler2D u_mr_extent0; // level-0 texels, exclusive upper end), full mip chains
uniform sampler2D u_mr_depth1;
uniform sampler2D u_mr_extent1;
uniform sampler2D u_mr_depth2;
uniform sampler2D u_mr_extent2;
uniform sampler2D u_mr_depth3;
uniform sampler2D u_mr_extent3;
#endif
#if COVERAGE
uniform sampler2D u_cov0;       // per layer: mean, count, max, variance of the non-empty texels per cell
uniform sampler2D u_cov1;       // (structures/coverage.py) or microrect (its member statistics)
uniform sampler2D u_cov2;
uniform sampler2D u_cov3;
#endif
#if LOQ == LOQ_BLEND
uniform sampler2D u_loq;        // smoothed LOQ map: r = ℓ (negative: no backprojection)
#endif

layout(r32f, binding = 0) uniform writeonly image2D u_visibility;
layout(rgba32f, binding = 1) uniform writeonly image2D u_info;      // class, level, count, A
#if LOQ == LOQ_WRITE
layout(rgba32f, binding = 3) uniform writeonly image2D u_loq_out;   // ℓ, camera depth, ℓ, 0 (pass 1)
#endif
#if TEXTURED
uniform sampler2D u_sample_color;   // BITS×BITS: rgb colour of each light sample, a its luminance
layout(rgba32f, binding = 2) uniform writeonly image2D u_rgb;
#endif

// Relative depth gap (fraction of the receiver's linear depth) a micro-occluder needs in front of the
// receiver: a texel of the receiver's own surface, a rounding error nearer, must not occlude it.
const float SELF_GAP = 1e-6;

// What one pixel's gather knows about its receiver: the Receiver (light_view.glsl), its map depth d,
// its window coordinate tp, and the window units per map texel.
struct Pixel {
    Receiver r;
    float d;
    vec2 tp;
    vec2 tex;
    vec3 shading;       // shading normal in the view's frame (the sample weights' horizon)
    ivec2 px;           // its image pixel
    bool centre_lit;    // the depth map sees the receiver: nothing hides the light's centre from it
    Footprint fp;       // the light on the light plane as this receiver sees it (light_view.glsl)
    vec2 centre_n;      // the light's centre in light coordinates: −fp.centre / fp.half_box
};

// Occlusion gathered so far: the N×N bitmask of light samples hidden (§3) and the summed occluded fraction
// of the light (GBP06 area accumulation, unclamped).
struct Occlusion {
    float area;
#if BITS > 0
    uint bits[BITS];
#endif
};

// ---- hierarchy access -----------------------------------------------------------------------------------
// (min, max) depth of cell c of level l on the level's own grid (cells of 2^l × 2^l level-0 texels).
vec2 cell_minmax(int layer, int l, ivec2 c) {
#if REFINE == REFINE_MSSM
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
    return vec2(NO_OCCLUDER);
}

bool cell_outside(int l, ivec2 c) {
    ivec2 n = (u_map_size + (1 << l) - 1) >> l;
    return any(lessThan(c, ivec2(0))) || any(greaterThanEqual(c, n));
}

float cell_depth(int layer, int l, ivec2 c) {
    if (cell_outside(l, c)) return NO_OCCLUDER;
    return cell_minmax(layer, l, c).x;
}

#if PRIMITIVE == PRIMITIVE_MICRORECT
// Microrect of texel c of level l (§5.2): its depth and its extent [x0, x1) × [y0, y1) in level-0 texels.
float rect_depth(int layer, int l, ivec2 c, out vec4 ext) {
    ext = vec4(0.0);
    if (cell_outside(l, c)) return NO_OCCLUDER;
    if (layer == 0) { ext = texelFetch(u_mr_extent0, c, l); return texelFetch(u_mr_depth0, c, l).r; }
#if LAYERS > 1
    if (layer == 1) { ext = texelFetch(u_mr_extent1, c, l); return texelFetch(u_mr_depth1, c, l).r; }
#endif
#if LAYERS > 2
    if (layer == 2) { ext = texelFetch(u_mr_extent2, c, l); return texelFetch(u_mr_depth2, c, l).r; }
#endif
#if LAYERS > 3
    if (layer == 3) { ext = texelFetch(u_mr_extent3, c, l); return texelFetch(u_mr_depth3, c, l).r; }
#endif
    return NO_OCCLUDER;
}
#endif

// ---- search area -----------------------------------------------------------------------------------------
// Half extent (texels) of the pyramid section at occluder depth z: h·spread(z, d) (common/penumbra.glsl),
// capped at 1e7 texels so that an occluder on the light plane gives a huge but finite area.
vec2 search_half(Pixel p, float z) {
    float s = penumbra_spread_clamped(z, p.d, u_light_ortho);
    return min((abs(p.fp.centre) + p.fp.half_box) * s / p.tex, vec2(1.0e7));
}

// Texel range [lo, hi] (inclusive, level 0) of the search area for occluders no nearer than z; false if
// the area misses the map. The centre is clamped to ±2e7 texels to keep ivec2 conversion in range.
bool search_area(Pixel p, float z, out ivec2 lo, out ivec2 hi) {
    vec2 h = search_half(p, z);
    vec2 c = clamp(p.r.map.xy, vec2(-2.0e7), vec2(2.0e7));
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
    vec2 m = vec2(NO_OCCLUDER, -NO_OCCLUDER);
    for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x) {
            vec2 v = texelFetch(u_hsm0, ivec2(x, y), l).rg;
            m = vec2(min(m.x, v.x), max(m.y, v.y));
        }
    return m;
}

// The one-sample bound (pass 0) uses the neighbourhood centred at lo + 2^(l−1), the level being set by the
// area's longer side: along the shorter side that centre can lie beyond the map (seen: an area 88 × 63
// texels ending at the map's last row, centred 2 rows past it). The MSSM stores no texel there; clamping
// the centre back to the edge shifts the neighbourhood below lo, over texels outside the area, whose
// occluders then keep a pixel backprojected that the exact bound proves lit (~150 pixels on a 256 × 239
// map). Such an area takes the four-sample cover instead, which is exact and stays inside the map. `s`: the
// grid's level (the YSM part is on the level-s grid; its padding beyond the map is left to the same rule).
bool centre_in_map(ivec2 t, int s) {
    return all(lessThan(t, (u_map_size + (1 << s) - 1) >> s));
}

#if REFINE == REFINE_MSSM
vec2 cell_minmax_raw_mssm(ivec2 t, int l) {
    return texelFetch(u_mssm, ivec3(clamp(t, ivec2(0), u_map_size - 1), l), 0).rg;
}
#endif

#if REFINE == REFINE_YSM
// YSM sample (§6): MSSM level k of the part built from HSM level n − 1 (level 0 is that HSM level itself,
// not stored again). t is on the level-(n − 1) grid.
vec2 ysm_sample(ivec2 t, int k) {
    t = clamp(t, ivec2(0), u_ysm_size - 1);
    if (k == 0) return texelFetch(u_hsm0, t, u_ysm_base).rg;
    return texelFetch(u_ysm, ivec3(t, k - 1), 0).rg;
}

// Depth range over [lo, hi] from the YSM: the HSM's ≤ 2×2 cells while the area spans at most two cells of
// a level below n; beyond, the MSSM part on the level-(n − 1) grid, as area_bound does with a full MSSM.
vec2 ysm_bound(ivec2 lo, ivec2 hi, int fine) {
    int s = u_ysm_base;
    if (all(lessThanEqual((hi >> s) - (lo >> s), ivec2(1)))) return hsm_bound(lo, hi);
    ivec2 clo = lo >> s, chi = hi >> s;
    ivec2 n = chi - clo + 1;
    int k = ceil_log2(max(n.x, n.y));
    ivec2 t = clo + (1 << (k - 1));
    // Same rule as area_bound's MSSM (a centre beyond the map takes the four-sample cover), so that a YSM
    // whose part is the whole map classifies exactly like the MSSM.
    if (fine == 0 && k <= u_ysm_levels && centre_in_map(t, s)) return ysm_sample(t, k);
    k = ceil_log2(max((n.x + 1) / 2, (n.y + 1) / 2));
    if (k > u_ysm_levels) return hsm_bound(lo, hi);
    ivec2 a = k == 0 ? clo : clo + (1 << (k - 1));
    ivec2 b = k == 0 ? chi : chi + 1 - (1 << (k - 1));
    vec2 m0 = ysm_sample(a, k), m1 = ysm_sample(ivec2(b.x, a.y), k);
    vec2 m2 = ysm_sample(ivec2(a.x, b.y), k), m3 = ysm_sample(b, k);
    return vec2(min(min(m0.x, m1.x), min(m2.x, m3.x)), max(max(m0.y, m1.y), max(m2.y, m3.y)));
}
#endif

// Depth range bound over the area (§5). `fine` = 0: one MSSM sample covering it (HSM: the ≤ 2×2 cells of
// the level where it spans at most two); `fine` = 1: four MSSM samples on the corners of the area whose
// (overlapping) neighbourhoods tightly cover it.
vec2 area_bound(ivec2 lo, ivec2 hi, int fine) {
    ivec2 n = hi - lo + 1;
#if REFINE == REFINE_MSSM
    int l = min(ceil_log2(max(n.x, n.y)), u_levels - 1);
    ivec2 t = l == 0 ? lo : lo + (1 << (l - 1));
    if (fine == 0 && l < u_mssm_levels && centre_in_map(t, 0)) return cell_minmax_raw_mssm(t, l);
    l = min(ceil_log2(max((n.x + 1) / 2, (n.y + 1) / 2)), u_levels - 1);
    if (l >= u_mssm_levels) return hsm_bound(lo, hi);
    ivec2 a = l == 0 ? lo : lo + (1 << (l - 1));
    ivec2 b = l == 0 ? hi : hi + 1 - (1 << (l - 1));
    vec2 m0 = cell_minmax_raw_mssm(a, l), m1 = cell_minmax_raw_mssm(ivec2(b.x, a.y), l);
    vec2 m2 = cell_minmax_raw_mssm(ivec2(a.x, b.y), l), m3 = cell_minmax_raw_mssm(b, l);
    return vec2(min(min(m0.x, m1.x), min(m2.x, m3.x)), max(max(m0.y, m1.y), max(m2.y, m3.y)));
#elif REFINE == REFINE_YSM
    return ysm_bound(lo, hi, fine);
#else
    return hsm_bound(lo, hi);
#endif
}

// ---- occlusion accounting ---------------------------------------------------------------------------------
#if BITS > 0
const uint ROW_MASK = BITS == 32 ? 0xffffffffu : ((1u << BITS) - 1u);

uint bit_range(int k0, int k1) {
    if (k1 <= k0) return 0u;
    uint width = uint(k1 - k0);
    return (width >= 32u ? 0xffffffffu : ((1u << width) - 1u)) << uint(k0);
}

// OR the samples inside [u0, u1) × [v0, v1) (light coordinates in [0, 1]) into the bitmask (§3). Sample
// (column k, row l) sits at ((k + jx[l&1]) / N, (l + jy[k&1]) / N): the regular N×N grid for offsets ½, the
// 8×8 tiling of the 2×2 rotated grid (RGSS) for the jittered 16×16 pattern. Columns are turned into a bit
// range per row parity, rows into a range per column parity (scale, bias and integer conversion). The
// owner of the bitmask ORs span_row(s, l) into rows s.rows.x ≤ l < s.rows.y (no bitmask is passed around:
// a function taking the array inout would copy it per micro-occluder).
#if !MULTI_JITTER
struct Span {
    uvec2 cols;                 // column bits, for even and odd rows
    ivec2 r0, r1;               // row range [r0, r1), for even and odd columns
    ivec2 rows;                 // rows touched: [min r0, max r1)
};
#endif

#if MULTI_JITTER
// Multi-jittered rooks (ours; the layout of Chiu, Shirley & Wang's multi-jittered sampling): sample (column k,
// row l) sits at ((k + (P[l] + ½)/N) / N, (l + (P[k] + ½)/N) / N), P the bit-reversal permutation. The N² samples
// take N² distinct x and N² distinct y values, where the jittered pattern's take 2N: an edge parallel to the
// light's sides (a box, a plane, the light's own outline) crossed a whole row of samples at once and the
// penumbra came out in 2N steps, the same with N = 32. P, not the identity (a sheared lattice): with the
// identity a cell's y offset grows with k, so the samples left of a vertical edge sit low in their cells, and
// under a light whose irradiance weights change steeply over it (one seen low over the receiver) the shadow
// shifted (`grazing` 0.0097 → 0.0129); any prefix of the bit-reversal order is spread evenly. Within a row x is
// k plus a per-row offset, so a rectangle's x bounds give one range of k (⌊A⌋ or ⌊A⌋ + 1 by whether P[l] lies
// below a threshold); its y bounds cut only its first and last row, by a mask of the columns k whose P[k]
// clears the threshold (MJ_AT_LEAST).
// Both tables come from backprojection.multi_jitter_defines (the Python pattern's own permutation):
// MJ_AT_LEAST[t] holds the columns k with P[k] ≥ t.
const int MJ_PERM[BITS] = MJ_PERM_VALUES;
const uint MJ_AT_LEAST[BITS + 1] = MJ_AT_LEAST_VALUES;

struct Span {
    ivec4 x;                    // (⌊a.x·N⌋, its threshold on P[l], ⌊b.x·N⌋, its threshold)
    ivec4 y;                    // (first row, its threshold on P[k], last row, its threshold)
    ivec2 rows;                 // rows touched: [first, last + 1)
};

Span rect_span(vec2 a, vec2 b) {
    float N = float(BITS);
    Span s;
    vec2 ax = clamp(vec2(a.x, b.x), -1.0, 2.0) * N, mx = floor(ax);
    ivec2 tx = ivec2(ceil((ax - mx) * N - 0.5));
    s.x = ivec4(int(mx.x), tx.x, int(mx.y), tx.y);
    vec2 ay = clamp(vec2(a.y, b.y), -1.0, 2.0) * N, my = floor(ay);
    ivec2 ty = clamp(ivec2(ceil((ay - my) * N - 0.5)), 0, BITS);
    s.y = ivec4(int(my.x), ty.x, int(my.y), ty.y);
    s.rows = ivec2(max(s.y.x, 0), min(s.y.z, BITS - 1) + 1);
    return s;
}

uint span_row(Span s, int l) {
    if (l < s.y.x || l > s.y.z) return 0u;
    int p = MJ_PERM[l];
    uint m = bit_range(clamp(s.x.x + int(p < s.x.y), 0, BITS), clamp(s.x.z + int(p < s.x.w), 0, BITS));
    if (l == s.y.x) m &= MJ_AT_LEAST[s.y.y];
    if (l == s.y.z) m &= ~MJ_AT_LEAST[s.y.w] & ROW_MASK;
    return m;
}
#else
Span rect_span(vec2 a, vec2 b) {
    float N = float(BITS);
    Span s;
    for (int q = 0; q < 2; ++q) {
        int k0 = int(clamp(ceil(a.x * N - u_jitter_x[q]), 0.0, N));
        int k1 = int(clamp(ceil(b.x * N - u_jitter_x[q]), 0.0, N));
        s.cols[q] = bit_range(k0, k1);
        s.r0[q] = int(clamp(ceil(a.y * N - u_jitter_y[q]), 0.0, N));
        s.r1[q] = int(clamp(ceil(b.y * N - u_jitter_y[q]), 0.0, N));
    }
    s.rows = ivec2(min(s.r0[0], s.r0[1]), max(s.r1[0], s.r1[1]));
    return s;
}

uint span_row(Span s, int l) {
    const uint EVEN = 0x55555555u & ROW_MASK, ODD = 0xaaaaaaaau & ROW_MASK;
    uint sel = ((l >= s.r0[0] && l < s.r1[0]) ? EVEN : 0u) | ((l >= s.r0[1] && l < s.r1[1]) ? ODD : 0u);
    return s.cols[l & 1] & sel;
}
#endif

// A rectangle swept linearly from [a0, b0] to [a1, b1] (light coordinates in [0, 1]; a solid column's
// backprojection, solid_column): the union over t of [mix(a0, a1, t), mix(b0, b1, t)], which is the convex hull
// of the two. Row l's samples of column parity q sit at one height y; the t for which the rectangle holds
// that height form an interval (two linear bounds), and the row's x extent is the union of the rectangle's at
// its two ends (each edge moves linearly in t).
struct Sweep {
    vec2 a0, b0, a1, b1;
};

// Clip [t.x, t.y] to where f0 + t·df ≤ 0.
void clip_linear(float f0, float df, inout vec2 t) {
    if (df > 0.0) t.y = min(t.y, -f0 / df);
    else if (df < 0.0) t.x = max(t.x, -f0 / df);
    else if (f0 > 0.0) t = vec2(1.0, 0.0);
}

// The hull's x extent [x0, x1) at height y (x0 > x1: the hull does not reach y).
vec2 sweep_extent(Sweep s, float y) {
    vec2 t = vec2(0.0, 1.0);
    clip_linear(s.a0.y - y, s.a1.y - s.a0.y, t);
    clip_linear(y - s.b0.y, s.b0.y - s.b1.y, t);
    if (t.x > t.y) return vec2(1.0, 0.0);
    return vec2(min(mix(s.a0.x, s.a1.x, t.x), mix(s.a0.x, s.a1.x, t.y)),
                max(mix(s.b0.x, s.b1.x, t.x), mix(s.b0.x, s.b1.x, t.y)));
}

#if MULTI_JITTER
// Row l of the rooks pattern, in two halves by height: the columns whose sample lies in the lower half of its
// cell (P[k] < N/2) take the hull's extent at the middle of the part of that half the hull spans, the others
// at the upper half's; the hull's height range cuts by each sample's own height (a side of the hull that
// slants within a half is taken at one height). Not the half's own middle: where the hull's top or bottom
// edge crosses a half, that middle may lie outside the hull, and the half's samples inside it were all
// dropped; a cube's columns lost 3 % of their samples that way, their shadow's penumbra too light (`cube` at
// 64², level 0: mae_shadow 0.0096, 0.0023 without columns).
uint sweep_row(Sweep s, int l) {
    float N = float(BITS), c = (float(MJ_PERM[l]) + 0.5) / N;
    float ymin = min(s.a0.y, s.a1.y), ymax = max(s.b0.y, s.b1.y);
    int t0 = int(clamp(ceil((ymin * N - float(l)) * N - 0.5), 0.0, N));
    int t1 = int(clamp(ceil((ymax * N - float(l)) * N - 0.5), 0.0, N));
    uint in_range = MJ_AT_LEAST[t0] & ~MJ_AT_LEAST[t1];
    uint bits = 0u;
    for (int h = 0; h < 2; ++h) {
        float lo = max((float(l) + 0.5 * float(h)) / N, ymin), hi = min((float(l) + 0.5 * float(h) + 0.5) / N, ymax);
        vec2 e = sweep_extent(s, 0.5 * (lo + hi));
        int k0 = int(clamp(ceil(e.x * N - c), 0.0, N)), k1 = int(clamp(ceil(e.y * N - c), 0.0, N));
        uint half_ = h == 0 ? ~MJ_AT_LEAST[BITS / 2] & ROW_MASK : MJ_AT_LEAST[BITS / 2];
        bits |= e.x <= e.y ? bit_range(k0, k1) & half_ : 0u;
    }
    return bits & in_range;
}
#else
uint sweep_row(Sweep s, int l) {
    const uint PARITY[2] = uint[2](0x55555555u & ROW_MASK, 0xaaaaaaaau & ROW_MASK);
    float N = float(BITS);
    uint bits = 0u;
    for (int q = 0; q < 2; ++q) {
        vec2 e = sweep_extent(s, (float(l) + u_jitter_y[q]) / N);
        int k0 = int(clamp(ceil(e.x * N - u_jitter_x[l & 1]), 0.0, N));
        int k1 = int(clamp(ceil(e.y * N - u_jitter_x[l & 1]), 0.0, N));
        bits |= e.x <= e.y ? bit_range(k0, k1) & PARITY[q] : 0u;
    }
    return bits;
}
#endif
#endif

// Fraction of the unit disk covered by the rectangle [a, b] (exact: common/disk.glsl).
float disk_fraction(vec2 a, vec2 b) {
    return any(greaterThanEqual(a, b)) ? 0.0 : disk_share(vec4(a, b));
}

// Occluded fraction of the light for the rectangle [a, b] in light coordinates ([−1, 1]² = the light's
// bounding rectangle).
float rect_area(vec2 a, vec2 b) {
    if (u_round == 1) return disk_fraction(a, b);
    vec2 lo = max(a, vec2(-1.0)), hi = min(b, vec2(1.0));
    return max(hi.x - lo.x, 0.0) * max(hi.y - lo.y, 0.0) * 0.25;
}

// Occluded fraction for a light rectangle swept linearly from [a, b] to back's (solid columns), for the area
// accumulation: the clipped box around both, less the share of the unclipped box that its two corners
// outside their hull take.
float sweep_area(vec2 a, vec2 b, vec4 back) {
    vec2 lo = min(a, back.xy), hi = max(b, back.zw);
    float box = (hi.x - lo.x) * (hi.y - lo.y);
    vec2 shift = abs(0.5 * (back.xy + back.zw - a - b));
    float hull = box - min(shift.x * shift.y, box);
    return rect_area(lo, hi) * (box > 0.0 ? hull / box : 1.0);
}

// ---- micro-occluders --------------------------------------------------------------------------------------
// Light-plane units per window unit for a point at depth z (the header's z·d/(d − z), or 1/(d − z) for a sun).
float k_of(Pixel p, float z) {
    return u_light_ortho == 1 ? 1.0 / (p.d - z) : z * p.d / (p.d - z);
}

// The receiver plane's nearest depth (receiver_depth_at) over the map rectangle [p0, p1]: at one corner, found
// from the normal instead of evaluating all four. Along map rays the plane's depth is z = c / (n.xy·w − n.z)
// (perspective, c = n·x < 0 with the origin above) or (n.xy·w − c) / n.z (ortho, n.z > 0): either way it grows
// with the window coordinate w where n.xy is positive, and its clamps (the receiver's depth, rays that miss
// the plane) keep it monotone; w grows with the map position. Below the plane it is one constant.
float receiver_depth_min(Pixel p, vec2 p0, vec2 p1) {
    return receiver_depth_at(p.r, mix(p1, p0, vec2(greaterThan(p.r.normal.xy, vec2(0.0)))));
}

// Its deepest depth over [p0, p1]: the opposite corner.
float receiver_depth_max(Pixel p, vec2 p0, vec2 p1) {
    return receiver_depth_at(p.r, mix(p0, p1, vec2(greaterThan(p.r.normal.xy, vec2(0.0)))));
}

// A stored depth that is a surface (not empty) nearer than `bound`.
bool surface_before(float z, float bound) {
    return z < EMPTY_DEPTH && z < bound;
}

// A stored depth that is a surface nearer than the receiver (the first test of every micro-occluder).
bool before_receiver(Pixel p, float z) {
    return surface_before(z, p.d * (1.0 - SELF_GAP));
}

// The depth a coarse cell's texels over [p0, p1] must lie nearer than to occlude: the receiver's plane at its
// nearest corner there, and never deeper than the receiver itself.
float occluding_depth(Pixel p, vec2 p0, vec2 p1) {
    return min(receiver_depth_min(p, p0, p1), p.d * (1.0 - SELF_GAP));
}

// A coarse cell (level > 0) holds the minimum depth of its 2^l × 2^l texels; the receiver's own plane
// inside it reaches as near as its nearest corner (1/z is linear over the window), so compare there, or a
// tilted receiver shadows itself from coarse levels (the acne §4 warns about).
bool cell_occludes(Pixel p, float z, vec2 p0, vec2 p1, int l) {
    if (l == 0) return before_receiver(p, z) && z < receiver_depth_at(p.r, 0.5 * (p0 + p1));
    return surface_before(z, occluding_depth(p, p0, p1));
}

#if COVERAGE
vec4 cov_fetch(int layer, int l, ivec2 c) {
    if (cell_outside(l, c)) return vec4(0.0);
    if (layer == 0) return texelFetch(u_cov0, c, l);
#if LAYERS > 1
    if (layer == 1) return texelFetch(u_cov1, c, l);
#endif
#if LAYERS > 2
    if (layer == 2) return texelFetch(u_cov2, c, l);
#endif
#if LAYERS > 3
    if (layer == 3) return texelFetch(u_cov3, c, l);
#endif
    return vec4(0.0);
}

// The texels of a cell's statistics s (mean μ, count, max M, variance) nearer than depth d, read as two
// clusters (see cover): (their share of the cell's texels, their mean depth). All of them when M is nearer
// than d; else a far cluster at M and a near one whose share q = (M − μ)² / E[(M − z)²] matches μ and the
// variance, and whose mean follows from μ = q·z + (1 − q)·M.
vec2 near_cluster(vec4 s, float d) {
    if (s.b < d) return vec2(1.0, s.r);
    float gap = s.b - s.r;
    float q = gap * gap / max(s.a + gap * gap, 1e-30);
    return vec2(q, s.r - gap * (1.0 - q) / max(q, 1e-30));
}
#endif

#if REFIT != REFIT_NONE
// Coarse refit (our addition to the 2007/2008 coarse levels): a level-l micro-occluder over [p0, p1) at the
// minimum depth z of all its texels also turns the texels that do not occlude this receiver (the ground
// beside a silhouette, the receiver's own surface) into occluders at z, and lifts the deeper ones towards
// the light: too large, too central a backprojection (over-darkening). Per receiver, its level-(l − 1)
// parts that occlude at their own depth are kept: the extent shrinks to their bounding box (within
// [p0, p1)), the depth becomes their minimum (REFIT_EXTENT: still no deeper than any occluding texel) or their
// mean (REFIT_MEAN: the deeper texels no longer lifted to the nearest; with coverage on, each part counts at
// the mean depth of its own occluding texels); REFIT_DEPTH keeps the extent and takes only the mean depth.
// The parts: a micropatch's 2×2 cells of level l − 1; a microrect's level-(l − 1) microrects among
// 2c + {−1, 0, 1}² whose reference point (level-0 texel j·2^(l−1)) lies in its extent, which holds every
// microrect merged into it (each holds its own reference point, and the merge unites extents), clipped to
// that extent. REFIT_PLANE is REFIT_MEAN plus the parts' depth slope (see
// backproject_tilted), returned in `slope` (depth per level-0 texel in x and y, the parts' nearest depth, and
// the deepest the plane reaches over them: their deepest depth plus half a part's fall along the slope; zero
// slope for the other refits). False: no part occludes.
#if PRIMITIVE == PRIMITIVE_MICRORECT
const int REFIT_PARTS = REFIT_PARTS_MICRORECT;
#else
const int REFIT_PARTS = REFIT_PARTS_MICROPATCH;
#endif

// `centre`: the mean of the occluding parts' centres, where cover() shrinks the box towards.
bool refit(Pixel p, int layer, int l, ivec2 c, inout float z, inout vec2 p0, inout vec2 p1, out vec4 slope,
           out vec2 centre) {
    int f = l - 1;
    vec2 lo = vec2(NO_OCCLUDER), hi = vec2(-NO_OCCLUDER);
    float zmin = NO_OCCLUDER, zmax = -NO_OCCLUDER, zsum = 0.0, n = 0.0;
    vec2 xsum = vec2(0.0), xzsum = vec2(0.0), xxsum = vec2(0.0);   // part centres, from the cell's corner
    for (int k = 0; k < REFIT_PARTS; ++k) {
#if PRIMITIVE == PRIMITIVE_MICRORECT
        ivec2 j = 2 * c + ivec2(k % 3 - 1, k / 3 - 1);
        vec2 ref = vec2(j * (1 << f));
        if (any(lessThan(ref, p0)) || any(greaterThanEqual(ref, p1))) continue;
        vec4 e;
        float zc = rect_depth(layer, f, j, e);
        vec2 q0 = max(e.xy, p0), q1 = min(e.zw, p1);
#else
        ivec2 j = 2 * c + ivec2(k & 1, k >> 1);
        vec2 q0 = vec2(j * (1 << f)), q1 = min(q0 + float(1 << f), p1);
        if (any(greaterThanEqual(q0, p1))) continue;
        float zc = cell_depth(layer, f, j);
#endif
        // cell_occludes, keeping a coarse part's occluding depth for its coverage below.
        float dq = f > 0 ? occluding_depth(p, q0, q1) : 0.0;
        if (f > 0 ? !surface_before(zc, dq) : !cell_occludes(p, zc, q0, q1, 0)) continue;
        lo = min(lo, q0);
        hi = max(hi, q1);
        zmin = min(zmin, zc);
        float zpart = zc;
#if COVERAGE
        // The part's depth for the mean and the slope: the mean of its texels nearer than the receiver, not
        // their minimum. The minimum lies on the part's edge nearest the light: on a surface the light meets
        // at a slant (a ball's flank) every part's minimum sits half a part towards the light, and the plate
        // through them stands that far in front of the surface, too small on the light: the inner penumbra
        // next to a ball came out light (tilted at 128²: mae_shadow 0.0187, 0.0138 with the means). A level-0
        // part is one texel: its own mean.
        if (f > 0) {
            vec2 near = near_cluster(cov_fetch(layer, f, j), dq);
            if (near.x > 1e-3) zpart = clamp(near.y, zc, max(dq, zc));
        }
#endif
        zsum += zpart;
        zmax = max(zmax, zpart);
        n += 1.0;
        vec2 x = 0.5 * (q0 + q1) - p0;
        xsum += x;
        xzsum += x * zpart;
        xxsum += x * x;
    }
    slope = vec4(0.0, 0.0, zmin, zmax);
    centre = p0 + xsum / max(n, 1.0);
    if (n == 0.0) return false;
#if REFIT == REFIT_PLANE
    // Least-squares slope of the parts' depths, per axis (the parts lie on a grid, so the axes decouple).
    vec2 xm = xsum / n, spread = xxsum / n - xm * xm;
    slope.xy = mix(vec2(0.0), (xzsum / n - xm * (zsum / n)) / max(spread, vec2(1e-12)),
                   greaterThan(spread, vec2(1e-6)));
    slope.w += 0.5 * float(1 << f) * (abs(slope.x) + abs(slope.y));
#endif
    if (REFIT != REFIT_DEPTH) {
        p0 = lo;
        p1 = hi;
    }
    z = REFIT == REFIT_EXTENT ? max(zmin, z) : max(zsum / n, z);
    return true;
}
#endif


#if COVERAGE
// Coverage (ours): a coarse micro-occluder stands for all the texels of its cell (micropatch) or of its
// members (microrect), but only those nearer than the receiver occlude it: bars thinner than a cell (fences,
// grids) or a cell astride the receiver's own surface would otherwise block the whole backprojected box. Its
// statistics (structures/coverage.py for cells, the microrects' member chain) give the non-empty texels'
// count n, max M, mean μ and variance σ². All occlude when M is nearer than the receiver; else the texels
// are read as two clusters, a far one at M (the receiver's own surface, the ground behind a fence) and a
// near one, which matching μ and σ² puts at share (M − μ)² / (σ² + (M − μ)²) (exact for two depths; a near
// cluster spread in depth comes out smaller, never above its true share). The box [p0, p1) (after the
// refit) is shrunk to the area of the occluding texels (never grown), towards the refit's occluding parts
// (`centre`) and along the axis they lean on: the same occluded area of the light, where the texels are.
// Cells tile the map, so a cell's box always takes that area;
// microrect extents overlap their neighbours' (n can be less than the extent of a solid surface), so a
// microrect of the depth map whose members all occlude keeps its box whole, as in the papers. A peeled layer
// (layer > 0) is sparse: its texels are what the layers in front hide, scattered over a microrect's extent,
// so there the members' count is measured against their own 2^l × 2^l block; and a partly covering coarse
// micro-occluder of a peeled layer is left out: shrunk on its own it no longer lines up with the
// one in front that hides the same occluder, and the two together doubled the occlusion of thin bars and
// slabs (thin at 2 layers: 0.30; level 0 and whole coarse cells still count). False: nothing occludes.
bool cover(Pixel p, int layer, int l, ivec2 c, vec2 centre, inout vec2 p0, inout vec2 p1) {
    vec4 s = cov_fetch(layer, l, c);       // mean, count, max, variance
    if (s.g <= 0.0) return false;
    float d = occluding_depth(p, p0, p1);
    float near = near_cluster(s, d).x;
    vec2 size = p1 - p0;
    float room = size.x * size.y;
#if PRIMITIVE == PRIMITIVE_MICRORECT
    if (near >= 1.0) {
        if (layer == 0) return true;
        vec2 b0 = vec2(c << l), block = max(min(b0 + float(1 << l), vec2(u_map_size)) - b0, vec2(0.0));
        room = min(room, block.x * block.y);
    }
#endif
    float share = min(near * s.g / max(room, 1e-30), 1.0);
    if (share >= 1.0) return true;
    if (layer > 0) return false;
    // Shrunk towards the occluding parts (`centre`): a box of side fraction f pressed against one side of
    // [p0, p1) has its centre 1 − f of the half side off the middle, so the offsets say how the share splits
    // between the axes (parts on one side of the cell: that axis alone; in a corner, or centred: both alike).
    vec2 offset = clamp(abs(centre - 0.5 * (p0 + p1)) / max(0.5 * size, vec2(1e-12)), 0.0, 0.99);
    vec2 lean = log(1.0 - offset);
    float split = lean.x + lean.y < -1e-4 ? lean.x / (lean.x + lean.y) : 0.5;
    vec2 fraction = exp(log(share) * vec2(split, 1.0 - split));
    vec2 half_size = 0.5 * size * fraction, mid = clamp(centre, p0 + half_size, p1 - half_size);
    p0 = mid - half_size;
    p1 = mid + half_size;
    return true;
}
#endif

#if SPLIT && COVERAGE
// Hidden occluders (ours). A coarse cell is tested at its nearest texel; when that texel lies on the
// receiver's own plane (the floor in front of a post's foot, seen from a light low over it: the floor comes
// nearer to the light than the post), the cell fails cell_occludes although the texels behind it, above the
// plane where they are, do occlude, and the post's foot leaks light (grazing at 128²: V 0.42 right behind
// the post, Cycles 0). Such a cell is left to the near-field split, which tests its parts one by one. A cell
// of the plane alone is told apart by its texels' mean depth (coverage statistics), which lies on the plane
// at the cell's middle; occluders above the plane pull the mean nearer. Only a cell nearer than the plane's
// deepest point in it can hold any occluder at all.
bool hides_occluders(Pixel p, int layer, int l, ivec2 c, float z, vec2 p0, vec2 p1) {
    if (l == 0 || !before_receiver(p, z) || !(z < receiver_depth_max(p, p0, p1))) return false;
    vec4 s = cov_fetch(layer, l, c);
    return s.g > 0.0 && s.r < receiver_depth_at(p.r, 0.5 * (p0 + p1));
}
#endif

vec2 window_at(Pixel p, vec2 pos) {
    return u_light_window.xz + pos * p.tex;
}

// Light coordinates of the window point w at depth z (§2.1 backprojection, see the header): [−1, 1]² is the
// bounding box of the receiver's footprint of the light.
vec2 backproject(Pixel p, vec2 w, float z) {
    return ((w - p.tp) * k_of(p, z) - p.fp.centre) / p.fp.half_box;
}

// The axis-aligned rectangle [a, b] through the midpoints of the edges of the quad v (v[0] = (0,0),
// v[1] = (1,0), v[2] = (0,1), v[3] = (1,1)): how a microquad or a tilted micro-occluder enters the bitmask
// (Schwarz & Stamminger 2007, §4, Fig. 6 right).
void midpoint_rect(vec2 v[4], out vec2 a, out vec2 b) {
    vec2 ml = 0.5 * (v[0] + v[2]), mr = 0.5 * (v[1] + v[3]);
    vec2 mb = 0.5 * (v[0] + v[1]), mt = 0.5 * (v[2] + v[3]);
    a = vec2(min(ml.x, mr.x), min(mb.y, mt.y));
    b = vec2(max(ml.x, mr.x), max(mb.y, mt.y));
}

#if REFIT == REFIT_PLANE
// Depth gap, as a share of the receiver's depth, that a tilted micro-occluder's corner keeps in front of the
// receiver where its plane reaches it (the surface meets the receiver: a wall's foot, a ball's contact).
const float CONTACT_GAP = 1e-3;

// Tilted coarse micro-occluder (REFIT_PLANE, ours). A coarse cell over a surface the light meets at a grazing
// angle (a wall's face, a ball's flank) spans a wide depth range; as one plate at one depth it stands out of
// that surface by up to the whole range, and next to the receiver 1/(d − z) magnifies the difference into a
// wrong share of the light: dark dashes along a wall's foot, light leaking under a ball. Tilted by its
// parts' depth slope, the plate follows the surface: each corner of [p0, p1) at the plane's depth through
// the mean z at the box centre, no nearer than the nearest part, no deeper than the receiver there nor than
// the plane reaches over the parts (slope.w); the quad backprojected as microquads are (the axis-aligned
// rectangle through its edges' midpoints, Schwarz & Stamminger 2007, §4, Fig. 6). A flat cell keeps the
// rectangle [a, b] it has. Without the parts' bound a steep plate (the face of a wall the light grazes, a
// ball's flank) ran on past them to the receiver's depth at a far corner, where 1/(d − z) backprojects it
// over the whole light: dark blotches inside penumbrae (slab at 128², level 4 forced: a 4 × 10 pixel blotch
// 0.2 too dark; mae_shadow by default 0.0129 → 0.0114, balls 0.0187 → 0.0173).
void backproject_tilted(Pixel p, vec2 p0, vec2 p1, float z, vec4 slope, inout vec2 a, inout vec2 b) {
    if (slope.x == 0.0 && slope.y == 0.0) return;
    vec2 mid = 0.5 * (p0 + p1);
    vec2 v[4];
    for (int i = 0; i < REFIT_CORNERS; ++i) {
        vec2 q = vec2((i & 1) == 0 ? p0.x : p1.x, (i >> 1) == 0 ? p0.y : p1.y);
        float deepest = min(min(receiver_depth_at(p.r, q), p.d) * (1.0 - CONTACT_GAP), slope.w);
        float zq = clamp(z + dot(slope.xy, q - mid), min(slope.z, deepest), deepest);
        v[i] = backproject(p, window_at(p, q), zq);
    }
    midpoint_rect(v, a, b);
}
#endif

#if REFIT != REFIT_NONE
// Centre clip (ours, with the coarse refits). A receiver the depth map sees has nothing between it and the
// light's centre, so no occluder's light rectangle may hold the centre (light coordinates 0). A coarse
// micro-occluder whose box holds the receiver's own map position (a cell across a wall's foot: the wall and
// the ground in front of it) does hold it, and next to the receiver covers the whole light. Its rectangle
// is cut at the centre on the side where the box lies, along the axis in which the box's middle is farthest
// from the receiver in units of the box's size.
void clear_centre(Pixel p, vec2 p0, vec2 p1, inout vec2 a, inout vec2 b) {
    vec2 c = p.centre_n;
    if (!p.centre_lit || any(greaterThanEqual(a, c)) || any(lessThanEqual(b, c))) return;
    vec2 off = (window_at(p, 0.5 * (p0 + p1)) - p.tp) / max(abs((p1 - p0) * p.tex), vec2(1e-12));
    int axis = abs(off.x) >= abs(off.y) ? 0 : 1;
    if (off[axis] >= 0.0) a[axis] = c[axis];
    else b[axis] = c[axis];
}
#endif

#if COLUMNS
uniform sampler2D u_exits;      // layer 0's solid exits pyramid (structures/solid_exits.py)

// The nearest exit and the deepest surface of the solid texels among [p0, p1) (the solid exits pyramid; none:
// x = NO_OCCLUDER): from the 2 × 2 cells of the finest level at which the rectangle spans at most two cells a
// side (a level-l cell's own rectangle: that cell alone).
vec2 exits_over(vec2 p0, vec2 p1) {
    ivec2 lo = ivec2(floor(p0)), hi = max(ivec2(ceil(p1)) - 1, lo);
    ivec2 side = hi - lo;
    int j = findMSB(max(side.x, side.y)) + 1;       // 2^j > the side (no loop: llvmpipe counts iterations)
    lo >>= j;
    hi >>= j;
    vec2 e = vec2(NO_OCCLUDER, 0.0);
    for (int i = 0; i < 4; ++i) {
        vec2 f = texelFetch(u_exits, min(lo + ivec2(i & 1, i >> 1), hi), j).rg;
        e = vec2(min(e.x, f.x), max(e.y, f.y));
    }
    return e;
}

// Solid column (ours). Where the depth map's surface is a closed caster's front face, the light centre's ray
// runs inside the solid until its exit, and the texel stands for that whole stretch of the ray: its rectangle
// [p0, p1] at every depth from its surface to the exit, no deeper than the receiver's plane there. A light
// point off the centre sees the solid's sides, which the depth map holds only as its near faces' outline (a
// post's side faces, along the centre's rays under a low light, hold no texel at all). The columns of a
// solid's texels fill it without gaps, so level-0 columns need no gap filling. A coarse micro-occluder is
// solid from the deepest surface to the nearest exit of the solid texels in its (refitted) rectangle; its
// plate in front stays as it was. The column's backprojection sweeps linearly from the rectangle `s0` at its
// near end to `s1` at its far end (both the centre and the size of a backprojected rectangle are linear in
// d/(d − z)); false where no stretch is solid.
bool solid_column(Pixel p, int layer, vec2 p0, vec2 p1, out vec4 s0, out vec4 s1) {
    if (layer != 0) return false;               // the exits are layer 0's
    vec2 e = exits_over(p0, p1);
    float x = min(e.x, occluding_depth(p, p0, p1));
    if (!(e.x < EMPTY_DEPTH && x > e.y)) return false;
    vec2 w0 = window_at(p, p0), w1 = window_at(p, p1);
    s0 = vec4(backproject(p, w0, e.y), backproject(p, w1, e.y));
    s1 = vec4(backproject(p, w0, x), backproject(p, w1, x));
    return true;
}
#endif

// Micropatch of cell c (level l): the cell's square at its (minimum) depth, parallel to the light. Gap
// filling (GBP06): when the left (bottom) neighbour is an occluder too, the patch's left (bottom) edge is
// extended to where that neighbour's right (top) edge backprojects, closing the gap between them. False
// when the cell occludes nothing (with `area` < 0 where it may hide occluders all the same, for the split to
// look inside: hides_occluders); else its light rectangle [a, b] and occluded fraction `area`, and (SPLIT)
// `whole`, the light rectangle of the whole cell before the refit and coverage shrink it (the split's test).
// `fill`: whether gap filling applies (see gather_range: not to a split's coarse parts). `col0`, `col1`: the
// ends of its solid column's sweep (solid_column; both [a, b] where it has none).
bool micropatch(Pixel p, int layer, int l, ivec2 c, bool fill, out vec2 a, out vec2 b, out float area,
                out vec4 whole, out vec4 col0, out vec4 col1) {
    float s = float(1 << l);
    float z = cell_depth(layer, l, c);
    vec2 p0 = vec2(c) * s, p1 = min(p0 + s, vec2(u_map_size));
    area = 0.0;
    col0 = col1 = vec4(0.0);
    bool occludes = cell_occludes(p, z, p0, p1, l);
#if SPLIT && COVERAGE
    if (!occludes && hides_occluders(p, layer, l, c, z, p0, p1)) area = -1.0;
#endif
#if SPLIT
    if (occludes || area < 0.0)
        whole = vec4(backproject(p, window_at(p, p0), z), backproject(p, window_at(p, p1), z));
#endif
    if (!occludes) return false;
#if REFIT != REFIT_NONE
    vec4 slope = vec4(0.0);
    vec2 centre;
    if (l > 0 && !refit(p, layer, l, c, z, p0, p1, slope, centre)) return false;
#else
    vec2 centre = 0.5 * (p0 + p1);
#endif
#if COVERAGE
    if (l > 0 && !cover(p, layer, l, c, centre, p0, p1)) return false;
#endif
    vec2 w0 = window_at(p, p0), w1 = window_at(p, p1);
    a = backproject(p, w0, z);
    b = backproject(p, w1, z);
#if REFIT == REFIT_PLANE
    if (l > 0) backproject_tilted(p, p0, p1, z, slope, a, b);
#endif
#if COLUMNS
    bool solid = solid_column(p, layer, p0, p1, col0, col1);
#else
    const bool solid = false;
#endif
#if GAP_FILL
    if (fill && !(solid && l == 0)) {
        float zl = cell_depth(layer, l, c - ivec2(1, 0));
        if (cell_occludes(p, zl, p0 - vec2(s, 0.0), vec2(p0.x, p1.y), l))
            a.x = min(a.x, backproject(p, w0, zl).x);
        float zb = cell_depth(layer, l, c - ivec2(0, 1));
        if (cell_occludes(p, zb, p0 - vec2(0.0, s), vec2(p1.x, p0.y), l))
            a.y = min(a.y, backproject(p, w0, zb).y);
    }
#endif
#if REFIT != REFIT_NONE
    if (l > 0) clear_centre(p, p0, p1, a, b);
#endif
    if (!solid) col0 = col1 = vec4(a, b);
#if NEED_AREA
    area = solid ? max(rect_area(a, b), sweep_area(col0.xy, col0.zw, col1)) : rect_area(a, b);
#endif
    return true;
}

#if PRIMITIVE == PRIMITIVE_MICRORECT
// Microrect of texel c (level l, §5.2): a micropatch over its own extent at its (minimum) depth; gap filling
// as for micropatches, towards the left/bottom neighbour microrect when its extent reaches this one's. At
// level 0 extent and depth are the texel's own, so this is exactly micropatch().
bool microrect(Pixel p, int layer, int l, ivec2 c, bool fill, out vec2 a, out vec2 b, out float area,
               out vec4 whole, out vec4 col0, out vec4 col1) {
    vec4 ext;
    float z = rect_depth(layer, l, c, ext);
    vec2 p0 = ext.xy, p1 = min(ext.zw, vec2(u_map_size));
    area = 0.0;
    col0 = col1 = vec4(0.0);
    bool occludes = cell_occludes(p, z, p0, p1, l);
#if SPLIT && COVERAGE
    if (!occludes && hides_occluders(p, layer, l, c, z, p0, p1)) area = -1.0;
#endif
#if SPLIT
    if (occludes || area < 0.0)
        whole = vec4(backproject(p, window_at(p, p0), z), backproject(p, window_at(p, p1), z));
#endif
    if (!occludes) return false;
#if REFIT != REFIT_NONE
    vec4 slope = vec4(0.0);
    vec2 centre;
    if (l > 0 && !refit(p, layer, l, c, z, p0, p1, slope, centre)) return false;
#else
    vec2 centre = 0.5 * (p0 + p1);
#endif
#if COVERAGE
    if (l > 0 && !cover(p, layer, l, c, centre, p0, p1)) return false;
#endif
    vec2 w0 = window_at(p, p0), w1 = window_at(p, p1);
    a = backproject(p, w0, z);
    b = backproject(p, w1, z);
#if REFIT == REFIT_PLANE
    if (l > 0) backproject_tilted(p, p0, p1, z, slope, a, b);
#endif
#if COLUMNS
    bool solid = solid_column(p, layer, p0, p1, col0, col1);
#else
    const bool solid = false;
#endif
#if GAP_FILL
    if (fill && !(solid && l == 0)) {
        vec4 el, eb;
        float zl = rect_depth(layer, l, c - ivec2(1, 0), el);
        if (el.z >= p0.x && cell_occludes(p, zl, el.xy, min(el.zw, vec2(u_map_size)), l))
            a.x = min(a.x, backproject(p, w0, zl).x);
        float zb = rect_depth(layer, l, c - ivec2(0, 1), eb);
        if (eb.w >= p0.y && cell_occludes(p, zb, eb.xy, min(eb.zw, vec2(u_map_size)), l))
            a.y = min(a.y, backproject(p, w0, zb).y);
    }
#endif
#if REFIT != REFIT_NONE
    if (l > 0) clear_centre(p, p0, p1, a, b);
#endif
    if (!solid) col0 = col1 = vec4(a, b);
#if NEED_AREA
    area = solid ? max(rect_area(a, b), sweep_area(col0.xy, col0.zw, col1)) : rect_area(a, b);
#endif
    return true;
}
#endif

// Microquad (§4) whose corners are the centres of cells c, c+(1,0), c+(0,1), c+(1,1): backprojected only
// when all four are occluders. Area accumulation: the quad with its corners clamped to the light rectangle
// (Fig. 6 left; watertight). Bitmask (and round lights): the axis-aligned rectangle through the midpoints of
// the quad's edges (Fig. 6 right). Returns like micropatch.
bool microquad(Pixel p, int layer, int l, ivec2 c, out vec2 a, out vec2 b, out float area, out vec4 whole) {
    float s = float(1 << l);
    vec2 v[4];
    area = 0.0;
    for (int i = 0; i < 4; ++i) {
        ivec2 ci = c + ivec2(i & 1, i >> 1);
        float z = cell_depth(layer, l, ci);
        vec2 p0 = vec2(ci) * s, p1 = min(p0 + s, vec2(u_map_size));
        vec2 pos = 0.5 * (p0 + p1);
        if (!cell_occludes(p, z, p0, p1, l)) return false;
        v[i] = backproject(p, window_at(p, pos), z);
    }
    // v[0] = (0,0), v[1] = (1,0), v[2] = (0,1), v[3] = (1,1)
    midpoint_rect(v, a, b);
#if NEED_AREA
    if (u_round == 1) {
        area = disk_fraction(a, b);
    } else {
        vec2 q0 = clamp(v[0], -1.0, 1.0), q1 = clamp(v[1], -1.0, 1.0);
        vec2 q3 = clamp(v[3], -1.0, 1.0), q2 = clamp(v[2], -1.0, 1.0);
        // Shoelace over the loop (0,0) → (1,0) → (1,1) → (0,1).
        float twice = (q0.x * q1.y - q1.x * q0.y) + (q1.x * q3.y - q3.x * q1.y)
                    + (q3.x * q2.y - q2.x * q3.y) + (q2.x * q0.y - q0.x * q2.y);
        area = abs(twice) * 0.5 * 0.25;
    }
#endif
    return true;
}

#if BITS > 0
// Light coordinates of bitmask sample (row l, column k); mirrors sample_positions() in
// engine/techniques/backprojection.py.
vec2 sample_position(int l, int k) {
    float n = float(BITS);
#if MULTI_JITTER
    return vec2(float(k) + (float(MJ_PERM[l]) + 0.5) / n, float(l) + (float(MJ_PERM[k]) + 0.5) / n) / n * 2.0 - 1.0;
#else
    return vec2((float(k) + u_jitter_x[l & 1]) / n, (float(l) + u_jitter_y[k & 1]) / n) * 2.0 - 1.0;
#endif
}

// Bitmask row l's samples that stand for points of the light: the light's shape (u_valid) for planar lights
// and suns; for a sphere, those inside this receiver's footprint ellipse, which touches the sides of the
// light coordinates' box [−1, 1]². `to_kernel` takes light coordinates to the kernel's unit disk.
uint valid_row(mat2 to_kernel, int l) {
    if (u_light_sphere == 0) return u_valid[l];
    uint m = 0u;
    for (int k = 0; k < BITS; ++k) {
        vec2 e = to_kernel * sample_position(l, k);
        if (dot(e, e) <= 1.0) m |= 1u << uint(k);
    }
    return m;
}
#endif

#if WEIGHTED
// Unoccluded contribution of light sample (row l, column k) at the receiver (light_view.glsl's
// light_sample_weight at the sample's light-plane point, with the shading normal: zero below the horizon).
float sample_weight(Pixel p, int l, int k) {
    return light_sample_weight(p.r, p.shading, p.fp.centre + p.fp.half_box * sample_position(l, k));
}
#endif

// ---- the three steps of a pixel ---------------------------------------------------------------------------
struct Result {
    float v;                    // visibility
    float cls;                  // CLASS_LIT, CLASS_UMBRA or CLASS_BACKPROJECTED
    float level;                // hierarchy level the micro-occluders came from
    float count;                // micro-occluders processed (all layers)
    float a_vis;                // 1 − accumulated area, unclamped (drives §3.1 post-filtering)
    vec3 rgb;                   // per-channel visibility of a textured light
};

Pixel make_pixel(ivec2 px) {
    Pixel p;
    p.r = pixel_receiver(px);
    p.r.bias = slope_scaled_bias(p.r);      // micro-occluders over a whole search area
    p.d = p.r.map.z;
    p.tex = map_texel_window();
    p.tp = window_coords(p.r.local);
    p.shading = view_direction(texelFetch(g_normal, px, 0).xyz);
    p.px = px;
    p.fp = light_footprint(p.r.local);
    p.centre_n = -p.fp.centre / p.fp.half_box;
#if REFIT != REFIT_NONE
    p.centre_lit = map_lit_plane(u_depth, ivec2(floor(p.r.map.xy)), p.r) > 0.5;
#else
    p.centre_lit = false;
#endif
    return p;
}

// ---- budget and level (Schwarz & Stamminger 2008, §4.2) ----------------------------------------------------
// b_mo at this pixel: uniform, falling linearly from the centre value to u_budget_border at the left and
// right image borders (the paper's Fig. 1d), or from an importance source (an image, objects), the larger of
// the two importances taking the budget from u_budget_low to u_budget.
float pixel_budget(ivec2 px) {
    if (u_budget_mode == BUDGET_IMPORTANCE) {
        float w = max(texelFetch(u_importance_image, px, 0).r, texelFetch(u_importance_objects, px, 0).r);
        return mix(u_budget_low, u_budget, clamp(w, 0.0, 1.0));
    }
    if (u_budget_mode == BUDGET_BORDER) {
        float t = abs((float(px.x) + 0.5) / float(u_image_size.x) * 2.0 - 1.0);
        return mix(u_budget, u_budget_border, t);
    }
    return u_budget;
}

// Microquads need one more cell per side than the area holds (the quads between cell centres).
const int QUAD_EXTRA = PRIMITIVE == PRIMITIVE_MICROQUAD ? 1 : 0;

// Integer level (2007): the finest whose grid covers [lo, hi] with at most b cells per side.
int integer_level(ivec2 lo, ivec2 hi, float b) {
    if (u_force_level >= 0) return min(u_force_level, u_levels - 1);
    if (u_budget_mode == BUDGET_UNBOUNDED) return 0;
    int l = 0;
    while (l < u_levels - 1 && any(greaterThan(vec2((hi >> l) - (lo >> l) + 1 + QUAD_EXTRA), vec2(b)))) ++l;
    return l;
}

// Fractional level ℓ (§4.2), continuous in the area's side n: log2(n / (b − 1 − extra)), so that ⌈ℓ⌉'s grid
// covers the area with at most b cells per side even where it straddles a cell boundary (one cell more
// than n / 2^⌈ℓ⌉); ℓ = 0 while the area fits at level 0.
float fractional_level(ivec2 lo, ivec2 hi, float b) {
    if (u_force_level >= 0) return float(min(u_force_level, u_levels - 1));
    if (u_budget_mode == BUDGET_UNBOUNDED) return 0.0;
    float n = float(max(hi.x - lo.x, hi.y - lo.y) + 1);
    return clamp(log2(n / max(b - 1.0 - float(QUAD_EXTRA), 1.0)), 0.0, float(u_levels - 1));
}

// The level a pixel will gather at for [lo, hi] (with blending: the coarser of its two levels).
int query_level(ivec2 lo, ivec2 hi, float b) {
#if LOQ == LOQ_INTEGER
    return integer_level(lo, hi, b);
#else
    // ℓ is a whole number exactly when the area's side is b − 1 − extra times a power of two; log2's last-bit
    // rounding must not push such a pixel one level up (separately compiled passes must agree).
    return int(ceil(fractional_level(lo, hi, b) - 1e-4));
#endif
}

#if GROW
// Over-precision fix (§6): the texels the level-j micro-occluders touching [lo, hi] read — whole level-j
// cells, one more per side for microquads (quads span neighbouring cell centres) and microrects (extents
// reach towards the neighbouring reference points).
void grow_to_support(inout ivec2 lo, inout ivec2 hi, int j) {
    int extra = PRIMITIVE == PRIMITIVE_MICROPATCH ? 0 : 1;
    lo = max(((lo >> j) - extra) << j, ivec2(0));
    hi = min((((hi >> j) + 1 + extra) << j) - 1, u_map_size - 1);
}
#endif

// Classify (§2.1, §5): the search area (pyramid ∩ near plane) as [lo, hi]; with a refinement, bound its
// depth range, classify, narrow the area to occluders no nearer than z_min, bound again (finer), classify
// and narrow once more before any micro-occluder is touched. Returns the class.
int classify(Pixel p, float budget, out ivec2 lo, out ivec2 hi) {
    bool inside = search_area(p, u_light_depth_range.x, lo, hi);
    int state = inside ? CLASS_BACKPROJECTED : CLASS_LIT;
#if REFINE != REFINE_NONE
    float d_biased = p.d - p.r.bias;
    bool own_inside = all(greaterThanEqual(p.r.map.xy, vec2(0.0))) && all(lessThan(p.r.map.xy, vec2(u_map_size)));
    for (int pass = 0; pass < 2 && state == CLASS_BACKPROJECTED; ++pass) {
        ivec2 qlo = lo, qhi = hi;
#if GROW
        grow_to_support(qlo, qhi, query_level(lo, hi, budget));
#endif
        vec2 zr = area_bound(qlo, qhi, pass);
        // The receiver plane's depth over the area: 1/z is linear in the window, so the corners bound it.
        float plo = d_biased, phi = d_biased;
        for (int i = 0; i < 4; ++i) {
            vec2 corner = vec2((i & 1) == 0 ? qlo.x : qhi.x + 1, (i >> 1) == 0 ? qlo.y : qhi.y + 1);
            float pz = receiver_depth_at(p.r, corner);
            plo = min(plo, pz);
            phi = max(phi, pz);
        }
        if (zr.x >= phi || zr.x >= p.d) state = CLASS_LIT;          // nothing nearer than the receiver
        // Umbra only for a pixel inside the map: a view holds every receiver a caster can shadow, so a pixel past
        // its edge is lit by design, and its search area, clipped to the edge, may hold only surfaces in front of
        // its plane that block none of its rays (a room's walls, concave around it: fuzz 30119, 13 pixels at V 0
        // that Cycles has lit). Asking for the whole area inside the map instead lost the umbra of a light almost
        // touching its caster, whose area reaches far past the map (tests/test_extreme.py near_light: V 0.998).
        else if (zr.y < plo && own_inside) state = CLASS_UMBRA;     // everything nearer, no gap
        else if (!search_area(p, zr.x, lo, hi)) state = CLASS_LIT;
    }
#endif
    return state;
}

// Micro-occluders a level-l gather over [lo, hi] visits, all layers: micropatches and microrects the area's
// cells, microquads the quads between the centres of its cells and their neighbours (one more per side).
int gather_cells(ivec2 lo, ivec2 hi, int l) {
    ivec2 n = (hi >> l) - (lo >> l) + 1 + QUAD_EXTRA;
    return n.x * n.y * LAYERS;
}

Occlusion no_occlusion() {
    Occlusion o;
    o.area = 0.0;
#if BITS > 0
    for (int i = 0; i < BITS; ++i) o.bits[i] = 0u;
#endif
    return o;
}

// Add micro-occluders [i0, i1) of the level-l gather over [lo, hi] (numbered layer by layer, row by row) to
// `o`. One loop over a flat index, and the bitmask rows in a loop of constant length (which the compiler
// unrolls): a software GL that ends a shader's loops after a fixed number of iterations in all (llvmpipe:
// 65535) then sees one iteration per micro-occluder, and CHUNKED can bound what one dispatch asks for.
// OR the light rectangle [a, b] (occluded fraction `area`) into `o`: a macro, not a function, so that the
// bitmask is not copied per micro-occluder (bitmask rows outside the span OR zero).
#if BITS > 0
#define ADD_OCCLUDER(o, a, b, ar) { (o).area += (ar); Span s_ = rect_span((a) * 0.5 + 0.5, (b) * 0.5 + 0.5); if (s_.rows.x < s_.rows.y) for (int r_ = 0; r_ < BITS; ++r_) (o).bits[r_] |= span_row(s_, r_); }
// The same for a rectangle swept from [a, b] to back's (solid columns): only the rows its hull reaches.
#define ADD_SWEEP(o, a, b, back, ar) { (o).area += (ar); Sweep w_ = Sweep((a) * 0.5 + 0.5, (b) * 0.5 + 0.5, (back).xy * 0.5 + 0.5, (back).zw * 0.5 + 0.5); int r0_ = int(floor(min(w_.a0.y, w_.a1.y) * float(BITS))) - 1, r1_ = int(ceil(max(w_.b0.y, w_.b1.y) * float(BITS))) + 1; for (int r_ = 0; r_ < BITS; ++r_) if (r_ >= r0_ && r_ < r1_) (o).bits[r_] |= sweep_row(w_, r_); }
#else
#define ADD_OCCLUDER(o, a, b, ar) { (o).area += (ar); }
#define ADD_SWEEP(o, a, b, back, ar) { (o).area += (ar); }
#endif
// A micro-occluder: its rectangle [a, b], and where it is solid (solid_column) the sweep from col0 to col1 (at
// level 0 the rectangle is col0 and only the sweep is added).
#if COLUMNS
#define ADD_MICRO_OCCLUDER(o, a, b, col0, col1, area) { if ((col0) == (col1)) ADD_OCCLUDER(o, a, b, area) else { if (vec4((a), (b)) != (col0)) ADD_OCCLUDER(o, a, b, 0.0) ADD_SWEEP(o, (col0).xy, (col0).zw, col1, area) } }
#else
#define ADD_MICRO_OCCLUDER(o, a, b, col0, col1, area) ADD_OCCLUDER(o, a, b, area)
#endif

#if SPLIT && PRIMITIVE != PRIMITIVE_MICROQUAD
// Loop iterations one split part of level f costs, which u_split_extra counts (llvmpipe's loop limit,
// engine/gpu/loops.py): its own, and when f > 0 the coarse refit's (REFIT_ITERATIONS, from
// techniques/backprojection.py refit_iterations). A cap on parts alone let parts of level 1 and above take a
// split gather past the limit: bp_split 0.1 on tilted at 128² came out in light streaks (mae_shadow 0.041,
// 0.017 counted).
int part_iterations(int f) {
    return f == 0 ? 1 : 1 + REFIT_ITERATIONS;
}
#endif

void gather_range(Pixel p, ivec2 lo, ivec2 hi, int l, int i0, int i1, inout Occlusion o, inout float count) {
    if (i1 <= i0) return;
    ivec2 first = (lo >> l) - QUAD_EXTRA, last = hi >> l;
    ivec2 n = last - first + 1;
    int per_layer = n.x * n.y;
    // The first cell by division, the rest by stepping (integer division is slow on a CPU's vectors).
    int layer = i0 / per_layer, j = i0 - layer * per_layer;
    ivec2 c = first + ivec2(j % n.x, j / n.x);
#if SPLIT && PRIMITIVE != PRIMITIVE_MICROQUAD
    int extra = u_split_extra;
#endif
    for (int i = i0; i < i1; ++i) {
        vec2 a, b;
        float area;
        vec4 whole, col0, col1;
#if PRIMITIVE == PRIMITIVE_MICROPATCH
        bool hit = micropatch(p, layer, l, c, true, a, b, area, whole, col0, col1);
#elif PRIMITIVE == PRIMITIVE_MICRORECT
        bool hit = microrect(p, layer, l, c, true, a, b, area, whole, col0, col1);
#else
        bool hit = microquad(p, layer, l, c, a, b, area, whole);
        col0 = col1 = vec4(a, b);
#endif
#if SPLIT && PRIMITIVE != PRIMITIVE_MICROQUAD
        // Near-field split (ours): a coarse micro-occluder stands for its texels only as far as its error
        // (about its whole extent) is small on the light; backprojected, a cell grows as 1/(d − z), so next to
        // the receiver (contact shadows, the ground at a wall's foot, a surface beside the receiver that the
        // cell lifts above its horizon) one cell spans much of the light and its error is the penumbra. Such a
        // cell (judged whole, before refit and coverage) is replaced by the micro-occluders of the level f
        // whose cells are k = l − f halvings smaller, enough to bring it under u_split of the light's side:
        // micropatches the 2^k × 2^k cells of level f inside it, microrects the level-f microrects whose
        // reference texel lies in its extent (level 0: exactly its texels). One flat loop, no stack (a local
        // array made every gather ~5× slower on llvmpipe); u_split_extra caps the parts per gather. A cell
        // whose nearest texel lies on the receiver's plane but that may hide occluders (area < 0,
        // hides_occluders) splits the same way.
        int k = 0;
        if ((hit || area < 0.0) && l > 0 && all(lessThan(whole.xy, vec2(1.0)))
            && all(greaterThan(whole.zw, vec2(-1.0)))) {
            float wide = max(whole.z - whole.x, whole.w - whole.y) / (2.0 * u_split);
            k = wide > 1.0 ? min(int(ceil(log2(wide))), l) : 0;
        }
        ivec2 s0 = ivec2(0), s1 = ivec2(-1);
#if PRIMITIVE == PRIMITIVE_MICRORECT
        vec4 ext;                       // the microrect's extent, which its parts at every level lie in
        if (k > 0) rect_depth(layer, l, c, ext);
#endif
        for (; k > 0; --k) {            // the finest level whose parts the cap still allows
            int f = l - k;
#if PRIMITIVE == PRIMITIVE_MICRORECT
            s0 = (ivec2(ext.xy) + (1 << f) - 1) >> f;
            s1 = (ivec2(ext.zw) + (1 << f) - 1 >> f) - 1;
#else
            s0 = c << k;
            s1 = min(((c + 1) << k) - 1, ((u_map_size + (1 << f) - 1) >> f) - 1);
#endif
            ivec2 m = max(s1 - s0 + 1, ivec2(0));
            if (m.x * m.y * part_iterations(f) <= extra) break;
        }
        if (any(lessThan(s1, s0))) k = 0;       // no parts found: keep the micro-occluder whole
        if (k > 0) {
            int f = l - k;
            int nx = s1.x - s0.x + 1, parts = nx * (s1.y - s0.y + 1);
            extra -= parts * part_iterations(f);
            count += float(parts);
            // The parts are gap-filled only at level 0. A coarse part, shrunk to its occluding share and
            // tilted, no longer ends at its cell's edge, nor does its neighbour; next to the receiver, where
            // the split works, filling towards the neighbour's edge at the neighbour's minimum depth covered
            // light no part occludes (at 128², suzanne 0.0152 → 0.0136, balls 0.0173 → 0.0161, slab 0.0114 →
            // 0.0105; grazing 0.0143 → 0.0145, no scene worse by more than 1.4 %). Unsplit coarse cells keep
            // it: small on the light, their fills close the gaps between neighbours (without: light stripes
            // across grazing's bar shadow, 0.0143 → 0.0169).
            bool fill = f == 0;
            for (int q = 0; q < parts; ++q) {
                ivec2 jq = s0 + ivec2(q % nx, q / nx);
#if PRIMITIVE == PRIMITIVE_MICRORECT
                bool h = microrect(p, layer, f, jq, fill, a, b, area, whole, col0, col1);
#else
                bool h = micropatch(p, layer, f, jq, fill, a, b, area, whole, col0, col1);
#endif
                if (h) ADD_MICRO_OCCLUDER(o, a, b, col0, col1, area);
            }
        } else
#endif
        if (hit) ADD_MICRO_OCCLUDER(o, a, b, col0, col1, area);
        if (++c.x > last.x) {
            c.x = first.x;
            if (++c.y > last.y) {
                c.y = first.y;
                ++layer;
            }
        }
    }
}

#if CHUNKED
// A pixel's gathers (one level, or ⌊ℓ⌋ then ⌈ℓ⌉ when blending) split over u_chunks dispatches of at most
// u_chunk_size micro-occluders each (the loop limit above); between them the occlusion of each gather
// ("slot") waits in u_state: BITS words of bitmask, then the area's bits.
layout(std430, binding = 4) buffer State { uint u_state[]; };
uniform int u_chunk;            // this dispatch, 0 … u_chunks − 1
uniform int u_chunks;
uniform int u_chunk_size;
const int SLOTS = LOQ == LOQ_BLEND ? 2 : 1;

int state_base(ivec2 px, int slot) {
    return ((px.y * u_image_size.x + px.x) * SLOTS + slot) * (BITS + 1);
}

Occlusion load_state(ivec2 px, int slot) {
    Occlusion o = no_occlusion();
    if (u_chunk == 0) return o;
    int base = state_base(px, slot);
#if BITS > 0
    for (int i = 0; i < BITS; ++i) o.bits[i] = u_state[base + i];
#endif
    o.area = uintBitsToFloat(u_state[base + BITS]);
    return o;
}

void store_state(ivec2 px, int slot, Occlusion o) {
    int base = state_base(px, slot);
#if BITS > 0
    for (int i = 0; i < BITS; ++i) u_state[base + i] = o.bits[i];
#endif
    u_state[base + BITS] = floatBitsToUint(o.area);
}
#endif

// Gather (§4, §5): every micro-occluder of every layer over [lo, hi] on the grid of level l, into gather
// `slot` of the pixel; adds the micro-occluders to `count`. CHUNKED: only this dispatch's share of them,
// `start` being where this gather begins in the pixel's list (advanced past it).
Occlusion gather(Pixel p, ivec2 lo, ivec2 hi, int l, inout float count, int slot, inout int start) {
    int n = gather_cells(lo, hi, l);
    count += float(n);
#if CHUNKED
    Occlusion o = load_state(p.px, slot);
    int w0 = u_chunk * u_chunk_size - start;
    gather_range(p, lo, hi, l, clamp(w0, 0, n), clamp(w0 + u_chunk_size, 0, n), o, count);
    store_state(p.px, slot, o);
#else
    Occlusion o = no_occlusion();
    gather_range(p, lo, hi, l, 0, n, o, count);
#endif
    start += n;
    return o;
}

// Resolve (§3, §3.3): visibility from the gathered occlusion — unset valid bits / valid bits, weighted by
// the light's colour and/or each sample's unoccluded contribution; or GBP06's area, clamped to 1.
void resolve(Pixel p, Occlusion o, inout Result res) {
    res.a_vis = 1.0 - o.area;
#if BITS > 0
    // Samples outside the light's shape never count.
    uint valid[BITS];
    float lit = 0.0, count = 0.0;
    mat2 to_kernel = u_light_sphere == 0 ? mat2(1.0)          // only a sphere's mask is per pixel (valid_row)
                   : inverse(p.fp.axes) * mat2(p.fp.half_box.x, 0.0, 0.0, p.fp.half_box.y);
    for (int i = 0; i < BITS; ++i) {
        valid[i] = valid_row(to_kernel, i);
        lit += float(bitCount(valid[i] & ~o.bits[i]));
        count += float(bitCount(valid[i]));
    }
    res.v = lit / max(count, 1.0);
#if TEXTURED || WEIGHTED
    vec4 sum_lit = vec4(0.0), sum_all = vec4(0.0);
    for (int i = 0; i < BITS; ++i) {
        uint m = valid[i];
        while (m != 0u) {
            int k = findLSB(m);
            m &= m - 1u;
#if TEXTURED
            vec4 w = texelFetch(u_sample_color, ivec2(k, i), 0);
#else
            vec4 w = vec4(1.0);
#endif
#if WEIGHTED
            w *= sample_weight(p, i, k);
#endif
            sum_all += w;
            if ((o.bits[i] & (1u << uint(k))) == 0u) sum_lit += w;
        }
    }
    if (sum_all.a > 0.0) res.v = sum_lit.a / sum_all.a;      // luminance-weighted scalar visibility
#if TEXTURED
    res.rgb = sum_lit.rgb / max(sum_all.rgb, vec3(1e-30));  // 1e-30: a channel the light does not emit
#endif
#endif
#else
    res.v = clamp(res.a_vis, 0.0, 1.0);
#if TEXTURED
    res.rgb = vec3(res.v);
#endif
#endif
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
#if LOQ == LOQ_WRITE
    imageStore(u_loq_out, px, vec4(-1.0, 0.0, -1.0, 0.0));     // no backprojection unless found below
#endif
    if (!pixel_lit(px)) {
        imageStore(u_visibility, px, vec4(1.0));
        imageStore(u_info, px, vec4(float(CLASS_UNREACHED), 0.0, 0.0, 1.0));
#if TEXTURED
        imageStore(u_rgb, px, vec4(1.0));
#endif
        return;
    }
    Pixel p = make_pixel(px);
    Result res = Result(1.0, float(CLASS_LIT), 0.0, 0.0, 1.0, vec3(1.0));
    if (u_delta == 1) {
        // A light without extent: the plain hard shadow-map test.
        float v = map_lit_plane(u_depth, ivec2(floor(p.r.map.xy)), p.r);
        res = Result(v, float(v > 0.5 ? CLASS_LIT : CLASS_UMBRA), 0.0, 0.0, v, vec3(v));
    } else {
        ivec2 lo, hi;
        float budget = pixel_budget(px);
        int cls = classify(p, budget, lo, hi);
#if LOQ == LOQ_WRITE
        // Pass 1 (§4.2): the LOQ map — ℓ of backprojecting pixels, −1 elsewhere (the smoothing stops there),
        // beside the camera depth (G-buffer) the smoothing compares: it stops at the image's depth edges, not
        // at the light's (a silhouette over a far background can be at one light depth; a surface the light
        // grazes changes light depth fast without any edge).
        float ell = cls == CLASS_BACKPROJECTED ? fractional_level(lo, hi, budget) : -1.0;
        imageStore(u_loq_out, px, vec4(ell, texelFetch(g_normal, px, 0).w, ell, 0.0));
        return;
#else
        if (cls == CLASS_UMBRA) {
            res = Result(0.0, float(CLASS_UMBRA), 0.0, 0.0, 0.0, vec3(0.0));
        } else if (cls == CLASS_BACKPROJECTED) {
            res.cls = float(CLASS_BACKPROJECTED);
#if LOQ == LOQ_BLEND
            // Pass 3 (§4.2): always blend the visibility of ⌊ℓ⌋ and ⌈ℓ⌉ by ℓ's fraction (no Δℓ band).
            float ell = texelFetch(u_loq, px, 0).r;
            if (ell < 0.0) ell = fractional_level(lo, hi, budget);
            int l0 = int(floor(ell)), l1 = min(l0 + 1, u_levels - 1);
            float f = l1 > l0 ? ell - float(l0) : 0.0;
            res.level = ell;
            int start = 0;
            Occlusion o0 = gather(p, lo, hi, l0, res.count, 0, start);
            Occlusion o1 = o0;
            if (f > 0.0) o1 = gather(p, lo, hi, l1, res.count, 1, start);
#if CHUNKED
            if (u_chunk < u_chunks - 1) return;
#endif
            resolve(p, o0, res);
            if (f > 0.0) {
                Result r1 = res;
                resolve(p, o1, r1);
                res.v = mix(res.v, r1.v, f);
                res.a_vis = mix(res.a_vis, r1.a_vis, f);
                res.rgb = mix(res.rgb, r1.rgb, f);
            }
#else
            int l = integer_level(lo, hi, budget);
            res.level = float(l);
            int start = 0;
            Occlusion o = gather(p, lo, hi, l, res.count, 0, start);
#if CHUNKED
            if (u_chunk < u_chunks - 1) return;
#endif
            resolve(p, o, res);
#endif
        }
#endif
    }
    imageStore(u_visibility, px, vec4(clamp(res.v, 0.0, 1.0)));
    imageStore(u_info, px, vec4(res.cls, res.level, res.count, res.a_vis));
#if TEXTURED
    imageStore(u_rgb, px, vec4(clamp(res.rgb, 0.0, 1.0), 1.0));
#endif
}
