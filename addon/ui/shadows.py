"""Comparisons > Shadows: shadow scenes against ray-traced shadows (issue: shadow lab)."""
import bpy
from bpy.props import EnumProperty, StringProperty

from ..core.errors import InputError
from ..lab.options import LIGHT_TYPE_CHOICES, SHADOW_SCENE_CHOICES, ShadowOptions
from .panel import Sidebar
from . import polls, props
from .operator import BuildSceneOperator, JobOperator


class IL_PG_shadows(bpy.types.PropertyGroup):
    """Shadow-lab settings, stored at ``scene.illumination.shadows`` (lab.options.ShadowOptions; the
    reference is always run, so the panel's method list leaves it out)."""
    __annotations__ = {
        "scene_name": EnumProperty(name="Scene", items=SHADOW_SCENE_CHOICES, default="sphere"),
        "light_type": EnumProperty(name="Light", items=LIGHT_TYPE_CHOICES, default="sun"),
        "light": StringProperty(name="Light Object", description="Light to test (empty: the scene's first light)"),
        **props.properties(ShadowOptions, bias={"precision": 4}, pcf={"step": 2}, methods={
            "items": [c for c in ShadowOptions.__dataclass_fields__["methods"].metadata["spec"].choices
                      if c[0] != "raytraced"],
            "default": {"planar", "shadowmap", "volume_zpass", "volume_zfail"}}),
        "output_dir": props.output_dir("//shadows", "Folder for the masks, error images and shadows_report.json"),
        "last_report": StringProperty(name="Report", default=""),
        "last_summary": StringProperty(default=""),
    }


class IL_OT_build_shadow_scene(BuildSceneOperator, bpy.types.Operator):
    """Add a built-in minimal shadow scene as a new scene (your scenes stay as they are)"""
    bl_idname = "illumination.build_shadow_scene"
    bl_label = "Build Shadow Scene"

    @classmethod
    def poll(cls, context):
        return polls.object_mode(cls, context)

    def build(self, context):
        from ..lab.shadows import scenes as shadow_scenes
        st = context.scene.illumination.shadows
        return shadow_scenes.build(st.scene_name, st.light_type, (st.resolution, st.resolution))

    def built(self, context, scene):
        new = scene.illumination.shadows
        new.light = scene["il_shadow_light"]
        new.receiver = scene["il_shadow_receiver"]


class IL_OT_run_shadow_comparison(JobOperator, bpy.types.Operator):
    """Render the ray-traced reference and every chosen method on the same pixels; write masks and a report"""
    bl_idname = "illumination.run_shadow_comparison"
    bl_label = "Run Shadow Comparison"

    @classmethod
    def poll(cls, context):
        if not (polls.has_scene(cls, context) and polls.object_mode(cls, context)):
            return False
        return polls.saved_or_absolute(cls, context.scene.illumination.shadows.output_dir)

    def job(self, context):
        from ..lab import shadows
        scene = context.scene
        st = scene.illumination.shadows
        light = st.light or next((o.name for o in scene.objects if o.type == "LIGHT"), "")
        if not light:
            raise InputError(f"scene '{scene.name}' has no light: add one (or Build Shadow Scene)")
        o = props.options(ShadowOptions, st, methods=["raytraced", *sorted(st.methods)])
        return shadows.compare(scene, light, bpy.path.abspath(st.output_dir), o)

    def finished(self, context, result):
        st = context.scene.illumination.shadows
        st.last_report = result.path
        st.last_summary = result.summary
        result.summary = f"Shadow report: {result.path}"


class IL_PT_shadows(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_shadows"
    bl_label = "Shadows"
    bl_parent_id = "IL_PT_comparisons"
    bl_order = 10

    def draw(self, context):
        layout = self.layout
        st = context.scene.illumination.shadows
        col = layout.column(align=True)
        col.prop(st, "scene_name")
        col.prop(st, "light_type")
        col.operator(IL_OT_build_shadow_scene.bl_idname, icon="LIGHT_SUN")
        layout.prop_search(st, "light", context.scene, "objects")
        layout.prop_search(st, "receiver", context.blend_data, "objects")
        layout.prop(st, "methods")
        col = layout.column(align=True)
        col.prop(st, "resolution")
        col.prop(st, "shadowmap_size")
        col.prop(st, "bias")
        col.prop(st, "slope_bias")
        col.prop(st, "pcf")
        layout.prop(st, "output_dir")
        layout.operator(IL_OT_run_shadow_comparison.bl_idname, icon="RENDER_STILL")
        if st.last_report:
            box = layout.box()
            box.label(text="Report:")
            box.label(text=st.last_report)
            if st.last_summary:
                box.label(text=st.last_summary)


classes = (IL_PG_shadows, IL_OT_build_shadow_scene, IL_OT_run_shadow_comparison, IL_PT_shadows)
register, unregister = bpy.utils.register_classes_factory(classes)
