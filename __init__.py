"""Track & Stride Blender extension entry point: delegates to :mod:`.addon`."""


def register():
    from . import addon
    addon.register()


def unregister():
    from . import addon
    addon.unregister()
