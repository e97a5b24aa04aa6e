"""A spot with a radius whose hard cone edge (no blend) sweeps its disk across the receivers (fuzz seeds 18021
and 17001: every technique over the Unshadowed bound). Cycles applies the cone per emitter sample, so across
the band the edge crosses, the lit share of the disk falls smoothly from 1 to 0; a mean over a few disk cells
falls in steps of one cell's share, bands that near the outer rim are tens of per cent of the light. Cycles
references are cached on disk."""
import pytest


def _spot_over_floor(scale, radius) -> dict:
    """A soft-falloff spot of `radius` 7 m from a ball on a floor, a 35° cone with no blend, `scale` on its object
    (a non-uniform one makes the cone elliptical); the camera above sees the cone's edge on the floor."""
    spot = dict(name="Spot", type="SPOT", location=[-1.2, -6.0, 4.0], target=[0.0, 0.5, 0.3], scale=list(scale),
                scale_kind="one" if len(set(scale)) == 1 else "nonuniform", distance=7.8, radius=radius,
                soft_falloff=True, energy=30000.0, spot_size=0.62, spot_blend=0.0)
    return {"seed": 0,
            "objects": [dict(name="Ball", primitive="UV_SPHERE", transform="plain", location=[0.0, 0.5, 0.75],
                             rotation=[0.0, 0.0, 0.0], scale=[0.75, 0.75, 0.75], smooth=True)],
            "floor": dict(half_size=12.0, rotation=[0.0, 0.0, 0.0], z=0.0),
            "lights": [spot],
            "camera": dict(ortho=False, location=[0.5, -1.5, 7.0], target=[0.0, 0.8, 0.0], lens=30.0,
                           ortho_scale=2.0, inside=None)}


@pytest.mark.parametrize("scale, radius", [((1.0, 1.0, 1.0), 1.0), ((2.3, 0.66, 1.9), 0.6)])
def test_unshadowed_light_across_a_hard_cone_edge(scale, radius):
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    err, bound = fuzz.unshadowed_score(_spot_over_floor(scale, radius), (64, 64), samples=256)
    print(scale, err, bound)
    assert err <= bound
