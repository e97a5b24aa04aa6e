"""What the viewport's scene reader hands the renderer: object-space meshes, their instances, lights.
Plain data, no bpy and no GL."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MeshPiece:
    """One mesh in object space, ready to upload: positions/normals (T,3,3), albedo (T,3) or per corner
    (T,3,3), local bounds. Textured: triangles ordered by texture, `uv` (T,3,2), `ranges` of
    (index into `textures` or -1, first triangle, count)."""
    positions: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    version: int = 0
    uv: np.ndarray | None = None
    ranges: list = field(default_factory=list)
    textures: list = field(default_factory=list)        # AlbedoTexture
    closed: bool = False        # the mesh is watertight (ObjectInfo.closed), read with the piece

    @property
    def bounds(self) -> np.ndarray:
        flat = self.positions.reshape(-1, 3)
        return np.stack([flat.min(axis=0), flat.max(axis=0)]).astype(np.float64)


@dataclass
class Instance:
    key: tuple                  # MeshPiece key
    matrix: np.ndarray          # (4,4) object → world
    object_index: int


@dataclass
class SceneState:
    """What one viewport frame needs besides the GPU-resident meshes."""
    pieces: dict                # key → MeshPiece (only the ones that changed since the last sync are new)
    instances: list
    objects: list
    lights: list
    warnings: list
    name: str
    version: int
    images: dict = field(default_factory=dict)     # SceneSnapshot.images
