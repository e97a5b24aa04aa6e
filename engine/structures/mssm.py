"""Multi-scale shadow map (Schwarz & Stamminger 2007, §5, Fig. 7): per level the depth map's resolution,
texel x of level l holding the (min, max) depth of the 2^l × 2^l neighbourhood centred on it. An RG32F
texture array released when the pipeline finishes the light (a 2048² map takes ~400 MB)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..gpu.programs import program, set_uniforms
from . import structure
from .depth_map import DEPTH_MAP

MSSM = "mssm"
MSSM_BUDGET_BYTES = 512 << 20   # full-resolution MSSM levels beyond this come from the HSM (§5's hybrid)


def level_count(width: int, height: int) -> int:
    """Hierarchy levels so that the coarsest cell (2^(L−1) texels) covers the whole map."""
    return max(int(math.ceil(math.log2(max(width, height, 1)))), 0) + 1


def mssm_levels(width: int, height: int) -> int:
    """Full-resolution MSSM levels kept: all of them unless that exceeds MSSM_BUDGET_BYTES (a 4096² map would
    need 1.7 GB); the coarser ones are then read from the HSM — §5's hybrid of pyramid and MSSM, with the
    roles swapped (fine levels MSSM, coarse HSM), which keeps the tight fine bounds that matter most."""
    return max(1, min(level_count(width, height), MSSM_BUDGET_BYTES // max(width * height * 8, 1)))


@dataclass
class Mssm:
    texture: object             # RG32F texture array, one layer per level
    levels: int

    @property
    def nbytes(self) -> int:
        return int(self.texture.width * self.texture.height * self.levels * 8)


@structure(MSSM, requires=(DEPTH_MAP,))
def build(frame, lc):
    depth, width, height = lc.structures[DEPTH_MAP], lc.view.width, lc.view.height
    with frame.timings.stage("bp_mssm"):
        levels = mssm_levels(width, height)
        tex = frame.texture_array_per_light((width, height, levels), 2)     # GL_NEAREST
        prog = program(frame.worker, compute="backprojection/mssm.comp")
        depth.use(location=0)
        set_uniforms(prog, {"u_depth": 0, "u_map_size": (width, height)})
        tex.bind_to_image(0, read=True, write=True)
        tex.bind_to_image(1, read=True, write=True)
        for l_ in range(levels):
            set_uniforms(prog, {"u_level": l_})
            prog.run((width + 7) // 8, (height + 7) // 8, 1)
            frame.ctx.memory_barrier()
    return Mssm(tex, levels)
