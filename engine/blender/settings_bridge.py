"""scene.penumbra (Blender properties, declared in ui/properties.py) → RenderSettings, the only settings object
the renderer reads."""
from __future__ import annotations

from ..core.settings import RenderSettings
from ..render.pipeline import TECHNIQUES


def settings_from_scene(scene) -> RenderSettings:
    """RenderSettings from scene.penumbra (defaults where a field has no property)."""
    props = getattr(scene, "penumbra", None)
    if props is None:
        return RenderSettings()
    values = {name: getattr(props, name) for name in RenderSettings.field_names()
              if name in props.bl_rna.properties}
    extras = {opt.name: getattr(props, opt.name) for t in TECHNIQUES.values() for opt in t.options
              if opt.name in props.bl_rna.properties}
    return RenderSettings(**values, extras=extras)


def viewport_settings(scene) -> RenderSettings:
    """RenderSettings of the viewport's refined frame."""
    settings = settings_from_scene(scene)
    props = scene.penumbra
    changes = {"shadow_map_size": props.viewport_map_size}
    if props.viewport_technique != "SAME":
        changes["technique"] = props.viewport_technique
    if props.viewport_pass not in ("Combined", "Visibility", "Unshadowed"):
        changes["debug_passes"] = True
    return settings.with_(**changes)
