from . import panels, properties


def register():
    properties.register()
    panels.register()


def unregister():
    panels.unregister()
    properties.unregister()
