"""Light → uniforms of glsl/shading/irradiance.glsl.

Blender's power conventions (checked against Cycles in tests/test_irradiance_cycles.py, the numpy twin is
engine/core/irradiance.py):
  area light, power P [W] over area A:   radiance L = P / (π·A)             (all of P leaves the front side)
  sphere light, power P, radius r:       radiance L = P / (4π·r² · π)        (intensity P/(4π) W/sr);
                                         with soft falloff (Blender's default) it emits from a disk of
                                         radius r at its centre facing the receiver, else from a sphere
  point light, radius 0:                 intensity I = P / (4π)
  sun, strength S [W/m²], angle a:       irradiance S at normal incidence; as a disk of directions of
                                         half-angle a/2, L = S / (π·sin²(a/2))
Colour multiplies each, and Light.power already carries 2^exposure.
"""
from __future__ import annotations

import numpy as np

from .irradiance import MAX_SUNS, SUN_MAX_HALF, spot_tan_wide, sun_tree_terms, tree_suns
from .snapshot import AREA, DISK, ELLIPSE, POINT, SPOT, SUN, Light

LIGHT_POLYGON, LIGHT_SPHERE, LIGHT_POINT, LIGHT_SUN = 0, 1, 2, 3
ELLIPSE_SIDES = 64


def light_defines(light: Light) -> dict:
    """Compile-time specialisation of glsl/shading/irradiance.glsl for this light (shape, sides, cone)."""
    u = _light_values(light)
    sides = ELLIPSE_SIDES if light.kind == AREA and light.shape in (DISK, ELLIPSE) else 4
    return {"LIGHT_SHAPE": u["u_shape"], "POLY_SIDES": sides, "LIGHT_SPOT": int(light.kind == SPOT)}


def light_uniforms(light: Light, lights=None) -> dict:
    """Uniform values of glsl/shading/irradiance.glsl for this light, one of the scene's `lights` (None: the
    light alone), whose suns weigh the smooth-normal band (sun_pick_uniforms)."""
    u = _light_values(light)
    del u["u_shape"]
    u.update(sun_pick_uniforms(light, [light] if lights is None else lights))
    return u


def sun_pick_uniforms(light: Light, lights) -> dict:
    """What irradiance.glsl's sun_pick needs: the scene's suns (tree_suns: direction towards each, its
    strength as Cycles' light tree weighs it, the channel mean, and the cosine of its half angle) and this
    light's index among them (-1 where it is none, or past MAX_SUNS: then no band weighting)."""
    suns = tree_suns(lights)[:MAX_SUNS]
    rows, cos_half = [(0.0, 0.0, 0.0, 0.0)] * MAX_SUNS, [1.0] * MAX_SUNS
    own = -1
    for i, sun in enumerate(suns):
        toward, strength, cos_half[i] = sun_tree_terms(sun)
        rows[i] = (*map(float, toward), strength)
        if sun is light:
            own = i
    return {"u_sun_count": len(suns), "u_sun_self": own, "u_suns": rows, "u_sun_cos_half": cos_half}


def _light_values(light: Light) -> dict:
    m = np.asarray(light.matrix, float)
    x_axis, y_axis, z_axis, pos = m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3]
    color = np.asarray(light.color, float) * light.power
    u = {
        "u_center": tuple(pos), "u_emit_dir": tuple(-z_axis), "u_axis_u": (0.0, 0.0, 0.0),
        "u_axis_v": (0.0, 0.0, 0.0), "u_radius": 0.0, "u_one_sided": 0,
        "u_spot_tan_wide": spot_tan_wide(light) if light.kind == SPOT else 0.0,   # irradiance.glsl's footprint
        "u_soft_falloff": int(light.use_soft_falloff),
        "u_spot_axisless": int(light.kind == SPOT and light.spot_axisless),
    }
    if light.kind == AREA and not light.is_delta:
        u.update(u_shape=LIGHT_POLYGON, u_one_sided=1,
                 u_axis_u=tuple(x_axis * light.size_x / 2), u_axis_v=tuple(y_axis * light.size_y / 2),
                 u_radiance=tuple(color / (np.pi * light.area)))
    elif light.kind == SUN:
        half = light.angle / 2.0
        if half > 1e-6:
            # A disk of directions of radius tan(half) at unit distance; at 180° (half = π/2) it is the whole
            # hemisphere, capped at tan = 1e4 (the cone then misses 1e-8 of it) so it stays finite.
            u.update(u_shape=LIGHT_SUN, u_radius=float(np.tan(min(half, SUN_MAX_HALF))),
                     u_radiance=tuple(color / (np.pi * np.sin(half) ** 2)))
        else:
            u.update(u_shape=LIGHT_SUN, u_radius=0.0, u_radiance=tuple(color))
    elif light.kind in (POINT, SPOT) and light.radius > 0.0:
        u.update(u_shape=LIGHT_SPHERE, u_radius=float(light.radius),
                 u_radiance=tuple(color / (4.0 * np.pi ** 2 * light.radius ** 2)))
    else:
        # A point light or a zero-radius spot; a zero-size area light emits nothing, as in Cycles.
        scale = 0.0 if light.kind == AREA else 1.0 / (4.0 * np.pi)
        u.update(u_shape=LIGHT_POINT, u_radiance=tuple(color * scale))
    u.update(spot_uniforms(light))
    return u


def spot_uniforms(light: Light) -> dict:
    """Uniforms of glsl/common/spot.glsl (Cycles' cone) for this light; no cone (cos_half = -1) unless a spot."""
    if light.kind != SPOT:
        return {"u_spot_to_local": tuple(np.eye(3).ravel()), "u_spot_cos_half": -1.0, "u_spot_smooth": 0.0}
    cos_half = float(np.cos(light.spot_size / 2.0))
    to_local = light.spot_to_local()
    return {"u_spot_cos_half": cos_half, "u_spot_smooth": float((1.0 - cos_half) * light.spot_blend),
            "u_spot_to_local": tuple(to_local.T.ravel())}
