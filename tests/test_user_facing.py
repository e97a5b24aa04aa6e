"""What a user meets first (issue 15): outputs refused before rendering, file modes, huge images, unreadable
.blend files, the stress command's verdict, compare's numbers and pictures, Blender-version guards."""
from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile

import numpy as np
import pytest

from penumbra.engine.core import exr
from penumbra.engine.core.files import OutputError, check_output_file, check_output_folder, write_atomic
from penumbra.engine.gpu.frame import image_size_problem
from penumbra.engine.measure import stress

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _cli(*args, cwd, prefix=()):
    return subprocess.run([*prefix, sys.executable, "-m", "penumbra", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300, env={**os.environ})


def _one_line_error(r, *needles):
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.startswith("penumbra:")]
    assert len(lines) == 1, r.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert "frame total" not in r.stdout         # refused before anything was rendered
    return lines[0]


# ---- item 3: file modes -----------------------------------------------------------------------------------

@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_written_files_honour_the_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        write_atomic(tmp_path / "a.json", "{}")
        exr.write(str(tmp_path / "b.exr"), {"Combined": np.ones((2, 2, 4), np.float32)})
        exr.write_png(str(tmp_path / "c.png"), np.zeros((2, 2, 3), np.uint8))
    finally:
        os.umask(old)
    for name in ("a.json", "b.exr", "c.png"):
        assert stat.S_IMODE(os.stat(tmp_path / name).st_mode) == mode, name


# ---- item 2: outputs checked before rendering --------------------------------------------------------------

def test_output_checks_name_the_path(tmp_path):
    folder = tmp_path / "folder"
    folder.mkdir()
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(OutputError, match="is a folder"):
        check_output_file(str(folder))
    with pytest.raises(OutputError, match="is a file"):
        check_output_folder(str(afile))
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output_file(str(afile / "x.exr"))
    assert check_output_file(str(tmp_path / "new" / "deeper" / "x.exr")).endswith("x.exr")
    assert not (tmp_path / "new").exists()             # checking creates nothing
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "folder"]   # no probe left behind


def test_render_refuses_an_out_that_is_a_folder(tmp_path):
    (tmp_path / "dir.exr").mkdir()
    r = _cli("render", "--scene", "plane", "--resolution", "32", "32", "--out", str(tmp_path / "dir.exr"),
             cwd=tmp_path)
    _one_line_error(r, str(tmp_path / "dir.exr"), "is a folder")


def test_render_refuses_an_unwritable_folder_before_rendering(tmp_path):
    target = "/proc/penumbra-test/out.png"        # /proc takes no new files, not even from root
    r = _cli("render", "--scene", "plane", "--resolution", "32", "32", "--out", str(tmp_path / "ok.exr"),
             "--png", target, cwd=tmp_path)
    _one_line_error(r, target, "not writable")
    assert not (tmp_path / "ok.exr").exists()     # the good output is not written either: nothing partial


def _read_only_mount_prefix(folder):
    """Run a command with `folder` mounted read-only (a user and mount namespace), or None where the
    system does not allow it."""
    if not shutil.which("unshare"):
        return None
    probe = subprocess.run(["unshare", "-r", "-m", "sh", "-c", f"mount -t tmpfs -o ro tmpfs '{folder}'"],
                           capture_output=True)
    return None if probe.returncode else ["unshare", "-r", "-m", "sh", "-c",
                                          f"mount -t tmpfs -o ro tmpfs '{folder}' && exec \"$@\"", "sh"]


def test_render_refuses_a_read_only_file_system(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    prefix = _read_only_mount_prefix(ro)
    if prefix is None:
        pytest.skip("no user namespaces here to mount a read-only file system")
    r = _cli("render", "--scene", "plane", "--resolution", "32", "32", "--out", str(ro / "x.exr"),
             cwd=tmp_path, prefix=prefix)
    line = _one_line_error(r, str(ro / "x.exr"))
    assert "Read-only file system" in line


def test_compare_refuses_an_out_that_is_a_file(tmp_path):
    (tmp_path / "cmp").write_text("not a folder")
    r = _cli("compare", "--scene", "plane", "--resolution", "32", "32", "--out", str(tmp_path / "cmp"),
             cwd=tmp_path)
    _one_line_error(r, str(tmp_path / "cmp"), "is a file")
    assert (tmp_path / "cmp").read_text() == "not a folder"


# ---- item 5: huge images ---------------------------------------------------------------------------------

def test_image_size_problem_says_what_fits():
    assert image_size_problem(1920, 1080, 16384, 64 * 2**30, 256) is None
    text = image_size_problem(40000, 20000, 16384, None, 256)
    assert "GL_MAX_TEXTURE_SIZE" in text and "16384×8192 fits" in text
    # 8192² at 256 B/px is 16 GiB; with 4 GiB available half the side fits.
    text = image_size_problem(8192, 8192, 16384, 4 * 2**30, 256)
    assert "16.0 GiB" in text and "4.0 GiB" in text and "4096×4096 fits" in text


def test_render_refuses_a_resolution_beyond_the_gpu(tmp_path):
    r = _cli("render", "--scene", "plane", "--technique", "HARD", "--resolution", "40000", "40000",
             "--out", str(tmp_path / "x.exr"), cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "40000×40000" in r.stderr and "GL_MAX_TEXTURE_SIZE" in r.stderr and "fits" in r.stderr
    assert not (tmp_path / "x.exr").exists()


# ---- item 6: unreadable .blend, unknown stress case ---------------------------------------------------------

@pytest.mark.parametrize("content", [b"BLENDER-v500 truncated", b"\x89PNG not a blend at all"])
def test_corrupt_blend_is_one_line(tmp_path, content):
    blend = tmp_path / "broken.blend"
    blend.write_bytes(content)
    r = _cli("render", str(blend), "--out", str(tmp_path / "x.exr"), cwd=tmp_path)
    assert r.returncode != 0 and "Traceback" not in r.stderr, r.stderr
    assert f"penumbra: cannot read '{blend}' as a .blend file" in r.stderr
    assert not (tmp_path / "x.exr").exists()


def test_stress_unknown_case_lists_the_cases(tmp_path):
    r = _cli("stress", "--case", "no_such_case", cwd=tmp_path)
    line = _one_line_error(r, "no_such_case")
    assert all(c.name in line for c in stress.CASES) and "--list" in line


def test_stress_list(tmp_path):
    r = _cli("stress", "--list", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == len(stress.CASES)
    assert any(line.startswith("fp16_accumulation") and "expected to fail: SSM" in line for line in lines)


# ---- item 7: stress verdict and table ----------------------------------------------------------------------

def test_stress_exits_0_when_only_expected_failures_fail(tmp_path):
    r = _cli("stress", "--case", "touch_plane", "--technique", "HARD", cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "expected failures" in r.stdout and "touch_plane HARD: default bias" in r.stdout
    assert "0 passed, 1 expected failures, 0 unexpected" in r.stdout


def test_stress_reports_an_expected_failure_that_passes(tmp_path):
    # A bias below the 1e-4 m gap (and no normal offset): the documented light leak no longer happens.
    r = _cli("stress", "--case", "touch_plane", "--technique", "HARD", "--set", "bias=0.05",
             "--set", "normal_offset=0", cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "unexpected pass: touch_plane HARD" in r.stdout and "XPASS" in r.stdout


def test_stress_verdict_counts_only_unexpected_results():
    rows = [dict(status="ok"), dict(status="xfail"), dict(status="xfail")]
    assert stress.verdict(rows)[2] == 0
    for status in ("FAIL", "CRASH", "XPASS"):
        assert stress.verdict(rows + [dict(status=status)])[2] == 1


def test_stress_table_does_not_cut_names():
    rows = [dict(case="fp16_accumulation", technique="BACKPROJECTION", nonfinite=0, v_min=0.0, v_max=1.0,
                 metric="vs_float32_shadow", error=0.5, tol=0.02, class_err=float("nan"), time_ms=3.0,
                 status="xfail", notes="n")]
    head, _, line = stress.format_table(rows).splitlines()
    for word in ("fp16_accumulation", "BACKPROJECTION", "vs_float32_shadow", "xfail"):
        assert word in line.split()
    assert head.split()[:3] == ["case", "technique", "nonfinite"]
    assert line.split()[8] == "-"          # NaN class_err


def test_expected_failures_name_real_cases_and_techniques():
    from penumbra.engine.techniques import TECHNIQUES
    for case, technique in stress.EXPECTED_FAILURES:
        assert case in stress.CASE_BY_NAME and technique in TECHNIQUES


# ---- item 11: Blender-version guards -------------------------------------------------------------------------

def test_eevee_identifier_follows_the_running_blender():
    from penumbra.engine.blender.compat import eevee_engine_id
    assert eevee_engine_id({"BLENDER_EEVEE_NEXT", "BLENDER_WORKBENCH", "CYCLES"}) == "BLENDER_EEVEE_NEXT"  # 4.2–4.5
    assert eevee_engine_id({"BLENDER_EEVEE", "BLENDER_WORKBENCH", "CYCLES"}) == "BLENDER_EEVEE"            # 5.0
    pytest.importorskip("bpy")
    from penumbra.engine.blender.compat import engine_ids
    assert eevee_engine_id() in engine_ids()


def test_file_format_sets_media_type_only_where_blender_has_it():
    from penumbra.engine.blender.compat import SettingsRecorder, set_file_format

    class Old:                      # 4.2–4.5: no media_type
        file_format = "PNG"

    class New(Old):                 # 5.0
        media_type = "IMAGE"
    old, new = Old(), New()
    st = SettingsRecorder()
    set_file_format(st, old, "OPEN_EXR_MULTILAYER")
    set_file_format(st, new, "OPEN_EXR_MULTILAYER")
    assert not hasattr(old, "media_type") and old.file_format == "OPEN_EXR_MULTILAYER"
    assert (new.media_type, new.file_format) == ("MULTI_LAYER_IMAGE", "OPEN_EXR_MULTILAYER")
    st.restore()
    assert old.file_format == "PNG" and (new.media_type, new.file_format) == ("IMAGE", "PNG")


# ---- item 9: pictures through Blender's colour management ----------------------------------------------------

def _png_pixels(path):
    from PIL import Image
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(int)


@pytest.fixture()
def agx_blend(tmp_path):
    """A built-in scene saved with the AgX view transform (Blender's default for new files), undithered."""
    bpy = pytest.importorskip("bpy")
    import penumbra
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    from penumbra.engine.measure import scenes
    sc = scenes.build("suzanne", resolution=(64, 48))
    sc.render.engine = "PENUMBRA"
    sc.penumbra.technique = "HARD"
    sc.view_settings.view_transform = "AgX"
    sc.view_settings.look = "None"
    sc.render.dither_intensity = 0.0
    for other in list(bpy.data.scenes):
        if other != sc:
            bpy.data.scenes.remove(other)
    blend = tmp_path / "agx.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    return bpy, sc, blend


def test_cli_png_matches_blenders_own_png(agx_blend, tmp_path):
    bpy, sc, blend = agx_blend
    from penumbra.engine.blender.compat import SettingsRecorder, set_file_format
    st = SettingsRecorder()
    set_file_format(st, sc.render.image_settings, "PNG")
    sc.render.image_settings.color_mode = "RGB"
    sc.render.filepath = str(tmp_path / "blender.png")
    bpy.ops.render.render(write_still=True)
    r = _cli("render", str(blend), "--technique", "HARD", "--out", str(tmp_path / "ours.exr"),
             "--png", str(tmp_path / "ours.png"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    blender, ours = _png_pixels(tmp_path / "blender.png"), _png_pixels(tmp_path / "ours.png")
    assert ours.shape == blender.shape == (48, 64, 3)
    assert np.abs(ours - blender).max() <= 1
    # The plain sRGB curve (what the PNG used to be) is visibly brighter than AgX here.
    srgb = exr.to_srgb8(exr.read(str(tmp_path / "ours.exr"))["Combined"]).astype(int)
    assert np.abs(srgb - blender).mean() > 5


# ---- item 8: compare's numbers ---------------------------------------------------------------------------------

@pytest.fixture()
def plane_scene(monkeypatch, tmp_path):
    bpy = pytest.importorskip("bpy")
    import penumbra
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    monkeypatch.setenv("PENUMBRA_CACHE", str(tmp_path / "cache"))     # fresh renders, timed here
    from penumbra.engine.measure import scenes
    return bpy, scenes.build("plane", resolution=(40, 32))


def _strict_json(path):
    def refuse(name):
        raise AssertionError(f"{name} in JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def test_compare_times_one_cycles_render_and_counts_shadow_pixels(plane_scene, tmp_path):
    bpy, sc = plane_scene
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure.compare import compare
    cmp = compare(sc, RenderSettings(technique="PCSS"), samples=4, with_noise_floor=False,
                  out_dir=str(tmp_path / "out"))
    assert not cmp.ref.cached
    assert cmp.cycles_seconds == cmp.ref.shadowed_seconds and cmp.cycles_timed_by == "shadowed render"
    assert 0 < cmp.cycles_seconds < cmp.cycles_pair_seconds == pytest.approx(cmp.ref.seconds)
    text = cmp.summary()
    assert f"Cycles {cmp.cycles_seconds:.2f} s for one render" in text
    assert f"mae_shadow {cmp.metrics['mae_shadow']:.4f} over {cmp.metrics['n_shadow']} shadow px" in text
    data = _strict_json(tmp_path / "out" / "plane_pcss.json")
    assert data["cycles_seconds"] == pytest.approx(cmp.cycles_seconds)
    assert data["metrics"]["n_shadow"] == cmp.metrics["n_shadow"] > 0
    # A second compare reads the cached pair and still reports one render.
    again = compare(sc, RenderSettings(technique="PCSS"), samples=4, with_noise_floor=False)
    assert again.ref.cached and again.cycles_seconds == pytest.approx(cmp.cycles_seconds)


def test_compare_without_lights_writes_null_and_says_why(plane_scene, tmp_path):
    bpy, sc = plane_scene
    for ob in [o for o in sc.objects if o.type == "LIGHT"]:
        bpy.data.objects.remove(ob)
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure.compare import compare
    cmp = compare(sc, RenderSettings(technique="HARD"), samples=2, with_noise_floor=False,
                  out_dir=str(tmp_path / "out"))
    data = _strict_json(tmp_path / "out" / "plane_hard.json")
    assert data["metrics"]["mae_shadow"] is None and data["metrics"]["ssim_shaded"] is None
    assert "has no lights" in data["undefined"]
    assert "no error measured" in cmp.summary() and "SSIM" not in cmp.summary()


def test_compare_png_has_both_rows_and_a_fallback_without_matplotlib(plane_scene, tmp_path, monkeypatch):
    bpy, sc = plane_scene
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure import compare as C
    cmp = C.compare(sc, RenderSettings(technique="PCSS"), samples=4, with_noise_floor=False)
    ours, theirs, diffs, view = C._panels(cmp, sc)
    assert view == sc.view_settings.view_transform
    assert [o.shape for o in ours] == [(32, 40), (32, 40, 3)] and [d.shape for d in diffs] == [(32, 40)] * 2
    # Cycles' visibility panel is the reference itself; the Combined panel is through the view transform.
    np.testing.assert_array_equal(theirs[0], np.flipud(cmp.ref.visibility))
    from penumbra.engine.blender.compat import display_rgb8
    np.testing.assert_array_equal(ours[1], display_rgb8(cmp.passes["Combined"], sc))
    C.write_comparison_png(str(tmp_path / "fig.png"), cmp, sc)
    fig = _png_pixels(tmp_path / "fig.png")
    assert fig.shape[0] > 2 * 32 and fig.shape[1] > 3 * 40        # titled figure, not the bare strip
    reds = ((fig[..., 0] > 150) & (fig[..., 2] < 100)).sum()
    blues = ((fig[..., 2] > 150) & (fig[..., 0] < 100)).sum()
    assert reds > 0 and blues > 0                                  # the colour scale shows both ends
    monkeypatch.setitem(sys.modules, "matplotlib", None)           # Blender's Python has no matplotlib
    C.write_comparison_png(str(tmp_path / "strip.png"), cmp, sc)
    assert _png_pixels(tmp_path / "strip.png").shape == (2 * 32 + 4, 3 * 40 + 8, 3)
    assert any("matplotlib is not installed" in w and "red: Penumbra darker" in w for w in cmp.warnings)


# ---- item 7: the README's extension build works from a fresh checkout --------------------------------------

def test_readme_extension_build_runs_in_a_fresh_copy(tmp_path):
    """The README's build line, run as written in a copy of the sources without dist/ (Blender's own
    `blender --command extension` is the bpy wheel's blender_ext.py here)."""
    import re
    from tests.test_packaging import _validator
    script, _ = _validator()
    readme = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    line = next(ln for ln in readme.splitlines() if "extension build" in ln).split("#")[0].strip()
    assert "/dist/" in open(os.path.join(ROOT, ".gitignore")).read().split()
    src = tmp_path / "clone"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".venv", ".git", "dist", "out", "__pycache__",
                                                             ".pytest_cache", "*.egg-info"))
    command = re.sub(r"\bblender --command extension\b", f"'{sys.executable}' '{script}'", line)
    proc = subprocess.run(["sh", "-c", command], cwd=src, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "FATAL" not in proc.stdout + proc.stderr, proc.stdout + proc.stderr
    assert len(list((src / "dist").glob("penumbra-*.zip"))) == 1


# ---- item 1 and item 2 (operators): Compare with Cycles in Blender ------------------------------------------

@pytest.fixture()
def saved_scene(monkeypatch, tmp_path):
    bpy = pytest.importorskip("bpy")
    import penumbra
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    monkeypatch.setenv("PENUMBRA_CACHE", str(tmp_path / "cache"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    from penumbra.engine.measure import scenes
    sc = scenes.build("plane", resolution=(400, 300))
    return bpy, sc


def test_compare_operator_preview_shows_the_result_in_blender(saved_scene, tmp_path):
    bpy, sc = saved_scene
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    sc = bpy.data.scenes[sc.name]
    sc.penumbra.technique = "PCSS"
    assert bpy.ops.penumbra.compare_cycles(preview=True, samples=256) == {"FINISHED"}
    folder = tmp_path / "penumbra_compare"                  # derived from the .blend
    data = _strict_json(folder / "plane_pcss.json")
    assert data["resolution"] == [256, 192] and data["reference_samples"] == 32 and data["noise_floor"] is None
    assert "256×192 (scene 400×300)" in data["preview"] and "32 Cycles spp (asked 256)" in data["preview"]
    assert (sc.render.resolution_x, sc.render.resolution_y) == (400, 300)      # the scene is restored
    state = sc.penumbra_compare
    assert not state.running and state.status == "done"
    assert state.mae_shadow == pytest.approx(data["metrics"]["mae_shadow"], abs=1e-6)
    assert state.n_shadow == data["metrics"]["n_shadow"] and state.preview_caps == data["preview"]
    image = bpy.data.images[state.image]
    assert tuple(image.size) == _png_pixels(folder / "plane_pcss_compare.png").shape[1::-1]


def test_compare_operator_unsaved_file_never_writes_into_the_working_directory(saved_scene, tmp_path,
                                                                              monkeypatch):
    bpy, sc = saved_scene
    assert not bpy.data.filepath
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    sc.render.resolution_x, sc.render.resolution_y = 48, 32
    assert bpy.ops.penumbra.compare_cycles(preview=True, samples=4) == {"FINISHED"}
    assert list(cwd.iterdir()) == []
    assert len(list((tmp_path / "tmp" / "penumbra_compare").glob("plane_*.json"))) == 1


def test_operators_report_output_errors_without_a_traceback(saved_scene, tmp_path):
    bpy, sc = saved_scene
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(RuntimeError) as info:
        bpy.ops.penumbra.compare_cycles(directory=str(afile), preview=True, samples=4)
    assert f"output folder '{afile}' is a file" in str(info.value) and "Traceback" not in str(info.value)
    assert afile.read_text() == "x"
    with pytest.raises(RuntimeError) as info:
        bpy.ops.penumbra.export_exr(filepath=str(tmp_path))
    assert "is a folder" in str(info.value) and "Traceback" not in str(info.value)


def test_cancelling_a_comparison_restores_the_scene_and_writes_nothing(saved_scene, tmp_path):
    bpy, sc = saved_scene
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure.compare import compare_steps
    steps = compare_steps(sc, RenderSettings(technique="HARD"), samples=4, preview=True,
                          out_dir=str(tmp_path / "out"))
    next(steps)
    assert (sc.render.resolution_x, sc.render.resolution_y) == (256, 192)      # preview caps in force
    next(steps)                                                               # our frame done
    steps.close()                                                             # Esc
    assert (sc.render.resolution_x, sc.render.resolution_y) == (400, 300)
    assert not (tmp_path / "out").exists()


class _FakeWM:
    def __init__(self):
        self.calls = []

    def __getattr__(self, name):            # progress_begin/update/end, event_timer_add/remove, modal_handler_add
        return lambda *args, **kwargs: self.calls.append(name)


def _modal_driver(bpy, sc, **props):
    """The operator's modal machinery driven by hand (no window in background mode): a stand-in `self` that
    borrows the operator's own methods, and a context whose window manager records the calls."""
    from types import SimpleNamespace
    from penumbra.operators.render_ops import PENUMBRA_OT_compare_cycles as Op
    reports = []
    fake = type("FakeOp", (), {name: getattr(Op, name) for name in ("_start", "_advance", "_end", "_show",
                                                                    "modal")})()
    fake.directory, fake.samples, fake.preview, fake.noise_floor = props["directory"], 4, True, False
    fake.report = lambda kind, text: reports.append((set(kind), text))
    fake._timer = object()
    context = SimpleNamespace(scene=sc, window_manager=_FakeWM(), screen=None)
    assert fake._start(context)
    return fake, context, reports


def test_compare_modal_runs_on_timer_events_and_esc_cancels(saved_scene, tmp_path):
    bpy, sc = saved_scene
    from types import SimpleNamespace
    timer, esc = SimpleNamespace(type="TIMER"), SimpleNamespace(type="ESC")
    fake, context, reports = _modal_driver(bpy, sc, directory=str(tmp_path / "a"))
    statuses = [fake.modal(context, timer) for _ in range(2)]
    assert statuses == [{"RUNNING_MODAL"}] * 2 and sc.penumbra_compare.running
    assert 0.0 < sc.penumbra_compare.progress < 1.0 and "Cycles" in sc.penumbra_compare.status
    assert fake.modal(context, esc) == {"CANCELLED"}
    assert sc.penumbra_compare.status == "cancelled" and not sc.penumbra_compare.running
    assert (sc.render.resolution_x, sc.render.resolution_y) == (400, 300)
    assert "event_timer_remove" in context.window_manager.calls and not (tmp_path / "a").exists()

    fake, context, reports = _modal_driver(bpy, sc, directory=str(tmp_path / "b"))
    for _ in range(10):
        status = fake.modal(context, timer)
        if status != {"RUNNING_MODAL"}:
            break
    assert status == {"FINISHED"} and sc.penumbra_compare.status == "done"
    assert any("PREVIEW" in text for kind, text in reports if kind == {"INFO"})
    assert len(list((tmp_path / "b").glob("*_compare.png"))) == 1


def test_ctrl_c_during_cycles_stops_compare_with_status_130(tmp_path):
    """Blender swallows the KeyboardInterrupt raised inside Cycles; the run must still stop (after the
    render in progress), exit 130, and cache nothing."""
    import glob
    import signal
    import time
    env = {**os.environ, "PENUMBRA_CACHE": str(tmp_path / "cache"), "TMPDIR": str(tmp_path)}
    # 16000 samples: each Cycles render of the pair lasts seconds, so the signal lands inside one of them.
    p = subprocess.Popen([sys.executable, "-m", "penumbra", "compare", "--scene", "plane", "--resolution", "32",
                          "32", "--cycles-samples", "16000", "--no-noise-floor"], cwd=tmp_path, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    start = time.monotonic()
    while not glob.glob(str(tmp_path / "penumbra_ref_*")) and time.monotonic() - start < 120:
        time.sleep(0.1)                 # the reference's temporary folder: Cycles is about to render
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=300)
    assert p.returncode == 130, err[-2000:]
    assert "penumbra: compare cancelled" in err
    assert not list((tmp_path / "cache").rglob("*.npz"))
