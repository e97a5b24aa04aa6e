// Budget-map importance of the object drawn (Schwarz & Stamminger 2008, §4.2: an importance source), drawn
// from the camera after common/depth.vert: the nearest surface's object decides the pixel.
in float v_depth;
uniform float u_value;
out float f_importance;

void main() {
    f_importance = u_value;
}
