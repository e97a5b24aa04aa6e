// Unoccluded irradiance from one light at a receiver, analytic for every light kind (engine/shading.py
// packs the uniforms; engine/irradiance.py is the same mathematics in numpy, checked against Cycles).
//
// Every extended light is a convex polygon of constant radiance seen from x: a rectangle, an N-gon for a
// disk or ellipse, a disk for a point/spot light with a radius (Cycles' default "soft falloff" emits from a
// disk of that radius at the light centre facing x; without it the light is a true sphere, whose tangency
// circle subtends the same cone of directions), or a disk of directions for the sun. The polygon is clipped to the
// receiver's upper hemisphere and integrated with Lambert's edge formula:
//     E = L/2 · |Σ_i θ_i · n·ĝ_i|,  θ_i = angle between v_i and v_{i+1},  ĝ_i = normalize(v_i × v_{i+1}).
// Suns use the closed form of a cone of directions instead (cap_form_factor), small lights a point (SMALL_LIGHT).

const int LIGHT_POLYGON = 0;   // area light: rectangle (sides = 4) or ellipse (sides > 4)
const int LIGHT_SPHERE = 1;    // point/spot with a radius
const int LIGHT_POINT = 2;     // point/spot without radius: I·cosθ/d²
const int LIGHT_SUN = 3;       // sun: disk of directions, or S·cosθ when the angle is zero

// Specialised per light when compiled (engine/shading.py light_defines): with the shape, the polygon's side
// count and the spot cone known, the compiler unrolls and drops what a light does not use.
#ifndef LIGHT_SHAPE
#define LIGHT_SHAPE 0
#endif
#ifndef POLY_SIDES
#define POLY_SIDES 4
#endif
#ifndef LIGHT_SPOT
#define LIGHT_SPOT 0
#endif
#include "common/spot.glsl"
#include "common/polygon.glsl"

uniform vec3 u_center;         // light position (world)
uniform vec3 u_axis_u;         // polygon half-extent along local X (world vector)
uniform vec3 u_axis_v;         // polygon half-extent along local Y
uniform vec3 u_emit_dir;       // unit emission axis (local -Z) in world space
uniform float u_radius;        // sphere radius, or tan(angle/2) for the sun
uniform vec3 u_radiance;       // polygon/sphere/sun radiance, or point intensity (W/sr), RGB
uniform int u_one_sided;       // area lights emit only towards u_emit_dir
uniform int u_soft_falloff;    // sphere lights: disk facing x (1) or true sphere (0)
uniform int u_spot_axisless;   // a spot with a zero Z scale: lit only where Cycles' light tree sees it

// Share of Cycles' samples in which its light tree still sees a spot without an emission axis: the float32
// operations of engine/core/irradiance.py cycles_radius_share, averaged over the same 64 distances around d.
float cycles_radius_share(vec3 to_light) {
    float d0 = sqrt(dot(to_light, to_light));
    float seen = 0.0;
    for (int j = 0; j < 64; j++) {
        float d = d0 * (1.0 + (float(j) - 31.5) * 3.814697265625e-6);   // steps of 2^-18
        float cos_u;
        if (u_soft_falloff == 1) {
            cos_u = d / sqrt(u_radius * u_radius + d * d);
        } else {
            float s = u_radius / d;
            cos_u = d > u_radius ? sqrt(1.0 - s * s) : -1.0;
        }
        seen += cos_u < 1.0 ? 1.0 : 0.0;
    }
    return seen / 64.0;
}

vec3 orthogonal(vec3 d) {
    return abs(d.z) < 0.9 ? normalize(cross(d, vec3(0, 0, 1))) : normalize(cross(d, vec3(0, 1, 0)));
}

// Cycles applies the cone per ray (the direction from the emitter point towards x), so a spot with a radius
// lights x only from the part of its disk whose rays fall inside the cone. Two quadratures of
// E/L = ∫ cosθ_x · cosθ_disk / d² · spot dA over the disk (centre `center` relative to x, facing x, radius ρ):
//  * the cone's footprint: rays that reach x inside the cone leave the disk's plane inside the cut of the
//    plane by the cone of half angle β = atan(u_spot_tan_wide) around -u_emit_dir with its apex at x (an
//    ellipse, or an unbounded conic). Where the cut's bounding box clipped to the disk's is smaller than ρ²
//    (a narrow spot whose disk is wide against its distance), a 12 × 12 grid of that box carries the integral;
//    cells over the whole disk would miss the footprint;
//  * otherwise the disk: 32 cells of equal solid angle seen from x, whose attenuation-weighted mean scales
//    the disk's exact form factor.
const int SPOT_GRID_T = 12, SPOT_GRID_S = 12;
uniform float u_spot_tan_wide;     // tan of the cone's widest half angle (the object scale widens one axis)

// E/L through the cone's footprint, or -1 where the footprint covers too much of the disk for it to pay.
float spot_footprint(vec3 center, float rho, vec3 n) {
    float H = length(center);
    vec3 normal = center / H;                       // the disk's plane, at distance H from x
    vec3 back = -u_emit_dir;                        // from x back towards where in-cone rays come from
    float cos_g = dot(back, normal);
    float beta = atan(u_spot_tan_wide);
    float gamma = acos(clamp(cos_g, -1.0, 1.0));
    if (gamma - beta >= 1.5707) return 0.0;         // the cone turns away from the plane
    bool bounded = gamma + beta < 1.55;
    float t0 = max(H * tan(max(gamma - beta, -1.55)), -rho);
    float t1 = bounded ? min(H * tan(gamma + beta), rho) : rho;
    float half_s = bounded ? min(H * sin(beta) / sqrt(cos(gamma + beta) * cos(gamma - beta)), rho) : rho;
    if (t1 <= t0) return 0.0;
    if ((t1 - t0) * 2.0 * half_s >= rho * rho) return -1.0;
    vec3 tilt = back - normal * cos_g;
    tilt = dot(tilt, tilt) > 1e-12 ? normalize(tilt) : orthogonal(normal);
    vec3 side = cross(normal, tilt);
    float dt = (t1 - t0) / float(SPOT_GRID_T), ds = 2.0 * half_s / float(SPOT_GRID_S);
    float sum = 0.0;
    for (int i = 0; i < SPOT_GRID_T; ++i) {
        float t = t0 + (float(i) + 0.5) * dt;
        for (int j = 0; j < SPOT_GRID_S; ++j) {
            float sd = -half_s + (float(j) + 0.5) * ds;
            if (t * t + sd * sd > rho * rho) continue;
            vec3 p = center + t * tilt + sd * side;
            float d2 = max(dot(p, p), 1e-30);
            vec3 w = p * inversesqrt(d2);
            sum += max(dot(n, w), 0.0) * dot(w, normal) / d2 * spot_attenuation(-p);
        }
    }
    return sum * dt * ds;
}

// Attenuation-weighted mean over the disk: `rings` × `sectors` cells of equal solid angle (the share of the
// disk's solid angle inside radius r is (1 − D/√(D² + r²)) / (1 − D/√(D² + ρ²))), weighted by the receiver's
// cosine. `split`: whether the cells or as many points on the rim disagree (the cone's edge or blend band
// crosses the disk).
float spot_disk_mean(vec3 center, vec3 u, vec3 v, vec3 n, int rings, int sectors, out bool split) {
    float D = length(center);
    float rho = length(u);
    float whole = 1.0 - D * inversesqrt(D * D + rho * rho);
    vec3 eu = u / rho, ev = v / rho;
    float sum = 0.0, weight = 0.0, lo = 1.0, hi = 0.0;
    for (int ring = 0; ring < rings; ++ring) {
        float k = 1.0 - whole * (float(ring) + 0.5) / float(rings);     // D/√(D² + r²) of this ring
        float r = D * sqrt(max(1.0 / (k * k) - 1.0, 0.0));
        for (int sector = 0; sector < sectors; ++sector) {
            float phi = 6.28318530718 * (float(sector) + 0.5 * float(ring & 1)) / float(sectors);
            vec3 p = center + r * (cos(phi) * eu + sin(phi) * ev);
            float w = max(dot(n, normalize(p)), 0.0);
            float a = spot_attenuation(-p);
            sum += w * a;
            weight += w;
            lo = min(lo, a);
            hi = max(hi, a);
        }
    }
    for (int sector = 0; sector < sectors; ++sector) {          // the rim, which no cell centre reaches
        float phi = 6.28318530718 * (float(sector) + 0.5) / float(sectors);
        float a = spot_attenuation(-center - cos(phi) * u - sin(phi) * v);
        lo = min(lo, a);
        hi = max(hi, a);
    }
    split = lo < hi;
    return weight > 0.0 ? sum / weight : spot_attenuation(-center);
}

// The disk's mean cone factor: 4 × 8 cells, and where the cone's edge crosses them, 12 × 24. Each cell lies
// wholly in or out of a hard edge (no blend), so the mean steps by one cell's share as the edge sweeps the
// disk from pixel to pixel: bands of ±1/32 that at the outer rim, where a few cells are lit, were tens of
// per cent of the light. Fuzz 18021 (a 0.6 m spot 8.5 m away), relative error against Cycles over 3500
// pixels: 0.069 with 4 × 8 cells, 0.031 with 8 × 16, 0.024 with 12 × 24, 0.020 with 16 × 32; Cycles' own
// (a second seed) 0.024. Fuzz 17001: 0.112 → 0.031 (Cycles' own 0.038).
float spot_over_disk(vec3 center, vec3 u, vec3 v, vec3 n) {
    bool split;
    float coarse = spot_disk_mean(center, u, v, n, 4, 8, split);
    return split ? spot_disk_mean(center, u, v, n, 12, 24, split) : coarse;
}

// The cone factor of a disk too small for the form factor's edge sum: Cycles tests the cone per emitter
// sample, so where the cone's edge or blend band crosses the disk (a rim point disagrees with the centre)
// the disk's mean (spot_over_disk) is taken, not the centre's value (fuzz seed 8411: a 2.2 cm spot 2.4 m away).
float spot_over_small_disk(vec3 center, vec3 dir, float rho, vec3 n) {
    float s = spot_attenuation(-center);
    if (rho <= 0.0) return s;
    vec3 u = orthogonal(dir) * rho;
    vec3 v = cross(dir, u);
    if (spot_attenuation(-center - u) == s && spot_attenuation(-center + u) == s
            && spot_attenuation(-center - v) == s && spot_attenuation(-center + v) == s) return s;
    return spot_over_disk(center, u, v, n);
}

// E/L of a cone of directions of half angle β (s2 = sin²β) whose axis makes cos_t with the normal, clipped to
// the receiver's hemisphere: Snyder's closed form ("Area light sources for real-time graphics", Microsoft
// Research tech. report MSR-TR-96-11, 1996), as written in Lagarde & de Rousiers, "Moving Frostbite to PBR"
// (SIGGRAPH 2014 course, §4.7.2, eq. 44). Exact up to β = 90° (a sun of 180°: the whole hemisphere around
// the axis, π(1 + cos_t)/2), where a disk of directions of radius tan β is no longer drawable.
float cap_form_factor(float cos_t, float s2) {
    if (cos_t * cos_t >= s2) return 3.14159265359 * s2 * max(cos_t, 0.0);    // wholly above or below
    float sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    float x = sqrt(max(1.0 / s2 - 1.0, 0.0));                                  // cot β
    float y = clamp(-x * cos_t / sin_t, -1.0, 1.0);
    float sty = sin_t * sqrt(max(1.0 - y * y, 0.0));
    return max((cos_t * acos(y) - x * sty) * s2 + atan(sty, x), 0.0);
}

// Cycles' diffuse BSDF never samples a direction below the geometric surface (bsdf_diffuse_sample rejects
// it), while its light sampling keeps every direction above the smooth shading normal's horizon. In the band
// between the two horizons only the light strategy counts, at its MIS weight, the power heuristic
// p_l²/(p_l² + p_b²) with p_b = cosθ_s/π the BSDF's pdf and p_l the light's (its pick probability over the
// solid angle it is sampled in). Measured with a plane whose custom normals lean 40° from its face, under a
// 3 rad sun (scripted in tests/test_irradiance_cycles.py): Cycles 0.950, the unweighted cone 0.987, weighted
// 0.950. band_loss returns ∫(1 − weight)·cosθ_s dω over the part of a cone of directions (axis, cos β) in
// that band, so E = L·(cap − band_loss). The band is the wedge between the two planes: ω = cosθ·a + sinθ·
// (cosψ·b0 − sinψ·ng), a along their common line, b0 in the geometric plane, ψ ∈ [0, δ] (δ the angle
// between the normals), dω = sinθ dθ dψ and cosθ_s = sinθ·sin(δ − ψ). Per ψ the cone cuts θ to one interval
// |θ − θ0| ≤ acos(cos β / R), exact, and midpoints integrate the smooth rest. The light's pdf is
// light_pdf / cos^pdf_power of the angle off the axis: power 0 for a cone sampled uniformly (a sun, a true
// sphere seen from outside), 3 for a disk facing x sampled by area (soft falloff: t²/(πr²·cos) with
// t = d/cos).
const int BAND_PSI = 6, BAND_THETA = 8;

// The wedge between the two horizons: its common line a, b0 in the geometric plane, its angle δ; false where
// the normals agree (no band).
bool band_wedge(vec3 ns, vec3 ng, out vec3 a, out vec3 b0, out float delta) {
    a = cross(ng, ns);
    float s = length(a);
    b0 = vec3(0.0);
    delta = 0.0;
    if (s < 1e-4) return false;
    a /= s;
    delta = atan(s, dot(ns, ng));
    b0 = cross(a, ng);
    return true;
}

// ∫(1 − weight)·cosθ_s over the half circle's arc θ ∈ [t0, t1] at ψ, the light's pdf p0 / |ω·axis|^power.
float band_arc(vec3 a, vec3 b, float t0, float t1, float psi, float delta, vec3 axis, float p0, float power) {
    float k = sin(delta - psi) * 0.318309886;       // p_b = k·sinθ
    float d_theta = (t1 - t0) / float(BAND_THETA);
    float sum = 0.0;
    for (int i = 0; i < BAND_THETA; ++i) {
        float t = t0 + (float(i) + 0.5) * d_theta;
        float st = sin(t);
        float pb2 = k * k * st * st;
        float pl = power > 0.0 ? p0 / pow(max(abs(dot(cos(t) * a + st * b, axis)), 1e-4), power) : p0;
        sum += st * st * pb2 / (pl * pl + pb2);
    }
    return sum * d_theta * sin(delta - psi);
}

float band_loss(vec3 ns, vec3 ng, vec3 axis, float cos_beta, float light_pdf, float pdf_power) {
    float sin_beta = sqrt(max(1.0 - cos_beta * cos_beta, 0.0));
    if (dot(axis, ng) >= sin_beta || dot(axis, ns) <= -sin_beta) return 0.0;   // wholly above / below
    vec3 a, b0;
    float delta;
    if (!band_wedge(ns, ng, a, b0, delta)) return 0.0;
    float a_axis = dot(a, axis), b0_axis = dot(b0, axis), ng_axis = dot(ng, axis);
    float d_psi = delta / float(BAND_PSI);
    float loss = 0.0;
    for (int j = 0; j < BAND_PSI; ++j) {
        float psi = (float(j) + 0.5) * d_psi;
        vec3 b = cos(psi) * b0 - sin(psi) * ng;
        float b_axis = dot(b, axis);
        float R = sqrt(a_axis * a_axis + b_axis * b_axis);
        if (R <= cos_beta) continue;
        float theta0 = atan(b_axis, a_axis);
        float half_width = acos(clamp(cos_beta / R, -1.0, 1.0));
        float t0 = max(theta0 - half_width, 0.0), t1 = min(theta0 + half_width, 3.14159265359);
        if (t1 > t0) loss += band_arc(a, b, t0, t1, psi, delta, axis, light_pdf, pdf_power);
    }
    return loss * d_psi;
}

// Solid angle of the triangle (a, b, c) seen from the origin (Van Oosterom & Strackee, "The solid angle of a
// plane triangle", IEEE Trans. Biomed. Eng. 30(2), 1983).
float triangle_solid_angle(vec3 a, vec3 b, vec3 c) {
    float la = length(a), lb = length(b), lc = length(c);
    float num = abs(dot(a, cross(b, c)));
    float den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    return 2.0 * atan(num, den);
}

// band_loss for an area light, the light picked alone: the rectangle or ellipse C + u·U + v·V (|u|, |v| ≤ 1,
// or u² + v² ≤ 1; C relative to x) instead of a cone. Cycles samples a rectangle uniformly over its solid
// angle (Ureña et al.'s spherical rectangles, kernel/light/area.h) and an ellipse by area (pdf t²/(A·cosθ_l)).
// Per ψ the wedge's half circle ω(θ) meets the light along one arc: the plane of that circle cuts the light's
// plane in a line, clipped to the shape in (u, v); its ends give θ, the band's θ ∈ [0, π] keeps a part.
float polygon_band_loss(vec3 ns, vec3 ng, vec3 C, vec3 U, vec3 V, vec3 emit, bool ellipse) {
    vec3 a, b0;
    float delta;
    if (!band_wedge(ns, ng, a, b0, delta)) return 0.0;
    float h = dot(C, emit);                           // the light's plane is at signed height h along emit
    float p0 = 0.0;
    if (ellipse) {
        p0 = h * h / (3.14159265359 * sqrt(dot(U, U) * dot(V, V)));   // p_l = h²/(A·|ω·emit|³)
    } else {
        vec3 p00 = C - U - V, p10 = C + U - V, p11 = C + U + V, p01 = C - U + V;
        float omega = triangle_solid_angle(p00, p10, p11) + triangle_solid_angle(p00, p11, p01);
        if (omega <= 0.0) return 0.0;
        p0 = 1.0 / omega;
    }
    float d_psi = delta / float(BAND_PSI);
    float loss = 0.0;
    for (int j = 0; j < BAND_PSI; ++j) {
        float psi = (float(j) + 0.5) * d_psi;
        vec3 b = cos(psi) * b0 - sin(psi) * ng;
        vec3 m = cross(a, b);                         // normal of the circle's plane
        // The line m·(C + u·U + v·V) = 0 in (u, v): α·u + β·v + γ = 0, clipped to the shape.
        float al = dot(m, U), be = dot(m, V), ga = dot(m, C);
        float nn = al * al + be * be;
        if (nn < 1e-20) continue;
        vec2 f = -ga * vec2(al, be) / nn, dir = vec2(-be, al) * inversesqrt(nn);
        float s0, s1;
        if (ellipse) {
            float d2 = dot(f, f);
            if (d2 >= 1.0) continue;
            s1 = sqrt(1.0 - d2); s0 = -s1;
        } else {
            s0 = -1e9; s1 = 1e9;            // unbounded until the box clips it
            for (int k = 0; k < 2; ++k) {
                if (abs(dir[k]) < 1e-12) { if (abs(f[k]) > 1.0) { s1 = -1e9; } continue; }
                float e0 = (-1.0 - f[k]) / dir[k], e1 = (1.0 - f[k]) / dir[k];
                s0 = max(s0, min(e0, e1)); s1 = min(s1, max(e0, e1));
            }
            if (s1 <= s0) continue;
        }
        vec3 q0 = C + (f.x + s0 * dir.x) * U + (f.y + s0 * dir.y) * V;
        vec3 q1 = C + (f.x + s1 * dir.x) * U + (f.y + s1 * dir.y) * V;
        float th0 = atan(dot(q0, b), dot(q0, a)), th1 = atan(dot(q1, b), dot(q1, a));
        float lo = min(th0, th1), hi = max(th0, th1);
        if (hi - lo > 3.14159265359) { lo = hi; hi = 3.14159265359; }    // the arc passes through -a
        float t0 = max(lo, 0.0), t1 = min(hi, 3.14159265359);
        if (t1 > t0) loss += band_arc(a, b, t0, t1, psi, delta, emit, p0, ellipse ? 3.0 : 0.0);
    }
    return loss * d_psi;
}

// The suns of the scene for Cycles' light tree, which picks one per light sample (kernel/light/tree.h): all
// distant lights share one leaf, whose emitters it picks with probability ½(max_i/Σmax + min_i/Σmin), the
// importance bounds of a cone of half angle θ_u seen at incidence θ_i from the shading normal:
// max = E·cos(max(θ_i − θ_u, 0)) (0 where that is below the horizon), min = E·max(cos(θ_i + θ_u), 0)·cosθ_u,
// with E the light's strength (its channel mean); where every min is 0, ½(max_i/Σmax + 1/count of max > 0).
// Only the suns are counted: with point, spot or area lights in the scene the pick is smaller than this.
const int MAX_SUNS = 8;
uniform int u_sun_count;              // distant lights, sharp ones too, at most MAX_SUNS (engine/core/shading.py)
uniform int u_sun_self;               // this light's index among them; -1: not a sun
uniform vec4 u_suns[MAX_SUNS];        // xyz towards the sun (unit), w strength
uniform float u_sun_cos_half[MAX_SUNS];

float sun_pick(vec3 n) {
    float own_max = 0.0, own_min = 0.0, sum_max = 0.0, sum_min = 0.0, seen = 0.0;
    for (int i = 0; i < u_sun_count; ++i) {
        float cu = u_sun_cos_half[i], su = sqrt(max(1.0 - cu * cu, 0.0));
        float ci = dot(u_suns[i].xyz, n), si = sqrt(max(1.0 - ci * ci, 0.0));
        float c_min = ci >= cu ? 1.0 : ci * cu + si * su;
        if (c_min < 0.0) continue;
        float hi = c_min * u_suns[i].w;
        float lo = max(ci * cu - si * su, 0.0) * u_suns[i].w * cu;
        sum_max += hi; sum_min += lo; seen += hi > 0.0 ? 1.0 : 0.0;
        if (i == u_sun_self) { own_max = hi; own_min = lo; }
    }
    if (sum_max <= 0.0) return 1.0;
    float by_min = sum_min > 0.0 ? own_min / sum_min : (own_max > 0.0 ? 1.0 / seen : 0.0);
    return 0.5 * (own_max / sum_max + by_min);
}

// A light that subtends less than SMALL_LIGHT (extent / distance) is integrated as a point: E = L·A·cosθ_x·
// cosθ_light / d², within (SMALL_LIGHT)² of the exact form factor. The edge formula cannot be used there in
// float32: the edges' angles (~1e-5 rad for a 1e-4 m light 2 m away) drown in the rounding of the normalised
// vertices and their cross products (measured: errors of 6–70× on llvmpipe).
const float SMALL_LIGHT = 1e-2;

vec3 light_irradiance(vec3 x, vec3 n, vec3 ng) {
    vec3 to_light = u_center - x;
    if (LIGHT_SHAPE == LIGHT_POLYGON) {
        if (u_one_sided == 1 && dot(x - u_center, u_emit_dir) <= 0.0) return vec3(0.0);
        float d2 = dot(to_light, to_light);
        float extent2 = dot(u_axis_u, u_axis_u) + dot(u_axis_v, u_axis_v);
        if (extent2 < SMALL_LIGHT * SMALL_LIGHT * d2) {
            vec3 w = to_light * inversesqrt(max(d2, 1e-38));
            float area = (POLY_SIDES == 4 ? 4.0 : 3.14159265359) * length(cross(u_axis_u, u_axis_v));
            return u_radiance * (area * max(dot(n, w), 0.0) * abs(dot(w, u_emit_dir)) / max(d2, 1e-38));
        }
        float ff = 0.5 * clipped_polygon_sum(to_light, u_axis_u, u_axis_v, POLY_SIDES, n);
        return u_radiance * max(ff - polygon_band_loss(n, ng, to_light, u_axis_u, u_axis_v, u_emit_dir,
                                                       POLY_SIDES > 4), 0.0);
    }
    if (LIGHT_SHAPE == LIGHT_POINT) {
        float spot = LIGHT_SPOT == 1 ? spot_attenuation(-to_light) : 1.0;
        float d2 = max(dot(to_light, to_light), 1e-30);
        float lobe = u_one_sided == 1 ? max(dot(-to_light, u_emit_dir), 0.0) / sqrt(d2) : 1.0;
        return u_radiance * spot * lobe * max(dot(n, to_light), 0.0) / (d2 * sqrt(d2));
    }
    if (LIGHT_SHAPE == LIGHT_SUN) {
        float cos_t = dot(n, -u_emit_dir);
        if (u_radius <= 0.0) return u_radiance * max(cos_t, 0.0);
        float t2 = u_radius * u_radius;
        float cap = cap_form_factor(cos_t, t2 / (1.0 + t2));
        if (u_sun_self >= 0) {
            float cos_beta = inversesqrt(1.0 + t2);
            float pdf = sun_pick(n) / (6.28318530718 * (1.0 - cos_beta));   // uniform over the cone
            cap = max(cap - band_loss(n, ng, -u_emit_dir, cos_beta, pdf, 0.0), 0.0);
        }
        return u_radiance * cap;
    }
    float axisless = LIGHT_SPOT == 1 && u_spot_axisless == 1 ? cycles_radius_share(to_light) : 1.0;
    if (axisless <= 0.0) return vec3(0.0);
    vec3 radiance = u_radiance * axisless;
    vec3 dir, center;
    float rho;
    if (u_soft_falloff == 1) {
        float d = length(to_light);
        dir = d > 0.0 ? to_light / d : n;        // disk of radius r at the centre, facing x
        center = to_light;
        rho = u_radius;
    } else {
        float d = length(to_light);
        // Inside a true sphere every direction of the hemisphere meets the emitter: E = π·L, with no spot
        // cone (Cycles kernel/light/spot.h). A spot's sphere, though, is hit only by rays heading towards
        // its centre (spot_light_intersect is one-sided), so Cycles' MIS keeps half of the light samples'
        // share plus half of the BSDF rays' share, (1 + cosθ)/2 of the hemisphere: E = π·L·(3 + cosθ)/4.
        if (d <= u_radius) {
            float cos_c = d > 0.0 ? dot(n, to_light) / d : 1.0;
            if (LIGHT_SPOT == 1) return radiance * (3.14159265359 * (0.75 + 0.25 * cos_c));
            // Cycles samples the inside of a sphere over the cosine hemisphere (point_light_sample): its pdf
            // is the BSDF's, so the band between the horizons keeps half, a loss of ∫_band cosθ_s dω / 2 =
            // π(1 − cos δ)/4 (band_loss's wedge integrated whole).
            return radiance * (3.14159265359 * (1.0 - 0.25 * (1.0 - clamp(dot(n, ng), -1.0, 1.0))));
        }
        dir = to_light / max(length(to_light), 1e-30);
        float r2 = u_radius * u_radius;
        center = dir * ((d * d - r2) / d);       // tangency circle: centre and radius
        rho = u_radius * sqrt(max(d * d - r2, 0.0)) / d;
    }
    float c2 = dot(center, center);
    if (rho * rho < SMALL_LIGHT * SMALL_LIGHT * c2) {
        // A small disk facing x (cosθ_light = 1): E = L·π·ρ²·cosθ_x / d², with the cone over the disk.
        float spot = LIGHT_SPOT == 1 ? spot_over_small_disk(center, dir, rho, n) : 1.0;
        return radiance * (spot * 3.14159265359 * rho * rho * max(dot(n, dir), 0.0) / max(c2, 1e-38));
    }
    vec3 u = orthogonal(dir) * rho;
    vec3 v = cross(dir, u);
    if (LIGHT_SPOT == 1) {
        float through_footprint = spot_footprint(center, rho, n);
        if (through_footprint >= 0.0) return radiance * through_footprint;
    }
    float spot = LIGHT_SPOT == 1 ? spot_over_disk(center, u, v, n) : 1.0;
    if (spot <= 0.0) return vec3(0.0);
    // The smooth-normal band (band_loss), the light picked alone: Cycles samples the soft-falloff disk by
    // area, the true sphere's cone uniformly (point_light_sample). The spot's cone as its mean over the disk.
    float D2 = dot(center, center);
    float cos_beta = sqrt(D2 / (D2 + rho * rho));
    float loss = u_soft_falloff == 1
        ? band_loss(n, ng, dir, cos_beta, D2 / (3.14159265359 * rho * rho), 3.0)
        : band_loss(n, ng, dir, cos_beta, 1.0 / (6.28318530718 * (1.0 - cos_beta)), 0.0);
    return radiance * spot * max(0.5 * clipped_polygon_sum(center, u, v, 32, n) - loss, 0.0);
}

// What the shading passes store for a covered receiver: irradiance clamped at zero, NaN/Inf dropped, and its
// scalar weight (the channel mean) in alpha. irradiance.comp (per pixel) and accumulate_msaa.comp (per
// sample) share it, so a sample that is its pixel's first gets bit-identical values.
vec4 receiver_irradiance(vec3 x, vec3 n, vec3 ng) {
    vec3 e = max(light_irradiance(x, n, ng), vec3(0.0));
    if (any(isnan(e)) || any(isinf(e))) e = vec3(0.0);
    return vec4(e, dot(e, vec3(1.0 / 3.0)));
}
