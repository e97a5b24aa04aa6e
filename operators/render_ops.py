"""Operators: export the current frame's Penumbra passes as a multilayer EXR; compare with Cycles.

Errors reach the user through `self.report` (one line naming the path or setting), never as a traceback."""
from __future__ import annotations

import os
import tempfile

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty

COMPARE_IMAGE = "Penumbra Compare"


class PENUMBRA_OT_export_exr(bpy.types.Operator):
    """Render the active scene with Penumbra and write every pass to a multilayer EXR"""
    bl_idname = "penumbra.export_exr"
    bl_label = "Export Penumbra EXR"
    filepath: StringProperty(subtype="FILE_PATH", default="//penumbra.exr")

    def execute(self, context):
        from ..engine.core import exr
        from ..engine.core.files import check_output_file
        from ..engine.render import pipeline
        from ..engine.blender.extract import extract
        from ..engine.blender.settings_bridge import settings_from_scene
        path = bpy.path.abspath(self.filepath)
        try:
            if not os.path.isabs(path):
                raise ValueError(f"'{self.filepath}' is relative to an unsaved .blend: save the file or give "
                                 "an absolute path")
            check_output_file(path)         # before rendering: a bad path costs nothing
            snap = extract(context.evaluated_depsgraph_get(), context.scene)
            result = pipeline.render(snap, settings_from_scene(context.scene))
            exr.write(path, result.passes)
        except (ValueError, RuntimeError) as exc:       # OutputError is a ValueError
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for message in result.warnings:
            self.report({"WARNING"}, message)
        self.report({"INFO"}, f"Wrote {path} ({result.total_ms:.0f} ms)")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


def compare_folder(directory: str) -> tuple[str, str]:
    """(absolute output folder, a note for the user or ""). Empty: `penumbra_compare` beside the .blend. A
    file that was never saved has no folder of its own, and the process's working directory is nobody's
    choice, so then the system's temporary folder is used and the note says so."""
    saved = bool(bpy.data.filepath)
    if directory and (saved or not directory.startswith("//")):
        return os.path.abspath(bpy.path.abspath(directory)), ""
    if saved:
        return os.path.join(os.path.dirname(bpy.data.filepath), "penumbra_compare"), ""
    folder = os.path.join(tempfile.gettempdir(), "penumbra_compare")
    return folder, f"the .blend is not saved: results go to {folder}"


class PENUMBRA_OT_compare_cycles(bpy.types.Operator):
    """Render the active scene with Penumbra and with Cycles (direct light) and report the visibility error
    beside both times, one stage at a time (Esc cancels between stages); writes the EXRs, a comparison
    image (also shown in Blender as "Penumbra Compare") and a JSON of the numbers"""
    bl_idname = "penumbra.compare_cycles"
    bl_label = "Compare with Cycles"
    directory: StringProperty(subtype="DIR_PATH", default="",
                              description="Empty: penumbra_compare beside the .blend (temporary folder if unsaved)")
    samples: IntProperty(name="Cycles Samples", default=256, min=1, max=65536)
    preview: BoolProperty(name="Preview", default=True,
                          description="Capped resolution and samples, no noise floor (stated in the result)")
    noise_floor: BoolProperty(name="Noise Floor", default=True)

    def _start(self, context) -> bool:
        from ..engine.blender.settings_bridge import settings_from_scene
        from ..engine.core.files import check_output_folder
        from ..engine.measure.compare import compare_steps
        state = context.scene.penumbra_compare
        folder, note = compare_folder(self.directory)
        try:
            check_output_folder(folder)
            settings = settings_from_scene(context.scene)
            settings.validate()
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return False
        if note:
            self.report({"INFO"}, note)
        self._scene = context.scene
        self._steps = compare_steps(context.scene, settings, samples=self.samples, out_dir=folder,
                                    with_noise_floor=self.noise_floor, preview=self.preview)
        state.running, state.progress, state.status, state.folder = True, 0.0, "starting", folder
        return True

    def _advance(self, context) -> set:
        """One stage of the comparison; {'RUNNING_MODAL'} while there is more to do."""
        state = self._scene.penumbra_compare
        try:
            fraction, message = next(self._steps)
        except StopIteration as done:
            self._show(context, done.value)
            return {"FINISHED"}
        except (ValueError, RuntimeError) as exc:       # bad scene or setting, unwritable output, GPU error
            state.running, state.status = False, f"failed: {exc}"
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        state.progress, state.status = fraction, message
        context.window_manager.progress_update(fraction)
        _redraw(context)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        """Blocking: scripts and background mode (no window to keep responsive)."""
        if not self._start(context):
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0.0, 1.0)
        try:
            while True:
                status = self._advance(context)
                if status != {"RUNNING_MODAL"}:
                    return status
        finally:
            wm.progress_end()

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        if not self._start(context):
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0.0, 1.0)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._steps.close()             # the generator restores every scene setting it changed
            self._scene.penumbra_compare.running = False
            self._scene.penumbra_compare.status = "cancelled"
            self._end(context)
            self.report({"WARNING"}, "Compare with Cycles cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        status = self._advance(context)
        if status != {"RUNNING_MODAL"}:
            self._end(context)
        return status

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        _redraw(context)

    def _show(self, context, cmp) -> None:
        """The numbers into the panel, the comparison image into an image datablock (and into any open
        Image Editor), the summary into the status bar."""
        state = self._scene.penumbra_compare
        m, floor = cmp.metrics, cmp.noise_floor or {}

        def num(x):
            return float(x) if isinstance(x, (int, float)) and x == x else -1.0
        state.running, state.progress, state.status = False, 1.0, "done"
        state.technique, state.mae_shadow, state.n_shadow = cmp.technique, num(m["mae_shadow"]), m["n_shadow"]
        state.noise_mae, state.ours_ms = num(floor.get("mae_shadow")), cmp.ours_ms
        state.cycles_seconds, state.reference_samples = cmp.cycles_seconds, cmp.reference_samples
        state.preview_caps, state.undefined = cmp.preview, cmp.undefined
        png = next((p for p in cmp.files if p.endswith("_compare.png")), None)
        if png:
            image = bpy.data.images.get(COMPARE_IMAGE)
            if image is None:
                image = bpy.data.images.load(png)
                image.name = COMPARE_IMAGE
            else:
                image.filepath = png
                image.reload()
            state.image = image.name
            for area in (context.screen.areas if context.screen else ()):
                if area.type == "IMAGE_EDITOR":
                    area.spaces.active.image = image
        for message in cmp.warnings:
            self.report({"WARNING"}, message)
        self.report({"INFO"}, cmp.summary())


def _redraw(context) -> None:
    for area in (context.screen.areas if context.screen else ()):
        if area.type in {"PROPERTIES", "IMAGE_EDITOR"}:
            area.tag_redraw()


classes = (PENUMBRA_OT_export_exr, PENUMBRA_OT_compare_cycles)
