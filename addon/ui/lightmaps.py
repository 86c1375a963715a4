"""Panel section "Light maps": AO and irradiance bakes, their preview on the materials and their glTF export."""
import os

import bpy
from bpy.props import EnumProperty, StringProperty

from ..bake.cost import panel_max_side
from ..bake.options import BakeOptions
from ..core.errors import InputError, warn
from ..core.lightmap import MAX_RESOLUTION
from ..core.result import JobResult
from ..nodes import lightmap_preview
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


def _selected_meshes_and_folder(cls, context):
    """Object Mode, selected meshes and an output folder that resolves (Bake and Preview)."""
    return (polls.has_scene(cls, context) and polls.object_mode(cls, context) and polls.selected_meshes(cls, context)
            and polls.saved_or_absolute(cls, context.scene.illumination.lightmaps.output_dir))


class IL_OT_bake_lightmaps(JobOperator, bpy.types.Operator):
    """Bake AO and irradiance light maps of the selected meshes with Cycles (CPU)"""

    bl_idname = "illumination.bake_lightmaps"
    bl_label = "Bake Light Maps"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return _selected_meshes_and_folder(cls, context)

    def job(self, context):
        from ..bake import bake_lightmaps
        settings = context.scene.illumination.lightmaps
        options = settings.options()
        result = bake_lightmaps(list(context.selected_objects), options.maps, bpy.path.abspath(settings.output_dir),
                                options, scene=context.scene)
        n = sum(len(m) for m in result["objects"].values())
        result.summary = f"Baked {n} map(s) in {result['seconds']:.1f} s: {result.summary}; {result.path}"
        return result


class IL_OT_apply_lightmaps(JobOperator, bpy.types.Operator):
    """Show the baked light maps of the output folder on the selected objects' materials: base colour x E/pi
    (irradiance) or x k_A (AO) as emission, seen in EEVEE and Cycles without lights (Remove Preview undoes it)"""

    bl_idname = "illumination.apply_lightmaps"
    bl_label = "Preview Light Maps"
    bl_options = {"REGISTER", "UNDO"}

    source: EnumProperty(name="Map", default="IRRADIANCE",
                         items=(("IRRADIANCE", "Irradiance", "Base colour x E/pi: the lit diffuse surface's radiance"),
                                ("AO", "AO", "Base colour x k_A: the surface under a white sky of radiance 1")))

    @classmethod
    def poll(cls, context):
        return _selected_meshes_and_folder(cls, context)

    def job(self, context):
        folder = bpy.path.abspath(context.scene.illumination.lightmaps.output_dir)
        report, warnings = lightmap_preview.apply_lightmaps(context.selected_objects, folder, self.source)
        for w in warnings:
            warn(w)
        objects = report["objects"]
        return JobResult(report, summary=f"{report['source'].lower()} shown on {len(objects)} object(s): "
                                         f"{', '.join(objects)}")


def _previewed(cls, context):
    if lightmap_preview.previewed(context.selected_objects):
        return True
    cls.poll_message_set("Nothing to remove: no selected object shows a light-map preview")
    return False


class IL_OT_remove_lightmaps(JobOperator, bpy.types.Operator):
    """Give the selected objects back the materials Preview Light Maps replaced"""

    bl_idname = "illumination.remove_lightmaps"
    bl_label = "Remove Preview"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context) and polls.object_mode(cls, context) and _previewed(cls, context)

    def job(self, context):
        count = lightmap_preview.remove_lightmaps(context.selected_objects)
        return JobResult({"slots": count}, summary=f"restored {count} material slot(s)")


class IL_OT_export_lightmaps(JobOperator, bpy.types.Operator):
    """Export the scene as glTF binary with the light maps of the output folder on TEXCOORD_1 (AO as occlusion,
    irradiance as MOZ_lightmap), through Blender's glTF exporter; the scene is left as it was"""

    bl_idname = "illumination.export_lightmaps"
    bl_label = "Export glTF with Light Maps"
    bl_options = {"REGISTER"}

    filepath: StringProperty(name="File", subtype="FILE_PATH", description="The .glb file to write")
    filter_glob: StringProperty(default="*.glb", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return (polls.has_scene(cls, context) and polls.object_mode(cls, context)
                and polls.saved_or_absolute(cls, context.scene.illumination.lightmaps.output_dir))

    def invoke(self, context, event):
        if not self.filepath:
            stem = os.path.splitext(os.path.basename(bpy.data.filepath))[0] or "lightmaps"
            self.filepath = os.path.join(bpy.path.abspath(context.scene.illumination.lightmaps.output_dir),
                                         stem + ".glb")
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def job(self, context):
        from ..bake.gltf import export_glb
        if not self.filepath.strip():
            raise InputError("Choose a .glb file to write")
        out = os.path.abspath(bpy.path.abspath(self.filepath))
        if not out.lower().endswith(".glb"):
            raise InputError(f"Choose a .glb file to write, not '{os.path.basename(out)}'")
        if not os.path.isdir(os.path.dirname(out)):
            raise InputError(f"No such folder: {os.path.dirname(out)}")
        if os.path.isdir(out):
            raise InputError(f"'{os.path.basename(out)}' is a folder: choose a .glb file to write")
        try:
            import io_scene_gltf2  # noqa: F401
        except ImportError:
            raise InputError("Enable Blender's glTF 2.0 add-on (io_scene_gltf2) first") from None
        folder = bpy.path.abspath(context.scene.illumination.lightmaps.output_dir)
        result = export_glb(context.scene, folder, out)
        for line in result["notes"]:
            warn(line)
        return JobResult(result, path=out,
                         summary=f"{len(result['objects'])} object(s) with light maps written to {out}")


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
            col.prop(s, "seam_fix")
        col = layout.column(align=True)
        col.prop(s, "quality_mode")
        col.prop(s, "samples" if s.quality_mode == "SAMPLES" else "target_error")
        col.prop(s, "ao_distance")
        col.prop(s, "bounces")
        row = layout.row(align=True)
        row.prop(s, "overwrite")
        row.prop(s, "force")
        layout.operator(IL_OT_bake_lightmaps.bl_idname, text="Bake", icon="RENDER_STILL")
        col = layout.column(align=True)
        col.label(text="Preview on the materials:")
        row = col.row(align=True)
        row.operator(IL_OT_apply_lightmaps.bl_idname, text="Irradiance", icon="SHADING_RENDERED").source = "IRRADIANCE"
        row.operator(IL_OT_apply_lightmaps.bl_idname, text="AO", icon="SHADING_SOLID").source = "AO"
        col.operator(IL_OT_remove_lightmaps.bl_idname, icon="LOOP_BACK")
        layout.operator(IL_OT_export_lightmaps.bl_idname, text="Export glTF", icon="EXPORT")


classes = (IL_PG_lightmaps, IL_OT_bake_lightmaps, IL_OT_apply_lightmaps, IL_OT_remove_lightmaps, IL_OT_export_lightmaps,
           IL_PT_lightmaps)
register, unregister = bpy.utils.register_classes_factory(classes)
