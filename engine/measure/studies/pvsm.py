"""The studies of Shen et al. 2011 ("Predicted Virtual Soft Shadow Maps") for the PVSM technique, in its
fixed-resolution mode, on scenes whose visibility has a closed form (no Cycles needed):

    python -m penumbra bench --study pvsm --out DIR -- [--size 64] [--map 1024]

  closed   the parallel-planes scene (square occluder over a plane, square light): mean |V − V_exact| over the
           penumbra and umbra, anti-aliasing off and on, uniform weights (the closed form is the plain share of
           the light's area);
  aa       thin bars parallel to the floor under a small light, whose sub-pixel shadows alias: error against
           the box-filtered closed form (each pixel the mean of the exact visibility over its footprint on the
           ground, 64×64 points) for the analytic anti-aliasing of §4.2 against screen-space supersampling
           8×8 and 32×32 without it (the paper: as good as 32×32 at ~1/9 of 8×8's time), with times;
  stages   milliseconds per stage (Table 1's columns: G-buffer, low-resolution map, z-averaging, tile grid
           and tiling, tile maps, filtering) for the fixed and the adaptive mode;
  rho      the finest level under the kernel cap against ρ_dynamic (the cubic), ρ_static and a line in
           log2 n (the paper's Fig. 8 foil), each with its error and time;
  rho_time ρ_dynamic against the line at equal time: each over kernel caps 8 … 256, the line's error read off
           its (time, error) curve at the cubic's time;
  table2   adaptive tiles against one fixed map at the paper's proportions (its 1024² image, 1024² low-resolution
           map and 4096² tiles and fixed map become a low-resolution map of the image's size and 4× that for
           the tiles and the fixed map), for a small and a large light over the parallel planes: time and
           error against the closed form (the paper's Table 2: adaptive at 0.73× fixed's speed for its small
           light, 2.96× for its large one);
  fig10    a point-like light against an area light: tiles, tile texels, time (the paper's Fig. 10: fewer
           tiles and about twice the speed for the soft shadow).

Writes DIR/pvsm_study.json and DIR/pvsm_study.md atomically.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...core.files import write_atomic
from ...core.settings import RenderSettings
from ...render import pipeline
from .. import stress

BAR_HEIGHT, BAR_WIDTH, BAR_PITCH, BAR_COUNT = 0.5, 0.01, 0.06, 15
BAR_LIGHT = 0.02                    # light size (m) at 3 m: a penumbra of ~3 mm on the floor


# ---- scenes with a closed form ------------------------------------------------------------------------------
def ground_hits(cam, width, height, sub=1):
    """World points where the rays through a sub×sub grid of each pixel meet the ground z = 0:
    (height, width, sub·sub, 3)."""
    offs = (np.arange(sub) + 0.5) / sub
    xs = (np.arange(width)[:, None] + offs[None, :]).ravel() / width * 2 - 1
    ys = (np.arange(height)[:, None] + offs[None, :]).ravel() / height * 2 - 1
    from ..stress import ndc_rays
    near, far = ndc_rays(cam, np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2))
    t = near[:, 2] / (near[:, 2] - far[:, 2])
    pts = (near + (far - near) * t[:, None]).reshape(height, sub, width, sub, 3)
    return pts.transpose(0, 2, 1, 3, 4).reshape(height, width, sub * sub, 3)


def plane_exact(pts, light_half=0.5, occ_half=0.5, occ_height=1.0, light_height=3.0):
    """Unoccluded share of a square light past a parallel square occluder (stress.plane_scene's geometry)."""
    k = light_height / occ_height
    centre = pts[..., :2] * (1 - k)
    lo = np.maximum(centre - occ_half * k, -light_half)
    hi = np.minimum(centre + occ_half * k, light_half)
    return 1.0 - np.clip(hi - lo, 0, None).prod(axis=-1) / (2 * light_half) ** 2


def bar_centres():
    return (np.arange(BAR_COUNT) - (BAR_COUNT - 1) / 2.0) * BAR_PITCH


def bars_scene(size):
    """BAR_COUNT thin bars along y at height BAR_HEIGHT over the ground, a small square light above."""
    parts = [("Ground", stress.quad((0, 0, 0), 4.0), True, True)]
    tris = [stress.strip((x, -1.0), (x, 1.0), BAR_WIDTH, BAR_HEIGHT) for x in bar_centres()]
    parts.append(("Bars", np.concatenate(tris), True, False))
    light = stress.area_light((0.0, 0.0, 3.0), size=BAR_LIGHT)
    cam = stress.camera(eye=(0.0, -2.2, 1.6), target=(0.0, 0.0, 0.0), fov=40.0, size=size)
    return stress.assemble(parts, [light], cam, "pvsm_bars")


def bars_exact(pts, light_height=3.0):
    """Unoccluded share of the light (width BAR_LIGHT along x) past the bars: each bar, seen from a ground
    point x, hides the interval of the light between its edges projected from x (similar triangles); the
    bars are long enough in y that only x matters. Bars never overlap on the light here."""
    h = BAR_LIGHT / 2.0
    k = light_height / BAR_HEIGHT
    x = pts[..., 0]
    hidden = np.zeros_like(x)
    for c in bar_centres():
        a = x + (c - BAR_WIDTH / 2 - x) * k
        b = x + (c + BAR_WIDTH / 2 - x) * k
        hidden += np.clip(np.minimum(b, h) - np.maximum(a, -h), 0, None)
    inside = np.abs(pts[..., 1]) < 1.0 - 0.1
    return np.where(inside, 1.0 - np.clip(hidden / (2 * h), 0, 1), 1.0)


# ---- measurements -------------------------------------------------------------------------------------------
def _render(snap, settings, repeats):
    """The fastest of `repeats` frames, after an untimed 8×8 frame that compiles the shaders."""
    pipeline.render(replace(snap, camera=replace(snap.camera, width=8, height=8)), settings)
    best, result = None, None
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        result = pipeline.render(snap, settings, stage_times=True)
        dt = (time.perf_counter() - t0) * 1000.0
        best = dt if best is None else min(best, dt)
    return result, best


def _box_down(v, sub):
    h, w = v.shape[0] // sub, v.shape[1] // sub
    return v.reshape(h, sub, w, sub).mean(axis=(1, 3))


def closed_form(size, map_size, repeats, log):
    snap = stress.plane_scene(name="plane_closed")
    snap = replace(snap, camera=replace(snap.camera, width=size, height=size))
    exact = plane_exact(ground_hits(snap.camera, size, size)[:, :, 0])
    rows = []
    for aa in (False, True):
        s = RenderSettings(technique="PVSM", shadow_map_size=map_size).with_(pvsm_antialiasing=aa,
                                                                            pvsm_weighting="UNIFORM")
        r, ms = _render(snap, s, repeats)
        v = r.passes["Visibility"][..., 0]
        ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(snap, size)) < 1e-3
        m = ground & ((exact < 0.99) | (v < 0.99))
        err = np.abs(v - exact)[m]
        rows.append({"antialiasing": aa, "mean_error": float(err.mean()), "p99": float(np.percentile(err, 99)),
                     "pixels": int(m.sum()), "ms": ms})
        log(f"closed form, AA {aa}: mean {err.mean():.4f}, {ms:.0f} ms")
    return rows


def _ground_depth(snap, size):
    pts = ground_hits(snap.camera, size, size)[:, :, 0]
    hom = np.c_[pts.reshape(-1, 3), np.ones(size * size)] @ snap.camera.view.T
    return -hom[:, 2].reshape(size, size)


def antialiasing(size, map_size, repeats, log):
    snap = bars_scene(size)
    ref = bars_exact(ground_hits(snap.camera, size, size, sub=64)).mean(axis=-1)
    point = bars_exact(ground_hits(snap.camera, size, size)[:, :, 0])
    rows = []
    configs = [("analytic AA (§4.2)", 1, True), ("no AA", 1, False), ("supersampling 8×8", 8, False),
               ("supersampling 32×32", 32, False)]
    for name, sub, aa in configs:
        big = replace(snap, camera=replace(snap.camera, width=size * sub, height=size * sub))
        s = RenderSettings(technique="PVSM", shadow_map_size=map_size).with_(pvsm_antialiasing=aa,
                                                                            pvsm_weighting="UNIFORM")
        r, ms = _render(big, s, repeats)
        v = _box_down(r.passes["Visibility"][..., 0], sub)
        m = (ref < 0.999) | (v < 0.999)
        rows.append({"method": name, "mean_error": float(np.abs(v - ref)[m].mean()),
                     "max_error": float(np.abs(v - ref)[m].max()), "ms": ms,
                     "pvsm_filter_ms": float(r.timings.get("pvsm_filter", 0.0))})
        log(f"bars, {name}: mean {rows[-1]['mean_error']:.4f}, {ms:.0f} ms")
    rows.append({"method": "point-sampled closed form (what any 1-sample method converges to)",
                 "mean_error": float(np.abs(point - ref)[(ref < 0.999) | (point < 0.999)].mean()),
                 "max_error": float(np.abs(point - ref).max()), "ms": 0.0, "pvsm_filter_ms": 0.0})
    return rows


ADAPTIVE = {"pvsm_mode": "ADAPTIVE", "pvsm_tile_size": 4096}
STAGES = ("gbuffer", "shadow_map", "pvsm_search_map", "pvsm_predict", "pvsm_tiling", "pvsm_tile_maps",
          "pvsm_filter", "irradiance", "accumulate")


def stages(size, map_size, repeats, log):
    """Table 1's columns; `shadow_map` is the pipeline's structures (the low-resolution search map, and
    the one filtering map in the fixed mode), `pvsm_predict` z-averaging with the tile grid."""
    snap = stress.plane_scene(name="plane_stages")
    snap = replace(snap, camera=replace(snap.camera, width=size, height=size))
    rows = []
    for mode, options in (("FIXED", {}), ("ADAPTIVE", ADAPTIVE)):
        s = RenderSettings(technique="PVSM", shadow_map_size=map_size, collect_stats=True).with_(**options)
        r, ms = _render(snap, s, repeats)
        row = {"mode": mode, **{k: float(r.timings.get(k, 0.0)) for k in STAGES}, "frame_ms": ms,
               "tiles": (r.stats.get("per_light") or [{}])[0].get("tiles", 0)}
        rows.append(row)
        log("stages: " + ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()))
    return rows


def _plane_error(snap, size, light_size, r):
    exact = plane_exact(ground_hits(snap.camera, size, size)[:, :, 0], light_half=light_size / 2.0)
    v = r.passes["Visibility"][..., 0]
    ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(snap, size)) < 1e-3
    m = ground & ((exact < 0.99) | (v < 0.99))
    return float(np.abs(v - exact)[m].mean()) if m.any() else 0.0


def close_up_plane(light_size, size, name="plane_close"):
    """The parallel planes seen from under the occluder, close to the shadow's edge: the ground fills the image,
    so that its pixels ask for texels finer than a low-resolution map of the image's size (the default camera
    sees 8 m of ground)."""
    snap = stress.plane_scene(light_size=light_size, name=name)
    return replace(snap, camera=stress.camera(eye=(0.2, -1.3, 0.5), target=(0.3, 0.3, 0.0), fov=40.0, size=size))


def _light_rows(size, map_size, repeats, log, lights, configs, tag):
    rows = []
    for light_name, light_size in lights:
        snap = close_up_plane(light_size, size, f"plane_{tag}_{light_name}")
        for config, shadow_map, options in configs:
            s = RenderSettings(technique="PVSM", shadow_map_size=shadow_map, collect_stats=True).with_(**options)
            r, ms = _render(snap, s, repeats)
            per = (r.stats.get("per_light") or [{}])[0]
            rows.append({"light": light_name, "light_size": light_size, "config": config, "ms": ms,
                         "mean_error": _plane_error(snap, size, light_size, r), "tiles": per.get("tiles", 1),
                         "tile_texels": per.get("tile_texels", shadow_map * shadow_map),
                         "levels": str(per.get("tile_levels", "")),
                         "shadow_map_ms": float(r.timings.get("shadow_map", 0.0) + r.timings.get("pvsm_tile_maps", 0.0)),
                         "filter_ms": float(r.timings.get("pvsm_filter", 0.0))})
            log(f"{tag} {light_name} {config}: {ms:.0f} ms, mean {rows[-1]['mean_error']:.4f}, "
                f"{rows[-1]['tiles']} tiles")
    return rows


def _paper_scale(size):
    """The paper's proportions (a 1024² image, a 1024² low-resolution map, tiles and the fixed map 4096²) at
    this image size: low-resolution map = image side, tiles and fixed map 4× that, virtual map ≤ 16× that."""
    low = max(16, int(size))
    return low, 4 * low, {**ADAPTIVE, "pvsm_tile_size": 4 * low, "pvsm_max_resolution": 16 * low}


def table2(size, map_size, repeats, log):
    """Adaptive against one fixed map (the paper's 4096², here 4× the image side); speed = fixed's time /
    adaptive's (the paper's ratio of FPS)."""
    low, big, adaptive = _paper_scale(size)
    configs = [(f"fixed {big}²", big, {}), (f"adaptive ({low}² + tiles ≤ {big}²)", low, adaptive)]
    rows = _light_rows(size, map_size, repeats, log, (("small", 0.05), ("large", 2.0)), configs, "table2")
    for light in ("small", "large"):
        fixed, tiled = (r for r in rows if r["light"] == light)
        tiled["speed_vs_fixed"] = fixed["ms"] / max(tiled["ms"], 1e-9)
        fixed["speed_vs_fixed"] = 1.0
    return rows


def fig10(size, map_size, repeats, log):
    low, _, adaptive = _paper_scale(size)
    configs = [("adaptive", low, adaptive)]
    return _light_rows(size, map_size, repeats, log, (("point-like", 1e-3), ("area", 1.0)), configs, "fig10")


def rho_equal_time(size, map_size, repeats, log):
    """(time, error) over kernel caps for ρ_dynamic and the line; the line's error at the cubic's times."""
    snap = stress.plane_scene(name="plane_rho_time")
    snap = replace(snap, camera=replace(snap.camera, width=size, height=size))
    exact = plane_exact(ground_hits(snap.camera, size, size)[:, :, 0])
    ground = None
    curves = {}
    for metric in ("DYNAMIC", "LINEAR"):
        pts = []
        for cap in (8, 16, 32, 64, 128, 256):
            s = RenderSettings(technique="PVSM", shadow_map_size=map_size).with_(
                pvsm_resolution=metric, pvsm_weighting="UNIFORM", pvsm_cap=cap)
            r, ms = _render(snap, s, repeats)
            v = r.passes["Visibility"][..., 0]
            if ground is None:
                ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(snap, size)) < 1e-3
            m = ground & ((exact < 0.99) | (v < 0.99))
            pts.append({"metric": metric, "cap": cap, "filter_ms": float(r.timings.get("pvsm_filter", 0.0)),
                        "ms": ms, "mean_error": float(np.abs(v - exact)[m].mean())})
        curves[metric] = pts
    rows = []
    line = sorted(curves["LINEAR"], key=lambda p: p["filter_ms"])
    for p in curves["DYNAMIC"]:
        t = p["filter_ms"]
        lt, le = [q["filter_ms"] for q in line], [q["mean_error"] for q in line]
        inside = lt[0] <= t <= lt[-1]
        rows.append({**p, "linear_error_at_equal_time": float(np.interp(t, lt, le)) if inside else float("nan")})
        log(f"rho equal time, cap {p['cap']}: cubic {p['mean_error']:.4f} at {t:.0f} ms, line "
            f"{rows[-1]['linear_error_at_equal_time']:.4f}")
    return {"curves": curves, "cubic_vs_line": rows}


def rho_levels(size, map_size, repeats, log):
    snap = stress.plane_scene(name="plane_rho")
    snap = replace(snap, camera=replace(snap.camera, width=size, height=size))
    exact = plane_exact(ground_hits(snap.camera, size, size)[:, :, 0])
    rows = []
    for metric in ("NONE", "DYNAMIC", "STATIC", "LINEAR"):
        s = RenderSettings(technique="PVSM", shadow_map_size=map_size, collect_stats=True).with_(
            pvsm_resolution=metric, pvsm_weighting="UNIFORM", pvsm_cap=256)
        r, ms = _render(snap, s, repeats)
        v = r.passes["Visibility"][..., 0]
        ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(snap, size)) < 1e-3
        m = ground & ((exact < 0.99) | (v < 0.99))
        per = (r.stats.get("per_light") or [{}])[0]
        rows.append({"metric": metric, "mean_error": float(np.abs(v - exact)[m].mean()), "ms": ms,
                     "pvsm_filter_ms": float(r.timings.get("pvsm_filter", 0.0)),
                     "mean_level": per.get("mean_level"), "mean_cells": per.get("mean_count")})
        log(f"rho {metric}: mean {rows[-1]['mean_error']:.4f}, filter {rows[-1]['pvsm_filter_ms']:.0f} ms")
    return rows


def _table(rows, cols):
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append("| " + " | ".join(f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c]) for c in cols) + " |")
    return "\n".join(out)


def run(out: Path, size: int, map_size: int, repeats: int, log=print) -> dict:
    result = {"size": size, "map_size": map_size,
              "closed_form": closed_form(size, map_size, repeats, log),
              "antialiasing": antialiasing(size, map_size, repeats, log),
              "stages": stages(size, map_size, repeats, log),
              "rho": rho_levels(size, map_size, repeats, log),
              "rho_time": rho_equal_time(size, map_size, repeats, log),
              "table2": table2(size, map_size, repeats, log),
              "fig10": fig10(size, map_size, repeats, log)}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "pvsm_study.json", json.dumps(result, indent=2))
    md = [f"# PVSM study ({size}² image, {map_size}² map; adaptive: {map_size}² low-resolution map)", "",
          "## Closed form, parallel planes (uniform weights)", "",
          _table(result["closed_form"], ["antialiasing", "mean_error", "p99", "pixels", "ms"]), "",
          "## Anti-aliasing on thin bars: error against the box-filtered closed form", "",
          _table(result["antialiasing"], ["method", "mean_error", "max_error", "ms", "pvsm_filter_ms"]), "",
          "## Stages (ms, Table 1)", "", _table(result["stages"], list(result["stages"][0])), "",
          "## Resolution metric (kernel cap 256 so that only the metric picks coarser levels)", "",
          _table(result["rho"], ["metric", "mean_error", "ms", "pvsm_filter_ms", "mean_level", "mean_cells"]), "",
          "## ρ cubic against the line at equal time (kernel caps 8 … 256; the line's error interpolated at the "
          "cubic's filter time)", "",
          _table(result["rho_time"]["cubic_vs_line"], ["cap", "filter_ms", "mean_error",
                                                       "linear_error_at_equal_time"]), "",
          "## Table 2: adaptive tiles against one fixed map, the paper's proportions (parallel planes, error against "
          "the closed form)",
          "", _table(result["table2"], ["light", "light_size", "config", "ms", "speed_vs_fixed", "mean_error",
                                        "tiles", "tile_texels", "levels", "shadow_map_ms", "filter_ms"]), "",
          "## Fig. 10: point-like against area light (adaptive)", "",
          _table(result["fig10"], ["light", "light_size", "ms", "mean_error", "tiles", "tile_texels", "levels",
                                   "shadow_map_ms", "filter_ms"]), ""]
    write_atomic(out / "pvsm_study.md", "\n".join(md))
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m penumbra bench --study pvsm", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--size", type=int, default=64, help="image pixels per side (32×32 supersampling renders "
                    "32× that)")
    ap.add_argument("--map", type=int, default=1024, help="shadow-map texels")
    ap.add_argument("--repeats", type=int, default=1, help="timed renders per configuration (fastest kept)")
    args = ap.parse_args(argv)
    run(args.out, args.size, args.map, args.repeats, log=lambda s: print(s, file=sys.stderr, flush=True))
    print(f"wrote {args.out}/pvsm_study.md and pvsm_study.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
