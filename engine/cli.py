"""Command line: `python -m penumbra render|scenes …` (bench, compare and stress plug in here too)."""
from __future__ import annotations

import argparse
import os
import sys
import time

from .core.settings import RenderSettings
from .measure.progress import ProgressBar
from .measure.studies import STUDIES


def _import_bpy():
    try:
        import bpy  # noqa: F401
    except ImportError:
        sys.exit("penumbra: this command needs Blender's Python module 'bpy' (bpy==5.0.1 for Python 3.11); "
                 "run `bash tools/setup.sh` and use .venv/bin/python")
    import penumbra
    try:
        penumbra.register()
    except ValueError:
        pass                # already registered in this process
    return bpy


def parse_overrides(pairs: list[str]) -> dict:
    """`--set name=value` pairs, typed like the RenderSettings field they name."""
    from .techniques import all_options
    defaults = RenderSettings()
    options = all_options()
    names = [n for n in RenderSettings.field_names() if n != "extras"] + list(options)
    out = {}
    for pair in pairs or []:
        name, sep, raw = pair.partition("=")
        if not sep or name not in names:
            raise SystemExit(f"penumbra: --set expects NAME=VALUE with NAME one of {', '.join(names)}; "
                             f"got '{pair}'")
        kind = type(options[name].default) if name in options else type(getattr(defaults, name))
        try:
            out[name] = raw.lower() in ("1", "true", "yes", "on") if kind is bool else kind(raw)
        except ValueError:
            raise SystemExit(f"penumbra: setting '{name}' expects a {kind.__name__}, got '{raw}'") from None
    return out


def load_scene(args):
    """The bpy scene named by --scene (built in code) or FILE.blend."""
    bpy = _import_bpy()
    from .measure import scenes
    if args.blend:
        if not os.path.isfile(args.blend):
            raise SystemExit(f"penumbra: no such file '{args.blend}'")
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        scene = bpy.context.scene
        if args.resolution:
            scene.render.resolution_x, scene.render.resolution_y = args.resolution
            scene.render.resolution_percentage = 100
        return scene
    try:
        return scenes.build(args.scene, resolution=tuple(args.resolution or (256, 256)))
    except ValueError as exc:
        raise SystemExit(f"penumbra: {exc}") from None


def settings_for(scene, args) -> RenderSettings:
    from .blender.settings_bridge import settings_from_scene
    settings = settings_from_scene(scene)
    changes = parse_overrides(args.set)
    if args.technique:
        changes["technique"] = args.technique
    if args.map_size:
        changes["shadow_map_size"] = args.map_size
    if args.samples:
        changes["reference_samples"] = args.samples
    settings = settings.with_(**changes)
    try:
        settings.validate()
    except ValueError as exc:
        raise SystemExit(f"penumbra: {exc}") from None
    return settings


def cmd_render(args) -> int:
    scene = load_scene(args)
    settings = settings_for(scene, args)
    import bpy
    from .core import exr
    from .render import pipeline
    from .blender.extract import extract
    t0 = time.perf_counter()
    try:
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    except ValueError as exc:
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    extract_ms = (time.perf_counter() - t0) * 1000.0
    bar = ProgressBar(f"{snap.name} {settings.technique}")
    t1 = time.perf_counter()
    try:
        result = pipeline.render(snap, settings, on_progress=bar)
    finally:
        bar.close()
    wall_ms = (time.perf_counter() - t1) * 1000.0
    for message in result.warnings:
        print(f"warning: {message}", file=sys.stderr)
    meta = {"penumbra:technique": settings.technique, "penumbra:scene": snap.name,
            "penumbra:frame_ms": f"{wall_ms:.2f}"}
    exr.write(args.out, result.passes, meta)
    if args.png:
        exr.write_png(args.png, exr.to_srgb8(result.passes["Combined"]))
    print(f"scene {snap.name}: {snap.triangle_count} triangles, {len(snap.lights)} lights, "
          f"{snap.camera.width}x{snap.camera.height}, technique {settings.technique}, "
          f"map {settings.shadow_map_size}")
    print(f"  extract      {extract_ms:9.1f} ms")
    for name, ms in result.timings.items():
        print(f"  {name:<12} {ms:9.1f} ms")
    print(f"  frame total  {wall_ms:9.1f} ms (first frame in this process: includes shader compilation)")
    print(f"wrote {args.out}" + (f" and {args.png}" if args.png else ""))
    return 0


def cmd_compare(args) -> int:
    scene = load_scene(args)
    settings = settings_for(scene, args)
    from .measure.compare import compare
    bar = ProgressBar(f"{scene.name} {settings.technique}")
    try:
        cmp = compare(scene, settings, samples=args.cycles_samples, out_dir=args.out, repeats=args.repeats,
                      with_noise_floor=not args.no_noise_floor, on_progress=bar)
    except ValueError as exc:
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    finally:
        bar.close()
    for message in cmp.warnings:
        print(f"warning: {message}", file=sys.stderr)
    print(cmp.summary())
    if args.out:
        print(f"wrote {args.out}/{cmp.scene}_{cmp.technique.lower()}{{.exr,_cycles.exr,_compare.png,.json}}")
    return 0


def cmd_stress(args) -> int:
    from .measure import stress
    rows = stress.run(args.technique, args.case, parse_overrides(args.set),
                      progress=lambda line: print(line, file=sys.stderr, flush=True))
    print(stress.format_table(rows))
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"{len(rows) - len(failed)} passed, {len(failed)} failed")
    return 0 if not failed else 1


def cmd_fuzz(args) -> int:
    _import_bpy()
    from .measure import fuzz
    print(fuzz.HEADER, flush=True)
    bar = ProgressBar("fuzz")
    try:
        rows = fuzz.run(args.seed, args.n, args.technique, resolution=tuple(args.resolution),
                        samples=args.cycles_samples, overrides=parse_overrides(args.set), out_dir=args.out,
                        on_row=lambda row: print(fuzz.format_row(row), flush=True), on_progress=bar)
    finally:
        bar.close()
    print(fuzz.summary(rows))
    failed = [r for r in rows if r.status != "ok"]
    if failed and args.out:
        print(f"saved {len({r.seed for r in failed})} scene(s) over their bound in {args.out}/"
              "<seed>.blend with <seed>_<technique>.{json,png}")
    return 1 if failed else 0


def cmd_scenes(args) -> int:
    from .measure.scenes import list_scenes
    for name, description in list_scenes():
        print(f"{name:<12} {description}")
    return 0


def _csv_list(text: str) -> list[str]:
    return [item.strip() for item in (text or "").split(",") if item.strip()]


def _int_list(text: str) -> list[int]:
    try:
        return [int(item) for item in _csv_list(text)]
    except ValueError:
        raise SystemExit(f"penumbra: expected comma-separated integers, got '{text}'") from None


def cmd_bench(args) -> int:
    _import_bpy()
    if args.study:
        # The paper studies: each study module has its own options; pass them after `--`.
        from .measure import studies
        return studies.run(args.study, ["--out", args.out, *args.study_args])
    if args.viewport:
        from .measure import viewport_bench
        scenes = _csv_list(args.scenes) or ["suzanne", "balls", "city"]
        techniques = [t.upper() for t in _csv_list(args.techniques)] or None
        viewport_bench.run(args.out, scenes=scenes, techniques=techniques, size=tuple(args.viewport_size),
                           repeats=max(1, min(args.repeats, 5)))
        print(f"wrote {args.out}/viewport.{{json,md}}")
        return 0
    from .measure import bench
    peers = [p.lower() for p in _csv_list(args.peers)]
    if peers in (["none"], ["off"]):
        peers = []
    t0 = time.perf_counter()
    try:
        results = bench.run_bench(
            args.out, scenes=_csv_list(args.scenes) or None,
            techniques=[t.upper() for t in _csv_list(args.techniques)] or None, sweep=args.sweep, peers=peers,
            resolution=tuple(args.resolution), repeats=args.repeats, reference_samples=args.reference_samples,
            cycles_samples=_int_list(args.cycles_samples), eevee_samples=_int_list(args.eevee_samples),
            eevee_jitter=not args.eevee_no_jitter, target_samples=args.target_samples,
            overrides=parse_overrides(args.set), budget_s=args.budget or None,
            peer_budget_s=args.peer_budget or None)
    except ValueError as exc:
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    print(bench.summary_table(results["summary"]))
    print(f"bench wall time {time.perf_counter() - t0:.0f} s; wrote {args.out}/results.{{json,csv,md}} and "
          f"pareto_<scene>.png")
    return 0


def _common_render_args(p) -> None:
    from .techniques import TECHNIQUES
    p.add_argument("--technique", type=str.upper, choices=list(TECHNIQUES),
                   help="shadow technique (default: the scene's setting)")
    p.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"))
    p.add_argument("--map-size", type=int, help="shadow-map size in texels")
    p.add_argument("--samples", type=int, help="light samples for REFERENCE")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="any render setting, repeatable")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m penumbra", description="Penumbra soft-shadow renderer")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a .blend file or a built-in scene to a multilayer EXR")
    src = r.add_mutually_exclusive_group(required=True)
    src.add_argument("blend", nargs="?", help="a .blend file")
    src.add_argument("--scene", help="a built-in scene (see `python -m penumbra scenes`)")
    _common_render_args(r)
    r.add_argument("--out", required=True, help="multilayer EXR to write")
    r.add_argument("--png", help="also write Combined as an sRGB PNG")
    r.set_defaults(func=cmd_render)

    c = sub.add_parser("compare", help="render with Penumbra and Cycles, print error and time side by side")
    src = c.add_mutually_exclusive_group(required=True)
    src.add_argument("blend", nargs="?", help="a .blend file")
    src.add_argument("--scene", help="a built-in scene")
    _common_render_args(c)
    c.add_argument("--out", help="folder for EXRs, the comparison PNG and a JSON of the numbers")
    c.add_argument("--cycles-samples", type=int, default=256, help="Cycles samples of the reference")
    c.add_argument("--repeats", type=int, default=3, help="timed repeats of our frame (median reported)")
    c.add_argument("--no-noise-floor", action="store_true", help="skip the second Cycles seed")
    c.set_defaults(func=cmd_compare)

    b = sub.add_parser("bench", help="time and error of every technique against Cycles (and EEVEE), per scene")
    b.add_argument("--scenes", default="", help="comma-separated built-in scenes (default: all)")
    b.add_argument("--techniques", default="", help="comma-separated techniques (default: all)")
    b.add_argument("--sweep", action="store_true", help="sweep each technique's knobs (map size, kernels, …)")
    b.add_argument("--peers", default="cycles", help="comma-separated peers: cycles, eevee, or none")
    b.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"), default=[128, 128])
    b.add_argument("--repeats", type=int, default=5, help="timed frames per configuration (median reported)")
    b.add_argument("--reference-samples", type=int, default=1024, help="Cycles samples of the reference")
    b.add_argument("--cycles-samples", default="1,4,16,64,256", help="sample counts of the Cycles peer")
    b.add_argument("--eevee-samples", default="1,16,64", help="sample counts of the EEVEE peer")
    b.add_argument("--eevee-no-jitter", action="store_true",
                   help="EEVEE with Blender's default unjittered shadows (default: lights' shadow jitter on)")
    b.add_argument("--target-samples", type=int, default=64,
                   help="the summary lists our fastest configuration at least as accurate as Cycles at this")
    b.add_argument("--budget", type=float, default=20.0,
                   help="seconds of timed frames per configuration before fewer repeats are taken (0: no cap)")
    b.add_argument("--peer-budget", type=float, default=5.0,
                   help="seconds of Cycles renders per sample count before fewer repeats are taken (0: no cap)")
    b.add_argument("--set", action="append", metavar="NAME=VALUE", help="base render setting, repeatable")
    b.add_argument("--viewport", action="store_true",
                   help="interactive latency instead: first and refined frame after a camera move, an object "
                        "move and a light edit (default scenes suzanne, balls, city)")
    b.add_argument("--viewport-size", type=int, nargs=2, metavar=("W", "H"), default=[1280, 720])
    b.add_argument("--study", choices=tuple(STUDIES),
                   help="a paper's study instead: SSM's §4.2 curves (map size, light size, occluder position) "
                        "or the bitmask paper's Table 2/3 columns; further options after `--`")
    b.add_argument("study_args", nargs="*", help=argparse.SUPPRESS)
    b.add_argument("--out", required=True, help="folder for results.json/.csv/.md and pareto_<scene>.png")
    b.set_defaults(func=cmd_bench)

    st = sub.add_parser("stress", help="stiff and extreme cases × every technique: NaN/Inf, range, error, time")
    st.add_argument("--technique", action="append", type=str.upper, help="technique(s) (default: all)")
    st.add_argument("--case", action="append", help="case(s) (default: all)")
    st.add_argument("--set", action="append", metavar="NAME=VALUE", help="render setting, repeatable")
    st.set_defaults(func=cmd_stress)

    from .techniques import TECHNIQUES
    fz = sub.add_parser("fuzz", help="random scenes × techniques against Cycles; saves every scene over its bound")
    fz.add_argument("--seed", type=int, default=0, help="first scene seed")
    fz.add_argument("--n", type=int, default=10, help="number of scenes (seeds seed … seed+n-1)")
    fz.add_argument("--technique", action="append", type=str.upper, choices=list(TECHNIQUES),
                    help="technique(s), repeatable (default: all)")
    fz.add_argument("--out", help="folder for <seed>.blend, <seed>_<technique>.json and .png of each failure")
    fz.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"), default=[64, 64])
    fz.add_argument("--cycles-samples", type=int, default=256, help="Cycles samples of the reference")
    fz.add_argument("--set", action="append", metavar="NAME=VALUE", help="render setting, repeatable")
    fz.set_defaults(func=cmd_fuzz)

    s = sub.add_parser("scenes", help="list the built-in scenes")
    s.set_defaults(func=cmd_scenes)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)
