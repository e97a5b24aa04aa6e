"""A shadow ray whose start the terminator lift raises over the light (issue 10: grazing receivers). On a smooth
low-poly surface Cycles starts the shadow ray from the point lifted towards the smooth surface the corner normals
describe (common/gbuffer.frag terminator_lift); on a smooth-shaded cube's face that lift reaches a third of the
cube's size. A light at grazing incidence, a little above the face's plane, then lies below the plane through the
lifted start, and the receiver's depth tests took "the light is below my plane" to mean "nothing can shadow me"
(light_view.glsl receiver_depth_at). The ray in fact leaves the start downwards towards the light and meets whatever
stands between: the comparison now uses the start's own depth there, as long as the light is above the surface
itself (origin_above_own_surface).

Hand scene: a smooth-shaded cube 1.6 m tall, a 0.05 × 0.2 m area light 3 m away 0.01 rad over its top face, a wall
between them standing 0.2 m over the face (Cycles: the top face in the wall's shadow). 64², Cycles 256 spp,
mae_shadow before → after (bound): HARD 0.067 → 0.010 (0.040), PCF 0.067 → 0.008 (0.070), PCSS 0.073 → 0.020,
REFERENCE 0.041 → 0.0007 (0.032), SSM 0.091 → 0.042, BACKPROJECTION 0.067 → 0.010, SPSM 0.067 → 0.010 (0.040),
PVSM 0.067 → 0.009. Fuzz 30385 (the lifted starts of a smooth cube's top face inside a small cube hanging over
it): REFERENCE 0.467 → 0.009 against 0.138."""
import math

import pytest

TECHNIQUES = ("HARD", "PCF", "PCSS", "REFERENCE", "SSM", "BACKPROJECTION", "SPSM", "PVSM")


def _walled_cube(elevation: float) -> dict:
    from penumbra.engine.measure import fuzz
    top, distance = 1.6, 3.0
    light = fuzz.hand_light("Lamp", "AREA", (distance, 0.0, top + distance * math.tan(elevation)), (0.0, 0.0, top),
                            200.0, shape="RECTANGLE", size=0.05, size_y=0.2)
    objects = [fuzz.hand_object("Block", "CUBE", (0.0, 0.0, 0.8), (0.8, 0.8, 0.8), smooth=True),
               fuzz.hand_object("Wall", "CUBE", (1.5, 0.0, 0.9), (0.05, 1.5, 0.9))]
    return fuzz.hand_scene(objects, [light], fuzz.hand_camera((-3.0, -2.0, 4.0), (0.0, 0.0, 1.4)),
                           floor_half_size=8.0)


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_a_wall_shadows_a_smooth_face_lit_at_grazing(technique):
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, bound = fuzz.shadow_score(_walled_cube(0.01), technique, (64, 64))
    print(technique, m["mae_shadow"], bound)
    assert m["mae_shadow"] <= bound

