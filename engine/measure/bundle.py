"""Scene bundles: built-in scenes taken out of Blender, with their Cycles references, so that a machine without
Blender (a GPU box that cannot install the bpy wheel) can render every technique on them, time it and score it.

`export` (needs bpy) writes one `<scene>_<W>x<H>.pkl` per scene and size: the extracted SceneSnapshot (numpy
arrays and dataclasses only, see engine/core/snapshot.py) and, at the sizes asked for, the Cycles reference
visibility and its mask. `run` (no bpy) loads them, times each technique with the bench's own timer
(bench.time_ours: a warm-up frame, then the median of the timed frames) and scores it with the bench's metrics,
so its table reads like the bench's and its figures can stand beside the bench's on another machine.
The pickles carry numpy arrays: read them with the numpy major version that wrote them.
"""
from __future__ import annotations

import json
import os
import pickle
import time

import numpy as np

from . import metrics
from .bench import machine_info, machine_label, time_ours
from ..core.files import write_atomic
from ..core.settings import RenderSettings

FORMAT = 1


def bundle_name(scene: str, width: int, height: int) -> str:
    return f"{scene}_{width}x{height}.pkl"


def export(out_dir: str, scene_names: list[str], sizes: list[tuple[int, int]], *, reference_sizes=(),
           samples: int = 1024, log=print) -> list[str]:
    """Build, extract and pickle each scene at each size; with a Cycles reference (seed 0, the bench's) at the
    sizes in `reference_sizes` (cached like the bench's). Returns the files written."""
    import bpy

    from . import reference
    from . import scenes as scene_lib
    from ..blender.extract import extract
    os.makedirs(out_dir, exist_ok=True)
    written = []
    for name in scene_names:
        for w, h in sizes:
            log(f"{name} {w}×{h}: building and extracting")
            scene = scene_lib.build(name, resolution=(w, h))
            snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
            ref = None
            if (w, h) in {tuple(s) for s in reference_sizes}:
                log(f"{name} {w}×{h}: Cycles reference {samples} spp")
                r = reference.cycles_visibility(scene, samples=samples, seed=0, width=w, height=h)
                ref = {"visibility": np.asarray(r.visibility, np.float32), "mask": np.asarray(r.mask, bool),
                       "samples": int(samples)}
            path = os.path.join(out_dir, bundle_name(name, w, h))
            write_atomic(path, pickle.dumps({"format": FORMAT, "scene": name, "resolution": [w, h],
                                             "numpy": np.__version__, "snapshot": snap, "reference": ref},
                                            protocol=4))
            written.append(path)
    return written


def load(path: str) -> dict:
    with open(path, "rb") as f:
        data = pickle.load(f)
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: bundle format {data.get('format')!r}, this Penumbra reads {FORMAT}")
    return data


def run(paths: list[str], techniques: list[str], *, repeats: int = 5, overrides: dict | None = None,
        on_row=None) -> dict:
    """Time and score each technique on each bundle. Rows: scene, size, technique, median frame ms, first-frame
    ms, mae_shadow (None without a reference) and the frame's stats."""
    started = time.perf_counter()
    rows = []
    for path in paths:
        data = load(path)
        snap, ref = data["snapshot"], data["reference"]
        for tid in techniques:
            settings = RenderSettings().with_(**{**(overrides or {}), "technique": tid})
            timing = time_ours(snap, settings, repeats, budget_s=None)
            result = timing.pop("result")
            m = None
            if ref is not None:
                m = metrics.compare(result.passes["Visibility"][..., 0], ref["visibility"], ref["mask"])
            row = {"scene": data["scene"], "resolution": data["resolution"], "technique": tid,
                   "time_ms": timing["time_ms"], "first_frame_ms": timing["first_frame_ms"],
                   "times_ms": timing["times_ms"], "stages_ms": timing["stages_ms"],
                   "mae_shadow": None if m is None else m["mae_shadow"], "metrics": m,
                   "views": result.stats.get("views"), "warnings": sorted(set(result.warnings))}
            rows.append(row)
            if on_row:
                on_row(row)
    return {"machine": machine_info(), "overrides": dict(overrides or {}), "repeats": int(repeats), "rows": rows,
            "wall_seconds": time.perf_counter() - started}


HEADER = f"{'scene':<11} {'size':>9} {'technique':<15} {'ms':>9} {'first ms':>9} {'mae_shadow':>10}  ×HARD"


def table(results: dict) -> str:
    """The rows as text, each technique's time also as a multiple of HARD's on the same scene and size."""
    hard = {(r["scene"], tuple(r["resolution"])): r["time_ms"] for r in results["rows"] if r["technique"] == "HARD"}
    lines = [HEADER]
    for r in results["rows"]:
        key = (r["scene"], tuple(r["resolution"]))
        mae = "-" if r["mae_shadow"] is None else f"{r['mae_shadow']:.4f}"
        ratio = f"{r['time_ms'] / hard[key]:.1f}" if key in hard and hard[key] > 0 else "-"
        lines.append(f"{r['scene']:<11} {'%dx%d' % tuple(r['resolution']):>9} {r['technique']:<15} "
                     f"{r['time_ms']:9.1f} {r['first_frame_ms']:9.1f} {mae:>10}  {ratio}")
    return "\n".join(lines)


def write(results: dict, out_dir: str) -> None:
    os.makedirs(out_dir, exist_ok=True)
    write_atomic(os.path.join(out_dir, "bundle_results.json"), json.dumps(results, indent=1, default=float))
    write_atomic(os.path.join(out_dir, "bundle_results.md"),
                 f"Machine: {machine_label(results['machine'])}\n\n```\n{table(results)}\n```\n")
