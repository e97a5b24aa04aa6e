"""Penumbra against Cycles on one scene: render both, measure, and write what a person wants to look at
(EXRs, a JSON of the numbers and a titled PNG: Visibility and Combined rows, ours | Cycles | the signed
difference with its colour scale). Used by `python -m penumbra compare` and the "Compare with Cycles"
operator, which runs `compare_steps` one stage per timer tick so Blender stays responsive and Esc cancels."""
from __future__ import annotations

import io
import json
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import exr
from . import metrics, reference
from .bench import _clean as json_safe
from ..render import pipeline
from ..core.files import check_output_folder, write_atomic
from ..core.settings import RenderSettings

# A preview comparison: the longest image side and the Cycles samples are capped, and no noise floor.
PREVIEW_MAX_SIDE = 256
PREVIEW_SAMPLES = 32
# |ΔV| at which the difference panels saturate.
DIFF_SATURATION = 0.25


@dataclass
class Comparison:
    scene: str
    technique: str
    metrics: dict                       # engine.metrics.compare of Visibility vs the Cycles reference
    noise_floor: dict | None            # the same metrics between two Cycles seeds
    ours_ms: float                      # our frame (wall clock, shaders already compiled)
    cycles_seconds: float               # ONE Cycles render (the shadowed one), as the bench times its peers
    cycles_pair_seconds: float          # both reference renders (shadowed + unshadowed)
    cycles_timed_by: str                # "shadowed render", or "half of the pair" for an old cache entry
    reference_samples: int
    unshadowed_rel_error: float         # mean |U − U_cycles| / U_cycles over lit pixels
    resolution: tuple = (0, 0)
    warnings: list = field(default_factory=list)
    undefined: str = ""                 # why the metrics are null, when they are
    preview: str = ""                   # the caps of a preview comparison ("" for a full one)
    files: list = field(default_factory=list)
    passes: dict | None = field(default=None, repr=False)      # our frame's passes
    ref: object = field(default=None, repr=False)               # the reference.ReferenceResult

    def summary(self) -> str:
        m, n = self.metrics, self.noise_floor or {}
        if self.undefined and not _finite(m.get("mae_shadow")) and not _finite(m.get("rmse")):
            head = f"{self.scene} {self.technique}: no error measured ({self.undefined})"
        else:
            floor = f" (Cycles noise floor {_fmt(n.get('mae_shadow'), '.4f')})" if n else ""
            head = (f"{self.scene} {self.technique}: mae_shadow {_fmt(m['mae_shadow'], '.4f')} over "
                    f"{m['n_shadow']} shadow px{floor}, rmse {_fmt(m['rmse'], '.4f')}, "
                    f"max_abs {_fmt(m['max_abs'], '.3f')}, pixel_match {_fmt(m['pixel_match'], '.4f')} over "
                    f"{m['n_mask']} lit px, SSIM (shaded) {_fmt(m.get('ssim_shaded'), '.4f')}"
                    + (f" [{self.undefined}]" if self.undefined else ""))
        speed = (f"ours {self.ours_ms:.1f} ms vs Cycles {self.cycles_seconds:.2f} s for one render "
                 f"({self.reference_samples} spp, {self.cycles_timed_by})")
        tail = f"; Unshadowed rel. error {_fmt(self.unshadowed_rel_error, '.4f')}"
        if self.preview:
            tail += f"; PREVIEW: {self.preview}"
        return f"{head}; {speed}{tail}"

    def as_json(self) -> dict:
        """JSON-safe (NaN → null, with `undefined` saying why)."""
        return json_safe({
            "scene": self.scene, "technique": self.technique, "resolution": list(self.resolution),
            "metrics": self.metrics, "noise_floor": self.noise_floor, "ours_ms": self.ours_ms,
            "cycles_seconds": self.cycles_seconds, "cycles_timed_by": self.cycles_timed_by,
            "cycles_pair_seconds": self.cycles_pair_seconds,
            "reference_samples": self.reference_samples, "unshadowed_rel_error": self.unshadowed_rel_error,
            "undefined": self.undefined or None, "preview": self.preview or None, "warnings": self.warnings})


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def _fmt(x, spec: str) -> str:
    return format(x, spec) if _finite(x) else "n/a"


def compare(scene, settings: RenderSettings, *, on_progress=None, **kwargs) -> Comparison:
    """Render `scene` (a bpy scene) with Penumbra and Cycles and measure the difference; see
    `compare_steps` for the keyword arguments. `on_progress(fraction, message)` follows every stage."""
    steps = compare_steps(scene, settings, **kwargs)
    while True:
        try:
            fraction, message = next(steps)
        except StopIteration as done:
            return done.value
        if on_progress:
            on_progress(fraction, message)


def preview_caps(width: int, height: int, samples: int) -> tuple[int, int, int]:
    """The preview's resolution (longest side ≤ PREVIEW_MAX_SIDE, aspect kept) and samples."""
    scale = min(1.0, PREVIEW_MAX_SIDE / max(width, height))
    return max(1, round(width * scale)), max(1, round(height * scale)), min(samples, PREVIEW_SAMPLES)


def compare_steps(scene, settings: RenderSettings, *, samples: int = 256, with_noise_floor: bool = True,
                  out_dir: str | None = None, repeats: int = 1, preview: bool = False):
    """A generator: does one stage (our frames, the Cycles pair, the second seed, metrics and files) per
    `next()`, yielding (fraction done, what comes next); its return value is the Comparison. A caller can
    stop between stages (Esc in Blender, Ctrl-C on the command line): the scene is restored either way.
    `preview`: longest side ≤ PREVIEW_MAX_SIDE and ≤ PREVIEW_SAMPLES Cycles samples, no noise floor."""
    import bpy
    from ..blender.compat import SettingsRecorder
    from ..blender.extract import extract
    if out_dir:
        check_output_folder(out_dir)            # refuse before any render (OutputError, one line)
    st = SettingsRecorder()
    try:
        r = scene.render
        pct = r.resolution_percentage / 100.0
        width, height = max(1, int(r.resolution_x * pct)), max(1, int(r.resolution_y * pct))
        caps = ""
        if preview:
            pw, ph, ps = preview_caps(width, height, samples)
            caps = (f"{pw}×{ph} (scene {width}×{height}), {ps} Cycles spp (asked {samples}), no noise floor")
            st.set(r, "resolution_x", pw)
            st.set(r, "resolution_y", ph)
            st.set(r, "resolution_percentage", 100)
            samples, with_noise_floor = ps, False
        yield 0.0, "Penumbra frame"
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
        settings = settings.with_(debug_passes=True)   # the Irradiance pass checks our Unshadowed light
        result = pipeline.render(snap, settings)       # the first frame compiles shaders: untimed
        ours_ms = []
        for _ in range(max(repeats, 1)):
            start = time.perf_counter()
            result = pipeline.render(snap, settings)
            ours_ms.append((time.perf_counter() - start) * 1000.0)
        # The shading check is against Cycles' point-filtered render: an anti-aliased frame's Irradiance is the
        # mean over each pixel, so that check takes the frame without anti-aliasing (Visibility is the same).
        point = pipeline.render(snap, settings.with_(antialiasing=False)) if settings.antialiasing else result
        w, h = snap.camera.width, snap.camera.height
        share = 0.45 if with_noise_floor else 0.85
        yield 0.05, f"Cycles reference, {samples} spp (shadowed + unshadowed)"
        ref = reference.cycles_visibility(scene, samples=samples, width=w, height=h)
        floor = None
        if with_noise_floor:
            yield 0.05 + share, f"Cycles noise floor, second seed, {samples} spp"
            floor = reference.noise_floor(scene, samples, width=w, height=h)
        yield 0.05 + (2 if with_noise_floor else 1) * share, "metrics and files"
    finally:
        st.restore()
    cmp = measure(snap, settings, result, ref, floor, float(np.median(ours_ms)), samples, shading=point)
    cmp.preview = caps
    if out_dir:
        cmp.files = write_outputs(out_dir, cmp, scene)
    return cmp


def measure(snap, settings, result, ref, floor, ours_ms: float, samples: int, shading=None) -> Comparison:
    """The numbers of one comparison; metrics that have no pixels to be taken over are NaN (null in JSON) and
    `undefined` says why. `shading`: the frame whose Irradiance is checked against Cycles' unshadowed render
    (default `result`)."""
    v = result.passes["Visibility"][..., 0]
    m = metrics.compare(v, ref.visibility, ref.mask)
    undefined = ""
    if not snap.lights:
        undefined = f"scene '{snap.name}' has no lights: there is no shadow to compare"
    elif m["n_mask"] == 0:
        undefined = "no visible pixel receives light in the Cycles reference: there is no shadow to compare"
    elif m["n_shadow"] == 0:
        undefined = "mae_shadow: neither image has a shadow or penumbra pixel"
    if m["n_mask"] == 0:
        m["ssim_shaded"] = float("nan")     # black against black says nothing
    else:
        m["ssim_shaded"] = metrics.ssim_shaded(result.passes["Combined"], result.passes["Unshadowed"],
                                               ref.visibility)
    if ref.shadowed_seconds is not None:
        one, timed_by = ref.shadowed_seconds, "shadowed render"
    else:
        one, timed_by = ref.seconds / 2.0, "half of the cached pair"
    return Comparison(snap.name, settings.technique, m, floor, ours_ms, one, ref.seconds, timed_by, samples,
                      unshadowed_error((shading or result).passes["Irradiance"] / np.pi, ref.unshadowed, ref.mask),
                      resolution=(snap.camera.width, snap.camera.height), warnings=list(result.warnings),
                      undefined=undefined, passes=result.passes, ref=ref)


def unshadowed_error(ours: np.ndarray, cycles: np.ndarray, mask: np.ndarray, depth: np.ndarray | None = None,
                     background: float = 1.0e10) -> float:
    """Mean relative error of our unshadowed radiance against Cycles' unshadowed render, over lit pixels
    (unshadowed_terms); NaN where no pixel is lit."""
    terms = unshadowed_terms(ours, cycles, mask, depth, background)
    return float(np.mean(terms)) if len(terms) else float("nan")


def unshadowed_terms(ours: np.ndarray, cycles: np.ndarray, mask: np.ndarray, depth: np.ndarray | None = None,
                     background: float = 1.0e10) -> np.ndarray:
    """The relative error of our unshadowed radiance against Cycles' unshadowed render at each lit pixel.
    The reference renders every surface white, so `ours` is E/π (the Irradiance pass over π). With our Depth
    pass, a pixel we leave uncovered beside a covered one is left out: its centre is off the surface, and
    Cycles' 0.01 px pixel filter (reference.POINT_FILTER_WIDTH) still grazes the silhouette in a few samples
    (fuzz seed 3033: 0.6 % of a neighbour's value, the one such pixel of six made the error 0.17).
    The same holds for a hard light edge (a spot cone with no blend): a pixel we leave unlit beside one we
    light, whose Cycles value is under half of its brightest neighbour's, has its centre unlit in Cycles too
    and is left out. Cycles lights such a pixel with a stray camera ray, not its filter: fuzz seed 8020 (edge
    0.23 px from the centre) gets exactly one lit sample at 256 and at 1024 spp, for filter widths 0.001 to
    0.1 px alike, and none at 16 or 64 spp.
    A pixel counts at most as wholly wrong (relative error 1, as a fully dark one does), so that one pixel at a
    hard light edge, where Cycles' value is a trace of ours, cannot outweigh the image: a floor that crosses
    the plane of a large area light (fuzz seeds 1035, 1039) is lit up to that line, and Cycles' values fall
    off over the last pixel before it, one of them to 0.2 % of ours (a relative error of 542, 0.29 over the
    image's 2794 pixels); capped, those 13 pixels weigh 0.004."""
    a = metrics.luminance(ours)
    b = metrics.luminance(cycles)
    lit = mask & (b > 1e-3 * max(float(np.percentile(b[mask], 99)) if mask.any() else 0.0, 1e-30))
    if depth is not None:
        covered = np.asarray(depth).reshape(lit.shape) < background
        lit &= covered | ~_beside(covered)
    brightest = _neighbour_max(b)
    lit &= (a > 0.0) | ~_beside(a > 0.0) | ~(b < 0.5 * brightest)
    return np.minimum(np.abs(a[lit] - b[lit]) / b[lit], 1.0)


def _beside(m: np.ndarray) -> np.ndarray:
    """Pixels with one of their 8 neighbours in `m`."""
    return _neighbour_max(m.astype(np.float32)) > 0.0


def _neighbour_max(x: np.ndarray) -> np.ndarray:
    """The largest of each pixel's 8 neighbours (0 past the border): diagonal ones too, as a thin surface seen
    edge-on along a diagonal touches the pixels beside its silhouette only at their corners (fuzz seed 11017:
    a plane's edge grazed by a pixel centre whose 4 neighbours are all off it)."""
    pad = np.pad(x, 1)
    h, w = x.shape
    return np.max([pad[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1)
                   if dy or dx], axis=0)


def write_outputs(out_dir: str, cmp: Comparison, scene=None) -> list[str]:
    """The JSON first (the numbers survive whatever fails after it), then the EXRs and the PNG; each file is
    written atomically, so what was written is complete. Returns the paths."""
    passes, ref = cmp.passes, cmp.ref
    stem = os.path.join(out_dir, f"{cmp.scene}_{cmp.technique.lower()}")
    paths = [stem + ".json", stem + ".exr", stem + "_cycles.exr", stem + "_compare.png"]
    write_atomic(paths[0], json.dumps(cmp.as_json(), indent=2, allow_nan=False))
    exr.write(paths[1], passes, {"penumbra:technique": cmp.technique})
    exr.write(paths[2], {"Visibility": ref.visibility[..., None].astype(np.float32),
                         "Combined": np.dstack([ref.shadowed, np.ones(ref.visibility.shape)]).astype(np.float32)})
    write_comparison_png(paths[3], cmp, scene)
    return paths


def write_comparison_png(path: str, cmp: Comparison, scene=None) -> None:
    """The titled figure (`comparison_png`), or where matplotlib is missing (Blender's own Python ships
    without it) the same six panels untitled, with a warning saying how to read them."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        ours, theirs, diffs = _panels(cmp, scene)[:3]
        gap = np.full((ours[0].shape[0], 4, 3), 64, np.uint8)
        rows = [np.concatenate([_grey8(o) if o.ndim == 2 else o, gap, _grey8(t) if t.ndim == 2 else t, gap,
                                _diff8(d)], axis=1) for o, t, d in zip(ours, theirs, diffs)]
        exr.write_png(path, np.concatenate([rows[0], np.full((4, rows[0].shape[1], 3), 64, np.uint8), rows[1]]))
        cmp.warnings.append(f"matplotlib is not installed: {os.path.basename(path)} has no titles; rows "
                            f"Visibility and Combined, columns ours | Cycles | difference (red: Penumbra darker, "
                            f"blue: lighter, ±{DIFF_SATURATION:g} saturates)")
        return
    write_atomic(path, comparison_png(cmp, scene))


def _grey8(x: np.ndarray) -> np.ndarray:
    g = (np.clip(np.nan_to_num(x), 0, 1) * 255 + 0.5).astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=2)


def _diff8(d: np.ndarray) -> np.ndarray:
    """Signed difference → white (0), red (negative) or blue (positive), saturating at ±DIFF_SATURATION;
    grey where undefined."""
    t = np.clip(np.abs(np.nan_to_num(d)) / DIFF_SATURATION, 0, 1)
    fade = (255 * (1 - t)).astype(np.uint8)
    out = np.full(d.shape + (3,), 255, np.uint8)
    out[..., 1] = fade
    out[..., 0] = np.where(d > 0, fade, 255)
    out[..., 2] = np.where(d < 0, fade, 255)
    out[~np.isfinite(d)] = 208
    return out


def comparison_strip(v: np.ndarray, v_ref: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """A plain (H, 3W+8, 3) uint8 strip, top row first: our V | Cycles' | the signed difference (the
    colours of the compare PNG), for tools that save many of them (fuzz)."""
    gap = np.full((v.shape[0], 4, 3), 64, np.uint8)
    d = np.flipud(np.where(mask, v - v_ref, np.nan))
    return np.concatenate([_grey8(np.flipud(v)), gap, _grey8(np.flipud(v_ref)), gap, _diff8(d)], axis=1)


def _panels(cmp: Comparison, scene=None):
    """Rows (Visibility, Combined) of ours, Cycles and the signed difference, row 0 at the top; and the view
    transform's name. Combined goes through `scene`'s colour management."""
    passes, ref = cmp.passes, cmp.ref
    v, v_ref, mask = passes["Visibility"][..., 0], ref.visibility, ref.mask
    target = np.dstack([passes["Unshadowed"][..., :3] * v_ref[..., None], np.ones(v.shape)])
    if scene is not None:
        from ..blender.compat import display_rgb8
        ours_rgb, cycles_rgb = display_rgb8(passes["Combined"], scene), display_rgb8(target, scene)
        view = scene.view_settings.view_transform
    else:
        ours_rgb, cycles_rgb = exr.to_srgb8(passes["Combined"]), exr.to_srgb8(target)
        view = "Standard"
    d_vis = np.flipud(np.where(mask, v - v_ref, np.nan))
    luma = np.asarray(metrics.LUMA)
    d_comb = (ours_rgb.astype(np.float64) @ luma - cycles_rgb.astype(np.float64) @ luma) / 255.0
    d_comb = np.where(np.flipud(mask), d_comb, np.nan)
    return ((np.flipud(v), ours_rgb), (np.flipud(v_ref), cycles_rgb), (d_vis, d_comb), view)


def comparison_png(cmp: Comparison, scene=None) -> bytes:
    """The comparison figure as PNG bytes: a Visibility row and a Combined row, each ours | Cycles | signed
    difference (red: Penumbra darker, blue: lighter, saturating at ±DIFF_SATURATION), with titles, the
    colour scale and the numbers. Combined is shown through `scene`'s view transform (Blender's colour
    management); its Cycles panel is our shading times Cycles' visibility, which is what SSIM (shaded) is
    measured against (the reference itself is rendered white, with no materials)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    ours, theirs, diffs, view = _panels(cmp, scene)
    h, w = ours[0].shape
    fig = Figure(figsize=(3 * 3.2 + 0.8, 2 * 3.2 * h / w + 1.2), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3)
    m = cmp.metrics
    rows = [
        (ours[0], theirs[0], diffs[0], "Visibility", "ΔV = ours − Cycles"),
        (ours[1], theirs[1], diffs[1], f"Combined ({view})", "Δ display luminance"),
    ]
    for r, (ours, theirs, diff, label, diff_label) in enumerate(rows):
        grey = dict(cmap="gray", vmin=0.0, vmax=1.0) if ours.ndim == 2 else {}
        axes[r, 0].imshow(ours, interpolation="nearest", **grey)
        axes[r, 0].set_title(f"Penumbra {cmp.technique}: {label}", fontsize=8)
        axes[r, 1].imshow(theirs, interpolation="nearest", **grey)
        axes[r, 1].set_title(f"Cycles {cmp.reference_samples} spp: {label}" if r == 0 else
                             "Cycles visibility × our shading", fontsize=8)
        im = axes[r, 2].imshow(diff, cmap="RdBu", vmin=-DIFF_SATURATION, vmax=DIFF_SATURATION,
                               interpolation="nearest")
        axes[r, 2].set_facecolor("#d0d0d0")     # unlit pixels (outside the reference mask): grey
        axes[r, 2].set_title(diff_label, fontsize=8)
        bar = fig.colorbar(im, ax=axes[r, 2], fraction=0.046, pad=0.03,
                           ticks=[-DIFF_SATURATION, 0.0, DIFF_SATURATION])
        bar.ax.tick_params(labelsize=6)
        bar.set_label(f"red: Penumbra darker, blue: lighter (±{DIFF_SATURATION:g} saturates)", fontsize=6)
        for ax in axes[r]:
            ax.set_xticks([])
            ax.set_yticks([])
    numbers = (f"{cmp.scene} {w}×{h}: mae_shadow {_fmt(m['mae_shadow'], '.4f')} over {m['n_shadow']} px, "
               f"noise floor {_fmt((cmp.noise_floor or {}).get('mae_shadow'), '.4f')}, "
               f"ours {cmp.ours_ms:.1f} ms, Cycles {cmp.cycles_seconds:.2f} s / render")
    if cmp.undefined:
        numbers += f"\n{cmp.undefined}"
    if cmp.preview:
        numbers += f"\nPREVIEW: {cmp.preview}"
    fig.suptitle(numbers, fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
