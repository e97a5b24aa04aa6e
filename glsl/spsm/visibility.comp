// SPSM visibility (Lecocq et al. 2014, §3.3–§5): one fetch per stored triangle, classification into lit /
// shadowed / uncertain, and the shadow silhouette recovered from the 3×3 neighbourhood for uncertain pixels.
#include "common/pixel.glsl"
#include "common/light_view.glsl"
#include "conservative_map/texel.glsl"

uniform usampler2D u_texels;
uniform sampler2D u_depth_map;      // the hard depth map, for the shadow terminator only
uniform sampler2D u_slope_table;    // 256 decoded Q codes (§3.4: the decoding look-up table)
#ifdef SPSM_FLOAT_SLOPES
uniform sampler2D u_slopes;         // quantiser ablation: unquantised dη/dx, dη/dy
#endif
uniform sampler2D u_patterns;       // 512×1: up to two shadow directions per 3×3 mask (spsm.py)
uniform int u_recovery;             // 1: silhouette recovery for uncertain pixels (§4.2)
uniform int u_aa_samples;           // sub-pixel samples for uncertain pixels (§5); 1 = off

layout(r32f, binding = 0) uniform writeonly image2D u_visibility;
layout(r32f, binding = 1) uniform writeonly image2D u_class;

// How a pixel was decided (the class image; spsm.py counts them).
const float C_LIT_1 = 1.0;          // one look-up: empty texel, or the receiver is the stored triangle
const float C_SHADOW_1 = 2.0;       // one look-up: the stored triangle occludes it
const float C_SHADOW_9 = 3.0;       // a triangle of the 3×3 neighbourhood occludes it
const float C_RECOVERED = 4.0;      // uncertain: silhouette recovery (or its trivial masks) decided
const float C_UNCERTAIN = 5.0;      // uncertain, recovery off: the centre's consistent depth decided

const float GRAZING_COS = 0.05;     // cos 87°

const ivec2 RING[8] = ivec2[8](ivec2(1, 0), ivec2(1, 1), ivec2(0, 1), ivec2(-1, 1),
                               ivec2(-1, 0), ivec2(-1, -1), ivec2(0, -1), ivec2(1, -1));

struct Tri {
    vec2 v[3];      // absolute texel coordinates
    vec2 centre;    // the storing texel's centre
    float eta_c;    // η of the plane at the centre (z̃)
    vec2 grad;      // dη per texel
    bool valid;
    float area2;    // twice the signed 2D area
};

Tri fetch_tri(ivec2 k) {
    Tri t;
    t.valid = false;
    t.centre = vec2(k) + 0.5;
    t.eta_c = 0.0; t.grad = vec2(0.0); t.area2 = 0.0;
    t.v[0] = t.v[1] = t.v[2] = t.centre;
    if (any(lessThan(k, ivec2(0))) || any(greaterThanEqual(k, u_map_size))) return t;
    uvec4 w = texelFetch(u_texels, k, 0);
    if ((w.a & 0xFFu) == 0u) return t;              // no triangle touches this texel
    t.valid = true;
    for (int i = 0; i < 3; ++i) t.v[i] = t.centre + unpack_vertex(w[i]);
    float n = u_light_depth_range.x, f = u_light_depth_range.y;
    float zc = n + float(w.a >> 16) / 65535.0 * (f - n);
    t.eta_c = eta_from_depth(zc);
#ifdef SPSM_FLOAT_SLOPES
    t.grad = texelFetch(u_slopes, k, 0).xy;
#else
    vec2 s = vec2(texelFetch(u_slope_table, ivec2(int((w.a >> 8) & 0xFFu), 0), 0).r,
                  texelFetch(u_slope_table, ivec2(int(w.a & 0xFFu), 0), 0).r);
    t.grad = -s * slope_scale();
#endif
    t.area2 = cross2(t.v[1] - t.v[0], t.v[2] - t.v[0]);
    return t;
}

// Eq. 1: the stored plane's η at a map position, first-order from the texel centre.
float eta_at(Tri t, vec2 p) {
    return t.eta_c + dot(t.grad, p - t.centre);
}

// 2D point in triangle, either winding; a degenerate (edge-on) triangle contains nothing.
bool inside(Tri t, vec2 p) {
    if (abs(t.area2) < 1e-10) return false;
    float s = sign(t.area2);
    return s * cross2(t.v[1] - t.v[0], p - t.v[0]) >= 0.0 &&
           s * cross2(t.v[2] - t.v[1], p - t.v[1]) >= 0.0 &&
           s * cross2(t.v[0] - t.v[2], p - t.v[2]) >= 0.0;
}

// Algorithm 1: depth rejection by Eq. 1, then the 2D point-in-triangle test.
bool occludes(Tri t, vec2 p, float eta_receiver) {
    if (!t.valid || eta_at(t, p) <= eta_receiver) return false;
    return inside(t, p);
}

// §4.2, Fig. 9: consistent depth, the nearest η the triangle reaches inside texel k (not the texel
// corner's, which underestimates the depth of a partly covering triangle). η is affine, so the extreme lies
// on a vertex of triangle ∩ texel: texel corners inside the triangle, triangle vertices inside the texel,
// edge/border crossings. Degenerate edges give no crossing; no candidate at all (the quantised vertices
// miss the texel) falls back to the conservative corner value.
// Returns the position (xy) and η (z) of that nearest point.
vec3 consistent_depth(Tri t, ivec2 k) {
    vec2 lo = vec2(k), hi = lo + 1.0;
    vec3 best = vec3(0.0, 0.0, -EMPTY_DEPTH);
    for (int i = 0; i < 4; ++i) {
        vec2 corner = vec2(i % 2 == 0 ? lo.x : hi.x, i < 2 ? lo.y : hi.y);
        float e = eta_at(t, corner);
        if (inside(t, corner) && e > best.z) best = vec3(corner, e);
    }
    for (int i = 0; i < 3; ++i) {
        vec2 a = t.v[i], b = t.v[(i + 1) % 3];
        if (all(greaterThanEqual(a, lo)) && all(lessThanEqual(a, hi)) && eta_at(t, a) > best.z)
            best = vec3(a, eta_at(t, a));
        vec2 d = b - a;
        for (int axis = 0; axis < 2; ++axis) {
            if (abs(d[axis]) < 1e-12) continue;
            for (int side = 0; side < 2; ++side) {
                float edge = side == 0 ? lo[axis] : hi[axis];
                float s = (edge - a[axis]) / d[axis];
                if (s < 0.0 || s > 1.0) continue;
                vec2 x = a + d * s;
                float o = x[1 - axis];
                if (o >= lo[1 - axis] && o <= hi[1 - axis] && eta_at(t, x) > best.z) best = vec3(x, eta_at(t, x));
            }
        }
    }
    if (best.z < -1e29) {
        vec2 corner = t.centre + 0.5 * sign(t.grad);
        best = vec3(corner, eta_at(t, corner));
    }
    return best;
}

// The receiver's biased η under map position q (its own plane, glsl/common/light_view.glsl).
float receiver_eta(Receiver r, vec2 q) {
    return eta_from_depth(receiver_depth_at(r, q));
}

// ---- silhouette recovery (§4.2, Fig. 10) ---------------------------------------------------------------
Tri g_tri[9];           // the neighbourhood: index 0 the centre, 1 + i the ring
bool g_front[9];        // consistent depth in front of the receiver (the 3×3 test bitmask)

// A boundary vertex of the shadow faces the lit side: its outward 2D normal (sum of its edges' outward
// normals) has a positive component against the shadow direction n. Vertices of edge-on triangles lie on the
// silhouette itself (Fig. 3) and all count.
bool faces_lit_side(Tri t, int i, vec2 n) {
    if (abs(t.area2) < 1e-10) return true;
    float s = sign(t.area2);
    vec2 prev = t.v[i] - t.v[(i + 2) % 3], next = t.v[(i + 1) % 3] - t.v[i];
    vec2 out_n = s * (vec2(prev.y, -prev.x) / max(length(prev), 1e-12) + vec2(next.y, -next.x) / max(length(next), 1e-12));
    return dot(out_n, -n) > 0.0;
}

// A vertex strictly inside another front triangle is behind a shadow edge: not on the boundary.
bool hidden(vec2 v, int owner) {
    for (int j = 0; j < 9; ++j) {
        if (j == owner || !g_front[j]) continue;
        Tri t = g_tri[j];
        if (abs(t.area2) < 1e-10) continue;
        float s = sign(t.area2);
        if (s * cross2(t.v[1] - t.v[0], v - t.v[0]) > 1e-4 && s * cross2(t.v[2] - t.v[1], v - t.v[1]) > 1e-4 &&
            s * cross2(t.v[0] - t.v[2], v - t.v[2]) > 1e-4) return true;
    }
    return false;
}

// Boundary vertices for one shadow direction n, projected on the tangent axis through o: t = position along
// the axis, d = signed distance towards the shadow (a dot product, so no square root to guard).
vec2 g_td[27];
int g_count;

// Only the texels on this tangent's occluder side (and the centre) take part: with two tangents, the other
// occluder's lit-facing vertices would otherwise pull φ across the gap between them (shadow fusion).
void collect(vec2 n, vec2 o, float side) {
    vec2 tangent = vec2(-n.y, n.x);
    g_count = 0;
    for (int j = 0; j < 9; ++j) {
        if (!g_front[j]) continue;
        if (j > 0 && dot(vec2(RING[j - 1]), n) <= side) continue;
        for (int i = 0; i < 3; ++i) {
            vec2 v = g_tri[j].v[i];
            if (!faces_lit_side(g_tri[j], i, n) || hidden(v, j)) continue;
            g_td[g_count++] = vec2(dot(v - o, tangent), dot(v - o, n));
        }
    }
}

// φ(t): the boundary vertices linked in order along the axis; beyond the last one the boundary stays at
// its height. True when the point (t, d) is on the shadow side of φ.
bool beyond_phi(vec2 td) {
    float tl = -EMPTY_DEPTH, dl = 0.0, tr = EMPTY_DEPTH, dr = 0.0;   // ±"infinity": beyond any depth
    bool has_l = false, has_r = false;
    for (int i = 0; i < g_count; ++i) {
        vec2 q = g_td[i];
        if (q.x <= td.x && q.x > tl) { tl = q.x; dl = q.y; has_l = true; }
        if (q.x >= td.x && q.x < tr) { tr = q.x; dr = q.y; has_r = true; }
    }
    if (!has_l && !has_r) return false;
    float phi;
    if (has_l && has_r) phi = tr - tl > 1e-9 ? mix(dl, dr, (td.x - tl) / (tr - tl)) : min(dl, dr);
    else phi = has_l ? dl : dr;
    return td.y > phi;
}

// HARD's decision (glsl/hard/visibility.comp) where the sub-texel tests cannot decide: the hard map against
// the Cycles-style receiver (the terminator lift of g_geometric.w, position and depth lifted together) and its
// tangent-plane rule, so that a receiver facing away from the light centre is not shadowed by its own object
// (a wide sun or a large light still lights it) and a terminator pixel starts where Cycles' shadow ray does.
float hard_decision(ivec2 px) {
    Receiver h = pixel_receiver(px);
    return map_lit_plane(u_depth_map, ivec2(floor(h.map.xy)), h);
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px)) return;
    float v = 1.0, cls = 0.0;
    if (pixel_lit(px)) {
        // Not pixel_receiver's lifted point: the sub-texel tests compare this surface point's own position
        // and depth with the stored triangles (the terminator is handled below, as HARD handles it).
        vec3 surface = texelFetch(g_position, px, 0).xyz;
        Receiver r = make_receiver(surface, texelFetch(g_geometric, px, 0).xyz);
        // The normal offset keeps its depth, not its sideways shift: at sub-texel precision that shift
        // (δ·tanθ on the receiver) moves outer shadow edges outwards.
        vec2 p = map_coords(light_local(surface)).xy;
        r.map.xy = p;
        r.bias = slope_scaled_bias(r);     // triangles rebuilt from 16-bit planes
        ivec2 k = ivec2(floor(p));
        float eta_front = eta_from_depth(r.map.z - r.bias);     // nearer than this occludes
        float eta_back = eta_from_depth(r.map.z + r.bias);
        Tri tc = fetch_tri(k);
        cls = C_LIT_1;
        vec3 l_local = light_local(surface);
        vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-l_local);
        if (any(lessThan(k, ivec2(0))) || any(greaterThanEqual(k, u_map_size)) || !tc.valid) {
            v = 1.0;                                        // nothing touches the texel: lit
        } else if (dot(r.normal, to_light) < GRAZING_COS || depth_step() > r.bias) {
            // The triangle faces away from the light centre. Either the shadow terminator of a smooth mesh
            // (the shading normal faces the light, so its own mesh shadows it geometrically; Cycles lifts
            // such shadow rays off the flat triangle, its shadow-terminator geometry offset) or a receiver
            // lit only by the rest of a wide light (a sun's far side under a 2.5 rad sun), which its own
            // object must not shadow. Sub-texel tests against the surface point would shadow both; here
            // SPSM decides exactly as HARD does (hard_decision). So are receivers within 3° of edge-on (city's walls at 89.8°):
            // there one texel spans tens of texel-widths of depth and the sub-texel tests are
            // ill-conditioned, while HARD's capped slope bias still holds. And so are receivers whose bias
            // is finer than one step of the texel's 16-bit plane depth, which spans the view's whole depth
            // range (texel.glsl): a small window over casters many metres deep (fuzz 27002, a 15× Suzanne:
            // a 0.8 mm step against 0.07 mm texels) put the receivers' own triangles in front of them by the
            // rounding alone, in stripes, where HARD's float map holds.
            v = hard_decision(px);
        } else {
            float e = eta_at(tc, p);
            if (e >= eta_back && e <= eta_front) {
                v = 1.0;                                    // §4.1: the receiver is the stored triangle
            } else if (occludes(tc, p, eta_front)) {
                v = 0.0; cls = C_SHADOW_1;
            } else {
                g_tri[0] = tc;
                bool hit = false;
                for (int i = 0; i < 8; ++i) {
                    g_tri[1 + i] = fetch_tri(k + RING[i]);
                    if (!hit && occludes(g_tri[1 + i], p, eta_front)) hit = true;
                }
                if (hit) {
                    v = 0.0; cls = C_SHADOW_9;
                } else {
                    // Uncertain (§4.1). The 3×3 bitmask of consistent-depth tests (§4.2, Fig. 9).
                    uint ring = 0u;
                    for (int j = 0; j < 9; ++j) {
                        ivec2 kj = j == 0 ? k : k + RING[j - 1];
                        // Compared where the triangle is nearest: the receiver's own plane there, so
                        // that the receiver's surface never counts as in front of itself.
                        // Algorithm 1's depth rejection at p itself too: a neighbour whose plane runs
                        // behind p there is the receiver's own surface curving away (a concave receiver),
                        // not an occluder whose edge was missed.
                        if (g_tri[j].valid) {
                            vec3 c = consistent_depth(g_tri[j], kj);
                            g_front[j] = c.z > receiver_eta(r, c.xy) && eta_at(g_tri[j], p) > eta_front;
                        } else {
                            g_front[j] = false;
                        }
                        if (j > 0 && g_front[j]) ring |= 1u << uint(j - 1);
                    }
                    if (u_recovery == 0) {
                        cls = C_UNCERTAIN;
                        v = g_front[0] ? 0.0 : 1.0;
                    } else {
                        cls = C_RECOVERED;
                        vec4 dirs = texelFetch(u_patterns, ivec2(int(ring) | (g_front[0] ? 256 : 0), 0), 0);
                        bool unite = !g_front[0];     // separate occluders: shadows unite
                        if (ring == 0xFFu) {
                            // Occluders in front all around yet none over p: a solid occluder whose
                            // triangle at p was not kept (the paper's case: shadowed) or a gap in a mesh of
                            // occluders finer than a texel (the paper's "shadow fusion", §6.4). The hard
                            // map's sample at p tells them apart as well as anything here can.
                            v = hard_decision(px);
                        } else if (ring == 0u && !g_front[0]) {
                            v = 1.0;                        // nothing in front anywhere around
                        } else {
                            vec2 dir[2] = vec2[2](dirs.xy, dirs.zw);
                            if (dot(dir[0], dir[0]) < 0.5) {
                                v = 1.0;                    // no usable pattern: nothing reaches past
                            } else {
                            // §5: the same φ at sub-pixel positions of the pixel's footprint in the map.
                            vec2 jx = vec2(0.0), jy = vec2(0.0);
                            if (u_aa_samples > 1) {
                                for (int axis = 0; axis < 2; ++axis) {
                                    ivec2 step_px = axis == 0 ? ivec2(1, 0) : ivec2(0, 1);
                                    vec2 dm = vec2(0.0);
                                    for (int sgn = 1; sgn >= -1; sgn -= 2) {
                                        ivec2 q = px + sgn * step_px;
                                        if (any(lessThan(q, ivec2(0))) || !pixel_in_image(q)) continue;
                                        vec4 pos = texelFetch(g_position, q, 0);
                                        if (pos.w <= 0.0) continue;
                                        vec3 mq = map_coords(light_local(pos.xyz));
                                        if (abs(mq.z - r.map.z) > 0.05 * r.map.z) continue;
                                        dm = float(sgn) * (mq.xy - map_coords(light_local(
                                             texelFetch(g_position, px, 0).xyz)).xy);
                                        break;
                                    }
                                    if (axis == 0) jx = dm; else jy = dm;
                                }
                            }
                            int samples = min(max(u_aa_samples, 1), 32);
                            // Two tangents: two occluders beside the centre unite their shadows; a thin
                            // occluder through the centre is bounded on both sides: they intersect (§4.2).
                            uint all_bits = samples == 32 ? 0xFFFFFFFFu : (1u << uint(samples)) - 1u;
                            uint shadow_bits = unite ? 0u : all_bits;   // one bit per sample
                            for (int d = 0; d < 2; ++d) {
                                vec2 n = dir[d];
                                if (d == 1 && dot(n, n) < 0.5) break;
                                vec2 origin = vec2(k) + 0.5 - 2.0 * n;      // on the lit side's corner
                                // Beside separate occluders: texels towards this one; across a thin
                                // one: every texel not behind its line.
                                collect(n, origin, unite ? 0.3 : -0.3);      // φ once per tangent
                                vec2 t_axis = vec2(-n.y, n.x);
                                for (int s = 0; s < samples; ++s) {
                                    // Rotated grid in the pixel; a single sample sits at its centre.
                                    vec2 o = samples == 1 ? vec2(0.0)
                                           : vec2(fract(0.5 + float(s) * 0.618034) - 0.5,
                                                  (float(s) + 0.5) / float(samples) - 0.5);
                                    vec2 ps = p + o.x * jx + o.y * jy;
                                    bool sh = beyond_phi(vec2(dot(ps - origin, t_axis), dot(ps - origin, n)));
                                    uint bit = 1u << uint(s);
                                    if (unite && sh) shadow_bits |= bit;
                                    if (!unite && !sh) shadow_bits &= ~bit;
                                }
                            }
                            float shadowed = float(bitCount(shadow_bits));
                            v = 1.0 - shadowed / float(samples);
                            }
                        }
                    }
                }
            }
        }
    }
    imageStore(u_visibility, px, vec4(v));
    imageStore(u_class, px, vec4(cls));
}
