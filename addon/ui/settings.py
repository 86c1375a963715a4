"""``scene.illumination``: one settings group, one sub-group per panel section."""
import bpy
from bpy.props import PointerProperty

from .lightmaps import IL_PG_lightmaps
from .raytrace import IL_PG_raytrace
from .reflections import IL_PG_reflections
from .shading import IL_PG_shading
from .shadows import IL_PG_shadows
from .ssao import IL_PG_ssao


class IL_PG_settings(bpy.types.PropertyGroup):
    shading: PointerProperty(type=IL_PG_shading)
    lightmaps: PointerProperty(type=IL_PG_lightmaps)
    shadows: PointerProperty(type=IL_PG_shadows)
    ssao: PointerProperty(type=IL_PG_ssao)
    reflections: PointerProperty(type=IL_PG_reflections)
    raytrace: PointerProperty(type=IL_PG_raytrace)


classes = (IL_PG_settings,)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    bpy.types.Scene.illumination = PointerProperty(type=IL_PG_settings)


def unregister():
    del bpy.types.Scene.illumination
    _unregister()
