"""BACKPROJECTION study: the columns of Schwarz & Stamminger 2007's Tables 2 and 3 on the built-in scenes.

Per scene and settings combination: frame time (median of timed frames after a warm-up), share of the lit
pixels that backproject (neither proven lit nor umbra), mean and spread of micro-occluders per such pixel,
the hierarchy level used, and the error against the Cycles reference (mae_shadow, rmse, pixel_match). The
HSM/MSSM build times per map size (Table 2) and the default setting's frame time at 512² output with a
1024² map, with HARD's time and Cycles' time at equal error, close the report.

    python -m penumbra bench --study backprojection --out DIR -- [--scenes balls,silhouette,suzanne]
        [--size 128] [--map 1024] [--repeats 3] [--cycles-samples 256] [--no-perf] [--quick]

Writes DIR/backprojection_study.md (and .json) atomically.
"""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

from .. import metrics, reference
from ...render import pipeline
from ...core.arguments import CYCLES_SAMPLES_RANGE, Parser, add_alias, ranged
from ...core.files import write_atomic
from ...core.settings import RenderSettings

# The 2007 paper's configuration (the technique's own defaults now include the 2008 paper's blending and YSM).
DEFAULT = {"bp_accumulation": "BITMASK_16J", "bp_primitive": "MICROPATCH", "bp_refinement": "MSSM", "bp_budget": 16,
           "bp_blend": False, "bp_query_growth": False, "bp_layers": 1}


def combinations(quick: bool = False) -> list[dict]:
    """Table 3's rows × {HSM, MSSM}, then the other knobs one at a time around the default."""
    rows = []
    table3 = [("AREA", "MICROPATCH"), ("AREA", "MICROQUAD"), ("BITMASK_8", "MICROPATCH"),
              ("BITMASK_16", "MICROPATCH"), ("BITMASK_16J", "MICROPATCH"), ("BITMASK_32", "MICROPATCH"),
              ("BITMASK_16J", "MICROQUAD")]
    if quick:
        table3 = [("AREA", "MICROPATCH"), ("BITMASK_16J", "MICROPATCH"), ("BITMASK_16J", "MICROQUAD")]
    for refine in ("HSM", "MSSM"):
        for acc, prim in table3:
            rows.append({**DEFAULT, "bp_accumulation": acc, "bp_primitive": prim, "bp_refinement": refine})
    extra = [{"bp_refinement": "NONE"}, {"bp_layers": 2}, {"bp_filter_passes": 5}, {"bp_gap_fill": False},
             {"bp_budget": 8}, {"bp_budget": 32}]
    if quick:
        extra = [{"bp_layers": 2}, {"bp_budget": 32}]
    rows += [{**DEFAULT, **e} for e in extra]
    return rows


def label(cfg: dict) -> str:
    short = {"MICROPATCH": "patch", "MICROQUAD": "quad", "AREA": "area", "BITMASK_8": "bits8",
             "BITMASK_16": "bits16", "BITMASK_16J": "bits16j", "BITMASK_32": "bits32"}
    parts = [short.get(cfg["bp_accumulation"]), short.get(cfg["bp_primitive"]), cfg["bp_refinement"],
             f"b={cfg['bp_budget']}"]
    for k, name in (("bp_layers", "layers"), ("bp_filter_passes", "filter"), ("bp_gap_fill", "gapfill")):
        if k in cfg:
            parts.append(f"{name}={cfg[k]}")
    return " ".join(str(p) for p in parts)


def timed(snap, settings, repeats: int):
    pipeline.render(snap, settings)                         # warm-up: shader compilation, first uploads
    times, result = [], None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        result = pipeline.render(snap, settings, stage_times=True)
        times.append((time.perf_counter() - t0) * 1000.0)
    return float(np.median(times)), result


def bp_stats(snap, settings):
    per_light = pipeline.render(snap, settings.with_(collect_stats=True)).stats.get("per_light", [])
    return per_light[0] if per_light else {}


def study_scene(name: str, size: int, map_size: int, repeats: int, samples: int, quick: bool, log) -> dict:
    import bpy
    from .. import scenes
    from ...blender.extract import extract
    sc = scenes.build(name, resolution=(size, size))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    ref = reference.cycles_visibility(sc, samples=samples)
    rows = []
    base = RenderSettings(technique="BACKPROJECTION", shadow_map_size=map_size)
    for tech in ("HARD", "PCSS"):
        ms, r = timed(snap, RenderSettings(technique=tech, shadow_map_size=map_size), repeats)
        m = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
        rows.append({"config": tech, "time_ms": ms, **{k: m[k] for k in ("mae_shadow", "rmse", "pixel_match")}})
    for cfg in combinations(quick):
        settings = base.with_(**cfg)
        ms, r = timed(snap, settings, repeats)
        m = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
        st = bp_stats(snap, settings)
        row = {"config": label(cfg), "settings": cfg, "time_ms": ms,
               "stages_ms": {k: v for k, v in r.timings.items() if k.startswith("bp_")},
               **{k: m[k] for k in ("mae_shadow", "rmse", "pixel_match")},
               **{k: st.get(k, float("nan")) for k in ("share_backprojected", "share_lit", "share_umbra",
                                                        "mean_count", "std_count", "mean_level")}}
        rows.append(row)
        log(f"{name}: {row['config']}: {ms:.0f} ms, mae_shadow {m['mae_shadow']:.4f}, "
            f"backprojected {row['share_backprojected']:.3f}")
    return {"scene": name, "size": size, "map": map_size, "reference_samples": samples, "rows": rows}


def build_times(sizes=(256, 512, 1024, 2048), repeats: int = 3, log=print) -> list[dict]:
    """Table 2: HSM and MSSM construction time per depth-map size (a suzanne map; timing stages)."""
    import bpy
    from .. import scenes
    from ...blender.extract import extract
    sc = scenes.build("suzanne", resolution=(64, 64))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    out = []
    for n in sizes:
        row = {"map": n}
        for refine, stage in (("HSM", "bp_hsm"), ("MSSM", "bp_mssm")):
            settings = RenderSettings(technique="BACKPROJECTION", shadow_map_size=n).with_(bp_refinement=refine)
            pipeline.render(snap, settings)
            vals = [pipeline.render(snap, settings, stage_times=True).timings.get(stage, float("nan")) for _ in range(repeats)]
            row[refine] = float(np.median(vals))
        out.append(row)
        log(f"build {n}²: HSM {row['HSM']:.1f} ms, MSSM {row['MSSM']:.1f} ms")
    return out


def perf(scene_name: str = "suzanne", size: int = 512, map_size: int = 1024, repeats: int = 3,
         ref_samples: int = 256, cycles_samples=(1, 2, 4, 8, 16, 32, 64), log=print) -> dict:
    """The default setting at 512² output with a 1024² map: its frame time, HARD's, and the time of the
    cheapest Cycles render whose mae_shadow is no worse (equal error)."""
    import bpy
    from .. import scenes
    from ...blender.extract import extract
    sc = scenes.build(scene_name, resolution=(size, size))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    ref = reference.cycles_visibility(sc, samples=ref_samples)
    ours_ms, r = timed(snap, RenderSettings(technique="BACKPROJECTION", shadow_map_size=map_size)
                       .with_(**DEFAULT), repeats)
    ours = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
    hard_ms, rh = timed(snap, RenderSettings(technique="HARD", shadow_map_size=map_size), repeats)
    hard = metrics.compare(rh.passes["Visibility"][..., 0], ref.visibility, ref.mask)
    cycles = []
    equal = None
    for spp in cycles_samples:
        peer = reference.cycles_visibility(sc, samples=spp, seed=7, use_cache=False, per_light=False)
        m = metrics.compare(peer.visibility, ref.visibility, ref.mask)
        cycles.append({"samples": spp, "time_ms": peer.seconds * 500.0, "mae_shadow": m["mae_shadow"]})
        log(f"cycles {spp} spp: {peer.seconds * 500.0:.0f} ms (half the shadowed/unshadowed pair), "
            f"mae_shadow {m['mae_shadow']:.4f}")
        if m["mae_shadow"] <= ours["mae_shadow"]:
            equal = cycles[-1]
            break
    out = {"scene": scene_name, "size": size, "map": map_size, "default_ms": ours_ms,
           "default_mae_shadow": ours["mae_shadow"], "hard_ms": hard_ms, "hard_mae_shadow": hard["mae_shadow"],
           "stages_ms": r.timings, "cycles": cycles, "cycles_equal_error": equal,
           "ratio_to_hard": ours_ms / hard_ms if hard_ms else float("nan"),
           "ratio_to_cycles": ours_ms / equal["time_ms"] if equal else float("nan")}
    log(f"perf: default {ours_ms:.0f} ms (mae {ours['mae_shadow']:.4f}), HARD {hard_ms:.0f} ms, "
        f"Cycles at equal error {equal}")
    return out


def markdown(results: dict) -> str:
    lines = ["# BACKPROJECTION study (Schwarz & Stamminger 2007, Tables 2–3 columns)", ""]
    for sc in results["scenes"]:
        lines += [f"## {sc['scene']} — {sc['size']}² image, {sc['map']}² map, Cycles {sc['reference_samples']} spp",
                  "", "| setting | time ms | backprojecting | lit | umbra | micro-occluders (mean ± sd) | level |"
                  " mae_shadow | rmse | pixel_match |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for r in sc["rows"]:
            if "share_backprojected" in r:
                lines.append(f"| {r['config']} | {r['time_ms']:.0f} | {r['share_backprojected']:.3f} | "
                             f"{r['share_lit']:.3f} | {r['share_umbra']:.3f} | {r['mean_count']:.0f} ± "
                             f"{r['std_count']:.0f} | {r['mean_level']:.2f} | {r['mae_shadow']:.4f} | "
                             f"{r['rmse']:.4f} | {r['pixel_match']:.3f} |")
            else:
                lines.append(f"| {r['config']} | {r['time_ms']:.0f} | | | | | | {r['mae_shadow']:.4f} | "
                             f"{r['rmse']:.4f} | {r['pixel_match']:.3f} |")
        lines.append("")
    if results.get("build"):
        lines += ["## Hierarchy construction (Table 2), ms", "", "| map | HSM | MSSM |", "|---:|---:|---:|"]
        lines += [f"| {b['map']}² | {b['HSM']:.1f} | {b['MSSM']:.1f} |" for b in results["build"]]
        lines.append("")
    p = results.get("perf")
    if p:
        eq = p["cycles_equal_error"]
        lines += [f"## Default setting at {p['size']}² output, {p['map']}² map ({p['scene']})", "",
                  f"* BACKPROJECTION default: {p['default_ms']:.0f} ms, mae_shadow {p['default_mae_shadow']:.4f}",
                  f"* HARD: {p['hard_ms']:.0f} ms (mae_shadow {p['hard_mae_shadow']:.4f}); ratio "
                  f"{p['ratio_to_hard']:.1f}×",
                  "* Cycles at equal error: " + (f"{eq['samples']} spp, {eq['time_ms']:.0f} ms; ratio "
                                                 f"{p['ratio_to_cycles']:.2f}×" if eq else
                                                 "no sample count tried reached our error"), ""]
        lines += ["| Cycles spp | time ms | mae_shadow |", "|---:|---:|---:|"]
        lines += [f"| {c['samples']} | {c['time_ms']:.0f} | {c['mae_shadow']:.4f} |" for c in p["cycles"]]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = Parser(prog="python -m penumbra bench --study backprojection",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenes", default="balls,silhouette,suzanne")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--map", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    add_alias(ap, "--samples", ap.add_argument("--cycles-samples", type=ranged(int, *CYCLES_SAMPLES_RANGE),
                                               default=256, help="Cycles reference samples"))
    ap.add_argument("--quick", action="store_true", help="fewer combinations")
    ap.add_argument("--no-perf", action="store_true", help="skip the 512² performance run and Table 2")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)

    def log(text):
        print(text, file=sys.stderr, flush=True)

    results = {"scenes": []}
    for name in [s for s in args.scenes.split(",") if s]:
        results["scenes"].append(study_scene(name, args.size, args.map, args.repeats, args.cycles_samples,
                                             args.quick, log))
    if not args.no_perf:
        results["build"] = build_times(log=log)
        results["perf"] = perf(log=log)
    write_atomic(os.path.join(args.out, "backprojection_study.json"), json.dumps(results, indent=1, default=str))
    write_atomic(os.path.join(args.out, "backprojection_study.md"), markdown(results))
    print(markdown(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
