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
    "sun": Light("L", SUN, _matrix(), COLOR, 3.0),
    "sun_angle": Light("L", SUN, _matrix(), COLOR, 3.0, angle=np.radians(30)),
}


def receivers(seed=0, n=4000):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-3, -3, -1], [3, 3, 1.5], size=(n, 3))
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pts, nrm


@pytest.mark.parametrize("name", list(LIGHTS))
def test_shader_irradiance_matches_numpy(name):
    light = LIGHTS[name]
    pts, nrm = receivers()
    ours = GpuWorker.get().submit(irradiance_at, light, pts, nrm).result()
    ref = irradiance.irradiance(light, pts, nrm)
    assert np.isfinite(ours).all()
    lum_ref, lum = ref.mean(axis=1), ours.mean(axis=1)
    lit = lum_ref > 1e-3 * lum_ref.max()
    assert lit.sum() > 500
    rel = np.abs(lum[lit] - lum_ref[lit]) / lum_ref[lit]
    # float32 shader vs float64 numpy, 32-gon disks vs numpy's 64-gons, 32 vs 64 cone samples for spots.
    assert rel.mean() < 0.005, rel.mean()
    assert np.percentile(rel, 99) < 0.05
    assert np.all(lum[~lit] <= 2e-3 * lum_ref.max())
