"""Penumbra's baselines against Cycles on the built-in scenes (Cycles references are cached on disk)."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import metrics, reference, scenes  # noqa: E402
from penumbra.engine.render import pipeline
from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402


def _scene(name, resolution, light_size=None):
    sc = scenes.build(name, resolution=resolution)
    if light_size is not None:
        for obj in sc.objects:
            if obj.type == "LIGHT":
                obj.data.size = light_size
    return sc, extract(bpy.context.evaluated_depsgraph_get(), sc)


@pytest.mark.parametrize("name", ["suzanne", "contact"])
def test_hard_with_a_tiny_light_matches_cycles(name):
    """A 1 cm light casts a hard shadow: a 1024² map on a 256² image puts ≥ 97 % of pixels on the same
    side of 0.5 as Cycles (the SPSM paper reports ≈ 97.9 % for a standard shadow map)."""
    sc, snap = _scene(name, (256, 256), light_size=0.01)
    ref = reference.cycles_visibility(sc, samples=64)
    r = pipeline.render(snap, RenderSettings(technique="HARD", shadow_map_size=1024))
    m = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
    print(name, m)
    assert m["n_shadow"] > 1000
    assert m["pixel_match"] >= 0.97


@pytest.mark.parametrize("name", ["plane", "suzanne"])
def test_reference_technique_matches_cycles_within_its_noise(name):
    """REFERENCE (256 light samples) against Cycles at 256 spp. Cycles' own noise floor (two seeds) is
    measured on the same pixels; we allow that floor plus 0.005 — the averaged maps' own discretisation
    (a one-texel edge shift over a 128² image, ≈ 0.003 mae_shadow on the closed-form parallel-planes
    test in test_pipeline.py)."""
    sc, snap = _scene(name, (128, 128))
    floor = reference.noise_floor(sc, 256)
    ref = reference.cycles_visibility(sc, samples=256)
    r = pipeline.render(snap, RenderSettings(technique="REFERENCE", shadow_map_size=1024)
                              .with_(averaged_light_samples=256))
    m = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
    print(name, "ours", m, "cycles floor", floor)
    assert m["n_shadow"] > 1000
    assert m["mae_shadow"] <= floor["mae_shadow"] + 0.005


@pytest.mark.parametrize("antialiasing", [False, True])
def test_unshadowed_light_matches_cycles_on_a_builtin_scene(antialiasing):
    """Our unoccluded light (Irradiance/π) against Cycles' unshadowed render with a white Lambertian
    override: within 2 % mean relative error over lit pixels. Without anti-aliasing each pixel is its
    centre, as Cycles' point-like filter; with it, the mean over the pixel's samples, as Cycles' box filter."""
    from penumbra.engine.measure.compare import unshadowed_error
    sc, snap = _scene("suzanne", (128, 128))
    ref = reference.cycles_visibility(sc, samples=256, filter_type="BOX" if antialiasing else "GAUSSIAN")
    r = pipeline.render(snap, RenderSettings(technique="HARD", debug_passes=True, antialiasing=antialiasing))
    err = unshadowed_error(r.passes["Irradiance"] / np.pi, ref.unshadowed, ref.mask)
    print("unshadowed relative error", err)
    assert err < 0.02
