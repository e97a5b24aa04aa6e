"""Wide suns and the shadow-map techniques that cast one light point's hard shadow (HARD, PCF, SPSM): receivers
whose horizon hides the sun's centre but not all of its disk (issue 10, fuzz seeds 7119 and 8105's class)."""
import pytest

from penumbra.engine.measure import fuzz

pytest.importorskip("bpy")

CENTRE_HIDDEN = ("HARD", "PCF", "SPSM")


def _room_under_wide_sun():
    """The camera inside a closed ball (3 m) under a 2.75 rad sun: no light reaches the inside (Cycles: V = 0),
    and half of the inner wall faces away from the sun's centre while the rest of its disk lies above it."""
    return dict(seed=0, objects=[dict(name="Room", primitive="UV_SPHERE", transform="room", location=[0, 0, 1.2],
                                      rotation=[0, 0, 0.4], scale=[3.0, 3.0, 3.0], smooth=False)],
                floor=None,
                lights=[dict(name="Sun", type="SUN", location=[2.0, -1.0, 5.0], target=[0, 0, 0], scale=[1, 1, 1],
                             scale_kind="one", distance=5.5, angle=2.75, energy=3.0)],
                camera=dict(ortho=False, location=[0.6, -0.8, 1.0], target=[-0.5, 1.0, 2.0], lens=20.0,
                            ortho_scale=5, inside="Room"))


@pytest.mark.parametrize("technique", CENTRE_HIDDEN)
def test_wide_sun_shadows_receivers_facing_away_from_its_centre(technique):
    """The centre's map holds nothing on the rays from a receiver facing away from the sun's centre to the part
    of the disk above its horizon; such receivers were left lit (V = 1 over half the room: HARD, PCF, SPSM)."""
    m, bound = fuzz.shadow_score(_room_under_wide_sun(), technique)
    print(technique, m["mae_shadow"], bound, m["n_shadow"])
    assert m["n_shadow"] > 2000
    assert m["mae_shadow"] <= bound
