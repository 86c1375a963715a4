"""Panel section "Environment & radiosity": irradiance environment maps and radiosity (issue 7)."""

import bpy
from bpy.props import StringProperty

from ..blender import compat
from ..core.errors import InputError, warn
from ..lab.options import EnvmapOptions, RadiosityOptions
from .panel import Sidebar
from . import polls, props
from .operator import BuildSceneOperator, JobOperator


def _output_folder_ok(path):
    """InputError when ``path`` is empty or relative to a file never saved."""
    if not path.strip():
        raise InputError("Choose an output folder")
    if path.startswith("//") and not bpy.data.filepath:
        raise InputError("Save the file first, or choose an absolute output folder")


class IL_OT_envmap_irradiance(JobOperator, bpy.types.Operator):
    """Write the irradiance map E(n) of the world's environment texture (or a file) as EXR and build the node
    group "IL Irradiance Env" that looks it up by the normal"""

    bl_idname = "illumination.envmap_irradiance"
    bl_label = "Irradiance Environment Map"
    bl_options = {"REGISTER", "UNDO"}

    __annotations__ = {
        "env_file": StringProperty(name="Environment", subtype="FILE_PATH", options=compat.BLEND_RELATIVE_PATH,
                                   description="Lat-long .exr/.hdr; empty = the world's Environment Texture"),
        "output_dir": props.output_dir("//irradiance", "Folder for irradiance_latlong.exr and envmap_report.json"),
        **props.properties(EnvmapOptions),
    }

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context)

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=400)

    def job(self, context):
        from ..lab import envmap
        _output_folder_ok(self.output_dir)
        o = props.options(EnvmapOptions, self, width=self.width + self.width % 2)
        try:
            result = envmap.run(bpy.path.abspath(self.output_dir), o, scene=context.scene,
                                env_file=bpy.path.abspath(self.env_file) if self.env_file else None)
        except InputError as e:
            if self.env_file:
                raise
            raise InputError(f"{e} (or choose an Environment file in this button's dialog)") from None
        envmap.ensure_node_group(envmap.load_irradiance_image(result["file"]))
        result.summary += f"; node group '{envmap.GROUP}' ready"
        return result


class IL_OT_radiosity(JobOperator, bpy.types.Operator):
    """Solve radiosity for the scene's meshes: new objects with vertex colours and light maps, optionally
    compared with a Cycles irradiance bake"""

    bl_idname = "illumination.radiosity"
    bl_label = "Radiosity"
    bl_options = {"REGISTER", "UNDO"}

    __annotations__ = {
        "output_dir": props.output_dir("//radiosity", "Folder for the light maps, the chart and radiosity_report.json"),
        **props.properties(RadiosityOptions),
    }

    @classmethod
    def poll(cls, context):
        return polls.object_mode(cls, context) and polls.has_scene(cls, context)

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=400)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "output_dir")
        props.draw(layout, self, [n for n in self.__annotations__ if n != "output_dir"])
        layout.label(text=_estimate_line(context.scene, self.max_edge, self.solver, self.compare_solvers))

    def job(self, context):
        from ..core import charts
        from ..lab import radiosity
        _output_folder_ok(self.output_dir)
        o = props.options(RadiosityOptions, self)
        chart = charts.available()
        if not chart:
            warn(charts.MISSING)
        return radiosity.run(bpy.path.abspath(self.output_dir), o, scene=context.scene, chart=chart)


_ESTIMATES = {}


def _estimate_line(scene, max_edge, solver="jacobi", compare_solvers=False):
    """The dialog's cost line, from the same estimate that refuses a run (lab.radiosity.estimate)."""
    from ..core import budget
    from ..lab import radiosity
    key = (scene.name, round(max_edge, 9), bpy.data.is_dirty, solver, compare_solvers)
    if key not in _ESTIMATES:
        try:
            cost, best = radiosity.estimate(scene, max_edge, solver, compare_solvers)
            fits = "" if best is None else f", smallest size that fits: {best:.2g} m"
            _ESTIMATES.clear()
            _ESTIMATES[key] = (f"up to ~{budget.format_count(cost.patches)} patches, "
                               f"{budget.format_bytes(cost.bytes)}, at most {budget.format_seconds(cost.seconds)}{fits}")
        except Exception as e:  # noqa: BLE001 - a label, never an error in a draw callback
            _ESTIMATES[key] = f"no estimate: {e}"[:120]
    return _ESTIMATES[key]


class IL_OT_build_cornell(BuildSceneOperator, bpy.types.Operator):
    """Build the Cornell-box-like radiosity scene as a new scene"""

    bl_idname = "illumination.build_cornell_box"
    bl_label = "Build Cornell Box"

    def build(self, context):
        from ..lab import radiosity
        return radiosity.build_cornell_scene()


class IL_PT_envmap(Sidebar, bpy.types.Panel):
    bl_idname = "IL_PT_envmap"
    bl_label = "Environment & radiosity"
    bl_parent_id = "IL_PT_main"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 25

    def draw(self, context):
        col = self.layout.column(align=True)
        col.operator(IL_OT_envmap_irradiance.bl_idname, icon="WORLD")
        col.separator()
        col.operator(IL_OT_build_cornell.bl_idname, icon="MESH_CUBE")
        col.operator(IL_OT_radiosity.bl_idname, icon="LIGHT_AREA")


classes = (IL_OT_envmap_irradiance, IL_OT_radiosity, IL_OT_build_cornell, IL_PT_envmap)
register, unregister = bpy.utils.register_classes_factory(classes)
