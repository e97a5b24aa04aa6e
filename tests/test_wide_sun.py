"""Wide suns and the shadow-map techniques that work from the map of the sun's centre (HARD, PCF, SPSM, PCSS,
PVSM): receivers whose horizon hides the centre but not all of the disk (issue 10, fuzz seeds 7119 and 8105's
class) take a view from the rim of the disk (core.lightview.sun_rim_faces)."""
import pytest

from penumbra.engine.measure import fuzz

pytest.importorskip("bpy")

PVSM_ROOM = ("PVSM 0.59 -> 0.163 against 0.150: the rest is grey over the whole room, the receivers of the "
             "centre's view as much as the rim views': a 2.75 rad sun's kernel (tan 4 × the room's 6 m) reaches past "
             "the room's silhouette in the map, where the averaged blocker plane finds the light")
CENTRE_HIDDEN = ("HARD", "PCF", "SPSM", "PCSS",
                 pytest.param("PVSM", marks=pytest.mark.xfail(strict=True, reason=PVSM_ROOM)))


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
    of the disk above its horizon; such receivers were left lit (V = 1 over half the room: mae_shadow HARD 0.585,
    PCF 0.590, SPSM 0.586, PCSS 0.583 against bounds of 0.15-0.24; with rim views 0.007-0.037)."""
    m, bound = fuzz.shadow_score(_room_under_wide_sun(), technique)
    print(technique, m["mae_shadow"], bound, m["n_shadow"])
    assert m["n_shadow"] > 2000
    assert m["mae_shadow"] <= bound
