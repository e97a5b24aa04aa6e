"""`python -m penumbra bench --viewport`: time to the first (coarse) frame and to the refined frame after a
camera move, an object move and a light edit, per scene and technique, through the same ViewportSession the
RenderEngine uses (everything but the final texture draw, which needs a window)."""
from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import replace

import numpy as np

from ..core.settings import RenderSettings
from ..core.files import write_atomic

EVENTS = ("camera", "object", "light")


def _wait_first(session, request: int, timeout: float = 120.0):
    """Seconds until any frame of `request` is in (coarse or refined)."""
    end = time.perf_counter() + timeout
    while time.perf_counter() < end:
        frame = session.latest
        if frame is not None and frame.request == request:
            return frame
        time.sleep(0.001)
    raise TimeoutError("viewport frame did not arrive")


def measure(scene_name: str, technique: str, *, size=(1280, 720), coarse_map=256, coarse_scale=0.5,
            map_size=1024, repeats=3, on_progress=None) -> list[dict]:
    import bpy
    from . import scenes
    from ..blender.extract import extract
    from ..blender.viewport_sync import BlenderViewport as ViewportSession, UpdateRecorder
    sc = scenes.build(scene_name, resolution=size)
    updates = UpdateRecorder()
    try:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        camera = extract(depsgraph, sc).camera
        session = ViewportSession()
        session.sync(depsgraph)
        settings = RenderSettings(technique=technique, shadow_map_size=map_size)
        session.request(camera, settings, coarse_map=coarse_map, coarse_scale=coarse_scale)
        session.wait()                                   # warm-up: shaders compiled, buffers uploaded
        movable = next(o for o in sc.objects if o.type == "MESH" and o.name != "Ground")
        light = next(o for o in sc.objects if o.type == "LIGHT")
        rows = []
        for event in EVENTS:
            firsts, fulls = [], []
            for k in range(repeats):
                start = time.perf_counter()
                if event == "camera":
                    view = camera.view.copy()
                    view[0, 3] += 0.02 * (k + 1)
                    camera = replace(camera, view=view)
                else:
                    if event == "object":
                        movable.location.x += 0.01
                    else:
                        light.data.energy *= 1.01
                        light.location.z += 0.01
                    session.sync(bpy.context.evaluated_depsgraph_get(), updates.take())
                session.request(camera, settings, coarse_map=coarse_map, coarse_scale=coarse_scale)
                request = session._request
                _wait_first(session, request)
                firsts.append((time.perf_counter() - start) * 1000.0)
                session.wait()
                fulls.append((time.perf_counter() - start) * 1000.0)
            rows.append({"scene": scene_name, "technique": technique, "event": event,
                         "first_frame_ms": float(np.median(firsts)), "refined_ms": float(np.median(fulls)),
                         "width": size[0], "height": size[1], "coarse_map": coarse_map,
                         "coarse_scale": coarse_scale, "map_size": map_size,
                         "uploads_total": int(sum(session.uploads.values()))})
            if on_progress:
                on_progress(rows[-1])
        session.free()
        return rows
    finally:
        updates.close()


def run(out_dir: str, scenes=("suzanne", "balls", "city"), techniques=None, **kwargs) -> list[dict]:
    from ..render.pipeline import TECHNIQUES
    techniques = techniques or list(TECHNIQUES)
    rows = []
    for name in scenes:
        for technique in techniques:
            rows += measure(name, technique, on_progress=lambda r: print(
                f"{r['scene']:<8} {r['technique']:<14} {r['event']:<7} first {r['first_frame_ms']:8.1f} ms  "
                f"refined {r['refined_ms']:8.1f} ms", flush=True), **kwargs)
    os.makedirs(out_dir, exist_ok=True)
    data = {"machine": platform.processor() or platform.machine(), "rows": rows}
    write_atomic(os.path.join(out_dir, "viewport.json"), json.dumps(data, indent=2))
    write_atomic(os.path.join(out_dir, "viewport.md"), markdown(rows) + "\n")
    return rows


def markdown(rows: list[dict]) -> str:
    lines = ["| scene | technique | event | first frame (ms) | refined (ms) |", "|---|---|---|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['technique']} | {r['event']} | {r['first_frame_ms']:.1f} | "
                     f"{r['refined_ms']:.1f} |")
    return "\n".join(lines)
