"""Occluder coverage pyramid (ours; glsl/backprojection/coverage.comp): per depth layer a power-of-two padded
RGBA32F mip chain whose level-l texel holds the mean depth, the count, the maximum depth and the depth variance
of the non-empty texels among its 2^l × 2^l level-0 texels. BACKPROJECTION reads it to shrink a coarse
micro-occluder to the share of its texels that lie nearer than the receiver (bars thinner than a cell, a
silhouette's edge cells), instead of taking the whole cell as one occluder."""
from __future__ import annotations

from dataclasses import dataclass

from . import structure
from .hsm import chain_bytes, reduce_pyramid, padded_size
from .peeled_layers import PEELED_LAYERS

COVERAGE = "coverage"


@dataclass
class Coverage:
    pyramids: list              # per depth layer: RGBA32F mipmapped texture
    levels: int
    padded: tuple

    @property
    def nbytes(self) -> int:
        return chain_bytes(*self.padded, 16) * len(self.pyramids)


@structure(COVERAGE, requires=(PEELED_LAYERS,))
def build(frame, lc):
    w, h = lc.view.width, lc.view.height
    size = padded_size(w, h)
    pyramids, levels = [], 1
    with frame.timings.stage("bp_coverage"):
        for depth in lc.structures[PEELED_LAYERS].maps:
            tex, levels = reduce_pyramid(frame, "backprojection/coverage.comp", depth, size,
                                         {"u_map_size": (w, h)}, components=4)
            pyramids.append(tex)
    return Coverage(pyramids, levels, size)
