// Layered depth pass (Frame.render_depth_layers): each triangle drawn once per view of the batch (REFERENCE's
// light samples), into that view's layer of a texture array (one geometry-shader invocation per layer), as
// common/depth.vert would draw it into the view's own map. A layer's map may be smaller than the array:
// `scale` (its size over the array's) maps its clip square onto its corner of the layer; 1 leaves the
// position exactly as depth.vert's. With FACET (Frame.render_facet_layers) each triangle also carries its plane
// normal in the layer's view frame, for common/facet_layers.frag.
layout(triangles, invocations = MAX_LAYERS) in;
layout(triangle_strip, max_vertices = 3) out;

struct LayerView {
    mat4 view;
    mat4 view_proj;
    vec4 scale;     // xy: layer map size / array size
};
layout(std430, binding = 0) readonly buffer LayerViews { LayerView views[]; };
uniform int u_count;

in vec4 v_world[];
out float v_depth;
#ifdef CLIP_SPHERE
out vec3 v_position;            // world position, for common/depth.frag's sphere clip
#endif
#if defined(PEEL) || defined(FACET)
flat out int v_layer;           // the layer, for the maps depth.frag and facet_layers.frag compare with
#endif
#ifdef FACET
flat out vec3 v_facet;          // the triangle's plane normal in the layer's view frame (not oriented)
#endif

void main() {
    int layer = gl_InvocationID;
    if (layer >= u_count) return;
    LayerView lv = views[layer];
#ifdef FACET
    vec3 a = (lv.view * v_world[0]).xyz, b = (lv.view * v_world[1]).xyz, c = (lv.view * v_world[2]).xyz;
    vec3 facet = cross(b - a, c - a);
    float facet_len = length(facet);
    facet = facet_len > 0.0 ? facet / facet_len : vec3(0.0);
#endif
    for (int k = 0; k < 3; ++k) {
        vec4 world = v_world[k];
        vec4 clip = lv.view_proj * world;
        clip.xy = clip.xy * lv.scale.xy + (lv.scale.xy - 1.0) * clip.w;
        gl_Position = clip;
        v_depth = -(lv.view * world).z;
#ifdef CLIP_SPHERE
        v_position = world.xyz;
#endif
        gl_Layer = layer;
#if defined(PEEL) || defined(FACET)
        v_layer = layer;
#endif
#ifdef FACET
        v_facet = facet;
#endif
        EmitVertex();
    }
    EndPrimitive();
}
