// A true sphere light's maps for receivers outside it (averaged.py): Cycles' shadow rays end on the sphere's
// surface, so nothing inside the sphere occludes them, and the layered passes (Frame.render_depth_layers,
// render_facet_layers) drop the casters' fragments that lie inside it. depth_layers.geom passes the world
// position under the same define.
#ifndef CLIP_SPHERE_GLSL
#define CLIP_SPHERE_GLSL
#ifdef CLIP_SPHERE
in vec3 v_position;
uniform vec4 u_clip_sphere;     // centre, r²

bool inside_clip_sphere() {
    vec3 from_centre = v_position - u_clip_sphere.xyz;
    return dot(from_centre, from_centre) < u_clip_sphere.w;
}
#else
bool inside_clip_sphere() {
    return false;
}
#endif
#endif
