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
def test_wide_sun_shadows_receivers_facing_away_from_its_centre(technique, monkeypatch):
    """The centre's map holds nothing on the rays from a receiver facing away from the sun's centre to the part
    of the disk above its horizon; such receivers were left lit (V = 1 over half the room: mae_shadow HARD 0.585,
    PCF 0.590, SPSM 0.586, PCSS 0.583 against bounds of 0.15-0.24; with rim views 0.007-0.015). The pipeline
    now leaves a sun outside a closed room around the camera unlit without any view (lightview.enclosing_shell,
    tests/test_enclosed_shell.py); that decision is turned off here, so the rim views still answer for it."""
    from penumbra.engine.core import lightview
    monkeypatch.setattr(lightview, "enclosing_shell", lambda *args, **kwargs: None)
    m, bound = fuzz.shadow_score(_room_under_wide_sun(), technique)
    print(technique, m["mae_shadow"], bound, m["n_shadow"])
    assert m["n_shadow"] > 2000
    assert m["mae_shadow"] <= bound


def _sliver_scene():
    """A floor tilted 25° under a 0.6 rad sun whose centre lies 6° below the floor's plane, so the floor sees only
    the top 11° of the disk, and a block on it that those directions cannot pass (fuzz seed 7119's class)."""
    import math
    tilt, below = 0.436, math.radians(6.0)
    normal = [0.0, -math.sin(tilt), math.cos(tilt)]
    up_slope = [0.0, math.cos(tilt), math.sin(tilt)]
    to_sun = [math.cos(below) * t - math.sin(below) * n for t, n in zip(up_slope, normal)]
    foot = [0.0, 1.0 * math.cos(tilt), 1.0 * math.sin(tilt)]       # on the floor, 1 m up the slope
    block = [f + 0.45 * n for f, n in zip(foot, normal)]
    view = [f - 1.8 * t for f, t in zip(foot, up_slope)]             # the floor down the slope from it
    return dict(seed=0, objects=[dict(name="Block", primitive="CUBE", transform="plain", location=block,
                                      rotation=[tilt, 0.0, 0.0], scale=[0.6, 0.3, 0.45], smooth=False)],
                floor=dict(half_size=8.0, rotation=[tilt, 0.0, 0.0], z=0.0),
                lights=[dict(name="Sun", type="SUN", location=[b + 4.0 * u for b, u in zip(block, to_sun)],
                             target=block, scale=[1, 1, 1], scale_kind="one", distance=4.0, angle=0.6,
                             energy=3.0)],
                camera=dict(ortho=True, location=[v + 5.0 * n for v, n in zip(view, normal)], target=view,
                            lens=40.0, ortho_scale=4.0, inside=None))


PVSM_RIM = ("PVSM 0.54 -> 0.179 against 0.165: in a rim view its kernel is the sun's whole disk centred on the "
            "rim point (its box filter has no test for the directions off the sun's disk, which PCSS's taps have), "
            "so its umbra runs too far down the slope")


@pytest.mark.parametrize("technique", ("HARD", "PCF", "SPSM", "PCSS",
                                       pytest.param("PVSM", marks=pytest.mark.xfail(strict=True, reason=PVSM_RIM))))
def test_wide_sun_below_a_tilted_floor_shadows_what_it_sees_of_the_disk(technique):
    """The floor sees only the top of the sun's disk, past a block that stops those directions: Cycles shadows
    the floor down the slope from the block; the centre's map had nothing on those rays and left the floor lit
    (mae_shadow 0.54 for every technique). From the rim view, measured: HARD 0.173, PCF 0.163, SPSM 0.173,
    PCSS 0.088, PVSM 0.179 (REFERENCE 0.030)."""
    m, bound = fuzz.shadow_score(_sliver_scene(), technique)
    print(technique, m["mae_shadow"], bound, m["n_shadow"])
    assert m["n_shadow"] > 1500
    assert m["mae_shadow"] <= bound


def _plate_under_very_wide_sun():
    """A 3 m plate 1.5 m above a floor under a 3.0 rad sun overhead: the plate hides a fraction of the sun's disk
    everywhere under it (no umbra: Cycles' darkest V ≈ 0.5) and the penumbra (tan 1.5 × 1.5 m ≈ 21 m) is wider
    than the whole view (4 m), so PCSS's search and filter radii both hit pcss_max_radius."""
    return dict(seed=0, objects=[dict(name="Plate", primitive="CUBE", transform="plain", location=[0.0, 0.0, 1.5],
                                      rotation=[0.0, 0.0, 0.3], scale=[1.5, 1.5, 0.05], smooth=False)],
                floor=dict(half_size=8.0, rotation=[0.0, 0.0, 0.0], z=0.0),
                lights=[dict(name="Sun", type="SUN", location=[0.0, 0.0, 5.0], target=[0, 0, 0], scale=[1, 1, 1],
                             scale_kind="one", distance=5.0, angle=3.0, energy=3.0)],
                camera=dict(ortho=True, location=[0.0, -0.01, 6.0], target=[0, 0, 0], lens=40.0, ortho_scale=4.0,
                            inside=None))


def test_pcss_radius_cap_darkens_a_very_wide_suns_penumbra():
    """The cap (0.1 of the map) turns the kernels into those of a smaller light whenever the penumbra is wider
    than it: here every tap lands on the plate and the floor under it comes out too dark. A cap of 0.5 reaches
    the penumbra the sun really casts (measured mae_shadow 0.137 at the default, 0.060 at 0.5, 0.059 at 1.0).
    The default stays 0.1: on stacked casters (fuzz 8369, a 1.6 rad sun) the wider filter reads lit texels on
    rays that a caster at another depth blocks, 0.057 -> 0.369 (see Pcss's options)."""
    capped, bound = fuzz.shadow_score(_plate_under_very_wide_sun(), "PCSS")
    wide, _ = fuzz.shadow_score(_plate_under_very_wide_sun(), "PCSS", overrides={"pcss_max_radius": 0.5})
    print(capped["mae_shadow"], wide["mae_shadow"], bound, wide["n_shadow"])
    assert wide["n_shadow"] > 1000
    assert wide["mae_shadow"] <= bound
    assert wide["mae_shadow"] <= 0.6 * capped["mae_shadow"]


def _ball_over_sun_hiding_floor():
    """A ball 0.5 m over a floor lit by a 1.1 rad sun from below it: the floor hides the whole sun from every
    point of the ball (Cycles: V = 0 wherever the ball sees the sun's disk above its horizon). The floor is the
    caster and spans far more than the ball, so each receiver sees the sun through the floor up to
    tan(0.55) × its 0.5-2.5 m depth gap away (fuzz seed 12023's class: a mirrored sun shining up under a floor)."""
    return dict(seed=0, objects=[dict(name="Ball", primitive="UV_SPHERE", transform="plain", location=[0, 0, 1.5],
                                      rotation=[0.3, 0.2, 0], scale=[1.0, 1.0, 1.0], smooth=True)],
                floor=dict(half_size=10.0, rotation=[0, 0, 0], z=0.0),
                lights=[dict(name="Sun", type="SUN", location=[0.5, 1.0, -3.0], target=[0, 0, 0], scale=[1, 1, 1],
                             scale_kind="one", angle=1.1, energy=5.0)],
                camera=dict(ortho=False, location=[4.0, -4.0, 3.5], target=[0, 0, 0.5], lens=35.0, ortho_scale=5,
                            inside=None))


SUN_WINDOW = ("a sun's view is fitted with no room for its disk of directions (lightview.fit: its extent counts as "
              "0), so the map holds only the ball's own patch of the floor and not the floor it sees the sun "
              "through. Widening the window by tan(half angle) x the depth gap gave SSM 0.045, BACKPROJECTION "
              "0.054, but a ball on the floor under a 2.5 rad sun went 0.049 -> 0.127 for BACKPROJECTION "
              "(tests/test_backprojection.py), so it did not land")


@pytest.mark.heavy
@pytest.mark.parametrize("technique", ["PCSS", "PVSM", "REFERENCE",
                                       pytest.param("SSM", marks=pytest.mark.xfail(strict=True, reason=SUN_WINDOW)),
                                       pytest.param("BACKPROJECTION",
                                                    marks=pytest.mark.xfail(strict=True, reason=SUN_WINDOW))])
def test_sun_hidden_by_a_caster_wider_than_the_receiver(technique):
    """Measured at 64², 256 spp: PCSS 0.048, PVSM 0.011, REFERENCE 0.0047 (bounds 0.159, 0.159, 0.039); SSM
    0.69 (0.71 before its shares were clipped to the receiver's horizon), BACKPROJECTION 0.28 (bounds 0.149,
    0.219)."""
    m, bound = fuzz.shadow_score(_ball_over_sun_hiding_floor(), technique)
    print(technique, m["mae_shadow"], bound, m["n_shadow"])
    assert m["n_shadow"] > 150
    assert m["mae_shadow"] <= bound
