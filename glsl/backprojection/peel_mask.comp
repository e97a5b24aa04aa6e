// Keeps a peeled layer's texel only where the ray from the light's centre meets another surface behind it
// (u_behind, every face, a solid's far side included). A texel on the last surface along its ray (the
// ground, a wall, seen through the gap the previous layer leaves) has nothing behind it from the centre's
// direction to shadow; as a micro-occluder it is the receiver's own surface, work the gather would only
// reject. Counts the texels kept, so a layer left empty is dropped (engine/structures/peeled_layers.py).
layout(local_size_x = 8, local_size_y = 8) in;
layout(r32f, binding = 0) uniform image2D u_layer;
uniform sampler2D u_behind;     // nearest fragment behind u_layer (R32F, NO_OCCLUDER where none)
uniform ivec2 u_image_size;
layout(std430, binding = 0) buffer Kept { uint kept; };

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, u_image_size))) return;
    if (!(imageLoad(u_layer, t).r < EMPTY_DEPTH)) return;
    if (texelFetch(u_behind, t, 0).r < EMPTY_DEPTH) atomicAdd(kept, 1u);
    else imageStore(u_layer, t, vec4(NO_OCCLUDER));
}
