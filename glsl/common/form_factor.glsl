// The share of a light's irradiance that a rectangle of the light plane carries to a receiver facing the
// light at height z over its foot point: the differential-area-to-parallel-rectangle form factor, up to a
// constant. With corner coordinates a, b in units of z,
//     F(a, b) = a/√(1+a²)·atan(b/√(1+a²)) + b/√(1+b²)·atan(a/√(1+b²)),
// odd in each argument, so any axis-aligned rectangle is four signed corners. Used by SSM and PVSM's
// irradiance weighting.
float ff_corner(float a, float b) {
    float ra = inversesqrt(1.0 + a * a), rb = inversesqrt(1.0 + b * b);
    return a * ra * atan(b * ra) + b * rb * atan(a * rb);
}

float ff_rect(vec4 r) {          // x0, y0, x1, y1
    return ff_corner(r.z, r.w) - ff_corner(r.x, r.w) - ff_corner(r.z, r.y) + ff_corner(r.x, r.y);
}
