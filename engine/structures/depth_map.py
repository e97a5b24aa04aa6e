"""The hard depth map of the casters from the light view's eye: linear light depth, R32F, NO_OCCLUDER where
nothing was drawn. HARD, PCF and PCSS read it; BACKPROJECTION builds its pyramids from it.
The back-face map: the same of the casters' faces turned away from the light centre only, the near side of a
solid's far half (second-depth shadow maps, Wang & Molnar 1994). PCSS reads it.
The facet map: the light-view normal of the surface each depth-map texel holds (RGBA16F, common/facet.frag),
drawn the same way so that the same triangle wins each texel. PCF's filter and PCSS's blocker search read it to
keep a surface that faces both the light and the receiver from counting as a blocker (light_view.glsl
facet_clears_receiver)."""
from __future__ import annotations

from ..gpu.frame import NO_OCCLUDER  # noqa: F401  (the empty-texel value readers compare against)
from . import structure

DEPTH_MAP = "depth_map"
BACK_DEPTH_MAP = "back_depth_map"
FACET_MAP = "facet_map"


@structure(DEPTH_MAP)
def build(frame, lc):
    return frame.render_depth_map(lc.view)


@structure(BACK_DEPTH_MAP)
def build_back(frame, lc):
    return frame.render_depth_map(lc.view, back_faces=True)


@structure(FACET_MAP)
def build_facets(frame, lc):
    return frame.render_facet_map(lc.view)


def closed_casters(frame) -> frozenset:
    """Indices of the snapshot's closed casters (watertight meshes): the solids whose far side the peeled
    layers thin out and whose inside the solid exits measure."""
    return frozenset(i for i, ob in enumerate(frame.snap.objects) if ob.closed)
