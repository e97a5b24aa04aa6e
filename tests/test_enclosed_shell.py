"""Receivers inside a closed shell under a wide light (fuzz seeds 17014, the camera inside a 17× Suzanne under a
180° sun, and 18001, the camera inside an 11 m cone under a 0.87 rad sun). Cycles has every pixel inside in
umbra: every path from inside to the light crosses the shell. The pipeline decides that for every technique
(lightview.enclosing_shell); before, only SSM did, and from inside the dome BACKPROJECTION (0.063), PCSS (0.080)
and PVSM (0.066) let light in at 64², Cycles 256 spp. Cycles references are cached on disk."""
import numpy as np
import pytest

from penumbra.engine.measure import stress
from penumbra.engine.techniques import TECHNIQUES


def _sphere_shell(angle: float = 1.0) -> dict:
    """A 10 m UV sphere shell over a floor, a 1 m ball inside it, the camera inside, a sun of `angle` radians
    60° above the horizon."""
    sun = dict(name="Sun", type="SUN", location=[0.0, -1.5, 2.6], target=[0.0, 0.0, 0.0], scale=[1, 1, 1],
               scale_kind="one", distance=3.0, angle=angle, energy=5.0)
    return {"seed": 0,
            "objects": [dict(name="Shell", primitive="UV_SPHERE", transform="huge", location=[0.0, 0.0, 1.0],
                             rotation=[0.0, 0.0, 0.0], scale=[5.0, 5.0, 5.0], smooth=False),
                        dict(name="Ball", primitive="UV_SPHERE", transform="plain", location=[0.0, 0.0, 0.5],
                             rotation=[0.0, 0.0, 0.0], scale=[0.5, 0.5, 0.5], smooth=True)],
            "floor": dict(half_size=20.0, rotation=[0.0, 0.0, 0.0], z=0.0),
            "lights": [sun],
            "camera": dict(ortho=False, location=[0.0, -3.0, 2.0], target=[0.0, 0.0, 0.3], lens=30.0,
                           ortho_scale=2.0, inside="Shell")}


def _torus_shell() -> dict:
    """The camera inside the tube of a 6 m torus (closed, not convex) that a floor cuts, a ball on the floor
    in the tube, the 1 rad sun. Before, BACKPROJECTION 0.205, PCSS 0.155, SSM 0.227, PVSM 0.099."""
    scene = _sphere_shell()
    scene["objects"] = [dict(name="Shell", primitive="TORUS", transform="huge", location=[0.0, 0.0, 1.2],
                             rotation=[0.0, 0.0, 0.0], scale=[6.0, 6.0, 6.0], smooth=False),
                        dict(name="Ball", primitive="UV_SPHERE", transform="plain", location=[5.6, 2.2, 0.4],
                             rotation=[0.0, 0.0, 0.0], scale=[0.4, 0.4, 0.4], smooth=True)]
    scene["camera"] = dict(ortho=False, location=[6.2, -0.5, 1.6], target=[5.4, 2.5, 0.6], lens=24.0,
                           ortho_scale=2.0, inside="Shell")
    return scene


@pytest.mark.parametrize("shell", [_sphere_shell, _torus_shell])
@pytest.mark.parametrize("technique", sorted(TECHNIQUES))
def test_no_light_inside_a_closed_shell(technique, shell):
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, _ = fuzz.shadow_score(shell(), technique, (64, 64), samples=256)
    print(technique, m["mae_shadow"], m["n_shadow"])
    assert m["n_shadow"] > 3000
    assert m["mae_shadow"] <= 0.01


@pytest.mark.heavy
@pytest.mark.parametrize("technique", sorted(TECHNIQUES))
def test_a_walled_off_light_gets_no_views(technique):
    """The camera inside a closed room, a sun outside and a lamp inside: the sun is left unlit on every pixel
    without a map (no view of its own), the lamp still casts the block's shadow."""
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.core.snapshot import SUN, Light
    from penumbra.engine.render import pipeline
    parts = [("Room", stress.box((-2, -2, 0), (2, 2, 3)), True, True),
             ("Block", stress.box((-0.3, -0.3, 0.0), (0.3, 0.3, 0.8)), True, True)]
    sun = Light("Sun", SUN, stress.look_at((4.0, 2.0, 9.0), (0.0, 0.0, 0.0)), np.ones(3), 3.0, angle=0.2)
    lamp = stress.area_light((0.5, 0.0, 2.5), size=0.5)
    cam = stress.camera(eye=(1.5, -1.5, 1.8), target=(0, 0, 0.3), fov=70.0, size=48)
    settings = RenderSettings(antialiasing=False, collect_stats=True).with_(technique=technique)
    alone = pipeline.render(stress.assemble(parts, [sun], cam, "sun"), settings)
    assert alone.stats["lights_enclosed"] == 1 and alone.stats.get("views", 0) == 0
    covered = alone.passes["Unshadowed"][..., :3].sum(axis=-1) > 0
    assert covered.sum() > 500
    assert np.all(alone.passes["Visibility"][..., 0][covered] == 0.0)
    both = pipeline.render(stress.assemble(parts, [sun, lamp], cam, "both"), settings)
    assert both.stats["lights_enclosed"] == 1 and both.stats["views"] >= 1
    v = both.passes["Visibility"][..., 0]
    assert v.max() > 0.5 and v.min() < 0.2      # the lamp lights (V counts the sun's share as shadowed too)
    # A room the camera sees through (visible_camera off) walls off nothing it sees: the floor beyond it is lit
    see_through = [("Room", parts[0][1], True, False), parts[1],
                   ("Floor", stress.box((-9, -9, -0.1), (9, 9, 0.0)), True, True)]
    through = pipeline.render(stress.assemble(see_through, [sun], cam, "through"), settings)
    assert through.stats["lights_enclosed"] == 0
