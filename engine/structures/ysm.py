"""Y shadow map (Schwarz & Stamminger 2008, §6): the first n levels of the HSM plus an MSSM built from HSM level
n − 1, whose resolution is the MSSM part's (256² by default: n = 3 for a 1024² map, n = 4 for 2048²). MSSM level
0 would repeat HSM level n − 1 and is not stored. The HSM pyramid is kept whole, as in the paper, so that
micro-occluders always come from it (layer 0's pyramid lives here; the HSM structure leaves it out)."""
from __future__ import annotations

from dataclasses import dataclass

from ..gpu.programs import program, set_uniforms
from . import structure
from .hsm import build_pyramid, chain_bytes, padded_size
from .mssm import level_count
from .peeled_layers import PEELED_LAYERS

YSM = "ysm"
YSM_PART = 256              # the MSSM part's resolution (§6: a good trade-off)


def split(width: int, height: int, part: int = YSM_PART) -> tuple[int, tuple[int, int], int]:
    """(n, MSSM part size, MSSM levels stored): n HSM levels (0 … n − 1), the part built from level n − 1
    (the padded map halved n − 1 times, no larger than `part` on its longer side), its levels 1 … K."""
    pw, ph = padded_size(width, height)
    n = 1
    while max(pw, ph) >> (n - 1) > part:
        n += 1
    size = (max(pw >> (n - 1), 1), max(ph >> (n - 1), 1))
    return n, size, level_count(*size) - 1


def ysm_bytes(width: int, height: int, part: int = YSM_PART) -> int:
    """GPU memory of a YSM over a width × height map, RG32F: full HSM pyramid + K part levels."""
    _, (sw, sh), k = split(width, height, part)
    return chain_bytes(width, height, 8) + sw * sh * k * 8


@dataclass
class Ysm:
    pyramid: object             # layer 0's RG32F HSM pyramid (all levels)
    texture: object             # RG32F array: layer k − 1 holds MSSM level k, or None when K = 0
    base: int                   # n − 1
    levels: int                 # K
    size: tuple                 # the MSSM part's resolution
    padded: tuple

    @property
    def nbytes(self) -> int:
        return chain_bytes(*self.padded, 8) + self.size[0] * self.size[1] * self.levels * 8


@structure(YSM, requires=(PEELED_LAYERS,))
def build(frame, lc, part: int = YSM_PART):
    w, h = lc.view.width, lc.view.height
    depth = lc.structures[PEELED_LAYERS].maps[0]
    n, size, k = split(w, h, part)
    with frame.timings.stage("bp_ysm"):
        pyramid, _, padded = build_pyramid(frame, depth, w, h)
        tex = None
        if k > 0:
            tex = frame.texture_array_per_light((size[0], size[1], k), 2)     # GL_NEAREST, from the pool
            prog = program(frame.worker, compute="backprojection/mssm.comp", defines={"FROM_HSM": 1})
            pyramid.use(location=0)
            set_uniforms(prog, {"u_hsm": 0, "u_base": n - 1, "u_map_size": size})
            tex.bind_to_image(0, read=True, write=True)
            tex.bind_to_image(1, read=True, write=True)
            for l_ in range(1, k + 1):
                set_uniforms(prog, {"u_level": l_})
                prog.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
                frame.ctx.memory_barrier()
    return Ysm(pyramid, tex, n - 1, k, size, padded)
