// Microrects (Schwarz & Stamminger 2008, §5.2): one micro-occluder per texel of every level, with its own
// depth and its extent, a rectangle of level-0 texels. Level 0 is the depth map's micropatches (extent = the
// texel). Level i + 1 texel c keeps the reference point of level-i texel A = 2c and gathers level-i
// microrects by a greedy two-pass merge:
//   pass 1: the positive-x neighbour B joins A when its depth is nearer A's than that of the next retained
//           texel C = 2c + (2, 0) (likewise D = 2c + (0, 1) against 2c + (0, 2)); the diagonal E = 2c + (1, 1)
//           joins when the extent so far already contains E's, or when its depth is nearer A's than that of
//           the retained texel P = 2c + (2, 2) that would take it in pass 2;
//   pass 2: the negative-direction neighbours (2c − (1, 0), 2c − (0, 1), 2c − (1, 1)) that pass 1 left to
//           no one join.
// Both passes are pure functions of level i, so one invocation evaluates its neighbours' pass-1 decisions
// itself. Depth: minimum of the members; extent: the smallest rectangle holding the members' extents, where
// empty members (no occluder) never widen it. Every level-i microrect joins exactly one level-(i + 1) one.
// STATS (BACKPROJECTION's coverage, ours): a third chain holds, per microrect, its non-empty members' mean
// depth, count of level-0 texels, maximum depth and depth variance, merged with the members.
#ifndef STATS
#define STATS 0
#endif
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;      // level 0 source (R32F)
uniform int u_first;            // 1: build level 0
uniform ivec2 u_map_size;
uniform ivec2 u_src_size;       // level i (padded) size
uniform int u_src_level;        // i
uniform ivec2 u_dst_size;
#if STATS
layout(r32f, binding = 0) uniform writeonly image2D u_dst_depth;
layout(rgba32f, binding = 1) uniform writeonly image2D u_dst_extent;
layout(rgba32f, binding = 2) uniform writeonly image2D u_dst_stats;
layout(r32f, binding = 3) uniform readonly image2D u_src_depth;
layout(rgba32f, binding = 4) uniform readonly image2D u_src_extent;
layout(rgba32f, binding = 5) uniform readonly image2D u_src_stats;
#else
layout(r32f, binding = 0) uniform writeonly image2D u_dst_depth;
layout(rgba32f, binding = 1) uniform writeonly image2D u_dst_extent;
layout(r32f, binding = 2) uniform readonly image2D u_src_depth;
layout(rgba32f, binding = 3) uniform readonly image2D u_src_extent;
#endif
#include "backprojection/depth_stats.glsl"

bool inside(ivec2 t) {
    return all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, u_src_size));
}

float z_of(ivec2 t) {
    return inside(t) ? imageLoad(u_src_depth, t).r : NO_OCCLUDER;
}

bool empty(float z) {
    return !(z < EMPTY_DEPTH);
}

// Depth difference that decides a merge: empty against an occluder is the largest possible.
float gap(float a, float b) {
    if (empty(a) || empty(b)) return empty(a) && empty(b) ? 0.0 : NO_OCCLUDER;
    return abs(a - b);
}

// Does the odd (in `axis`) texel t join its negative-side retained neighbour t − axis in pass 1? It does
// unless the positive-side one t + axis exists and is nearer in depth.
bool joins_back(ivec2 t, ivec2 axis) {
    ivec2 fwd = t + axis;
    if (!inside(fwd)) return true;
    float z = z_of(t);
    return gap(z, z_of(t - axis)) <= gap(z, z_of(fwd));
}

struct Rect {
    float z;
    vec4 ext;                   // x0, y0, x1, y1 (exclusive)
    bool any;                   // ext holds at least one occluder
    vec4 stats;                 // STATS: mean depth, count, max, variance of the non-empty members' texels
};

void add(inout Rect r, ivec2 t) {
    if (!inside(t)) return;
    float z = z_of(t);
    r.z = min(r.z, z);
    if (empty(z)) return;
#if STATS
    // Level 0's statistics are the texel's own depth (never stored: the gather reads them at coarse levels).
    r.stats = merge_stats(r.stats, u_src_level == 0 ? texel_stats(z) : imageLoad(u_src_stats, t));
#endif
    vec4 e = imageLoad(u_src_extent, t);
    r.ext = r.any ? vec4(min(r.ext.xy, e.xy), max(r.ext.zw, e.zw)) : e;
    r.any = true;
}

bool contains(Rect r, ivec2 t) {
    if (!r.any) return false;
    vec4 e = imageLoad(u_src_extent, t);
    return all(lessThanEqual(r.ext.xy, e.xy)) && all(greaterThanEqual(r.ext.zw, e.zw));
}

// Pass 1 of the retained texel a: itself, B and D when they join back, E when contained, when nearer in
// depth to A than to P, or when no P lies beyond E. The paper lets a non-contained E always go to P, by
// position only; but along a diagonal silhouette E is then the ground behind an object texel P (or the
// reverse) and P's microrect takes the ground's extent at the object's minimum depth: the whole coarse
// silhouette grows by the ground texels around it, the over-darkening microrects are meant to remove (the
// 2008 paper's §5.2 picks merge partners by the least depth difference; this applies it to E too; at
// forced level 3 on a tilted-plates scene the ground's mean bias went −0.089 → −0.047, micropatches
// −0.097). `took_e` says whether E joined.
Rect pass1(ivec2 a, out bool took_e) {
    Rect r = Rect(NO_OCCLUDER, vec4(0.0), false, NO_STATS);
    add(r, a);
    ivec2 b = a + ivec2(1, 0), d = a + ivec2(0, 1), e = a + ivec2(1, 1);
    if (inside(b) && joins_back(b, ivec2(1, 0))) add(r, b);
    if (inside(d) && joins_back(d, ivec2(0, 1))) add(r, d);
    took_e = false;
    if (inside(e)) {
        float ze = z_of(e);
        took_e = empty(ze) || contains(r, e) || !inside(e + ivec2(1, 1))
              || gap(ze, r.z) <= gap(ze, z_of(e + ivec2(1, 1)));
        if (took_e) add(r, e);
    }
    return r;
}

void main() {
    ivec2 c = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(c, u_dst_size))) return;
    if (u_first == 1) {
        bool in_map = all(lessThan(c, u_map_size));
        imageStore(u_dst_depth, c, vec4(in_map ? texelFetch(u_depth, c, 0).r : NO_OCCLUDER));
        imageStore(u_dst_extent, c, vec4(vec2(c), vec2(c + 1)));
        return;
    }
    ivec2 a = 2 * c;
    bool took_e;
    Rect r = pass1(a, took_e);
    // Pass 2: the negative-direction neighbours that no pass-1 merge took.
    ivec2 x = a - ivec2(1, 0), y = a - ivec2(0, 1), xy = a - ivec2(1, 1);
    if (inside(x) && !joins_back(x, ivec2(1, 0))) add(r, x);
    if (inside(y) && !joins_back(y, ivec2(0, 1))) add(r, y);
    if (inside(xy)) {
        bool diag_taken;
        pass1(a - ivec2(2, 2), diag_taken);
        if (!diag_taken) add(r, xy);
    }
    imageStore(u_dst_depth, c, vec4(r.z));
#if STATS
    imageStore(u_dst_stats, c, r.stats);
#endif
    imageStore(u_dst_extent, c, r.any ? r.ext : imageLoad(u_src_extent, a));     // empty: A's own extent
}
