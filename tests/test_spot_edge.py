"""A spot with a radius whose hard cone edge (no blend) sweeps its disk across the receivers (fuzz seeds 18021
and 17001: every technique over the Unshadowed bound). Cycles applies the cone per emitter sample, so across
the band the edge crosses, the lit share of the disk falls smoothly from 1 to 0; a mean over a few disk cells
falls in steps of one cell's share, bands that near the outer rim are tens of per cent of the light. Cycles
references are cached on disk."""
import pytest


def _spot_over_floor(scale, radius) -> dict:
    """A soft-falloff spot of `radius` 7 m from a ball on a floor, a 35° cone with no blend, `scale` on its object
    (a non-uniform one makes the cone elliptical); the camera above sees the cone's edge on the floor."""
    from penumbra.engine.measure import fuzz
    spot = fuzz.hand_light("Spot", "SPOT", (-1.2, -6.0, 4.0), (0.0, 0.5, 0.3), 30000.0, scale=scale, radius=radius,
                           soft_falloff=True, spot_size=0.62, spot_blend=0.0)
    ball = fuzz.hand_object("Ball", "UV_SPHERE", (0.0, 0.5, 0.75), (0.75, 0.75, 0.75), smooth=True)
    return fuzz.hand_scene([ball], [spot], fuzz.hand_camera((0.5, -1.5, 7.0), (0.0, 0.8, 0.0), 30.0),
                           floor_half_size=12.0)


@pytest.mark.parametrize("scale, radius", [((1.0, 1.0, 1.0), 1.0), ((2.3, 0.66, 1.9), 0.6)])
def test_unshadowed_light_across_a_hard_cone_edge(scale, radius):
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    err, bound = fuzz.unshadowed_score(_spot_over_floor(scale, radius), (64, 64), samples=256)
    print(scale, err, bound)
    assert err <= bound
