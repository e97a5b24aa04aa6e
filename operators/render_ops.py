"""Operators: export the current frame's Penumbra passes as a multilayer EXR."""
from __future__ import annotations

import bpy
from bpy.props import StringProperty


class PENUMBRA_OT_export_exr(bpy.types.Operator):
    """Render the active scene with Penumbra and write every pass to a multilayer EXR"""
    bl_idname = "penumbra.export_exr"
    bl_label = "Export Penumbra EXR"
    filepath: StringProperty(subtype="FILE_PATH", default="//penumbra.exr")

    def execute(self, context):
        from ..engine import exr, pipeline
        from ..engine.scene import extract
        from ..ui.properties import settings_from_scene
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


classes = (PENUMBRA_OT_export_exr,)
