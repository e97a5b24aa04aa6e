"""Early skip of lit and umbra pixels (issue 14): the lit_umbra structure classifies each pixel a light reaches,
and PCSS and REFERENCE skip their gather (blocker search and filter; every sample's look-up) where it proves
the pixel fully lit or in umbra. The skip must not change a single pixel: on versus off give the same
Visibility, and no pixel classified lit (umbra) comes out below 1 (above 0) from the full gather. Built-in
scenes with grazing and tilted receivers, a sphere light in a room (cube faces, ball samples), suns, and
generated scenes (engine/measure/fuzz.py)."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402
from penumbra.engine.core.shader_constants import CLASS_GATHER, CLASS_LIT, CLASS_UMBRA  # noqa: E402
from penumbra.engine.measure import fuzz, scenes  # noqa: E402
from penumbra.engine.render import pipeline  # noqa: E402
from penumbra.engine.structures import lit_umbra  # noqa: E402

RES = (48, 48)
TECHNIQUES = ["PCSS", "REFERENCE"]


def _snapshot(scene):
    return extract(bpy.context.evaluated_depsgraph_get(), scene)


def _render(snap, technique, skip, monkeypatch=None, **changes):
    """Visibility, stats and (skip on) the class image of each light view, read back through the stats."""
    classes = []
    if monkeypatch is not None:
        counts = lit_umbra.counts
        monkeypatch.setattr(lit_umbra, "counts", lambda c: (classes.append(c.copy()), counts(c))[1])
    s = RenderSettings(technique=technique, early_skip=skip, collect_stats=True, antialiasing=False)
    # The skip must match the full gather at any sample count: REFERENCE's 64 keep the file quick
    r = pipeline.render(snap, s.with_(**{"averaged_light_samples": 64, **changes}))
    return r.passes["Visibility"][..., 0], r.stats, classes


def _check_same(snap, technique, monkeypatch, min_skipped):
    full, off_stats, _ = _render(snap, technique, False)
    skipped, stats, classes = _render(snap, technique, True, monkeypatch)
    np.testing.assert_array_equal(skipped, full)
    assert "lit_umbra" not in off_stats.get("structure_bytes", {})    # off: nothing built
    if not stats.get("views"):
        return 0.0                      # no light view: every light unshadowed, nothing to classify
    assert stats["structure_bytes"]["lit_umbra"] > 0
    share = (stats["skip_lit"] + stats["skip_umbra"]) / max(stats["skip_candidates"], 1)
    print(technique, "skipped", round(share, 3), "lit", stats["skip_lit"], "umbra", stats["skip_umbra"])
    assert share >= min_skipped
    if len(snap.lights) == 1 and len(classes) == 1:     # one view: its classes are the frame's pixels
        c = classes[0]
        assert np.all(full[c == CLASS_LIT] == 1.0), "a pixel classified lit is shadowed by the full gather"
        assert np.all(full[c == CLASS_UMBRA] == 0.0), "a pixel classified umbra is lit by the full gather"
        assert np.all(np.isin(c[c != -1], (CLASS_LIT, CLASS_UMBRA, CLASS_GATHER)))
    return share


# The share each scene skips at 48² today (PCSS, REFERENCE), less a margin: a classification that stopped
# proving anything would pass the equality alone.
BUILT_IN = {"plane": (0.25, 0.3), "tilted": (0.35, 0.4), "grazing": (0.4, 0.4), "cube": (0.4, 0.4),
            "room": (0.4, 0.4), "flattened": (0.6, 0.6), "slab": (0.6, 0.6)}


@pytest.fixture(scope="module", params=list(BUILT_IN))
def built_in(request):
    return request.param, _snapshot(scenes.build(request.param, resolution=RES))


@pytest.mark.parametrize("technique", TECHNIQUES)
def test_skip_gives_the_full_gathers_visibility_on_built_in_scenes(built_in, technique, monkeypatch):
    name, snap = built_in
    _check_same(snap, technique, monkeypatch, BUILT_IN[name][TECHNIQUES.index(technique)])


@pytest.mark.heavy
@pytest.mark.parametrize("seed", [1, 4, 7, 8])
@pytest.mark.parametrize("technique", TECHNIQUES)
def test_skip_gives_the_full_gathers_visibility_on_generated_scenes(seed, technique, monkeypatch):
    snap = _snapshot(fuzz.build(fuzz.scene_params(seed), resolution=RES))
    _check_same(snap, technique, monkeypatch, 0.0)


@pytest.mark.parametrize("changes", [{"bias": 0.0, "normal_offset": 0.0}, {"bias": 4.0, "normal_offset": 3.0},
                                     {"shadow_map_size": 256}, {"averaged_weighted": False}],
                         ids=["no_bias", "large_bias", "map_256", "unweighted"])
def test_skip_follows_the_bias_settings_and_map_size(changes, monkeypatch):
    """The classes read the same bias, normal offset and map as the gathers (tilted floor, grazing sphere)."""
    snap = _snapshot(scenes.build("tilted", resolution=RES))
    for technique in TECHNIQUES:
        full, _, _ = _render(snap, technique, False, **changes)
        skipped, stats, _ = _render(snap, technique, True, **changes)
        np.testing.assert_array_equal(skipped, full)
        assert stats["skip_lit"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["suzanne", "balls", "silhouette", "contact", "thin", "textured"])
@pytest.mark.parametrize("technique", TECHNIQUES)
def test_skip_gives_the_full_gathers_visibility_on_more_scenes(name, technique, monkeypatch):
    _check_same(_snapshot(scenes.build(name, resolution=RES)), technique, monkeypatch, 0.05)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10, 30))
def test_skip_gives_the_full_gathers_visibility_on_more_generated_scenes(seed, monkeypatch):
    snap = _snapshot(fuzz.build(fuzz.scene_params(seed), resolution=RES))
    for technique in TECHNIQUES:
        _check_same(snap, technique, monkeypatch, 0.0)
