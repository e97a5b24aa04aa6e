"""Conservative lit/umbra classes of the pixels a light view reaches (issue 14: "pixels classified lit or umbra
early skip the per-technique gather"). One R32F image the size of the frame: CLASS_LIT where no point of the
light can be hidden, CLASS_UMBRA where every one is, CLASS_GATHER where the technique must look, and
CLASS_UNREACHED where the light reaches no covered pixel (glsl/lit_umbra/classify.comp says how).

Built from a coarse min/max pyramid of the depth map (GBP06's HSM from 8×8-texel cells up) over each pixel's
receiver–light pyramid, the search area of BACKPROJECTION's classification (Schwarz & Stamminger 2007 §2.1,
§5). PCSS and REFERENCE read it; with `collect_stats` the pixels skipped are counted (frame.count: skip_lit,
skip_umbra, skip_candidates; one readback per view)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.light_shape import light_depth_extent, light_shape_uniforms
from ..core.shader_constants import CLASS_LIT, CLASS_UMBRA, CLASS_UNREACHED
from . import structure
from .depth_map import DEPTH_MAP
from .hsm import chain_bytes, padded_size, reduce_pyramid

LIT_UMBRA = "lit_umbra"

# Texels added to each side of the search area: a kernel tap's floor() and PCSS's bilinear footprint (one
# each), and REFERENCE's sample maps, whose receiver falls in a texel of their own (one more).
MARGIN_TEXELS = 3.0
# Depth slack in receiver texels (times 1 + tan θ): covers a sample map's own bias and normal offset, which
# follow its texel size, not the centre map's; in units of (1 + bias + normal offset).
SLACK_TEXELS = 2.0


@dataclass
class LitUmbra:
    classes: object             # R32F texture, frame size: CLASS_* per pixel
    pyramid: object             # RG32F min/max pyramid of the depth map, from level `base` up
    padded: tuple               # its level-0 size
    base: int

    @property
    def nbytes(self) -> int:
        return self.classes.width * self.classes.height * 4 + chain_bytes(*self.padded, 8)


def counts(classes: np.ndarray) -> dict:
    """Pixels reached, and those classified lit and umbra, of a read-back class image."""
    return {"skip_candidates": int((classes != CLASS_UNREACHED).sum()),
            "skip_lit": int((classes == CLASS_LIT).sum()), "skip_umbra": int((classes == CLASS_UMBRA).sum())}


def base_level(width: int, height: int) -> int:
    """The pyramid's finest level B (cells of 2^B texels): 8×8 cells from 256-texel maps up, finer below. A
    search area is rarely under a few cells; the texels of finer levels would cost more to write than they
    save (llvmpipe: a 1024² full pyramid ≈ 25 ms, this one a few)."""
    return int(np.clip(int(np.log2(max(width, height, 1))) - 5, 0, 3))


def build_coarse_pyramid(frame, depth, width: int, height: int):
    """Min/max pyramid of an R32F depth map from level B = base_level up (glsl/lit_umbra/reduce.comp).
    Returns (texture, its level count, its level-0 size, B)."""
    base = base_level(width, height)
    block = 1 << base
    size = padded_size((width + block - 1) // block, (height + block - 1) // block)
    tex, levels = reduce_pyramid(frame, "lit_umbra/reduce.comp", depth, size,
                                 {"u_map_size": (width, height), "u_block": block})
    return tex, levels, size, base


@structure(LIT_UMBRA, requires=(DEPTH_MAP,))
def build(frame, lc, narrow: bool = False, cap: float = 0.0, texel_ratio: float = 1.0, umbra_cap: float = 0.0):
    """`narrow`: the area may shrink to the section at the least depth found in it (two passes more) — valid
    for a gather that follows rays to the light (REFERENCE), not for one that counts every texel of its
    search area nearer than the receiver's plane as a blocker (PCSS). `cap`: the area's half extent is
    capped at this fraction of the map's larger side, as a gather that never looks farther caps its own
    (0: no cap). `texel_ratio`: how much larger than this view's the texels of the gather's own maps may be
    (their bias and normal offset grow with them; 1: the gather reads this view's depth map). `umbra_cap`:
    the cap of the gather's widest kernel where it reaches past its search (PCSS's filter; 0: `cap`), over
    which umbra must hold."""
    view, s = lc.view, frame.settings
    cap_texels = cap * max(view.width, view.height) if cap > 0.0 else 1.0e7
    umbra_texels = max(cap_texels, umbra_cap * max(view.width, view.height)) if cap > 0.0 else cap_texels
    with frame.timings.stage("lit_umbra"):
        pyramid, levels, padded, base = build_coarse_pyramid(frame, lc.structures[DEPTH_MAP], view.width,
                                                             view.height)
        classes = frame.texture((frame.width, frame.height), 1)
        frame.dispatch("lit_umbra/classify.comp", {
            **lc.uniforms, **light_shape_uniforms(lc.light, view), "u_levels": levels, "u_base": base,
            "u_light_depth_extent": light_depth_extent(lc.light, view.face), "u_margin": MARGIN_TEXELS,
            "u_passes": 3 if narrow else 1, "u_cap": cap_texels, "u_umbra_cap": umbra_texels,
            "u_texel_ratio": float(texel_ratio),
            "u_slack": SLACK_TEXELS * (1.0 + float(s.bias) + float(s.normal_offset))},
            samplers={"g_irradiance": lc.irradiance, "u_pyramid": pyramid}, images={0: classes})
    if s.collect_stats:
        c = counts(frame.read(classes)[..., 0])
        frame.count(**c)
        lc.stats.update(c)
    return LitUmbra(classes, pyramid, padded, base)
