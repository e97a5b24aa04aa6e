// The penumbra-spread relation, the GLSL twin of engine/core/light_shape.py penumbra_spread (Atty et al.
// 2006 §3.3–3.4; Schwarz & Stamminger 2007 §2.1; Fernando 2005): window units of penumbra per unit of light
// half extent between an occluder at depth z and a receiver at depth d,
//     1/z − 1/d   (perspective view: window units are tangents at unit depth, h in metres)
//     d − z       (a sun's orthographic view: window units are metres, h is tan(angle/2)).
#ifndef PENUMBRA_GLSL
#define PENUMBRA_GLSL
float penumbra_spread(float z, float d, int ortho) {
    return ortho == 1 ? d - z : 1.0 / z - 1.0 / d;
}

// The same, never negative (an occluder behind the receiver widens nothing) and finite for an occluder on
// the light plane (z floored at 1e-30 m, perspective only).
float penumbra_spread_clamped(float z, float d, int ortho) {
    return max(penumbra_spread(ortho == 1 ? z : max(z, 1e-30), d, ortho), 0.0);
}
#endif
