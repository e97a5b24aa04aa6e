"""Light views: the frame and projection a shadow map is rendered with, fitted to what the camera sees.

Perspective lights (area, point, spot) look down their local -Z from a point on the light plane; suns use an
orthographic view along their direction. The window covers the visible receivers this light reaches and the
occluders that can stand between them and any point of the light, clipped to the casters' bounds: nothing
outside can change a visible pixel, so nothing outside is rendered. No bpy, no GL.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .snapshot import AREA, DISK, ELLIPSE, POINT, RECTANGLE, SPOT, SUN, Light
from .light_shape import light_frame, penumbra_spread, spot_cone_tans
from .shading import SUN_MAX_HALF
from .matrices import mat_uniform

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
    # A face of a light seen through several views: `frame` is the light's own world→local matrix and `face`
    # the rotation (3×3) from that frame to this view's, whose -Z looks along the face. None for a light's
    # single view (its frame is `view`).
    frame: np.ndarray | None = None
    face: np.ndarray | None = None

    @property
    def view_proj(self) -> np.ndarray:
        return self.proj @ self.view

    @property
    def size(self) -> int:
        """Texels along the longer side: the map size the view was fitted with."""
        return max(self.width, self.height)

    def resized(self, size: int) -> "LightView":
        """The same view with `size` texels along its window's longer side (fit's map size only shapes the
        map: the window, depths and matrices do not depend on it)."""
        width, height = _map_shape(self.window, size)
        return replace(self, width=width, height=height)

    def texel_size(self) -> tuple[float, float]:
        """Texel footprint in window units: tangent per texel (perspective) or metres per texel (ortho)."""
        x0, x1, y0, y1 = self.window
        return (x1 - x0) / self.width, (y1 - y0) / self.height

    def uniforms(self) -> dict:
        """Values every shadow-map shader reads (see glsl/common/light_view.glsl)."""
        x0, x1, y0, y1 = self.window
        tx, ty = self.texel_size()
        return {
            "u_light_view": mat_uniform(self.view),
            "u_light_view_proj": mat_uniform(self.view_proj),
            "u_light_window": (x0, x1, y0, y1),
            "u_light_ortho": int(self.is_ortho),
            "u_light_depth_range": (self.near, self.far),
            "u_map_size": (self.width, self.height),
            "u_texel_tan": max(tx, ty),
        }


def light_extent_local(light: Light) -> np.ndarray:
    """Points spanning the light's emitting extent in its local frame (z = 0), for window fitting."""
    if light.kind == AREA:
        hx, hy = light.size_x / 2.0, light.size_y / 2.0
    elif light.kind in (POINT, SPOT):
        hx = hy = light.radius
    else:
        return np.zeros((1, 3))
    return np.array([[sx * hx, sy * hy, 0.0] for sx in (-1, 1) for sy in (-1, 1)])


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners (8, 3) of an axis-aligned box."""
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def cell_corners(points: np.ndarray, cells: int = 24) -> np.ndarray:
    """The corners of the cells of a cells³ grid over the points' box that hold a point: at most (cells + 1)³
    points whose hull holds the points' hull, to fit many views to many receivers (REFERENCE's samples)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = np.maximum(hi - lo, 1e-12) / cells
    occupied = np.unique(np.minimum(((points - lo) / size).astype(np.int64), cells - 1), axis=0)
    corners = (occupied[:, None, :] + box_corners(np.zeros(3), np.ones(3))[None].astype(np.int64)).reshape(-1, 3)
    return lo + np.unique(corners, axis=0) * size


def fit(light: Light, receivers: tuple[np.ndarray, np.ndarray], casters: tuple[np.ndarray, np.ndarray] | None,
        map_size: int, *, origin_local: np.ndarray | None = None, margin: float = 0.02,
        frame: np.ndarray | None = None, face: np.ndarray | None = None,
        receiver_points: np.ndarray | None = None) -> LightView:
    """Fit a light view to the receiver bounds (world AABB lo, hi) and the caster bounds.

    The window is the part of the receivers a caster can shadow (the casters' window widened by how far the
    light's extent reaches past them), plus the occluders those receivers can see the light through. Both
    are measured in window units: tangents from the eye (perspective) or metres (sun). `origin_local` moves
    the eye to a point of the light (a REFERENCE sample); the frame keeps its axes and the light has no
    extent left around that eye. `frame` (the light's world→local matrix) and `face` (a rotation from it, see
    `split_faces`) make the view one face of a light seen through several views. `receiver_points` (world,
    N × 3), the receivers themselves where the caller has them, replace their box's corners.
    """
    r_lo, r_hi = (np.asarray(v, float) for v in receivers)
    world_to_light = light_frame(light, (r_lo + r_hi) / 2.0) if frame is None else np.asarray(frame, float)
    world_to_local = world_to_light
    extent = light_extent_local(light)
    if origin_local is not None:
        shift = np.eye(4)
        shift[:3, 3] = -np.asarray(origin_local, float)
        world_to_local = shift @ world_to_local
        extent = np.zeros((1, 3))
    if face is not None:
        turn = np.eye(4)
        turn[:3, :3] = face
        world_to_local = turn @ world_to_local
        extent = extent @ np.asarray(face, float).T
    half = np.max(np.abs(extent[:, :2]), axis=0)
    if casters is None:
        casters = receivers
    c_lo, c_hi = (np.asarray(v, float) for v in casters)
    # The receivers' own points, where known, bound the window tighter than their box: a cube face's points
    # lie within its 45° pyramid, while the far corners of their box can lie far outside it, or behind the eye.
    rec = to_local(world_to_local, box_corners(r_lo, r_hi) if receiver_points is None else receiver_points)
    cas = to_local(world_to_local, box_corners(c_lo, c_hi))
    extent = max(float(np.linalg.norm(r_hi - r_lo)), float(np.linalg.norm(c_hi - c_lo)), 1e-9)
    is_sun = light.kind == SUN

    if is_sun:
        r_depth, c_depth = -rec[:, 2], -cas[:, 2]
        win_r = _bounds(rec[:, :2])
        win_c = _bounds(cas[:, :2])
        grow = half * max(penumbra_spread(c_depth.min(), r_depth.max(), True), 0.0)   # tan(angle/2) · depth gap
        limit = np.inf
    else:
        near_floor = 1e-5 * extent
        limit = np.tan(MAX_HALF_ANGLE)
        win_r, r_depth = _tangent_window(rec, near_floor)
        win_c, c_depth = _tangent_window(cas, near_floor)
        nearest = float((-rec[:, 2]).min())
        if light.kind == SPOT and face is None and nearest > max(light.radius, near_floor):
            # A spot lights nothing past its cone (as its rays leave the emitter, kernel/light/spot.h): its
            # receivers' window is the cone's, however far their box's corners reach. From the centre, a ray
            # from a point of the emitter up to `radius` away reaches past that cone by radius/depth. Inside
            # its sphere there is no cone: kept for receivers all in front of the light and past its radius.
            tx, ty = spot_cone_tans(light)
            spill = 0.0 if origin_local is not None else light.radius * (1.0 + max(tx, ty)) / nearest
            win_r = _intersect(win_r, (-tx - spill, tx + spill, -ty - spill, ty + spill))
        z_c = max(c_depth.min(), near_floor)
        grow = half * max(penumbra_spread(z_c, max(r_depth.max(), z_c), False), 0.0)   # h · (1/z_occ − 1/z_rec)
    shadowable = _intersect(win_r, _widen(win_c, grow))
    occluders = _intersect(_widen(shadowable, grow), win_c)
    window = _union(shadowable, occluders)
    if not np.all(np.isfinite(window)) or window[1] <= window[0] or window[3] <= window[2]:
        window = _intersect(_union(win_r, win_c), (-limit, limit, -limit, limit))
    # Only receivers a caster can shadow need the map: with none (an empty window), a pixel left outside it
    # is lit for certain, and the view is not clamped however wide the fallback window below is.
    has_shadowable = shadowable[1] >= shadowable[0] and shadowable[3] >= shadowable[2]
    clamped = has_shadowable and bool(np.abs(np.asarray(shadowable)).max() > limit)
    if not is_sun and not clamped and ((-rec[:, 2] <= near_floor).any() and (-cas[:, 2] <= near_floor).any()):
        # Receivers and casters both reaching behind the eye's plane: what a caster shadows there, no window
        # of this view holds. The same test from the opposite direction decides it (fuzz 9145: a point light
        # aimed at a large floor's middle, the only caster behind it, its shadow on the floor lost).
        flip = np.array([1.0, 1.0, -1.0])
        back_r, back_r_depth = _tangent_window(rec * flip, near_floor)
        back_c, back_c_depth = _tangent_window(cas * flip, near_floor)
        z_b = max(back_c_depth.min(), near_floor)
        back = _intersect(back_r, _widen(back_c, half * max(penumbra_spread(z_b, max(back_r_depth.max(), z_b),
                                                                              False), 0.0)))
        clamped = bool(back[1] >= back[0] and back[3] >= back[2])
    window = np.clip(window, -limit, limit)
    pad = max(window[1] - window[0], window[3] - window[2], 1e-9) * margin
    window = (window[0] - pad, window[1] + pad, window[2] - pad, window[3] + pad)

    if is_sun:
        near, far = c_depth.min(), max(r_depth.max(), c_depth.max())
        pad_z = max(far - near, 1e-6 * extent) * 0.01
        near, far = near - pad_z, far + pad_z
    elif (-cas[:, 2] <= near_floor).any():
        near = near_floor       # the casters reach the light plane (or surround the light): keep them all
        far = max(r_depth.max(), c_depth.max()) * 1.02 + near_floor
    else:
        near = max(min(c_depth.min(), r_depth.min()) * 0.98, near_floor)
        far = max(r_depth.max(), c_depth.max()) * 1.02 + near_floor

    width, height = _map_shape(window, map_size)
    proj = ortho(window, near, far) if is_sun else frustum(window, near, far)
    return LightView(world_to_local, proj, width, height, float(near), float(far), is_sun,
                     tuple(float(v) for v in window), clamped,
                     frame=None if face is None else world_to_light, face=None if face is None else np.asarray(face))


# The six faces of a cube around the light, as directions in the light's frame. Index = 2·axis + (positive).
CUBE_FACES = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], float)


def face_rotation(direction) -> np.ndarray:
    """Rotation (3×3) from the light's frame to a view whose -Z looks along `direction` (a unit axis)."""
    forward = np.asarray(direction, float)
    z = -forward
    x = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x - z * np.dot(x, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z])         # rows: the view's axes in the light's frame


def outside_view(view: LightView, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Which world points (N, 3) fall outside the view's map (behind the eye or past the window); with
    `margin` (metres, perspective views), also those that a view from a point up to `margin` off its eye,
    looking the same way, would not hold: within margin / depth of the window's edge."""
    local = to_local(view.view, points)
    x0, x1, y0, y1 = view.window
    if view.is_ortho:
        w = local[:, :2]
        behind = np.zeros(len(points), bool)
        m = np.zeros(len(points))
    else:
        depth = -local[:, 2]
        behind = depth <= 0.0
        safe = np.where(behind, 1.0, depth)
        w = local[:, :2] / safe[:, None]
        m = margin / safe
    return behind | (w[:, 0] < x0 + m) | (w[:, 0] > x1 - m) | (w[:, 1] < y0 + m) | (w[:, 1] > y1 - m)


def split_faces(view: LightView, points: np.ndarray, lifted: np.ndarray | None = None,
                margin: float = 0.0) -> list[tuple[np.ndarray | None, np.ndarray]] | None:
    """When a light's single view had to be clamped and some lit points (N, 3, world) fall outside it: the views
    that hold them all, as
    [(rotation from the light's frame, or None for the single view itself; mask of the points it owns)].
    The single view keeps every point it holds; the others go to the cube faces around the light by the
    dominant axis of their direction from it (each at most 45° off its face's axis), only faces that own a
    point. None when the view was not clamped (its window holds every receiver a caster can shadow, so a
    point outside it is lit for certain), when it holds every point, and for orthographic views. `lifted`
    (N, 3): where each point's shadow ray leaves it (the terminator lift); the single view keeps a point
    only if it holds that too, the face that owns it is chosen by the point itself. `margin` (metres): the
    single view keeps only points that views from the light's points up to that far off its centre hold too
    (REFERENCE's sample maps look from there; outside_view)."""
    if view.is_ortho or not view.clamped or len(points) == 0:
        return None
    outside = outside_view(view, points, margin)
    if lifted is not None:
        outside |= outside_view(view, lifted, margin)
    if not outside.any():
        return None
    local = to_local(view.view, points)
    axis = np.argmax(np.abs(local), axis=1)
    index = np.where(outside, 2 * axis + (local[np.arange(len(local)), axis] > 0), -1)
    return [(None, ~outside)] * bool((~outside).any()) + [
        (face_rotation(CUBE_FACES[i]), index == i) for i in range(6) if (index == i).any()]


def centre_hidden(geometric: np.ndarray, shading: np.ndarray, to_centre: np.ndarray) -> np.ndarray:
    """Which receivers (geometric and shading normals, N × 3) have the light's centre (`to_centre`: the
    direction towards it, 3 or N × 3, any length) at or below their horizon by both normals: light_view.glsl
    then finds no texel that could shadow them, and they need rim views (sun_rim_faces, local_rim_lights)."""
    d = np.broadcast_to(np.asarray(to_centre, float), np.shape(geometric))
    reach = np.linalg.norm(d, axis=1)
    return (np.einsum("ij,ij->i", geometric, d) <= 1e-6 * reach) & (np.einsum("ij,ij->i", shading, d) <= 0.0)


# A sun's rim views: how many points around the edge of its disk stand for the disk where its centre is hidden.
SUN_RIM_VIEWS = 8


def sun_rim_faces(light: Light, view: LightView, geometric: np.ndarray, shading: np.ndarray
                  ) -> list[tuple[np.ndarray | None, np.ndarray]] | None:
    """For the techniques that work from one light point's map (Technique.rim_views), the views of a sun whose
    lit receivers include some with its centre below their horizon (geometric and shading normals, N × 3 world,
    both at or below it): the centre's map then holds nothing on their rays to the part of the disk they see,
    and its tangent-plane rule leaves them lit, even inside a closed room. Such a receiver takes instead the
    view from the point of the disk's rim nearest its geometric normal (the brightest point it sees: the rim
    point in the plane of the centre and the normal), rounded to one of SUN_RIM_VIEWS azimuths. Returned as
    split_faces does (rotation from the sun's frame, mask of the points each view owns; None: the centre's
    view for the rest); None when no receiver has the centre hidden."""
    if light.kind != SUN or light.angle <= 0.0 or len(geometric) == 0:
        return None
    turn = np.asarray(view.view, float)[:3, :3]         # world → the sun's frame (+z towards the sun)
    ng, n = np.asarray(geometric, float) @ turn.T, np.asarray(shading, float) @ turn.T
    hidden = centre_hidden(ng, n, np.array([0.0, 0.0, 1.0]))
    if not hidden.any():
        return None
    step = 2.0 * np.pi / SUN_RIM_VIEWS
    rim = np.round(np.arctan2(ng[:, 1], ng[:, 0]) / step).astype(int) % SUN_RIM_VIEWS
    half = min(light.angle / 2.0, SUN_MAX_HALF)
    faces = [(None, ~hidden)] * bool((~hidden).any())
    for i in range(SUN_RIM_VIEWS):
        mask = hidden & (rim == i)
        if mask.any():
            to_rim = np.array([np.sin(half) * np.cos(i * step), np.sin(half) * np.sin(i * step), np.cos(half)])
            faces.append((face_rotation(-to_rim), mask))
    return faces


# How finely the part of an emitter a receiver sees is sampled, and how finely the stand-in points of
# local_rim_lights are grouped (cells per side of the emitter's extent).
RIM_SAMPLES_PER_SIDE = 8
RIM_CELLS_PER_SIDE = 2
# Rounds of finer grouping for the receivers a group's stand-in leaves below their horizon, and the most
# stand-ins (each a light view) a finer round may bring the total to; past that, the receivers still left
# are grouped by the coarsest cells again, at most RIM_CELLS_PER_SIDE² more for an area light.
RIM_ROUNDS = 2
RIM_MAX_VIEWS = 8


def _unit_square_grid(round_shape: bool) -> np.ndarray:
    """Cell centres (M, 2) of a RIM_SAMPLES_PER_SIDE² grid over [-1, 1]², those inside the unit disk when
    `round_shape`."""
    c = (np.arange(RIM_SAMPLES_PER_SIDE) + 0.5) / RIM_SAMPLES_PER_SIDE * 2.0 - 1.0
    grid = np.stack(np.meshgrid(c, c), axis=-1).reshape(-1, 2)
    return grid[(grid ** 2).sum(axis=1) <= 1.0] if round_shape else grid


def seen_emitter(light: Light, points: np.ndarray, geometric: np.ndarray, chunk: int = 8192):
    """What each receiver (N × 3 world, geometric normals N × 3) sees of a local light's emitter, from a fixed
    grid of its points: over an area light's rectangle or ellipse, or over the disk of a sphere light that
    faces the receiver (as Cycles samples one). Per receiver: the centroid (N × 3 world) of the grid points
    above its tangent plane, their box (lo, hi: N × 2, grown by half a grid cell) in the emitter's axes (the
    area light's X and Y; for a sphere light, _perpendicular_axes of the direction from the light), and
    whether it sees any (N). In chunks of receivers, so a whole frame's take bounded memory."""
    pts, ng = np.asarray(points, float), np.asarray(geometric, float)
    m = np.asarray(light.matrix, float)
    if light.kind == AREA:
        half = np.array([light.size_x, light.size_y]) / 2.0
        grid = _unit_square_grid(light.shape in (DISK, ELLIPSE)) * half
    else:
        half = np.full(2, light.radius)
        grid = _unit_square_grid(True) * half
    pad = half / RIM_SAMPLES_PER_SIDE
    # The box of the grid points above a plane: along each axis, the first and last of them in the grid's
    # order by that coordinate (argmax of a boolean row finds its first True), with no N × M × 2 temporaries.
    orders = [np.argsort(grid[:, k], kind="stable") for k in range(2)]
    out = np.zeros((len(pts), 3)), np.zeros((len(pts), 2)), np.zeros((len(pts), 2)), np.zeros(len(pts), bool)
    for start in range(0, len(pts), chunk):
        p, n = pts[start:start + chunk], ng[start:start + chunk]
        if light.kind == AREA:
            t1, t2 = np.broadcast_to(m[:3, 0], p.shape), np.broadcast_to(m[:3, 1], p.shape)
        else:
            t1, t2 = _perpendicular_axes(p - m[:3, 3])
        # height of each grid point over each receiver's plane: (centre − p)·n + grid · (t·n)
        height = ((m[:3, 3] - p) * n).sum(axis=1)[:, None] + np.stack([(t1 * n).sum(1), (t2 * n).sum(1)], 1) @ grid.T
        above = height > 0.0
        count = above.sum(axis=1)
        flat = above @ grid / np.maximum(count, 1)[:, None]                 # centroid in the emitter's axes
        rows = slice(start, start + len(p))
        out[0][rows] = m[:3, 3] + flat[:, :1] * t1 + flat[:, 1:] * t2
        sees = count > 0
        for k, order in enumerate(orders):
            by_k = above[:, order]
            first = grid[order[np.argmax(by_k, axis=1)], k]
            last = grid[order[len(order) - 1 - np.argmax(by_k[:, ::-1], axis=1)], k]
            out[1][rows, k] = np.where(sees, first, np.inf) - pad[k]
            out[2][rows, k] = np.where(sees, last, -np.inf) + pad[k]
        out[3][rows] = sees
    return out


def _perpendicular_axes(directions: np.ndarray):
    """Two unit axes (N × 3 each) perpendicular to each direction (N × 3) and to each other, right-handed
    with the direction as the third."""
    d = directions / np.maximum(np.linalg.norm(directions, axis=1, keepdims=True), 1e-30)
    helper = np.where(np.abs(d[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(helper, d)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(d, t1)


def local_rim_lights(light: Light, points: np.ndarray, geometric: np.ndarray, shading: np.ndarray
                     ) -> list[tuple[Light | None, np.ndarray]] | None:
    """For the techniques that work from one light point's map (Technique.rim_views), an area or sphere light
    whose lit receivers (N × 3 world, with their geometric and shading normals) include some with its centre
    at or below their horizon: the centre's map holds nothing on their rays to the part of the emitter they
    see, and its tangent-plane rule leaves them lit. Such receivers take instead a stand-in for the part they
    see (seen_emitter, _stand_in): an area light in the emitter's plane (a sphere light's disk, facing them),
    centred on that part and as wide as it. They are
    grouped by where the centroid falls on the emitter (RIM_CELLS_PER_SIDE cells per side), one stand-in per
    group, averaged over it; the stand-in serves visibility only (the irradiance stays the whole emitter's).
    Returned as [(the stand-in, or None for the centre's view; mask of the points each owns)]; None when no
    receiver has the centre hidden. Receivers that see no part of the emitter keep the centre's view."""
    if light.is_delta or light.kind == SUN or len(points) == 0:
        return None
    pts = np.asarray(points, float)
    ng = np.asarray(geometric, float)
    hidden = centre_hidden(ng, np.asarray(shading, float), light.position - pts)
    if not hidden.any():
        return None
    where = np.flatnonzero(hidden)
    centroid, lo, hi, sees = seen_emitter(light, pts[where], ng[where])
    where, centroid, lo, hi = where[sees], centroid[sees], lo[sees], hi[sees]
    m = np.asarray(light.matrix, float)
    half = np.array([light.size_x, light.size_y, 1.0]) / 2.0 if light.kind == AREA else np.full(3, light.radius)
    local = (centroid - m[:3, 3]) @ m[:3, :3] / half         # the light's frame, in units of its extent
    if light.kind != AREA:
        # a sphere light's stand-in faces its group: group by the cube face of the direction to them too,
        # so that no member lies behind it (encoded in a fourth coordinate, one cell per face)
        away = (pts[where] - m[:3, 3]) @ m[:3, :3]
        axis = np.argmax(np.abs(away), axis=1)
        local = np.c_[local, 2.0 * axis + (away[np.arange(len(axis)), axis] > 0)]
    owner = np.full(len(pts), -1)
    stand_ins: list = []
    pending = np.arange(len(where))
    for round_ in range(RIM_ROUNDS):
        # cells twice as fine each round, for the members whose group's stand-in fell below their horizon
        groups = _rim_groups(local, pending, RIM_CELLS_PER_SIDE << round_)
        last = round_ == RIM_ROUNDS - 1
        if len(stand_ins) + len(groups) > RIM_MAX_VIEWS:      # too many views: back to the coarsest cells
            groups, last = _rim_groups(local, pending, RIM_CELLS_PER_SIDE), True
        left = []
        for group in groups:
            stand_in, ok = _stand_in(light, pts[where[group]], ng[where[group]], centroid[group], lo[group],
                                     hi[group])
            take = group if last else group[ok]
            if len(take):
                owner[where[take]] = len(stand_ins)
                stand_ins.append(stand_in)
            left += list(np.setdiff1d(group, take))
        # a member its group's stand-in leaves below its horizon takes the built stand-in highest above its
        # plane, if one is; only the others need finer groups
        left = np.array(left, int)
        best, height = _highest_stand_in(stand_ins, pts[where[left]], ng[where[left]])
        owner[where[left[height > 0.0]]] = best[height > 0.0]
        pending = left[height <= 0.0]
        if last or not len(pending):
            break
    stray = np.flatnonzero(owner >= 0)          # any still below its own: the highest, where one is above
    best, height = _highest_stand_in(stand_ins, pts[stray], ng[stray])
    centres = np.array([s.position for s in stand_ins], float).reshape(-1, 3)
    own = np.einsum("ij,ij->i", ng[stray], centres[owner[stray]] - pts[stray])
    move = (own <= 0.0) & (height > 0.0)
    owner[stray[move]] = best[move]
    rest = owner < 0
    return [(None, rest)] * bool(rest.any()) + [(light_, owner == i) for i, light_ in enumerate(stand_ins)]


def _rim_groups(local: np.ndarray, members: np.ndarray, cells: int) -> list:
    """The `members` (indices into `local`, centroids in the light's frame in units of its extent) grouped by
    cells² (area) or cells³ (sphere) cells over the emitter's extent, and for a sphere light by the cube face
    of their direction from it (local's fourth column)."""
    cell = np.clip(np.floor((local[members, :3] + 1.0) / 2.0 * cells), 0, cells - 1).astype(int)
    key = (cell[:, 0] * cells + cell[:, 1]) * cells + cell[:, 2]
    if local.shape[1] > 3:                  # a sphere light's: the cube face of the direction too
        key = key + cells ** 3 * local[members, 3].astype(int)
    return [members[key == k] for k in np.unique(key)]


def _highest_stand_in(stand_ins: list, pts, ng):
    """For receivers (points, geometric normals), the index of the stand-in whose centre lies highest above
    each one's tangent plane, of those that emit towards it, and that height (−inf with none)."""
    if not stand_ins or not len(pts):
        return np.zeros(len(pts), int), np.full(len(pts), -np.inf)
    centres = np.array([light_.position for light_ in stand_ins])
    directions = np.array([light_.direction for light_ in stand_ins])
    height = ng @ centres.T - np.einsum("ij,ij->i", ng, pts)[:, None]
    facing = pts @ directions.T > np.einsum("ij,ij->i", centres, directions)[None]     # in front of its plane
    height = np.where(facing, height, -np.inf)
    best = np.argmax(height, axis=1)
    return best, height[np.arange(len(pts)), best]


def _stand_in(light: Light, pts, ng, centroid, lo, hi):
    """One stand-in light for a group of receivers (points, geometric normals, and what they see of the
    emitter: seen_emitter's centroids and boxes), and which of them have its centre above their horizon
    (local_rim_lights): an area light keeps its axes and becomes the rectangle of its plane that spans the
    box; a sphere light's faces the group, in the plane of the disk it sees."""
    m = np.asarray(light.matrix, float)
    if light.kind == AREA:
        axes, width = m[:3, :2], np.array([light.size_x, light.size_y])
    else:                       # the disk that faces the group, in seen_emitter's axes
        t1, t2 = _perpendicular_axes((pts - m[:3, 3]).mean(axis=0)[None])
        axes, width = np.stack([t1[0], t2[0]], axis=1), np.full(2, 2.0 * light.radius)
    middle = centroid.mean(axis=0)
    lo, hi = lo.mean(axis=0), hi.mean(axis=0)          # the members' boxes in the emitter's axes, averaged
    # Centred on the box, the stand-in spans no more than that part (a gather technique counts all of it as
    # light); where the box's centre is below a member's horizon (the centre's tangent-plane rule would leave
    # it lit), it is centred on the centroid instead, wide enough to cover the box.
    box_centre = m[:3, 3] + axes @ ((lo + hi) / 2.0)
    if (np.einsum("ij,ij->i", ng, box_centre - pts) > 0.0).all():
        centre, size = box_centre, hi - lo
    else:
        at = (middle - m[:3, 3]) @ axes
        centre, size = middle, 2.0 * np.maximum(np.abs(lo - at), np.abs(hi - at))
    size = np.minimum(size, width)
    mat = np.array(m)
    mat[:3, 3] = centre
    if light.kind != AREA:      # a rectangle facing the group (emitting along its -Z, right-handed)
        mat[:3, 0], mat[:3, 1], mat[:3, 2] = axes[:, 1], axes[:, 0], np.cross(axes[:, 1], axes[:, 0])
        size = size[::-1]
    stand_in = replace(light, kind=AREA, matrix=mat, shape=RECTANGLE, size_x=float(size[0]), size_y=float(size[1]),
                       radius=0.0, texture=None, use_soft_falloff=False, spot_axisless=False)
    return stand_in, np.einsum("ij,ij->i", ng, centre - pts) > 0.0


def to_local(world_to_local: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Points (N, 3) through a 4×4 affine matrix."""
    return (world_to_local @ np.c_[pts, np.ones(len(pts))].T).T[:, :3]


def _bounds(xy: np.ndarray) -> tuple:
    return (xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max())


def _tangent_window(local: np.ndarray, near_floor: float):
    """Tangent bounds of a box's corners seen from the eye, and their depths. A box that reaches to or
    behind the light plane has no bound on that side: infinite there."""
    depth = -local[:, 2]
    front = depth > near_floor
    if not front.any():
        return (np.inf, -np.inf, np.inf, -np.inf), np.array([near_floor])
    t = local[front, :2] / depth[front, None]
    win = list(_bounds(t))
    if not front.all():
        # The box straddles the light plane: its points just in front of the plane, where it cuts the box, have
        # unbounded tangents on the side of the eye they lie. The cut is not where the corners behind lie: a
        # 47 m floor crossing a REFERENCE sample's plane cuts it at y < 0 while every corner behind has y > 0,
        # and a window bounded below left most receivers off the map, lit (fuzz 8423).
        cut = _plane_cut(local, front, near_floor)
        for axis in (0, 1):
            if (cut[:, axis] < 0).any():
                win[2 * axis] = -np.inf
            if (cut[:, axis] > 0).any():
                win[2 * axis + 1] = np.inf
            if np.allclose(cut[:, axis], 0.0):
                win[2 * axis], win[2 * axis + 1] = -np.inf, np.inf
    return tuple(win), depth[front]


def _plane_cut(local: np.ndarray, front: np.ndarray, plane: float) -> np.ndarray:
    """(k, 2) points where the segments from the points in front of depth `plane` to those behind it cross
    it: the convex hull's cut by that plane lies within theirs. Many points (a view's receivers) are replaced
    by the corners of two boxes (eye space), one round those in front and one round those behind, which stay
    on their sides and whose hull holds theirs."""
    a, b = local[front], local[~front]
    if len(a) * len(b) > 4096:
        a, b = (box_corners(q.min(axis=0), q.max(axis=0)) for q in (a, b))
    da, db = -a[:, 2][:, None], -b[:, 2][None, :]
    s = ((da - plane) / np.maximum(da - db, 1e-30))[..., None]          # (front, behind, 1)
    return (a[:, None, :2] + s * (b[None, :, :2] - a[:, None, :2])).reshape(-1, 2)


def _widen(win, grow) -> tuple:
    return (win[0] - grow[0], win[1] + grow[0], win[2] - grow[1], win[3] + grow[1])


def _intersect(a, b) -> tuple:
    return (max(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), min(a[3], b[3]))


def _union(a, b) -> tuple:
    return (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))


@dataclass
class ReceiverSides:
    """Where a frame's visible pixels lie against the scene's flat and convex objects (`receiver_sides`):
    what `shadowing_caster_bounds` needs to leave out a caster that cannot shadow them."""
    flat: dict = field(default_factory=dict)        # index → (normal, offset, lo, hi) of the signed distances
    enclosing: dict = field(default_factory=dict)   # index → (normals, offsets): convex objects holding them all


def receiver_sides(lights, flat: dict, convex: dict, xyz: np.ndarray, where: np.ndarray | None = None,
                   max_work: float = 2e8) -> ReceiverSides:
    """The receiver points `xyz` (…, 3), those selected by the boolean `where` (…) when given (a frame's
    covered pixels: a superset of what any light reaches, so what it rules out holds for every light), against
    the flat objects (SceneSnapshot.flat_objects) and the convex objects (SceneSnapshot.convex_objects) that
    hold one of `lights`; a convex object is tested only when its faces × the points stay under `max_work`."""
    sides = ReceiverSides()
    mask = True if where is None else where
    for index, (normal, offset) in flat.items():
        d = xyz @ np.asarray(normal, xyz.dtype) - np.asarray(offset, xyz.dtype)
        lo, hi = float(d.min(initial=np.inf, where=mask)), float(d.max(initial=-np.inf, where=mask))
        if lo <= hi:
            sides.flat[index] = (normal, offset, lo, hi)
    holding = {i: planes for i, planes in convex.items() if any(_light_inside(lt, *planes) for lt in lights)}
    if holding:
        pts = (xyz[where] if where is not None else xyz.reshape(-1, 3)).astype(np.float64)
        scale = max(float(np.abs(pts).max(initial=0.0)), 1.0)
        for index, (normals, offsets) in holding.items():
            if normals.shape[0] * pts.shape[0] > max_work:
                continue
            chunks = np.array_split(pts, max(1, pts.shape[0] * normals.shape[0] // 4_000_000))
            if max(float((c @ normals.T - offsets).max(initial=-np.inf)) for c in chunks) <= 1e-4 * scale:
                sides.enclosing[index] = (normals, offsets)
    return sides


def shadowing_caster_bounds(light: Light, object_bounds: np.ndarray, casters: np.ndarray,
                            receivers: tuple, sides: ReceiverSides | None = None, points: np.ndarray | None = None,
                            lifted: np.ndarray | None = None, facing: np.ndarray | None = None,
                            convex: dict | None = None) -> tuple | None:
    """World AABB of the caster objects that can shadow the lit receivers, or None.

    A flat caster (a ground plane at any tilt, a flattened object) shadows only what lies beyond its plane as
    seen from the light. It is left out when no lit receiver does: when the receivers' bounds stay on the
    light's side of an axis-aligned plane, or when the visible pixels do (`sides.flat`), so a large floor does
    not stretch every light's map. A convex caster that holds the light and every visible pixel
    (`sides.enclosing`: a room, a dome around the scene) shadows nothing either. Where the receivers are
    known point by point (`points`, N × 3, where their shadow rays leave from, `lifted`, and their geometric
    normals turned to the viewer, `facing`, with the `convex` casters' face planes: SceneSnapshot.convex_objects),
    a convex caster that can shadow none of them is left out too (faces_clear_light).
    """
    r_corners = box_corners(*receivers)
    tol = 1e-6 * max(float(np.abs(r_corners).max()), 1.0)
    sides = sides or ReceiverSides()
    keep = []
    for index in np.flatnonzero(casters):
        lo, hi = object_bounds[index]
        if not np.all(np.isfinite(lo)):
            continue
        if int(index) in sides.enclosing and _light_inside(light, *sides.enclosing[int(index)]):
            continue
        size = hi - lo
        axis = int(np.argmin(size))
        if size[axis] <= 1e-6 * max(float(size.max()), 1e-30):
            plane = (lo[axis] + hi[axis]) / 2.0
            side = _light_side(light, np.eye(3)[axis], plane)
            if side != 0 and np.all((r_corners[:, axis] - plane) * side >= -tol):
                continue
        if int(index) in sides.flat:    # visible pixels on the light's side of its plane (or on it): nothing to shadow
            normal, offset, d_lo, d_hi = sides.flat[int(index)]
            side = _light_side(light, normal, offset)
            # G-buffer positions on the plane itself carry float32 interpolation error (a few ulps): 1e-5 of
            # the scale. More would take a receiver just beyond it (a plane 1e-4 m above the ground) as on it.
            if (side > 0 and d_lo >= -10.0 * tol) or (side < 0 and d_hi <= 10.0 * tol):
                continue
        if points is not None and convex and int(index) in convex and faces_clear_light(
                light, *convex[int(index)], points, lifted, facing,
                1e-5 * max(float(np.abs(object_bounds[index]).max()), 1.0)):
            continue
        keep.append(index)
    if not keep:
        return None
    return object_bounds[keep, 0].min(axis=0), object_bounds[keep, 1].max(axis=0)


def faces_clear_light(light: Light, normals: np.ndarray, offsets: np.ndarray, points: np.ndarray,
                      lifted: np.ndarray | None, facing: np.ndarray | None, tol: float,
                      chunk: int = 1 << 21) -> bool:
    """Whether a convex object (the region n·p ≤ offset of its outward face planes) can shadow none of the
    receiver `points` (N × 3; `lifted`: where their shadow rays leave from, or None; `facing`: their
    geometric normals turned to the viewer, or None) in a view of `light`:
    - a point on the object's own surface (within `tol`), seen from outside (its `facing` normal along the
      face's outward one) with the light's centre (a sun's direction) in front of the face it lies on: every
      technique's tangent-plane rule (light_view.glsl receiver_depth_at) keeps what lies behind that plane,
      the whole object, from shadowing it (the terminator band of a ball under a stand-in for the part of a
      light it sees). Seen from inside (a room's wall), the object lies in front of the receiver's plane;
    - any other point, and its lifted point, with a face plane that has it on or in front and the whole light
      strictly in front: the segment to any point of the light stays in that open half-space, which the
      object does not enter."""
    normals, offsets = np.asarray(normals, float), np.asarray(offsets, float)
    whole, centre = _light_in_front(light, normals, offsets)
    if not centre.any():
        return False
    pts = np.asarray(points, float).reshape(-1, 3)
    up = None if lifted is None else np.asarray(lifted, float).reshape(-1, 3)
    # Faces a stride apart first (a mesh lists neighbouring faces together): most points lie in front of one
    # of the first few planes, and _in_front_of_any stops looking for them there.
    order = np.argsort(np.arange(int(whole.sum())) % 16, kind="stable")
    n_whole, o_whole = normals[whole][order], offsets[whole][order]
    start, step = 0, 256            # a small first chunk: a caster that does shadow them fails fast
    while start < len(pts):
        p = pts[start:start + step]
        clear = _in_front_of_any(p, n_whole, o_whole, tol)
        if up is not None:
            clear[clear] = _in_front_of_any(up[start:start + step][clear], n_whole, o_whole, tol)
        if not clear.all():             # the rest must lie on the surface, seen from outside, facing the centre
            if facing is None:
                return False
            rest = ~clear
            d = p[rest] @ normals.T - offsets
            face = np.argmax(d, axis=1)
            outside = np.einsum("ij,ij->i", np.asarray(facing, float)[start:start + step][rest], normals[face]) > 0.0
            if not ((np.abs(d.max(axis=1)) <= tol) & centre[face] & outside).all():
                return False
        start, step = start + step, max(step, chunk // len(normals))
    return True


def _in_front_of_any(points: np.ndarray, normals: np.ndarray, offsets: np.ndarray, tol: float,
                     block: int = 64) -> np.ndarray:
    """Whether each point (N × 3) lies on or in front of (n·p − o ≥ −tol) any of the planes: the planes a block
    at a time, each block for the points not yet in front of an earlier one (the answer of the whole N × F
    product at a fraction of its work when most points are in front of an early plane)."""
    front = np.zeros(len(points), bool)
    todo = np.arange(len(points))
    for start in range(0, len(normals), block):
        if not len(todo):
            break
        d = points[todo] @ normals[start:start + block].T - offsets[start:start + block]
        hit = (d >= -tol).any(axis=1)
        front[todo[hit]] = True
        todo = todo[~hit]
    return front


def enclosing_shell(snap, light: Light, casters, max_faces: int = 4096, bounds=None) -> int | None:
    """A closed caster among `casters` (object indices), seen by the camera, with the camera's whole near plane
    on one side of it and `light` wholly on the other, or None. Every point the camera sees then lies on the
    camera's side (the caster stops every camera ray that would cross it), and every path from there to any
    point of the light crosses it: the light reaches none of the visible receivers (a room or a huge ball
    around the camera lit from outside, a lamp inside a closed box seen from outside). A convex caster of up
    to `max_faces` faces around the camera is decided by its face planes; any other case by the side of a
    ball around the near plane and one around the light (solids.ball_inside); a sun lies outside them all.
    `bounds`: snap.object_bounds() where the caller has them (a pass over every triangle)."""
    cam = snap.camera
    ndc = np.array([[x, y, -1.0, 1.0] for x in (-1.0, 1.0) for y in (-1.0, 1.0)])
    near = ndc @ np.linalg.inv(np.asarray(cam.projection, float) @ np.asarray(cam.view, float)).T
    near = near[:, :3] / near[:, 3:]
    if not np.all(np.isfinite(near)):
        return None
    # The shell must stop the camera's rays too: one the camera sees through (visible_camera off) may hold
    # the camera while the receivers it sees lie outside, lit.
    wanted = set(int(i) for i in casters if snap.objects[int(i)].receiver)
    bounds = snap.object_bounds() if bounds is None else np.asarray(bounds, float)
    for index, (normals, offsets) in snap.convex_objects(max_faces, around=near, bounds=bounds).items():
        if index not in wanted:
            continue
        scale = max(float(np.abs(bounds[index]).max()), 1.0)
        inside = float((near @ normals.T - offsets).max()) < -1e-4 * scale     # strictly: not on its surface
        if inside and _light_outside(light, normals, offsets) and snap.is_closed(index):
            return index
    centre = near.mean(axis=0)
    radius = float(np.linalg.norm(near - centre, axis=1).max())
    holds_camera = np.all((near[None] >= bounds[:, None, 0]) & (near[None] <= bounds[:, None, 1]), axis=(1, 2))
    holds_light = np.zeros(len(bounds), bool)
    if light.kind != SUN:
        position = np.asarray(light.position, float)
        holds_light = np.all((position >= bounds[:, 0]) & (position <= bounds[:, 1]), axis=1)
    for index in np.flatnonzero(holds_camera | holds_light):
        if int(index) not in wanted or not snap.is_closed(int(index)):
            continue
        camera_inside = snap.ball_inside(int(index), centre, radius)
        if camera_inside is None:
            continue
        light_inside = False if light.kind == SUN else snap.ball_inside(int(index), light.position,
                                                                         light_ball_radius(light))
        if light_inside is not None and light_inside != camera_inside:
            return int(index)
    return None


def light_ball_radius(light: Light) -> float:
    """The radius of a ball around the light's centre that holds all of its emitter; 0 for a sun, which has
    no centre in the scene."""
    if light.kind == SUN:
        return 0.0
    if light.kind == AREA:
        return 0.5 * float(np.hypot(light.size_x, light.size_y))
    return float(light.radius)


def _light_in_front(light: Light, normals: np.ndarray, offsets: np.ndarray) -> tuple:
    """Per plane n·p = offset (unit normals, F × 3): whether the whole light (its extent; a sun's cone of
    directions) lies strictly in front of it, and whether its centre (a sun's direction) does."""
    if light.kind == SUN:
        towards = -(normals @ np.asarray(light.direction, float))
        return towards > np.sin(min(light.angle / 2.0, np.pi / 2)), towards > 0.0
    height = normals @ np.asarray(light.position, float) - offsets
    return height > np.maximum(_light_reach(light, normals), 1e-9), height > 0.0


def _light_outside(light: Light, normals: np.ndarray, offsets: np.ndarray) -> bool:
    """Whether the whole light (its extent included) lies strictly outside the convex region n·p ≤ offset:
    beyond one of its face planes. A sun lies outside every bounded region (its rays come from infinity)."""
    if light.kind == SUN:
        return True
    return bool(np.any(_light_in_front(light, normals, offsets)[0]))


def _light_inside(light: Light, normals: np.ndarray, offsets: np.ndarray) -> bool:
    """Whether the whole light (its extent included) lies strictly inside the convex region n·p ≤ offset."""
    if light.kind == SUN:
        return False
    return bool(np.all(normals @ np.asarray(light.position, float) - offsets < -np.maximum(
        _light_reach(light, normals), 1e-9)))


def _light_side(light: Light, normal: np.ndarray, offset: float) -> float:
    """The side (±1) of the plane n·p = offset the light is on; 0 when the light (a wide sun's cone of
    directions, or the extent of a large light) reaches across the plane, which can then shadow either side."""
    if light.kind == SUN:
        towards = -float(np.dot(light.direction, normal))
        return 0.0 if abs(towards) <= np.sin(min(light.angle / 2.0, np.pi / 2)) else float(np.sign(towards))
    height = float(np.dot(light.position, normal)) - offset
    return 0.0 if abs(height) <= float(_light_reach(light, normal)) else float(np.sign(height))


def _light_reach(light: Light, normals: np.ndarray) -> np.ndarray:
    """How far the light's emitter reaches from its centre along each unit normal (…, 3): the support of
    its rectangle or ellipse (an area light at 5° above the ground, 2.5 m wide, does not reach the ground
    though its half diagonal exceeds its height), or its radius."""
    if light.kind != AREA:
        return np.full(np.shape(normals)[:-1], float(light.radius))
    m = np.asarray(light.matrix, float)
    along_x = np.abs(np.asarray(normals) @ m[:3, 0]) * light.size_x / 2.0
    along_y = np.abs(np.asarray(normals) @ m[:3, 1]) * light.size_y / 2.0
    if light.shape in (DISK, ELLIPSE):
        return np.hypot(along_x, along_y)
    return along_x + along_y


# A part view's texels across a pixel's footprint (needed_map_size), and its least map size. Measured on
# suzanne and balls at 128² (HARD, PCSS, BACKPROJECTION, PVSM against Cycles): at 2, mae_shadow rose by up to
# 0.0007 over full-size part maps; at 4 by at most 0.0002, with 4.2× fewer texels over the 8 views.
PART_MAP_TEXELS_PER_PIXEL = 4.0
PART_MAP_LEAST = 64


def needed_map_size(view: LightView, points: np.ndarray, camera, size: int) -> int:
    """The map size (texels along the longer side, at most `size`) at which `view`'s texels cover at most
    1 / PART_MAP_TEXELS_PER_PIXEL of the camera pixel across at each of `points` (world, N × 3): finer
    texels than that no longer move a shadow edge the pixel shows. Both footprints are taken across, as if
    seen head on (the pixel's: its depth times the camera's tangent per pixel; the texel's: its tangent times
    the depth from the light, or metres for a sun), which errs on the fine side. For the views that hold a few pixels
    of a light (stand-ins, cube faces, a sun's rim views): built at the full size, each cost as much as the
    light's own view for a handful of pixels."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    if len(pts) == 0:
        return min(size, PART_MAP_LEAST)
    p = np.asarray(camera.projection, np.float64)
    per_pixel = min(2.0 / (abs(p[0, 0]) * camera.width), 2.0 / (abs(p[1, 1]) * camera.height))
    if camera.is_ortho:
        pixel = np.full(len(pts), per_pixel)
    else:
        pixel = np.maximum(-to_local(np.asarray(camera.view, np.float64), pts)[:, 2], 1e-9) * per_pixel
    x0, x1, y0, y1 = view.window
    extent = max(x1 - x0, y1 - y0)
    texel_depth = 1.0 if view.is_ortho else np.maximum(-to_local(np.asarray(view.view, np.float64), pts)[:, 2],
                                                       1e-9)
    need = float(np.max(PART_MAP_TEXELS_PER_PIXEL * extent * texel_depth / np.maximum(pixel, 1e-30)))
    if not np.isfinite(need):
        return size
    return int(min(size, max(PART_MAP_LEAST, math.ceil(need))))


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


def sub_view(view: LightView, window, width: int, height: int) -> LightView:
    """The same eye, frame and depth range as `view` over another window (a part of, or past, its own) at
    width × height texels: one tile of a virtual shadow map built on `view`."""
    window = tuple(float(v) for v in window)
    proj = ortho(window, view.near, view.far) if view.is_ortho else frustum(window, view.near, view.far)
    return LightView(view.view, proj, int(width), int(height), view.near, view.far, view.is_ortho, window,
                     view.clamped, frame=view.frame, face=view.face)
