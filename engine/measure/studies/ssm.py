"""The studies of Atty et al. 2006 §4.2 (and §5.2's timings) for the SSM technique, on our scenes against the
Cycles reference.

    python -m penumbra bench --study ssm --out DIR -- [--scenes plane suzanne] [--size 128] [--cycles-samples 64]

For each scene, one-pass and two-pass SSM (float32 accumulation) are compared with Cycles (mae_shadow:
mean |V − V_ref| over shadow and penumbra pixels, the paper's normalisation, §4.2.1) while one parameter
varies:
  map      occluder-map size 64 … 512 (§4.2.3; the paper finds no gain beyond ~200²)
  light    light size from point-like to as large as the occluder (§4.2.4)
  lateral  occluder moved sideways under the light (§4.2.5)
  vertical occluder from touching the receiver to almost touching the light (§4.2.6)
and the SSM time (its maps, scatter and projection stages, ms) is recorded beside every error (§5.2.2,
§5.2.3). The work budget is lifted so that every map size is really used. Each scene's Cycles noise floor
(the same mae_shadow of the reference itself against a NOISE_SPP_FACTOR× higher-spp Cycles render) is drawn
as a horizontal line on the map-size plot, whose error axis starts at 0, so a reader can judge whether
differences between map sizes matter. Writes DIR/ssm_study.json,
DIR/ssm_study.md and one PNG per plot, each file atomically (temporary name, then rename).

Needs bpy (scene variants and the Cycles reference; references are cached on disk).
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from ...core.arguments import CYCLES_SAMPLES_RANGE, Parser, add_alias, ranged
from ...core.files import write_atomic

MAP_SIZES = (64, 96, 128, 192, 256, 384, 512)
LIGHT_FRACTIONS = (0.01, 0.1, 0.25, 0.5, 0.75, 1.0)    # × the occluder's width
LATERAL = (-1.0, -0.5, 0.0, 0.5, 1.0)                   # metres, occluder centre relative to the light axis
VERTICAL = (0.0, 0.25, 0.5, 0.75, 0.9, 0.97)            # gap fraction: 0 touches the receiver, 1 the light
STUDY_MAP = 128                                         # the paper's bitmap for §4.2.4–4.2.6
PASSES = ("ONE", "TWO")
OCCLUDER = {"plane": "Occluder", "suzanne": "Suzanne"}
SSM_STAGES = ("ssm_maps", "ssm_scatter", "ssm_project")
NOISE_SPP_FACTOR = 4                                    # the noise floor's better reference: 4× the samples


def _world_bounds(obj):
    from mathutils import Vector
    pts = np.array([list(obj.matrix_world @ Vector(c)) for c in obj.bound_box])
    return pts.min(axis=0), pts.max(axis=0)


def _variant(name: str, size: int, *, light_fraction=None, lateral=None, vertical=None):
    """Build scene `name` and apply one change; returns (scene, parameter value actually set)."""
    import bpy
    from .. import scenes
    sc = scenes.build(name, resolution=(size, size))
    occ = sc.objects[OCCLUDER[name]]
    light = sc.objects[scenes.LIGHT_NAME]
    lo, hi = _world_bounds(occ)
    width = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    value = None
    if light_fraction is not None:
        light.data.size = max(light_fraction * width, 1e-3)
        value = float(light.data.size)
    if lateral is not None:
        occ.location.x += lateral
        value = float(lateral)
    if vertical is not None:
        # Occluder bottom from 1 cm above the ground (touching) to 1 cm below the light (almost touching).
        top_room = float(light.location.z) - 0.01
        lo_z, hi_z = float(lo[2]), float(hi[2])
        bottom = 0.01 + vertical * max(top_room - (hi_z - lo_z) - 0.01, 0.0)
        occ.location.z += bottom - lo_z
        value = float(vertical)
    bpy.context.view_layer.update()
    return sc, value


def _measure(sc, settings_list, samples: int, repeats: int):
    """Cycles reference once, then every settings: (metrics, SSM ms, total ms, stats) per settings."""
    import bpy
    from .. import metrics, reference
    from ...render import pipeline
    from ...blender.extract import extract
    ref = reference.cycles_visibility(sc, samples=samples)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    rows = []
    for settings in settings_list:
        best = None
        for _ in range(repeats):
            r = pipeline.render(snap, settings, stage_times=True)
            ms = sum(r.timings.get(k, 0.0) for k in SSM_STAGES)
            if best is None or ms < best[1]:
                best = (r, ms)
        r, ms = best
        m = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
        rows.append({"mae_shadow": m["mae_shadow"], "mae": m["mae"], "n_shadow": m["n_shadow"],
                     "ssm_ms": ms, "total_ms": r.total_ms, "stats": {k: v for k, v in r.stats.items()
                                                                      if k.startswith("ssm")},
                     "warnings": [w for w in r.warnings if w.startswith("SSM")]})
    return rows


def noise_floor(sc, samples: int) -> dict:
    """mae_shadow of the `samples`-spp Cycles reference against a NOISE_SPP_FACTOR× higher-spp one: the error
    a perfect technique would still show against the reference (both renders cached)."""
    from .. import metrics, reference
    ref = reference.cycles_visibility(sc, samples=samples)
    better = reference.cycles_visibility(sc, samples=samples * NOISE_SPP_FACTOR)
    m = metrics.compare(ref.visibility, better.visibility, ref.mask & better.mask)
    return {"mae_shadow": m["mae_shadow"], "n_shadow": m["n_shadow"], "samples": samples * NOISE_SPP_FACTOR}


def run(out: Path, scene_names=("plane", "suzanne"), size: int = 128, samples: int = 64, repeats: int = 1,
        map_sizes=MAP_SIZES, light_fractions=LIGHT_FRACTIONS, lateral=LATERAL, vertical=VERTICAL,
        log=print) -> dict:
    from ...core.settings import RenderSettings
    base = RenderSettings(technique="SSM").with_(ssm_budget=1.0e5, ssm_precision="FLOAT32")
    results = {"size": size, "samples": samples, "scenes": list(scene_names), "studies": {}}
    studies = results["studies"]
    t0 = time.time()
    for name in scene_names:
        # §4.2.3 error and §5.2.2 time vs occluder-map size: one reference, every size × passes.
        sc, _ = _variant(name, size)
        configs = [(n, p) for n in map_sizes for p in PASSES]
        rows = _measure(sc, [base.with_(ssm_map_size=n, ssm_passes=p) for n, p in configs], samples, repeats)
        results.setdefault("noise_floor", {})[name] = noise_floor(sc, samples)
        for (n, p), row in zip(configs, rows):
            studies.setdefault("map", []).append({"scene": name, "passes": p, "x": n, **row})
        log(f"[{time.time() - t0:6.0f}s] {name}: map sizes done")
        for key, values, kwarg in (("light", light_fractions, "light_fraction"), ("lateral", lateral, "lateral"),
                                   ("vertical", vertical, "vertical")):
            for value in values:
                sc, x = _variant(name, size, **{kwarg: value})
                rows = _measure(sc, [base.with_(ssm_map_size=STUDY_MAP, ssm_passes=p) for p in PASSES],
                                samples, repeats)
                for p, row in zip(PASSES, rows):
                    studies.setdefault(key, []).append({"scene": name, "passes": p, "x": x, **row})
            log(f"[{time.time() - t0:6.0f}s] {name}: {key} done")
    results["seconds"] = time.time() - t0
    write(out, results)
    return results


PLOTS = (
    ("map", "mae_shadow", "Occluder map size (texels per side)", "mean |V − V_Cycles| (shadow+penumbra)",
     "error_vs_map_size.png", "§4.2.3 error vs occluder-map size"),
    ("light", "mae_shadow", "Light size (m)", "mean |V − V_Cycles| (shadow+penumbra)",
     "error_vs_light_size.png", "§4.2.4 error vs light size (128² map)"),
    ("lateral", "mae_shadow", "Occluder lateral offset (m)", "mean |V − V_Cycles| (shadow+penumbra)",
     "error_vs_lateral.png", "§4.2.5 error vs lateral occluder position (128² map)"),
    ("vertical", "mae_shadow", "Occluder height (0 = on the receiver, 1 = at the light)",
     "mean |V − V_Cycles| (shadow+penumbra)", "error_vs_vertical.png",
     "§4.2.6 error vs vertical occluder position (128² map)"),
    ("map", "ssm_ms", "Occluder map size (texels per side)", "SSM time (ms, maps + scatter + projection)",
     "time_vs_map_size.png", "§5.2.2 time vs occluder-map size"),
    ("light", "ssm_ms", "Light size (m)", "SSM time (ms, maps + scatter + projection)",
     "time_vs_light_size.png", "§5.2.3 time vs light size (128² map)"),
)


def figure(results: dict, key: str, metric: str, xlabel: str, ylabel: str, title: str):
    """The matplotlib figure of one PLOTS entry (None without rows): one line per scene and passes; error
    axes start at 0, and the map-size error plot draws each scene's Cycles noise floor."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = results["studies"].get(key, [])
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for i, scene in enumerate(results["scenes"]):
        for passes, style in (("ONE", "o-"), ("TWO", "s--")):
            pts = sorted((r["x"], r[metric]) for r in rows if r["scene"] == scene and r["passes"] == passes)
            if pts:
                ax.plot(*zip(*pts), style, label=f"{scene}, {passes.lower()} pass")
        floor = (results.get("noise_floor") or {}).get(scene)
        if key == "map" and metric == "mae_shadow" and floor and floor.get("mae_shadow") is not None \
                and math.isfinite(floor["mae_shadow"]):
            ax.axhline(floor["mae_shadow"], color=f"C{2 * i}", linestyle=":", linewidth=1.2,
                       label=f"{scene}: Cycles noise floor ({results['samples']} vs {floor['samples']} spp)")
    if metric == "mae_shadow":
        ax.set_ylim(bottom=0.0)     # from 0: differences of 1e-5 must not fill the plot's height
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def write(out: Path, results: dict) -> None:
    import io
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    for key, metric, xlabel, ylabel, filename, title in PLOTS:
        fig = figure(results, key, metric, xlabel, ylabel, title)
        if fig is None:
            continue
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
        plt.close(fig)
        write_atomic(out / filename, buf.getvalue())
    write_atomic(out / "ssm_study.json", json.dumps(results, indent=1, default=float).encode())
    write_atomic(out / "ssm_study.md", markdown(results).encode())


def markdown(results: dict) -> str:
    lines = [f"# SSM studies (Atty et al. 2006 §4.2, §5.2) — {results['size']}² images, Cycles "
             f"{results['samples']} spp", ""]
    names = {"map": "occluder-map size", "light": "light size (m)", "lateral": "lateral offset (m)",
             "vertical": "vertical position (0 receiver … 1 light)"}
    floors = results.get("noise_floor") or {}
    if floors:
        lines += ["Cycles noise floor (mae_shadow of the reference against a render with more samples):", ""]
        lines += [f"- {scene}: {f['mae_shadow']:.4f} ({results['samples']} vs {f['samples']} spp, "
                  f"{f['n_shadow']} px)" for scene, f in floors.items()]
        lines.append("")
    for key, label in names.items():
        rows = results["studies"].get(key, [])
        if not rows:
            continue
        lines += [f"## Error and time vs {label}", "",
                  "| scene | x | one-pass mae_shadow | two-pass mae_shadow | one-pass ms | two-pass ms |",
                  "|---|---|---|---|---|---|"]
        for scene in results["scenes"]:
            xs = sorted({r["x"] for r in rows if r["scene"] == scene})
            for x in xs:
                one = next(r for r in rows if r["scene"] == scene and r["x"] == x and r["passes"] == "ONE")
                two = next(r for r in rows if r["scene"] == scene and r["x"] == x and r["passes"] == "TWO")
                lines.append(f"| {scene} | {x:g} | {one['mae_shadow']:.4f} | {two['mae_shadow']:.4f} | "
                             f"{one['ssm_ms']:.0f} | {two['ssm_ms']:.0f} |")
        lines.append("")
    lines.append(f"Total study time: {results.get('seconds', math.nan):.0f} s.")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = Parser(prog="python -m penumbra bench --study ssm", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--scenes", nargs="+", default=["plane", "suzanne"], choices=sorted(OCCLUDER))
    ap.add_argument("--size", type=int, default=128, help="image pixels per side")
    add_alias(ap, "--samples", ap.add_argument("--cycles-samples", type=ranged(int, *CYCLES_SAMPLES_RANGE),
                                               default=64, help="Cycles samples of the reference"))
    ap.add_argument("--repeats", type=int, default=1, help="renders per configuration (fastest kept)")
    ap.add_argument("--map-sizes", type=int, nargs="+", default=list(MAP_SIZES))
    args = ap.parse_args(argv)
    run(args.out, tuple(args.scenes), args.size, args.cycles_samples, args.repeats, tuple(args.map_sizes),
        log=lambda s: print(s, file=sys.stderr, flush=True))
    print(f"wrote {args.out}/ssm_study.md, ssm_study.json and plots")
    return 0


if __name__ == "__main__":
    sys.exit(main())
