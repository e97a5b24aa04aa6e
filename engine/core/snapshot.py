"""The scene as the GPU side sees it: numpy arrays and small dataclasses, no bpy, no GL.

`engine/blender/extract.py` fills these from a Blender depsgraph; the built-in test scenes and the tests may also
build them directly. Everything is in world space, metres, right-handed, Z up (Blender's convention).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from . import solids

# Light kinds, as Blender names them.
AREA, POINT, SPOT, SUN = "AREA", "POINT", "SPOT", "SUN"
# Area light shapes.
SQUARE, RECTANGLE, DISK, ELLIPSE = "SQUARE", "RECTANGLE", "DISK", "ELLIPSE"


@dataclass
class Light:
    """One light. `matrix` is the object's world matrix with scale removed (columns: local X, Y, Z axes
    and the position); lights emit along local -Z (area, spot, sun) or in all directions (point)."""

    name: str
    kind: str                       # AREA | POINT | SPOT | SUN
    matrix: np.ndarray              # (4, 4) float64, orthonormal rotation + translation
    color: np.ndarray               # (3,) float64, linear RGB, already includes temperature
    power: float                    # watts for AREA/POINT/SPOT, W/m² (irradiance) for SUN; exposure applied
    shape: str = SQUARE             # AREA only
    size_x: float = 0.0             # AREA: full extent along local X in world units (object scale applied)
    size_y: float = 0.0             # AREA: full extent along local Y (equals size_x for SQUARE/DISK)
    radius: float = 0.0             # POINT/SPOT: sphere radius in world units
    angle: float = 0.0              # SUN: full angular diameter in radians
    spot_size: float = np.pi        # SPOT: full cone angle in radians
    spot_blend: float = 0.0         # SPOT: 0..1
    spot_scale: np.ndarray = field(default_factory=lambda: np.ones(3))  # SPOT: object scale (shapes the cone)
    # SPOT whose object axes are not perpendicular (a light under a rotated, non-uniformly scaled parent): the
    # object's linear map in `matrix`'s frame (columns: its X, Y, Z axes there), which shapes the cone instead
    # of `spot_scale` (spot_to_local). None: the axes are perpendicular, diag(spot_scale) says it all.
    spot_linear: np.ndarray | None = None
    use_soft_falloff: bool = True   # POINT/SPOT: Cycles' soft falloff (emitter = disk facing the receiver)
    # SPOT with a zero Z scale: no emission axis, so Cycles' light tree gives it importance only where float32
    # still resolves its radius from the receiver (irradiance.cycles_radius_share).
    spot_axisless: bool = False
    # AREA: emission texture, (H, W, 3) linear RGB over the light's local [-1, 1]² (row 0 at local y = -1,
    # column 0 at x = -1), normalised to mean 1; its mean colour is folded into `color`. None: uniform.
    texture: np.ndarray | None = None
    casts_shadow: bool = True

    @property
    def position(self) -> np.ndarray:
        return self.matrix[:3, 3]

    @property
    def direction(self) -> np.ndarray:
        """Unit emission axis (local -Z) in world space."""
        return -self.matrix[:3, 2]

    @property
    def area(self) -> float:
        """World-space emitting area of an AREA light (0 for other kinds)."""
        if self.kind != AREA:
            return 0.0
        if self.shape in (DISK, ELLIPSE):
            return float(np.pi / 4.0 * self.size_x * self.size_y)
        return float(self.size_x * self.size_y)

    def spot_to_local(self) -> np.ndarray:
        """3×3 map of a world direction leaving a spot into the space where Cycles' cone is round (its local
        -Z the axis): the inverse of the object's linear map (kernel/light/spot.h takes each ray through the
        inverse object transform). With perpendicular axes that is diag(1 / spot_scale) · matrixᵀ."""
        turn = np.asarray(self.matrix, np.float64)[:3, :3].T
        if self.spot_linear is not None:
            return np.linalg.inv(np.asarray(self.spot_linear, np.float64)) @ turn
        return np.diag(1.0 / np.maximum(np.abs(np.asarray(self.spot_scale, np.float64)), 1e-12)) @ turn

    @property
    def is_delta(self) -> bool:
        """True when the light has no extent, so its shadow is hard."""
        if self.kind == AREA:
            return self.size_x <= 0.0 or self.size_y <= 0.0
        if self.kind == SUN:
            return self.angle <= 0.0
        return self.radius <= 0.0


@dataclass
class Camera:
    """`view` maps world to camera space (camera looks down -Z); `projection` is OpenGL-style clip space
    as Blender's `calc_matrix_camera` gives it (sensor fit, shift and orthographic already applied)."""

    name: str
    view: np.ndarray                # (4, 4) float64
    projection: np.ndarray          # (4, 4) float64
    width: int                      # pixels, resolution percentage applied
    height: int
    is_ortho: bool = False
    clip_start: float = 0.1
    clip_end: float = 100.0

    @property
    def position(self) -> np.ndarray:
        return np.linalg.inv(self.view)[:3, 3]


@dataclass
class ObjectInfo:
    """Per-object facts the techniques and the warnings need."""

    name: str
    caster: bool = True             # appears in shadow maps (Blender: visible_shadow)
    receiver: bool = True           # appears in the camera view (Blender: visible_camera)
    role: str = "BOTH"              # Penumbra object role for techniques that split casters/receivers
    importance: float = 0.0         # 0 … 1: BACKPROJECTION's importance budget map raises the budget on its pixels
    terminator_offset: float = 0.1  # Blender's Shadow Terminator Geometry Offset (Cycles' smooth-surface lift)
    closed: bool = False            # its mesh is watertight: every edge joins exactly two faces


@dataclass
class AlbedoTexture:
    """An image a material's base colour is sampled from, per pixel, through the triangles' `uv`."""

    name: str                       # the image's name, for messages
    pixels: np.ndarray              # (H, W, 3) float32 linear RGB, or uint8 sRGB bytes when `srgb`; row 0 at
                                    # v = 0 (the image's bottom row)
    interpolation: str = "Linear"   # Linear (bilinear) | Closest
    extension: str = "REPEAT"       # REPEAT | EXTEND (edge texels) | CLIP (black outside) | MIRROR
    srgb: bool = False              # pixels are sRGB bytes, decoded after filtering (as Cycles does)


# Convex objects up to this many triangles are told apart for caster culling (a UV sphere has 960, a level-3
# icosphere 1280): the test costs the object's corners × its faces.
CONVEX_CASTER_FACES = 2048


@dataclass
class SceneSnapshot:
    """Triangle soup plus lights and camera.

    positions: (T, 3, 3) float32 world-space corners, counter-clockwise seen from the front
    normals:   (T, 3, 3) float32 unit shading normals per corner (smooth or flat as the mesh says)
    object_id: (T,) int32 index into `objects`
    albedo:    (T, 3) float32 linear RGB diffuse colour (a factor on the texture / colour attribute, if any)

    Textured base colours (all three None when no triangle has one):
    uv:           (T, 3, 2) float32 texture coordinates per corner, the material's Mapping already applied
    texture_id:   (T,) int32 index into `textures`, -1 where the albedo is not textured
    corner_color: (T, 3, 3) float32 linear RGB per corner (a colour attribute) multiplying the albedo
    """

    positions: np.ndarray
    normals: np.ndarray
    object_id: np.ndarray
    albedo: np.ndarray
    objects: list[ObjectInfo]
    lights: list[Light]
    camera: Camera
    name: str = "scene"
    warnings: list[str] = field(default_factory=list)
    uv: np.ndarray | None = None
    texture_id: np.ndarray | None = None
    corner_color: np.ndarray | None = None
    textures: list[AlbedoTexture] = field(default_factory=list)
    # Images a setting names (a Blender image datablock, a blend-relative path), read by the extraction:
    # the setting's text → (H, W) float32 grey (core/importance.py), row 0 at the bottom.
    images: dict = field(default_factory=dict)

    @property
    def triangle_count(self) -> int:
        return int(self.positions.shape[0])

    def bounds(self, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds of the triangles selected by `mask` (all when None)."""
        pos = self.positions if mask is None else self.positions[mask]
        if pos.size == 0:
            return np.zeros(3), np.zeros(3)
        flat = pos.reshape(-1, 3)
        return flat.min(axis=0).astype(np.float64), flat.max(axis=0).astype(np.float64)

    def object_bounds(self) -> np.ndarray:
        """(O, 2, 3) float64: per-object AABB (lo, hi); +inf/-inf for objects without triangles."""
        out = np.empty((len(self.objects), 2, 3))
        out[:, 0], out[:, 1] = np.inf, -np.inf
        if self.triangle_count == 0:
            return out
        # Degenerate (zero-area or non-finite) triangles draw nothing, so they must not stretch the bounds.
        p = self.positions
        with np.errstate(invalid="ignore", over="ignore"):
            area2 = np.square(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])).sum(axis=1)
        valid = np.isfinite(area2) & (area2 > 0.0)
        if not valid.any():
            return out
        p, object_id = p[valid], self.object_id[valid]
        lo, hi = p.min(axis=1), p.max(axis=1)
        # Triangles arrive in runs per object: reduce each run, then fold runs of the same object.
        starts = np.flatnonzero(np.r_[True, object_id[1:] != object_id[:-1]])
        ids = object_id[starts]
        np.minimum.at(out[:, 0], ids, np.minimum.reduceat(lo, starts))
        np.maximum.at(out[:, 1], ids, np.maximum.reduceat(hi, starts))
        return out

    def clearances(self, points) -> np.ndarray:
        """For each of `points` (N × 3), a lower bound on its distance to the nearest triangle (inf without
        any): per triangle the larger of its plane's distance and its centroid's less its farthest corner's."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        p, normal, area, _ = self._drawn_triangles()
        if not len(p):
            return np.full(len(points), np.inf)
        centroid = p.mean(axis=1)
        reach = np.linalg.norm(p - centroid[:, None], axis=2).max(axis=1)
        unit = normal / area[:, None]
        return np.array([np.min(np.maximum(np.abs(np.einsum("ij,ij->i", x - p[:, 0], unit)),
                                           np.linalg.norm(x - centroid, axis=1) - reach)) for x in points])

    def _drawn_triangles(self, mask: np.ndarray | None = None):
        """The triangles (those selected by `mask`, all when None) that draw something (finite, non-zero
        area), in float64: corners (T, 3, 3), normals (T, 3, unnormalised, twice the area), areas ×2 (T,),
        object ids (T,)."""
        p = (self.positions if mask is None else self.positions[mask]).astype(np.float64)
        ids = self.object_id if mask is None else self.object_id[mask]
        with np.errstate(invalid="ignore", over="ignore"):
            normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
            area = np.linalg.norm(normal, axis=1)
        valid = np.isfinite(area) & (area > 0.0)
        return p[valid], normal[valid], area[valid], ids[valid]

    def drawn_triangles(self, index: int) -> np.ndarray:
        """Object `index`'s triangles that draw something, (T, 3, 3) float64 world corners."""
        return self._drawn_triangles(self.object_id == index)[0]

    def drawn_faces(self, index: int):
        """Object `index`'s triangles that draw something: world corners (T, 3, 3), normals (T, 3, unnormalised,
        twice the area) and areas ×2 (T,), in float64."""
        return self._drawn_triangles(self.object_id == index)[:3]

    def flat_objects(self, limit: int = 16, include=None) -> dict:
        """Objects whose triangles all lie in one plane (a floor at any tilt, a flattened object), the
        `limit` largest, or those of `include` (object indices): index → (unit normal, offset) of the plane
        n·p = offset. A flat object shadows only what lies beyond its plane as seen from the light
        (lightview.shadowing_caster_bounds)."""
        if self.triangle_count == 0 or not self.objects:
            return {}
        p, normal, area, ids = self._drawn_triangles()
        weight = np.bincount(ids, area, len(self.objects))
        tol = 1e-6 * max(float(np.abs(p).max()) if p.size else 1.0, 1.0)
        out = {}
        for index in (np.argsort(-weight)[:limit] if include is None else include):
            mine = ids == index
            if weight[index] <= 0.0:
                continue
            # The plane of the area-weighted normal (both faces of a flattened solid turned one way); flat
            # when every vertex lies on it.
            n_tri = normal[mine]
            n = (n_tri * np.where(n_tri @ n_tri[np.argmax(area[mine])] < 0.0, -1.0, 1.0)[:, None]).sum(axis=0)
            n /= np.linalg.norm(n)
            pts = p[mine].reshape(-1, 3) @ n
            offset = float(pts.mean())
            if np.abs(pts - offset).max() <= tol:
                out[int(index)] = (n, offset)
        return out

    def coincident_sheets(self) -> dict:
        """Closed casters flattened into a plane (a zero object scale axis), whose surface Cycles shadows
        through its own coincident opposite faces: index → (unit normal, offset, bounds (2, 3), share).
        Every point of a flattened closed surface lies on two or more of its sheets, and a shadow ray leaving
        one meets another at t ≈ 0. Where the plane is a coordinate plane (its coordinate the same float at
        every corner) t is exactly 0 and every ray is blocked (share 1); otherwise t's rounding is a coin
        flip and half of them are (share 0.5). Measured with Cycles, a flat torus under a sun: V 0.04 mean
        unrotated, 0.497 and 0.501 tilted by 17° and 40° (64 spp)."""
        if self.triangle_count == 0:
            return {}
        wanted = [i for i, ob in enumerate(self.objects) if ob.closed and ob.caster]
        if not wanted:
            return {}
        flat = self.flat_objects(include=wanted)
        bounds = self.object_bounds()
        out = {}
        for index in wanted:
            if index not in flat:
                continue
            corners = self.positions[self.object_id == index].reshape(-1, 3)
            exact = bool(np.any(np.all(corners == corners[:1], axis=0)))
            n, offset = flat[index]
            out[index] = (n, offset, bounds[index], 1.0 if exact else 0.5)
        return out

    def convex_objects(self, max_faces: int = 512, around=None, bounds: np.ndarray | None = None) -> dict:
        """Convex objects of at most `max_faces` triangles: index → (outward face normals (F, 3), offsets (F,)),
        the region n·p ≤ offset. A light inside such an object (a room, a dome) cannot be shadowed by it on
        anything inside it: the segment between two points of a convex region stays inside it, and the
        surface lies on the region's boundary. With `around` (points, (N, 3)), only the objects whose bounds
        hold one of them are examined (the lights: a scene of many small boxes costs one pass, not one per
        box). `bounds`: object_bounds() when the caller has it already."""
        if self.triangle_count == 0:
            return {}
        bounds = self.object_bounds() if bounds is None else bounds
        finite = np.isfinite(bounds).all(axis=(1, 2))
        if not finite.any():
            return {}
        # the scale of every drawn vertex, as the bounds hold them
        tol = 1e-4 * max(float(np.abs(bounds[finite]).max()), 1.0)
        counts = np.bincount(self.object_id, minlength=len(self.objects))
        candidates = finite & (counts > 3) & (counts <= max_faces)
        if around is not None:
            pts = np.asarray(around, float).reshape(-1, 3)
            holds = (pts[None] >= bounds[:, None, 0]) & (pts[None] <= bounds[:, None, 1])
            candidates &= holds.all(axis=2).any(axis=1)
        out = {}
        for index in np.flatnonzero(candidates):
            p, normal, area, _ = self._drawn_triangles(self.object_id == index)
            n = normal / area[:, None]
            d = np.einsum("fj,fj->f", n, p[:, 0])
            height = np.unique(p.reshape(-1, 3), axis=0) @ n.T - d     # each corner once: shared ones are many
            if height.max() <= tol:             # every vertex behind every face
                out[int(index)] = (n, d)
            elif height.min() >= -tol:          # faces wound inwards (a room seen from inside)
                out[int(index)] = (-n, -d)
        return out

    @cached_property
    def convex_casters(self) -> dict:
        """convex_objects of up to CONVEX_CASTER_FACES triangles, whatever they hold: where a light view's
        receivers are known point by point, those that can shadow none of them are left out
        (lightview.faces_clear_light). Once per snapshot, and only when asked for."""
        return self.convex_objects(CONVEX_CASTER_FACES)

    def is_closed(self, index: int) -> bool:
        """Whether object `index`'s drawn triangles close up into a watertight surface: every edge shared by
        exactly two of them, corners matched to 1e-6 of the object's extent. Only then does every path from
        its inside to its outside cross it (convex_objects alone admits an open dome)."""
        if index in self._closed:
            return self._closed[index]
        p = self.drawn_triangles(index)
        if len(p) < 4:
            self._closed[index] = False
            return False
        lo, hi = p.reshape(-1, 3).min(axis=0), p.reshape(-1, 3).max(axis=0)
        step = 1e-6 * max(float(np.abs(hi - lo).max()), 1e-30)
        corners = np.round((p - lo) / step).astype(np.int64)                      # (T, 3, 3) grid keys
        _, vertex = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
        vertex = vertex.reshape(-1, 3)
        edges = np.sort(np.stack([vertex[:, [0, 1]], vertex[:, [1, 2]], vertex[:, [2, 0]]], axis=1).reshape(-1, 2),
                        axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        self._closed[index] = closed = bool(np.all(counts == 2))
        return closed

    @cached_property
    def _closed(self) -> dict:
        """is_closed's answers, once per object and snapshot (every light of every frame asks)."""
        return {}

    def ball_inside(self, index: int, centre, radius: float) -> bool | None:
        """solids.ball_inside for object `index`'s drawn triangles, once per ball and snapshot: every light
        of a frame asks about the ball around the camera's near plane."""
        key = (index, *(float(v) for v in centre), float(radius))
        if key not in self._ball_sides:
            self._ball_sides[key] = solids.ball_inside(self.drawn_triangles(index), centre, radius)
        return self._ball_sides[key]

    @cached_property
    def _ball_sides(self) -> dict:
        return {}

    def terminator_offset(self) -> tuple[float, str | None]:
        """The Shadow Terminator Geometry Offset the visible objects share (Cycles' default 0.1 when there are
        none), and a warning when they differ: the G-buffer carries no object index, so one value serves
        the frame (the largest, the one most objects are rendered with being unknowable here)."""
        values = sorted({float(o.terminator_offset) for o in self.objects if o.receiver})
        if not values:
            return 0.1, None
        if len(values) == 1:
            return values[0], None
        return values[-1], (f"objects differ in Shadow Terminator Geometry Offset ({', '.join(f'{v:g}' for v in values)}): "
                            f"Penumbra uses {values[-1]:g} for all of them")

    @cached_property
    def has_smooth_triangles(self) -> bool:
        """True when some triangle's corner normals differ (flat triangles carry their own normal thrice).
        One pass over the normals per snapshot, not per frame (a bench renders one snapshot many times)."""
        n = self.normals
        return bool(n.shape[0]) and bool((np.abs(n[:, 1:] - n[:, :1]) > 1e-6).any())

    def caster_mask(self) -> np.ndarray:
        flags = np.array([o.caster for o in self.objects] or [False], dtype=bool)
        return flags[self.object_id] if self.triangle_count else np.zeros(0, dtype=bool)

    def receiver_mask(self) -> np.ndarray:
        flags = np.array([o.receiver for o in self.objects] or [False], dtype=bool)
        return flags[self.object_id] if self.triangle_count else np.zeros(0, dtype=bool)

    @staticmethod
    def empty_geometry() -> dict:
        return dict(
            positions=np.zeros((0, 3, 3), np.float32),
            normals=np.zeros((0, 3, 3), np.float32),
            object_id=np.zeros(0, np.int32),
            albedo=np.zeros((0, 3), np.float32),
        )
