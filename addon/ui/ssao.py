"""Comparisons > SSAO: screen-space AO against ray-traced AO (issue: SSAO lab)."""
import bpy


class IL_PG_ssao(bpy.types.PropertyGroup):
    """SSAO-lab settings, stored at ``scene.illumination.ssao``."""


class IL_PT_ssao(bpy.types.Panel):
    bl_idname = "IL_PT_ssao"
    bl_label = "SSAO"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
    bl_parent_id = "IL_PT_comparisons"
    bl_order = 20

    def draw(self, context):
        self.layout.label(text="Crytek, hemisphere, HBAO, GTAO, EEVEE, Workbench")


classes = (IL_PG_ssao, IL_PT_ssao)
register, unregister = bpy.utils.register_classes_factory(classes)
