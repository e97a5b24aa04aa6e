"""Scene bundles (engine/measure/bundle.py): a built-in scene exported with its Cycles reference renders, is
timed and is scored by a process that cannot import Blender (a GPU machine without the bpy wheel), with the
same error as rendering the scene directly."""
import json
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("bpy")

from penumbra.engine.measure import bundle  # noqa: E402

WITHOUT_BLENDER = ("import sys\n"
                   "for name in ('bpy', 'bmesh', 'mathutils'):\n"
                   "    sys.modules[name] = None\n"
                   "from penumbra.engine.cli import main\n"
                   "sys.exit(main(sys.argv[1:]))\n")


def test_export_then_run_without_blender(tmp_path):
    folder, out = tmp_path / "bundles", tmp_path / "results"
    files = bundle.export(str(folder), ["plane"], [(32, 32), (48, 32)], reference_sizes=[(32, 32)],
                          log=lambda m: None)
    assert sorted(p.split("/")[-1] for p in files) == ["plane_32x32.pkl", "plane_48x32.pkl"]
    data = bundle.load(files[0])
    assert data["reference"]["visibility"].shape == (32, 32) and data["snapshot"].camera.width == 32
    assert bundle.load(files[1])["reference"] is None

    run = subprocess.run([sys.executable, "-c", WITHOUT_BLENDER, "bundle", "run", str(folder), "--techniques",
                          "HARD,PCSS", "--repeats", "1", "--out", str(out)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    results = json.loads((out / "bundle_results.json").read_text())
    rows = {(r["technique"], tuple(r["resolution"])): r for r in results["rows"]}
    assert set(rows) == {(t, s) for t in ("HARD", "PCSS") for s in ((32, 32), (48, 32))}
    assert rows[("HARD", (48, 32))]["mae_shadow"] is None
    assert all(r["time_ms"] > 0 for r in rows.values())
    assert "×HARD" in (out / "bundle_results.md").read_text()

    # The same error as a render in this process, against the same reference.
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure import metrics
    from penumbra.engine.render import pipeline
    result = pipeline.render(data["snapshot"], RenderSettings().with_(technique="PCSS"))
    m = metrics.compare(result.passes["Visibility"][..., 0], data["reference"]["visibility"],
                        data["reference"]["mask"])
    assert np.isclose(rows[("PCSS", (32, 32))]["mae_shadow"], m["mae_shadow"], rtol=1e-6, atol=1e-7)
    assert rows[("HARD", (32, 32))]["mae_shadow"] > rows[("PCSS", (32, 32))]["mae_shadow"]


def test_bad_input_is_named(tmp_path):
    run = subprocess.run([sys.executable, "-m", "penumbra", "bundle", "run", str(tmp_path)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2 and "no scene bundles" in run.stderr
    run = subprocess.run([sys.executable, "-m", "penumbra", "bundle", "export", str(tmp_path), "--scenes",
                          "nosuch"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and "unknown scene(s) nosuch" in run.stderr
    run = subprocess.run([sys.executable, "-m", "penumbra", "bundle", "export", str(tmp_path), "--sizes", "12xq"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and "12xq" in run.stderr
