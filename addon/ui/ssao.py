"""Comparisons > SSAO: screen-space AO against ray-traced AO (issue: SSAO lab)."""
import json

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ..lab.options import SSAO_SCENE_CHOICES, SSAOOptions
from .panel import Sidebar
from . import polls, props
from .operator import BuildSceneOperator, JobOperator


class IL_PG_ssao(bpy.types.PropertyGroup):
    """SSAO-lab settings, stored at ``scene.illumination.ssao`` (lab.options.SSAOOptions)."""

    __annotations__ = {
        "scene_kind": EnumProperty(name="Scene", items=SSAO_SCENE_CHOICES, default="corner",
                                   description="Built-in scene that Build SSAO Scene adds"),
        **props.properties(SSAOOptions),
        "radius_auto": BoolProperty(name="Radius from Scene", default=True,
                                    description="Radius = a tenth of the frame's width at the median depth of the "
                                    "visible geometry (the report gives it); off: the Radius below"),
        "output_dir": props.output_dir("//ssao/", "Folder for the AO images, error images and ssao_report.json"),
        "last_report": StringProperty(name="Last Report", default="", options={"SKIP_SAVE"}),
    }


class IL_OT_ssao_build_scene(BuildSceneOperator, bpy.types.Operator):
    """Add the chosen built-in SSAO scene as a new scene (yours stay as they are)"""

    bl_idname = "illumination.ssao_build_scene"
    bl_label = "Build SSAO Scene"

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def build(self, context):
        from ..lab.ssao import scenes as ssao_scenes
        settings = context.scene.illumination.ssao
        return ssao_scenes.build_scene(settings.scene_kind, settings.resolution, settings.radius)


class IL_OT_ssao_compare(JobOperator, bpy.types.Operator):
    """Render the G-buffer and Cycles' AO reference, run the chosen methods, write images and a report"""

    bl_idname = "illumination.ssao_compare"
    bl_label = "Run SSAO Comparison"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if not polls.has_scene(cls, context):
            return False
        if context.scene.camera is None:
            cls.poll_message_set("The scene needs a camera")
            return False
        return polls.saved_or_absolute(cls, context.scene.illumination.ssao.output_dir)

    def job(self, context):
        from ..lab import ssao as lab
        s = context.scene.illumination.ssao
        o = props.options(SSAOOptions, s, radius=None if s.radius_auto else s.radius)
        out = bpy.path.abspath(s.output_dir)
        result = lab.compare(context.scene, out, o)
        result.summary = f"SSAO report written to {out}"
        return result

    def finished(self, context, result):
        context.scene.illumination.ssao.last_report = json.dumps(
            {m: [r["rmse"], r["bias"], r["seconds"]] for m, r in result["methods"].items()})


class IL_PT_ssao(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_ssao"
    bl_label = "SSAO"
    bl_parent_id = "IL_PT_comparisons"
    bl_order = 20

    def draw(self, context):
        layout = self.layout
        s = context.scene.illumination.ssao
        row = layout.row(align=True)
        row.prop(s, "scene_kind", text="")
        row.operator(IL_OT_ssao_build_scene.bl_idname, text="Build", icon="SCENE_DATA")
        layout.prop(s, "methods")
        col = layout.column(align=True)
        col.prop(s, "resolution")
        col.prop(s, "samples")
        col.prop(s, "radius_auto")
        sub = col.row(align=True)
        sub.active = not s.radius_auto
        sub.prop(s, "radius")
        col.prop(s, "reference_samples")
        layout.prop(s, "blur")
        layout.prop(s, "output_dir")
        layout.operator(IL_OT_ssao_compare.bl_idname, icon="RENDER_STILL")
        if s.last_report:
            box = layout.box()
            box.label(text="RMSE / bias / seconds against Cycles AO")
            for method, (rmse, bias, seconds) in json.loads(s.last_report).items():
                box.label(text=f"{method}: {rmse:.3f}  {bias:+.3f}  {seconds:.2f} s")


classes = (IL_PG_ssao, IL_OT_ssao_build_scene, IL_OT_ssao_compare, IL_PT_ssao)
register, unregister = bpy.utils.register_classes_factory(classes)
