"""Quality scalability study: Schwarz & Stamminger 2008 ("Quality Scalability of Soft Shadow Mapping") inside
BACKPROJECTION, on the built-in scenes against Cycles.

* Table 1: build time and memory of the HSM, MSSM and YSM at 1024² and 2048² (paper: 10.67 / 88 / 14.67 and
  42.67 / 384 / 46.67 MiB for RG32F);
* Table 2: budgets ∞ / 12 / 9 / 5 / border 12→5 — frame time relative to ∞, share of backprojecting pixels,
  mean ± sd micro-occluders per such pixel, mae_shadow;
* the extra micro-occluders blending costs (paper: about 30 %), and a seam metric across neighbouring pixels
  whose integer level differs, without and with blending;
* micropatches, microrects and microquads at forced coarse levels: signed bias and mae_shadow;
* PNG plots: mae_shadow and time against the budget, bias against the forced level.

    python -m penumbra bench --study quality-scalability --out DIR -- [--scenes suzanne,balls,plane]
        [--size 128] [--map 1024] [--repeats 3] [--cycles-samples 256] [--small]

`--small`: CI-speed smoke run (one scene, 64² image, 256² map, Table 1 at 256²/512², one repeat).
Writes DIR/quality_scalability.md, .json and the PNGs atomically.
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np

from .. import metrics, reference
from ...core.arguments import CYCLES_SAMPLES_RANGE, Parser, add_alias, ranged
from ...core.files import write_atomic
from ...core.settings import RenderSettings
from ...render import pipeline
from .backprojection import timed

BP = "BACKPROJECTION"
# The 2008 configuration the budget rows vary (blending and the over-precision fix on, as in the paper).
PAPER = {"bp_blend": True, "bp_query_growth": True, "bp_refinement": "YSM", "bp_primitive": "MICRORECT"}
BUDGETS = (("∞", {"bp_budget_map": "UNBOUNDED"}), ("12", {"bp_budget": 12}), ("9", {"bp_budget": 9}),
           ("5", {"bp_budget": 5}), ("border 12→5", {"bp_budget_map": "BORDER", "bp_budget": 12,
                                                       "bp_budget_border": 5}))
PRIMITIVES = ("MICROPATCH", "MICRORECT", "MICROQUAD")
TABLE1_PAPER = {1024: {"HSM": 10.67, "MSSM": 88.0, "YSM": 14.67}, 2048: {"HSM": 42.67, "MSSM": 384.0, "YSM": 46.67}}


def seam_metric(v, v_ref, level, active) -> float:
    """Mean |ΔV − ΔV_ref| over 4-neighbour pixel pairs, both `active` (backprojecting), whose integer level
    differs: the visibility step a level change adds beyond the reference's own gradient. NaN without such
    pairs."""
    lv = np.floor(np.asarray(level) + 1e-6)
    errs = []
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(0, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        pair = active[a] & active[b] & (lv[a] != lv[b])
        d = (v[a] - v[b]) - (v_ref[a] - v_ref[b])
        errs.append(np.abs(d[pair]))
    e = np.concatenate(errs)
    return float(e.mean()) if e.size else float("nan")


def signed_bias(v, v_ref, mask) -> float:
    """Mean V − V_ref over the shadow pixels (mae_shadow's set): negative = occluders overestimated."""
    sel = mask & np.isfinite(v) & np.isfinite(v_ref) & ((v < metrics.SHADOW_LEVEL) | (v_ref < metrics.SHADOW_LEVEL))
    return float((v - v_ref)[sel].mean()) if sel.any() else float("nan")


def _run(snap, settings, repeats):
    """(ms, visibility, per-light stats of light 0, debug level map, class map)."""
    ms, r = timed(snap, settings, repeats)
    d = pipeline.render(snap, settings.with_(collect_stats=True, debug_passes=True))
    st = (d.stats.get("per_light") or [{}])[0]
    level = d.passes["BP Level"][..., 0] if "BP Level" in d.passes else np.zeros(r.passes["Visibility"].shape[:2])
    cls = d.passes["BP Class"] if "BP Class" in d.passes else None
    active = cls[..., 2] > 0.5 if cls is not None else np.zeros(level.shape, bool)
    return ms, r.passes["Visibility"][..., 0], st, level, active


def table1(sizes, repeats: int, log) -> list[dict]:
    """Build time (stage timings, median) and memory (structure_bytes) of HSM, MSSM and YSM per map size."""
    from ..stress import plane_scene
    snap = plane_scene()
    rows = []
    for n in sizes:
        row = {"map": n}
        for refine, stage, key in (("HSM", "bp_hsm", "hsm"), ("MSSM", "bp_mssm", "mssm"), ("YSM", "bp_ysm", "ysm")):
            s = RenderSettings(technique=BP, shadow_map_size=n).with_(bp_refinement=refine)
            pipeline.render(snap, s)
            runs = [pipeline.render(snap, s) for _ in range(max(1, repeats))]
            row[refine] = {"ms": float(np.median([r.timings.get(stage, float("nan")) for r in runs])),
                           "mib": runs[0].stats["structure_bytes"].get(key, 0) / float(1 << 20),
                           "paper_mib": TABLE1_PAPER.get(n, {}).get(refine)}
        rows.append(row)
        log(f"table 1 {n}²: " + ", ".join(f"{k} {row[k]['ms']:.1f} ms {row[k]['mib']:.2f} MiB"
                                          for k in ("HSM", "MSSM", "YSM")))
    return rows


def study_scene(name, size, map_size, repeats, samples, log) -> dict:
    import bpy
    from .. import scenes
    from ...blender.extract import extract
    sc = scenes.build(name, resolution=(size, size))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    ref = reference.cycles_visibility(sc, samples=samples)
    vref, mask = ref.visibility, ref.mask
    base = RenderSettings(technique=BP, shadow_map_size=map_size).with_(**PAPER)
    out = {"scene": name, "size": size, "map": map_size, "budgets": [], "blending": [], "primitives": []}
    # Table 2.
    t_inf = None
    for label, cfg in BUDGETS:
        ms, v, st, _, _ = _run(snap, base.with_(**cfg), repeats)
        t_inf = ms if t_inf is None else t_inf
        m = metrics.compare(v, vref, mask)
        row = {"budget": label, "ms": ms, "time_rel": ms / t_inf, "share_backprojected": st.get("share_backprojected"),
               "mean_count": st.get("mean_count"), "std_count": st.get("std_count"), "mae_shadow": m["mae_shadow"]}
        out["budgets"].append(row)
        log(f"{name} b={label}: {ms:.0f} ms ({row['time_rel']:.2f}×), backprojecting "
            f"{row['share_backprojected']:.3f}, {row['mean_count']:.0f} ± {row['std_count']:.0f}, "
            f"mae_shadow {m['mae_shadow']:.4f}")
    # Blending: cost and seams (pairs taken from the unblended integer levels).
    for label, cfg in BUDGETS[1:]:
        ms0, v0, st0, lev0, act0 = _run(snap, base.with_(**cfg, bp_blend=False), repeats)
        ms1, v1, st1, _, act1 = _run(snap, base.with_(**cfg, bp_blend=True), repeats)
        n0 = st0.get("mean_count", 0) * st0.get("backprojected", 0)
        n1 = st1.get("mean_count", 0) * st1.get("backprojected", 0)
        row = {"budget": label, "ms_unblended": ms0, "ms_blended": ms1,
               "extra_occluders": n1 / n0 - 1.0 if n0 else float("nan"),
               "seam_unblended": seam_metric(v0, vref, lev0, act0 & mask),
               "seam_blended": seam_metric(v1, vref, lev0, act0 & mask),
               "mae_unblended": metrics.compare(v0, vref, mask)["mae_shadow"],
               "mae_blended": metrics.compare(v1, vref, mask)["mae_shadow"]}
        out["blending"].append(row)
        log(f"{name} blending b={label}: +{100 * row['extra_occluders']:.0f} % micro-occluders, seam "
            f"{row['seam_unblended']:.4f} → {row['seam_blended']:.4f}")
    # Occluder approximations at forced coarse levels (bitmask, same search area; no blending).
    for level in (1, 2, 3):
        for prim in PRIMITIVES:
            s = base.with_(bp_primitive=prim, bp_force_level=level, bp_blend=False)
            ms, v, _, _, _ = _run(snap, s, 1)
            m = metrics.compare(v, vref, mask)
            out["primitives"].append({"level": level, "primitive": prim, "ms": ms, "mae_shadow": m["mae_shadow"],
                                      "bias": signed_bias(v, vref, mask)})
            log(f"{name} level {level} {prim}: bias {out['primitives'][-1]['bias']:+.4f}, mae {m['mae_shadow']:.4f}")
    return out


def plots(results: dict, out_dir: str) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    written = []
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    for sc in results["scenes"]:
        labels = [r["budget"] for r in sc["budgets"]]
        axes[0].plot(labels, [r["mae_shadow"] for r in sc["budgets"]], "o-", label=sc["scene"])
        axes[1].plot(labels, [r["time_rel"] for r in sc["budgets"]], "o-", label=sc["scene"])
    axes[0].set_title("mae_shadow by budget b_mo")
    axes[1].set_title("frame time relative to b = ∞")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(out_dir, "qs_budget.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    written.append(path)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for prim, style in zip(PRIMITIVES, ("o-", "s-", "^-")):
        for sc in results["scenes"]:
            rows = [r for r in sc["primitives"] if r["primitive"] == prim]
            ax.plot([r["level"] for r in rows], [r["bias"] for r in rows], style, label=f"{sc['scene']} {prim.lower()}")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("forced level")
    ax.set_ylabel("signed bias V − V_ref")
    ax.legend(fontsize=6)
    fig.tight_layout()
    path = os.path.join(out_dir, "qs_primitives.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    written.append(path)
    return written


def markdown(results: dict) -> str:
    lines = ["# Quality scalability study (Schwarz & Stamminger 2008)", "",
             f"Budget rows use {PAPER} (b = ∞: level 0, no blending).", ""]
    if results.get("table1"):
        lines += ["## Table 1: acceleration structures (RG32F)", "",
                  "| map | HSM ms | HSM MiB | MSSM ms | MSSM MiB | YSM ms | YSM MiB | paper MiB (HSM/MSSM/YSM) |",
                  "|---:|---:|---:|---:|---:|---:|---:|---|"]
        for r in results["table1"]:
            paper = "/".join(f"{r[k]['paper_mib']:g}" for k in ("HSM", "MSSM", "YSM")) if r["HSM"]["paper_mib"] else ""
            lines.append(f"| {r['map']}² | " + " | ".join(f"{r[k]['ms']:.1f} | {r[k]['mib']:.2f}"
                                                      for k in ("HSM", "MSSM", "YSM")) + f" | {paper} |")
        lines.append("")
    for sc in results["scenes"]:
        lines += [f"## {sc['scene']} — {sc['size']}² image, {sc['map']}² map", "",
                  "### Table 2: budgets", "",
                  "| b_mo | time ms | rel. to ∞ | backprojecting | micro-occluders (mean ± sd) | mae_shadow |",
                  "|---|---:|---:|---:|---:|---:|"]
        lines += [f"| {r['budget']} | {r['ms']:.0f} | {r['time_rel']:.2f} | {r['share_backprojected']:.3f} | "
                  f"{r['mean_count']:.0f} ± {r['std_count']:.0f} | {r['mae_shadow']:.4f} |" for r in sc["budgets"]]
        lines += ["", "### Blending: cost and seams", "",
                  "| b_mo | extra micro-occluders | seam unblended | seam blended | mae unblended | mae blended | "
                  "ms unblended | ms blended |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
        lines += [f"| {r['budget']} | {100 * r['extra_occluders']:+.0f} % | {r['seam_unblended']:.4f} | "
                  f"{r['seam_blended']:.4f} | {r['mae_unblended']:.4f} | {r['mae_blended']:.4f} | "
                  f"{r['ms_unblended']:.0f} | {r['ms_blended']:.0f} |" for r in sc["blending"]]
        lines += ["", "### Occluder approximations at forced levels", "",
                  "| level | primitive | signed bias | mae_shadow | ms |", "|---:|---|---:|---:|---:|"]
        lines += [f"| {r['level']} | {r['primitive'].lower()} | {r['bias']:+.4f} | {r['mae_shadow']:.4f} | "
                  f"{r['ms']:.0f} |" for r in sc["primitives"]]
        lines.append("")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = Parser(prog="python -m penumbra bench --study quality-scalability", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenes", default="suzanne,balls,plane")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--map", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    add_alias(ap, "--samples", ap.add_argument("--cycles-samples", type=ranged(int, *CYCLES_SAMPLES_RANGE),
                                               default=256, help="Cycles reference samples"))
    ap.add_argument("--small", action="store_true", help="CI-speed smoke run")
    args = ap.parse_args(argv)
    if args.small:
        args.scenes, args.size, args.map, args.repeats, args.cycles_samples = "suzanne", 64, 256, 1, 64
    os.makedirs(args.out, exist_ok=True)

    def log(text):
        print(text, file=sys.stderr, flush=True)

    results = {"args": vars(args), "scenes": []}
    results["table1"] = table1((256, 512) if args.small else (1024, 2048), args.repeats, log)
    for name in [s for s in args.scenes.split(",") if s]:
        results["scenes"].append(study_scene(name, args.size, args.map, args.repeats, args.cycles_samples, log))
    results["plots"] = plots(results, args.out)
    write_atomic(os.path.join(args.out, "quality_scalability.json"), json.dumps(results, indent=1, default=str))
    write_atomic(os.path.join(args.out, "quality_scalability.md"), markdown(results))
    print(markdown(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
