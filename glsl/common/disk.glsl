// The share of the unit disk inside an axis-aligned rectangle, in closed form: a round light (disk, ellipse,
// sun) in coordinates where its bounding rectangle is [-1, 1]² (an ellipse is then the unit disk).
#ifndef DISK_GLSL
#define DISK_GLSL

// Area of the unit disk inside the rectangle spanned by the origin and (a, b): odd in each argument, so any
// rectangle's area is four signed corners. For |a|, |b| ≤ 1 it is a·b up to where the circle's height falls
// to b (x = √(1 − b²)), plus the circle's own area ∫√(1 − x²) dx = (x√(1 − x²) + asin x)/2 beyond.
float disk_corner(float a, float b) {
    float x = min(abs(a), 1.0), y = min(abs(b), 1.0);
    float xs = sqrt(max(1.0 - y * y, 0.0));
    float area = x <= xs ? x * y
               : xs * y + 0.5 * (x * sqrt(max(1.0 - x * x, 0.0)) + asin(x) - xs * y - asin(xs));
    return sign(a) * sign(b) * area;
}

// Share of the unit disk's area inside the rectangle r = (x0, y0, x1, y1): negative where exactly one axis
// runs backwards (x1 < x0 or y1 < y0), as the rectangle's own signed area.
float disk_share(vec4 r) {
    return (disk_corner(r.z, r.w) - disk_corner(r.x, r.w) - disk_corner(r.z, r.y) + disk_corner(r.x, r.y))
           * 0.31830988618;     // 1/π
}
#endif
