"""Comparisons > Shadows: shadow scenes against ray-traced shadows (issue: shadow lab)."""
import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from ..blender import compat
from ..core.shadow import depth_map
from . import common, polls

_METHOD_ITEMS = [
    ("planar", "Planar", "Projected shadows onto the receiver plane"),
    ("shadowmap", "Shadow map", "Depth map from the light, numpy lookup with bias and PCF"),
    ("volume_zpass", "Volume z-pass", "Shadow volumes, stencil counted in front of the surface"),
    ("volume_zfail", "Volume z-fail", "Shadow volumes with caps, stencil counted behind the surface"),
    ("eevee", "EEVEE", "EEVEE's virtual shadow maps"),
    ("workbench", "Workbench", "Workbench stencil shadows (sun lights only)"),
]


class IL_PG_shadows(bpy.types.PropertyGroup):
    """Shadow-lab settings, stored at ``scene.illumination.shadows``."""
    scene_name: EnumProperty(name="Scene", items=[
        ("sphere", "Sphere", "A sphere over a floor"), ("stairs", "Stairs", "A sphere over steps (non-planar receiver)"),
        ("acne", "Acne", "A box under a grazing sun"), ("plate", "Plate", "A thin plate just above the floor"),
        ("inside", "Inside", "The camera stands inside a shadow volume")], default="sphere")
    light_type: EnumProperty(name="Light", items=[("sun", "Sun", ""), ("point", "Point", ""), ("spot", "Spot", "")],
                             default="sun")
    light: StringProperty(name="Light Object", description="Light to test (empty: the scene's first light)")
    receiver: StringProperty(name="Receiver", description="Plane object for planar shadows (empty: Floor)")
    methods: EnumProperty(name="Methods", items=_METHOD_ITEMS, options={"ENUM_FLAG"},
                          default={"planar", "shadowmap", "volume_zpass", "volume_zfail"})
    resolution: IntProperty(name="Resolution", default=128, min=8, max=depth_map.MAX_RESOLUTION,
                            description="Render width in pixels (memory is checked before rendering)")
    shadowmap_size: IntProperty(name="Shadow Map Size", default=1024, min=2, max=depth_map.MAX_SIZE,
                                description="N x N texels per map (memory is checked before rendering)")
    bias: FloatProperty(name="Bias", default=0.01, min=0.0, precision=4, unit="LENGTH")
    slope_bias: FloatProperty(name="Slope Bias", default=2.0, min=0.0, description="In texels x tan(theta)")
    pcf: IntProperty(name="PCF", default=1, min=1, max=15, step=2, description="Odd kernel size")
    output: StringProperty(name="Output", subtype="DIR_PATH", default="//shadows",
                           options=compat.BLEND_RELATIVE_PATH)
    last_report: StringProperty(name="Report", default="")
    last_summary: StringProperty(default="")


class IL_OT_build_shadow_scene(bpy.types.Operator):
    """Add a built-in minimal shadow scene as a new scene (your scenes stay as they are)"""
    bl_idname = "illumination.build_shadow_scene"
    bl_label = "Build Shadow Scene"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return polls.object_mode(cls, context)

    def execute(self, context):
        from ..lab.shadows import scenes as shadow_scenes
        st = context.scene.illumination.shadows
        result, scene = common.open_built_scene(
            self, context, lambda: shadow_scenes.build(st.scene_name, st.light_type, (st.resolution, st.resolution)))
        if scene is not None:
            new = scene.illumination.shadows
            new.light = scene["il_shadow_light"]
            new.receiver = scene["il_shadow_receiver"]
        return result


class IL_OT_run_shadow_comparison(bpy.types.Operator):
    """Render the ray-traced reference and every chosen method on the same pixels; write masks and a report"""
    bl_idname = "illumination.run_shadow_comparison"
    bl_label = "Run Shadow Comparison"

    @classmethod
    def poll(cls, context):
        if not (polls.has_scene(cls, context) and polls.object_mode(cls, context)):
            return False
        return polls.saved_or_absolute(cls, context.scene.illumination.shadows.output)

    def execute(self, context):
        from ..lab import shadows
        scene = context.scene
        st = scene.illumination.shadows
        light = st.light or next((o.name for o in scene.objects if o.type == "LIGHT"), "")
        if not light:
            self.report({"ERROR"}, f"scene '{scene.name}' has no light: add one (or Build Shadow Scene)")
            return {"CANCELLED"}
        ok, report = common.run_job(self, lambda: shadows.compare(
            scene, light, ["raytraced", *sorted(st.methods)], bpy.path.abspath(st.output),
            resolution=st.resolution, shadowmap_size=st.shadowmap_size, bias=st.bias,
            slope_bias=st.slope_bias, pcf=st.pcf, receiver=st.receiver or None))
        if not ok:
            return {"CANCELLED"}
        st.last_report = report["report"]
        st.last_summary = "  ".join(f"{m} {e['error']:.2%}" for m, e in report["methods"].items() if m != "raytraced")
        self.report({"INFO"}, f"Shadow report: {report['report']}")
        return {"FINISHED"}


class IL_PT_shadows(bpy.types.Panel):
    bl_idname = "IL_PT_shadows"
    bl_label = "Shadows"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
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
        layout.prop_search(st, "receiver", context.scene, "objects")
        layout.prop(st, "methods")
        col = layout.column(align=True)
        col.prop(st, "resolution")
        col.prop(st, "shadowmap_size")
        col.prop(st, "bias")
        col.prop(st, "slope_bias")
        col.prop(st, "pcf")
        layout.prop(st, "output")
        layout.operator(IL_OT_run_shadow_comparison.bl_idname, icon="RENDER_STILL")
        if st.last_report:
            box = layout.box()
            box.label(text="Report:")
            box.label(text=st.last_report)
            if st.last_summary:
                box.label(text=st.last_summary)


classes = (IL_PG_shadows, IL_OT_build_shadow_scene, IL_OT_run_shadow_comparison, IL_PT_shadows)
register, unregister = bpy.utils.register_classes_factory(classes)
