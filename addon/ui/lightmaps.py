"""Panel section "Light maps": AO and irradiance bakes (issue: light maps)."""
import bpy


class IL_PG_lightmaps(bpy.types.PropertyGroup):
    """Light-map settings, stored at ``scene.illumination.lightmaps``."""


class IL_PT_lightmaps(bpy.types.Panel):
    bl_idname = "IL_PT_lightmaps"
    bl_label = "Light maps"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
    bl_parent_id = "IL_PT_main"
    bl_order = 20

    def draw(self, context):
        self.layout.label(text="Ambient occlusion and irradiance, baked with Cycles")


classes = (IL_PG_lightmaps, IL_PT_lightmaps)
register, unregister = bpy.utils.register_classes_factory(classes)
