"""Penumbra: a soft-shadow render engine for Blender, measured against Cycles.

Only register()/unregister() live here. Importing the package pulls in no bpy, so the engine's GPU side and
the command line work without Blender's UI.
"""


def register():
    from . import blender
    blender.register()


def unregister():
    from . import blender
    blender.unregister()
