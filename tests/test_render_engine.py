"""The PENUMBRA RenderEngine inside Blender (bpy module) and the command line."""
import os
import subprocess
import sys

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

import penumbra  # noqa: E402
from penumbra.engine.core import exr, passes  # noqa: E402
from penumbra.engine.render import pipeline
from penumbra.engine.gpu.context import GpuError  # noqa: E402
from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402


@pytest.fixture()
def scene():
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    from penumbra.engine.measure import scenes
    sc = scenes.build("plane", resolution=(48, 48))
    sc.render.engine = "PENUMBRA"
    return sc


def render_to_exr(sc, path):
    sc.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    sc.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return exr.read(str(path))


def test_engine_writes_every_pass_like_the_pipeline(scene, tmp_path):
    scene.penumbra.technique = "PCSS"
    out = render_to_exr(scene, tmp_path / "f.exr")
    for name, channels, _, _ in passes.render_passes(RenderSettings()):
        assert name in out, name
        assert out[name].shape == (48, 48, channels)
    direct = pipeline.render(extract(bpy.context.evaluated_depsgraph_get(), scene),
                             RenderSettings(technique="PCSS"))
    np.testing.assert_allclose(out["Visibility"], direct.passes["Visibility"], atol=1e-6)
    np.testing.assert_allclose(out["Combined"], direct.passes["Combined"], rtol=1e-5, atol=1e-6)
    assert 0.0 < out["Visibility"].min() < 1.0 or out["Visibility"].min() == 0.0


def test_debug_passes_are_registered_and_written(scene, tmp_path):
    scene.penumbra.debug_passes = True
    out = render_to_exr(scene, tmp_path / "d.exr")
    assert "Irradiance" in out and out["Irradiance"].max() > 0.0


def test_gpu_failure_marks_the_render_failed_and_blender_goes_on(scene, tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise GpuError("EGL: eglInitialize failed")
    monkeypatch.setattr(pipeline, "render", broken)
    with pytest.raises(RuntimeError, match="Penumbra: GPU pipeline failed: EGL: eglInitialize failed"):
        bpy.ops.render.render()
    monkeypatch.undo()
    out = render_to_exr(scene, tmp_path / "ok.exr")        # the next render works
    assert out["Combined"][..., :3].max() > 0.0


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "penumbra", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_cli_renders_a_builtin_scene(tmp_path):
    r = _cli("render", "--scene", "contact", "--technique", "HARD", "--resolution", "64", "48",
             "--out", str(tmp_path / "c.exr"), "--png", str(tmp_path / "c.png"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "frame total" in r.stdout and "shadow_map" in r.stdout
    out = exr.read(str(tmp_path / "c.exr"))
    assert out["Combined"].shape == (48, 64, 4)
    assert (tmp_path / "c.png").read_bytes().startswith(b"\x89PNG")
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".penumbra-")], "temporary file left behind"


def test_cli_without_camera_names_the_scene(tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.name = "NoCam"
    bpy.ops.mesh.primitive_plane_add()
    blend = tmp_path / "nocam.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    r = _cli("render", str(blend), "--out", str(tmp_path / "x.exr"), cwd=tmp_path)
    assert r.returncode != 0
    assert "NoCam" in r.stderr and "camera" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "x.exr").exists()


def test_cli_rejects_bad_settings_by_name(tmp_path):
    r = _cli("render", "--scene", "plane", "--set", "shadow_map_size=3", "--out", str(tmp_path / "x.exr"),
             cwd=tmp_path)
    assert r.returncode != 0 and "shadow_map_size" in r.stderr and "Traceback" not in r.stderr


def test_atomic_write_keeps_the_old_file_when_writing_fails(tmp_path):
    target = tmp_path / "keep.exr"
    good = {"Combined": np.ones((4, 4, 4), np.float32)}
    exr.write(str(target), good)
    before = target.read_bytes()
    with pytest.raises(Exception):
        exr.write(str(target), {"Combined": np.ones((4, 4, 4), np.float32), "Bad": object()})
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["keep.exr"]


def test_compare_operator_reports_error_and_time(scene, tmp_path):
    scene.penumbra.technique = "PCSS"
    bpy.ops.penumbra.compare_cycles(directory=str(tmp_path), samples=16)
    data = __import__("json").loads((tmp_path / "plane_pcss.json").read_text())
    assert 0.0 <= data["metrics"]["mae_shadow"] < 0.2 and data["ours_ms"] > 0 and data["cycles_seconds"] > 0
    assert (tmp_path / "plane_pcss_compare.png").exists()
