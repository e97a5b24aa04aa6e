// A light seen through several views (cube faces): copy one view's visibility into the light's visibility
// for the pixels that view owns (engine/render/pipeline.py _face_visibility). A face with nothing that can
// shadow its pixels writes 1.
#include "common/pixel.glsl"

uniform sampler2D u_view_visibility;  // this view's V (R32F)
uniform sampler2D u_view_rgb;         // this view's coloured V, when u_has_rgb
uniform int u_unshadowed;
uniform int u_has_rgb;
layout(r32f, binding = 0) uniform image2D u_visibility;
layout(rgba32f, binding = 1) uniform image2D u_visibility_rgb;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (!pixel_in_image(px) || !pixel_owned(px)) return;     // the view's own pixels (Frame.view_of)
    float v = u_unshadowed == 1 ? 1.0 : texelFetch(u_view_visibility, px, 0).r;
    vec3 rgb = (u_unshadowed == 0 && u_has_rgb == 1) ? texelFetch(u_view_rgb, px, 0).rgb : vec3(v);
    imageStore(u_visibility, px, vec4(v));
    imageStore(u_visibility_rgb, px, vec4(rgb, 1.0));
}
