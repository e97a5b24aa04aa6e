"""The hard depth map of the casters from the light view's eye: linear light depth, R32F, NO_OCCLUDER where
nothing was drawn. HARD, PCF and PCSS read it; BACKPROJECTION builds its pyramids from it."""
from __future__ import annotations

from ..gpu.frame import NO_OCCLUDER  # noqa: F401  (the empty-texel value readers compare against)
from . import structure

DEPTH_MAP = "depth_map"


@structure(DEPTH_MAP)
def build(frame, lc):
    return frame.render_depth_map(lc.view)
