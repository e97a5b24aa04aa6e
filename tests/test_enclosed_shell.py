"""Receivers inside a closed shell under a wide light (fuzz seed 17014: the camera inside a 17× Suzanne under a
180° sun). Cycles has every pixel inside in umbra. The strict xfails are the techniques that let light in,
with the measured figures (64², Cycles 256 spp, mae_shadow, which is here the mean visibility). A fix flips them.
Cycles references are cached on disk."""
import pytest


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


def _leak(reason: str):
    return pytest.mark.xfail(strict=True, reason=reason)


@pytest.mark.parametrize("technique", [
    "REFERENCE", "HARD", "PCF", "SPSM", "SSM",
    pytest.param("BACKPROJECTION", marks=_leak(
        "0.063: parts of the light that no micro-occluder's rectangle covers, seen from inside the dome (0.033 "
        "at level 0 everywhere, 0.108 there without gap filling, 0.0001 with area accumulation)")),
    pytest.param("PCSS", marks=_leak("0.080")),
    pytest.param("PVSM", marks=_leak("0.066")),
])
def test_no_light_inside_a_closed_shell(technique):
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, _ = fuzz.shadow_score(_sphere_shell(), technique, (64, 64), samples=256)
    print(technique, m["mae_shadow"], m["n_shadow"])
    assert m["n_shadow"] > 3000
    assert m["mae_shadow"] <= 0.01
