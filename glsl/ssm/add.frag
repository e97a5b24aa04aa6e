// Appendix A workaround: one batch's FP16 sum, added (by FP16 blending) into the running total.
uniform sampler2D u_batch;
layout(location = 0) out vec2 f_sum;

void main() {
    f_sum = texelFetch(u_batch, ivec2(gl_FragCoord.xy), 0).rg;
}
