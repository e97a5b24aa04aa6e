"""Where the light centre's rays leave the closed casters they enter at the depth map (ours, for
BACKPROJECTION's solid columns, glsl/backprojection/visibility.comp solid_column): a texel is solid where the
depth map's surface is a closed caster's front face; from there the ray runs inside that solid until the nearest
back face of a closed caster behind it, its exit. A power-of-two padded RG32F pyramid: level 0 holds a solid
texel's (exit, surface depth), (NO_OCCLUDER, 0) elsewhere; level l the nearest exit and the deepest surface of
the solid texels among its 2^l × 2^l, so every solid texel of a cell is solid between the two."""
from __future__ import annotations

from dataclasses import dataclass

from ..gpu.programs import program
from . import structure
from .depth_map import DEPTH_MAP, closed_casters
from .hsm import chain_bytes, padded_size, reduce_pyramid

SOLID_EXITS = "solid_exits"
# Relative depth gap between a closed caster's front face and the depth map's surface within which they are
# the same surface, and behind the entry that the exit must lie (a face re-rasterised at its own depth).
SAME_SURFACE_EPS = 1e-4


@dataclass
class SolidExits:
    pyramid: object             # RG32F mipmapped texture; None where the view holds no closed caster
    padded: tuple

    @property
    def nbytes(self) -> int:
        return chain_bytes(*self.padded, 8) if self.pyramid is not None else 0


@structure(SOLID_EXITS, requires=(DEPTH_MAP,))
def build(frame, lc):
    view = lc.view
    size = padded_size(view.width, view.height)
    closed = closed_casters(frame)
    if not closed or not frame.geometry.has_casters:
        return SolidExits(None, size)
    with frame.timings.stage("bp_exits"):
        draw = dict(view=view.view, view_proj=view.view_proj, draws=[(closed, {})])
        entry = frame.rasterise(frame.new_depth_target(view),
                                program(frame.worker, "common/depth.vert", "common/depth.frag",
                                        defines={"FRONT_FACES": 1}), **draw)
        exit_ = frame.rasterise(frame.new_depth_target(view),
                                program(frame.worker, "common/depth.vert", "backprojection/solid_exit.frag"),
                                samplers={"u_entry": entry}, uniforms={"u_eps": SAME_SURFACE_EPS}, **draw)
        pyramid, _ = reduce_pyramid(frame, "backprojection/solid_exits.comp", lc.structures[DEPTH_MAP], size,
                                    {"u_map_size": (view.width, view.height), "u_eps": SAME_SURFACE_EPS},
                                    components=2, samplers={"u_entry": entry, "u_exit": exit_})
    return SolidExits(pyramid, size)
