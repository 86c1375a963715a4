"""Panel section "Environment mapping": reflection and refraction mapping of the world's image (issue 29)."""
import bpy

from ..blender.materials import buried
from ..core.errors import warn
from ..core.result import JobResult
from ..nodes import environment
from ..nodes.environment import EnvironmentOptions
from .panel import Sidebar
from . import polls, props
from .operator import JobOperator


class IL_OT_assign_environment_mapping(JobOperator, bpy.types.Operator):
    """Give the selected meshes a material that reflects (r) or refracts (t) the world's environment image
    through a lat-long, cube or sphere map, times Schlick's F or 1 - F (Remove Environment Mapping undoes it)"""

    bl_idname = "illumination.assign_environment_mapping"
    bl_label = "Assign Environment Mapping"
    bl_options = {"REGISTER", "UNDO"}

    __annotations__ = props.properties(EnvironmentOptions)

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=360)

    def job(self, context):
        o = props.options(EnvironmentOptions, self)
        mats, warnings = environment.assign_environment_mapping(context.scene, context.selected_objects, o)
        for w in warnings:
            warn(w)
        what = f"'{mats[0].name}'" if len(mats) == 1 else f"{len(mats)} materials"
        return JobResult({"materials": [m.name for m in mats]},
                         summary=f"assigned {what} ({o.mode.lower()}, {o.projection.lower()})")


class IL_OT_remove_environment_mapping(JobOperator, bpy.types.Operator):
    """Give the selected objects back the materials Assign Environment Mapping replaced"""

    bl_idname = "illumination.remove_environment_mapping"
    bl_label = "Remove Environment Mapping"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if not (polls.has_scene(cls, context) and polls.object_mode(cls, context)):
            return False
        if environment.restorable(context.selected_objects):
            return True
        over = buried(context.selected_objects, "environment")
        cls.poll_message_set(f"Environment mapping is under the {over}: remove that first" if over else
                             "Nothing to restore: no selected object has a material made by Assign Environment Mapping")
        return False

    def job(self, context):
        count = environment.remove_environment_mapping(context.selected_objects)
        return JobResult({"slots": count}, summary=f"restored {count} material slot(s)")


class IL_OT_add_environment_group(JobOperator, bpy.types.Operator):
    """Add the node group "IL Environment Map" (lookup direction, Fresnel weight, cube and sphere map
    coordinates) for your own materials"""

    bl_idname = "illumination.add_environment_group"
    bl_label = "Add Environment Map Group"
    bl_options = {"REGISTER", "UNDO"}

    def job(self, context):
        tree = environment.ensure_group()
        return JobResult({"group": tree.name}, summary=f"node group '{tree.name}' ready")


class IL_PT_environment(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_environment"
    bl_label = "Environment mapping"
    bl_parent_id = "IL_PT_main"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 15

    def draw(self, context):
        col = self.layout.column(align=True)
        col.operator(IL_OT_assign_environment_mapping.bl_idname, icon="MAT_SPHERE_SKY")
        col.operator(IL_OT_remove_environment_mapping.bl_idname, icon="LOOP_BACK")
        col.operator(IL_OT_add_environment_group.bl_idname, icon="NODETREE")


classes = (IL_OT_assign_environment_mapping, IL_OT_remove_environment_mapping, IL_OT_add_environment_group,
           IL_PT_environment)
register, unregister = bpy.utils.register_classes_factory(classes)
