"""PCSS's blocker depth on rounded casters (issue 10's tilted class, without the tilt).

A ball resting on a floor: the light centre's depth map holds the ball's top, while the outline that sizes the
penumbra is its equator. With the top as the blocker depth the penumbra comes out about twice too wide and its
core too light. With `pcss_midpoint` (the default) each blocker texel counts halfway between the near side and
the back faces behind it, which for a ball is its equator. Cycles references are cached on disk."""
import pytest

from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.structures.depth_map import BACK_DEPTH_MAP, DEPTH_MAP
from penumbra.engine.techniques.pcss import Pcss


def _ball_on_floor(light_x: float) -> dict:
    """A 0.5 m ball on the floor under a 1.5 m × 0.75 m rectangle light 3 m up, `light_x` metres to the side."""
    from penumbra.engine.measure import fuzz
    light = fuzz.hand_light("Lamp", "AREA", (light_x, 0.0, 3.0), (0.0, 0.0, 0.0), 400.0, shape="RECTANGLE", size=1.5,
                            size_y=0.75)
    ball = fuzz.hand_object("Ball", "UV_SPHERE", (0.0, 0.0, 0.5), (0.5, 0.5, 0.5), smooth=True)
    return fuzz.hand_scene([ball], [light], fuzz.hand_camera((0.0, -3.0, 2.5), (0.0, 0.3, 0.0)), floor_half_size=6.0)


@pytest.mark.parametrize("light_x", [0.0, 1.0], ids=["overhead", "to_the_side"])
def test_ball_on_a_floor_within_twice_reference(light_x):
    """Issue 10's target for the soft techniques, twice REFERENCE's mae_shadow, with REFERENCE at the 64 samples
    it was measured with (at its default 256 REFERENCE's error is lower and PCSS misses twice it: the
    xfails of tests/test_grazing.py's TWICE_REFERENCE_XFAIL). Measured at 64², Cycles 1024 spp:
    overhead REFERENCE 0.0196, PCSS 0.055 with the near side, 0.027 with the midpoint; light 1 m to the side
    REFERENCE 0.0178, PCSS 0.064 and 0.026. (A box's outline from above is its top, which the midpoint moves
    down: the same scene with a cube, 0.055 → 0.060 against REFERENCE's 0.012, PCSS's known limit there.)"""
    pytest.importorskip("bpy")
    scene = _ball_on_floor(light_x)
    from penumbra.engine.measure import fuzz
    err = {t: fuzz.shadow_score(scene, t, (64, 64), samples=1024, overrides={"averaged_light_samples": 64})[0]
           ["mae_shadow"] for t in ("REFERENCE", "PCSS")}
    print(err)
    assert err["PCSS"] <= 2.0 * err["REFERENCE"]


def test_back_face_map_only_where_the_midpoint_is_on():
    """The back-face pass costs a second raster of the casters per view: built only for the midpoint."""
    on = Pcss().needs_for(RenderSettings(technique="PCSS"))
    off = Pcss().needs_for(RenderSettings(technique="PCSS").with_(pcss_midpoint=False))
    assert BACK_DEPTH_MAP in on and DEPTH_MAP in on
    assert BACK_DEPTH_MAP not in off and DEPTH_MAP in off
