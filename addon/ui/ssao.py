"""Comparisons > SSAO: screen-space AO against ray-traced AO (issue: SSAO lab)."""
import json

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from ..blender import compat
from ..core.ssao import limits
from . import common, polls

_SCENES = [("plane", "Plane", "One open plane: k_A = 1 (the sphere kernel reads 0.5)"),
           ("corner", "Box in a Corner", "A box in a room corner (closed forms away from the box)"),
           ("thin", "Thin Occluders", "A thin pole and a thin plate over a floor"),
           ("edge", "Screen Edge", "A box cut by the screen edge"),
           ("discontinuity", "Depth Discontinuity", "A ball floating in front of a wall (halos)")]
_METHODS = [("crytek", "Crytek", "Sphere kernel (seed 000)"),
            ("hemisphere", "Hemisphere", "Normal-oriented hemisphere with bias and range check"),
            ("hbao", "HBAO", "Horizon-based AO (Bavoil 2008)"),
            ("gtao", "GTAO", "Ground-truth AO, cosine-weighted slices (Jimenez 2016)"),
            ("eevee", "EEVEE", "EEVEE's AO pass (first render compiles shaders: about a minute)"),
            ("workbench", "Workbench", "Workbench world-space cavity")]


class IL_PG_ssao(bpy.types.PropertyGroup):
    """SSAO-lab settings, stored at ``scene.illumination.ssao``."""

    scene_kind: EnumProperty(name="Scene", items=_SCENES, default="corner",
                             description="Built-in scene that Build SSAO Scene adds")
    methods: EnumProperty(name="Methods", items=_METHODS, options={"ENUM_FLAG"},
                          default={"crytek", "hemisphere", "hbao", "gtao"},
                          description="Methods compared with the ray-traced reference")
    resolution: IntProperty(name="Resolution", default=128, min=16, max=limits.MAX_RESOLUTION,
                            description="Frame width in pixels (height keeps the scene's aspect; memory and "
                                        "time are checked before rendering)")
    samples: IntProperty(name="Samples", default=16, min=1, max=limits.MAX_SAMPLES,
                         description="Samples per pixel")
    radius: FloatProperty(name="Radius", default=1.0, min=0.001, soft_max=10.0, unit="LENGTH",
                          description="SSAO radius = the reference's AO distance")
    reference_samples: IntProperty(name="Reference Samples", default=1024, min=1,
                                   max=limits.MAX_REFERENCE_SAMPLES,
                                   description="Cycles AO samples per pixel of the reference")
    blur: BoolProperty(name="Depth-Aware Blur", default=False, description="Blur the numpy methods' results")
    output_dir: StringProperty(name="Output", subtype="DIR_PATH", default="//ssao/",
                               options=compat.BLEND_RELATIVE_PATH,
                               description="Folder for the AO images, error images and ssao_report.json")
    last_report: StringProperty(name="Last Report", default="", options={"SKIP_SAVE"})


class IL_OT_ssao_build_scene(bpy.types.Operator):
    """Add the chosen built-in SSAO scene as a new scene (yours stay as they are)"""

    bl_idname = "illumination.ssao_build_scene"
    bl_label = "Build SSAO Scene"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context)

    def execute(self, context):
        from ..lab.ssao import scenes as ssao_scenes
        settings = context.scene.illumination.ssao
        return common.open_built_scene(
            self, context, lambda: ssao_scenes.build_scene(settings.scene_kind, settings.resolution,
                                                           settings.radius))[0]


class IL_OT_ssao_compare(bpy.types.Operator):
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

    def execute(self, context):
        from ..lab import ssao as lab
        scene = context.scene
        s = scene.illumination.ssao
        out = bpy.path.abspath(s.output_dir)
        ok, report = common.run_job(self, lambda: lab.compare(
            scene, sorted(s.methods, key=[m[0] for m in _METHODS].index), out, samples=s.samples, radius=s.radius,
            reference_samples=s.reference_samples, resolution=s.resolution, blur=s.blur))
        if not ok:
            return {"CANCELLED"}
        s.last_report = json.dumps({m: [r["rmse"], r["bias"], r["seconds"]] for m, r in report["methods"].items()})
        self.report({"INFO"}, f"SSAO report written to {out}")
        return {"FINISHED"}


class IL_PT_ssao(bpy.types.Panel):
    bl_idname = "IL_PT_ssao"
    bl_label = "SSAO"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
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
        col.prop(s, "radius")
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
