in float v_depth;
layout(location = 0) out float f_depth;

void main() {
    f_depth = v_depth;
}
