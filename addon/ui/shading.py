"""Panel section "Shading": node groups, shading-model assignment, light relinking, model parameters."""
import bpy
from bpy.props import EnumProperty, FloatProperty

from ..core.errors import ILError
from ..nodes import groups, material
from . import polls

MODEL_ITEMS = [
    ("PHONG", "Phong", "k_a I_a + I (k_d n.l + k_s (r.v)^n) + I_e"),
    ("BLINN_PHONG", "Blinn-Phong", "Phong with (n.h)^n"),
    ("OREN_NAYAR", "Oren-Nayar", "Rough diffuse, qualitative model"),
    ("COOK_TORRANCE", "Cook-Torrance", "Microfacet specular: F D G / (4 n.l n.v)"),
]
LIGHT_ITEMS = [("ALL", "All Lights", "Every renderable light of the scene"),
               ("SELECTED", "Selected Lights", "Only the lights selected together with the meshes")]
ATTENUATION_ITEMS = [("PHYSICAL", "Physical (1/d²)", "Inverse-square law, matches Cycles' own lights"),
                     ("EMPIRICAL", "Empirical", "f_att = min(1/(c1 + c2 d + c3 d²), 1)")]


class IL_PG_shading(bpy.types.PropertyGroup):
    """Shading settings, stored at ``scene.illumination.shading``."""

    model: EnumProperty(name="Model", items=MODEL_ITEMS, default="PHONG")
    lights: EnumProperty(name="Lights", items=LIGHT_ITEMS, default="ALL")
    attenuation: EnumProperty(name="Attenuation", items=ATTENUATION_ITEMS, default="PHYSICAL")
    c1: FloatProperty(name="c1", default=1.0, min=0.0, description="Constant attenuation")
    c2: FloatProperty(name="c2", default=0.0, min=0.0, description="Linear attenuation")
    c3: FloatProperty(name="c3", default=1.0, min=0.0, description="Quadratic attenuation")


class IL_OT_add_node_groups(bpy.types.Operator):
    """Add the IL shading node groups to this file (updates groups made by an older version)"""

    bl_idname = "illumination.add_node_groups"
    bl_label = "Add Node Groups"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            result = groups.add_node_groups()
        except ILError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"node groups: {len(result['created'])} created, {len(result['updated'])} updated, "
                              f"{len(result['current'])} already current")
        return {"FINISHED"}


class IL_OT_assign_shading_model(bpy.types.Operator):
    """Give the selected meshes a material that sums the model over the lights, linked by drivers"""

    bl_idname = "illumination.assign_shading_model"
    bl_label = "Assign Shading Model"
    bl_options = {"REGISTER", "UNDO"}

    model: EnumProperty(name="Model", items=MODEL_ITEMS, default="PHONG")
    lights: EnumProperty(name="Lights", items=LIGHT_ITEMS, default="ALL")
    attenuation: EnumProperty(name="Attenuation", items=ATTENUATION_ITEMS, default="PHYSICAL")
    c1: FloatProperty(name="c1", default=1.0, min=0.0)
    c2: FloatProperty(name="c2", default=0.0, min=0.0)
    c3: FloatProperty(name="c3", default=1.0, min=0.0)

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def execute(self, context):
        try:
            mat, warnings = material.assign_shading_model(
                context.scene, context.selected_objects, self.model, self.lights, self.attenuation,
                (self.c1, self.c2, self.c3))
        except ILError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        for w in warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"assigned '{mat.name}' ({len(mat['il_light_names'])} lights)")
        return {"FINISHED"}


class IL_OT_relink_lights(bpy.types.Operator):
    """Relink the IL materials to the scene's current lights (after adding or deleting lights)"""

    bl_idname = "illumination.relink_lights"
    bl_label = "Relink Lights"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context)

    def execute(self, context):
        try:
            count, warnings = material.relink_lights(context.scene)
        except ILError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        for w in warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"relinked {count} material(s)")
        return {"FINISHED"}


class IL_PT_shading(bpy.types.Panel):
    bl_idname = "IL_PT_shading"
    bl_label = "Shading"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
    bl_parent_id = "IL_PT_main"
    bl_order = 10

    def draw(self, context):
        layout = self.layout
        settings = context.scene.illumination.shading
        layout.operator(IL_OT_add_node_groups.bl_idname, icon="NODETREE")
        col = layout.column(align=True)
        col.prop(settings, "model")
        col.prop(settings, "lights")
        col.prop(settings, "attenuation")
        if settings.attenuation == "EMPIRICAL":
            row = col.row(align=True)
            row.prop(settings, "c1")
            row.prop(settings, "c2")
            row.prop(settings, "c3")
        op = layout.operator(IL_OT_assign_shading_model.bl_idname, icon="MATERIAL")
        op.model, op.lights, op.attenuation = settings.model, settings.lights, settings.attenuation
        op.c1, op.c2, op.c3 = settings.c1, settings.c2, settings.c3
        layout.operator(IL_OT_relink_lights.bl_idname, icon="LIGHT")

        obj = context.active_object
        mat = obj.active_material if obj is not None else None
        params = material.parameter_nodes(mat)
        if not params:
            return
        box = layout.box()
        box.label(text=f"{mat.name}: {material.MODEL_LABELS.get(mat['il_model'], '?')}", icon="MATERIAL")
        for name, node in params:
            box.prop(node.outputs[0], "default_value", text=name)
        box.label(text=f"Lights: {', '.join(mat.get('il_light_names', [])) or 'none'}", icon="LIGHT")


classes = (IL_PG_shading, IL_OT_add_node_groups, IL_OT_assign_shading_model, IL_OT_relink_lights, IL_PT_shading)
register, unregister = bpy.utils.register_classes_factory(classes)
