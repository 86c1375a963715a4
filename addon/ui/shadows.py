"""Comparisons > Shadows: shadow scenes against ray-traced shadows (issue: shadow lab)."""
import bpy


class IL_PG_shadows(bpy.types.PropertyGroup):
    """Shadow-lab settings, stored at ``scene.illumination.shadows``."""


class IL_PT_shadows(bpy.types.Panel):
    bl_idname = "IL_PT_shadows"
    bl_label = "Shadows"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
    bl_parent_id = "IL_PT_comparisons"
    bl_order = 10

    def draw(self, context):
        self.layout.label(text="Planar, shadow map, shadow volume, EEVEE, Workbench")


classes = (IL_PG_shadows, IL_PT_shadows)
register, unregister = bpy.utils.register_classes_factory(classes)
