// The 128-bit triangle texel of the conservative map (Lecocq et al. 2014, "Sub-Pixel Shadow Mapping",
// §3.3) and the depth conventions shared by the writer (raster.frag) and its readers (glsl/spsm/).
//
//   R, G, B  the three 2D vertices, x in the low and y in the high 16 bits: signed fixed point relative to
//            the texel's centre, VERT_SCALE steps per texel (±511 texels reach)
//   A        high 16 bits: z̃, the triangle plane's linear light depth at the texel centre, normalised to the
//            light view's [near, far]; low 16 bits: the slopes along x (bits 8–15) and y (bits 0–7),
//            quantised by Q (§3.4, Eq. 2–4)
//
// Depth that is affine across the map is the nearness η = 1 − window depth (a perspective view: affine
// in 1/z; an ortho view: linear), 1 at the near plane and 0 at the far one. Eq. 1 extrapolates η.
// Slopes are quantised as dimensionless slopes s = −(dη/dx)/J, J = −dη/dz × the lateral size of one texel
// at the reference depth (slope_scale): at that depth atan(s) is the surface's tilt away from facing the
// light.
// Include after common/light_view.glsl (u_light_depth_range, u_light_ortho come from there).
uniform vec2 u_texel_window;        // window units per texel along x and y
uniform float u_quant_n;            // exponent n of Q: 1 (linear in angle), 3, 5 (the paper's)

const float VERT_SCALE = 64.0;
const float VERT_REACH = 511.0;
const float PI_CM = 3.14159265358979;
const uint Q_MIN = 1u;              // Q away from 0 and 254: tan(±π/2) flips sign in float32
const uint Q_MAX = 253u;

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }

float eta_from_depth(float z) {
    float n = u_light_depth_range.x, f = u_light_depth_range.y;
    return u_light_ortho == 1 ? (f - z) / (f - n) : n * (f - z) / (z * (f - n));
}

float depth_from_eta(float eta) {
    float n = u_light_depth_range.x, f = u_light_depth_range.y;
    if (u_light_ortho == 1) return f - eta * (f - n);
    return n * f / max(eta * (f - n) + n, 1e-30);
}

// −dη/dz times the lateral size of one texel, per axis, at the view's reference depth √(near·far) (any
// fixed depth decodes exactly; this one keeps atan's useful range over the view's depths). A triangle's
// dη/dx is constant, so its codes are too: the geometry stage quantises once per triangle.
vec2 slope_scale() {
    float n = u_light_depth_range.x, f = u_light_depth_range.y;
    if (u_light_ortho == 1) return u_texel_window / (f - n);
    float z_ref = sqrt(n * f);
    return n * f * u_texel_window / ((f - n) * z_ref);
}

// Q(d) = 127·(1 + ((2/π)·atan d)^n), the odd power keeping the sign (§3.4, Eq. 3).
uint quantise_slope(float d) {
    float x = atan(d) * (2.0 / PI_CM);
    float y = sign(x) * pow(abs(x), u_quant_n);
    return uint(clamp(round(127.0 * (1.0 + y)), float(Q_MIN), float(Q_MAX)));
}

uint pack_vertex(vec2 v) {
    ivec2 q = ivec2(round(clamp(v, -VERT_REACH, VERT_REACH) * VERT_SCALE));
    return (uint(q.x) & 0xFFFFu) | ((uint(q.y) & 0xFFFFu) << 16);
}

vec2 unpack_vertex(uint bits) {
    // Sign-extend each 16-bit half.
    return vec2(float(int(bits << 16) >> 16), float(int(bits) >> 16)) / VERT_SCALE;
}

float normalised_depth(float z) {
    float n = u_light_depth_range.x, f = u_light_depth_range.y;
    return clamp((z - n) / (f - n), 0.0, 1.0);
}

// The depth that one step of z̃ spans.
float depth_step() {
    return (u_light_depth_range.y - u_light_depth_range.x) / 65535.0;
}

uint pack_depth_slopes(float z, uint q_xy) {
    uint zq = uint(round(normalised_depth(z) * 65535.0));
    return (zq << 16) | q_xy;
}
