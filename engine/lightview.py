"""Light views: the frame and projection a shadow map is rendered with, fitted to what the camera sees.

Perspective lights (area, point, spot) look down their local -Z from a point on the light plane; suns use an
orthographic view along their direction. The window covers the visible receivers this light reaches and the
occluders that can stand between them and any point of the light, clipped to the casters' bounds: nothing
outside can change a visible pixel, so nothing outside is rendered. No bpy, no GL.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .snapshot import AREA, POINT, SPOT, SUN, Light

MAX_HALF_ANGLE = np.radians(80.0)   # a single perspective map cannot cover a hemisphere; beyond this it clamps


@dataclass
class LightView:
    view: np.ndarray        # (4,4) world → light-local (looks down -Z)
    proj: np.ndarray        # (4,4) light-local → clip
    width: int              # shadow-map texels
    height: int
    near: float             # light-local depth range (positive distances along -Z)
    far: float
    is_ortho: bool
    window: tuple           # (x0, x1, y0, y1): tangent window at unit depth (perspective) or world (ortho)
    clamped: bool = False   # the receivers needed more than MAX_HALF_ANGLE and some fall outside

    @property
    def view_proj(self) -> np.ndarray:
        return self.proj @ self.view

    def texel_size(self) -> tuple[float, float]:
        """Texel footprint in window units: tangent per texel (perspective) or metres per texel (ortho)."""
        x0, x1, y0, y1 = self.window
        return (x1 - x0) / self.width, (y1 - y0) / self.height

    def uniforms(self) -> dict:
        """Values every shadow-map shader reads (see glsl/common/light_view.glsl)."""
        x0, x1, y0, y1 = self.window
        tx, ty = self.texel_size()
        return {
            "u_light_view": _mat(self.view),
            "u_light_view_proj": _mat(self.view_proj),
            "u_light_window": (x0, x1, y0, y1),
            "u_light_ortho": int(self.is_ortho),
            "u_light_depth_range": (self.near, self.far),
            "u_map_size": (self.width, self.height),
            "u_texel_tan": max(tx, ty),
        }


def _mat(m: np.ndarray) -> tuple:
    """Column-major float tuple for a GLSL mat4 uniform."""
    return tuple(np.asarray(m, dtype=np.float32).T.ravel())


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


def light_extent_local(light: Light) -> np.ndarray:
    """Points spanning the light's emitting extent in its local frame (z = 0), for window fitting."""
    if light.kind == AREA:
        hx, hy = light.size_x / 2.0, light.size_y / 2.0
    elif light.kind in (POINT, SPOT):
        hx = hy = light.radius
    else:
        return np.zeros((1, 3))
    return np.array([[sx * hx, sy * hy, 0.0] for sx in (-1, 1) for sy in (-1, 1)])


def _box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def _clip_segments_to_box(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Slab-clip segments a→b (N,3) to the box; return the endpoints of the surviving pieces (M,3)."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - a) / d
        t1 = (hi - a) / d
    tmin = np.where(np.abs(d) < 1e-30, np.where((a >= lo) & (a <= hi), -np.inf, np.inf), np.minimum(t0, t1))
    tmax = np.where(np.abs(d) < 1e-30, np.where((a >= lo) & (a <= hi), np.inf, -np.inf), np.maximum(t0, t1))
    enter = np.clip(tmin.max(axis=1), 0.0, 1.0)
    leave = np.clip(tmax.min(axis=1), 0.0, 1.0)
    keep = enter <= leave
    pts = np.concatenate([a[keep] + d[keep] * enter[keep, None], a[keep] + d[keep] * leave[keep, None]])
    return pts


def fit(light: Light, receivers: tuple[np.ndarray, np.ndarray], casters: tuple[np.ndarray, np.ndarray] | None,
        map_size: int, *, origin_local: np.ndarray | None = None, margin: float = 0.02) -> LightView:
    """Fit a light view to the receiver bounds (world AABB lo, hi) and caster bounds.

    `origin_local` moves the eye to a point of the light (a REFERENCE sample); the frame keeps its axes.
    """
    r_lo, r_hi = (np.asarray(v, float) for v in receivers)
    centre = (r_lo + r_hi) / 2.0
    world_to_local = light_frame(light, centre)
    if origin_local is not None:
        shift = np.eye(4)
        shift[:3, 3] = -np.asarray(origin_local, float)
        world_to_local = shift @ world_to_local
        sources = np.asarray(origin_local, float)[None, :] * 0.0     # the eye is the only source
    else:
        sources = light_extent_local(light)
    local_to_world = np.linalg.inv(world_to_local)

    rec = _box_corners(r_lo, r_hi)
    pts = [rec]
    if casters is not None:
        c_lo, c_hi = (np.asarray(v, float) for v in casters)
        if light.kind == SUN:
            # Occluders lie up-sun of receivers: sweep receiver corners towards the sun across the casters.
            toward = -light.direction * (np.linalg.norm(c_hi - c_lo) + np.linalg.norm(r_hi - r_lo) + 1.0)
            a, b = rec, rec + toward
        else:
            src_world = (local_to_world @ np.c_[sources, np.ones(len(sources))].T).T[:, :3]
            a = np.repeat(rec, len(src_world), axis=0)
            b = np.tile(src_world, (len(rec), 1))
        pts.append(_clip_segments_to_box(a, b, c_lo, c_hi))
    pts = np.concatenate(pts)
    local = (world_to_local @ np.c_[pts, np.ones(len(pts))].T).T[:, :3]
    depth = -local[:, 2]
    extent = float(np.linalg.norm(r_hi - r_lo)) + 1e-9
    if casters is not None:
        extent = max(extent, float(np.linalg.norm(casters[1] - casters[0])))

    if light.kind == SUN:
        x0, y0 = local[:, 0].min(), local[:, 1].min()
        x1, y1 = local[:, 0].max(), local[:, 1].max()
        pad = max(x1 - x0, y1 - y0, 1e-6 * extent) * margin
        window = (x0 - pad, x1 + pad, y0 - pad, y1 + pad)
        near, far = depth.min(), depth.max()
        pad_z = max(far - near, 1e-6 * extent) * 0.01
        near, far = near - pad_z, far + pad_z
        clamped = False
    else:
        near_floor = 1e-5 * extent
        front = depth > near_floor
        if not front.any():
            # Nothing in front of the light: a degenerate view that no receiver uses.
            local, depth = np.array([[0.0, 0.0, -1.0]]), np.array([1.0])
            front = np.array([True])
        tan_x = local[front, 0] / depth[front]
        tan_y = local[front, 1] / depth[front]
        limit = np.tan(MAX_HALF_ANGLE)
        clamped = bool((~front).any() and (depth[: len(rec)] <= near_floor).any()) or \
            bool(np.abs(tan_x).max() > limit or np.abs(tan_y).max() > limit)
        tan_x, tan_y = np.clip(tan_x, -limit, limit), np.clip(tan_y, -limit, limit)
        x0, x1, y0, y1 = tan_x.min(), tan_x.max(), tan_y.min(), tan_y.max()
        pad = max(x1 - x0, y1 - y0, 1e-6) * margin
        window = (x0 - pad, x1 + pad, y0 - pad, y1 + pad)
        near = max(depth[front].min() * 0.98, near_floor)
        far = depth[front].max() * 1.02 + near_floor

    width, height = _map_shape(window, map_size)
    proj = ortho(window, near, far) if light.kind == SUN else frustum(window, near, far)
    return LightView(world_to_local, proj, width, height, float(near), float(far), light.kind == SUN,
                     tuple(float(v) for v in window), clamped)


def _map_shape(window, size: int) -> tuple[int, int]:
    """Square texels: the longer side of the window gets `size` texels."""
    w, h = window[1] - window[0], window[3] - window[2]
    if w >= h:
        return size, int(np.clip(round(size * h / max(w, 1e-30)), 16, size))
    return int(np.clip(round(size * w / max(h, 1e-30)), 16, size)), size


def frustum(window, near: float, far: float) -> np.ndarray:
    """OpenGL off-axis perspective with the window given as tangents at unit depth."""
    x0, x1, y0, y1 = window
    l, r, b, t = x0 * near, x1 * near, y0 * near, y1 * near
    m = np.zeros((4, 4))
    m[0, 0] = 2 * near / (r - l)
    m[1, 1] = 2 * near / (t - b)
    m[0, 2] = (r + l) / (r - l)
    m[1, 2] = (t + b) / (t - b)
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -2 * far * near / (far - near)
    m[3, 2] = -1.0
    return m


def ortho(window, near: float, far: float) -> np.ndarray:
    x0, x1, y0, y1 = window
    m = np.eye(4)
    m[0, 0] = 2 / (x1 - x0)
    m[1, 1] = 2 / (y1 - y0)
    m[2, 2] = -2 / (far - near)
    m[0, 3] = -(x1 + x0) / (x1 - x0)
    m[1, 3] = -(y1 + y0) / (y1 - y0)
    m[2, 3] = -(far + near) / (far - near)
    return m
