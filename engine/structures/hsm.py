"""Hierarchical min/max shadow map (GBP06, recalled in Schwarz & Stamminger 2007 §2.1/§5): per depth layer a
power-of-two padded RG32F mip pyramid whose level-l texel holds the (min, max) depth of 2^l × 2^l texels."""
from __future__ import annotations

from dataclasses import dataclass

from ..gpu.programs import program, set_uniforms
from . import structure
from .mssm import level_count, mssm_levels
from .peeled_layers import PEELED_LAYERS

HSM = "hsm"


@dataclass
class Hsm:
    pyramids: list              # per depth layer: RG32F mipmapped texture, or None (read from the MSSM)
    levels: int
    padded: tuple               # (width, height) of level 0, powers of two

    @property
    def nbytes(self) -> int:
        return chain_bytes(*self.padded, 8) * sum(p is not None for p in self.pyramids)


def padded_size(width: int, height: int) -> tuple[int, int]:
    """The power-of-two size a pyramid's level 0 is padded to."""
    return 1 << max(width - 1, 0).bit_length(), 1 << max(height - 1, 0).bit_length()


def chain_bytes(width: int, height: int, texel_bytes: int) -> int:
    """Bytes of a power-of-two padded mip chain down to 1×1 (at 1024² RG32F: 10.67 MiB, Table 1's HSM)."""
    pw, ph = padded_size(width, height)
    return sum(max(pw >> l_, 1) * max(ph >> l_, 1) * texel_bytes for l_ in range(level_count(pw, ph)))


def reduce_pyramid(frame, shader: str, depth, size, uniforms: dict, components: int = 2,
                   samplers: dict | None = None):
    """A pyramid over the padded `size` (full mip chain, nearest filtering; RG32F min/max unless `components`
    says otherwise), its level 0 filled from the R32F `depth` map (and any further `samplers`) by the compute
    `shader` and the rest by mip_chain. Returns (texture, levels)."""
    pw, ph = size
    levels = level_count(pw, ph)
    tex = frame.texture((pw, ph), components)
    tex.build_mipmaps(0, levels - 1)
    tex.filter = (0x2600, 0x2600)       # GL_NEAREST
    prog = program(frame.worker, compute=shader)
    depth.use(location=0)
    set_uniforms(prog, {"u_depth": 0, **uniforms})
    if samplers:
        for unit, (name, source) in enumerate(samplers.items(), start=1):
            source.use(location=unit)
            set_uniforms(prog, {name: unit})
    mip_chain(frame, prog, [tex], (pw, ph), levels)
    return tex, levels


def build_pyramid(frame, depth, width: int, height: int):
    """Min/max pyramid of one R32F depth map. Returns (texture, levels, padded size)."""
    size = padded_size(width, height)
    tex, levels = reduce_pyramid(frame, "backprojection/hsm.comp", depth, size, {"u_map_size": (width, height)})
    return tex, levels, size


def mip_chain(frame, prog, textures, padded, levels: int, extra=None) -> None:
    """Run `prog` once per mip level, coarsest last: level l of texture i is bound as image i (write), level
    l − 1 as image len(textures) + i (read); uniforms u_first, u_dst_size and `extra(l)` per level."""
    pw, ph = padded
    n = len(textures)
    for l_ in range(levels):
        size = (max(pw >> l_, 1), max(ph >> l_, 1))
        for i, tex in enumerate(textures):
            tex.bind_to_image(i, read=False, write=True, level=l_)
            if l_ > 0:
                tex.bind_to_image(n + i, read=True, write=False, level=l_ - 1)
        set_uniforms(prog, {"u_first": int(l_ == 0), "u_dst_size": size, **(extra(l_) if extra else {})})
        prog.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
        frame.ctx.memory_barrier()


@structure(HSM, requires=(PEELED_LAYERS,))
def build(frame, lc, mssm_first: bool = False, ysm_first: bool = False):
    """`mssm_first`: layer 0 is read from an MSSM (built as its own structure); its pyramid is left out when
    that MSSM holds every level. `ysm_first`: the YSM structure holds layer 0's pyramid."""
    w, h = lc.view.width, lc.view.height
    pw, ph = padded_size(w, h)
    pyramids, levels = [], level_count(pw, ph)
    with frame.timings.stage("bp_hsm"):
        for i, depth in enumerate(lc.structures[PEELED_LAYERS].maps):
            if i == 0 and (ysm_first or (mssm_first and mssm_levels(w, h) >= level_count(w, h))):
                pyramids.append(None)
                continue
            pyramids.append(build_pyramid(frame, depth, w, h)[0])
    return Hsm(pyramids, levels, (pw, ph))
