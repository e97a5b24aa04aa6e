"""Scene geometry on the GPU, drawn through one interface whatever its layout.

`SoupGeometry` (final renders) holds the snapshot's world-space triangle soup in one vertex buffer, with
index buffers per role. The viewport's geometry (engine/render/viewport.py) keeps one object-space buffer per mesh
and draws instances with their model matrices, so moving an object uploads nothing. Shaders see the same
attributes either way (position, normal, albedo: 9 floats per vertex) plus u_model / u_normal_matrix.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.snapshot import SceneSnapshot
from .programs import set_uniforms

VERTEX_FORMAT = "3f 3f 3f"
ATTRIBUTES = ("in_position", "in_normal", "in_albedo")
IDENTITY4 = tuple(np.eye(4, dtype=np.float32).ravel())
IDENTITY3 = tuple(np.eye(3, dtype=np.float32).ravel())


@dataclass
class Draw:
    vbo: object
    ibo: object | None          # None: draw the whole buffer
    vertices: int
    model: tuple = IDENTITY4     # column-major mat4
    normal: tuple = IDENTITY3    # column-major mat3 (cofactor of the model's 3×3, sign-fixed)
    mirrored: bool = False       # the model flips handedness: front faces wind the other way


def interleave(positions: np.ndarray, normals: np.ndarray, albedo: np.ndarray) -> bytes:
    """(T,3,3) positions and normals and (T,3) albedo → the vertex buffer layout."""
    t = positions.shape[0]
    vertices = np.empty((t, 3, 9), np.float32)
    vertices[..., 0:3] = positions
    vertices[..., 3:6] = normals
    vertices[..., 6:9] = albedo[:, None, :]
    return vertices.tobytes()


class SceneGeometry:
    """What the frame needs from geometry: draws per role, per-object bounds, whether anything casts."""

    has_casters = False

    def draws(self, role: str, objects: frozenset | None = None) -> list[Draw]:
        raise NotImplementedError

    def object_bounds(self) -> np.ndarray:
        raise NotImplementedError

    def flat_objects(self) -> dict:
        """Flat objects' planes (SceneSnapshot.flat_objects); none known."""
        return {}

    def convex_objects(self) -> dict:
        """Convex objects' face planes (SceneSnapshot.convex_objects); none known."""
        return {}

    def render(self, ctx, prog, role: str, objects: frozenset | None = None, position_only: bool = False):
        """Draw `role` ("receiver" or "caster"), optionally only the given object indices, with `prog`."""
        fmt = "3f 24x" if position_only else VERTEX_FORMAT
        attrs = ATTRIBUTES[:1] if position_only else ATTRIBUTES
        for d in self.draws(role, objects):
            set_uniforms(prog, {"u_model": d.model, "u_normal_matrix": d.normal, "u_mirrored": int(d.mirrored)})
            if d.ibo is None:
                vao = ctx.vertex_array(prog, [(d.vbo, fmt, *attrs)])
            else:
                vao = ctx.vertex_array(prog, [(d.vbo, fmt, *attrs)], d.ibo, index_element_size=4)
            vao.render(vertices=d.vertices)
            vao.release()

    def release(self):
        pass


class SoupGeometry(SceneGeometry):
    """The snapshot's world-space triangles in one buffer; index buffers per role (and object filter)."""

    def __init__(self, ctx, snap: SceneSnapshot):
        self._ctx, self._snap = ctx, snap
        t = snap.triangle_count
        self.vbo = ctx.buffer(interleave(snap.positions, snap.normals, snap.albedo) if t else bytes(36))
        self._masks = {"receiver": snap.receiver_mask(), "caster": snap.caster_mask()}
        self.has_casters = bool(self._masks["caster"].any())
        self._ibos: dict = {}
        self._bounds = self._flat = self._convex = None
        self.nbytes = self.vbo.size

    def draws(self, role, objects=None):
        key = (role, objects)
        if key not in self._ibos:
            mask = self._masks[role]
            if objects is not None:
                mask = mask & np.isin(self._snap.object_id, list(objects))
            corners = np.flatnonzero(np.repeat(mask, 3)).astype(np.uint32)
            self._ibos[key] = (self._ctx.buffer(corners.tobytes()) if corners.size else None, int(corners.size))
        ibo, count = self._ibos[key]
        return [Draw(self.vbo, ibo, count)] if count else []

    def object_bounds(self):
        if self._bounds is None:
            self._bounds = self._snap.object_bounds()
        return self._bounds

    def flat_objects(self):
        if self._flat is None:
            self._flat = self._snap.flat_objects()
        return self._flat

    def convex_objects(self):
        if self._convex is None:
            self._convex = self._snap.convex_objects()
        return self._convex

    def release(self):
        self.vbo.release()
        for ibo, _ in self._ibos.values():
            if ibo is not None:
                ibo.release()
        self._ibos.clear()
