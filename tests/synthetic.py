"""Scenes built directly as SceneSnapshots (no bpy): fast GPU tests of the pipeline's geometry."""
from __future__ import annotations

import numpy as np

from penumbra.engine.snapshot import AREA, SQUARE, Camera, Light, ObjectInfo, SceneSnapshot


def quad(center, half, normal_up=True):
    """Two triangles of an axis-aligned horizontal square, counter-clockwise seen from +Z."""
    cx, cy, cz = center
    a, b = np.array([cx - half, cy - half, cz]), np.array([cx + half, cy - half, cz])
    c, d = np.array([cx + half, cy + half, cz]), np.array([cx - half, cy + half, cz])
    tris = np.array([[a, b, c], [a, c, d]], np.float32)
    return tris if normal_up else tris[:, ::-1]


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    x = np.cross(f, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(f, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(x, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, -f, eye
    return m


def perspective(fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / np.tan(fov_y / 2.0)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2], m[2, 3], m[3, 2] = -(far + near) / (far - near), -2 * far * near / (far - near), -1.0
    return m


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
