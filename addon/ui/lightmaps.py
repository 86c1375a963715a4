"""Panel section "Light maps": AO and irradiance bakes (issue: light maps)."""
import bpy
from bpy.props import EnumProperty

from ..bake.cost import panel_max_side
from ..bake.options import BakeOptions
from ..core.lightmap import MAX_RESOLUTION
from .panel import Sidebar
from . import polls, props
from .operator import JobOperator

MAX_SIDE = panel_max_side(MAX_RESOLUTION)
"""The panel's resolution limit: the largest side whose bake fits this machine's memory (bake/cost.py, the
same estimate the bake checks against the memory available when it starts)."""


class IL_PG_lightmaps(bpy.types.PropertyGroup):
    """Light-map settings, stored at ``scene.illumination.lightmaps``: the fields of bake.options.BakeOptions,
    plus the output folder and the two switches that choose resolution or texel density, samples or target
    error."""

    __annotations__ = {
        **props.properties(BakeOptions, resolution={"max": MAX_SIDE, "default": min(256, MAX_SIDE)},
                           max_resolution={"max": MAX_SIDE, "default": min(BakeOptions.max_resolution, MAX_SIDE)}),
        "output_dir": props.output_dir("//lightmaps/", "Folder for the EXR maps, PNG previews and bake_report.json"),
        "size_mode": EnumProperty(name="Size", items=(("RESOLUTION", "Resolution", "A fixed map side"),
                                                      ("DENSITY", "Texel Density", "Texels per metre, capped")),
                                  default="RESOLUTION"),
        "quality_mode": EnumProperty(name="Quality",
                                     items=(("SAMPLES", "Samples", "A fixed sample count"),
                                            ("ERROR", "Target Error", "Samples from a pilot bake's variance")),
                                     default="SAMPLES"),
    }

    def options(self):
        """The BakeOptions the panel shows (the switched-off one of each pair left at None)."""
        off = {}
        if self.size_mode != "DENSITY":
            off["texel_density"] = None
        if self.quality_mode != "ERROR":
            off["target_error"] = None
        return props.options(BakeOptions, self, **off)


class IL_OT_bake_lightmaps(JobOperator, bpy.types.Operator):
    """Bake AO and irradiance light maps of the selected meshes with Cycles (CPU)"""

    bl_idname = "illumination.bake_lightmaps"
    bl_label = "Bake Light Maps"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return (polls.has_scene(cls, context) and polls.object_mode(cls, context)
                and polls.selected_meshes(cls, context)
                and polls.saved_or_absolute(cls, context.scene.illumination.lightmaps.output_dir))

    def job(self, context):
        from ..bake import bake_lightmaps
        settings = context.scene.illumination.lightmaps
        options = settings.options()
        result = bake_lightmaps(list(context.selected_objects), options.maps, bpy.path.abspath(settings.output_dir),
                                options, scene=context.scene)
        n = sum(len(m) for m in result["objects"].values())
        result.summary = f"Baked {n} map(s) in {result['seconds']:.1f} s: {result.summary}; {result.path}"
        return result


class IL_PT_lightmaps(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_lightmaps"
    bl_label = "Light maps"
    bl_parent_id = "IL_PT_main"
    bl_order = 20

    def draw(self, context):
        layout = self.layout
        s = context.scene.illumination.lightmaps
        layout.row(align=True).prop(s, "maps", expand=True)
        layout.prop(s, "output_dir")
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
