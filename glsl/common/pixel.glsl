// Per-pixel inputs shared by the compute passes: the camera G-buffer and this light's irradiance.
layout(local_size_x = 8, local_size_y = 8) in;
#define G_BUFFER_PIXELS     // common/light_view.glsl adds pixel_receiver

uniform sampler2D g_position;
uniform sampler2D g_normal;
uniform sampler2D g_geometric;
uniform sampler2D g_irradiance;   // rgb: unoccluded irradiance from this light, a: its scalar weight
uniform ivec2 u_image_size;
// A light seen through several views (engine/render/pipeline.py _face_visibility): the view each lit pixel
// takes (-1 where the light is not lit), and the one being made or merged (-1: the light's single view, which
// takes every pixel). Gpu/frame.py's dispatch sets both inside Frame.view_of.
uniform sampler2D u_view_owner;
uniform float u_view_index = -1.0;

bool pixel_in_image(ivec2 px) {
    return all(lessThan(px, u_image_size));
}

// True where the view being made or merged takes this pixel.
bool pixel_owned(ivec2 px) {
    return u_view_index < 0.0 || texelFetch(u_view_owner, px, 0).r == u_view_index;
}

// True where this light reaches a covered pixel that the view being made owns; only those pixels need a
// visibility from it (the others take another view's).
bool pixel_lit(ivec2 px) {
    return texelFetch(g_position, px, 0).w > 0.0 && texelFetch(g_irradiance, px, 0).a > 0.0 && pixel_owned(px);
}
