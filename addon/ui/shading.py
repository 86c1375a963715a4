"""Panel section "Shading": node groups, shading-model assignment, light relinking, model parameters."""
import bpy
from ..blender.materials import buried
from ..core.errors import warn
from ..core.result import JobResult
from ..nodes import groups, material
from ..nodes.options import ShadingOptions
from .panel import Sidebar
from . import polls, props
from .operator import JobOperator


class IL_PG_shading(bpy.types.PropertyGroup):
    """Shading settings, stored at ``scene.illumination.shading`` (nodes.options.ShadingOptions)."""

    __annotations__ = props.properties(ShadingOptions)


class IL_OT_add_node_groups(JobOperator, bpy.types.Operator):
    """Add the IL shading node groups to this file (updates groups made by an older version)"""

    bl_idname = "illumination.add_node_groups"
    bl_label = "Add Node Groups"
    bl_options = {"REGISTER", "UNDO"}

    def job(self, context):
        result = groups.add_node_groups()
        return JobResult(result, summary=f"node groups: {len(result['created'])} created, "
                                         f"{len(result['updated'])} updated, {len(result['current'])} already current")


class IL_OT_assign_shading_model(JobOperator, bpy.types.Operator):
    """Give each material of the selected meshes an IL material that sums the model over the lights, linked by
    drivers, with the parameters read from it (Remove Shading Model gives the originals back)"""

    bl_idname = "illumination.assign_shading_model"
    bl_label = "Assign Shading Model"
    bl_options = {"REGISTER", "UNDO"}

    __annotations__ = props.properties(ShadingOptions)

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def job(self, context):
        o = props.options(ShadingOptions, self)
        mats, warnings = material.assign_materials(context.scene, context.selected_objects, o)
        for w in warnings:
            warn(w)
        names, lights = [m.name for m in mats], list(mats[0]["il_light_names"])
        what = f"'{names[0]}'" if len(names) == 1 else f"{len(names)} materials"
        return JobResult({"material": names[0], "materials": names, "lights": lights},
                         summary=f"assigned {what} ({len(lights)} lights)")


def _restorable(cls, context):
    """True when a selected object holds a material Assign Shading Model made."""
    if material.restorable(context.selected_objects):
        return True
    over = buried(context.selected_objects, "shading")
    cls.poll_message_set(f"The shading model is under the {over}: remove that first" if over else
                         "Nothing to restore: no selected object has a material made by Assign Shading Model")
    return False


class IL_OT_remove_shading_model(JobOperator, bpy.types.Operator):
    """Give the selected objects back the materials Assign Shading Model replaced"""

    bl_idname = "illumination.remove_shading_model"
    bl_label = "Remove Shading Model"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context) and _restorable(cls, context)

    def job(self, context):
        count = material.restore_materials(context.selected_objects)
        return JobResult({"slots": count}, summary=f"restored {count} material slot(s)")


class IL_OT_relink_lights(JobOperator, bpy.types.Operator):
    """Relink the IL materials to the scene's current lights (after adding or deleting lights)"""

    bl_idname = "illumination.relink_lights"
    bl_label = "Relink Lights"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context)

    def job(self, context):
        count, warnings = material.relink_lights(context.scene)
        for w in warnings:
            warn(w)
        return JobResult({"materials": count}, summary=f"relinked {count} material(s)")


class IL_PT_shading(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_shading"
    bl_label = "Shading"
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
        for name in ShadingOptions.__dataclass_fields__:
            setattr(op, name, getattr(settings, name))
        layout.operator(IL_OT_remove_shading_model.bl_idname, icon="LOOP_BACK")
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


classes = (IL_PG_shading, IL_OT_add_node_groups, IL_OT_assign_shading_model, IL_OT_remove_shading_model,
           IL_OT_relink_lights, IL_PT_shading)
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    material.add_handlers()


def unregister():
    material.remove_handlers()
    _unregister_classes()
