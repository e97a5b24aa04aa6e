"""The protocol every shadow technique follows.

A technique declares which per-light structures it needs (the pipeline builds only those) and turns them
into a visibility V ∈ [0, 1] for every pixel this light reaches. It writes V into `out` (an R32F texture
the size of the image); pixels the light does not reach are ignored downstream.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..lightview import LightView
from ..snapshot import Light

DEPTH_MAP = "depth_map"     # hard depth map of the casters from the light view's eye


@dataclass
class LightContext:
    light: Light
    view: LightView
    irradiance: object                  # RGBA32F texture: unoccluded E (rgb) and its scalar weight (a)
    receivers: tuple                    # world AABB (lo, hi) of the pixels this light reaches
    casters: tuple | None               # world AABB of the casters, None when there are none
    uniforms: dict                      # light-view uniforms plus bias settings
    structures: dict = field(default_factory=dict)
    debug: dict = field(default_factory=dict)   # name → (H, W) arrays for debug passes


class Technique:
    identifier = ""
    label = ""
    description = ""
    needs: tuple[str, ...] = (DEPTH_MAP,)

    def visibility(self, frame, lc: LightContext, out) -> None:
        raise NotImplementedError


def light_shape_uniforms(light: Light, view: LightView) -> dict:
    """Half extent of the light in the view's frame (metres, or tan(angle/2) for the sun) and whether it
    is round (disk, ellipse, sphere, sun) or rectangular: what filter kernels and samplers need."""
    from ..snapshot import AREA, DISK, ELLIPSE, SUN
    if light.kind == AREA:
        half = (light.size_x / 2.0, light.size_y / 2.0)
        round_ = light.shape in (DISK, ELLIPSE)
    elif light.kind == SUN:
        import math
        t = math.tan(light.angle / 2.0)
        half, round_ = (t, t), True
    else:
        half, round_ = (light.radius, light.radius), True
    return {"u_light_half": half, "u_light_round": int(round_)}
