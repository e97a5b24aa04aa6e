"""Depth peeling from the light centre (Schwarz & Stamminger 2007, §3.2): the depth map and up to three
layers behind it, each holding per texel the nearest caster fragment strictly behind the previous layer, so
occluders hidden from the centre still become micro-occluders. BACKPROJECTION reads them."""
from __future__ import annotations

from dataclasses import dataclass

from ..gpu.frame import resource_bytes
from ..gpu.programs import program
from . import structure
from .depth_map import DEPTH_MAP

PEELED_LAYERS = "peeled_layers"
# Relative depth gap (fraction of the previous layer's linear depth) a fragment must lie behind it to count
# as the next layer: a surface's own depth, re-rasterised, must not come back as a layer of its own.
PEEL_EPS = 1e-4


@dataclass
class PeeledLayers:
    maps: list                  # R32F linear-depth textures, maps[0] the depth map itself

    @property
    def nbytes(self) -> int:    # the depth map is counted under its own name
        return resource_bytes(self.maps[1:])

    def __len__(self):
        return len(self.maps)


@structure(PEELED_LAYERS, requires=(DEPTH_MAP,))
def build(frame, lc, layers: int = 1):
    view, out = lc.view, [lc.structures[DEPTH_MAP]]
    with frame.timings.stage("bp_peel"):
        if layers <= 1 or not frame.geometry.has_casters:
            return PeeledLayers(out)
        prog = program(frame.worker, "common/depth.vert", "backprojection/peel.frag")
        for _ in range(layers - 1):
            out.append(frame.rasterise(frame.new_depth_target(view), prog, view.view, view.view_proj,
                                       uniforms={"u_peel_eps": PEEL_EPS}, samplers={"u_prev": out[-1]}))
    return PeeledLayers(out)
