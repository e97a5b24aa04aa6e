"""Per-light structures (engine/structures/): declared by the techniques, built by the pipeline once per light
view in dependency order, each reporting its memory; techniques themselves hold no raw GL state."""
import re
from pathlib import Path

import numpy as np
import pytest

from penumbra.engine import structures
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.render import pipeline
from penumbra.engine.structures import need
from penumbra.engine.techniques import TECHNIQUES
from penumbra.tests.synthetic import floating_plane

ROOT = Path(__file__).resolve().parent.parent


def _solids_over_ground(parts, closed=True):
    """floating_plane's ground, light and camera with `parts` (triangle arrays) as objects of their own, all
    marked watertight or not."""
    from penumbra.engine.core.snapshot import ObjectInfo, SceneSnapshot
    base = floating_plane(32)
    ground = base.positions[base.object_id == 0]
    tris = [ground] + [np.asarray(p, np.float32) for p in parts]
    positions = np.concatenate(tris)
    n = np.cross(positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0])
    normals = np.repeat((n / np.linalg.norm(n, axis=1, keepdims=True))[:, None], 3, axis=1).astype(np.float32)
    object_id = np.concatenate([np.full(len(t), i, np.int32) for i, t in enumerate(tris)])
    objects = [ObjectInfo("Ground")] + [ObjectInfo(f"Part{i}", closed=closed) for i in range(len(parts))]
    return SceneSnapshot(positions, normals, object_id, np.full((len(positions), 3), 0.8, np.float32),
                         objects, base.lights, base.camera, name="solids_over_ground")



def _stacked_boxes(closed=True):
    """Three closed boxes over the ground, each hidden from the light's centre by the wider one above it: the
    depth map and two peeled layers all hold occluders. All wider than the light, so that no side face is lit
    (one light view). `closed`: whether they are marked watertight."""
    from penumbra.engine.measure.stress import box
    return _solids_over_ground([box((-0.8, -0.8, 1.4), (0.8, 0.8, 1.5)), box((-0.7, -0.7, 1.0), (0.7, 0.7, 1.1)),
                                box((-0.6, -0.6, 0.5), (0.6, 0.6, 0.6))], closed=closed)

def test_plan_puts_requirements_first_once_and_keeps_asked_parameters():
    order = structures.plan([need("hsm", mssm_first=True), need("peeled_layers", layers=3), "mssm"])
    names = [n.name for n in order]
    assert names.index("depth_map") < names.index("peeled_layers") < names.index("hsm")
    assert names.index("depth_map") < names.index("mssm")
    assert sorted(names) == sorted(set(names))
    assert {n.name: n.kwargs for n in order}["peeled_layers"] == {"layers": 3}


def test_plan_rejects_unknown_names_and_conflicting_parameters():
    with pytest.raises(KeyError, match="no_such_structure"):
        structures.plan(["no_such_structure"])
    with pytest.raises(ValueError, match="peeled_layers"):
        structures.plan([need("peeled_layers", layers=2), need("peeled_layers", layers=3)])


@pytest.mark.parametrize("identifier", sorted(TECHNIQUES))
def test_every_declared_need_has_a_builder(identifier):
    technique = TECHNIQUES[identifier]
    for n in structures.plan(technique.needs_for(RenderSettings(technique=identifier))):
        assert n.name in structures.BUILDERS


def _counting(monkeypatch):
    calls: dict = {}
    for name, builder in list(structures.BUILDERS.items()):
        def build(frame, lc, _inner=builder.build, _name=name, **params):
            calls[_name] = calls.get(_name, 0) + 1
            return _inner(frame, lc, **params)
        monkeypatch.setitem(structures.BUILDERS, name, structures.Builder(build, builder.requires))
    return calls


def test_options_decide_the_structures_and_each_is_built_once_per_light_view(monkeypatch):
    calls = _counting(monkeypatch)
    snap = _stacked_boxes()
    # Micropatches read the hierarchy itself (the default microrects add their own structure, checked below).
    base = RenderSettings(technique="BACKPROJECTION", shadow_map_size=64).with_(bp_primitive="MICROPATCH")
    r = pipeline.render(snap, base.with_(bp_refinement="HSM", bp_layers=3, bp_coverage=False))
    assert calls == {"depth_map": 1, "peeled_layers": 1, "hsm": 1, "solid_exits": 1}
    memory = r.stats["structure_bytes"]
    depth = memory["depth_map"]
    assert depth > 0
    assert memory["peeled_layers"] == 2 * depth       # two layers behind the depth map, same texel format
    assert memory["hsm"] > 3 * 2 * depth               # an RG32F pyramid (≥ 4/3 of a level) per layer
    calls.clear()
    r = pipeline.render(snap, base.with_(bp_refinement="MSSM", bp_coverage=False, bp_layers=1))
    assert calls == {"depth_map": 1, "peeled_layers": 1, "hsm": 1, "mssm": 1, "solid_exits": 1}
    memory = r.stats["structure_bytes"]
    assert memory["hsm"] == 0                          # layer 0 reads the MSSM, which holds every level
    assert memory["mssm"] >= 2 * memory["depth_map"] * 6    # RG32F, one full-resolution layer per level
    calls.clear()
    r = pipeline.render(snap, base.with_(bp_refinement="YSM", bp_primitive="MICRORECT", bp_layers=2))
    assert calls == {"depth_map": 1, "peeled_layers": 1, "hsm": 1, "ysm": 1, "microrects": 1, "solid_exits": 1}
    memory = r.stats["structure_bytes"]
    assert memory["hsm"] == 8 * (64 * 64 * 4 - 1) // 3     # layer 1's pyramid only: the YSM holds layer 0's
    assert memory["microrects"] == 2 * (4 + 16 + 16) * (64 * 64 * 4 - 1) // 3   # two layers, R32F + RGBA32F chains
    # …plus (bp_coverage, the default) the RGBA32F member statistics; without it the two chains alone.
    calls.clear()
    r = pipeline.render(snap, base.with_(bp_refinement="YSM", bp_primitive="MICRORECT", bp_coverage=False,
                                         bp_layers=1))
    assert r.stats["structure_bytes"]["microrects"] == (4 + 16) * (64 * 64 * 4 - 1) // 3
    # Micropatches with coverage read one RGBA32F coverage pyramid per layer; microquads need none.
    calls.clear()
    r = pipeline.render(snap, base.with_(bp_refinement="HSM", bp_layers=2))
    assert calls == {"depth_map": 1, "peeled_layers": 1, "hsm": 1, "coverage": 1, "solid_exits": 1}
    assert r.stats["structure_bytes"]["coverage"] == 2 * 16 * (64 * 64 * 4 - 1) // 3
    calls.clear()
    pipeline.render(snap, base.with_(bp_refinement="HSM", bp_primitive="MICROQUAD"))
    assert "coverage" not in calls and "solid_exits" not in calls       # a microquad spans four texels
    # The solid exits (bp_solid_columns): asked for by default, an RG32F pyramid where a caster is closed, nothing
    # where none is; not asked for when off.
    calls.clear()
    pipeline.render(snap, base.with_(bp_refinement="HSM", bp_solid_columns=False))
    assert "solid_exits" not in calls
    assert pipeline.render(snap, base).stats["structure_bytes"]["solid_exits"] == 8 * (64 * 64 * 4 - 1) // 3
    assert pipeline.render(_stacked_boxes(closed=False), base).stats["structure_bytes"]["solid_exits"] == 0


def test_ssm_structures_follow_its_options(monkeypatch):
    calls = _counting(monkeypatch)
    snap = floating_plane(32)
    r = pipeline.render(snap, RenderSettings(technique="SSM").with_(ssm_map_size=32, ssm_passes="ONE"))
    assert calls == {"ssm_maps": 1, "soft_shadow_map": 1, "ssm_receiver_mask": 1}
    memory = r.stats["structure_bytes"]
    assert memory["soft_shadow_map"] > 0 and memory["ssm_maps"] > memory["soft_shadow_map"]
    assert r.stats["ssm_map_size"] == 32


RAW_GL = re.compile(r"\bctx\.(enable|disable)\b|\.use\(|_own\(|frame\.own\(|framebuffer\(|blend_func|"
                    r"depth_func|vertex_array\(|\.render\(")


@pytest.mark.parametrize("path", sorted((ROOT / "engine" / "techniques").glob("*.py")), ids=lambda p: p.name)
def test_techniques_hold_no_raw_gl_state(path):
    hits = [f"{path.name}:{i}: {line.strip()}" for i, line in enumerate(path.read_text().splitlines(), 1)
            if RAW_GL.search(line)]
    assert not hits, "raw GL state in a technique (move it to gpu/ or structures/):\n" + "\n".join(hits)


def test_peeling_leaves_out_a_solids_far_side_and_the_bare_ground():
    """A floating box wider than the light: from every light point its outline is its top face's rim, so its
    far side (bottom, sides turned away from the centre) adds no occluder, and the ground seen under it has
    nothing behind it. A second layer holds nothing to shadow with, so none is kept and the frame is the
    one-layer frame. The same box not known to be closed keeps its bottom face as a layer."""
    from penumbra.engine.measure.stress import box
    base = RenderSettings(technique="BACKPROJECTION", shadow_map_size=64)
    solid = _solids_over_ground([box((-0.8, -0.8, 0.8), (0.8, 0.8, 1.0))])
    one = pipeline.render(solid, base.with_(bp_layers=1))
    two = pipeline.render(solid, base.with_(bp_layers=2))
    assert two.stats["structure_bytes"]["peeled_layers"] == 0
    assert [s["depth_layers"] for s in two.stats["per_light"]] == [1]
    assert np.array_equal(one.passes["Visibility"], two.passes["Visibility"])
    assert (one.passes["Visibility"][..., 0] < 0.5).any()
    shell = _solids_over_ground([box((-0.8, -0.8, 0.8), (0.8, 0.8, 1.0))], closed=False)
    assert pipeline.render(shell, base.with_(bp_layers=2)).stats["structure_bytes"]["peeled_layers"] > 0
    # Narrower than the light, the box's sides turned away from the centre lie on its outline seen from the
    # light's far edge: they are peeled, unless the solid columns (the default) stand for the far side.
    narrow = _solids_over_ground([box((-0.3, -0.3, 0.8), (0.3, 0.3, 1.0))])
    peeled = pipeline.render(narrow, base.with_(bp_layers=2, bp_solid_columns=False)).stats["structure_bytes"]
    assert peeled["peeled_layers"] > 0
    columns = pipeline.render(narrow, base.with_(bp_layers=2)).stats
    assert columns["structure_bytes"]["peeled_layers"] == 0 and columns["structure_bytes"]["solid_exits"] > 0
    assert [s["depth_layers"] for s in columns["per_light"]] == [1]


def test_peeling_keeps_a_solid_hidden_from_the_light_centre():
    """A small box right under a wider one is hidden from the light's centre, with the ground behind it: the
    second layer holds it (the single-silhouette case of Schwarz & Stamminger 2007, §3.2)."""
    from penumbra.engine.measure.stress import box
    base = RenderSettings(technique="BACKPROJECTION", shadow_map_size=64)
    stacked = _solids_over_ground([box((-0.5, -0.5, 1.0), (0.5, 0.5, 1.1)), box((-0.3, -0.3, 0.5), (0.3, 0.3, 0.6))])
    r = pipeline.render(stacked, base.with_(bp_layers=2))
    assert r.stats["structure_bytes"]["peeled_layers"] == r.stats["structure_bytes"]["depth_map"]
    assert [s["depth_layers"] for s in r.stats["per_light"]] == [2]
