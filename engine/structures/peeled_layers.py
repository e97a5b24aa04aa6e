"""Depth peeling from the light centre (Schwarz & Stamminger 2007, §3.2): the depth map and up to three
layers behind it, each holding per texel the nearest caster fragment strictly behind the previous layer, so
occluders hidden from the centre still become micro-occluders. Ours, to leave out what a light does not
need: of a closed caster's far side only the faces the centre sees within the light's angular radius of
edge-on are peeled (glsl/backprojection/peel.frag: only they can lie on the solid's outline from another
light point), none where BACKPROJECTION's solid columns stand for the far side (`far_side`); a peeled texel
is kept only where some surface lies behind it, and a layer left empty is dropped. BACKPROJECTION reads them."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.light_shape import light_half_extent
from ..gpu.frame import resource_bytes
from ..gpu.programs import program
from . import structure
from .depth_map import DEPTH_MAP, closed_casters

PEELED_LAYERS = "peeled_layers"
# Relative depth gap (fraction of the previous layer's linear depth) a fragment must lie behind it to count
# as the next layer: a surface's own depth, re-rasterised, must not come back as a layer of its own.
PEEL_EPS = 1e-4


@dataclass
class PeeledLayers:
    maps: list                  # R32F linear-depth textures, maps[0] the depth map itself; fewer than asked
                                # where peeled layers came out empty

    @property
    def nbytes(self) -> int:    # the depth map is counted under its own name
        return resource_bytes(self.maps[1:])

    def __len__(self):
        return len(self.maps)


@structure(PEELED_LAYERS, requires=(DEPTH_MAP,))
def build(frame, lc, layers: int = 1, far_side: bool = True):
    """`far_side`: peel a closed caster's faces turned away from the centre where they lie within the light's
    angular radius of edge-on; off where something else stands for the far side (BACKPROJECTION's solid
    columns), so that only occluders hidden behind others are peeled."""
    view, out = lc.view, [lc.structures[DEPTH_MAP]]
    with frame.timings.stage("bp_peel"):
        if layers <= 1 or not frame.geometry.has_casters:
            return PeeledLayers(out)
        prog = program(frame.worker, "common/depth.vert", "backprojection/peel.frag")
        everything = frozenset(range(len(frame.snap.objects)))
        closed = closed_casters(frame)
        near_faces = [(ids, {"u_closed": flag}) for ids, flag in ((closed, 1), (everything - closed, 0)) if ids]
        all_faces = [(everything, {"u_closed": 0})]
        radius = float(np.hypot(*light_half_extent(lc.light, view.face)))
        peel = dict(prog=prog, view=view.view, view_proj=view.view_proj,
                    uniforms={"u_peel_eps": PEEL_EPS, "u_light_ortho": int(view.is_ortho), "u_light_radius": radius,
                              "u_far_side": int(far_side)})
        peeled = [out[0]]
        for _ in range(layers - 1):     # each behind the previous one as drawn, before the mask thins it
            peeled.append(frame.rasterise(frame.new_depth_target(view), draws=near_faces,
                                          samplers={"u_prev": peeled[-1]}, **peel))
        counter = frame.buffer(bytes(4))
        for layer in peeled[1:]:
            behind = frame.rasterise(frame.target((view.width, view.height), 1), draws=all_faces,
                                     samplers={"u_prev": layer}, **peel)
            counter.write(bytes(4))
            frame.dispatch("backprojection/peel_mask.comp", samplers={"u_behind": behind}, images={0: layer},
                           buffers={0: counter}, size=(view.width, view.height))
            if int(np.frombuffer(counter.read(), np.uint32)[0]) > 0:
                out.append(layer)
    return PeeledLayers(out)
