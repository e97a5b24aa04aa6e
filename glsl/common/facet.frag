// The facet map (structures/depth_map.py): for the nearest caster surface at each texel, the one the depth map
// keeps, its plane's normal in the light view's frame, not oriented (light_view.glsl facet_clears_receiver
// turns it to the light). The screen derivatives of the light-view position span the triangle's plane, helper
// fragments beyond an edge included, so this is the triangle's own normal; (0, 0, 0) where they do not span it
// (a triangle seen edge-on).
in vec3 v_view;
layout(location = 0) out vec4 f_normal;

void main() {
    vec3 n = cross(dFdx(v_view), dFdy(v_view));
    float len = length(n);
    f_normal = vec4(len > 1e-30 ? n / len : vec3(0.0), 0.0);
}
