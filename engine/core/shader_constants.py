"""Numbers the shaders and the Python side must agree on, defined once here. gpu/programs.py writes each as a
`#define NAME value` at the top of every program, so GLSL names them instead of repeating a literal."""
from __future__ import annotations

# Empty-texel sentinels (linear light depth, metres).
NO_OCCLUDER = 3.0e38        # what a depth map holds where nothing was drawn: beyond any scene, below float max
EMPTY_DEPTH = 1.0e30        # a depth at or beyond this is an empty texel (NO_OCCLUDER), never a surface

# BACKPROJECTION's per-pixel classes (u_info.r; the BP Class debug pass and the per-light stats).
CLASS_UNREACHED = -1        # the light does not reach the pixel
CLASS_LIT = 0               # proven fully lit by the search refinement
CLASS_UMBRA = 1             # proven in umbra
CLASS_BACKPROJECTED = 2     # micro-occluders were backprojected
# The lit_umbra structure's classes (structures/lit_umbra.py) are the same, with one for what it cannot prove.
CLASS_GATHER = 2            # neither proven lit nor umbra: the technique's full gather runs

# BACKPROJECTION's search refinement (the REFINE define) and micro-occluder (PRIMITIVE define).
REFINE_NONE, REFINE_HSM, REFINE_MSSM, REFINE_YSM = 0, 1, 2, 3
PRIMITIVE_MICROPATCH, PRIMITIVE_MICROQUAD, PRIMITIVE_MICRORECT = 0, 1, 2
# BACKPROJECTION's budget map b_mo(x, y) (Schwarz & Stamminger 2008, §4.2; u_budget_mode) and level passes
# (the LOQ define: 0 one integer level per pixel, 1 write the fractional level, 3 blend the two levels).
BUDGET_UNIFORM, BUDGET_BORDER, BUDGET_UNBOUNDED, BUDGET_IMPORTANCE = 0, 1, 2, 3
LOQ_INTEGER, LOQ_WRITE, LOQ_BLEND = 0, 1, 3
# BACKPROJECTION's coarse refit (the REFIT define, bp_coarse_fit): none (the papers'), the occluding finer
# parts' box at their minimum or mean depth, the cell's own box at their mean depth, or the parts' box at
# their mean depth tilted by their depth slope.
REFIT_NONE, REFIT_EXTENT, REFIT_MEAN, REFIT_DEPTH, REFIT_PLANE = 0, 1, 2, 3, 4
# The finer parts a coarse refit looks at: a microrect's level-(l − 1) neighbourhood 2c + {−1, 0, 1}², a
# micropatch's 2×2 cells; and the corners REFIT_PLANE tilts (loops whose iterations llvmpipe's limit counts:
# techniques/backprojection.py cell_iterations).
REFIT_PARTS_MICRORECT, REFIT_PARTS_MICROPATCH = 9, 4
REFIT_CORNERS = 4

# REFERENCE's sample weights (u_weight_mode).
WEIGHT_NONE = 0             # plain average of the hard maps
WEIGHT_AREA = 1             # cosθ_receiver · cosθ_light / d² (planar emitter)
WEIGHT_SPHERE = 2           # cosθ_receiver / d² (sphere light's great disk)
WEIGHT_SUN = 3              # cosθ_receiver (a sun sample: constant radiance over its uniform cone)
# Which receivers a REFERENCE sample set serves (u_side): all, or those outside / inside a true sphere light;
# or for a soft-falloff light whose ball holds geometry, each receiver from the samples beyond its facing disk.
SIDE_ALL, SIDE_OUTSIDE, SIDE_INSIDE, SIDE_BEYOND_DISK = 0, 1, 2, 3

# SSM compute scatter: fixed-point units per 1.0 of hidden light (2^24: ≤ 256 full occlusions fit a u32).
FIXED_POINT = float(1 << 24)

# PVSM's blocker search: most cells per axis of its search loop (a wider box is cut): 160² and a filter share
# (engine/gpu/loops.CHUNK) stay below llvmpipe's
# loop limit whatever pvsm_cap is.
PVSM_SEARCH_CELLS = 160

DEFINES = {name: value for name, value in dict(globals()).items()
           if name.isupper() and isinstance(value, (int, float)) and not isinstance(value, bool)}


def glsl_literal(value) -> str:
    """A Python number as a GLSL literal: ints as they are, floats always with an exponent."""
    return str(value) if isinstance(value, int) else f"{value:.9e}"
