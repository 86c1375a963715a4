"""Panel section "Shading": node groups and shading-model assignment (issue: shading)."""
import bpy


class IL_PG_shading(bpy.types.PropertyGroup):
    """Shading settings, stored at ``scene.illumination.shading``."""


class IL_PT_shading(bpy.types.Panel):
    bl_idname = "IL_PT_shading"
    bl_label = "Shading"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
    bl_parent_id = "IL_PT_main"
    bl_order = 10

    def draw(self, context):
        self.layout.label(text="Phong, Blinn-Phong, Oren-Nayar, Cook-Torrance")


classes = (IL_PG_shading, IL_PT_shading)
register, unregister = bpy.utils.register_classes_factory(classes)
