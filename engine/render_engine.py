"""The Blender RenderEngine "PENUMBRA": final renders through the GPU pipeline, passes written from the one
generator in engine/passes.py."""
from __future__ import annotations

import bpy

from . import passes, pipeline
from .gpu.context import Cancelled, GpuError
from .gpu.programs import ShaderError
from .scene import extract


def _settings(scene):
    from ..ui.properties import settings_from_scene
    return settings_from_scene(scene)


def format_timings(timings: dict) -> str:
    return " | ".join(f"{name} {ms:.1f} ms" for name, ms in timings.items())


class PenumbraRenderEngine(bpy.types.RenderEngine):
    bl_idname = "PENUMBRA"
    bl_label = "Penumbra"
    bl_use_preview = False
    bl_use_postprocess = True
    bl_use_eevee_viewport = True        # until the interactive viewport lands, Rendered shading uses EEVEE

    def update_render_passes(self, scene=None, renderlayer=None):
        for name, channels, chan_id, kind in passes.render_passes(_settings(scene)):
            self.register_pass(scene, renderlayer, name, channels, chan_id, kind)

    def render(self, depsgraph):
        scene = depsgraph.scene
        settings = _settings(scene)
        self.update_stats("", "Penumbra: reading scene")
        try:
            settings.validate()
            snap = extract(depsgraph, scene)
        except ValueError as exc:           # bad input: a message naming the scene/object/setting
            self._fail(str(exc))
            return
        for name, channels, chan_id, _ in passes.render_passes(settings):
            if name != "Combined":
                self.add_pass(name, channels, chan_id)

        def on_progress(fraction, message):
            self.update_progress(fraction)
            if message:
                self.update_stats("", f"Penumbra {settings.technique}: {message}")

        try:
            result = pipeline.render(snap, settings, on_progress=on_progress, should_stop=self.test_break)
        except Cancelled:
            return
        except (GpuError, ShaderError, RuntimeError) as exc:
            self._fail(f"Penumbra: GPU pipeline failed: {exc}")
            return
        for message in result.warnings:
            self.report({"WARNING"}, message)
        self._write(result, snap.camera.width, snap.camera.height)
        self.update_stats("", f"Penumbra {settings.technique}: {result.total_ms:.0f} ms | "
                              f"{format_timings(result.timings)}")

    def _write(self, result, width, height):
        render_result = self.begin_result(0, 0, width, height)
        layer = render_result.layers[0]
        for name, array in result.passes.items():
            target = layer.passes.find_by_name(name, "") if hasattr(layer.passes, "find_by_name") else None
            target = target or layer.passes.get(name)
            if target is not None:
                target.rect.foreach_set(array.reshape(-1))
        self.end_result(render_result)

    def _fail(self, message: str):
        self.report({"ERROR"}, message)
        self.error_set(message)


def register():
    bpy.utils.register_class(PenumbraRenderEngine)


def unregister():
    bpy.utils.unregister_class(PenumbraRenderEngine)
