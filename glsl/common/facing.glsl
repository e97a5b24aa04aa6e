// Which side of its triangle a fragment shows the eye. Meshes wind counter-clockwise seen from the front
// (blender/extract.py swaps corners of mirrored instances to keep it so); a model matrix that flips
// handedness (gpu/geometry.py sets u_mirrored per draw) makes front faces wind clockwise on screen.
#ifndef FACING_GLSL
#define FACING_GLSL
uniform int u_mirrored = 0;

bool front_facing() {
    return gl_FrontFacing != (u_mirrored == 1);
}
#endif
