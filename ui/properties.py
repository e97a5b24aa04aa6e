"""Blender properties: scene.penumbra (render settings: the technique, then one property per Option, shared
or a technique's own, generated from the Option's default and range) and object.penumbra (the object's role
for techniques that split casters from receivers)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

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
    if isinstance(opt.default, str):
        return StringProperty(default=opt.default, **common)
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
    importance: FloatProperty(name="Shadow Importance", default=0.0, min=0.0, max=1.0, subtype="FACTOR",
                              description="BACKPROJECTION with the Importance budget map: the budget on this "
                                          "object's pixels, from the low budget (0) to the budget (1); a custom "
                                          "property 'penumbra_importance' overrides it")


class PenumbraCompareSettings(bpy.types.PropertyGroup):
    """Compare with Cycles: what to run, its progress while it runs, and the last result's numbers (saved
    with the .blend, so they stay beside the image they describe)."""
    preview: BoolProperty(name="Preview", default=True,
                          description="Capped resolution (longest side 256 px) and Cycles samples (32), no noise "
                                      "floor: seconds instead of minutes; the result says so")
    samples: IntProperty(name="Cycles Samples", default=256, min=1, max=65536)
    noise_floor: BoolProperty(name="Noise Floor", default=True,
                              description="Render Cycles a second time with another seed to measure its own noise")
    directory: StringProperty(name="Output Folder", subtype="DIR_PATH", default="",
                              description="Empty: a folder penumbra_compare beside the .blend file (the system "
                                          "temporary folder while the file is unsaved)")
    running: BoolProperty(default=False)
    progress: FloatProperty(default=0.0, min=0.0, max=1.0, subtype="FACTOR")
    status: StringProperty(default="")
    technique: StringProperty(default="")
    mae_shadow: FloatProperty(default=-1.0, precision=4)
    n_shadow: IntProperty(default=0)
    noise_mae: FloatProperty(default=-1.0, precision=4)
    ours_ms: FloatProperty(default=0.0)
    cycles_seconds: FloatProperty(default=0.0)
    reference_samples: IntProperty(default=0)
    preview_caps: StringProperty(default="")
    undefined: StringProperty(default="")
    folder: StringProperty(default="")
    image: StringProperty(default="")


classes = (PenumbraSceneSettings, PenumbraObjectSettings, PenumbraCompareSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.penumbra = PointerProperty(type=PenumbraSceneSettings)
    bpy.types.Object.penumbra = PointerProperty(type=PenumbraObjectSettings)
    bpy.types.Scene.penumbra_compare = PointerProperty(type=PenumbraCompareSettings)


def unregister():
    del bpy.types.Scene.penumbra_compare
    del bpy.types.Object.penumbra
    del bpy.types.Scene.penumbra
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
