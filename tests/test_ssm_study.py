"""The SSM study's map-size plot (issue 15 item 9): its error axis starts at 0 and it marks each scene's Cycles
noise floor, so differences far below the noise do not look like a trend."""
from __future__ import annotations

import json
import math

import pytest

pytest.importorskip("bpy")

from penumbra.engine.measure.studies import ssm as study  # noqa: E402


def test_map_size_plot_starts_at_zero_and_marks_the_noise_floor(tmp_path):
    results = study.run(tmp_path, scene_names=("plane",), size=32, samples=16, map_sizes=(64, 96),
                        light_fractions=(), lateral=(), vertical=(), log=lambda s: None)
    floor = results["noise_floor"]["plane"]
    assert floor["samples"] == 16 * study.NOISE_SPP_FACTOR and floor["n_shadow"] > 0
    assert 0.0 < floor["mae_shadow"] < 0.2
    saved = json.loads((tmp_path / "ssm_study.json").read_text())
    assert math.isclose(saved["noise_floor"]["plane"]["mae_shadow"], floor["mae_shadow"])
    assert "Cycles noise floor" in (tmp_path / "ssm_study.md").read_text()
    assert (tmp_path / "error_vs_map_size.png").stat().st_size > 0

    key, metric, xlabel, ylabel, _, title = study.PLOTS[0]
    fig = study.figure(results, key, metric, xlabel, ylabel, title)
    ax = fig.axes[0]
    assert ax.get_ylim()[0] == 0.0
    flat = [line for line in ax.lines if len(set(line.get_ydata())) == 1
            and math.isclose(line.get_ydata()[0], floor["mae_shadow"])]
    assert len(flat) == 1 and "noise floor" in flat[0].get_label()
    # The time plot keeps matplotlib's own axis and has no floor.
    time_fig = study.figure(results, *[study.PLOTS[4][i] for i in (0, 1, 2, 3, 5)])
    assert not any("noise floor" in line.get_label() for line in time_fig.axes[0].lines)
