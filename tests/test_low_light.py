"""Objects standing on a floor under a light low over it (issue 10's grazing class), against Cycles.

Seen from a light a few degrees above the floor, the floor in front of an object's foot is nearer to the light
than the foot itself. A coarse micro-occluder of BACKPROJECTION holding both is tested at its nearest texel,
the floor, which lies on the receiver's own plane: before such cells were split (visibility.comp,
hides_occluders) the foot's texels in them were lost and the ground right behind a post came out half lit
(the built-in `grazing`: V 0.42 where Cycles has 0). A post and a ball under a 2 m square light 15 m away,
at two elevations and azimuths; 64², Cycles 1024 spp (cached on disk). (At 7° and 20°: REFERENCE 0.0032,
BACKPROJECTION 0.0094 before, 0.0084 after; left out to keep the test run short.)"""
import math

import pytest

ELEVATIONS = [(4.0, 0.0), (12.0, -25.0)]        # degrees above the floor, degrees about Z


def _post_and_ball(elevation: float, azimuth: float) -> dict:
    from penumbra.engine.measure import fuzz
    d, e, a = 15.0, math.radians(elevation), math.radians(azimuth)
    position = (-d * math.cos(e) * math.cos(a), -d * math.cos(e) * math.sin(a), d * math.sin(e))
    light = fuzz.hand_light("Lamp", "AREA", position, (0.0, 0.0, 0.0), 4000.0, shape="SQUARE", size=2.0, size_y=2.0)
    post = fuzz.hand_object("Post", "CUBE", (0.0, 0.0, 0.25), (0.1, 0.1, 0.25), rotation=(0.0, 0.0, 0.3))
    ball = fuzz.hand_object("Ball", "UV_SPHERE", (0.2, 0.9, 0.25), (0.25, 0.25, 0.25), smooth=True)
    camera = fuzz.hand_camera((1.2, -1.6, 3.0), (1.0, 0.4, 0.0), 35.0)
    return fuzz.hand_scene([post, ball], [light], camera, floor_half_size=8.0)


@pytest.fixture(scope="module")
def errors():
    """mae_shadow of REFERENCE and BACKPROJECTION per (elevation, azimuth), each rendered once."""
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    out = {}

    def get(key):
        if key not in out:
            scene = _post_and_ball(*key)
            out[key] = {t: fuzz.shadow_score(scene, t, (64, 64), samples=1024)[0]["mae_shadow"]
                        for t in ("REFERENCE", "BACKPROJECTION")}
            print(key, out[key])
        return out[key]
    return get


@pytest.mark.parametrize("key", ELEVATIONS, ids=[f"{e:g}deg" for e, _ in ELEVATIONS])
def test_backprojection_keeps_the_foot_of_objects_under_a_low_light(errors, key):
    """Within three times REFERENCE's error (REFERENCE at 256 samples). Before the split looked inside such
    cells: 0.033 against REFERENCE's 0.0056 at 4° (5.9×); with it 0.0118 (2.1×), 12° 0.0059 (1.8×)."""
    e = errors(key)
    assert e["BACKPROJECTION"] <= 3.0 * e["REFERENCE"]


# Strict xfails of the twice-REFERENCE target, by (elevation, azimuth). The 4° case met it with the multi-jittered
# bitmask (0.0126 against REFERENCE's 0.0056 with the jittered 16×16 pattern, 0.0110 with it) until the fuzz
# scored only the pixels both renders send light to.
TWICE_XFAIL: dict = {
    (4.0, 0.0): "0.0096 against REFERENCE's 0.0043 (2.25x) since fuzz.scored_mask: one pixel "
                "that we send no light to and Cycles a trace (its V 0, ours 1 for both techniques) had counted "
                "as an error of 1 for both, 0.0110 against 0.0057 (1.94x)",
}


@pytest.mark.parametrize("key", [pytest.param(k, marks=[pytest.mark.xfail(strict=True, reason=TWICE_XFAIL[k])]
                                              if k in TWICE_XFAIL else []) for k in ELEVATIONS],
                         ids=[f"{e:g}deg" for e, _ in ELEVATIONS])
def test_backprojection_within_twice_reference_under_a_low_light(errors, key):
    """Issue 10's target for the grazing class, twice REFERENCE's mae_shadow."""
    e = errors(key)
    assert e["BACKPROJECTION"] <= 2.0 * e["REFERENCE"]
