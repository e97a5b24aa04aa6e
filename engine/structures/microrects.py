"""Microrects (Schwarz & Stamminger 2008, §5.2): micropatches whose extent, at coarser levels, is any rectangle
of level-0 texels around their reference point, built by a greedy two-pass merge (glsl/backprojection/
microrects.comp). Per depth layer two power-of-two padded textures with full mip chains: depth (R32F, minimum
of the merged microrects) and extent (RGBA32F: x0, y0, x1, y1 in level-0 texels, upper ends exclusive)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gpu.programs import program, set_uniforms
from . import structure
from .hsm import chain_bytes, mip_chain, padded_size
from .mssm import level_count
from .peeled_layers import PEELED_LAYERS

MICRORECTS = "microrects"


@dataclass
class Microrects:
    depth: list                 # per depth layer: R32F mipmapped texture
    extent: list                # per depth layer: RGBA32F mipmapped texture
    levels: int
    padded: tuple
    stats: list = ()            # with stats: per depth layer, RGBA32F mipmapped member statistics

    @property
    def nbytes(self) -> int:
        w, h = self.padded
        return len(self.depth) * chain_bytes(w, h, 4 + 16) + len(self.stats) * chain_bytes(w, h, 16)

    def read(self, layer: int, level: int) -> tuple[np.ndarray, np.ndarray]:
        """(depth (H, W), extent (H, W, 4)) of one level, on the GPU thread (tests, studies)."""
        d, e = self.depth[layer], self.extent[layer]
        w, h = max(self.padded[0] >> level, 1), max(self.padded[1] >> level, 1)
        depth = np.frombuffer(d.read(level=level), np.float32).reshape(h, w)
        extent = np.frombuffer(e.read(level=level), np.float32).reshape(h, w, 4)
        return depth.copy(), extent.copy()


def build_chain(frame, depth, width: int, height: int, stats: bool = False):
    """Microrect depth and extent chains of one R32F depth map (and, with `stats`, the chain of the members'
    mean depth, texel count, maximum depth and depth variance: BACKPROJECTION's coarse coverage; level 0 left
    unwritten, the texels' own depths). Returns (depth,
    extent, stats or None, levels, padded size)."""
    pw, ph = padded_size(width, height)
    levels = level_count(pw, ph)
    textures = [frame.texture((pw, ph), 1), frame.texture((pw, ph), 4)] + ([frame.texture((pw, ph), 4)] if stats
                                                                           else [])
    for tex in textures:
        tex.build_mipmaps(0, levels - 1)
        tex.filter = (0x2600, 0x2600)       # GL_NEAREST
    prog = program(frame.worker, compute="backprojection/microrects.comp", defines={"STATS": int(stats)})
    depth.use(location=0)
    set_uniforms(prog, {"u_depth": 0, "u_map_size": (width, height)})
    mip_chain(frame, prog, textures, (pw, ph), levels,
              lambda l_: {"u_src_size": (max(pw >> max(l_ - 1, 0), 1), max(ph >> max(l_ - 1, 0), 1)),
                          "u_src_level": max(l_ - 1, 0)})
    return textures[0], textures[1], textures[2] if stats else None, levels, (pw, ph)


@structure(MICRORECTS, requires=(PEELED_LAYERS,))
def build(frame, lc, stats: bool = False):
    w, h = lc.view.width, lc.view.height
    depths, extents, members, levels, padded = [], [], [], 1, padded_size(w, h)
    with frame.timings.stage("bp_microrects"):
        for depth in lc.structures[PEELED_LAYERS].maps:
            d, e, m, levels, padded = build_chain(frame, depth, w, h, stats)
            depths.append(d)
            extents.append(e)
            if m is not None:
                members.append(m)
    return Microrects(depths, extents, levels, padded, members)
