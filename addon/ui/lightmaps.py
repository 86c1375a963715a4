"""Panel section "Light maps": AO and irradiance bakes (issue: light maps)."""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from ..blender import compat
from ..bake.cost import panel_max_side
from ..core.lightmap import MAX_RESOLUTION
from . import polls
from .common import run_job

MAX_SIDE = panel_max_side(MAX_RESOLUTION)
"""The panel's resolution limit: the largest side whose bake fits this machine's memory (bake/cost.py, the
same estimate the bake checks against the memory available when it starts)."""


class IL_PG_lightmaps(bpy.types.PropertyGroup):
    """Light-map settings, stored at ``scene.illumination.lightmaps``."""

    bake_ao: BoolProperty(name="Ambient Occlusion", default=True, description="Bake k_A (1 = open)")
    bake_irradiance: BoolProperty(name="Irradiance", default=True, description="Bake E in W/m² (RGB)")
    out_dir: StringProperty(name="Output", subtype="DIR_PATH", default="//lightmaps/",
                            options=compat.BLEND_RELATIVE_PATH, description="Folder for the EXR maps, PNG previews and bake_report.json")
    size_mode: EnumProperty(name="Size", items=(("RESOLUTION", "Resolution", "A fixed map side"),
                                                ("DENSITY", "Texel Density", "Texels per metre, capped")),
                            default="RESOLUTION")
    resolution: IntProperty(name="Resolution", default=256, min=1, max=MAX_SIDE, description="Map side in texels")
    texel_density: FloatProperty(name="Texels/m", default=32.0, min=0.01, soft_max=1024.0,
                                 description="Texels per metre of surface")
    max_resolution: IntProperty(name="Max Resolution", default=min(2048, MAX_SIDE), min=1, max=MAX_SIDE,
                                description="Cap of the side chosen from the texel density")
    quality_mode: EnumProperty(name="Quality", items=(("SAMPLES", "Samples", "A fixed sample count"),
                                                      ("ERROR", "Target Error", "Samples from a pilot bake's variance")),
                               default="SAMPLES")
    samples: IntProperty(name="Samples", default=64, min=1, max=1 << 20)
    target_error: FloatProperty(name="Target Error", default=0.01, min=1e-6, precision=4,
                                description="Wanted RMS Monte Carlo error (k_A units for AO, W/m² for irradiance)")
    ao_distance: FloatProperty(name="AO Distance", default=10.0, min=1e-4, unit="LENGTH")
    bounces: IntProperty(name="Bounces", default=3, min=0, max=1024,
                         description="Diffuse bounces of the irradiance bake (0 = direct light only)")
    margin: IntProperty(name="Margin", default=4, min=0, max=1024, subtype="PIXEL",
                        description="Dilation beyond the covered texels")
    denoise: BoolProperty(name="Denoise", default=False, description="Blender's denoiser (OpenImageDenoise)")
    uv_layer: StringProperty(name="UV Layer", default="",
                             description="Existing UV layer to use as it is; empty generates 'Lightmap'")
    target: EnumProperty(name="Target", items=(("image", "Image", "EXR map + PNG preview per object"),
                                               ("vertex", "Vertex Colors", "A colour attribute per map")),
                         default="image")
    atlas: BoolProperty(name="Shared Atlas", default=False, description="One map shared by all selected objects")
    overwrite: BoolProperty(name="Overwrite", default=False, description="Replace existing files")

    def options(self):
        from ..bake import BakeOptions
        return BakeOptions(
            resolution=self.resolution, texel_density=self.texel_density if self.size_mode == "DENSITY" else None,
            max_resolution=self.max_resolution, samples=self.samples,
            target_error=self.target_error if self.quality_mode == "ERROR" else None,
            ao_distance=self.ao_distance, bounces=self.bounces, margin=self.margin, denoise=self.denoise,
            uv_layer=self.uv_layer or None, target=self.target, atlas=self.atlas, overwrite=self.overwrite)

    def maps(self):
        return [m for m, on in (("ao", self.bake_ao), ("irradiance", self.bake_irradiance)) if on]


class IL_OT_bake_lightmaps(bpy.types.Operator):
    """Bake AO and irradiance light maps of the selected meshes with Cycles (CPU)"""

    bl_idname = "illumination.bake_lightmaps"
    bl_label = "Bake Light Maps"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return (polls.has_scene(cls, context) and polls.object_mode(cls, context)
                and polls.selected_meshes(cls, context)
                and polls.saved_or_absolute(cls, context.scene.illumination.lightmaps.out_dir))

    def execute(self, context):
        from ..bake import bake_lightmaps, summary
        settings = context.scene.illumination.lightmaps
        objects = list(context.selected_objects)
        ok, report = run_job(self, lambda: bake_lightmaps(objects, settings.maps(), bpy.path.abspath(settings.out_dir),
                                                          settings.options(), scene=context.scene))
        if not ok:
            return {"CANCELLED"}
        n = sum(len(m) for m in report["objects"].values())
        self.report({"INFO"}, f"Baked {n} map(s) in {report['seconds']:.1f} s: {summary(report)}; {report['report']}")
        return {"FINISHED"}


class IL_PT_lightmaps(bpy.types.Panel):
    bl_idname = "IL_PT_lightmaps"
    bl_label = "Light maps"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
    bl_parent_id = "IL_PT_main"
    bl_order = 20

    def draw(self, context):
        layout = self.layout
        s = context.scene.illumination.lightmaps
        row = layout.row(align=True)
        row.prop(s, "bake_ao", toggle=True)
        row.prop(s, "bake_irradiance", toggle=True)
        layout.prop(s, "out_dir")
        col = layout.column(align=True)
        col.prop(s, "target")
        if s.target == "image":
            col.prop(s, "size_mode")
            if s.size_mode == "RESOLUTION":
                col.prop(s, "resolution")
            else:
                col.prop(s, "texel_density")
                col.prop(s, "max_resolution")
            col.prop(s, "uv_layer")
            col.prop(s, "margin")
            col.prop(s, "atlas")
            col.prop(s, "denoise")
        col = layout.column(align=True)
        col.prop(s, "quality_mode")
        col.prop(s, "samples" if s.quality_mode == "SAMPLES" else "target_error")
        col.prop(s, "ao_distance")
        col.prop(s, "bounces")
        layout.prop(s, "overwrite")
        layout.operator(IL_OT_bake_lightmaps.bl_idname, text="Bake", icon="RENDER_STILL")


classes = (IL_PG_lightmaps, IL_OT_bake_lightmaps, IL_PT_lightmaps)
register, unregister = bpy.utils.register_classes_factory(classes)
