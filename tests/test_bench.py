"""engine.measure.bench on one small scene: the outputs exist, hold the expected rows, and make sense (needs bpy;
about 15 s: a 64-spp Cycles reference pair for two seeds at 48×48, two Cycles peers, two techniques)."""
import csv
import io
import json
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import bench  # noqa: E402

TECHNIQUES = ["HARD", "PCSS"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    log = io.StringIO()
    results = bench.run_bench(str(out), scenes=["plane"], techniques=TECHNIQUES, resolution=(48, 48),
                              reference_samples=64, repeats=1, peers=["cycles"], cycles_samples=(1, 16),
                              target_samples=16, cache_dir=str(out / "cache"), stream=log)
    return out, results, log.getvalue()


def test_files_exist(run):
    out, _, _ = run
    for name in ("results.json", "results.csv", "results.md", "pareto_plane.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert (out / "pareto_plane.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob("*.tmp")), "temporary files left behind"


def test_json_rows(run):
    out, results, log = run
    data = json.loads((out / "results.json").read_text())
    assert data["machine"]["gl_renderer"] and data["machine"]["cpu"]
    (scene,) = data["scenes"]
    assert scene["scene"] == "plane" and scene["resolution"] == [48, 48]
    assert scene["reference"]["samples"] == 64
    assert math.isfinite(scene["noise_floor"]["mae_shadow"])
    ours = [r for r in scene["rows"] if r["kind"] == "ours"]
    peers = [r for r in scene["rows"] if r["kind"] == "peer"]
    assert [r["technique"] for r in ours] == TECHNIQUES
    assert [(r["technique"], r["samples"]) for r in peers] == [("Cycles", 1), ("Cycles", 16)]
    for r in scene["rows"]:
        assert r["time_ms"] > 0, r
        for key in ("mae_shadow", "mae", "rmse", "max_abs", "pixel_match"):
            assert math.isfinite(r["metrics"][key]), (r["technique"], r["config"], key)
    for r in ours:
        assert r["first_frame_ms"] > 0 and r["repeats"] == 1
        assert r["stages_ms"]["shadow_map"] >= 0 and "visibility" in r["stages_ms"]
    # Cycles' error is its noise: 1 spp is far noisier than 16 spp.
    assert peers[0]["metrics"]["mae_shadow"] > peers[1]["metrics"]["mae_shadow"]
    assert "plane HARD default" in log


def test_csv_and_markdown(run):
    out, _, _ = run
    rows = list(csv.DictReader(io.StringIO((out / "results.csv").read_text())))
    assert [(r["technique"], r["config"]) for r in rows] == [("HARD", "default"), ("PCSS", "default"),
                                                              ("Cycles", "1 spp"), ("Cycles", "16 spp")]
    assert all(float(r["time_ms"]) > 0 and math.isfinite(float(r["mae_shadow"])) for r in rows)
    md = (out / "results.md").read_text()
    assert "## plane" in md and "Noise floor" in md
    assert md.count("| HARD | default |") == 1 and md.count("| Cycles | 16 spp |") == 1
    assert "| technique | config | time ms (median) | first-frame ms | mae_shadow | rmse | max_abs | pixel_match |" in md


def test_summary_prints(run, capsys):
    _, results, _ = run
    (s,) = results["summary"]
    assert s["scene"] == "plane" and s["target_ms"] > 0
    print(bench.summary_table(results["summary"]))
    text = capsys.readouterr().out
    assert "Cycles-16" in text and "plane" in text
    line = next(l for l in text.splitlines() if l.startswith("plane"))
    assert ("none" in line) == (s["best"] is None)
    if s["best"] is not None:
        assert s["best"]["mae_shadow"] <= s["target_mae_shadow"] and s["speedup"] > 0


def test_sweep_table():
    assert [c["shadow_map_size"] for c in bench.sweep_configs("HARD")] == [256, 512, 1024, 2048]
    pcss = bench.sweep_configs("PCSS")
    assert {"pcss_blocker_samples": 64, "pcss_filter_samples": 128} in pcss
    labels = [label for label, _, _ in bench.configurations("PCF", bench.RenderSettings(), sweep=True)]
    assert labels == ["map=256", "map=512", "map=1024", "map=2048", "radius=1", "radius=4"]   # radius=2 is map=1024
    assert [label for label, _, _ in bench.configurations("PCF", bench.RenderSettings(), sweep=False)] == ["default"]


def test_scaling_quick_smoke(tmp_path):
    """`bench --scaling --quick`: every axis has its points, the sweeps built what they say (more triangles,
    more lights, more pixels), slopes are finite, every point has its techniques' errors against the Cycles
    reference, the Cycles ladder, a Cycles-matched time per technique and the 30× check, and the files are
    written."""
    results = bench.run_scaling(str(tmp_path), techniques=["HARD", "PCSS"], peers=["cycles"], quick=True,
                                progress=False)
    axes = results["axes"]
    assert set(axes) == {"pixels", "triangles", "lights"}
    px, tris, lights = axes["pixels"]["rows"], axes["triangles"]["rows"], axes["lights"]["rows"]
    assert [r["resolution"] for r in px] == [[32, 32], [64, 64]]
    assert tris[0]["triangles"] < tris[1]["triangles"] and 1_000 <= tris[0]["triangles"] < 2_000
    assert [r["lights"] for r in lights] == [1, 2]
    target = bench.SCALING_QUICK_CYCLES["target"]
    for data in axes.values():
        assert set(data["slopes"]) == {"HARD", "PCSS", f"Cycles-{target}"}
        assert all(math.isfinite(s) for s in data["slopes"].values())
        assert all(math.isfinite(s) for s in data["matched_slopes"].values())
        assert all(r["ms"]["PCSS"] > 0 and r["bytes"]["PCSS"] > 0 for r in data["rows"])
    for name in ("scaling.json", "scaling.md", "scaling.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    data = json.loads((tmp_path / "scaling.json").read_text())
    ladder = list(bench.SCALING_QUICK_CYCLES["ladder"])
    assert data["cycles"]["ladder"] == ladder and data["cycles"]["target_samples"] == target
    for axis in data["axes"].values():
        for r in axis["rows"]:
            assert [c["samples"] for c in r["cycles"]] == ladder
            assert all(c["time_ms"] > 0 and math.isfinite(c["mae_shadow"]) for c in r["cycles"]), r["cycles"]
            errs = [c["mae_shadow"] for c in r["cycles"]]
            times = [c["time_ms"] for c in r["cycles"]]
            assert errs[0] > errs[-1]           # Cycles' noise: 1 spp is far worse than 16
            for t in ("HARD", "PCSS"):
                m, e = r["matched"][t], r["mae_shadow"][t]
                assert math.isfinite(e) and math.isfinite(m["spp"]) and math.isfinite(m["time_ms"])
                assert ladder[0] <= m["spp"] <= ladder[-1] and min(times) <= m["time_ms"] <= max(times)
                assert min(errs) <= m["cycles_mae_shadow"] <= max(errs)
                if m["clamped"] is None:        # inside the ladder: Cycles' error there is the technique's
                    assert m["cycles_mae_shadow"] == pytest.approx(e, rel=1e-9)
                assert m["speedup"] == pytest.approx(m["time_ms"] / r["ms"][t])
            # Monotone: the technique with the larger error is matched by no more Cycles samples.
            lo, hi = sorted(("HARD", "PCSS"), key=lambda t: r["mae_shadow"][t])
            assert r["matched"][hi]["spp"] <= r["matched"][lo]["spp"]
            c = r["check"]
            assert c["target_ms"] == r["ms"][f"Cycles-{target}"] == times[ladder.index(target)]
            ok = [t for t in ("HARD", "PCSS") if r["mae_shadow"][t] <= c["target_mae_shadow"]]
            assert c["best"] == (min(ok, key=lambda t: r["ms"][t]) if ok else None)
            if c["best"]:
                assert c["speedup"] == pytest.approx(c["target_ms"] / r["ms"][c["best"]])
            assert c["met"] == (c["best"] is not None and c["speedup"] >= 30.0)
            assert c["closest"] == lo
    assert data["check_30x"]["points"] == 6
    md = (tmp_path / "scaling.md").read_text()
    assert "log–log slope" in md and "log–log interpolation" in md
    assert "**30× check**" in md and f"met at {data['check_30x']['met']} of 6 points" in md


def test_matched_cycles_interpolates_log_log_and_clamps():
    """Cycles' error ∝ spp^-½ and time ∝ spp: log–log interpolation recovers both exactly between ladder
    counts; outside the ladder the match clamps; a noisy ladder (a count worse than the one before) still gives
    a monotone match."""
    spp = [1, 4, 16, 64, 256]
    ladder = [(s, 3.0 * s, 0.4 / math.sqrt(s)) for s in spp]
    m = bench.matched_cycles(ladder, 0.4 / math.sqrt(8))
    assert m["spp"] == pytest.approx(8) and m["time_ms"] == pytest.approx(24) and m["clamped"] is None
    assert bench.matched_cycles(ladder, 0.1)["spp"] == pytest.approx(16)          # a ladder count itself
    assert bench.matched_cycles(ladder, 1.0) == {"spp": 1, "time_ms": 3.0, "cycles_mae_shadow": 0.4,
                                                 "clamped": "below"}
    top = bench.matched_cycles(ladder, 0.001)
    assert top["spp"] == 256 and top["time_ms"] == 768 and top["clamped"] == "above"
    noisy = [(1, 10.0, 0.4), (4, 12.0, 0.2), (16, 11.0, 0.25), (64, 40.0, 0.05)]
    errors = np.geomspace(0.5, 0.03, 40)
    got = [bench.matched_cycles(noisy, e) for e in errors]
    assert all(a["spp"] <= b["spp"] and a["time_ms"] <= b["time_ms"] for a, b in zip(got, got[1:]))
    assert all(1 <= g["spp"] <= 64 for g in got)
    assert math.isnan(bench.matched_cycles(ladder, float("nan"))["spp"])


def test_scaling_refuses_bad_caps_and_targets(tmp_path):
    with pytest.raises(ValueError, match="--max-pixels 100 leaves no output size to run"):
        bench.run_scaling(str(tmp_path), techniques=["HARD"], max_pixels=100, progress=False)
    with pytest.raises(ValueError, match="target samples 32 is not in the Cycles ladder 1,4,16,64,256"):
        bench.run_scaling(str(tmp_path), techniques=["HARD"], target_samples=32, progress=False)


def test_matched_cycles_time_stays_within_the_ladder_when_a_noisy_rung_is_flattened():
    """A Cycles time that comes out lower at more samples (a loaded machine) is raised to its predecessor's,
    so the segment's ends are equal: exp(log t) alone gave 442.52194600267120 for t = 442.52194600267103,
    past the ladder's own maximum (test_scaling_quick_smoke failed on it under load)."""
    ladder = [(1, 70.09606700012228, 0.2), (4, 442.52194600267103, 0.1), (16, 172.9509550059447, 0.05)]
    m = bench.matched_cycles(ladder, 0.07)
    assert 4 <= m["spp"] <= 16 and m["time_ms"] == 442.52194600267103
