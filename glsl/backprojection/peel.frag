// Depth peeling from the light's centre (Schwarz & Stamminger 2007, §3.2): layer k keeps, per texel, the
// nearest fragment strictly behind layer k-1, so occluders hidden from the centre (the single-silhouette
// case) still become micro-occluders. Used with common/depth.vert (linear depth along the light's -Z).
in float v_depth;
uniform sampler2D u_prev;       // the previous layer (R32F linear depth, NO_OCCLUDER where empty)
uniform float u_peel_eps;       // relative depth separation between layers
layout(location = 0) out float f_depth;

void main() {
    float prev = texelFetch(u_prev, ivec2(gl_FragCoord.xy), 0).r;
    if (prev >= EMPTY_DEPTH || v_depth <= prev * (1.0 + u_peel_eps)) discard;
    f_depth = v_depth;
}
