"""Versioning of stored settings: a .blend saved by an older Penumbra keeps values under names that were
renamed since (core.settings.RENAMED). Blender leaves such values in the property group's storage, unused;
after each file load this handler copies them to their new names and drops the old entries, so a scene
renders as it was saved."""
from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from ..engine.core.settings import RENAMED


def _storage(props):
    """The ID-property group that holds scene.penumbra's stored values (Blender 5.0 keeps the values of
    registered properties apart from custom properties; 4.x reads them through the group itself)."""
    getter = getattr(props, "bl_system_properties_get", None)
    return getter() if getter is not None else props


def upgrade_scene(scene) -> list[str]:
    """Move values stored under old names to their new names; returns 'old → new' for each one moved."""
    props = getattr(scene, "penumbra", None)
    store = _storage(props) if props is not None else None
    if store is None:
        return []
    moved = []
    for old, new in RENAMED.items():
        if old not in store.keys():
            continue
        value = store[old]
        # A value already saved under the new name wins: the file was saved by a newer version too.
        if new not in store.keys():
            current = getattr(props, new)
            setattr(props, new, type(current)(value))     # stored ints become bools for boolean settings
            moved.append(f"{old} → {new}")
        del store[old]
    return moved


@persistent
def load_post(*_args):
    for scene in bpy.data.scenes:
        moved = upgrade_scene(scene)
        if moved:
            print(f"Penumbra: scene '{scene.name}': settings renamed since the file was saved: {', '.join(moved)}")


def register():
    if load_post not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(load_post)


def unregister():
    if load_post in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(load_post)
