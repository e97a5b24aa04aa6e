"""Benchmark: every technique (and, with a sweep, its knobs) against a high-sample Cycles reference, beside
Cycles itself (and optionally EEVEE) at a few sample counts on the same scene and resolution.

Per scene: build it, extract the snapshot once, load (or render and cache) the Cycles reference and its noise
floor (the same metrics between two reference seeds). Per technique × configuration: one warm-up frame (its
time is reported apart as the first-frame time: shader compilation, first uploads), then N timed frames; the
time reported is the median wall clock of `pipeline.render` (which returns once the passes are read back), with
the stage times of one more frame synchronised after every stage beside it, and the error is `metrics.compare` of the Visibility pass against the reference.

Peers: Cycles at 1, 4, 16, … samples, rendered fresh (not cached, seed `PEER_SEED`, unlike the reference's
seeds), timed as a user pays for one shadowed image (the render of the shadowed half of the reference pair,
measured between Blender's render_init and render_complete handlers), with V = shadowed / unshadowed at that
sample count. EEVEE on request, its V computed the same way from a shadowed and an unshadowed render.

Outputs (each written atomically): results.json (everything, with machine info), results.csv, results.md
(one Markdown table per scene) and pareto_<scene>.png (time against mae_shadow). `summary_table` gives,
per scene, our fastest configuration whose mae_shadow is no worse than Cycles at `target_samples`.

Sweeps: `sweep_configs(technique)` — the `sweep` the technique declares (settings-change dicts: RenderSettings
fields or technique options; by default the shadow-map sizes every technique inherits from `Technique`).
"""
from __future__ import annotations

import csv
import io
import json
import math
import os
import platform
import subprocess
import sys
import time
from contextlib import contextmanager

import numpy as np

from . import metrics, reference
from ..blender.compat import eevee_engine_id
from ..render import pipeline
from ..core.files import write_atomic
from ..core.settings import RenderSettings

DEFAULT_RESOLUTION = (128, 128)
DEFAULT_REPEATS = 5
DEFAULT_REFERENCE_SAMPLES = 1024
REFERENCE_SEEDS = (0, 1)            # the reference is seed 0; seed 1 only measures its noise floor
PEER_SEED = 7                       # peers never share the reference's samples
CYCLES_SAMPLES = (1, 4, 16, 64, 256)
EEVEE_SAMPLES = (1, 16, 64)
TARGET_SAMPLES = 64                 # the summary's bar: Cycles' error at this many samples
PEERS = ("cycles", "eevee")
CONFIG_BUDGET_S = 20.0              # timed frames per configuration stop at about this much time (≥ 1 frame)
PEER_BUDGET_S = 5.0                 # Cycles pairs per sample count: repeated (≤ repeats) within this much time

METRIC_KEYS = ("mae_shadow", "mae", "rmse", "max_abs", "pixel_match", "ssim_shaded", "n_mask", "n_shadow")
STAGES = ("upload", "gbuffer", "readback", "irradiance", "light_view", "shadow_map", "visibility", "accumulate")

_SHORT = {"shadow_map_size": "map", "pcf_radius": "radius", "pcf_taps": "taps",
          "pcss_blocker_samples": "blocker", "pcss_filter_samples": "filter", "averaged_light_samples": "samples"}



def _checked_choices(techniques, peers, known_techniques) -> tuple[list, tuple]:
    """Technique identifiers (all when none are named) and peer names, each checked: a ValueError names
    the unknown one and the valid choices."""
    technique_ids = [t.upper() for t in techniques] if techniques else list(known_techniques)
    for tid in technique_ids:
        if tid not in known_techniques:
            raise ValueError(f"unknown technique {tid!r}; choose from {', '.join(known_techniques)}")
    peers = tuple(p.lower() for p in (peers or ()))
    for p in peers:
        if p not in PEERS:
            raise ValueError(f"unknown peer {p!r}; choose from {', '.join(PEERS)}")
    return technique_ids, peers

def sweep_configs(identifier: str) -> list[dict]:
    """The configurations a --sweep runs for technique `identifier` (its declared `sweep`)."""
    from ..render.pipeline import get_technique
    return [dict(c) for c in get_technique(identifier).sweep]


def config_label(changes: dict) -> str:
    if not changes:
        return "default"
    parts = []
    for name, value in changes.items():
        if name == "extras" and isinstance(value, dict):
            parts += [f"{k}={_fmt_value(v)}" for k, v in value.items()]
        else:
            parts.append(f"{_SHORT.get(name, name)}={_fmt_value(value)}")
    return " ".join(parts)


def _fmt_value(v) -> str:
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    return str(v)


def configurations(identifier: str, base: RenderSettings, sweep: bool) -> list[tuple[str, dict, RenderSettings]]:
    """(label, changes, settings) per configuration; configurations that resolve to the same settings
    (e.g. map=1024 and radius=2 for PCF) run once, under the first label."""
    out, seen = [], set()
    for changes in (sweep_configs(identifier) if sweep else [{}]):
        settings = base.with_(technique=identifier, **changes)
        settings.validate()
        key = json.dumps(settings.effective(), sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            out.append((config_label(changes), changes, settings))
    return out


# ----------------------------------------------------------------------------------------------------------
# Timing helpers


class RenderTimer:
    """Wall time of each Blender render (render_init → render_complete handlers) while in the `with` block."""

    def __init__(self):
        self.durations: list[float] = []
        self._start = None

    def __enter__(self):
        import bpy

        @bpy.app.handlers.persistent
        def on_init(*_):
            self._start = time.perf_counter()

        @bpy.app.handlers.persistent
        def on_complete(*_):
            if self._start is not None:
                self.durations.append(time.perf_counter() - self._start)
                self._start = None

        self._handlers = [(bpy.app.handlers.render_init, on_init), (bpy.app.handlers.render_complete, on_complete)]
        for lst, fn in self._handlers:
            lst.append(fn)
        return self

    def __exit__(self, *exc):
        for lst, fn in self._handlers:
            if fn in lst:
                lst.remove(fn)
        return False


@contextmanager
def _stdout_to_stderr(enabled: bool = True):
    """Send what Blender prints on stdout (render status lines) to stderr, so stdout keeps the results."""
    if not enabled:
        yield
        return
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        os.dup2(2, 1)
        yield
    finally:
        try:
            sys.stdout.flush()
        except Exception:
            pass
        os.dup2(saved, 1)
        os.close(saved)


def _median(xs) -> float:
    return float(np.median(xs)) if len(xs) else float("nan")


def time_ours(snap, settings: RenderSettings, repeats: int, *, on_frame=None,
              budget_s: float | None = CONFIG_BUDGET_S) -> dict:
    """Warm-up frame, then up to `repeats` timed frames (fewer when they would exceed `budget_s`, never 0),
    as a user gets them (the GPU synchronised only where a result is read back); then one frame with per-stage
    synchronisation (pipeline.render's stage_times) for the stage breakdown."""
    t0 = time.perf_counter()
    result = pipeline.render(snap, settings)
    first_ms = (time.perf_counter() - t0) * 1000.0
    n = max(1, int(repeats))
    if budget_s:
        n = max(1, min(n, int(budget_s * 1000.0 // max(first_ms, 1e-3))))
    if on_frame:
        on_frame(1, n + 1)
    times = []
    for i in range(n):
        t0 = time.perf_counter()
        result = pipeline.render(snap, settings)
        times.append((time.perf_counter() - t0) * 1000.0)
        if on_frame:
            on_frame(i + 2, n + 1)
    stages = [pipeline.render(snap, settings, stage_times=True).timings]
    names = [s for s in STAGES if any(s in st for st in stages)]
    names += sorted({k for st in stages for k in st} - set(names))
    return {"first_frame_ms": first_ms, "times_ms": times, "time_ms": _median(times),
            "stages_ms": {s: _median([st.get(s, 0.0) for st in stages]) for s in names},
            "result": result}


# ----------------------------------------------------------------------------------------------------------
# Peers


def cycles_peer(scene, samples: int, width: int, height: int, ref, *, repeats: int = 1,
                budget_s: float | None = None) -> dict:
    """Cycles at `samples` (fresh renders, seed PEER_SEED): median shadowed-render time over up to `repeats`
    pairs (fewer once `budget_s` would be exceeded) and the error of the first pair's V against `ref`."""
    times, pairs, first = [], [], None
    for i in range(max(1, int(repeats))):
        with RenderTimer() as timer:
            peer = reference.cycles_visibility(scene, samples=samples, seed=PEER_SEED, width=width,
                                               height=height, use_cache=False, per_light=False)
        times.append((timer.durations[0] if timer.durations else peer.seconds / 2.0) * 1000.0)
        pairs.append(peer.seconds * 1000.0)
        first = first or (peer, bool(timer.durations))
        if budget_s is not None and sum(pairs) + pairs[-1] > budget_s * 1000.0:
            break
    peer, timed = first
    return {"time_ms": _median(times), "times_ms": times, "pair_ms": _median(pairs),
            "timed_by": "render handlers" if timed else "half of the pair",
            "metrics": metrics.compare(peer.visibility, ref.visibility, ref.mask), "seed": PEER_SEED}


def eevee_visibility(scene, *, samples: int, width: int, height: int, jitter: bool = True, view_layer=None):
    """EEVEE's V = L(shadowed) / L(unshadowed) under the reference's white-Lambert override and black world;
    unshadowed = every light's use_shadow off. Returns (V, mask, shadowed seconds, pair seconds). Every
    scene setting changed is restored afterwards, also on error."""
    import bpy

    view_layer = view_layer or reference._pick_view_layer(scene)
    r = scene.render
    with reference.measurement_scene(scene, view_layer, width, height, "penumbra_eevee_") as (st, tmpdir):
        st.set(r, "engine", eevee_engine_id())
        st.set(scene.eevee, "taa_render_samples", int(samples))
        st.set(scene.eevee, "use_raytracing", False)
        st.set(scene.eevee, "use_shadows", True)
        st.set(r, "filter_size", reference.POINT_FILTER_WIDTH)
        lights = {ob.data for ob in scene.objects if ob.type == "LIGHT"}
        for light in lights:
            if hasattr(light, "use_shadow_jitter"):
                st.set(light, "use_shadow_jitter", bool(jitter))
        images, seconds = [], []
        for unshadowed in (False, True):
            if unshadowed:
                for light in lights:
                    st.set(light, "use_shadow", False)
            path = os.path.join(tmpdir, f"{'unshadowed' if unshadowed else 'shadowed'}.exr")
            st.set(r, "filepath", path)
            with RenderTimer() as timer:
                t0 = time.perf_counter()
                bpy.ops.render.render(write_still=True, scene=scene.name, layer=view_layer.name)
                wall = time.perf_counter() - t0
            seconds.append(timer.durations[0] if timer.durations else wall)
            if not os.path.exists(path):
                raise RuntimeError(f"EEVEE wrote no image to {path}")
            images.append(reference.read_exr_combined(path))
        vis, mask = reference.visibility_from(images[0], images[1])
        return vis, mask, seconds[0], seconds[0] + seconds[1]


def eevee_peer(scene, samples: int, width: int, height: int, ref, jitter: bool = True) -> dict:
    vis, _mask, shadowed_s, pair_s = eevee_visibility(scene, samples=samples, width=width, height=height,
                                                      jitter=jitter)
    return {"time_ms": shadowed_s * 1000.0, "times_ms": [shadowed_s * 1000.0], "pair_ms": pair_s * 1000.0,
            "timed_by": "render handlers", "jitter": bool(jitter),
            "metrics": metrics.compare(vis, ref.visibility, ref.mask)}


# ----------------------------------------------------------------------------------------------------------
# Machine


def machine_info() -> dict:
    info = {"platform": platform.platform(), "python": platform.python_version(),
            "cpu_count": os.cpu_count(), "cpu": platform.processor() or platform.machine()}
    try:
        info["cpus_usable"] = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        pass
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        info["load_average"] = [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        pass
    try:
        import bpy
        info["blender"] = bpy.app.version_string
    except ImportError:
        pass
    info["numpy"] = np.__version__
    try:
        from ..render.pipeline import GpuWorker
        gl = GpuWorker.get().submit(lambda w: {k: w.ctx.info.get(k) for k in
                                               ("GL_RENDERER", "GL_VENDOR", "GL_VERSION")}).result()
        info["gl_renderer"], info["gl_vendor"], info["gl_version"] = (gl["GL_RENDERER"], gl["GL_VENDOR"],
                                                                     gl["GL_VERSION"])
    except Exception as exc:  # report, never fail the bench on it
        info["gl_renderer"] = f"unknown ({exc})"
    try:
        here = os.path.dirname(os.path.abspath(__file__))
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True,
                                timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
                               capture_output=True, text=True, timeout=10).stdout.strip()
        if commit:
            info["git_commit"] = commit + ("+dirty" if dirty else "")
    except Exception:
        pass
    return info


def machine_label(info: dict) -> str:
    cpu = str(info.get("cpu", "?"))
    for noise in ("(R)", "(TM)", " CPU", " Processor"):
        cpu = cpu.replace(noise, "")
    cpu = " ".join(cpu.split()).split(" @ ")[0]
    gl = str(info.get("gl_renderer", "?")).split(" (")[0]
    return f"{cpu} ×{info.get('cpus_usable', info.get('cpu_count', '?'))}, GL {gl}"


# ----------------------------------------------------------------------------------------------------------
# The run


def run_bench(out_dir, *, scenes=None, techniques=None, sweep: bool = False, peers=("cycles",),
              resolution=DEFAULT_RESOLUTION, repeats: int = DEFAULT_REPEATS,
              reference_samples: int = DEFAULT_REFERENCE_SAMPLES, cycles_samples=CYCLES_SAMPLES,
              eevee_samples=EEVEE_SAMPLES, eevee_jitter: bool = True, target_samples: int = TARGET_SAMPLES,
              overrides: dict | None = None, cache_dir=None, budget_s: float | None = CONFIG_BUDGET_S,
              peer_budget_s: float | None = PEER_BUDGET_S,
              progress: bool = True, stream=None, quiet_renders: bool = True) -> dict:
    """Run the benchmark and write results.json/.csv/.md and pareto_<scene>.png under `out_dir`; returns
    the results dict (also what results.json holds). `overrides` change the base RenderSettings of every
    configuration (the sweep's changes apply on top)."""
    import bpy

    from . import scenes as scene_lib
    from .progress import ProgressBar
    from ..blender.extract import extract
    from ..render.pipeline import TECHNIQUES

    stream = stream or sys.stderr
    scene_names = list(scenes) if scenes else [name for name, _ in scene_lib.list_scenes()]
    known = [name for name, _ in scene_lib.list_scenes()]
    for name in scene_names:
        if name not in known:
            raise ValueError(f"unknown scene {name!r}; valid scenes: {', '.join(known)}")
    technique_ids, peers = _checked_choices(techniques, peers, TECHNIQUES)
    base = RenderSettings().with_(**(overrides or {}))
    plans = {tid: configurations(tid, base, sweep) for tid in technique_ids}   # validates every config early
    width, height = int(resolution[0]), int(resolution[1])
    os.makedirs(out_dir, exist_ok=True)
    ref_kwargs = {"cache_dir": cache_dir} if cache_dir is not None else {}

    def log(text: str) -> None:
        if progress:
            stream.write(text + "\n")
            stream.flush()

    def bar(label: str):
        return ProgressBar(label, stream=stream) if progress else None

    started = time.perf_counter()
    results = {
        "machine": machine_info(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "args": {"scenes": scene_names, "techniques": technique_ids, "sweep": bool(sweep), "peers": list(peers),
                 "resolution": [width, height], "repeats": int(repeats),
                 "reference_samples": int(reference_samples), "reference_seeds": list(REFERENCE_SEEDS),
                 "cycles_samples": [int(s) for s in cycles_samples], "eevee_samples": [int(s) for s in eevee_samples],
                 "eevee_jitter": bool(eevee_jitter), "target_samples": int(target_samples),
                 "overrides": dict(overrides or {}), "budget_s": budget_s, "peer_budget_s": peer_budget_s,
                 "peer_seed": PEER_SEED},
        "timing_note": ("ours: median wall clock of pipeline.render over the timed frames after one warm-up "
                        "frame (scene already extracted; geometry upload included), stage times from one "
                        "more frame synchronised after every stage; peers: Blender wall time "
                        "of one shadowed render (render_init → render_complete), median over the repeated pairs "
                        "(Cycles: as many as fit in peer_budget_s, up to repeats; EEVEE: one), after an "
                        "untimed 1-sample warm-up pair per scene whose time is the peers' first-frame"),
        "scenes": [],
    }
    for si, name in enumerate(scene_names):
        log(f"[{si + 1}/{len(scene_names)}] {name}: building at {width}×{height}")
        scene = scene_lib.build(name, resolution=(width, height))
        t0 = time.perf_counter()
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
        extract_ms = (time.perf_counter() - t0) * 1000.0
        w, h = snap.camera.width, snap.camera.height

        log(f"{name}: Cycles reference {reference_samples} spp, seeds {REFERENCE_SEEDS} (cached after the first run)")
        with _stdout_to_stderr(quiet_renders):
            ref = reference.cycles_visibility(scene, samples=reference_samples, seed=REFERENCE_SEEDS[0],
                                              width=w, height=h, **ref_kwargs)
            floor = reference.noise_floor(scene, reference_samples, seeds=REFERENCE_SEEDS, width=w, height=h,
                                          **ref_kwargs)
        entry = {"scene": name, "resolution": [w, h], "triangles": int(snap.triangle_count),
                 "lights": len(snap.lights), "extract_ms": extract_ms,
                 "reference": {"samples": ref.samples, "seed": ref.seed, "seconds_pair": ref.seconds,
                               "cached": ref.cached, "key": ref.key, "n_mask": int(ref.mask.sum())},
                 "noise_floor": floor, "rows": []}

        for tid in technique_ids:
            for label, changes, settings in plans[tid]:
                pb = bar(f"{name} {tid} {label}")
                try:
                    timing = time_ours(snap, settings, repeats, budget_s=budget_s,
                                       on_frame=(lambda i, n: pb(i / n, f"frame {i}/{n}")) if pb else None)
                finally:
                    if pb:
                        pb.close()
                result = timing.pop("result")
                v = result.passes["Visibility"][..., 0]
                entry["rows"].append({
                    "kind": "ours", "technique": tid, "config": label, "changes": changes,
                    "settings": settings.effective(), "repeats": len(timing["times_ms"]), **timing,
                    "metrics": {**metrics.compare(v, ref.visibility, ref.mask),
                                "ssim_shaded": metrics.ssim_shaded(result.passes["Combined"],
                                                                   result.passes["Unshadowed"], ref.visibility)},
                    "stats": result.stats, "warnings": sorted(set(result.warnings))})

        for peer in peers:
            counts = cycles_samples if peer == "cycles" else eevee_samples
            warmup_ms = None
            if counts:
                # Untimed 1-sample pair first: the first render in a process or scene pays one-off costs
                # (EEVEE compiles its shaders, ~50 s here; Cycles loads its kernels). Reported as first-frame.
                pb = bar(f"{name} {peer} warm-up")
                if pb:
                    pb(0.0, "first render")
                try:
                    with _stdout_to_stderr(quiet_renders):
                        if peer == "eevee":
                            warmup_ms = eevee_visibility(scene, samples=1, width=w, height=h,
                                                         jitter=eevee_jitter)[2] * 1e3
                        else:
                            warmup_ms = cycles_peer(scene, 1, w, h, ref)["time_ms"]
                    if pb:
                        pb(1.0, f"{warmup_ms:.0f} ms")
                finally:
                    if pb:
                        pb.close()
            for spp in counts:
                pb = bar(f"{name} {peer} {spp} spp")
                if pb:
                    pb(0.0, "rendering")
                try:
                    with _stdout_to_stderr(quiet_renders):
                        if peer == "cycles":
                            row = cycles_peer(scene, int(spp), w, h, ref, repeats=repeats,
                                              budget_s=peer_budget_s)
                        else:
                            row = eevee_peer(scene, int(spp), w, h, ref, jitter=eevee_jitter)
                    if pb:
                        pb(1.0, f"{row['time_ms']:.0f} ms")
                finally:
                    if pb:
                        pb.close()
                entry["rows"].append({"kind": "peer", "technique": "Cycles" if peer == "cycles" else "EEVEE",
                                      "config": f"{int(spp)} spp", "samples": int(spp),
                                      "first_frame_ms": warmup_ms, "repeats": len(row["times_ms"]), **row})
                warmup_ms = None
        results["scenes"].append(entry)
        results["summary"] = summarize(results, target_samples)
        results["wall_seconds"] = time.perf_counter() - started
        write_outputs(out_dir, results, plot_scene=entry)
    results["summary"] = summarize(results, target_samples)
    results["wall_seconds"] = time.perf_counter() - started
    write_outputs(out_dir, results)
    return results


# ----------------------------------------------------------------------------------------------------------
# Summary


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def summarize(results: dict, target_samples: int = TARGET_SAMPLES) -> list[dict]:
    """Per scene: our fastest configuration with mae_shadow ≤ Cycles' at `target_samples` (None if none)."""
    out = []
    for entry in results["scenes"]:
        target = next((r for r in entry["rows"] if r["kind"] == "peer" and r["technique"] == "Cycles"
                       and r.get("samples") == target_samples), None)
        row = {"scene": entry["scene"], "target_samples": target_samples, "best": None,
               "target_mae_shadow": None, "target_ms": None, "speedup": None}
        if target is not None:
            bar_ = target["metrics"]["mae_shadow"]
            row["target_mae_shadow"], row["target_ms"] = bar_, target["time_ms"]
            ok = [r for r in entry["rows"] if r["kind"] == "ours" and _finite(r["metrics"]["mae_shadow"])
                  and _finite(bar_) and r["metrics"]["mae_shadow"] <= bar_]
            if ok:
                best = min(ok, key=lambda r: r["time_ms"])
                row["best"] = {"technique": best["technique"], "config": best["config"],
                               "time_ms": best["time_ms"], "mae_shadow": best["metrics"]["mae_shadow"]}
                row["speedup"] = target["time_ms"] / best["time_ms"] if best["time_ms"] > 0 else None
        out.append(row)
    return out


def _num(x, fmt: str, missing: str = "–") -> str:
    return format(x, fmt) if _finite(x) else missing


def summary_table(summary: list[dict]) -> str:
    """The compact text table printed at the end of a run."""
    spp = summary[0]["target_samples"] if summary else TARGET_SAMPLES
    head = ("scene", f"fastest of ours with mae_shadow ≤ Cycles-{spp}", "mae_shadow", f"Cycles-{spp} mae",
            "ours ms", f"Cycles-{spp} ms", "speed-up")
    rows = []
    for s in summary:
        best = s["best"]
        if s["target_ms"] is None:
            what = f"n/a (no Cycles-{spp} peer)"
        elif best is None:
            what = "none"
        else:
            what = f"{best['technique']} {best['config']}"
        rows.append((s["scene"], what, _num(best["mae_shadow"], ".4f") if best else "–",
                     _num(s["target_mae_shadow"], ".4f"), _num(best["time_ms"], ".1f") if best else "–",
                     _num(s["target_ms"], ".1f"), f"{s['speedup']:.1f}×" if _finite(s["speedup"]) else "–"))
    widths = [max(len(str(c)) for c in col) for col in zip(head, *rows)]
    lines = ["  ".join(str(c).ljust(wd) if i < 2 else str(c).rjust(wd) for i, (c, wd) in enumerate(zip(r, widths)))
             for r in [head, *rows]]
    lines.insert(1, "  ".join("-" * wd for wd in widths))
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------------------
# Outputs


def _clean(x):
    """JSON-safe copy: NaN/inf → None, numpy scalars → Python numbers."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


CSV_FIELDS = ["scene", "width", "height", "kind", "technique", "config", "repeats", "time_ms", "first_frame_ms",
              *METRIC_KEYS, "noise_floor_mae_shadow", "reference_samples"]


def results_csv(results: dict) -> str:
    stages = list(STAGES) + sorted({s for e in results["scenes"] for r in e["rows"]
                                    for s in r.get("stages_ms", {})} - set(STAGES))
    buf = io.StringIO()
    wr = csv.writer(buf, lineterminator="\n")
    wr.writerow(CSV_FIELDS + [f"stage_{s}_ms" for s in stages] + ["changes"])
    for e in results["scenes"]:
        for r in e["rows"]:
            m = r["metrics"]
            vals = [e["scene"], e["resolution"][0], e["resolution"][1], r["kind"], r["technique"], r["config"],
                    r.get("repeats"), r["time_ms"], r.get("first_frame_ms"), *[m.get(k) for k in METRIC_KEYS],
                    e["noise_floor"].get("mae_shadow"), e["reference"]["samples"]]
            vals += [r.get("stages_ms", {}).get(s) for s in stages]
            vals.append(json.dumps(r.get("changes", {}), sort_keys=True) if r["kind"] == "ours" else "")
            wr.writerow(["" if v is None or (isinstance(v, float) and not math.isfinite(v)) else
                         (f"{v:.6g}" if isinstance(v, float) else v) for v in vals])
    return buf.getvalue()


def results_markdown(results: dict) -> str:
    a, mach = results["args"], results["machine"]
    lines = ["# Penumbra benchmark", "",
             f"Machine: {mach.get('cpu', '?')} ({mach.get('cpus_usable', mach.get('cpu_count', '?'))} usable cores), "
             f"GL renderer {mach.get('gl_renderer', '?')}; Blender {mach.get('blender', '?')}; "
             f"{mach.get('git_commit', '')}", "",
             f"Resolution {a['resolution'][0]}×{a['resolution'][1]}; ours: median of up to {a['repeats']} timed "
             f"frames after a warm-up frame (first-frame = that warm-up, with shader compilation); Cycles/EEVEE: "
             f"time of the shadowed render only (median of the repeated renders), first-frame = an untimed "
             f"1-sample warm-up render; their error is that of V = shadowed/unshadowed at that sample count "
             f"(seed {a['peer_seed']}). All errors against Cycles at {a['reference_samples']} spp (seed "
             f"{a['reference_seeds'][0]}).", ""]
    if results.get("summary"):
        lines += ["## Summary", "", "```", summary_table(results["summary"]), "```", ""]
    head = ["technique", "config", "time ms (median)", "first-frame ms", "mae_shadow", "rmse", "max_abs",
            "pixel_match", "SSIM (shaded)"]
    for e in results["scenes"]:
        f, ref = e["noise_floor"], e["reference"]
        lines += [f"## {e['scene']} ({e['resolution'][0]}×{e['resolution'][1]}, {e['triangles']} triangles, "
                  f"{e['lights']} light{'s' if e['lights'] != 1 else ''})", "",
                  f"Reference: Cycles {ref['samples']} spp, {ref['seconds_pair']:.1f} s for the shadowed + "
                  f"unshadowed pair{' (cached)' if ref['cached'] else ''}. Noise floor (seed "
                  f"{a['reference_seeds'][0]} vs {a['reference_seeds'][1]}): mae_shadow "
                  f"{_num(f.get('mae_shadow'), '.4f')}, rmse {_num(f.get('rmse'), '.4f')}, max_abs "
                  f"{_num(f.get('max_abs'), '.4f')}, pixel_match {_num(f.get('pixel_match'), '.4f')}.", "",
                  "| " + " | ".join(head) + " |", "|" + "|".join(["---", "---"] + ["---:"] * 7) + "|"]
        for r in e["rows"]:
            m = r["metrics"]
            lines.append("| " + " | ".join([
                r["technique"], r["config"], _num(r["time_ms"], ".1f"), _num(r.get("first_frame_ms"), ".1f"),
                _num(m.get("mae_shadow"), ".4f"), _num(m.get("rmse"), ".4f"), _num(m.get("max_abs"), ".4f"),
                _num(m.get("pixel_match"), ".4f"), _num(m.get("ssim_shaded"), ".4f")]) + " |")
        lines.append("")
    lines.append(f"Total wall time: {results.get('wall_seconds', float('nan')):.0f} s")
    return "\n".join(lines) + "\n"


def plot_pareto(entry: dict, machine: dict, path: str) -> None:
    """time (ms, log) against mae_shadow: one curve per technique and per peer, the noise floor dashed."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5.5), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    groups: dict[tuple, list] = {}
    for r in entry["rows"]:
        groups.setdefault((r["kind"], r["technique"]), []).append(r)
    ys = []
    for (kind, tech), rows in groups.items():
        pts = sorted([(r["time_ms"], r["metrics"]["mae_shadow"], r) for r in rows
                      if _finite(r["time_ms"]) and r["time_ms"] > 0 and _finite(r["metrics"]["mae_shadow"])],
                     key=lambda p: p[0])
        if not pts:
            continue
        x, y = [p[0] for p in pts], [p[1] for p in pts]
        ys += y
        if kind == "peer":
            ax.plot(x, y, linestyle="--", marker="s", markersize=5, label=f"{tech} (spp)", alpha=0.85)
            for xi, yi, r in pts:
                ax.annotate(str(r["samples"]), (xi, yi), textcoords="offset points", xytext=(4, 3), fontsize=7)
        else:
            many = len(pts) > 8
            ax.plot(x, y, marker="o", markersize=4 if many else 5, linewidth=0.8 if many else 1.5,
                    alpha=0.75 if many else 1.0, label=tech)
            if len(pts) > 1:    # label the technique's own Pareto front only: the rest would pile up
                best = math.inf
                for xi, yi, r in pts:
                    if yi < best:
                        best = yi
                        text = r["config"] if len(r["config"]) <= 28 else r["config"][:27] + "…"
                        ax.annotate(text, (xi, yi), textcoords="offset points", xytext=(4, -9), fontsize=6,
                                    alpha=0.8)
    floor = entry["noise_floor"].get("mae_shadow")
    if _finite(floor):
        ax.axhline(floor, color="grey", linestyle="--", linewidth=1.2,
                   label=f"Cycles noise floor ({entry['reference']['samples']} spp)")
        ys.append(floor)
    ax.set_xscale("log")
    pos = [y for y in ys if y > 0]
    if pos and max(pos) / min(pos) > 20:
        ax.set_yscale("log")
    else:
        ax.set_ylim(bottom=0)
    ax.set_xlabel("time per frame (ms, log scale)")
    ax.set_ylabel("mae_shadow vs Cycles reference (lower is better)")
    res = entry["resolution"]
    ax.set_title(f"{entry['scene']} — {res[0]}×{res[1]} — {machine_label(machine)}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    write_atomic(path, buf.getvalue())


def write_outputs(out_dir: str, results: dict, plot_scene: dict | None = None) -> None:
    """results.json/.csv/.md, and the Pareto plot of `plot_scene` (of every scene when None)."""
    os.makedirs(out_dir, exist_ok=True)
    write_atomic(os.path.join(out_dir, "results.json"),
                  json.dumps(_clean(results), indent=1, allow_nan=False, default=str))
    write_atomic(os.path.join(out_dir, "results.csv"), results_csv(results))
    write_atomic(os.path.join(out_dir, "results.md"), results_markdown(results))
    for entry in ([plot_scene] if plot_scene is not None else results["scenes"]):
        plot_pareto(entry, results["machine"], os.path.join(out_dir, f"pareto_{entry['scene']}.png"))


# ----------------------------------------------------------------------------------------------------------
# Scaling: how frame time grows with the work (`bench --scaling`)

SCALING_SIZES = ((128, 128), (256, 256), (512, 512), (1024, 1024), (1920, 1080))
SCALING_TRIANGLES = (1_000, 10_000, 100_000, 500_000, 2_000_000)
SCALING_LIGHTS = (1, 2, 4, 8, 16)
SCALING_QUICK = {"sizes": ((32, 32), (64, 64)), "triangles": (1_000, 4_000), "lights": (1, 2)}
SCALING_BASE_SIZE = (384, 384)          # output size of the triangle and light sweeps
SCALING_QUICK_CYCLES = {"ladder": (1, 4, 16), "target": 16, "reference": 64}
SCALING_SPEEDUP_BAR = 30.0              # issue 14: at Cycles-64's error, the fastest technique ≥ 30× faster


def _city_scene(triangles: int, resolution):
    """The built-in city with about `triangles` triangles (10 per box) over the same 12 m square."""
    import bpy
    from . import scenes as scene_lib
    scene = scene_lib.build("city", resolution=resolution)
    n = max(1, int(round(math.sqrt(triangles / 10.0))))
    pitch = 150 * 0.08 / n
    city = bpy.data.objects["City"]
    old = city.data
    city.data = scene_lib._city_mesh("City", n, n, pitch=pitch, footprint=pitch * 0.6875, seed=20240607)
    city.data.materials.append(old.materials[0])
    bpy.data.meshes.remove(old)
    bpy.context.view_layer.update()
    return scene


def _lights_scene(lights: int, resolution):
    """`suzanne` with `lights` area lights on a ring above it (the scene's own light first)."""
    import bpy
    from . import scenes as scene_lib
    scene = scene_lib.build("suzanne", resolution=resolution)
    for k in range(1, lights):
        a = 2.0 * math.pi * k / lights
        scene_lib._add_area_light(scene, (2.5 * math.cos(a), 2.5 * math.sin(a), 4.0), (0.0, 0.0, 0.0), 1.0,
                                  radiance=scene_lib.TARGET_RADIANCE / lights)
    bpy.context.view_layer.update()
    return scene


def _log_slope(xs, ys) -> float:
    """Slope of log y against log x (least squares): 1 = linear growth, 0 = flat."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if _finite(y) and y > 0 and x > 0]
    if len(pts) < 2:
        return float("nan")
    lx, ly = np.array(pts).T
    return float(np.polyfit(lx, ly, 1)[0])


def matched_cycles(ladder, error: float) -> dict:
    """Cycles' sample count and shadowed-render time at mae_shadow `error`, from a measured ladder of
    (samples, time_ms, mae_shadow): log–log interpolation of error against samples, and of time against samples,
    between the two ladder counts whose errors bracket `error`. The ladder is made monotone first (error
    non-increasing by a running minimum, time non-decreasing by a running maximum: one noisy Cycles image can
    score worse than the one before it). Outside the ladder the match is clamped to its ends: "above" when
    `error` is below the top count's error (Cycles needs more samples than the ladder has: its time is a lower
    bound), "below" when it is above the lowest count's (Cycles' cheapest image is already as good)."""
    nan = float("nan")
    pts = sorted((int(s), float(t), float(e)) for s, t, e in ladder
                 if s > 0 and _finite(t) and t > 0 and _finite(e))
    if not pts or not _finite(error):
        return {"spp": nan, "time_ms": nan, "cycles_mae_shadow": nan, "clamped": None}
    tiny = 1e-12                                    # a zero error would have no logarithm
    spp = [p[0] for p in pts]
    times = np.maximum.accumulate([p[1] for p in pts])
    errs = np.minimum.accumulate([max(p[2], tiny) for p in pts])
    e = max(float(error), tiny)
    if e >= errs[0]:
        return {"spp": float(spp[0]), "time_ms": float(times[0]), "cycles_mae_shadow": float(errs[0]),
                "clamped": "below" if e > errs[0] else None}
    if e < errs[-1]:
        return {"spp": float(spp[-1]), "time_ms": float(times[-1]), "cycles_mae_shadow": float(errs[-1]),
                "clamped": "above"}
    i = next(k for k in range(len(pts) - 1) if errs[k + 1] <= e)      # errs[i] > e ≥ errs[i + 1]
    u = math.log(errs[i] / e) / math.log(errs[i] / errs[i + 1])

    def between(lo, hi):            # log-log, kept within its two ends (exp∘log can round past the upper one)
        return min(max(math.exp(math.log(lo) + u * math.log(hi / lo)), lo), hi)
    return {"spp": float(between(spp[i], spp[i + 1])), "time_ms": float(between(times[i], times[i + 1])),
            "cycles_mae_shadow": e, "clamped": None}


def _speedup_check(row: dict, target_samples: int, bar: float = SCALING_SPEEDUP_BAR) -> dict:
    """At Cycles-`target_samples`' error: our fastest technique with mae_shadow ≤ it, and its speed-up over
    that Cycles render measured at the same point."""
    target = next(c for c in row["cycles"] if c["samples"] == target_samples)
    limit = target["mae_shadow"]
    ok = [t for t, e in row["mae_shadow"].items() if _finite(e) and _finite(limit) and e <= limit]
    best = min(ok, key=lambda t: row["ms"][t]) if ok else None
    speedup = target["time_ms"] / row["ms"][best] if best is not None and row["ms"][best] > 0 else None
    scored = [t for t, e in row["mae_shadow"].items() if _finite(e)]
    closest = min(scored, key=lambda t: row["mae_shadow"][t]) if scored else None     # when none is as good
    return {"target_samples": target_samples, "target_mae_shadow": limit, "target_ms": target["time_ms"],
            "best": best, "best_ms": row["ms"][best] if best else None,
            "best_mae_shadow": row["mae_shadow"][best] if best else None, "speedup": speedup,
            "closest": closest, "closest_mae_shadow": row["mae_shadow"][closest] if closest else None,
            "bar": bar, "met": bool(speedup is not None and speedup >= bar)}


def _check_summary(axes: dict) -> dict:
    """The 30× check over every point of every axis that ran Cycles."""
    checks = [(axis, r["x"], r["check"]) for axis, d in axes.items() for r in d["rows"] if "check" in r]
    speedups = [c["speedup"] for _, _, c in checks if _finite(c["speedup"])]
    return {"points": len(checks), "met": sum(c["met"] for _, _, c in checks),
            "missed": [f"{a}={x}" for a, x, c in checks if not c["met"]],
            "none_as_accurate": sum(c["best"] is None for _, _, c in checks),
            "min_speedup": min(speedups) if speedups else None,
            "max_speedup": max(speedups) if speedups else None}


def _capped(points, cap, what: str, flag: str):
    """The sweep points whose size is ≤ `cap` (all when None); a ValueError when none is left."""
    if cap is None:
        return points
    kept = [p for p in points if p[0] <= cap]
    if not kept:
        raise ValueError(f"{flag} {cap} leaves no {what} to run (smallest {min(p[0] for p in points)})")
    return kept


def run_scaling(out_dir, *, techniques=None, peers=("cycles",), quick: bool = False, repeats: int = 3,
                reference_samples: int = DEFAULT_REFERENCE_SAMPLES, cycles_ladder=CYCLES_SAMPLES,
                target_samples: int = TARGET_SAMPLES, max_pixels: int | None = None,
                max_triangles: int | None = None, max_lights: int | None = None,
                cycles_max_pixels: int | None = None, base_size=SCALING_BASE_SIZE, cache_dir=None,
                budget_s: float | None = CONFIG_BUDGET_S, progress: bool = True, stream=None) -> dict:
    """Frame time of every technique against output size, triangle count (the city, 1k → 2M) and light count
    (suzanne, 1 → 16); peak structure memory per technique from FrameResult.stats["structure_bytes"]. With the
    Cycles peer, per point: a Cycles reference at `reference_samples` (cached by content), every technique's
    mae_shadow against it, Cycles fresh at each count of `cycles_ladder` (time of the shadowed render and its
    mae_shadow), Cycles' time at the sample count matching each technique's error (`matched_cycles`), and the
    30× check at Cycles-`target_samples` (`_speedup_check`). `max_pixels`/`max_triangles`/`max_lights` drop
    the sweep points above them; `cycles_max_pixels` runs Cycles only at points with at most that many
    pixels; `base_size` is the output size of the triangle and light sweeps. Writes scaling.json, scaling.md
    and scaling.png (log–log, slope per curve) under `out_dir`.
    `quick`: two tiny points per axis, one frame each, each technique in its cheap viewport mode with 128²
    maps, Cycles ladder SCALING_QUICK_CYCLES (a smoke test)."""
    import bpy

    from . import scenes as scene_lib
    from ..blender.extract import extract
    from ..render.pipeline import TECHNIQUES
    from ..render.viewport import coarse_settings

    stream = stream or sys.stderr
    technique_ids, peers = _checked_choices(techniques, peers, TECHNIQUES)
    if quick:
        repeats = 1
        cycles_ladder, target_samples = SCALING_QUICK_CYCLES["ladder"], SCALING_QUICK_CYCLES["target"]
        reference_samples = SCALING_QUICK_CYCLES["reference"]
    ladder = sorted({int(s) for s in cycles_ladder})
    if "cycles" in peers and int(target_samples) not in ladder:
        raise ValueError(f"target samples {target_samples} is not in the Cycles ladder "
                         f"{','.join(map(str, ladder))}")
    target_samples = int(target_samples)
    grid = SCALING_QUICK if quick else {"sizes": SCALING_SIZES, "triangles": SCALING_TRIANGLES,
                                        "lights": SCALING_LIGHTS}
    base = SCALING_QUICK["sizes"][-1] if quick else (int(base_size[0]), int(base_size[1]))
    axes = (("pixels", _capped([(w * h, lambda r=(w, h): scene_lib.build("suzanne", resolution=r))
                                for w, h in grid["sizes"]], max_pixels, "output size", "--max-pixels")),
            ("triangles", _capped([(n, lambda n=n: _city_scene(n, base)) for n in grid["triangles"]],
                                  max_triangles, "triangle count", "--max-triangles")),
            ("lights", _capped([(n, lambda n=n: _lights_scene(n, base)) for n in grid["lights"]],
                               max_lights, "light count", "--max-lights")))
    ref_kwargs = {"cache_dir": cache_dir} if cache_dir is not None else {}
    os.makedirs(out_dir, exist_ok=True)
    use_cycles = "cycles" in peers
    results = {"machine": machine_info(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "quick": bool(quick),
               "repeats": int(repeats),
               "cycles": {"ladder": ladder, "target_samples": target_samples,
                          "reference_samples": int(reference_samples), "reference_seed": REFERENCE_SEEDS[0],
                          "peer_seed": PEER_SEED, "max_pixels": cycles_max_pixels,
                          "speedup_bar": SCALING_SPEEDUP_BAR} if use_cycles else None,
               "caps": {"max_pixels": max_pixels, "max_triangles": max_triangles, "max_lights": max_lights},
               "base_size": list(base),
               "timing_note": "ours: median wall clock of pipeline.render after a warm-up frame (time_ours); "
                              "Cycles: the shadowed render of a fresh pair (cycles_peer), after one untimed "
                              "1-sample warm-up pair per run; Cycles-matched: log–log interpolation of "
                              "mae_shadow and of time against samples on the ladder (matched_cycles)",
               "axes": {}}
    started = time.perf_counter()
    warmed = False
    for axis, points in axes:
        rows = []
        for x, make in points:
            scene = make()
            snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
            w, h = snap.camera.width, snap.camera.height
            row = {"x": x, "resolution": [w, h], "triangles": int(snap.triangle_count),
                   "lights": len(snap.lights), "ms": {}, "bytes": {}, "mae_shadow": {}}
            ref = None
            if use_cycles and (cycles_max_pixels is None or w * h <= cycles_max_pixels):
                with _stdout_to_stderr(True):
                    ref = reference.cycles_visibility(scene, samples=reference_samples, seed=REFERENCE_SEEDS[0],
                                                      width=w, height=h, **ref_kwargs)
                row["reference"] = {"samples": ref.samples, "cached": ref.cached, "seconds_pair": ref.seconds}
            for tid in technique_ids:
                settings = RenderSettings(technique=tid)
                if quick:               # each technique's cheap viewport mode, small maps
                    settings = coarse_settings(settings, 128)
                timing = time_ours(snap, settings, repeats, budget_s=budget_s)
                row["ms"][tid] = timing["time_ms"]
                row["bytes"][tid] = int(sum(timing["result"].stats.get("structure_bytes", {}).values()))
                if ref is not None:
                    v = timing["result"].passes["Visibility"][..., 0]
                    row["mae_shadow"][tid] = metrics.compare(v, ref.visibility, ref.mask)["mae_shadow"]
            if ref is not None:
                with _stdout_to_stderr(True):
                    if not warmed:      # the first Cycles render of a process loads its kernels: untimed
                        results["cycles"]["warmup_ms"] = cycles_peer(scene, 1, w, h, ref)["time_ms"]
                        warmed = True
                    peers_ = [(spp, cycles_peer(scene, spp, w, h, ref, repeats=repeats, budget_s=PEER_BUDGET_S))
                              for spp in ladder]
                row["cycles"] = [{"samples": spp, "time_ms": p["time_ms"], "mae_shadow": p["metrics"]["mae_shadow"]}
                                 for spp, p in peers_]
                row["ms"][f"Cycles-{target_samples}"] = next(c["time_ms"] for c in row["cycles"]
                                                             if c["samples"] == target_samples)
                points_ = [(c["samples"], c["time_ms"], c["mae_shadow"]) for c in row["cycles"]]
                row["matched"] = {}
                for tid in technique_ids:
                    m = matched_cycles(points_, row["mae_shadow"][tid])
                    m["speedup"] = m["time_ms"] / row["ms"][tid] if _finite(m["time_ms"]) and row["ms"][tid] > 0 \
                        else None
                    row["matched"][tid] = m
                row["check"] = _speedup_check(row, target_samples)
            rows.append(row)
            if progress:
                stream.write(f"scaling {axis}={x}: " + ", ".join(f"{k} {v:.0f} ms" for k, v in row["ms"].items())
                             + ("" if "check" not in row else
                                f"; 30× check: {row['check']['best'] or 'none'} "
                                f"{_num(row['check']['speedup'], '.1f')}×") + "\n")
                stream.flush()
        names = list(dict.fromkeys(k for r in rows for k in r["ms"]))     # Cycles may be capped at some points
        xs = [r["x"] for r in rows]
        results["axes"][axis] = {
            "rows": rows,
            "slopes": {k: _log_slope(xs, [r["ms"].get(k) for r in rows]) for k in names},
            "matched_slopes": {t: _log_slope(xs, [r.get("matched", {}).get(t, {}).get("time_ms") for r in rows])
                               for t in technique_ids} if use_cycles else {}}
    results["check_30x"] = _check_summary(results["axes"])
    results["wall_seconds"] = time.perf_counter() - started
    write_atomic(os.path.join(out_dir, "scaling.json"),
                 json.dumps(_clean(results), indent=1, allow_nan=False, default=str))
    write_atomic(os.path.join(out_dir, "scaling.md"), scaling_markdown(results))
    plot_scaling(results, os.path.join(out_dir, "scaling.png"))
    return results


def _spp_text(m: dict, ladder) -> str:
    if not _finite(m.get("spp")):
        return "–"
    if m.get("clamped") == "above":
        return f"≥{ladder[-1]}"
    if m.get("clamped") == "below":
        return f"≤{ladder[0]}"
    return f"{m['spp']:.1f}"


def scaling_markdown(results: dict) -> str:
    cy = results.get("cycles")
    load = results["machine"].get("load_average")
    lines = [f"# Scaling ({machine_label(results['machine'])})", "",
             f"Blender {results['machine'].get('blender', '?')}, {results['machine'].get('git_commit', '')}"
             + (f"; load average at the start {load[0]:.1f} (shared machine: times are noisy)" if load else "")
             + ".", "",
             f"Ours: median wall clock of up to {results['repeats']} timed frames after a warm-up frame"
             + (" (quick: each technique's viewport mode, 128² maps)." if results["quick"] else "."), ""]
    if cy:
        ladder, spp = cy["ladder"], cy["target_samples"]
        c = results["check_30x"]
        lines += [f"Cycles: time of the shadowed render of a fresh pair (seed {cy['peer_seed']}) at "
                  f"{', '.join(map(str, ladder))} spp; every mae_shadow is against Cycles {cy['reference_samples']} "
                  f"spp (seed {cy['reference_seed']}). **Cycles-matched** = Cycles' time at the sample count whose "
                  f"mae_shadow equals the technique's, by log–log interpolation of mae_shadow against spp and of "
                  f"time against spp between the two ladder counts that bracket it (ladder made monotone first); "
                  f"≥{ladder[-1]}: more accurate than Cycles-{ladder[-1]} (its time is a lower bound), "
                  f"≤{ladder[0]}: no better than Cycles-{ladder[0]}."
                  + (f" Cycles runs only at points of at most {cy['max_pixels']} pixels." if cy["max_pixels"] else ""),
                  "",
                  f"**{cy['speedup_bar']:.0f}× check** (at Cycles-{spp}'s mae_shadow, our fastest technique at least "
                  f"{cy['speedup_bar']:.0f}× faster than Cycles-{spp} in the same run): "
                  + ("no point ran Cycles" if not c["points"] else
                     f"{'met' if c['met'] == c['points'] else 'missed'}: met at {c['met']} of {c['points']} points"
                     + (f", speed-ups {c['min_speedup']:.1f}× – {c['max_speedup']:.1f}×"
                        if _finite(c["min_speedup"]) else "")
                     + (f"; missed at {', '.join(c['missed'])}" if c["missed"] else "")
                     + (f"; at {c['none_as_accurate']} of them no technique reaches Cycles-{spp}'s mae_shadow"
                        if c.get("none_as_accurate") else "")), ""]
    for axis, data in results["axes"].items():
        rows = data["rows"]
        names = list(data["slopes"])
        scene = "suzanne" if axis != "triangles" else "city"
        if axis != "pixels" and rows:
            scene += f", {rows[0]['resolution'][0]}×{rows[0]['resolution'][1]}"
        lines += [f"## Frame time (ms) against {axis} ({scene})", "",
                  "| " + axis + " | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
        for r in rows:
            lines.append(f"| {r['x']} | " + " | ".join(_num(r["ms"].get(k), ".1f") for k in names) + " |")
        lines.append("| log–log slope | " + " | ".join(_num(data["slopes"][k], ".2f") for k in names) + " |")
        peak = {k: max(r["bytes"].get(k, 0) for r in rows) for k in names if not k.startswith("Cycles")}
        lines += ["", "Peak structure memory (MiB): " + ", ".join(f"{k} {v / 2**20:.1f}" for k, v in peak.items()),
                  ""]
        if not cy or not any("matched" in r for r in rows):
            continue
        ours = [k for k in names if not k.startswith("Cycles")]
        lines += [f"### Error and Cycles-matched time against {axis}", "",
                  f"| {axis} | technique | ms | mae_shadow | matched spp | Cycles ms at matched spp | speed-up |",
                  "|---|---|---:|---:|---:|---:|---:|"]
        for r in rows:
            for t in ours if "matched" in r else ():
                m = r["matched"][t]
                lines.append(f"| {r['x']} | {t} | {_num(r['ms'][t], '.1f')} | {_num(r['mae_shadow'][t], '.4f')} | "
                             f"{_spp_text(m, cy['ladder'])} | {_num(m['time_ms'], '.1f')} | "
                             f"{_num(m['speedup'], '.1f')}× |")
        lines += ["", "Log–log slope of the Cycles-matched time: " + ", ".join(
            f"{t} {_num(data['matched_slopes'].get(t), '.2f')}" for t in ours) + ".",
                  "", "Cycles ladder (ms / mae_shadow):", "",
                  f"| {axis} | reference | " + " | ".join(f"{s} spp" for s in cy["ladder"]) + " |",
                  "|---" * (len(cy["ladder"]) + 2) + "|"]
        for r in rows:
            if "cycles" in r:
                ref = r["reference"]
                lines.append(f"| {r['x']} | {ref['samples']} spp{' (cached)' if ref['cached'] else ''} | " + " | ".join(
                    f"{_num(c['time_ms'], '.0f')} / {_num(c['mae_shadow'], '.4f')}" for c in r["cycles"]) + " |")
        spp = cy["target_samples"]
        lines += ["", f"{cy['speedup_bar']:.0f}× check against {axis}:", "",
                  f"| {axis} | Cycles-{spp} mae_shadow | Cycles-{spp} ms | fastest of ours with mae_shadow ≤ it | "
                  f"its mae_shadow | its ms | speed-up | met | most accurate of ours (mae_shadow) |",
                  "|---|---:|---:|---|---:|---:|---:|---|---|"]
        for r in rows:
            if "check" in r:
                c = r["check"]
                lines.append(f"| {r['x']} | {_num(c['target_mae_shadow'], '.4f')} | {_num(c['target_ms'], '.0f')} | "
                             f"{c['best'] or 'none'} | {_num(c['best_mae_shadow'], '.4f')} | "
                             f"{_num(c['best_ms'], '.1f')} | {_num(c['speedup'], '.1f')}× | "
                             f"{'yes' if c['met'] else 'no'} | {c.get('closest') or '–'} "
                             f"({_num(c.get('closest_mae_shadow'), '.4f')}) |")
        lines.append("")
    lines.append(f"Total wall time: {results.get('wall_seconds', float('nan')):.0f} s")
    return "\n".join(lines) + "\n"


def plot_scaling(results: dict, path: str) -> None:
    """One log–log panel per axis: frame time per technique (solid), Cycles at the spp matching that
    technique's error (dashed, same colour) and Cycles at the check's sample count (black, dotted); slopes in
    the legend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    axes = results["axes"]
    fig = Figure(figsize=(6 * len(axes), 7), dpi=100)
    FigureCanvasAgg(fig)
    for i, (axis, data) in enumerate(axes.items()):
        ax = fig.add_subplot(1, len(axes), i + 1)
        colours = {}
        for name, slope in data["slopes"].items():
            pts = [(r["x"], r["ms"][name]) for r in data["rows"] if _finite(r["ms"].get(name))
                   and r["ms"][name] > 0]
            if not pts:
                continue
            xs, ys = zip(*pts)
            label = f"{name} (slope {slope:.2f})" if _finite(slope) else name
            if name.startswith("Cycles"):
                ax.plot(xs, ys, ":", color="black", marker="s", ms=3, label=label)
            else:
                colours[name] = ax.plot(xs, ys, "-", marker="o", ms=3, label=label)[0].get_color()
        for name, colour in colours.items():
            pts = [(r["x"], r["matched"][name]["time_ms"]) for r in data["rows"] if "matched" in r
                   and _finite(r["matched"][name]["time_ms"])]
            if pts:
                xs, ys = zip(*pts)
                slope = data["matched_slopes"].get(name)
                ax.plot(xs, ys, "--", color=colour, marker="x", ms=3, alpha=0.8,
                        label=f"Cycles ≈ {name}'s error" + (f" (slope {slope:.2f})" if _finite(slope) else ""))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(axis)
        ax.set_ylabel("frame time (ms)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.13))   # below: 17 curves
    fig.suptitle(f"Penumbra scaling — {machine_label(results['machine'])}; dashed: Cycles at the spp matching "
                 f"each technique's mae_shadow (log–log interpolation on the ladder)", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    write_atomic(path, buf.getvalue())
