"""Anti-aliasing with one visibility sample per pixel (Schwarz & Stamminger 2008, §7) for every technique:
its time overhead and its error at silhouettes against a box-filtered Cycles reference.

    python -m penumbra bench --study msaa --out DIR -- [--scenes silhouette suzanne] [--size 128]
        [--samples 256] [--techniques HARD PCSS …] [--repeats 3]

Per scene and technique, four frames: anti-aliasing off, on (visibility at pixel centres, the default), on
with the paper's first-multisample visibility, and on with τ = 1 (every sample takes its pixel's visibility:
no interpolation from the neighbours, the left of the paper's Fig. 9). Each is rendered with every surface white, as Cycles'
reference is, so Combined is directly comparable with Cycles' shadowed render:
  frame_ms      whole frame, fastest of `--repeats` (interleaved, so load drifts hit all three alike)
  overhead      frame_ms / frame_ms(off) − 1 (paper: < 9 % on a GeForce 8800; MSAA alone ≈ 5 %)
  stage_overhead  the anti-aliased frame's own MSAA stages (multisampled G-buffer, edge list, per-sample
                shading) over the rest of that frame: the same measure, less exposed to load that drifts
                between frames on a shared machine
  edge_error    mean |L − L_ref| over the silhouette pixels (edge_pixels: a coverage step or a depth crease
                in the 3×3 neighbourhood, in the Depth pass), L the Rec. 709 luminance of Combined, L_ref that of
                Cycles' box-filtered (1 px) shadowed render, over the 99th percentile of L_ref(unshadowed)
  edge_error_vis  the same for the visibility ratio L(Combined)/L(Unshadowed) against Cycles' box-filtered
                V_ref, over silhouette pixels in its mask (an edge between two surfaces, not the background)
  per-sample pixels  pixels whose samples are not all their own fragment's (the only ones shaded per sample)
  mae_shadow    of the Visibility pass against Cycles' point-filtered reference (what every other measurement
                of this project uses): equal off and on by construction, and what the first-sample choice
                costs there
Writes DIR/msaa_study.json and DIR/msaa_study.md atomically. Needs bpy (scenes and Cycles, cached on disk).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from ...core.files import write_atomic

SCENES = ("silhouette", "suzanne")
# (label, setting changes): the frames each technique renders
MODES = (("off", {"antialiasing": False}),
         ("on", {"antialiasing": True, "aa_visibility_sample": "CENTER"}),
         ("on_first", {"antialiasing": True, "aa_visibility_sample": "FIRST"}),
         ("on_tau1", {"antialiasing": True, "aa_depth_threshold": 1.0}))
EDGE_DEPTH_STEP = 0.05      # relative camera-depth step that makes a silhouette in the Depth pass
PAPER_OVERHEAD = 0.09


def edge_pixels(depth: np.ndarray, background: float) -> np.ndarray:
    """(H, W) bool: silhouette pixels of the Depth pass, and their 8 neighbours. A silhouette is a step
    between covered and background pixels, or a crease or step in depth: inverse camera depth is affine in
    screen space over a plane, so its second difference along x or y is ~0 on any one surface and stands out
    (above EDGE_DEPTH_STEP relative) where two meet."""
    covered = depth < background
    inv = np.where(covered, 1.0 / np.where(covered, depth, 1.0), np.nan).astype(np.float64)
    mark = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        a, b, c = (np.take(inv, range(i, depth.shape[axis] - 2 + i), axis=axis) for i in range(3))
        with np.errstate(invalid="ignore"):
            jump = ~(np.abs(a - 2.0 * b + c) <= EDGE_DEPTH_STEP * b)      # NaN (a background pixel) counts
        inner = [slice(None), slice(None)]
        inner[axis] = slice(1, -1)
        mark[tuple(inner)] |= jump & ~(np.isnan(a) & np.isnan(b) & np.isnan(c))
    h, w = depth.shape
    pad = np.pad(mark, 1)
    return np.any([pad[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)], axis=0)


def edge_errors(passes: dict, ref, edges: np.ndarray) -> dict:
    """edge_error and edge_error_vis (module docstring) of a white-albedo frame's passes against the
    box-filtered Cycles reference `ref` (a reference.ReferenceResult)."""
    from ..metrics import LUMA
    lum = passes["Combined"][..., :3].astype(np.float64) @ LUMA
    un = passes["Unshadowed"][..., :3].astype(np.float64) @ LUMA
    lum_ref = ref.shadowed[..., :3].astype(np.float64) @ LUMA
    un_ref = ref.unshadowed[..., :3].astype(np.float64) @ LUMA
    scale = max(float(np.percentile(un_ref, 99)), 1e-12)
    out = {"edge_pixels": int(edges.sum()),
           "edge_error": float(np.abs(lum - lum_ref)[edges].mean() / scale) if edges.any() else float("nan")}
    with np.errstate(divide="ignore", invalid="ignore"):
        vis = np.where(un > 1e-12, lum / un, 1.0)
    vedges = edges & ref.mask & (un > 1e-12)
    out["edge_error_vis"] = (float(np.abs(np.clip(vis, 0, 1) - ref.visibility)[vedges].mean())
                             if vedges.any() else float("nan"))
    return out


def white(snap):
    """`snap` with every surface white, as Cycles' reference renders it."""
    return dataclasses.replace(snap, albedo=np.ones_like(snap.albedo))


def _scene(name: str, size: int):
    import bpy
    from .. import scenes
    sc = scenes.build(name, resolution=(size, size))
    bpy.context.view_layer.update()
    return sc


def run(out: Path, scene_names=SCENES, size: int = 128, samples: int = 256, techniques=None, repeats: int = 3,
        log=print) -> dict:
    import bpy
    from .. import metrics, reference
    from ...blender.extract import extract
    from ...core.settings import RenderSettings
    from ...render import pipeline
    techniques = list(techniques or pipeline.TECHNIQUES)
    results = {"size": size, "samples": samples, "scenes": list(scene_names), "techniques": techniques,
               "repeats": repeats, "rows": []}
    t0 = time.time()
    for name in scene_names:
        sc = _scene(name, size)
        box = reference.cycles_visibility(sc, samples=samples, filter_type="BOX")
        point = reference.cycles_visibility(sc, samples=samples)
        snap = white(extract(bpy.context.evaluated_depsgraph_get(), sc))
        for tech in techniques:
            settings = {label: RenderSettings(technique=tech).with_(**changes) for label, changes in MODES}
            best: dict = {}
            for s in settings.values():           # compiles each mode's shaders outside the timed frames
                pipeline.render(snap, s)
            for _ in range(max(repeats, 1)):      # interleaved: off, on, on_first, off, …
                for label, s in settings.items():
                    r = pipeline.render(snap, s)
                    if label not in best or r.total_ms < best[label].total_ms:
                        best[label] = r
            edges = edge_pixels(best["off"].passes["Depth"][..., 0], pipeline.BACKGROUND_DEPTH)
            base_ms = best["off"].total_ms
            for label, r in best.items():
                m = metrics.compare(r.passes["Visibility"][..., 0], point.visibility, point.mask)
                results["rows"].append({
                    "scene": name, "technique": tech, "mode": label, "frame_ms": r.total_ms,
                    "overhead": r.total_ms / max(base_ms, 1e-9) - 1.0,
                    "stage_overhead": _stage_overhead(r),
                    "msaa_ms": {k: r.timings.get(k, 0.0) for k in ("gbuffer_msaa", "gbuffer_resolve", "gbuffer",
                                                                   "accumulate", "accumulate_msaa")},
                    "msaa_edge_pixels": r.stats.get("msaa_edge_pixels", 0),
                    "mae_shadow": m["mae_shadow"], **edge_errors(r.passes, box, edges)})
            on = next(r for r in results["rows"][-len(MODES):] if r["mode"] == "on")
            log(f"[{time.time() - t0:6.0f}s] {name} {tech}: overhead {on['overhead'] * 100:+.1f} %, edge error "
                f"{results['rows'][-len(MODES)]['edge_error']:.4f} → {on['edge_error']:.4f}")
    results["summary"] = summary(results)
    results["seconds"] = time.time() - t0
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "msaa_study.json", json.dumps(results, indent=1, default=float).encode())
    write_atomic(out / "msaa_study.md", markdown(results).encode())
    return results


MSAA_STAGES = ("gbuffer_msaa", "gbuffer_resolve", "accumulate_msaa")


def _stage_overhead(r) -> float:
    own = sum(r.timings.get(k, 0.0) for k in MSAA_STAGES)
    return own / max(r.total_ms - own, 1e-9)


def summary(results) -> list[dict]:
    """Per technique over the scenes: mean overhead of the default anti-aliasing, and whether it lowered the
    edge error on every scene."""
    out = []
    for tech in results["techniques"]:
        rows = {(r["scene"], r["mode"]): r for r in results["rows"] if r["technique"] == tech}
        scenes = [s for s in results["scenes"] if (s, "on") in rows]
        if not scenes:
            continue
        overhead = float(np.mean([rows[s, "on"]["overhead"] for s in scenes]))
        stage = float(np.mean([rows[s, "on"]["stage_overhead"] for s in scenes]))
        ratio = float(np.mean([rows[s, "on"]["edge_error"] / max(rows[s, "off"]["edge_error"], 1e-12)
                               for s in scenes]))
        out.append({"technique": tech, "overhead": overhead, "stage_overhead": stage, "edge_error_ratio": ratio,
                    "lower_everywhere": all(rows[s, "on"]["edge_error"] < rows[s, "off"]["edge_error"] for s in scenes),
                    "overhead_below_paper": stage < PAPER_OVERHEAD})
    return out


def markdown(results) -> str:
    lines = [f"# MSAA study (Schwarz & Stamminger 2008, §7) — {results['size']}² images, Cycles "
             f"{results['samples']} spp (box filter 1 px for the edge errors, point-like for mae_shadow), fastest "
             f"of {results['repeats']}", "",
             "| scene | technique | AA | frame ms | overhead | MSAA stages | MSAA G-buffer ms | per-sample shading ms | "
             "per-sample pixels | edge pixels | edge error | edge error V | mae_shadow (point) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["rows"]:
        ms = r["msaa_ms"]
        lines.append(f"| {r['scene']} | {r['technique']} | {r['mode']} | {r['frame_ms']:.1f} | "
                     f"{r['overhead'] * 100:+.1f} % | {r['stage_overhead'] * 100:.1f} % | "
                     f"{ms['gbuffer_msaa'] + ms['gbuffer_resolve']:.1f} | {ms['accumulate_msaa']:.2f} | "
                     f"{r['msaa_edge_pixels']} | {r['edge_pixels']} | {r['edge_error']:.4f} | "
                     f"{r['edge_error_vis']:.4f} | {r['mae_shadow']:.4f} |")
    lines += ["", "## Per technique (mean over scenes, default anti-aliasing against off)", "",
              "| technique | overhead (frames) | overhead (MSAA stages) | edge error on/off | lower on every scene | "
              "MSAA stages < 9 % (paper) |", "|---|---|---|---|---|---|"]
    for s in results["summary"]:
        lines.append(f"| {s['technique']} | {s['overhead'] * 100:+.1f} % | {s['stage_overhead'] * 100:.1f} % | "
                     f"{s['edge_error_ratio']:.3f} | "
                     f"{'yes' if s['lower_everywhere'] else 'NO'} | {'yes' if s['overhead_below_paper'] else 'NO'} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m penumbra bench --study msaa", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--size", type=int, default=128, help="image pixels per side")
    ap.add_argument("--samples", type=int, default=256, help="Cycles samples of the references")
    ap.add_argument("--techniques", nargs="+", default=None, help="default: every technique")
    ap.add_argument("--repeats", type=int, default=3, help="renders per configuration (fastest kept)")
    args = ap.parse_args(argv)
    run(args.out, tuple(args.scenes), args.size, args.samples, args.techniques, args.repeats,
        log=lambda s: print(s, file=sys.stderr, flush=True))
    print(f"wrote {args.out}/msaa_study.md and msaa_study.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
