// PVSM, fixed-resolution mode: Shen, Guennebaud, Yang & Feng, "Predicted Virtual Soft Shadow Maps with High
// Quality Filtering" (2011), §4 (PCSS revisited), §4.1 (smooth convolution), §4.2 (anisotropic anti-aliasing)
// and §5.1 (perceptual resolution, here choosing the level of one map's min/max pyramid instead of a tile).
//
// Units: map positions are level-0 texels of the filtering map; window coordinates are tangents at unit depth
// (perspective) or metres (a sun's ortho view), as in common/light_view.glsl.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#ifndef WEIGHTED
#define WEIGHTED 0      // 1: each texel's share weighted by the irradiance its light sub-rectangle carries
#endif
#ifndef INFO
#define INFO 0          // 1: write the debug/statistics image
#endif
// MODE 0: fixed resolution (one map, V straight into u_visibility). The adaptive mode (§5.2) runs three:
// MODE 1 (steps 3–4): z-averaging into the kernel shape buffer and the predicted texel size of every pixel
//        into the shadow map tile grid (min by atomics);
// MODE 2 (step 8): one tile's filtering, adding its Σ V·A and Σ A to the merge buffer;
// MODE 3: the merge, V = Σ V·A / Σ A.
#ifndef MODE
#define MODE 0
#endif
// 1: kernel_sums runs a share of its cells per dispatch (llvmpipe ends an invocation's loops after 65535
// iterations in all; engine/gpu/loops.py). MODE 0 keeps its running sums in u_partial; MODE 2 adds each
// share to the merge buffer, which is a sum anyway.
#ifndef CHUNKED
#define CHUNKED 0
#endif
#if CHUNKED
uniform int u_chunk;
uniform int u_chunks;
uniform int u_chunk_size;
#if MODE == 0
layout(rgba32f, binding = 3) uniform image2D u_partial;         // occluded weight, total weight, cells
#endif
#endif

// The "low-resolution map" of §4 step 3 and three coarser ones, each halving (glsl/pvsm/reduce.comp): every
// cell the minimum depth of the search-map texels it covers.
uniform sampler2D u_search0;
uniform sampler2D u_search1;
uniform sampler2D u_search2;
uniform sampler2D u_search3;
uniform int u_fine_block;         // search-map texels per cell of u_search0
uniform vec2 u_search_scale;      // search-map texels per filtering-map texel
uniform sampler2D u_depth_map;    // the filtering map
uniform int u_filter_levels;      // levels of its (virtual) pyramid: level l keeps every 2^l-th texel
uniform int u_cap;                // most texels per axis one kernel loop visits: a coarser level beyond it
uniform int u_sub;                // depth tests per axis in a cell of a level coarser than the map's own
uniform float u_max_radius;       // cap on the search half extent, level-0 texels
uniform int u_skip_lit;
uniform int u_outside_lit;        // 1: every caster lies inside the map, so past its edge nothing occludes
uniform int u_aa;
uniform int u_rho;                // 0: finest level under the cap; 1: ρ_dynamic; 2: ρ_static; 3: linear in log2 n
uniform mat4 u_inv_view_proj;     // camera clip → world
#if MODE == 0 || MODE == 3
layout(r32f, binding = 0) uniform writeonly image2D u_visibility;
#endif
layout(rgba32f, binding = 1) uniform writeonly image2D u_info;   // class, level, screen size n, texels visited
// Adaptive mode. Tile pass coordinates are the tile's own map texels (its LightView's uniforms); the virtual
// map it is a window of spans u_virtual_lo … u_virtual_hi in them.
#if MODE == 1
layout(rgba32f, binding = 0) uniform writeonly image2D u_kernel;  // z_avg, blocker weight, texel size, class
layout(r32ui, binding = 2) uniform coherent uimage2D u_grid;      // tile grid pyramid, packed (see pvsm.py)
uniform float u_grid_cell;        // search-map texels per level-0 grid cell
uniform int u_grid_size;          // level-0 cells per axis (a power of two)
#endif
#if MODE == 2 || MODE == 3
uniform sampler2D u_kernel;
#endif
#if MODE == 2
layout(rgba32f, binding = 0) uniform image2D u_merge;              // Σ V·A, Σ A, texels visited
#endif
#if MODE == 3
uniform sampler2D u_merge;
#endif
uniform vec4 u_clip;              // x0, y0, x1, y1: the part of the kernel this map owns (texels)
uniform vec2 u_virtual_lo;        // the virtual map's extent (texels of this map)
uniform vec2 u_virtual_hi;
uniform float u_area_scale;       // this map's texel area in level-0 search-map texels (merge units)

const float TINY = 1e-4;          // texels: the smallest kernel half extent (a hard test of one texel)

Receiver g_r;
float g_depth;                    // receiver depth less its bias
int g_visited;
vec2 g_light_e;                   // half extent of the light filter alone (texels)
vec2 g_pad;                       // half extent of the pixel footprint on the map (texels), 0 without AA
float g_blocker_depth;            // the kernel's blocker plane (z-average), set by soft_kernel
vec3 g_n;                         // shading normal in the view's frame (a sun's weights)
// The part of the light this pixel's kernels stand for, on the view's light plane (metres; tangents for a
// sun): u_kernel_half about the axis, or under a spot's cone narrower than its ball the disk of the ball the
// receiver sees (light_view.glsl light_footprint, as PCSS takes it; ours, fuzz 30111), taken as its square.
// SPOT_CLIP (pvsm.py: a spot's own view with u_spot_cone set) compiles that in; without it every kernel is
// centred on its receiver, as before.
#ifndef SPOT_CLIP
#define SPOT_CLIP 0
#endif
uniform vec2 u_kernel_half;       // the light's half extent as a box kernel (a round light's of its variance)
uniform float u_round_box;        // that box's half extent for a disk of radius 1 (pvsm.py ROUND_BOX)
vec2 g_light_half;
vec2 g_light_centre;
bool g_spot_clipped;              // the part is a spot's clipped disk: weights take the cone (kernel_sums)

void set_light_part(vec3 local) {
    g_light_half = u_kernel_half;
    g_light_centre = vec2(0.0);
    g_spot_clipped = false;
#if SPOT_CLIP
    Footprint f = light_footprint(local);
    g_spot_clipped = f.cone_clipped;
    if (f.cone_clipped) {
        g_light_half = f.half_box * u_round_box;
        g_light_centre = f.centre;
    }
#endif
}

// Receiver depths to compare a search cell [lo, hi] (level-0 texels) against: the receiver plane's nearest
// and farthest points over the cell (its corners), less the bias. Nearer than the nearest, the cell's minimum
// is a blocker wherever in the cell it lies; nearer than the farthest only, it may be one (or the receiver's
// own surface, where the plane runs steeply through the cell: a grazing receiver).
vec2 depth_for_cell(vec2 lo, vec2 hi) {
    vec4 d = vec4(receiver_depth_at(g_r, lo), receiver_depth_at(g_r, hi),
                  receiver_depth_at(g_r, vec2(lo.x, hi.y)), receiver_depth_at(g_r, vec2(hi.x, lo.y)));
    return vec2(min(min(d.x, d.y), min(d.z, d.w)), max(max(d.x, d.y), max(d.z, d.w)));
}

// Cells of level l of a pyramid (llvmpipe's textureSize(sampler, lod) answers level 0's size here).
ivec2 level_cells(ivec2 size0, int l) {
    return max(size0 >> l, ivec2(1));
}

ivec2 search_cells(int l) {
    return l == 0 ? textureSize(u_search0, 0) : l == 1 ? textureSize(u_search1, 0)
         : l == 2 ? textureSize(u_search2, 0) : textureSize(u_search3, 0);
}

float search_min(int l, ivec2 t) {
    return l == 0 ? texelFetch(u_search0, t, 0).r : l == 1 ? texelFetch(u_search1, t, 0).r
         : l == 2 ? texelFetch(u_search2, t, 0).r : texelFetch(u_search3, t, 0).r;
}

// Coarsest level needed so that a kernel of half extent e (level-0 texels) spans at most u_cap cells.
int cap_level(float e, int levels) {
    float l = ceil(log2(max(2.0 * e / float(u_cap), 1.0)));
    return clamp(int(l), 0, levels - 1);
}

// Eq. 1's α as a half extent in texels of the light filter: h·(1/z_o − 1/z_y) tangents (perspective; the
// paper's (z_y − z_o)·z_n/(z_y·z_o) at the map plane z_n) or tan(angle/2)·(z_y − z_o) metres (sun).
float filter_spread(float zo, float zy) {
    return u_light_ortho == 1 ? max(zy - zo, 0.0) : max(1.0 / max(zo, 1e-30) - 1.0 / zy, 0.0);
}

vec2 filter_half_texels(float zo, float zy) {
    return g_light_half * filter_spread(zo, zy) / u_texel_tan;
}

// Where the light–receiver pyramid's section at depth zo is centred, relative to the receiver (texels): the
// light part's centre seen through that depth (0 for a light about the view's axis).
vec2 filter_centre_texels(float zo, float zy) {
#if SPOT_CLIP
    return g_light_centre * filter_spread(zo, zy) / u_texel_tan;
#else
    return vec2(0.0);
#endif
}

// ---- §4 step 3: z-averaging over the low-resolution map --------------------------------------------------
// Mean depth of the blockers around c (search-map texels) within the search box c ± e. The paper (like PCSS)
// counts every texel of the box nearer than the receiver; we keep only cells that can hide part of the light,
// i.e. that reach into the light–receiver pyramid at their own depth (c ± α(z_min)·h): a wall beside the
// receiver or geometry at the map's edge is then not averaged in. Each cell is weighted by its overlap with
// that pyramid's section (below), so the mean, and with it the filter size, moves smoothly. Cells that are
// blockers wherever their minimum lies make the mean; when there are none, the cells that may be blockers
// (depth_for_cell) make it instead: a coarse cell across a receiver turned from the light spans more depth
// than the gap to an occluder just in front of it, and skipping such a pixel as fully lit lost that shadow
// (fuzz seed 9: 0.32 → 0.16; tests/test_pvsm.py close_occluder_before_a_slope). The filter's per-texel tests
// (the plane at each texel) then find the occluder or reject the receiver's own surface.
// Returns (mean depth, blocker weight); weight 0: no blocker.
// With anti-aliasing the pixel's footprint (half extent `pad`) widens both, so that a pixel whose footprint
// reaches a shadow is not skipped as fully lit.
vec2 average_blockers(vec2 c, vec2 e, vec2 pad) {
    e += pad;
    vec2 receiver = g_r.map.xy * u_search_scale;
    // The finest level whose cells the box spans at most u_cap times (the coarsest one past that).
    int l = 0;
    int cap = min(u_cap, PVSM_SEARCH_CELLS - 2);
    while (l < 3 && 2.0 * max(e.x, e.y) > float(cap * (u_fine_block << l))) ++l;
    float s = float(u_fine_block << l);
    ivec2 cells = search_cells(l);
    ivec2 i0 = max(ivec2(floor((c - e) / s)), ivec2(0));
    ivec2 i1 = min(ivec2(floor((c + e) / s)), cells - 1);
    // The loop limit (engine/gpu/loops.py): a box wider than PVSM_SEARCH_CELLS cells of the coarsest level
    // is cut to that many around c, as far as the map allows (pvsm.py warns where it can happen).
    ivec2 ci = ivec2(floor(c / s));
    i0 = max(i0, min(ci - PVSM_SEARCH_CELLS / 2, i1 - PVSM_SEARCH_CELLS + 1));
    i1 = min(i1, i0 + PVSM_SEARCH_CELLS - 1);
    float sum = 0.0, weight = 0.0, maybe_sum = 0.0, maybe_weight = 0.0;
    for (int j = i0.y; j <= i1.y; ++j) {
        for (int i = i0.x; i <= i1.x; ++i) {
            ++g_visited;
            float zmin = search_min(l, ivec2(i, j));
            vec2 dc = depth_for_cell(vec2(i, j) * s / u_search_scale, vec2(i + 1, j + 1) * s / u_search_scale);
            if (!(zmin < dc.y))
                continue;
            vec2 reach = min(max(filter_half_texels(zmin, g_depth) * u_search_scale, vec2(0.5)) + pad, e);
            vec2 at = receiver + filter_centre_texels(zmin, g_depth) * u_search_scale;    // the section's centre
            vec2 w = min(vec2(i + 1, j + 1) * s, at + reach) - max(vec2(i, j) * s, at - reach);
            if (w.x > 0.0 && w.y > 0.0) {
                // Each cell weighs the share of the pyramid's section it fills, i.e. the share of the light it
                // hides: a layer that hides all of it counts 1 whatever its depth (a plain texel count would
                // favour blockers near the light, whose sections are wider, and over-blur).
                float area = max(w.x * w.y / (4.0 * reach.x * reach.y), 1e-12);
                if (zmin < dc.x) {
                    sum += area * zmin;
                    weight += area;
                } else {
                    maybe_sum += area * zmin;
                    maybe_weight += area;
                }
            }
        }
    }
    if (weight > 0.0) return vec2(sum / weight, weight);
    return vec2(maybe_weight > 0.0 ? maybe_sum / maybe_weight : 0.0, maybe_weight);
}

// ---- §4.2: pixel footprint -----------------------------------------------------------------------------
// Where the camera ray through NDC point `ndc` meets the receiver's tangent plane (p, n), in map texels.
// Near-parallel rays are held at 80 × the pixel's own distance so the axis stays finite.
vec2 footprint_point(vec2 ndc, vec3 p, vec3 n, out bool ok) {
    vec4 a = u_inv_view_proj * vec4(ndc, -1.0, 1.0), b = u_inv_view_proj * vec4(ndc, 1.0, 1.0);
    vec3 o = a.xyz / a.w, dir = b.xyz / b.w - o;
    float len = length(dir);
    dir /= max(len, 1e-30);
    float den = dot(dir, n);
    float reach = 80.0 * length(p - o);
    float t = abs(den) > 1e-6 ? dot(p - o, n) / den : reach;
    ok = t > 0.0 && t < reach && abs(den) > 1e-6;
    t = clamp(t, 0.0, reach);
    return map_coords(light_local(o + dir * t)).xy;
}

// The pixel's half axes (u_φ, v_φ) in map texels, through the receiver's tangent plane (Fig. 5).
mat2 pixel_footprint(ivec2 px, vec3 p, vec3 n) {
    vec2 ndc = (vec2(px) + 0.5) / vec2(u_image_size) * 2.0 - 1.0;
    vec2 d = 1.0 / vec2(u_image_size);          // half a pixel in NDC
    bool ok0, ok1, ok2, ok3;
    vec2 ux = footprint_point(ndc + vec2(d.x, 0.0), p, n, ok0) - footprint_point(ndc - vec2(d.x, 0.0), p, n, ok1);
    vec2 vy = footprint_point(ndc + vec2(0.0, d.y), p, n, ok2) - footprint_point(ndc - vec2(0.0, d.y), p, n, ok3);
    mat2 m = mat2(0.5 * ux, 0.5 * vy);
    // A grazing axis can reach far across the map: bound each to a quarter of the map.
    float cap = 0.25 * float(max(u_map_size.x, u_map_size.y));
    for (int k = 0; k < 2; ++k) {
        float l = length(m[k]);
        if (!(l <= EMPTY_DEPTH)) m[k] = vec2(0.0);         // NaN or Inf
        else if (l > cap) m[k] *= cap / l;
    }
    return m;
}

// Appendix `convolve`: the Gaussian of variance Σ M Mᵀ of two parallelograms, brought back by Cholesky to a
// parallelogram whose second axis is the map's vertical (columns of L). The appendix's "u2.y" is u_out.y.
// Guards: m00 = 0 (no horizontal extent) and a negative radicand (rounding) keep a TINY extent.
mat2 convolve(mat2 a, mat2 b) {
    float m00 = a[0].x * a[0].x + a[1].x * a[1].x + b[0].x * b[0].x + b[1].x * b[1].x;
    float m10 = a[0].x * a[0].y + a[1].x * a[1].y + b[0].x * b[0].y + b[1].x * b[1].y;
    float m11 = a[0].y * a[0].y + a[1].y * a[1].y + b[0].y * b[0].y + b[1].y * b[1].y;
    vec2 u, v;
    u.x = sqrt(max(m00, TINY * TINY));
    u.y = m00 > TINY * TINY ? m10 / u.x : 0.0;
    v = vec2(0.0, sqrt(max(m11 - u.y * u.y, TINY * TINY)));
    return mat2(u, v);
}

// ---- §5.1: perceptual resolution --------------------------------------------------------------------------
// ρ(n): texels a filter must span to look right at n pixels on screen, fitted in x = log2 n over the study's
// power-of-two sizes; x is held to [0, 9] (1 … 512 pixels) outside of which the cubics were not fitted.
float rho(float n) {
    float x = clamp(log2(max(n, 1e-6)), 0.0, 9.0);
    if (u_rho == 2) {       // ρ_static, held at its maximum (x ≈ 7.64) past which the cubic turns down
        x = min(x, 7.6375);
        return 0.5477 + x * (1.406 + x * (-0.04687 - 0.003944 * x));
    }
    float p0 = 0.667, p9 = 0.667 + 9.0 * (0.7794 + 9.0 * (0.3967 - 0.02716 * 9.0));
    if (u_rho == 3) return p0 + (p9 - p0) * x / 9.0;      // linear in log2 n through ρ_dynamic's end points
    return 0.667 + x * (0.7794 + x * (0.3967 - 0.02716 * x));                       // ρ_dynamic
}

// Eq. 4–5: the kernel's screen sizes n0, n1 along the map axes and the texel size r = 2·extent/ρ(n) they
// need; the level is the coarsest whose texels (2^l) are no larger than r. -1 when the footprint is singular.
float perceptual_texel(mat2 phi, mat2 h, out float n_screen) {
    float det = determinant(phi);
    n_screen = 0.0;
    if (!(abs(det) > 1e-12)) return -1.0;
    mat2 inv = inverse(phi);
    float n0 = length(inv * vec2(h[0].x, 0.0)), n1 = length(inv * h[1]);
    n_screen = max(n0, n1);
    float r0 = 2.0 * abs(h[0].x) / rho(n0), r1 = 2.0 * abs(h[1].y) / rho(n1);
    return min(r0, r1);
}

int perceptual_level(mat2 phi, mat2 h, out float n_screen) {
    float r = perceptual_texel(phi, h, n_screen);
    if (r < 0.0) return -1;
    return r >= 1.0 ? int(floor(log2(r))) : 0;
}

// ---- §4.1: smooth convolution (Eq. 2) ---------------------------------------------------------------------
// Occluded share of the semi-axis-aligned parallelogram c + s·u + t·v, |s|, |t| ≤ 1 (v vertical), at level
// l: each cell a constant-depth quad weighted by its overlap with the kernel, every one-cell column of the
// kernel taken as an axis-aligned box (the paper's vertical panels). Normalised by the kernel's actual
// area (Σ weights), so any size stays finite. kernel_sums returns (occluded weight, total weight) over the
// part of the kernel inside u_clip (a tile's own rectangle; unbounded for one map), whose cells it samples
// inside the tile: over tiles that partition the virtual map the sums add up to the one-map sums (§5.2's
// merge), exactly where the tiles' cells line up with the virtual map's.
vec2 kernel_sums(vec2 c, mat2 h, int l) {
    vec2 u = h[0], v = h[1];
    float s = float(1 << l);
    float hx = max(abs(u.x), TINY), hy = max(v.y, TINY);
    float slope = abs(u.x) > TINY ? u.y / u.x : 0.0;
    float cx0 = max(c.x - hx, u_clip.x), cx1 = min(c.x + hx, u_clip.z);
    if (!(cx1 > cx0)) return vec2(0.0);
    int i0 = int(floor(cx0 / s)), i1 = int(floor(cx1 / s));
#if WEIGHTED
    // Kernel coordinates → light plane: the kernel's bounding box is the light (exact without AA, where the
    // kernel is the light seen through the blocker plane; stretched over the pixel footprint with AA).
    vec2 box = vec2(hx, hy + abs(u.y));
    vec2 to_light = g_light_half / box;
    float zr = max(g_r.map.z, 1e-30);
    vec2 foot = g_r.local.xy;
    // A sun's view: a kernel offset through the blocker plane is the tangent of the direction to the sun
    // (metres per texel over the blocker's height above the receiver), kept when the kernel was clamped.
    float tan_per_texel = u_texel_tan / max(g_depth - g_blocker_depth, 1e-30);
#endif
    // One flat loop over (column, row, sub-sample): a column's cells are at most `rows`, a cell has
    // u_sub² depth tests past level 0; with CHUNKED only this dispatch's share of that numbering.
    int sub = l > 0 ? u_sub : 1;
    int per_cell = sub * sub;
    int rows = int(floor(2.0 * hy / s)) + 2;      // a column's [ya, yb] is at most 2·hy long
    int n = (i1 - i0 + 1) * rows * per_cell;
#if CHUNKED
    int k0 = min(u_chunk * u_chunk_size, n), k1 = min(k0 + u_chunk_size, n);
#else
    int k0 = 0, k1 = n;
#endif
    int q = k0 % per_cell, cell = k0 / per_cell;
    int col = cell / rows, row = cell - col * rows;
    float occ = 0.0, total = 0.0, w = 0.0, hidden = 0.0;
    int i = i0, j = 0;
    bool inside = false;
    for (int k = k0; k < k1; ++k) {
        if (q == 0 || k == k0) {
            // A new cell: column i0 + col, row `row` of the column's cells.
            i = i0 + col;
            hidden = 0.0;
            float xa = max(float(i) * s, cx0), xb = min(float(i + 1) * s, cx1);
            float wx = xb - xa;
            float yc = c.y + slope * (0.5 * (xa + xb) - c.x);
            float ya = max(yc - hy, u_clip.y), yb = min(yc + hy, u_clip.w);
            j = int(floor(ya / s)) + row;
            float wy = min(float(j + 1) * s, yb) - max(float(j) * s, ya);
            inside = wx > 0.0 && yb > ya && j <= int(floor(yb / s)) && wy > 0.0;
            w = wx * wy;
#if WEIGHTED
            if (inside && u_light_ortho == 0) {
                vec4 r = (vec4(xa, max(float(j) * s, ya), xb, min(float(j + 1) * s, yb)) - c.xyxy) * to_light.xyxy
                       + g_light_centre.xyxy;
                // Midpoint rule: the cell's area times the irradiance density at its centre, cosθ_r·cosθ_l/d²
                // for a receiver facing the light = 1/(1 + |q|²)² with q its offset in units of the height.
                // Against the exact parallel-rectangle form factor (as SSM's ssm/patch.glsl integrates it)
                // it gave the same mae_shadow on plane and suzanne at 0.7× the filter's time.
                vec2 qc = (0.5 * (r.xy + r.zw) - foot) / zr;
                float kw = 1.0 / (1.0 + dot(qc, qc));
                w *= kw * kw;
                // a spot's clipped disk: the cone at the cell's centre, and none off the ball (PCSS's weights)
#if SPOT_CLIP
                if (g_spot_clipped) w *= spot_point_weight(g_r.local, 0.5 * (r.xy + r.zw));
#endif
            } else if (inside) {
                // A sun: its directions are uniform in solid angle, which the map's tangent plane holds with
                // density cos³θ (dΩ = cos³θ dA for a unit-height plane), each carrying the receiver's
                // cosine. Uniform area weights overcount the directions near the sun's rim by 1/cos³θ, and
                // past the receiver's horizon count what carries no light at all: a 180° sun's kernel spans
                // the whole map, and was an even average of it.
                vec2 tq = (vec2(0.5 * (xa + xb), 0.5 * (max(float(j) * s, ya) + min(float(j + 1) * s, yb))) - c)
                          * tan_per_texel;
                float q2 = 1.0 + dot(tq, tq);
                w *= max(dot(g_n, vec3(tq, 1.0)), 0.0) / (q2 * q2);
            }
#endif
            if (inside && q == 0) {
                total += w;
                ++g_visited;
            }
        }
        if (inside) {
            // A cell of level l is the level-0 texels at the centres of its u_sub × u_sub sub-cells (one: the
            // texel at its centre, as a map rendered 2^l times coarser would sample it), each tested on its
            // own: one point per cell aliases geometry finer than the cell (a grid of thin bars beats with the
            // level's sampling into a moiré). Past the map's edge: lit when every caster lies inside the map,
            // else the edge texel continued outwards (compared where it lies, so a surface never shadows
            // itself). A tile reads the cells its rectangle cuts at its own border texels.
            int a = q % sub, b = q / sub;
            vec2 tc = (vec2(i, j) + (vec2(a, b) + 0.5) / float(sub)) * s;
            bool outside = any(lessThan(tc, u_virtual_lo)) || any(greaterThanEqual(tc, u_virtual_hi));
            if (!(outside && u_outside_lit == 1)) {
                if (outside) tc = clamp(tc, u_virtual_lo + 0.5, u_virtual_hi - 0.5);
                ivec2 t = clamp(ivec2(floor(tc)), ivec2(0), u_map_size - 1);
                // Eq. 2's occluding function, and one test more: a texel whose own light–receiver pyramid
                // (c ± α(z)·h, widened by the pixel footprint and the cell) misses the kernel's centre and
                // that lies close to the receiver (α(z) under a quarter of the kernel's) cannot hide the
                // light: it is the receiver's own curved surface, nearer than its tangent plane far out in
                // a wide kernel. Deeper occluders of a fused umbra keep counting (their light points are
                // covered by the z-average's plane, the model of Eq. 1).
                float z = texelFetch(u_depth_map, t, 0).r;
                vec2 own = filter_half_texels(z, g_depth);
                bool near_receiver = all(lessThan(own, 0.25 * g_light_e))
                    && any(greaterThan(abs(vec2(t) + 0.5 - g_r.map.xy - filter_centre_texels(z, g_depth)),
                                       own + g_pad + 0.5 * s));
                if (z < receiver_depth_at(g_r, vec2(t) + 0.5) && !near_receiver)
                    hidden += 1.0;
            }
            if (q == per_cell - 1 || k == k1 - 1) occ += w * hidden / float(per_cell);
        }
        if (++q == per_cell) {
            q = 0;
            if (++row == rows) { row = 0; ++col; }
        }
    }
    return vec2(occ, total);
}

float occluded_share(vec2 c, mat2 h, int l) {
    vec2 sums = kernel_sums(c, h, l);
    return sums.y > 0.0 ? clamp(sums.x / sums.y, 0.0, 1.0) : 0.0;
}

// The kernel's centre in this map's texels: the receiver's, moved by where the light part's centre is seen
// through the blockers' mean depth.
vec2 kernel_centre(float z_avg, float weight) {
    vec2 span = u_virtual_hi - u_virtual_lo;
    float far = max(span.x, span.y);
    return g_r.map.xy + (weight > 0.0 ? clamp(filter_centre_texels(z_avg, g_depth), -far, far) : vec2(0.0));
}

// The kernel of Eq. 1 (with the pixel footprint under anti-aliasing) around its centre, in this map's
// texels, from the blockers' mean depth; sets g_light_e.
mat2 soft_kernel(float z_avg, float weight, mat2 phi) {
    vec2 e = weight > 0.0 ? filter_half_texels(z_avg, g_depth) : vec2(0.0);
    g_blocker_depth = z_avg;
    vec2 span = u_virtual_hi - u_virtual_lo;
    e = min(e, vec2(max(span.x, span.y)));     // α → ∞ (occluder at the light)
    g_light_e = e;
    mat2 h = mat2(vec2(e.x, 0.0), vec2(0.0, e.y));
    if (u_aa == 1) h = convolve(h, phi);
    return h;
}

// The filtering level: the finest under the cap, or coarser where ρ(n) allows (§5.1).
int filter_level(mat2 phi, mat2 h, out float n_screen) {
    int l = cap_level(max(abs(h[0].x), h[1].y + abs(h[0].y)), u_filter_levels);
    n_screen = 0.0;
    if (u_rho != 0) l = max(l, min(perceptual_level(phi, h, n_screen), u_filter_levels - 1));
    return l;
}

#if MODE == 1
// Step 4: the texel size (search-map texels) this pixel's kernel needs — the cap's, ρ's (§5.1, Eq. 5) and
// no finer than half the pixel's own footprint on the map — min-blended into every tile
// grid cell its kernel's bounding box covers. The paper splats one point, into the receiver's own cell; a
// kernel reaching a cell that no pixel projects onto would then read a map that was never rendered. The box
// goes into the pyramid level where it spans at most 2×2 cells (a coarse cell's value holds for the cells
// under it), so each pixel costs at most four atomics. Positive floats order like their bit patterns.
float predicted_texel(mat2 phi, mat2 h) {
    float r = 2.0 * max(abs(h[0].x), h[1].y + abs(h[0].y)) / float(u_cap);
    float n_screen;
    if (u_rho != 0) r = max(r, perceptual_texel(phi, h, n_screen));
    // The footprint's floor is its half axis (half a pixel): what ρ gives a kernel no wider than the
    // footprint (2h/ρ(1) ≈ 1.1 h); a whole pixel per texel shifts hard edges by up to half a pixel.
    r = max(r, sqrt(abs(determinant(phi))));
    return r > 0.0 ? r : 1e-30;         // a degenerate kernel and footprint (or NaN): the finest level
}

void splat(vec2 c, mat2 h, float r) {
    vec2 ext = vec2(abs(h[0].x), h[1].y + abs(h[0].y));
    vec2 lo = clamp((c - ext) / u_grid_cell, vec2(0.0), vec2(u_grid_size) - 0.5);
    vec2 hi = clamp((c + ext) / u_grid_cell, vec2(0.0), vec2(u_grid_size) - 0.5);
    if (any(isnan(lo)) || any(isnan(hi))) return;
    int level = 0, row = 0, n = u_grid_size;
    ivec2 a = ivec2(lo), b = ivec2(hi);
    while (n > 1 && any(greaterThan(b - a, ivec2(1)))) {
        row += n;
        n >>= 1;
        ++level;
        a = ivec2(lo / float(1 << level));
        b = ivec2(hi / float(1 << level));
    }
    uint bits = floatBitsToUint(r);
    for (int j = a.y; j <= b.y; ++j)
        for (int i = a.x; i <= b.x; ++i)
            imageAtomicMin(u_grid, ivec2(i, row + j), bits);
}
#endif

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
#if MODE == 3
    // The merge: V = Σ V·A / Σ A over the tiles the kernel reached; a pixel with no kernel stays lit.
    vec4 k = texelFetch(u_kernel, px, 0);
    vec4 m = texelFetch(u_merge, px, 0);
    float v = k.w == 2.0 && m.y > 0.0 ? clamp(m.x / m.y, 0.0, 1.0) : 1.0;
    imageStore(u_visibility, px, vec4(v));
#if INFO
    imageStore(u_info, px, vec4(k.w, k.z > 0.0 ? -log2(k.z) : 0.0, 0.0, m.z));
#endif
#else
    float v = 1.0;
    vec4 info = vec4(-1.0, 0.0, 0.0, 0.0);
    g_visited = 0;
#if MODE == 1
    vec4 kernel = vec4(0.0, 0.0, 0.0, -1.0);
#endif
#if MODE == 2
    vec4 k = texelFetch(u_kernel, px, 0);
    if (k.w != 2.0) return;             // not reached, or fully lit: no tile filters it
#endif
    if (pixel_lit(px)) {
        vec3 p = texelFetch(g_position, px, 0).xyz, ng = texelFetch(g_geometric, px, 0).xyz;
        g_r = pixel_receiver(px);
        set_light_part(g_r.local);
        g_r.bias = slope_scaled_bias(g_r);  // blockers searched and filtered over a whole region
        g_n = view_direction(texelFetch(g_normal, px, 0).xyz);
        g_depth = g_r.map.z - g_r.bias;
        mat2 phi = mat2(0.0);
        if (u_aa == 1 || u_rho != 0 || MODE == 1) phi = pixel_footprint(px, p, ng);
        vec2 pad = u_aa == 1 ? abs(phi[0]) + abs(phi[1]) : vec2(0.0);
        g_pad = pad;
#if MODE == 2
        vec2 blockers = k.xy;
#else
        // Search box: the light seen from the receiver through the near plane; with the light part off the
        // receiver's axis (set_light_part) the box round that section and the receiver, the pyramid's apex,
        // since the sections in between slide from one to the other. Capped about the receiver.
        vec2 near_centre = filter_centre_texels(u_light_depth_range.x, g_depth);
        vec2 near_half = filter_half_texels(u_light_depth_range.x, g_depth);
        vec2 lo = clamp(near_centre - near_half, -u_max_radius, 0.0);
        vec2 hi = clamp(near_centre + near_half, 0.0, u_max_radius);
        vec2 search = max(0.5 * (hi - lo), vec2(0.5));
        vec2 blockers = average_blockers((g_r.map.xy + 0.5 * (lo + hi)) * u_search_scale, search * u_search_scale,
                                         pad * u_search_scale);
#endif
        info.x = 0.0;
        if (blockers.y > 0.0 || u_skip_lit == 0) {
            mat2 h = soft_kernel(blockers.x, blockers.y, phi);
#if MODE == 1
            float r = predicted_texel(phi, h);
            splat(kernel_centre(blockers.x, blockers.y), h, r);
            kernel = vec4(blockers, r, 2.0);
#else
            float n_screen;
            int l = filter_level(phi, h, n_screen);
            int searched = g_visited;
            vec2 sums = kernel_sums(kernel_centre(blockers.x, blockers.y), h, l);
#if CHUNKED && MODE == 0
            vec4 part = (u_chunk > 0 ? imageLoad(u_partial, px) : vec4(0.0)) + vec4(sums, g_visited - searched, 0.0);
            if (u_chunk < u_chunks - 1) {
                imageStore(u_partial, px, part);
                return;
            }
            sums = part.xy;
            g_visited = searched + int(part.z);
#endif
#if MODE == 2
            if (g_visited > 0) {
                vec4 m = imageLoad(u_merge, px);
                imageStore(u_merge, px, m + vec4((sums.y - sums.x) * u_area_scale, sums.y * u_area_scale,
                                                 float(g_visited), 0.0));
            }
            return;
#else
            v = sums.y > 0.0 ? 1.0 - clamp(sums.x / sums.y, 0.0, 1.0) : 1.0;
            info = vec4(blockers.y > 0.0 ? 2.0 : 0.0, float(l), n_screen, 0.0);
#endif
#endif
        }
#if MODE == 1
        else kernel.w = 0.0;
#endif
        info.w = float(g_visited);
    }
#if MODE == 1
    imageStore(u_kernel, px, kernel);
#elif MODE == 0
    imageStore(u_visibility, px, vec4(v));
#if INFO
    imageStore(u_info, px, info);
#endif
#endif
#endif
}
