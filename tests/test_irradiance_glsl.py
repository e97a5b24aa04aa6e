"""The shader's analytic irradiance against engine/core/irradiance.py (which tests/test_irradiance_cycles.py
checks against Cycles): every light kind and shape, receivers all around, straddling the horizon."""
import numpy as np
import pytest

from penumbra.engine.core import irradiance
from penumbra.engine.gpu.context import GpuWorker
from penumbra.engine.gpu.probes import irradiance_at
from penumbra.engine.core.snapshot import AREA, DISK, ELLIPSE, POINT, RECTANGLE, SPOT, SQUARE, SUN, Light


def _matrix(rot_deg=(30.0, -20.0, 10.0), pos=(0.3, -0.2, 2.0)):
    ax, ay, az = np.radians(rot_deg)
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    m[:3, 3] = pos
    return m


COLOR = np.array([1.0, 0.6, 0.3])
LIGHTS = {
    "square": Light("L", AREA, _matrix(), COLOR, 120.0, SQUARE, 0.8, 0.8),
    "rectangle": Light("L", AREA, _matrix(), COLOR, 120.0, RECTANGLE, 1.2, 0.4),
    "disk": Light("L", AREA, _matrix(), COLOR, 120.0, DISK, 1.0, 1.0),
    "ellipse": Light("L", AREA, _matrix(), COLOR, 120.0, ELLIPSE, 1.4, 0.6),
    "point": Light("L", POINT, _matrix(), COLOR, 300.0),
    "sphere_soft": Light("L", POINT, _matrix(), COLOR, 300.0, radius=0.25),
    "sphere_hard": Light("L", POINT, _matrix(), COLOR, 300.0, radius=0.25, use_soft_falloff=False),
    "spot": Light("L", SPOT, _matrix(), COLOR, 300.0, spot_size=np.radians(70), spot_blend=0.4,
                  spot_scale=np.array([1.4, 1.0, 1.0])),
    "spot_radius": Light("L", SPOT, _matrix(), COLOR, 300.0, radius=0.15, spot_size=np.radians(70),
                         spot_blend=0.5, spot_scale=np.array([1.4, 1.0, 1.0])),
    # A radius under the small-light limit (extent / distance < 1e-2) with a cone edge as narrow as the disk:
    # Cycles tests the cone per emitter sample, so the edge is softened by the disk even there.
    "spot_small_radius": Light("L", SPOT, _matrix(), COLOR, 300.0, radius=0.008, spot_size=np.radians(70),
                               spot_blend=0.01, spot_scale=np.array([1.4, 1.0, 1.0])),
    "sun": Light("L", SUN, _matrix(), COLOR, 3.0),
    "sun_angle": Light("L", SUN, _matrix(), COLOR, 3.0, angle=np.radians(30)),
    # Issue 10 item 5: lights far smaller than their distance (the edge sum's cancellation made these 6–70×
    # too bright in float32 and 20 % off in float64) and suns up to 180° (a disk of radius tan β breaks down).
    "square_tiny": Light("L", AREA, _matrix(), COLOR, 120.0, SQUARE, 1e-4, 1e-4),
    "ellipse_tiny": Light("L", AREA, _matrix(), COLOR, 120.0, ELLIPSE, 1e-3, 6e-4),
    "sphere_tiny": Light("L", POINT, _matrix(), COLOR, 300.0, radius=1e-4),
    "sun_tiny": Light("L", SUN, _matrix(), COLOR, 3.0, angle=1e-4),
    "sun_3rad": Light("L", SUN, _matrix(), COLOR, 3.0, angle=3.0),
    "sun_180": Light("L", SUN, _matrix(), COLOR, 3.0, angle=np.pi),
}


def receivers(seed=0, n=4000):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-3, -3, -1], [3, 3, 1.5], size=(n, 3))
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pts, nrm


@pytest.mark.parametrize("name", list(LIGHTS))
def test_shader_irradiance_matches_numpy(name):
    """Also the numpy side's own small-light and wide-sun limits, which have closed forms: a tiny light is a
    point (E = L·A·cosθ·cosθ_light/d²), a 180° sun is the hemisphere around its axis (E = S·(1 + cosθ)/2)."""
    light = LIGHTS[name]
    pts, nrm = receivers()
    ours = GpuWorker.get().submit(irradiance_at, light, pts, nrm).result()
    ref = irradiance.irradiance(light, pts, nrm)
    assert np.isfinite(ours).all()
    lum_ref, lum = ref.mean(axis=1), ours.mean(axis=1)
    lit = lum_ref > 1e-3 * lum_ref.max()
    assert lit.sum() > 500
    rel = np.abs(lum[lit] - lum_ref[lit]) / lum_ref[lit]
    # float32 shader vs float64 numpy, 32-gon disks vs numpy's 64-gons, 32 vs 64 cone samples for spots
    # (both 288 where the cone's edge crosses the disk).
    assert rel.mean() < 0.005, rel.mean()
    assert np.percentile(rel, 99) < 0.05
    assert np.all(lum[~lit] <= 2e-3 * lum_ref.max())


def test_small_lights_and_wide_suns_have_their_closed_forms():
    pts, nrm = receivers(1, 2000)
    sq = LIGHTS["square_tiny"]
    to = sq.position - pts
    d2 = np.einsum("ij,ij->i", to, to)
    w = to / np.sqrt(d2)[:, None]
    front = (pts - sq.position) @ sq.matrix[:3, 2] < 0
    point = (sq.power / (np.pi * sq.area)) * sq.area * np.maximum(np.einsum("ij,ij->i", nrm, w), 0) \
        * np.abs(w @ sq.direction) / d2 * front
    assert np.allclose(irradiance.irradiance(sq, pts, nrm)[:, 0] / COLOR[0], point, rtol=1e-4, atol=0)
    sun = LIGHTS["sun_180"]
    hemisphere = sun.power * (1.0 + nrm @ sun.matrix[:3, 2]) / 2.0
    assert np.allclose(irradiance.irradiance(sun, pts, nrm)[:, 0] / COLOR[0], hemisphere, rtol=1e-9, atol=1e-12)


def _leaning(nrm, seed, max_deg=35.0):
    """Geometric normals leaning from the shading normals by up to `max_deg`, random azimuth."""
    rng = np.random.default_rng(seed)
    other = rng.normal(size=nrm.shape)
    side = np.cross(nrm, other)
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    lean = np.radians(rng.uniform(0.0, max_deg, len(nrm)))[:, None]
    return np.cos(lean) * nrm + np.sin(lean) * side


SUNS = [Light("A", SUN, _matrix(), COLOR, 3.0, angle=3.0),
        Light("B", SUN, _matrix((-40.0, 30.0, 0.0)), COLOR, 2.0, angle=1.2),
        Light("C", SUN, _matrix((10.0, 60.0, 0.0)), COLOR, 1.0)]


# (A wide spot is left out: its cone's quadratures differ by 1.1 % on average between the shader and numpy
# with or without the band, for a 1 m true sphere with a 120° cone; the band itself is the point light's code.)
WIDE_LOCAL = [Light("L", POINT, _matrix(), COLOR, 300.0, radius=1.5),
              Light("L", POINT, _matrix(), COLOR, 300.0, radius=1.5, use_soft_falloff=False),
              Light("L", AREA, _matrix(), COLOR, 300.0, RECTANGLE, 3.0, 2.0),
              Light("L", AREA, _matrix(), COLOR, 300.0, DISK, 3.0, 3.0)]


@pytest.mark.parametrize("lights", [SUNS[:1], SUNS] + [[light] for light in WIDE_LOCAL],
                         ids=["one_sun", "three_suns", "soft_disk", "true_sphere", "rectangle", "disk"])
def test_shader_weighs_the_smooth_normal_band_as_numpy(lights):
    """Wide suns over receivers whose geometric normal leans from the shading one (irradiance.band_loss and
    sun_pick): the shader against numpy, and the band's weight must matter here for the check to mean much."""
    pts, nrm = receivers(2)
    geo = _leaning(nrm, 3)
    for light in lights[:2]:
        ours = GpuWorker.get().submit(irradiance_at, light, pts, nrm, geo, lights).result().mean(axis=1)
        ref = irradiance.irradiance(light, pts, nrm, geo, lights).mean(axis=1)
        plain = irradiance.irradiance(light, pts, nrm, None, lights).mean(axis=1)
        lit = ref > 1e-3 * ref.max()
        rel = np.abs(ours[lit] - ref[lit]) / ref[lit]
        assert rel.mean() < 0.002 and np.percentile(rel, 99) < 0.02, (light.name, rel.mean())
        # Where the band is wide it matters (measured up to 35 % (A), 86 % (B), 4.5 % (soft disk), 6.2 % (true sphere))
        assert np.max(np.abs(plain[lit] - ref[lit]) / ref[lit]) > 0.02, light.name
