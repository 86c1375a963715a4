"""Comparisons > Ray tracing: ray casting and Whitted ray tracing against Cycles (scripts/raytrace.py)."""
import json

import bpy
from bpy.props import EnumProperty, StringProperty

from ..lab.options import RAYTRACE_SCENE_CHOICES, RaytraceOptions
from .panel import Sidebar
from . import polls, props
from .operator import BuildSceneOperator, JobOperator


class IL_PG_raytrace(bpy.types.PropertyGroup):
    """Ray-tracing-lab settings, stored at ``scene.illumination.raytrace`` (lab.options.RaytraceOptions)."""

    __annotations__ = {
        "scene_kind": EnumProperty(name="Scene", items=RAYTRACE_SCENE_CHOICES, default="glass",
                                   description="Built-in scene that Build adds"),
        **props.properties(RaytraceOptions),
        "output_dir": props.output_dir("//raytrace/", "Folder for the images and raytrace_report.json"),
        "last_report": StringProperty(name="Last Report", default="", options={"SKIP_SAVE"}),
    }


class IL_OT_raytrace_build_scene(BuildSceneOperator, bpy.types.Operator):
    """Add the chosen built-in ray-tracing scene as a new scene"""

    bl_idname = "illumination.raytrace_build_scene"
    bl_label = "Build Ray-Tracing Scene"

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def build(self, context):
        from ..lab.raytrace import scenes
        s = context.scene.illumination.raytrace
        return scenes.build(s.scene_kind, (s.resolution, s.resolution))


class IL_OT_raytrace_render(JobOperator, bpy.types.Operator):
    """Render the scene camera by ray casting or Whitted ray tracing, compare with Cycles on the same light paths,
    write the images (and the light Whitted leaves out) and the report"""

    bl_idname = "illumination.raytrace_render"
    bl_label = "Run Ray Tracing"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if not (polls.has_scene(cls, context) and polls.object_mode(cls, context)):
            return False
        if context.scene.camera is None:
            cls.poll_message_set("The scene needs a camera")
            return False
        return polls.saved_or_absolute(cls, context.scene.illumination.raytrace.output_dir)

    def job(self, context):
        from ..lab import raytrace
        s = context.scene.illumination.raytrace
        out = bpy.path.abspath(s.output_dir)
        result = raytrace.run(context.scene, out, props.options(RaytraceOptions, s))
        result.summary = f"{result.summary}; {result.path}"
        return result

    def finished(self, context, result):
        r = result.report
        context.scene.illumination.raytrace.last_report = json.dumps(
            [r["method"], r["rays_per_second"], r["relative_rmse_vs_cycles"],
             (r.get("missing") or {}).get("fraction")])


class IL_PT_raytrace(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_raytrace"
    bl_label = "Ray tracing"
    bl_parent_id = "IL_PT_comparisons"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 40

    def draw(self, context):
        layout = self.layout
        s = context.scene.illumination.raytrace
        row = layout.row(align=True)
        row.prop(s, "scene_kind", text="")
        row.operator(IL_OT_raytrace_build_scene.bl_idname, text="Build", icon="SCENE_DATA")
        col = layout.column(align=True)
        for name in ("method", "max_depth", "resolution", "engine", "compare", "samples"):
            col.prop(s, name)
        layout.prop(s, "output_dir")
        layout.operator(IL_OT_raytrace_render.bl_idname, icon="RENDER_STILL")
        if s.last_report:
            method, rays_per_second, rel, missing = json.loads(s.last_report)
            box = layout.box()
            if rays_per_second is not None:
                box.label(text=f"{method}: {rays_per_second / 1e3:.0f} k rays/s")
            if rel is not None:
                box.label(text=f"relative RMSE against Cycles: {rel:.3f}")
            if missing is not None:
                box.label(text=f"light left out: {100 * missing:.1f} %")


classes = (IL_PG_raytrace, IL_OT_raytrace_build_scene, IL_OT_raytrace_render, IL_PT_raytrace)
register, unregister = bpy.utils.register_classes_factory(classes)
