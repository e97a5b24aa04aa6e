"""Panels in Render, Light and Object Properties, shown only when Penumbra is the render engine."""
from __future__ import annotations

import bpy

ENGINE = "PENUMBRA"


class PenumbraPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class RENDER_PT_penumbra(PenumbraPanel, bpy.types.Panel):
    bl_label = "Penumbra Shadows"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        props = context.scene.penumbra
        layout.prop(props, "technique")
        layout.prop(props, "shadow_map_size")
        col = layout.column(align=True)
        col.prop(props, "bias")
        col.prop(props, "normal_offset")
        from ..engine.render.pipeline import TECHNIQUES
        technique = TECHNIQUES.get(props.technique)
        # Every technique's settings come from its Option list (and the shared ones it reads).
        names = tuple(o.name for o in technique.options) + tuple(technique.reads_shared)
        if names:
            box = layout.column(heading=technique.label)
            for name in names:
                if name == "bp_budget_image":   # a Blender image by name (or a file path typed in)
                    box.prop_search(props, name, bpy.data, "images")
                else:
                    box.prop(props, name)
        layout.prop(props, "antialiasing")
        aa = layout.column(align=True)
        aa.active = props.antialiasing
        aa.prop(props, "aa_depth_threshold")
        aa.prop(props, "aa_visibility_sample")
        layout.prop(props, "debug_passes")
        layout.operator("penumbra.export_exr", icon="EXPORT")


class RENDER_PT_penumbra_viewport(PenumbraPanel, bpy.types.Panel):
    bl_label = "Viewport"
    bl_context = "render"
    bl_parent_id = "RENDER_PT_penumbra"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        props = context.scene.penumbra
        layout.prop(props, "viewport_technique", text="Technique")
        layout.prop(props, "viewport_map_size", text="Map Size")
        col = layout.column(align=True, heading="First Frame")
        col.prop(props, "viewport_coarse_map_size", text="Map Size")
        col.prop(props, "viewport_coarse_scale", text="Resolution")
        layout.prop(props, "viewport_pass", text="Pass")


class RENDER_PT_penumbra_compare(PenumbraPanel, bpy.types.Panel):
    bl_label = "Compare with Cycles"
    bl_context = "render"
    bl_parent_id = "RENDER_PT_penumbra"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        state = context.scene.penumbra_compare
        layout.prop(state, "preview")
        col = layout.column()
        col.prop(state, "samples")
        col.prop(state, "noise_floor")
        col.enabled = not state.preview
        layout.prop(state, "directory")
        row = layout.row()
        row.enabled = not state.running
        op = row.operator("penumbra.compare_cycles", icon="IMAGE_REFERENCE")
        op.preview, op.samples, op.noise_floor, op.directory = (state.preview, state.samples, state.noise_floor,
                                                                state.directory)
        if state.running:
            text = f"{state.status} (Esc cancels)"
            if hasattr(layout, "progress"):         # UILayout.progress: Blender 4.0 and newer
                layout.progress(factor=state.progress, text=text)
            else:
                layout.label(text=f"{state.progress:.0%} {text}")
            return
        if state.status.startswith("failed") or state.status == "cancelled":
            layout.label(text=state.status, icon="ERROR")
        if not state.technique:
            return
        box = layout.box()
        box.use_property_split = False
        box.label(text=f"{state.technique} against Cycles {state.reference_samples} spp", icon="INFO")
        if state.mae_shadow >= 0.0:
            floor = f" (noise floor {state.noise_mae:.4f})" if state.noise_mae >= 0.0 else ""
            box.label(text=f"mae_shadow {state.mae_shadow:.4f} over {state.n_shadow} px{floor}")
        else:
            box.label(text=f"no error measured: {state.undefined}")
        box.label(text=f"Penumbra {state.ours_ms:.1f} ms, Cycles {state.cycles_seconds:.2f} s per render")
        if state.preview_caps:
            box.label(text=f"Preview: {state.preview_caps}", icon="ERROR")
        if state.image:
            box.label(text=f"Image '{state.image}' (Image Editor), files in {state.folder}", icon="IMAGE_DATA")


def draw_viewport_pass(self, context):
    """Penumbra's pass selector in the 3D view's shading popover (Rendered mode)."""
    if context.engine == ENGINE and context.space_data.shading.type == "RENDERED":
        self.layout.prop(context.scene.penumbra, "viewport_pass", text="Render Pass")


class DATA_PT_penumbra_light(PenumbraPanel, bpy.types.Panel):
    bl_label = "Penumbra"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.light is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        light = context.light
        layout.prop(light, "color")
        layout.prop(light, "energy")
        layout.prop(light, "use_shadow", text="Cast Shadow")
        technique = context.scene.penumbra.technique
        if technique == "SSM" and not (light.type == "AREA" and light.shape in {"SQUARE", "RECTANGLE"}):
            layout.label(text="Soft Shadow Maps use this light's bounding rectangle", icon="INFO")
        if light.type == "AREA":
            layout.prop(light, "shape")
            col = layout.column(align=True)
            if light.shape in {"SQUARE", "DISK"}:
                col.prop(light, "size")
            else:
                col.prop(light, "size", text="Size X")
                col.prop(light, "size_y", text="Y")
            if light.spread < 3.14159:
                layout.label(text="Spread below 180° is not modelled", icon="INFO")
        elif light.type in {"POINT", "SPOT"}:
            layout.prop(light, "shadow_soft_size", text="Radius")
            if light.type == "SPOT":
                layout.prop(light, "spot_size")
                layout.prop(light, "spot_blend")
        elif light.type == "SUN":
            layout.prop(light, "angle")


class OBJECT_PT_penumbra(PenumbraPanel, bpy.types.Panel):
    bl_label = "Penumbra"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.object is not None and context.object.type != "LIGHT"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        obj = context.object
        layout.prop(obj.penumbra, "role")
        if context.scene.penumbra.technique == "BACKPROJECTION":
            row = layout.row()
            row.active = context.scene.penumbra.bp_budget_map == "IMPORTANCE"
            row.prop(obj.penumbra, "importance")
        if context.scene.penumbra.technique == "SSM":
            col = layout.column(align=True)
            col.label(text="Soft Shadow Maps: casters shadow receivers;", icon="INFO")
            col.label(text="an object never shadows itself (no self-shadowing).")
        col = layout.column(heading="Visibility")
        col.prop(obj, "visible_camera", text="Camera")
        col.prop(obj, "visible_shadow", text="Shadow")


def material_report(mat, width: int = 60) -> list[tuple[str, str]]:
    """(icon, line) pairs: where Penumbra's final render takes `mat`'s diffuse colour from, and every node it
    does not read (extraction's own warnings, wrapped to `width` characters)."""
    import textwrap

    from ..engine.blender.extract import material_albedo_source
    problems: list[str] = []
    source = material_albedo_source(mat, problems.append)
    lines = [("INFO", f"Base colour: {source.description or 'constant colour'}")]
    for problem in problems:
        for i, part in enumerate(textwrap.wrap(problem, width)):
            lines.append(("ERROR" if i == 0 else "BLANK1", part))
    lines.append(("BLANK1", "Read: Principled/Diffuse colour, RGB, Image Texture through"))
    lines.append(("BLANK1", "UV Map / Texture Coordinate UV / Mapping, Color Attribute"))
    return lines


class MATERIAL_PT_penumbra(PenumbraPanel, bpy.types.Panel):
    bl_label = "Penumbra"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and getattr(context, "material", None) is not None

    def draw(self, context):
        col = self.layout.column(align=True)
        for icon, text in material_report(context.material):
            col.label(text=text, icon=icon)


classes = (RENDER_PT_penumbra, RENDER_PT_penumbra_viewport, RENDER_PT_penumbra_compare, DATA_PT_penumbra_light,
           OBJECT_PT_penumbra, MATERIAL_PT_penumbra)


def _compatible_panels():
    """Blender's stock panels that make sense for Penumbra too (dimensions, output, colour management …)."""
    exclude = {"VIEWLAYER_PT_filter", "VIEWLAYER_PT_layer_passes"}
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is not None and "BLENDER_RENDER" in engines and panel.__name__ not in exclude:
            yield panel


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE)
    bpy.types.VIEW3D_PT_shading.append(draw_viewport_pass)


def unregister():
    bpy.types.VIEW3D_PT_shading.remove(draw_viewport_pass)
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
