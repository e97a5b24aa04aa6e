"""Blender properties: scene.penumbra (render settings: the technique, then one property per Option, shared
or a technique's own, generated from the Option's default and range) and object.penumbra (the object's role
for techniques that split casters from receivers)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

from ..engine.core.settings import SHARED, RenderSettings
from ..engine.render.pipeline import TECHNIQUES

_D = RenderSettings()   # defaults come from the dataclass, so the two never disagree


def refresh_passes(self, context):
    """The pass list depends on these settings (core/passes.render_passes): ask every view layer of the scene
    to query the engine's passes again, as Cycles does for its pass toggles, so the compositor's Render
    Layers node and the pass menus follow at once."""
    for view_layer in self.id_data.view_layers:
        view_layer.update_render_passes()


PASS_LIST_SETTINGS = {"technique", "debug_passes"}


class PenumbraSceneSettings(bpy.types.PropertyGroup):
    technique: EnumProperty(name="Technique", items=[
        (t.identifier, t.label, t.description) for t in TECHNIQUES.values()], default=_D.technique,
        description="Soft-shadow technique for final renders", update=refresh_passes)
    # The viewport's own quality (Rendered shading); final renders ignore these.
    viewport_technique: EnumProperty(name="Viewport Technique", items=[
        ("SAME", "Same as Render", "Use the final render's technique")] + [
        (t.identifier, t.label, t.description) for t in TECHNIQUES.values()], default="SAME")
    viewport_map_size: IntProperty(name="Viewport Map Size", default=1024, min=16, max=8192,
                                   description="Shadow-map size of the viewport's refined frame")
    viewport_coarse_map_size: IntProperty(name="First Frame Map Size", default=256, min=16, max=4096,
                                          description="Shadow-map size of the quick frame drawn right after a "
                                                      "change, before the refined one")
    viewport_coarse_scale: FloatProperty(name="First Frame Resolution", default=0.5, min=0.1, max=1.0,
                                         subtype="FACTOR", description="Resolution of the quick first frame, "
                                                                       "relative to the viewport")
    viewport_pass: EnumProperty(name="Viewport Pass", default="Combined", items=[
        ("Combined", "Combined", "Shaded image"), ("Visibility", "Visibility", "Σ E·V / Σ E"),
        ("Unshadowed", "Unshadowed", "Shading without shadows"),
        ("Irradiance", "Irradiance (debug)", "Unoccluded irradiance, with debug passes on")],
        description="Pass shown in the viewport's Rendered shading")


def _option_property(opt):
    """A Blender property for an Option (a shared setting or a technique's own)."""
    common = dict(name=opt.label, description=opt.description)
    if opt.name in PASS_LIST_SETTINGS:
        common["update"] = refresh_passes
    if opt.items:
        return EnumProperty(items=[tuple(i) for i in opt.items], default=opt.default, **common)
    if isinstance(opt.default, bool):
        return BoolProperty(default=opt.default, **common)
    bounds = {k: v for k, v in (("min", opt.min), ("max", opt.max), ("soft_min", opt.soft_min),
                                ("soft_max", opt.soft_max)) if v is not None}
    if isinstance(opt.default, int):
        return IntProperty(default=opt.default, **{k: int(v) for k, v in bounds.items()}, **common)
    return FloatProperty(default=opt.default, **bounds, **common)


for _opt in SHARED + tuple(o for t in TECHNIQUES.values() for o in t.options):
    PenumbraSceneSettings.__annotations__[_opt.name] = _option_property(_opt)


class PenumbraObjectSettings(bpy.types.PropertyGroup):
    role: EnumProperty(name="Shadow Role", default="BOTH", items=[
        ("BOTH", "Caster and Receiver", "Casts shadows and receives them"),
        ("CASTER", "Caster", "Only casts shadows (for techniques that split casters from receivers)"),
        ("RECEIVER", "Receiver", "Only receives shadows (for techniques that split casters from receivers)"),
    ])


classes = (PenumbraSceneSettings, PenumbraObjectSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.penumbra = PointerProperty(type=PenumbraSceneSettings)
    bpy.types.Object.penumbra = PointerProperty(type=PenumbraObjectSettings)


def unregister():
    del bpy.types.Object.penumbra
    del bpy.types.Scene.penumbra
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
