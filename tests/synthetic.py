"""Scenes built directly as SceneSnapshots (no bpy): fast GPU tests of the pipeline's geometry."""
from __future__ import annotations

import numpy as np

from penumbra.engine.core.snapshot import AREA, SQUARE, Camera, Light, ObjectInfo, SceneSnapshot
from penumbra.engine.measure.stress import look_at, perspective


def quad(center, half, normal_up=True):
    """Two triangles of an axis-aligned horizontal square, counter-clockwise seen from +Z."""
    cx, cy, cz = center
    a, b = np.array([cx - half, cy - half, cz]), np.array([cx + half, cy - half, cz])
    c, d = np.array([cx + half, cy + half, cz]), np.array([cx - half, cy + half, cz])
    tris = np.array([[a, b, c], [a, c, d]], np.float32)
    return tris if normal_up else tris[:, ::-1]


def floating_plane(size=128, light_size=1.0, occluder_height=1.0, light_height=3.0, ground_half=4.0):
    """A square occluder floating over a ground plane, lit by a square area light straight above."""
    ground = quad((0, 0, 0), ground_half)
    occluder = quad((0, 0, occluder_height), 0.5)
    positions = np.concatenate([ground, occluder])
    normals = np.zeros_like(positions)
    normals[..., 2] = 1.0
    object_id = np.array([0, 0, 1, 1], np.int32)
    albedo = np.full((4, 3), 0.8, np.float32)
    light_m = np.eye(4)
    light_m[:3, 3] = (0.0, 0.0, light_height)
    light = Light("Area", AREA, light_m, np.ones(3), 100.0, SQUARE, light_size, light_size)
    cam_world = look_at((0.0, -5.0, 6.0), (0.0, 0.0, 0.0))
    cam = Camera("Camera", np.linalg.inv(cam_world), perspective(np.radians(40), 1.0, 0.1, 100.0), size, size)
    return SceneSnapshot(positions, normals, object_id, albedo,
                         [ObjectInfo("Ground"), ObjectInfo("Occluder")], [light], cam, name="floating_plane")
