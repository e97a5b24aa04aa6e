// Shared by every shadow-map technique: where a world point falls in the light's map, and the bias that
// keeps a surface from shadowing itself. Uniforms are filled from engine/lightview.py LightView.uniforms().
// A shader that walks several views in one pass (REFERENCE's batches) defines LIGHT_VIEW_PER_LAYER and sets
// the view's values itself, as plain variables, before each use.
#ifdef LIGHT_VIEW_PER_LAYER
#define LIGHT_VIEW_VALUE
#else
#define LIGHT_VIEW_VALUE uniform
#endif
LIGHT_VIEW_VALUE mat4 u_light_view;
LIGHT_VIEW_VALUE vec4 u_light_window;      // x0, x1, y0, y1: tangents at unit depth, or metres for an ortho view
LIGHT_VIEW_VALUE int u_light_ortho;
LIGHT_VIEW_VALUE vec2 u_light_depth_range; // near, far
LIGHT_VIEW_VALUE ivec2 u_map_size;
LIGHT_VIEW_VALUE float u_texel_tan;        // window units per texel
uniform float u_bias;             // texels, scaled by the receiver's slope
uniform float u_normal_offset;    // texels along the geometric normal
uniform float u_terminator_offset = 0.0;  // Cycles' Shadow Terminator Geometry Offset (make_lit_receiver)

#include "common/spot.glsl"

vec3 light_local(vec3 p) {
    return (u_light_view * vec4(p, 1.0)).xyz;
}

// Window coordinates of a light-local point: tangents (perspective) or metres (ortho).
vec2 window_coords(vec3 l) {
    float depth = max(-l.z, 1e-30);
    return u_light_ortho == 1 ? l.xy : l.xy / depth;
}

// Window units per texel along each axis, and the window position of a map position (texels, 0 … size):
// the inverse of map_coords' first two coordinates.
vec2 map_texel_window() {
    return (u_light_window.yw - u_light_window.xz) / vec2(u_map_size);
}

vec2 map_window(vec2 map_pos) {
    return u_light_window.xz + map_pos * map_texel_window();
}

// Map texel coordinates (0 … size) and linear depth of a light-local point.
vec3 map_coords(vec3 l) {
    vec2 w = window_coords(l);
    vec2 uv = (w - u_light_window.xz) / (u_light_window.yw - u_light_window.xz);
    return vec3(uv * vec2(u_map_size), -l.z);
}

// World size of one texel at a given depth.
float texel_world(float depth) {
    return u_light_ortho == 1 ? u_texel_tan : u_texel_tan * depth;
}

// The world size of one texel at a receiver (world p, light-local l), but never finer than what float32
// tells apart there: positions, their light-local transform and the maps' depths each round to about 2^-23
// of their magnitude, so a bias and normal offset scaled from a texel finer than a few such steps (a window
// of millimetres over a receiver tens of metres from the origin or the light) let the surface shadow
// itself in stripes. Far below any texel of an ordinary view (19 µm at 10 m).
const float FLOAT_STEPS = 8.0;
float receiver_texel(vec3 p, vec3 l) {
    return max(texel_world(max(-l.z, 0.0)), FLOAT_STEPS * 1.1920929e-7 * (length(p) + length(l)));
}

// A receiver as the shadow-map techniques see it: its light-local position pushed off the surface along
// the geometric normal (normal-offset bias), that normal in light space, its map coordinates (texels,
// depth) and the depth bias to subtract before comparing with the map. `through_surface`: the light lies
// behind the receiver's own triangle, see make_lit_receiver.
struct Receiver {
    vec3 local;
    vec3 normal;
    vec3 map;
    float bias;
    bool through_surface;
    float own_plane;    // dot(normal, point) of the receiver's own surface (before any lift or offset)
    vec3 start;         // the light-local point the shadow ray leaves from: local before the normal offset
    vec3 surface;       // the light-local point on the receiver's surface (before any lift or offset), where
                        // Cycles takes the directions to the light's points (its BSDF's and light's cosines)
    float texel;        // world size of a map texel at the receiver (receiver_texel)
    float slope;        // tan of the receiver's angle to the view's origin, at most 10
};

// The depth bias grows with the receiver's slope by this much per unit of tan θ. Every comparison follows the
// receiver's own plane (receiver_depth_at), which a planar receiver's texels match exactly at any slope, so
// the slope term only hid real shadows: at 1 per unit, creases and contact shadows within (0.5 + tan θ)
// texels of a grazing receiver were lost. Against Cycles' shadow of the light centre (fuzz.centre_errors),
// HARD over fuzz seeds 28000-28176 and 29000-29139 came closer on 20 scenes and farther on none with 0.1
// (and a normal offset of 0.25); with no slope term it was no worse either, and with no constant term
// striped acne spread over 254 of 276 scenes.
const float SLOPE_BIAS = 0.1;

// The depth bias at the receiver (world units): u_bias times half a texel plus `per_slope` texels per unit of
// its tan θ.
float depth_bias(Receiver r, float per_slope) {
    return u_bias * r.texel * (0.5 + per_slope * r.slope);
}

// The depth bias with the whole slope term (one texel per unit of tan θ), for the tests whose error grows with
// the receiver's slope beyond one texel of its plane: SPSM's triangles rebuilt from 16-bit planes, and the
// blocker searches and filters over a whole region (BACKPROJECTION, PCSS, PVSM), across which a curved
// receiver leaves its tangent plane by more the more grazing it is (with SLOPE_BIAS there: fuzz 29074 SPSM
// 0.009 -> 0.59, 29014 BACKPROJECTION 0.078 -> 0.29, 29030 PCSS 0.057 -> 0.110).
float slope_scaled_bias(Receiver r) {
    return depth_bias(r, 1.0);
}

Receiver make_receiver(vec3 p, vec3 ng) {
    Receiver r;
    vec3 l = light_local(p);
    r.normal = mat3(u_light_view) * ng;
    vec3 to_light = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : normalize(-l);
    float cos_t = clamp(abs(dot(r.normal, to_light)), 1e-3, 1.0);
    float tan_t = min(sqrt(1.0 - cos_t * cos_t) / cos_t, 10.0);
    float texel = receiver_texel(p, l);
    r.start = l;
    r.surface = l;
    r.local = l + r.normal * (u_normal_offset * texel);
    r.map = map_coords(r.local);
    r.texel = texel;
    r.slope = tan_t;
    r.bias = depth_bias(r, SLOPE_BIAS);
    r.through_surface = false;
    r.own_plane = dot(r.normal, l);
    return r;
}

// The receiver as Cycles' shadow ray towards `to_light` (world, unit) leaves it (shadow_ray_offset), for a
// pixel with viewer-facing shading normal n and geometric normal ng and the terminator lift of
// common/gbuffer.frag: on a smooth triangle the ray starts lifted along n, by an amount that ramps up to
// the whole lift as the light nears either normal's horizon (over u_terminator_offset in cosine). A light
// behind the triangle (below ng) while n still faces it sends the ray into the surface the receiver lies
// on, which is meant to stop it: such a receiver is compared with the map as it is (through_surface),
// without the tangent-plane rule that keeps a surface from shadowing itself.
Receiver make_lit_receiver(vec3 p, vec3 ng, vec3 n, float lift, vec3 to_light) {
    float nl_signed = dot(n, to_light);
    float nl = abs(nl_signed);
    float ngl = dot(ng, to_light);
    vec3 q = p;
    if (u_terminator_offset > 0.0 && lift != 0.0) {
        float amount = nl < u_terminator_offset ? clamp(2.0 - (ngl + nl) / u_terminator_offset, 0.0, 1.0)
                                                : clamp(1.0 - ngl / u_terminator_offset, 0.0, 1.0);
        q += n * (lift * amount);
    }
    Receiver r = make_receiver(q, ng);
    r.surface = light_local(p);
    r.own_plane = dot(r.normal, r.surface);
    // Only while n faces the light: a light point below both horizons carries nothing itself, and the
    // techniques that stand for a whole light by its centre must not let the receiver's own object shadow
    // the part of the light that is above them (a cube's sides, a ball's far side under a wide light).
    r.through_surface = ngl <= 0.0 && nl_signed > 0.0;
    return r;
}

// make_lit_receiver with the shadow ray towards the view's own origin: the light centre, or a sun's
// direction for an orthographic view (the techniques that test one map from the centre).
Receiver make_view_receiver(vec3 p, vec3 ng, vec3 n, float lift) {
    vec3 to_origin = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : -light_local(p);
    return make_lit_receiver(p, ng, n, lift, normalize(transpose(mat3(u_light_view)) * to_origin));
}

#ifdef G_BUFFER_PIXELS
// The receiver at a G-buffer pixel (common/pixel.glsl), towards the view's origin.
Receiver pixel_receiver(ivec2 px) {
    vec4 geometric = texelFetch(g_geometric, px, 0);
    return make_view_receiver(texelFetch(g_position, px, 0).xyz, geometric.xyz, texelFetch(g_normal, px, 0).xyz,
                              geometric.w);
}
#endif

// A receiver depth that no texel is nearer than, so nothing in the map shadows it. A perspective view's depths
// are positive (its near plane lies in front of the eye), so 0 serves and keeps η (1/z) at +inf; a sun's
// orthographic depths are measured from a point among the receivers and are negative for whatever lies
// nearer the sun than that point (a wide sun's receivers facing away from its centre met such texels).
float no_blocker_depth() {
    return u_light_ortho == 1 ? -NO_OCCLUDER : 0.0;
}

// The plane dot(n, x) = c (light frame) along the map ray through `map_pos`: a point of the ray at depth z
// lies slope·z + offset above the plane (n's side). Returns (slope, offset); the ray crosses the plane at
// depth −offset/slope. Every test of a map ray against a receiver's plane starts from this.
vec2 plane_along_map_ray(vec3 n, float c, vec2 map_pos) {
    vec2 w = map_window(map_pos);
    return u_light_ortho == 1 ? vec2(-n.z, dot(n.xy, w) - c)     // the ray's point at depth z: (w, −z)
                              : vec2(dot(n.xy, w) - n.z, -c);    // the ray's point at depth z: z·(w, −1)
}

// Whether the view's origin (the light's centre: the eye at depth 0, or for a sun the direction towards
// it, depth → −∞) lies above the receiver's tangent plane.
bool centre_above_plane(Receiver r) {
    return u_light_ortho == 1 ? r.normal.z > 1e-6 : dot(r.normal, r.local) < 0.0;
}

// Whether the view's origin lies above the plane of the receiver's own surface (through the pixel's point, before
// the terminator lift and the normal offset move the shadow ray's start off it). A start lifted over the origin
// (a smooth low-poly surface lit at grazing: the lift of a smooth-shaded cube's face reaches a third of its
// size) has the origin below its plane while the surface itself still faces it: that ray leaves the start
// downwards and is blocked by whatever lies between the start and the light, which only the start's own depth
// tells (fuzz 30385: the lifted starts inside a small cube over a big smooth one, Cycles V 0, REFERENCE 0.4-1).
bool origin_above_own_surface(Receiver r) {
    return u_light_ortho == 0 && r.own_plane < 0.0;
}

// Depth along the map ray through `map_pos` below which a surface lies on the light's side of the receiver's
// tangent plane, less the bias: what a texel there must be nearer than to shadow the receiver. A ray from the
// receiver to a light point above its tangent plane stays above that plane, so nothing below it (the
// receiver's own surface, a convex object's far side, the face behind an edge) can shadow it; following the
// plane instead of using the centre depth also keeps a flat receiver from shadowing itself across a wide
// kernel (receiver-plane depth bias). When the map's origin lies on or below the plane, no ray of the map
// reaches the receiver from above it: nothing in the map counts as a blocker (no_blocker_depth), unless the
// shadow ray's start left the surface towards the origin (through_surface, origin_above_own_surface): then the
// start's own depth decides.
float receiver_depth_at(Receiver r, vec2 map_pos) {
    // Nothing beyond the receiver's own depth counts: a texel ray that runs past the receiver without meeting
    // its plane (grazing) hits surfaces behind it, which cannot shadow it.
    float far = r.map.z;
    if (!centre_above_plane(r)) return r.through_surface || origin_above_own_surface(r) ? far - r.bias
                                                                                    : no_blocker_depth();
    vec2 h = plane_along_map_ray(r.normal, dot(r.normal, r.local), map_pos);
    // With the origin above, the ray descends through the plane where slope < 0; one that never meets the
    // plane stays above it
    float z = h.x < 0.0 ? -h.y / h.x : far;
    return min(z, far) - r.bias;
}

// For a receiver aimed through its own smooth triangle (through_surface) while the terminator offset is on:
// Cycles then does not skip that triangle (shadow_ray_offset: "we're meant to hit this surface"), so the ray
// from the lifted point stops where it crosses the receiver's own plane, if the triangle is there. The map
// tells: the texel's stored depth `stored` at or in front of where the texel's ray meets that plane (within
// the slope-scaled bias) means the receiver's surface, or something nearer, is in the way. A ray that crosses
// the plane off the triangle (grazing, near an edge) finds the map farther than the plane: not stopped here.
bool own_surface_blocks(Receiver r, float stored, vec2 map_pos) {
    if (!r.through_surface || u_terminator_offset <= 0.0) return false;
    vec2 h = plane_along_map_ray(r.normal, r.own_plane, map_pos);
    if (abs(h.x) <= 1e-9) return false;     // a ray along the plane
    float z = -h.y / h.x;
    return z > 0.0 && stored <= z + r.bias;
}

// Hard comparison against one texel: 1 lit, 0 shadowed. Outside the map counts as lit.
float map_lit(sampler2D map, ivec2 texel, float receiver_depth) {
    if (any(lessThan(texel, ivec2(0))) || any(greaterThanEqual(texel, u_map_size))) return 1.0;
    return texelFetch(map, texel, 0).r < receiver_depth ? 0.0 : 1.0;
}

// The light-local point where the map ray through `map_pos` reaches depth `depth`.
vec3 map_ray_point(vec2 map_pos, float depth) {
    vec2 w = map_window(map_pos);
    return u_light_ortho == 1 ? vec3(w, -depth) : depth * vec3(w, -1.0);
}

// The triangle a map texel holds, known by its plane (normal n in the view's frame, not oriented; through the
// texel's surface point at depth `stored` on the map ray through `map_pos`), stands between the view's origin
// and the receiver's shadow-ray start when they lie strictly on opposite sides of that plane and that point lies
// in front of the receiver's own plane (a ray from the start to an origin above that plane stays above it, so
// the other face of a convex edge, behind it, cannot block it). The one map ray cannot tell where the triangle
// ends within the texel; what the test adds is what the depth bias hides: the far face of a concave crease,
// rising over the receiver within the bias (fuzz 1103: Suzanne's creases, lit at n·l 0.1 from 3 m, under
// 1 cm texels). The margins: the stored normal's rounding, and a quarter of the receiver's texel for its own
// triangle and float rounding (r.texel is at least 8 float steps at the receiver's distance; a tenth let
// stress zoomed_far's micrometre texels 30 m out shadow their own ball).
const float FACET_NORMAL_ERROR = 2e-3;      // radians: a unit normal in RGBA16F, 11-bit mantissas

// What both facet tests (facet_separates, facet_clears_receiver) weigh against a texel's facet plane, from the
// texel's surface point (the map ray through `map_pos` at `depth`): the way to the view's origin (a sun's ortho
// view: +Z) and the receiver's shadow-ray start.
void facet_frame(Receiver r, vec2 map_pos, float depth, out vec3 towards, out vec3 d) {
    vec3 s = map_ray_point(map_pos, depth);
    towards = u_light_ortho == 1 ? vec3(0.0, 0.0, 1.0) : -s;
    d = r.start - s;
}

bool facet_separates(Receiver r, vec3 n, vec2 map_pos, float stored) {
    if (dot(n, n) < 0.25 || !centre_above_plane(r)) return false;
    vec2 own = plane_along_map_ray(r.normal, dot(r.normal, r.start), map_pos);
    if (own.x >= 0.0 || stored >= -own.y / own.x) return false;
    vec3 towards, d;
    facet_frame(r, map_pos, stored, towards, d);
    float light_side = dot(n, towards);
    return abs(light_side) > FACET_NORMAL_ERROR * length(towards)
        && sign(light_side) * dot(n, d) < -FACET_NORMAL_ERROR * length(d) - 0.25 * r.texel;
}

#ifdef FACET_MAP
// The filters that reach texels away from the receiver's own (PCF, PCSS's search) compare them with the
// receiver's plane extended under them, and a surface that meets the receiver at a concave edge lies in front of
// that plane: a room's far wall at its corner, a wall where the floor meets it. Extended, the plane runs behind
// that surface, so it came out as a blocker and the corners of every room were drawn dark (fuzz 30032, 30088,
// 30118). What the texel holds is one triangle (the facet map's normal, structures/depth_map.py): when the
// receiver's shadow ray start and the whole light lie strictly on one side of its plane, no segment between
// them crosses that plane, so that triangle blocks no part of the light from the receiver. FACET_FILTER applies
// the test in map_lit_plane, and so in every filter built on it.
uniform sampler2D u_facet_map;
// Half extents of a box about the view's origin that holds the whole light, along the view's axes (metres; for
// a sun's ortho view the tangents of its directions (a, b, 1), and 0): core/light_shape.py light_reach_box.
// Zero: the origin alone (PCF, which stands for the light by its centre whatever its size).
uniform vec3 u_facet_light = vec3(0.0);

bool facet_clears_receiver(Receiver r, ivec2 texel, float depth) {
    vec3 n = texelFetch(u_facet_map, texel, 0).xyz;
    if (dot(n, n) < 0.25) return false;             // no facet known
    vec3 towards_light, d;
    facet_frame(r, vec2(texel) + 0.5, depth, towards_light, d);
    n = dot(n, towards_light) < 0.0 ? -n : n;
    // How far the light's box (or a sun's directions (a, b, 1)) reaches from its origin towards the plane
    float reach = dot(abs(n), u_facet_light);
    float light_side = u_light_ortho == 1 ? n.z - reach : dot(n, towards_light) - reach;
    // The receiver's side by more than the stored normal's half-float rounding can move the plane there (the
    // depth bias would be too much: a pixel a centimetre from a room's corner lies within it under a grazing light)
    return light_side > 0.0 && dot(n, d) > FACET_NORMAL_ERROR * length(d);
}
#endif

// Receiver-plane test of one texel: the plane's depth at the texel's own centre, where the map sampled it,
// so that a planar receiver matches its own texels exactly.
float map_lit_plane(sampler2D map, ivec2 texel, Receiver r) {
    float lit = map_lit(map, texel, receiver_depth_at(r, vec2(texel) + 0.5));
#ifdef FACET_FILTER
    if (lit == 0.0 && facet_clears_receiver(r, texel, texelFetch(map, texel, 0).r)) lit = 1.0;
#endif
    return lit;
}

// Bilinear percentage-closer comparison at a fractional texel position, each texel against the receiver's
// plane at that texel.
float map_lit_bilinear_plane(sampler2D map, vec2 pos, Receiver r) {
    vec2 p = pos - 0.5;
    ivec2 i = ivec2(floor(p));
    vec2 f = p - vec2(i);
    float a = map_lit_plane(map, i, r);
    float b = map_lit_plane(map, i + ivec2(1, 0), r);
    float c = map_lit_plane(map, i + ivec2(0, 1), r);
    float d = map_lit_plane(map, i + ivec2(1, 1), r);
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// The light as kernels over it see it (filled by techniques/base.py light_shape_uniforms).
uniform vec2 u_light_half;        // half extent in the view's frame: metres, or tan(angle/2) for a sun
uniform int u_light_round;        // disk, ellipse, sphere, sun: kernels over a disk
uniform int u_light_one_sided;    // 1: a planar emitter, whose own cosine counts in a sample's weight
uniform vec3 u_light_emit;        // its emission axis in the view's frame
uniform int u_light_sphere = 0;   // 1: a point or spot light with a radius, in a perspective view
// A spot with a radius in its own view: tan of its cone's half angle along the view's X and Y (core/light_shape.py
// spot_cone_clip), with common/spot.glsl's uniforms set; (0, 0) otherwise.
uniform vec2 u_spot_cone = vec2(0.0);

// Where the kernel's unit disk (or square) lands on the view's light plane z = 0 for one receiver: kernel
// position k stands for the plane point centre + axes·k, the ray from the receiver through it for its light
// point. A planar emitter lies in that plane: centre 0, axes diag(u_light_half), the same for every receiver;
// so does a sun's plane of tangents.
struct Footprint {
    vec2 centre;
    mat2 axes;
    vec2 half_box;      // half extent of the footprint's bounding box about its centre
    bool cone_clipped;  // a spot's cone cut it down to the disk centre ± half_box.x (u_spot_cone)
};

// A sphere light does not lie in the plane: each receiver sees it as a disk of radius R through its centre,
// facing the receiver (Cycles' point and spot lights with soft falloff, as REFERENCE samples them:
// techniques/averaged.py projected_disk_ball). Seen from the receiver, that disk covers an ellipse of the plane.
// With θ the receiver's angle off the view's axis, u the direction of its offset in the plane and t = R/D (D
// its distance), the disk's rim in the plane of u and the axis projects (from the receiver, similar triangles)
// to R/(cos θ + t sin θ) on the receiver's side and R/(cos θ − t sin θ) on the other; across u the rim lies in
// the plane itself, at ±R. So the ellipse is stretched along u by about 1/cos θ and its centre moves away from
// the receiver. The plain disk of radius R under-spreads off-axis receivers' penumbrae along u, and the
// stretch alone, as an axis-aligned box over a diagonal ellipse, over-spreads them across u
// (tests/test_sphere_footprint.py). Both denominators are held at 0.1 or more: a receiver near the light's
// plane would see an unbounded section.
Footprint light_footprint(vec3 local) {
    Footprint f;
    f.centre = vec2(0.0);
    f.axes = mat2(u_light_half.x, 0.0, 0.0, u_light_half.y);
    f.half_box = u_light_half;
    f.cone_clipped = false;
    float h = -local.z, dist = length(local);
    float r = u_light_half.x, rho = length(local.xy);
    // Behind the plane, or inside the sphere (no disk faces it): the plain disk.
    if (u_light_sphere == 0 || u_light_ortho == 1 || h <= 0.0 || !(dist > r)) return f;
    float t = r / dist, cos_t = h / dist, sin_t = rho / dist;
    float near = r / max(cos_t + t * sin_t, 0.1);
    float far = r / max(cos_t - t * sin_t, 0.1);
    float a = 0.5 * (near + far), c = 0.5 * (near - far);
    float b = r * inversesqrt(max(1.0 - (c * c) / (a * a), 1e-4));      // through ±R across u, at the centre
    vec2 u = rho > 1e-9 * dist ? local.xy / rho : vec2(1.0, 0.0), v = vec2(-u.y, u.x);
    f.centre = c * u;
    f.axes = a * outerProduct(u, u) + b * outerProduct(v, v);
    f.half_box = sqrt(a * a * u * u + b * b * v * v);
    if (u_spot_cone.x > 0.0) {
        // Cycles applies a spot's cone to each ray as it leaves the emitter (kernel/light/spot.h), so a receiver
        // sees only the emitter points whose ray to it lies inside the cone: a disk of radius h·tan about the
        // point straight above it along the axis. Under a narrow cone and a wide ball (fuzz 30111: a 1.4 m ball,
        // a 5.4° cone, whose shadows Cycles draws as sharp as a 0.3 m light's) the kernels cover the smallest of
        // three disks that hold what both regions share (the ball's footprint taken as the disk round its
        // ellipse): either region's, or for a lens the one on its chord; light_sample_weight weighs each point
        // by the cone and drops those off the ball's disk.
        float big = max(a, b), cone = h * max(u_spot_cone.x, u_spot_cone.y);
        vec2 between = local.xy - f.centre;
        float gap = length(between);
        vec2 centre = f.centre;
        float radius = big;
        if (cone < radius) { centre = local.xy; radius = cone; }
        if (gap > 1e-9 * dist && gap < big + cone) {
            float x0 = (gap * gap + big * big - cone * cone) / (2.0 * gap);     // the chord, from the ball's centre
            float chord = sqrt(max(big * big - x0 * x0, 0.0));
            if (x0 >= 0.0 && x0 <= gap && chord < radius) { centre = f.centre + between * (x0 / gap); radius = chord; }
        }
        if (radius < big) {
            f.centre = centre;
            f.axes = mat2(radius, 0.0, 0.0, radius);
            f.half_box = vec2(radius);
            f.cone_clipped = true;
        }
    }
    return f;
}

// For a footprint clipped by a spot's cone (u_spot_cone): the share of light a plane point q sends to a receiver
// at light-local `local`: 0 off the ball's disk that faces the receiver (the ray from it through q misses the
// disk), else Cycles' cone and blend for the ray from q to it (common/spot.glsl).
float spot_point_weight(vec3 local, vec2 q) {
    vec3 ray = local - vec3(q, 0.0);
    float along = dot(local, ray);
    if (!(along > 0.0)) return 0.0;
    vec3 on_disk = local - ray * (dot(local, local) / along);      // where the ray meets the disk's plane
    if (dot(on_disk, on_disk) > u_light_half.x * u_light_half.x) return 0.0;
    return spot_attenuation(transpose(mat3(u_light_view)) * ray);
}

// The light-plane point kernel position k stands for.
vec2 light_point(Footprint f, vec2 k) {
    return f.centre + f.axes * k;
}

// A world direction (a normal) in the light view's frame.
vec3 view_direction(vec3 world_dir) {
    return mat3(u_light_view) * world_dir;
}

// Unoccluded contribution at receiver r (shading normal n, view frame) of the light seen through light-plane
// point q (light_point: the plane point itself; for a sun the direction (q, 1)): the
// receiver's cosine, times the emitter's cosine over d² for a planar light and for the plane point of a
// sphere's footprint.
// A sun's directions are uniform in solid angle, which the tangent plane holds with density cos³θ
// (dΩ = cos³θ dA at unit height): with the receiver's cosine, (n·d)/|d|⁴ for d = (q, 1). Without that
// density a wide sun's rim directions counted up to 1/cos³θ too much (15× at 66° off its axis).
// Zero below the receiver's horizon: such a point carries no light, so it counts neither as lit nor occluded.
// The light's own factor in a perspective view, for the unit direction `dir` from the receiver to a plane
// point: a planar emitter's cosine; for a sphere's footprint the |cos| at which its rays cross the plane (a
// region of the plane too, light_footprint: its unit area holds a solid angle of |cos| / d², the same density
// as a planar emitter's); 1 otherwise.
float emitter_cosine(vec3 dir) {
    if (u_light_one_sided == 1) return max(-dot(dir, u_light_emit), 0.0);
    if (u_light_sphere == 1) return abs(dir.z);
    return 1.0;
}

float light_sample_weight(Receiver r, vec3 n, vec2 q) {
    if (u_light_ortho == 1) {
        vec3 d = vec3(q, 1.0);
        float q2 = dot(d, d);
        return max(dot(n, d), 0.0) / (q2 * q2);
    }
    vec3 to_sample = vec3(q, 0.0) - r.surface;
    float d2 = max(dot(to_sample, to_sample), 1e-30);
    vec3 dir = to_sample * inversesqrt(d2);
    float w = max(dot(n, dir), 0.0) / d2 * emitter_cosine(dir);
    return u_spot_cone.x > 0.0 && w > 0.0 ? w * spot_point_weight(r.local, q) : w;
}
