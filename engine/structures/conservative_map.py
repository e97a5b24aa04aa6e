"""The conservative triangle map of the casters from the light view's eye (Lecocq, Marvie, Sourimant,
Gautron 2014, "Sub-Pixel Shadow Mapping", §3.2–3.4; conservative rasterization after Hasselgren,
Akenine-Möller and Ohlsson 2005, emulated in a geometry shader since neither core GL 4.5 nor llvmpipe has it).

Every texel any caster triangle overlaps gets a fragment (glsl/conservative_map/raster.geom: near-plane
clip, bounding box grown by half a texel; raster.frag: exact triangle/texel test). The triangle with the
minimum conservative depth over the texel wins the depth test, and the map keeps for it:

  min_depth  R32F: that minimum conservative depth as linear light depth (NO_OCCLUDER where empty), what
             any reader can compare against like the hard depth map;
  texels     RGBA32UI: the 128-bit triangle texel (glsl/conservative_map/texel.glsl): three texel-relative
             2D vertices, z̃ at the texel centre, both depth slopes quantised by Q (§3.4);
  slopes     RG32F unquantised dη/dx, dη/dy, only for the quantiser ablation (`quantiser="FLOAT"`).

SPSM reads it through the `conservative_map` structure; other techniques can render one with other
quantiser settings through `render()`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.lightview import LightView, sub_view
from ..core.options import known_options
from ..gpu.frame import NO_OCCLUDER
from ..gpu.programs import mat_uniform, program, set_uniforms
from . import structure

CONSERVATIVE_MAP = "conservative_map"
VERT_SCALE = 64           # fixed-point steps per texel of the stored vertices (texel.glsl)
Q_MIN, Q_MAX = 1, 253     # Q stays away from 0 and 254: tan(±π/2) flips sign in float32
# Quantiser name → exponent n of Q (§3.4, Eq. 3); FLOAT keeps the slopes unquantised (ablation).
QUANTISERS = {"FLOAT": 5, "LINEAR": 1, "POW3": 3, "POW5": 5}


def quantise(d, n: int = 5) -> np.ndarray:
    """Q(d) = 127·(1 + ((2/π)·atan d)^n), odd roots keeping the sign, clamped to [1, 253] (§3.4, Eq. 3).
    The numpy twin of texel.glsl's quantise_slope."""
    x = np.arctan(np.asarray(d, np.float64)) * (2.0 / math.pi)
    y = np.sign(x) * np.abs(x) ** n
    return np.clip(np.round(127.0 * (1.0 + y)), Q_MIN, Q_MAX).astype(np.uint8)


def dequantise(q, n: int = 5) -> np.ndarray:
    """Eq. 4: d = tan(π/2 · (Q/127 − 1)^(1/n)), the odd root keeping the sign."""
    y = np.asarray(q, np.float64) / 127.0 - 1.0
    return np.tan(0.5 * math.pi * np.sign(y) * np.abs(y) ** (1.0 / n))


def decode_table(n: int = 5) -> np.ndarray:
    """The 256 decoded slopes (the paper's look-up table, §3.4); codes outside [1, 253] decode as their
    clamped neighbour, so no entry is ±tan(π/2)."""
    return dequantise(np.clip(np.arange(256), Q_MIN, Q_MAX), n).astype(np.float32)


@dataclass
class ConservativeMap:
    min_depth: object           # R32F texture
    texels: object              # RGBA32UI texture
    slopes: object | None       # RG32F texture (FLOAT quantiser only)
    slope_table: object         # R32F 256×1: decoded Q codes
    quantiser: str
    view: LightView

    def uniforms(self) -> dict:
        """What a reader of the texels needs besides the light view's own uniforms (texel.glsl)."""
        return {"u_texel_window": tuple(float(v) for v in self.view.texel_size()),
                "u_quant_n": float(QUANTISERS[self.quantiser])}


def render(frame, view: LightView, quantiser: str = "POW5") -> ConservativeMap:
    """Conservatively rasterize the casters seen from `view` (see the module docstring)."""
    if quantiser not in QUANTISERS:
        raise ValueError(f"Conservative map quantiser '{quantiser}': choose one of {', '.join(QUANTISERS)}")
    ctx = frame.ctx
    size = (view.width, view.height)
    min_depth = frame.texture(size, 1)
    texels = frame.texture(size, 4, dtype="u4")
    attachments = [min_depth, texels]
    slopes = None
    if quantiser == "FLOAT":
        slopes = frame.texture(size, 2)
        attachments.append(slopes)
    depth = frame.depth_texture(size)
    fbo = frame.framebuffer(attachments, depth)
    table = frame.texture((256, 1), 1)
    table.write(decode_table(QUANTISERS[quantiser]).tobytes())
    cmap = ConservativeMap(min_depth, texels, slopes, table, quantiser, view)
    # Clear each attachment with its own value on the GPU (uploading cleared arrays cost ~0.3 s at 4096²):
    # the float maps and the depth test through one framebuffer, the integer texels through another.
    floats = [min_depth] + ([slopes] if slopes is not None else [])
    clear_f = frame.framebuffer(floats, depth)
    clear_f.clear(NO_OCCLUDER, 0.0, 0.0, 0.0, depth=1.0)
    clear_u = frame.framebuffer([texels])
    clear_u.clear(0.0, 0.0, 0.0, 0.0)
    fbo.use()
    if frame.geometry.has_casters:
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        defines = {"CMAP_FLOAT_SLOPES": 1} if slopes is not None else {}
        prog = program(frame.worker, "conservative_map/raster.vert", "conservative_map/raster.frag",
                       geometry="conservative_map/raster.geom", defines=defines)
        set_uniforms(prog, {**view.uniforms(), **cmap.uniforms(),
                            "u_light_view_proj": mat_uniform(view.view_proj)})
        frame.geometry.render(ctx, prog, "caster", position_only=True)
    return cmap


@structure(CONSERVATIVE_MAP)
def build(frame, lc, size: int | None = None):
    # The quantiser is a setting of the technique that reads the texels (SPSM's `spsm_quantiser`); the
    # structure looks it up through the option catalogue so that it never imports a technique.
    quantiser = frame.settings.option("spsm_quantiser") if "spsm_quantiser" in known_options() else "POW5"
    view = lc.view
    if size is not None and size < max(view.width, view.height):
        # A coarser map over the same window (PVSM's low-resolution search map, Shen et al. 2011 §5.2 step 2).
        scale = size / max(view.width, view.height)
        view = sub_view(view, view.window, max(1, round(view.width * scale)), max(1, round(view.height * scale)))
    return render(frame, view, quantiser)
