"""Command line: `python -m penumbra render|scenes …` (bench, compare and stress plug in here too)."""
from __future__ import annotations

import argparse
import os
import sys
import textwrap
import time
from pathlib import Path

from .core.arguments import CYCLES_SAMPLES_RANGE, RESOLUTION_RANGE, Parser, add_alias, option_type, ranged
from .core.settings import RENAMED, SHARED, RenderSettings, setting_option, setting_options
from .measure.progress import ProgressBar
from .measure.studies import STUDIES


class Refusal(SystemExit):
    """Bad input: `main` prints the one-line message and exits with status 2, like argparse's own errors."""


def version() -> str:
    """The version the extension's manifest declares (pyproject.toml carries the same number)."""
    import tomllib
    manifest = Path(__file__).resolve().parent.parent / "blender_manifest.toml"
    try:
        return tomllib.loads(manifest.read_text())["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return "unknown"


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


_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def parse_overrides(pairs: list[str]) -> dict:
    """`--set name=value` pairs, typed like the setting they name and checked against its range."""
    from .techniques import TECHNIQUES
    defaults = RenderSettings()
    options = {o.name: o for o in setting_options()}
    names = list(dict.fromkeys([n for n in RenderSettings.field_names() if n != "extras"] + list(options)))
    out = {}
    for pair in pairs or []:
        name, sep, raw = pair.partition("=")
        if name in RENAMED:
            print(f"penumbra: setting '{name}' is now called '{RENAMED[name]}'", file=sys.stderr)
            name = RENAMED[name]
        if not sep or name not in names:
            raise Refusal(f"penumbra: --set expects NAME=VALUE with NAME one of {', '.join(names)}; "
                          f"got '{pair}'")
        kind = type(options[name].default) if name in options else type(getattr(defaults, name))
        if kind is bool:
            if raw.lower() not in _TRUE + _FALSE:
                raise Refusal(f"penumbra: setting '{name}' expects true or false, got '{raw}'")
            value = raw.lower() in _TRUE
        else:
            try:
                value = kind(raw)
            except ValueError:
                raise Refusal(f"penumbra: setting '{name}' expects a {kind.__name__}, got '{raw}'") from None
        try:
            if name in options:
                options[name].check(value)
            elif name == "technique" and value not in TECHNIQUES:
                raise ValueError(f"Unknown technique '{value}'; choose one of {', '.join(TECHNIQUES)}")
        except ValueError as exc:
            raise Refusal(f"penumbra: {exc}") from None
        out[name] = value
    return out


def load_scene(args):
    """The bpy scene named by --scene (built in code) or FILE.blend."""
    bpy = _import_bpy()
    from .measure import scenes
    if args.blend:
        if not os.path.isfile(args.blend):
            raise Refusal(f"penumbra: no such file '{args.blend}'")
        try:
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        except RuntimeError as exc:     # truncated, corrupt or not a .blend at all
            reason = (str(exc).strip().splitlines() or ["unreadable"])[-1].removeprefix("Error: ")
            raise Refusal(f"penumbra: cannot read '{args.blend}' as a .blend file ({reason})") from None
        scene = bpy.context.scene
        if args.resolution:
            scene.render.resolution_x, scene.render.resolution_y = args.resolution
            scene.render.resolution_percentage = 100
        return scene
    try:
        return scenes.build(args.scene, resolution=tuple(args.resolution or (256, 256)))
    except ValueError as exc:
        raise Refusal(f"penumbra: {exc}") from None


def settings_for(scene, args) -> RenderSettings:
    from .blender.settings_bridge import settings_from_scene
    settings = settings_from_scene(scene)
    changes = dict(args.overrides)
    if args.technique:
        changes["technique"] = args.technique
    if args.map_size is not None:
        changes["shadow_map_size"] = args.map_size
    if args.light_samples is not None:
        changes["averaged_light_samples"] = args.light_samples
    settings = settings.with_(**changes)
    try:
        settings.validate()
    except ValueError as exc:
        raise Refusal(f"penumbra: {exc}") from None
    return settings


def check_outputs(files=(), folders=()) -> None:
    """Refuse unwritable outputs before any work: one line naming the path, exit status 2."""
    from .core.files import OutputError, check_output_file, check_output_folder
    try:
        for path in files:
            if path:
                check_output_file(path)
        for path in folders:
            if path:
                check_output_folder(path)
    except OutputError as exc:
        raise _refuse(exc) from None


def _refuse(exc) -> SystemExit:
    """`penumbra: <message>` on stderr and exit status 2 (argparse's status for bad arguments)."""
    print(f"penumbra: {exc}", file=sys.stderr)
    return SystemExit(2)


def cmd_render(args) -> int:
    check_outputs(files=[args.out, args.png])
    scene = load_scene(args)
    settings = settings_for(scene, args)
    import bpy
    from .core import exr
    from .render import pipeline
    from .blender.extract import extract
    t0 = time.perf_counter()
    try:
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene, settings=settings)
    except ValueError as exc:
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    extract_ms = (time.perf_counter() - t0) * 1000.0
    bar = ProgressBar(f"{snap.name} {settings.technique}")
    t1 = time.perf_counter()
    try:
        result = pipeline.render(snap, settings, on_progress=bar, stage_times=True)   # it prints them
    except ValueError as exc:           # e.g. an image too large for the GPU (engine/gpu/frame.py)
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    finally:
        bar.close()
    wall_ms = (time.perf_counter() - t1) * 1000.0
    for message in result.warnings:
        print(f"warning: {message}", file=sys.stderr)
    meta = {"penumbra:technique": settings.technique, "penumbra:scene": snap.name,
            "penumbra:frame_ms": f"{wall_ms:.2f}"}
    from .core.files import OutputError
    from .blender.compat import write_display_png
    try:
        if args.out.lower().endswith(".png"):   # through the scene's view transform, as Blender's own PNG
            write_display_png(args.out, result.passes["Combined"], scene)
        else:
            exr.write(args.out, result.passes, meta)
        if args.png:
            write_display_png(args.png, result.passes["Combined"], scene)
    except OutputError as exc:          # what was written before stays complete (atomic writes)
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
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
    check_outputs(folders=[args.out])
    scene = load_scene(args)
    settings = settings_for(scene, args)
    from .core.files import OutputError
    from .measure.compare import compare, write_outputs
    bar = ProgressBar(f"{scene.name} {settings.technique}")
    _interrupt_cycles_on_sigint()
    try:
        cmp = compare(scene, settings, samples=args.cycles_samples, repeats=args.repeats,
                      with_noise_floor=not args.no_noise_floor, on_progress=bar)
    except ValueError as exc:
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("penumbra: compare cancelled", file=sys.stderr)
        return 130
    finally:
        bar.close()
    for message in cmp.warnings:
        print(f"warning: {message}", file=sys.stderr)
    print(cmp.summary())                # the numbers first: they survive an output that fails
    if args.out:
        try:
            paths = write_outputs(args.out, cmp, scene)
        except OutputError as exc:      # what was written before stays complete (atomic writes)
            print(f"penumbra: {exc}", file=sys.stderr)
            return 2
        print("wrote " + ", ".join(paths))
    return 0


def _interrupt_cycles_on_sigint() -> None:
    """Ctrl-C during a Cycles render: Blender swallows the KeyboardInterrupt raised inside Cycles' Python
    callback (it logs it and saves the image), so the handler also sets the flag the reference checks after
    every render; the run then stops there (exit 130) and the interrupted render is not cached. Cycles
    itself finishes the render in progress: nothing here can stop it sooner."""
    import signal
    from .measure import reference
    reference.interrupted.clear()

    def on_sigint(signum, frame):
        reference.interrupted.set()
        raise KeyboardInterrupt
    signal.signal(signal.SIGINT, on_sigint)


def cmd_stress(args) -> int:
    from .measure import stress
    if args.list:
        print(stress.format_cases())
        return 0
    try:
        rows = stress.run(args.technique, args.case, args.overrides,
                          progress=lambda line: print(line, file=sys.stderr, flush=True))
    except ValueError as exc:           # unknown case or technique: the message lists the valid ones
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    print(stress.format_table(rows))
    bad, expected, status = stress.verdict(rows)
    if expected:
        print("\nexpected failures (documented limits, see README 'Known limits'):")
        for r in expected:
            print(f"  {r['case']} {r['technique']}: {r['expected']}")
    for r in bad:
        if r["status"] == "XPASS":
            print(f"unexpected pass: {r['case']} {r['technique']} passes although stress.EXPECTED_FAILURES "
                  "lists it as failing at the default settings")
    ok = sum(r["status"] == "ok" for r in rows)
    print(f"{ok} passed, {len(expected)} expected failures, {len(bad)} unexpected "
          f"({', '.join(sorted({r['status'] for r in bad})) or 'none'})")
    return status


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


def _sizes(text: str) -> list[tuple[int, int]]:
    """'128,512x256' → [(128, 128), (512, 256)]: square sizes or W x H, each in the render range."""
    out = []
    for item in (t.strip() for t in text.split(",") if t.strip()):
        w, _, h = item.lower().partition("x")
        try:
            size = (int(w), int(h or w))
        except ValueError:
            raise Refusal(f"penumbra: size {item!r} is neither N nor WxH")
        if not all(RESOLUTION_RANGE[0] <= v <= RESOLUTION_RANGE[1] for v in size):
            raise Refusal(f"penumbra: size {item!r} is outside {RESOLUTION_RANGE[0]}…{RESOLUTION_RANGE[1]}")
        out.append(size)
    return out


def cmd_bundle(args) -> int:
    from .measure import bundle
    from .techniques import TECHNIQUES
    if args.action == "export":
        _import_bpy()
        from .measure.scenes import SCENES
        names = [n.strip() for n in args.scenes.split(",") if n.strip()] or list(SCENES)
        unknown = [n for n in names if n not in SCENES]
        if unknown:
            raise Refusal(f"penumbra: unknown scene(s) {', '.join(unknown)}; valid: {', '.join(SCENES)}")
        files = bundle.export(args.folder, names, _sizes(args.sizes), reference_sizes=_sizes(args.reference_sizes),
                              samples=args.cycles_samples, log=lambda m: print(m, file=sys.stderr, flush=True))
        print(f"wrote {len(files)} bundle(s) to {args.folder}")
        return 0
    paths = sorted(str(p) for p in Path(args.folder).glob("*.pkl"))
    if not paths:
        raise Refusal(f"penumbra: no scene bundles (*.pkl) in {args.folder}")
    techniques = [t.strip().upper() for t in args.techniques.split(",") if t.strip()] or list(TECHNIQUES)
    unknown = [t for t in techniques if t not in TECHNIQUES]
    if unknown:
        raise Refusal(f"penumbra: unknown technique(s) {', '.join(unknown)}; valid: {', '.join(TECHNIQUES)}")
    print(bundle.HEADER, flush=True)
    results = bundle.run(paths, techniques, repeats=args.repeats, overrides=args.overrides,
                         on_row=lambda r: print(bundle.table({"rows": [r]}).splitlines()[1], flush=True))
    print(bundle.table(results))
    if args.out:
        bundle.write(results, args.out)
        print(f"wrote {args.out}/bundle_results.{{json,md}}")
    return 0


def cmd_scenes(args) -> int:
    from .measure.scenes import list_scenes
    for name, description in list_scenes():
        print(f"{name:<12} {description}")
    return 0


def _csv_list(text: str) -> list[str]:
    return [item.strip() for item in (text or "").split(",") if item.strip()]


def _int_list(text: str, flag: str, lo: int = 1, hi: int | None = None) -> list[int]:
    parse = ranged(int, lo, hi)
    try:
        return [parse(item) for item in _csv_list(text)]
    except argparse.ArgumentTypeError as exc:
        raise Refusal(f"penumbra: {flag}: {exc}") from None


def cmd_bench(args) -> int:
    check_outputs(folders=[args.out])
    _import_bpy()
    if args.study:
        # The paper studies: each study module has its own options; pass them after `--`.
        from .measure import studies
        return studies.run(args.study, ["--out", args.out, *args.study_args])
    if args.scaling:
        from .measure import bench
        peers = [p for p in _csv_list(args.peers.lower()) if p not in ("none", "off")]
        try:
            bench.run_scaling(args.out, techniques=_csv_list(args.techniques) or None, peers=peers,
                              quick=args.quick, repeats=args.repeats, budget_s=args.budget or None,
                              reference_samples=args.cycles_samples, target_samples=args.target_samples,
                              cycles_ladder=_int_list(args.cycles_peer_samples, "--cycles-peer-samples",
                                                      *CYCLES_SAMPLES_RANGE),
                              max_pixels=args.max_pixels, max_triangles=args.max_triangles,
                              max_lights=args.max_lights, cycles_max_pixels=args.cycles_max_pixels,
                              base_size=tuple(args.base_size))
        except ValueError as exc:
            print(f"penumbra: {exc}", file=sys.stderr)
            return 2
        print(f"wrote {args.out}/scaling.{{json,md,png}}")
        return 0
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
            resolution=tuple(args.resolution), repeats=args.repeats, reference_samples=args.cycles_samples,
            cycles_samples=_int_list(args.cycles_peer_samples, "--cycles-peer-samples", *CYCLES_SAMPLES_RANGE),
            eevee_samples=_int_list(args.eevee_samples, "--eevee-samples"),
            eevee_jitter=not args.eevee_no_jitter, target_samples=args.target_samples,
            overrides=args.overrides, budget_s=args.budget or None,
            peer_budget_s=args.peer_budget or None)
    except ValueError as exc:
        print(f"penumbra: {exc}", file=sys.stderr)
        return 2
    print(bench.summary_table(results["summary"]))
    print(f"bench wall time {time.perf_counter() - t0:.0f} s; wrote {args.out}/results.{{json,csv,md}} and "
          f"pareto_<scene>.png")
    return 0


class _Help(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults after each flag's help (none where there is nothing to show); the epilog as written."""

    def _get_help_string(self, action):
        text, default = action.help, action.default
        if not text or default is None or default is False or default == "" or "(default" in text:
            return text
        if isinstance(default, (list, tuple)):         # nargs=2 flags: "128 128", as typed
            return f"{text} (default: {' '.join(map(str, default))})"
        return super()._get_help_string(action)


def _flag_of(name: str) -> str:
    return {"technique": "--technique", "shadow_map_size": "--map-size",
            "averaged_light_samples": "--light-samples"}.get(name, "")


def settings_epilog() -> str:
    """Every setting `--set NAME=VALUE` takes, with its default and range, generated from the Options."""
    from .techniques import TECHNIQUES

    def rows(options):
        for opt in options:
            default = str(opt.default).lower() if isinstance(opt.default, bool) else str(opt.default)
            flag = _flag_of(opt.name)
            yield f"  {opt.name} = {default}   ({opt.allowed()}{'; ' + flag if flag else ''})"
            yield from textwrap.wrap(opt.description, 104, initial_indent=" " * 6, subsequent_indent=" " * 6)

    lines = ["settings: --set NAME=VALUE (repeatable) sets any of these, each shown with its default and its",
             "allowed values (a .blend file's own values replace the defaults)",
             f"  technique = {RenderSettings().technique}   (one of {', '.join(TECHNIQUES)}; --technique)",
             "shared by every technique:", *rows(SHARED)]
    for technique in TECHNIQUES.values():
        if technique.options:
            label = technique.label
            named = technique.identifier + (f" ({label})" if label != technique.identifier else "")
            lines += [f"{named}:", *rows(technique.options)]
    return "\n".join(lines)


def _common_render_args(p) -> None:
    from .techniques import TECHNIQUES
    p.add_argument("--technique", type=str.upper, choices=list(TECHNIQUES),
                   help="shadow technique (default: the scene's setting)")
    p.add_argument("--resolution", type=ranged(int, *RESOLUTION_RANGE), nargs=2, metavar=("W", "H"),
                   help=f"image size in pixels, each {RESOLUTION_RANGE[0]} … {RESOLUTION_RANGE[1]} "
                        "(default: the .blend's, 256 256 for a built-in scene)")
    map_size, samples = setting_option("shadow_map_size"), setting_option("averaged_light_samples")
    p.add_argument("--map-size", type=option_type(map_size),
                   help=f"shadow-map size in texels, {map_size.allowed()} (default: the scene's setting)")
    add_alias(p, "--samples", p.add_argument(
        "--light-samples", type=option_type(samples),
        help=f"hard shadow maps averaged per light by REFERENCE, {samples.allowed()} (default: the scene's)"))
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="any render setting, repeatable (listed below)")


def _cycles_samples(text: str) -> int:
    """bench's --cycles-samples: one count (it used to be the Cycles peer's list, now --cycles-peer-samples)."""
    if "," in text:
        raise argparse.ArgumentTypeError(
            f"'{text}': --cycles-samples is the Cycles reference's sample count (one number); the Cycles "
            "peer's list of counts is now --cycles-peer-samples")
    return ranged(int, *CYCLES_SAMPLES_RANGE)(text)


_cycles_samples.__name__ = "int"


def _output_file(*suffixes: str):
    """An argparse `type` for an output file whose format follows its extension; others are refused."""
    def parse(text: str) -> str:
        if not text.lower().endswith(suffixes):
            raise argparse.ArgumentTypeError(
                f"'{text}': the format follows the extension; use {' or '.join(suffixes)}")
        return text
    parse.__name__ = "file name"
    return parse


def build_parser() -> argparse.ArgumentParser:
    prog = "penumbra" if Path(sys.argv[0]).name == "penumbra" else "python -m penumbra"
    p = Parser(prog=prog, description="Penumbra soft-shadow renderer")
    p.add_argument("--version", action="version", version=f"penumbra {version()}")
    sub = p.add_subparsers(dest="command", required=True)
    epilog = settings_epilog()

    r = sub.add_parser("render", help="render a .blend file or a built-in scene to a multilayer EXR or a PNG",
                       formatter_class=_Help, epilog=epilog)
    src = r.add_mutually_exclusive_group(required=True)
    src.add_argument("blend", nargs="?", help="a .blend file")
    src.add_argument("--scene", help="a built-in scene (see `python -m penumbra scenes`)")
    _common_render_args(r)
    r.add_argument("--out", required=True, type=_output_file(".exr", ".png"),
                   help="file to write: .exr (multilayer, every pass) or .png (Combined, sRGB)")
    r.add_argument("--png", type=_output_file(".png"), help="also write Combined as an sRGB PNG")
    r.set_defaults(func=cmd_render)

    c = sub.add_parser("compare", help="render with Penumbra and Cycles, print error and time side by side",
                       formatter_class=_Help, epilog=epilog)
    src = c.add_mutually_exclusive_group(required=True)
    src.add_argument("blend", nargs="?", help="a .blend file")
    src.add_argument("--scene", help="a built-in scene")
    _common_render_args(c)
    c.add_argument("--out", help="folder for EXRs, the comparison PNG and a JSON of the numbers")
    c.add_argument("--cycles-samples", type=ranged(int, *CYCLES_SAMPLES_RANGE), default=256,
                   help="Cycles samples of the reference")
    c.add_argument("--repeats", type=ranged(int, 1), default=3,
                   help="timed repeats of our frame (median reported)")
    c.add_argument("--no-noise-floor", action="store_true", help="skip the second Cycles seed")
    c.set_defaults(func=cmd_compare)

    b = sub.add_parser("bench", help="time and error of every technique against Cycles (and EEVEE), per scene",
                       formatter_class=_Help, epilog=epilog)
    b.add_argument("--scenes", default="", help="comma-separated built-in scenes (default: all)")
    b.add_argument("--techniques", default="", help="comma-separated techniques (default: all)")
    b.add_argument("--sweep", action="store_true", help="sweep each technique's knobs (map size, kernels, …)")
    b.add_argument("--peers", default="cycles", help="comma-separated peers: cycles, eevee, or none")
    b.add_argument("--resolution", type=ranged(int, *RESOLUTION_RANGE), nargs=2, metavar=("W", "H"),
                   default=[128, 128], help="image size in pixels")
    b.add_argument("--repeats", type=ranged(int, 1), default=5,
                   help="timed frames per configuration (median reported)")
    add_alias(b, "--reference-samples", b.add_argument(
        "--cycles-samples", type=_cycles_samples, default=1024, help="Cycles samples of the reference"))
    b.add_argument("--cycles-peer-samples", default="1,4,16,64,256",
                   help="comma-separated sample counts of the Cycles peer")
    b.add_argument("--eevee-samples", default="1,16,64", help="sample counts of the EEVEE peer")
    b.add_argument("--eevee-no-jitter", action="store_true",
                   help="EEVEE with Blender's default unjittered shadows (default: lights' shadow jitter on)")
    b.add_argument("--target-samples", type=ranged(int, 1), default=64,
                   help="the summary lists our fastest configuration at least as accurate as Cycles at this")
    b.add_argument("--budget", type=ranged(float, 0.0), default=20.0,
                   help="seconds of timed frames per configuration before fewer repeats are taken (0: no cap)")
    b.add_argument("--peer-budget", type=ranged(float, 0.0), default=5.0,
                   help="seconds of Cycles renders per sample count before fewer repeats are taken (0: no cap)")
    b.add_argument("--set", action="append", metavar="NAME=VALUE", help="base render setting, repeatable")
    b.add_argument("--viewport", action="store_true",
                   help="interactive latency instead: first and refined frame after a camera move, an object "
                        "move and a light edit (default scenes suzanne, balls, city)")
    b.add_argument("--scaling", action="store_true",
                   help="frame time of every technique and of Cycles (ladder --cycles-peer-samples; its time at "
                        "each technique's error; the 30× check at --target-samples) against output size (128² → "
                        "1920×1080), triangles (city, 1k → 2M) and lights (1 → 16), log–log plots with slopes")
    b.add_argument("--quick", action="store_true", help="with --scaling: two tiny points per axis, one frame")
    for flag, what in (("--max-pixels", "output sizes"), ("--max-triangles", "triangle counts"),
                       ("--max-lights", "light counts"), ("--cycles-max-pixels", "Cycles (reference and ladder)")):
        b.add_argument(flag, type=ranged(int, 1), default=None,
                       help=f"with --scaling: {what} only up to this many" + (" pixels" if "pixels" in flag else ""))
    b.add_argument("--base-size", type=ranged(int, *RESOLUTION_RANGE), nargs=2, metavar=("W", "H"),
                   default=[384, 384], help="with --scaling: output size of the triangle and light sweeps")
    b.add_argument("--viewport-size", type=ranged(int, *RESOLUTION_RANGE), nargs=2, metavar=("W", "H"),
                   default=[1280, 720], help="viewport size in pixels")
    b.add_argument("--study", choices=tuple(STUDIES),
                   help="a paper's study instead: SSM's §4.2 curves (map size, light size, occluder position) "
                        "or the bitmask paper's Table 2/3 columns; further options after `--`")
    b.add_argument("study_args", nargs="*", help=argparse.SUPPRESS)
    b.add_argument("--out", required=True, help="folder for results.json/.csv/.md and pareto_<scene>.png")
    b.set_defaults(func=cmd_bench)

    st = sub.add_parser("stress", help="stiff and extreme cases × every technique: NaN/Inf, range, error, time",
                        formatter_class=_Help, epilog=epilog)
    st.add_argument("--technique", action="append", type=str.upper, help="technique(s) (default: all)")
    st.add_argument("--case", action="append", help="case(s) (default: all)")
    st.add_argument("--set", action="append", metavar="NAME=VALUE", help="render setting, repeatable")
    st.add_argument("--list", action="store_true", help="list the cases and their expected failures, then exit")
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

    bu = sub.add_parser("bundle", help="built-in scenes with their Cycles references to files, and time and "
                                       "score every technique on them where Blender is not installed (a GPU box)",
                        formatter_class=_Help, epilog=epilog)
    bu.add_argument("action", choices=("export", "run"),
                    help="export: build, extract and save (needs bpy); run: render, time and score (no bpy)")
    bu.add_argument("folder", help="the bundles' folder")
    bu.add_argument("--scenes", default="", help="export: comma-separated built-in scenes (default: all)")
    bu.add_argument("--sizes", default="128", help="export: image sizes, N or WxH, comma-separated")
    bu.add_argument("--reference-sizes", default="128",
                    help="export: the sizes that get a Cycles reference (each costs a 1024-spp pair)")
    bu.add_argument("--cycles-samples", type=_cycles_samples, default=1024, help="export: reference samples")
    bu.add_argument("--techniques", default="", help="run: comma-separated techniques (default: all)")
    bu.add_argument("--repeats", type=ranged(int, 1), default=5, help="run: timed frames (median reported)")
    bu.add_argument("--set", action="append", metavar="NAME=VALUE", help="run: render setting, repeatable")
    bu.add_argument("--out", help="run: folder for bundle_results.json and .md")
    bu.set_defaults(func=cmd_bundle)

    s = sub.add_parser("scenes", help="list the built-in scenes")
    s.set_defaults(func=cmd_scenes)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        # Checked before any scene is loaded: a bad --set is refused at once.
        args.overrides = parse_overrides(getattr(args, "set", None))
        return args.func(args)
    except Refusal as exc:
        print(exc, file=sys.stderr)
        return 2
