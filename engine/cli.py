"""Command line: `python -m penumbra render|scenes …` (bench, compare and stress plug in here too)."""
from __future__ import annotations

import argparse
import os
import sys
import time

from .settings import RenderSettings


class ProgressBar:
    """A progress bar on stderr; on a terminal it redraws in place, otherwise it prints every 25%."""

    def __init__(self, label: str, stream=None, width: int = 30):
        self.label, self.stream, self.width = label, stream or sys.stderr, width
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._last_quarter = -1

    def __call__(self, fraction: float, message: str = "") -> None:
        fraction = min(max(fraction, 0.0), 1.0)
        filled = int(round(fraction * self.width))
        line = f"{self.label} [{'#' * filled}{'.' * (self.width - filled)}] {fraction * 100:5.1f}% {message}"
        if self.tty:
            self.stream.write("\r" + line[:120].ljust(120))
            self.stream.flush()
        elif int(fraction * 4) > self._last_quarter:
            self._last_quarter = int(fraction * 4)
            self.stream.write(line + "\n")

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")


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
    from . import scenes
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
    from ..ui.properties import settings_from_scene
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
    from . import exr, pipeline
    from .scene import extract
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
    from .compare import compare
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


def cmd_scenes(args) -> int:
    from .scenes import list_scenes
    for name, description in list_scenes():
        print(f"{name:<12} {description}")
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

    s = sub.add_parser("scenes", help="list the built-in scenes")
    s.set_defaults(func=cmd_scenes)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)
