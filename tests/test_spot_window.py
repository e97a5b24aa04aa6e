"""A spot's light view follows its cone: a spot lights nothing past its cone (Cycles applies the cone to each
ray as it leaves the emitter), so the receivers' window is bounded by the cone however far the corners of
their box reach. Before, a wide spot (147°) over a big floor with a huge caster (fuzz seed 8113) had its view
clamped to ±80°, whose texels were coarser than the camera's pixels there: the small casters' shadow edges
came out up to half a texel short. A Cycles reference is cached."""
import numpy as np
import pytest

from penumbra.engine.core import lightview
from penumbra.engine.core.light_shape import spot_cone_tans
from penumbra.engine.core.snapshot import POINT, SPOT, Light
from penumbra.engine.measure import stress


def _spot(size_deg=120.0, radius=0.0, kind=SPOT):
    """A spot 3 m above the origin looking down."""
    return Light("Spot", kind, stress.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0)), np.ones(3), 100.0,
                 radius=radius, spot_size=float(np.radians(size_deg)))


def test_a_spot_view_is_bounded_by_its_cone_not_its_receivers_box():
    light = _spot(120.0)
    receivers = (np.array([-40.0, -40.0, 0.0]), np.array([40.0, 40.0, 0.5]))    # far past ±80° from the light
    view = lightview.fit(light, receivers, receivers, 1024)
    tx, ty = spot_cone_tans(light)
    assert not view.clamped
    assert max(abs(v) for v in view.window) <= tx * 1.05
    point = _spot(120.0, kind=POINT)                                              # the same without a cone
    assert lightview.fit(point, receivers, receivers, 1024, frame=lightview.light_frame(light)).clamped


@pytest.mark.parametrize("seed", range(4))
def test_a_skewed_spots_cone_stays_inside_its_bounds(seed):
    """A spot with skewed axes (Light.spot_linear): every direction its cone lets light through has tangents
    within spot_cone_tans along the frame's X and Y and within spot_tan_wide off -Z, which the view window,
    the cone region and the irradiance footprint rely on; and the bounds are tight (the cone reaches 99 % of
    them)."""
    from penumbra.engine.core.irradiance import spot_attenuation, spot_tan_wide
    rng = np.random.default_rng(seed)
    linear = np.triu(rng.uniform(-0.8, 0.8, (3, 3)), 1).T + np.diag(rng.uniform(0.4, 2.0, 3))
    linear[:, 2] = [0.0, 0.0, rng.uniform(0.4, 2.0)]        # the frame's Z is the object's Z axis
    light = _spot(float(rng.uniform(20.0, 110.0)))
    light.spot_blend = 0.3
    light.spot_linear = linear
    turn = light.matrix[:3, :3]
    local = rng.normal(size=(200000, 3))
    local[:, 2] = -np.abs(local[:, 2]) * rng.uniform(0.05, 3.0, len(local))
    local /= np.linalg.norm(local, axis=1, keepdims=True)
    lit = spot_attenuation(light, local @ turn.T) > 0.0
    assert lit.sum() > 1000
    t = local[lit, :2] / -local[lit, 2:3]
    tx, ty = spot_cone_tans(light)
    wide = spot_tan_wide(light)
    assert np.abs(t[:, 0]).max() <= tx and np.abs(t[:, 1]).max() <= ty and np.hypot(*t.T).max() <= wide
    assert np.abs(t[:, 0]).max() > 0.97 * tx and np.hypot(*t.T).max() > 0.97 * wide


def test_a_spot_with_a_radius_keeps_what_its_emitter_reaches_past_the_cone():
    """From the light's centre, a receiver lit through the edge of a spot's disk lies up to radius/depth past
    the cone; inside the sphere there is no cone at all."""
    receivers = (np.array([-40.0, -40.0, 0.0]), np.array([40.0, 40.0, 0.5]))
    thin, wide = (lightview.fit(_spot(60.0, r), receivers, receivers, 1024) for r in (0.0, 0.5))
    tx, _ = spot_cone_tans(_spot(60.0))
    assert thin.window[1] <= tx * 1.05 < wide.window[1]
    enclosing = lightview.fit(_spot(60.0, 5.0), receivers, receivers, 1024)
    assert enclosing.window[1] > 2.0 * tx


WIDE_SPOT = {
    "seed": 0,
    "objects": [
        dict(name="Torus", primitive="TORUS", transform="huge", location=[-1.1426, 0.1589, 0.2541],
             rotation=[1.3787, 0.6169, 2.9204], scale=[10.2635, 10.2635, 10.2635], smooth=False),
        dict(name="Ico", primitive="ICO_SPHERE", transform="plain", location=[-1.2862, 0.0659, 0.2645],
             rotation=[-2.4894, -1.9946, 0.7665], scale=[0.3788, 0.3788, 0.3788], smooth=False),
        dict(name="Cone", primitive="CONE", transform="mirrored", location=[-1.3796, 0.0011, 0.2458],
             rotation=[-0.9618, -1.1938, -1.6313], scale=[0.5596, 0.3809, -0.5255], smooth=True)],
    "floor": dict(half_size=19.0, rotation=[0.0, 0.0, 0.0], z=-0.2862),
    "lights": [dict(name="Spot", type="SPOT", location=[-4.9574, -1.3638, 3.6611], target=[-0.2783, -0.9346, 0.5369],
                    scale=[1, 1, 1], scale_kind="one", radius=0.00745, soft_falloff=True, energy=13640.0,
                    spot_size=2.5723, spot_blend=0.0)],
    "camera": dict(ortho=False, location=[2.4579, -3.0912, 5.9955], target=[-0.253, -0.2874, 0.6299], lens=40.18,
                   ortho_scale=6.44, inside=None),
}


def test_reference_shadow_edges_under_a_wide_spot_over_a_huge_caster():
    """Measured at 64², 256 spp: 0.099 before (bound 0.049), 0.027 after."""
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, bound = fuzz.shadow_score(WIDE_SPOT, "REFERENCE", (64, 64))
    print(f"mae_shadow {m['mae_shadow']:.4f} over {m['n_shadow']} px, bound {bound:.4f}")
    assert m["n_shadow"] > 50
    assert m["mae_shadow"] <= bound
