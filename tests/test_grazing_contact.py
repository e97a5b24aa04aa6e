"""A caster next to a receiver lit at grazing light (issue 10, fuzz seed 8207: a cylinder through a flat-shaded
ball, the receiver 1.3 cm from the cylinder along its ray to the light, n·l 0.03). make_receiver's bias grows
with the receiver's slope up to 10.5 texels, which at grazing light hid any caster nearer the receiver than
that along the ray: REFERENCE lit what Cycles shadows. REFERENCE compares each texel with the receiver's plane
at that texel's centre (receiver_depth_at), exact for the receiver's own triangle, so it keeps only the
bias's constant part (glsl/averaged/accumulate.comp). The scene is built here, and what is shadowed is known
without a reference: a 1 m wall standing on a floor, lit by a 0.1 mm light 3° above the floor, shadows the
floor behind it for 19 m."""
import numpy as np

from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.core.snapshot import AREA, SQUARE, Camera, Light, ObjectInfo, SceneSnapshot
from penumbra.engine.measure.stress import look_at, perspective
from penumbra.engine.render import pipeline
from penumbra.tests.synthetic import quad

SIZE = 64


def _wall_on_floor(elevation_deg: float) -> SceneSnapshot:
    ground = quad((1.0, 0.0, 0.0), 3.0)
    a, b, c, d = (np.array(v, float) for v in ([0, -1, 0], [0, 1, 0], [0, 1, 1], [0, -1, 1]))
    wall = np.array([[a, c, b], [a, d, c]], np.float32)             # the plane x = 0, both faces
    positions = np.concatenate([ground, wall, wall[:, ::-1]])
    normals = np.zeros_like(positions)
    normals[:2, :, 2], normals[2:4, :, 0], normals[4:, :, 0] = 1.0, -1.0, 1.0
    el = np.radians(elevation_deg)
    m = np.eye(4)
    z = np.array([-np.cos(el), 0.0, np.sin(el)])                  # the light's +Z: away from the scene
    x = np.cross([0.0, 1.0, 0.0], z)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, 6.0 * z
    light = Light("L", AREA, m, np.ones(3), 100.0, SQUARE, 1e-4, 1e-4)
    cam = Camera("C", np.linalg.inv(look_at((1.2, -1.5, 1.2), (0.5, 0.0, 0.0))),
                 perspective(np.radians(50), 1.0, 0.1, 100.0), SIZE, SIZE)
    return SceneSnapshot(positions, normals, np.array([0, 0, 1, 1, 1, 1], np.int32),
                         np.full((6, 3), 0.8, np.float32), [ObjectInfo("Ground"), ObjectInfo("Wall")], [light], cam,
                         name="wall_on_floor")


def _floor_points(cam: Camera) -> np.ndarray:
    """Where each pixel's centre ray meets the floor z = 0 (NaN where it does not, in front of the camera)."""
    inv = np.linalg.inv(cam.projection @ cam.view)
    ys, xs = np.mgrid[0:cam.height, 0:cam.width]
    ndc = np.stack([(xs + 0.5) / cam.width * 2 - 1, (ys + 0.5) / cam.height * 2 - 1], -1).reshape(-1, 2)
    ends = [np.c_[ndc, np.full(len(ndc), z), np.ones(len(ndc))] @ inv.T for z in (-1.0, 1.0)]
    a, b = (e[:, :3] / e[:, 3:] for e in ends)
    t = -a[:, 2] / (b[:, 2] - a[:, 2])
    hit = a + t[:, None] * (b - a)
    hit[t <= 0] = np.nan
    return hit.reshape(cam.height, cam.width, 3)


def test_reference_shadows_the_floor_right_behind_a_wall_at_grazing_light():
    """Every pixel on the floor 1 cm to 3.5 m behind the wall (and within its width) is in its shadow. Before:
    20 of them lit at the default 1024² map, up to 3.1 cm from the wall (98, up to 10 cm, at 256²); HARD,
    with the slope-scaled bias, still does."""
    snap = _wall_on_floor(3.0)
    p = _floor_points(snap.camera)
    with np.errstate(invalid="ignore"):
        behind = (p[..., 0] > 0.01) & (p[..., 0] < 3.5) & (np.abs(p[..., 1]) < 0.9)
    assert behind.sum() > 1500
    for size in (1024, 256):
        r = pipeline.render(snap, RenderSettings(antialiasing=False, shadow_map_size=size).with_(
            technique="REFERENCE"))
        v = r.passes["Visibility"][..., 0]
        lit = behind & (v > 0.5)
        assert not lit.any(), (size, int(lit.sum()), float(np.nanmax(np.where(lit, p[..., 0], np.nan))))
