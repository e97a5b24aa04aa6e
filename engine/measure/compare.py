"""Penumbra against Cycles on one scene: render both, measure, and write what a person wants to look at
(EXRs, and a PNG strip: our Visibility | Cycles' | the signed difference). Used by `python -m penumbra
compare` and the "Compare with Cycles" operator."""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import exr
from . import metrics, reference
from ..render import pipeline
from ..core.files import write_atomic
from ..core.settings import RenderSettings


@dataclass
class Comparison:
    scene: str
    technique: str
    metrics: dict                       # engine.metrics.compare of Visibility vs the Cycles reference
    noise_floor: dict | None            # the same metrics between two Cycles seeds
    ours_ms: float                      # our frame (wall clock, shaders already compiled)
    cycles_seconds: float               # Cycles time of the reference pair (from the cache if cached)
    reference_samples: int
    unshadowed_rel_error: float         # mean |U − U_cycles| / U_cycles over lit pixels
    warnings: list = field(default_factory=list)

    def summary(self) -> str:
        m, n = self.metrics, self.noise_floor or {}
        floor = f" (Cycles noise floor {n.get('mae_shadow', float('nan')):.4f})" if n else ""
        return (f"{self.scene} {self.technique}: mae_shadow {m['mae_shadow']:.4f}{floor}, rmse {m['rmse']:.4f}, "
                f"max_abs {m['max_abs']:.3f}, pixel_match {m['pixel_match']:.4f} over {m['n_shadow']} shadow px, "
                f"SSIM (shaded) {m['ssim_shaded']:.4f}; "
                f"ours {self.ours_ms:.1f} ms vs Cycles {self.cycles_seconds:.2f} s "
                f"({self.reference_samples} spp); Unshadowed rel. error {self.unshadowed_rel_error:.4f}")


def compare(scene, settings: RenderSettings, *, samples: int = 256, with_noise_floor: bool = True,
            out_dir: str | None = None, repeats: int = 1, on_progress=None) -> Comparison:
    """Render `scene` (a bpy scene) with Penumbra and Cycles and measure the difference."""
    import bpy
    from ..blender.extract import extract
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    settings = settings.with_(debug_passes=True)       # the Irradiance pass checks our Unshadowed light
    result = pipeline.render(snap, settings, on_progress=on_progress)     # first frame compiles shaders
    ours_ms = []
    for _ in range(max(repeats, 1)):
        start = time.perf_counter()
        result = pipeline.render(snap, settings)
        ours_ms.append((time.perf_counter() - start) * 1000.0)
    ref = reference.cycles_visibility(scene, samples=samples, width=snap.camera.width,
                                      height=snap.camera.height)
    floor = reference.noise_floor(scene, samples, width=snap.camera.width,
                                  height=snap.camera.height) if with_noise_floor else None
    v = result.passes["Visibility"][..., 0]
    m = metrics.compare(v, ref.visibility, ref.mask)
    m["ssim_shaded"] = metrics.ssim_shaded(result.passes["Combined"], result.passes["Unshadowed"], ref.visibility)
    cmp = Comparison(snap.name, settings.technique, m, floor, float(np.median(ours_ms)), ref.seconds, samples,
                     unshadowed_error(result.passes["Irradiance"] / np.pi, ref.unshadowed, ref.mask),
                     result.warnings)
    if out_dir:
        write_outputs(out_dir, cmp, result.passes, ref)
    return cmp


def unshadowed_error(ours: np.ndarray, cycles: np.ndarray, mask: np.ndarray) -> float:
    """Mean relative error of our unshadowed radiance against Cycles' unshadowed render, over lit pixels.
    The reference renders every surface white, so `ours` is E/π (the Irradiance pass over π)."""
    a = metrics.luminance(ours)
    b = metrics.luminance(cycles)
    lit = mask & (b > 1e-3 * max(float(np.percentile(b[mask], 99)) if mask.any() else 0.0, 1e-30))
    if not lit.any():
        return float("nan")
    return float(np.mean(np.abs(a[lit] - b[lit]) / b[lit]))


def write_outputs(out_dir: str, cmp: Comparison, passes: dict, ref) -> None:
    os.makedirs(out_dir, exist_ok=True)
    stem = os.path.join(out_dir, f"{cmp.scene}_{cmp.technique.lower()}")
    exr.write(stem + ".exr", passes, {"penumbra:technique": cmp.technique})
    exr.write(stem + "_cycles.exr", {"Visibility": ref.visibility[..., None].astype(np.float32),
                                     "Combined": np.dstack([ref.shadowed, np.ones(ref.visibility.shape)])
                                     .astype(np.float32)})
    exr.write_png(stem + "_compare.png", comparison_strip(passes["Visibility"][..., 0], ref.visibility,
                                                          ref.mask))
    write_atomic(stem + ".json", json.dumps({
        "scene": cmp.scene, "technique": cmp.technique, "metrics": cmp.metrics, "noise_floor": cmp.noise_floor,
        "ours_ms": cmp.ours_ms, "cycles_seconds": cmp.cycles_seconds, "reference_samples": cmp.reference_samples,
        "unshadowed_rel_error": cmp.unshadowed_rel_error}, indent=2))


def comparison_strip(v: np.ndarray, v_ref: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, 3W+8, 3) uint8, top row first: ours | Cycles | difference (red: we are darker, blue: lighter)."""
    def grey(x):
        g = (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)
        return np.repeat(np.flipud(g)[..., None], 3, axis=2)
    d = np.flipud(np.where(mask, v - v_ref, 0.0))
    scale = 1.0 / 0.25            # ±0.25 visibility saturates the colour
    diff = np.full(d.shape + (3,), 255, np.uint8)
    diff[..., 1] = (255 * (1 - np.clip(np.abs(d) * scale, 0, 1))).astype(np.uint8)
    diff[..., 0] = np.where(d > 0, diff[..., 1], 255)
    diff[..., 2] = np.where(d < 0, diff[..., 1], 255)
    gap = np.full((v.shape[0], 4, 3), 64, np.uint8)
    return np.concatenate([grey(v), gap, grey(v_ref), gap, diff], axis=1)
