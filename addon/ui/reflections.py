"""Comparisons > Reflections: lat-long, cube and sphere maps against Cycles' mirror (scripts/reflections.py)."""
import json

import bpy
from bpy.props import EnumProperty, StringProperty

from ..lab.options import REFLECTION_SCENE_CHOICES, ReflectionOptions
from .panel import Sidebar
from . import polls, props
from .operator import BuildSceneOperator, JobOperator


class IL_PG_reflections(bpy.types.PropertyGroup):
    """Reflection-lab settings, stored at ``scene.illumination.reflections`` (lab.options.ReflectionOptions)."""

    __annotations__ = {
        "scene_kind": EnumProperty(name="Scene", items=REFLECTION_SCENE_CHOICES, default="sphere",
                                   description="Built-in scene that Build adds"),
        **props.properties(ReflectionOptions),
        "output_dir": props.output_dir("//reflections/", "Folder for the method images and reflections_report.json"),
        "last_report": StringProperty(name="Last Report", default="", options={"SKIP_SAVE"}),
    }


class IL_OT_reflections_build_scene(BuildSceneOperator, bpy.types.Operator):
    """Add the chosen built-in reflection scene (a mirror named "Mirror" under a sky) as a new scene"""

    bl_idname = "illumination.reflections_build_scene"
    bl_label = "Build Reflection Scene"

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def build(self, context):
        from ..lab.reflections import scenes
        s = context.scene.illumination.reflections
        return scenes.build(s.scene_kind, s.resolution)


class IL_OT_reflections_compare(JobOperator, bpy.types.Operator):
    """Render Cycles' mirror on the chosen object, look the reflected rays up in each map type, write the images
    and the report"""

    bl_idname = "illumination.reflections_compare"
    bl_label = "Run Reflection Comparison"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if not (polls.has_scene(cls, context) and polls.object_mode(cls, context)):
            return False
        if context.scene.camera is None:
            cls.poll_message_set("The scene needs a camera")
            return False
        return polls.saved_or_absolute(cls, context.scene.illumination.reflections.output_dir)

    def job(self, context):
        from ..lab import reflections
        s = context.scene.illumination.reflections
        out = bpy.path.abspath(s.output_dir)
        result = reflections.compare(context.scene, out, props.options(ReflectionOptions, s))
        result.summary = f"{result.summary}; {result.path}"
        return result

    def finished(self, context, result):
        context.scene.illumination.reflections.last_report = json.dumps(
            {m: [e["relative_rmse"], e["seconds"]] for m, e in result["methods"].items()})


class IL_PT_reflections(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_reflections"
    bl_label = "Reflections"
    bl_parent_id = "IL_PT_comparisons"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 30

    def draw(self, context):
        layout = self.layout
        s = context.scene.illumination.reflections
        row = layout.row(align=True)
        row.prop(s, "scene_kind", text="")
        row.operator(IL_OT_reflections_build_scene.bl_idname, text="Build", icon="SCENE_DATA")
        layout.prop(s, "methods")
        col = layout.column(align=True)
        for name in ("object", "resolution", "map_size", "samples"):
            col.prop(s, name)
        layout.prop(s, "output_dir")
        layout.operator(IL_OT_reflections_compare.bl_idname, icon="RENDER_STILL")
        if s.last_report:
            box = layout.box()
            box.label(text="Relative RMSE / seconds against Cycles' mirror")
            for method, (rel, seconds) in json.loads(s.last_report).items():
                box.label(text=f"{method}: {rel:.3f}  {seconds:.2f} s")


classes = (IL_PG_reflections, IL_OT_reflections_build_scene, IL_OT_reflections_compare, IL_PT_reflections)
register, unregister = bpy.utils.register_classes_factory(classes)
