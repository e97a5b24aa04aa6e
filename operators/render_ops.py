"""Operators: export the current frame's Penumbra passes as a multilayer EXR; compare with Cycles."""
from __future__ import annotations

import bpy
from bpy.props import StringProperty


class PENUMBRA_OT_export_exr(bpy.types.Operator):
    """Render the active scene with Penumbra and write every pass to a multilayer EXR"""
    bl_idname = "penumbra.export_exr"
    bl_label = "Export Penumbra EXR"
    filepath: StringProperty(subtype="FILE_PATH", default="//penumbra.exr")

    def execute(self, context):
        from ..engine.core import exr
        from ..engine.render import pipeline
        from ..engine.blender.extract import extract
        from ..engine.blender.settings_bridge import settings_from_scene
        try:
            snap = extract(context.evaluated_depsgraph_get(), context.scene)
            result = pipeline.render(snap, settings_from_scene(context.scene))
        except (ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        path = bpy.path.abspath(self.filepath)
        exr.write(path, result.passes)
        for message in result.warnings:
            self.report({"WARNING"}, message)
        self.report({"INFO"}, f"Wrote {path} ({result.total_ms:.0f} ms)")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


class PENUMBRA_OT_compare_cycles(bpy.types.Operator):
    """Render the active scene with Penumbra and with Cycles (direct light) and report the visibility error
    beside both times; writes the EXRs, a difference image and a JSON of the numbers"""
    bl_idname = "penumbra.compare_cycles"
    bl_label = "Compare with Cycles"
    directory: StringProperty(subtype="DIR_PATH", default="//penumbra_compare")
    samples: bpy.props.IntProperty(name="Cycles Samples", default=256, min=1, max=65536)

    def execute(self, context):
        from ..engine.measure.compare import compare
        from ..engine.blender.settings_bridge import settings_from_scene
        wm = context.window_manager
        wm.progress_begin(0.0, 1.0)
        try:
            cmp = compare(context.scene, settings_from_scene(context.scene), samples=self.samples,
                          out_dir=bpy.path.abspath(self.directory),
                          on_progress=lambda fraction, message: wm.progress_update(fraction))
        except (ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        self.report({"INFO"}, cmp.summary())
        return {"FINISHED"}


classes = (PENUMBRA_OT_export_exr, PENUMBRA_OT_compare_cycles)
