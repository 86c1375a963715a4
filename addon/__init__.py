"""Illumination Lab: classic illumination models as Blender tools, measured.

``register()`` registers each UI module's ``classes`` in order, ``unregister()``
in reverse, and leaves nothing behind. ``import addon.core`` needs no bpy: the
UI modules are imported only when registering.
"""


def _modules():
    from .ui import environment, envmap, lightmaps, panel, raytrace, reflections, settings, shading, shadows, ssao
    return (panel, shading, environment, lightmaps, envmap, shadows, ssao, reflections, raytrace, settings)


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
