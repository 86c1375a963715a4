"""The sidebar panel "Illumination" (3D viewport > N panel) and its Comparisons parent."""
import bpy

from ..lab.demo import scene as demo
from . import polls
from .operator import BuildSceneOperator


class Sidebar:
    """Where every panel of the add-on lives: the 3D viewport's sidebar, tab "Illumination"."""
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"


class IL_OT_build_demo_scene(BuildSceneOperator, bpy.types.Operator):
    """Build the embedded demo scene as a new scene (the current one is left untouched)"""

    bl_idname = "illumination.build_demo_scene"
    bl_label = "Build Demo Scene"

    @classmethod
    def poll(cls, context):
        return polls.object_mode(cls, context)

    def build(self, context):
        return demo.build_demo_scene(new_scene=True)


class IL_PT_main(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_main"
    bl_label = "Illumination"

    def draw(self, context):
        self.layout.operator(IL_OT_build_demo_scene.bl_idname, icon="SCENE_DATA")


class IL_PT_comparisons(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_comparisons"
    bl_label = "Comparisons"
    bl_parent_id = "IL_PT_main"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 30

    def draw(self, context):
        self.layout.label(text="Each method against a ray-traced reference")


classes = (IL_OT_build_demo_scene, IL_PT_main, IL_PT_comparisons)
register, unregister = bpy.utils.register_classes_factory(classes)
