"""Penumbra: a soft-shadow render engine for Blender, measured against Cycles.

Only register()/unregister() live here. Importing the package pulls in no bpy, so the GPU pipeline and the
command line work without Blender's UI.
"""


def _modules():
    from . import operators, ui
    from .engine.blender import render_engine
    return (ui, render_engine, operators)


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
