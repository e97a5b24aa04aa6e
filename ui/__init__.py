from . import panels, properties, versioning


def register():
    versioning.register()           # before the properties: a file loaded from now on gets upgraded
    properties.register()
    panels.register()


def unregister():
    panels.unregister()
    properties.unregister()
    versioning.unregister()
