"""A light's extent in its light view, and the penumbra it casts: the relation every soft-shadow technique
rests on, written once here (and once in GLSL, glsl/common/penumbra.glsl).

Similar triangles through an occluder point at depth z (from the light plane) seen from a receiver at depth
d: a light of half extent h widens the occluder's shadow on the receiver's window by h·s with the spread

    s = 1/z − 1/d      (perspective view: window units are tangents at unit depth)
    s = d − z          (a sun's orthographic view: h is tan(angle/2), window units are metres)

(Atty et al. 2006 §3.3–3.4; the same pyramid bounds Schwarz & Stamminger's search area, §2.1, and PCSS's
penumbra estimate)."""
from __future__ import annotations

import math

import numpy as np

from .irradiance import spot_edge_tans
from .shading import SUN_MAX_HALF, spot_uniforms
from .snapshot import AREA, DISK, ELLIPSE, POINT, SPOT, SUN, Light


def penumbra_spread(z, d, ortho: bool):
    """Window units of penumbra per unit of light half extent between an occluder at depth z and a
    receiver at depth d (scalars or numpy arrays; no clamping: negative when z lies behind d)."""
    return d - z if ortho else 1.0 / z - 1.0 / d


def spot_cone_tans(light: Light) -> tuple[float, float]:
    """tan of the spot cone's half angle along the light's local X and Y: the object scale stretches the cone
    by scale x (y) over scale z, as spot.glsl's u_spot_to_local does. Unbounded (inf) for other lights."""
    if light.kind != SPOT:
        return math.inf, math.inf
    if light.spot_linear is not None:
        return spot_edge_tans(light)[:2]
    s = np.maximum(np.abs(np.asarray(light.spot_scale, float)), 1e-12)
    t = np.tan(min(light.spot_size / 2.0, np.pi / 2.0 - 1e-6))
    return float(t * s[0] / s[2]), float(t * s[1] / s[2])


def light_half_extent(light: Light, face=None) -> tuple[float, float]:
    """Half extent of the light in its view's frame: metres (area: half its sides; sphere: its radius),
    or tan(angle/2) for a sun. `face`: the turn of a cube-face view (LightView.face), if the view is one."""
    if light.kind == AREA:
        half = (light.size_x / 2.0, light.size_y / 2.0)
        if face is None:
            return half
        # A side face sees the area light at an angle: its extent projected onto the face's plane (kept above
        # 5 % of the light's size, so kernels built on it never collapse).
        corners = np.array([[sx * half[0], sy * half[1], 0.0] for sx in (-1, 1) for sy in (-1, 1)])
        projected = np.max(np.abs(corners @ np.asarray(face, float).T)[:, :2], axis=0)
        return tuple(float(v) for v in np.maximum(projected, 0.05 * max(half)))
    if light.kind == SUN:
        t = math.tan(min(light.angle / 2.0, SUN_MAX_HALF))      # finite up to a 180° sun
        return (t, t)
    return (light.radius, light.radius)


def light_reach_box(light: Light, view) -> tuple[float, float, float]:
    """Half extents, along a view's axes, of a box about its origin that holds every point of the light (metres);
    for a sun's orthographic view, the tangents (a, b) of every direction (a, b, 1) towards its disk, and 0.
    Filters that drop a texel whose triangle has the receiver and the whole light on one side (light_view.glsl
    facet_clears_receiver) read it; it holds the light from any view: its own, a cube face, a rim view."""
    rotation = np.asarray(view.view, float)[:3, :3]
    if light.kind == SUN:
        towards = rotation @ -np.asarray(light.direction, float)
        widest = math.acos(max(-1.0, min(1.0, float(towards[2])))) + min(light.angle / 2.0, SUN_MAX_HALF)
        t = math.tan(widest) if widest < 0.4999 * math.pi else 1e30
        return (t, t, 0.0)
    centre = rotation @ np.asarray(light.position, float) + np.asarray(view.view, float)[:3, 3]
    if light.kind == AREA:
        axes = rotation @ (np.asarray(light.matrix, float)[:3, :2] * (light.size_x / 2.0, light.size_y / 2.0))
        half = np.abs(axes).sum(axis=1)
    else:
        half = np.full(3, float(light.radius))
    return tuple(float(v) for v in np.abs(centre) + half)


def light_depth_extent(light: Light, face=None) -> float:
    """How far (metres) the light's points reach off its view's z = 0 plane: 0 for an area light seen along
    its own axis and for a sun's ortho view; an area light's corners across a cube face's axis; a point or
    spot light's radius (REFERENCE may sample its ball, not only the disk facing the view)."""
    if light.kind == SUN:
        return 0.0
    if light.kind == AREA:
        if face is None:
            return 0.0
        corners = np.array([[sx * light.size_x / 2.0, sy * light.size_y / 2.0, 0.0] for sx in (-1, 1)
                            for sy in (-1, 1)])
        return float(np.max(np.abs(corners @ np.asarray(face, float).T)[:, 2]))
    return float(light.radius)


# Weighted kernels and light samples of a sun stop at directions 76° off its axis (tan 4): past them a receiver
# facing the sun gets cos²76° ≈ 6 % of its light under the cos³θ·cosθ weights (light_view.glsl's
# light_sample_weight), while a disk of tangents out to tan 90° spends its samples, or the filter its level,
# on directions that carry almost nothing (PVSM's and BACKPROJECTION's measurements in their modules).
SUN_KERNEL_TAN = 4.0


def weighted_sun_half(light: Light, half) -> tuple:
    """A light's half extent in the view (light_half_extent) as weighted kernels use it: a sun's held to
    SUN_KERNEL_TAN."""
    return tuple(min(float(x), SUN_KERNEL_TAN) if light.kind == SUN else float(x) for x in half)


def is_round(light: Light) -> bool:
    """Whether the light's shape is round (a disk or ellipse area light, a sphere, a sun's disk of directions)
    rather than a rectangle."""
    return light.kind != AREA or light.shape in (DISK, ELLIPSE)


def round_in_view(light: Light, face=None) -> bool:
    """Whether a view's light plane holds the light's round shape itself: a disk or ellipse area light or a
    sun's disk of directions, in the light's own view (`face` None). A cube face sees a disk light slanted, a
    sun's rim view is centred on the rim, and a sphere light's disk (Cycles') faces each receiver, so its rays
    cross the light plane in an ellipse stretched by 1/cosθ off the axis: those keep rectangular stand-ins."""
    return is_round(light) and light.kind in (AREA, SUN) and face is None


def light_shape_uniforms(light: Light, view) -> dict:
    """Half extent of the light in the view's frame (metres, or tan(angle/2) for the sun), whether it
    is round (disk, ellipse, sphere, sun) or rectangular, whether it is a one-sided planar emitter and
    its emission axis in the view's frame, and whether it is a sphere (a point or spot light with a radius,
    whose footprint on the light plane depends on the receiver: light_view.glsl light_footprint): what
    filter kernels, samplers and their weights need."""
    emit = np.asarray(view.view, float)[:3, :3] @ np.asarray(light.direction, float)
    cone = spot_cone_clip(light, view)
    return {"u_light_half": light_half_extent(light, view.face), "u_light_round": int(is_round(light)),
            "u_light_one_sided": int(light.kind == AREA), "u_light_emit": tuple(float(x) for x in emit),
            "u_light_sphere": int(light.kind in (POINT, SPOT) and light.radius > 0.0), "u_spot_cone": cone,
            **(spot_uniforms(light) if cone[0] > 0.0 else {})}


def light_frame(light: Light, target: np.ndarray | None = None) -> np.ndarray:
    """World→local matrix of the light. Point lights have no axes of their own: aim -Z at `target`."""
    m = np.array(light.matrix, dtype=np.float64)
    if light.kind == POINT and target is not None:
        forward = np.asarray(target, float) - m[:3, 3]
        n = np.linalg.norm(forward)
        forward = forward / n if n > 1e-12 else np.array([0.0, 0.0, -1.0])
        up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(forward, up)
        x /= np.linalg.norm(x)
        y = np.cross(-forward, x)
        m[:3, 0], m[:3, 1], m[:3, 2] = x, y, -forward
    return np.linalg.inv(m)


# A cone wider than this (tan of its half angle) clips no footprint worth the per-tap test.
SPOT_CLIP_MAX_TAN = 100.0


def spot_cone_clip(light: Light, view) -> tuple[float, float]:
    """For a spot with a radius seen in its own view (its own axes, from its centre): tan of the cone's half angle
    along the view's X and Y, with which light_view.glsl light_footprint keeps each receiver's kernels to the part
    of the ball the cone lets it see. (0, 0) elsewhere: other lights, a cube face or stand-in view, a cone on
    skewed axes (spot_linear) or one nearly as wide as a hemisphere."""
    if light.kind != SPOT or light.radius <= 0.0 or light.spot_linear is not None or view.face is not None:
        return (0.0, 0.0)
    to_view = np.asarray(view.view, float)
    to_light = light_frame(light)
    scale = max(float(np.abs(light.position).max()), light.radius, 1.0)
    if not (np.allclose(to_view[:3, :3], to_light[:3, :3], atol=1e-6)
            and np.allclose(to_view[:3, 3], to_light[:3, 3], atol=1e-6 * scale)):
        return (0.0, 0.0)
    tx, ty = spot_cone_tans(light)
    return (tx, ty) if max(tx, ty) <= SPOT_CLIP_MAX_TAN else (0.0, 0.0)
