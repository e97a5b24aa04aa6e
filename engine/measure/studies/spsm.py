"""The measurements of Lecocq et al. 2014 (sub-pixel shadow maps) for SPSM against HARD, on our scenes against
Cycles with a 1 cm light (hard shadows; the light's size set on every scene).

    python -m penumbra bench --study spsm --out DIR -- [--scenes suzanne contact thin grazing city]
        [--size 128] [--samples 64] [--map-sizes 512 1024 2048 4096] [--repeats 2]

Per scene and map size, HARD and SPSM (defaults: n = 5 quantiser, recovery, 8 edge samples):
  pixel_match      share of pixels on the same side of 0.5 as Cycles (the paper's Fig. 12 measure)
  mismatched       the number of pixels that are not
  boundary_rate    mismatched share of the pixels next to a Cycles shadow edge (3×3 with both sides)
  recall           share of Cycles' shadowed pixels (V < 0.5) the technique shadows (sub-texel bars on thin)
  frame_ms         whole frame, best of `--repeats` (Table 2: SPSM/HARD ratio per map size)
  shares           SPSM's pixels decided by one look-up, the 3×3 look-ups and silhouette recovery (Fig. 14)
Then at `--ablation-map` (default 1024): the quantiser ablation (FLOAT, LINEAR, POW3, POW5: false shadows,
i.e. pixels SPSM shadows that Cycles lights, §3.4 Fig. 6) and antialiasing on/off against a box-filtered
Cycles reference (mean |V − V_ref| over the edge pixels, §5). The issue's targets are checked at the end.
Writes DIR/spsm_study.json and DIR/spsm_study.md atomically.

Needs bpy (the scenes and the Cycles reference; references are cached on disk).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ...core.files import write_atomic

SCENES = ("suzanne", "contact", "thin", "grazing", "city")
MAP_SIZES = (512, 1024, 2048, 4096)
LIGHT_SIZE = 0.01           # metres: a hard shadow for Cycles
QUANTISERS = ("FLOAT", "LINEAR", "POW3", "POW5")
SHARES = ("share_lit_1", "share_shadow_1", "share_shadow_3x3", "share_recovered")


def edge_pixels(v_ref: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Pixels whose 3×3 neighbourhood in the reference holds both sides of 0.5 (a shadow edge)."""
    dark = v_ref < 0.5
    h, w = dark.shape
    pad = np.pad(dark, 1, mode="edge")
    any_dark = np.zeros_like(dark)
    any_lit = np.zeros_like(dark)
    for dy in range(3):
        for dx in range(3):
            win = pad[dy:dy + h, dx:dx + w]
            any_dark |= win
            any_lit |= ~win
    return mask & any_dark & any_lit


def score(v: np.ndarray, v_ref: np.ndarray, mask: np.ndarray) -> dict:
    from .. import metrics
    m = metrics.compare(v, v_ref, mask)
    ok = mask & np.isfinite(v) & np.isfinite(v_ref)
    wrong = ok & ((v < 0.5) != (v_ref < 0.5))
    edges = edge_pixels(v_ref, ok)
    shadowed_ref = ok & (v_ref < 0.5)
    return {"pixel_match": m["pixel_match"], "mismatched": int(wrong.sum()),
            "false_shadow": int((ok & (v < 0.5) & (v_ref >= 0.5)).sum()),
            "boundary_rate": float(wrong[edges].mean()) if edges.any() else float("nan"),
            "edge_pixels": int(edges.sum()),
            "edge_mae": float(np.abs(v - v_ref)[edges].mean()) if edges.any() else float("nan"),
            "recall": float((shadowed_ref & (v < 0.5)).sum() / max(int(shadowed_ref.sum()), 1)),
            "n_mask": m["n_mask"]}


def _scene(name: str, size: int):
    import bpy
    from .. import scenes
    sc = scenes.build(name, resolution=(size, size))
    for obj in sc.objects:
        if obj.type == "LIGHT":
            obj.data.size = LIGHT_SIZE
            if hasattr(obj.data, "shadow_soft_size"):
                obj.data.shadow_soft_size = LIGHT_SIZE / 2
    bpy.context.view_layer.update()
    return sc


def _render(snap, settings, repeats: int):
    from ...render import pipeline
    best = None
    for _ in range(max(repeats, 1)):
        r = pipeline.render(snap, settings, stage_times=True)
        if best is None or r.total_ms < best.total_ms:
            best = r
    return best


def _shares(r) -> dict:
    per = r.stats.get("per_light") or []
    if not per:
        return {}
    total = sum(p["pixels"] for p in per)
    return {k: float(sum(p[k] * p["pixels"] for p in per) / max(total, 1)) for k in SHARES}


def run(out: Path, scene_names=SCENES, size: int = 128, samples: int = 64, map_sizes=MAP_SIZES,
        repeats: int = 2, ablation_map: int = 1024, log=print) -> dict:
    import bpy
    from .. import reference
    from ...blender.extract import extract
    from ...core.settings import RenderSettings
    results = {"size": size, "samples": samples, "light_size": LIGHT_SIZE, "scenes": list(scene_names),
               "map_sizes": list(map_sizes), "rows": [], "ablation": [], "aa": []}
    t0 = time.time()
    for name in scene_names:
        sc = _scene(name, size)
        ref = reference.cycles_visibility(sc, samples=samples)
        snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
        v_ref, mask = ref.visibility, ref.mask
        for n in map_sizes:
            for tech in ("HARD", "SPSM"):
                r = _render(snap, RenderSettings(technique=tech, shadow_map_size=n, collect_stats=True), repeats)
                row = {"scene": name, "map": n, "technique": tech, "frame_ms": r.total_ms,
                       "visibility_ms": r.timings.get("visibility", 0.0) + r.timings.get("shadow_map", 0.0),
                       **score(r.passes["Visibility"][..., 0], v_ref, mask), **_shares(r)}
                results["rows"].append(row)
            log(f"[{time.time() - t0:6.0f}s] {name} {n}²: HARD {results['rows'][-2]['mismatched']} "
                f"SPSM {results['rows'][-1]['mismatched']} mismatched")
        base = RenderSettings(technique="SPSM", shadow_map_size=ablation_map)
        for q in QUANTISERS:
            r = _render(snap, base.with_(spsm_quantiser=q), 1)
            results["ablation"].append({"scene": name, "quantiser": q,
                                        **score(r.passes["Visibility"][..., 0], v_ref, mask)})
        box = reference.cycles_visibility(sc, samples=samples, filter_type="BOX")
        for label, samples_aa in (("off", 1), ("on", 8)):
            r = _render(snap, base.with_(spsm_aa_samples=samples_aa), 1)
            results["aa"].append({"scene": name, "aa": label,
                                  **score(r.passes["Visibility"][..., 0], box.visibility, box.mask)})
        log(f"[{time.time() - t0:6.0f}s] {name}: ablations done")
    results["targets"] = targets(results)
    results["seconds"] = time.time() - t0
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "spsm_study.json", json.dumps(results, indent=1, default=float).encode())
    write_atomic(out / "spsm_study.md", markdown(results).encode())
    return results


def _row(results, scene, n, tech):
    for r in results["rows"]:
        if r["scene"] == scene and r["map"] == n and r["technique"] == tech:
            return r
    return None


def targets(results) -> list[dict]:
    """The issue's targets, per scene: SPSM mismatched ≤ 0.3× HARD's at 2048²; SPSM at 1024² no worse than
    HARD at 4096²; SPSM frame time ≤ 2× HARD's at 2048²."""
    out = []
    for scene in results["scenes"]:
        h2, s2 = _row(results, scene, 2048, "HARD"), _row(results, scene, 2048, "SPSM")
        h4, s1 = _row(results, scene, 4096, "HARD"), _row(results, scene, 1024, "SPSM")
        if h2 and s2:
            ratio = s2["mismatched"] / max(h2["mismatched"], 1)
            out.append({"scene": scene, "target": "mismatched SPSM/HARD at 2048² ≤ 0.3", "value": ratio,
                        "met": ratio <= 0.3})
            t = s2["frame_ms"] / max(h2["frame_ms"], 1e-9)
            out.append({"scene": scene, "target": "frame time SPSM/HARD at 2048² ≤ 2", "value": t, "met": t <= 2.0})
        if h4 and s1:
            out.append({"scene": scene, "target": "SPSM 1024² mismatched ≤ HARD 4096²",
                        "value": f"{s1['mismatched']} vs {h4['mismatched']}",
                        "met": s1["mismatched"] <= h4["mismatched"]})
    return out


def markdown(results) -> str:
    lines = [f"# SPSM study (Lecocq et al. 2014) — {results['size']}² images, Cycles {results['samples']} spp, "
             f"{results['light_size'] * 100:.0f} cm light", "",
             "| scene | map | technique | pixel_match | mismatched | boundary rate | recall | frame ms | "
             "1 look-up | 3×3 | recovery |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        sh = (f"{r.get('share_lit_1', 0) + r.get('share_shadow_1', 0):.3f} | {r.get('share_shadow_3x3', 0):.4f} | "
              f"{r.get('share_recovered', 0):.4f}") if r["technique"] == "SPSM" else " | | "
        lines.append(f"| {r['scene']} | {r['map']} | {r['technique']} | {r['pixel_match']:.4f} | {r['mismatched']} | "
                     f"{r['boundary_rate']:.3f} | {r['recall']:.3f} | {r['frame_ms']:.1f} | {sh} |")
    lines += ["", "## SPSM/HARD frame time (mean over scenes)", "", "| map | ratio |", "|---|---|"]
    for n in results["map_sizes"]:
        ratios = [_row(results, s, n, "SPSM")["frame_ms"] / max(_row(results, s, n, "HARD")["frame_ms"], 1e-9)
                  for s in results["scenes"] if _row(results, s, n, "SPSM") and _row(results, s, n, "HARD")]
        if ratios:
            lines.append(f"| {n} | {np.mean(ratios):.2f} |")
    lines += ["", "## Quantiser ablation (SPSM)", "", "| scene | quantiser | pixel_match | mismatched | false shadow |",
              "|---|---|---|---|---|"]
    for r in results["ablation"]:
        lines.append(f"| {r['scene']} | {r['quantiser']} | {r['pixel_match']:.4f} | {r['mismatched']} | "
                     f"{r['false_shadow']} |")
    lines += ["", "## Antialiasing against a box-filtered Cycles reference", "",
              "| scene | AA | edge mae | pixel_match |", "|---|---|---|---|"]
    for r in results["aa"]:
        lines.append(f"| {r['scene']} | {r['aa']} | {r['edge_mae']:.4f} | {r['pixel_match']:.4f} |")
    lines += ["", "## Targets (issue 12)", "", "| scene | target | value | met |", "|---|---|---|---|"]
    for t in results.get("targets", []):
        value = f"{t['value']:.3f}" if isinstance(t["value"], float) else t["value"]
        lines.append(f"| {t['scene']} | {t['target']} | {value} | {'yes' if t['met'] else 'NO'} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m penumbra bench --study spsm", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--size", type=int, default=128, help="image pixels per side")
    ap.add_argument("--samples", type=int, default=64, help="Cycles samples of the reference")
    ap.add_argument("--map-sizes", type=int, nargs="+", default=list(MAP_SIZES))
    ap.add_argument("--repeats", type=int, default=2, help="renders per configuration (fastest kept)")
    ap.add_argument("--ablation-map", type=int, default=1024)
    args = ap.parse_args(argv)
    run(args.out, tuple(args.scenes), args.size, args.samples, tuple(args.map_sizes), args.repeats,
        args.ablation_map, log=lambda s: print(s, file=sys.stderr, flush=True))
    print(f"wrote {args.out}/spsm_study.md and spsm_study.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
