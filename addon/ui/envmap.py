"""Panel section "Environment & radiosity": irradiance environment maps and radiosity (issue 7)."""

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from ..blender import compat
from ..core.errors import InputError
from . import common, polls


def _output_folder_ok(op):
    """False (and an error report) when ``op.out_dir`` is relative to a file never saved."""
    if op.out_dir.startswith("//") and not bpy.data.filepath:
        op.report({"ERROR"}, "Save the file first, or choose an absolute output folder")
        return False
    return True


class IL_OT_envmap_irradiance(bpy.types.Operator):
    """Write the irradiance map E(n) of the world's environment texture (or a file) as EXR and build the node
    group "IL Irradiance Env" that looks it up by the normal"""

    bl_idname = "illumination.envmap_irradiance"
    bl_label = "Irradiance Environment Map"
    bl_options = {"REGISTER", "UNDO"}

    env_file: StringProperty(name="Environment", subtype="FILE_PATH", options=compat.BLEND_RELATIVE_PATH,
                             description="Lat-long .exr/.hdr; empty = the world's Environment Texture")
    out_dir: StringProperty(name="Output", subtype="DIR_PATH", default="//irradiance",
                            options=compat.BLEND_RELATIVE_PATH)
    method: EnumProperty(name="Method", items=(("sh9", "Nine SH", "Ramamoorthi & Hanrahan 2001"),
                                               ("brute", "Brute force", "Full cosine convolution")))
    width: IntProperty(name="Width", default=64, min=4, max=1024)

    @classmethod
    def poll(cls, context):
        return polls.has_scene(cls, context)

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=400)

    def execute(self, context):
        from ..lab import envmap
        if not _output_folder_ok(self):
            return {"CANCELLED"}

        def job():
            try:
                s = envmap.run(bpy.path.abspath(self.out_dir), scene=context.scene,
                               env_file=bpy.path.abspath(self.env_file) if self.env_file else None,
                               method=self.method, width=self.width + self.width % 2)
            except InputError as e:
                if self.env_file:
                    raise
                raise InputError(f"{e} (or choose an Environment file in this button's dialog)") from None
            envmap.ensure_node_group(envmap.load_irradiance_image(s["file"]))
            return s

        ok, s = common.run_job(self, job)
        if not ok:
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {s['file']} ({s['seconds'] * 1e3:.1f} ms); node group '{envmap.GROUP}' ready")
        return {"FINISHED"}


class IL_OT_radiosity(bpy.types.Operator):
    """Solve radiosity for the scene's meshes: new objects with vertex colours and light maps, optionally
    compared with a Cycles irradiance bake"""

    bl_idname = "illumination.radiosity"
    bl_label = "Radiosity"
    bl_options = {"REGISTER", "UNDO"}

    out_dir: StringProperty(name="Output", subtype="DIR_PATH", default="//radiosity",
                            options=compat.BLEND_RELATIVE_PATH)
    solver: EnumProperty(name="Solver", items=(("jacobi", "Jacobi", ""), ("gauss_seidel", "Gauss-Seidel", ""),
                                               ("progressive", "Progressive refinement", "")))
    max_edge: FloatProperty(name="Patch size", default=0.25, min=0.001, unit="LENGTH",
                            description="Longest patch edge; a size whose N² solve would not fit in the available "
                                        "memory or would take more than an hour is refused (the dialog shows "
                                        "the estimate and the smallest size that fits)")
    adaptive: IntProperty(name="Adaptive rounds", default=0, min=0, max=4)
    samples: IntProperty(name="Cycles samples", default=32, min=0, max=4096,
                         description="Samples of the comparison bake (0 = no comparison)")

    @classmethod
    def poll(cls, context):
        return polls.object_mode(cls, context) and polls.has_scene(cls, context)

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=400)

    def draw(self, context):
        layout = self.layout
        for name in ("out_dir", "solver", "max_edge", "adaptive", "samples"):
            layout.prop(self, name)
        layout.label(text=_estimate_line(context.scene, self.max_edge))

    def execute(self, context):
        from ..core import charts
        from ..lab import radiosity
        if not _output_folder_ok(self):
            return {"CANCELLED"}
        chart = charts.available()
        if not chart:
            self.report({"WARNING"}, charts.MISSING)
        ok, r = common.run_job(self, lambda: radiosity.run(
            bpy.path.abspath(self.out_dir), scene=context.scene, solver=self.solver, max_edge=self.max_edge,
            adaptive=self.adaptive, samples=max(self.samples, 1), compare=self.samples > 0, chart=chart))
        if not ok:
            return {"CANCELLED"}
        rep = r["report"]
        extra = "" if rep["rms_vs_cycles"] is None else f", RMS vs Cycles {rep['rms_vs_cycles']:.3g} W/m²"
        self.report({"INFO"}, f"{rep['patches']} patches, {rep['iterations']} iterations{extra}")
        return {"FINISHED"}


_ESTIMATES = {}


def _estimate_line(scene, max_edge):
    """The dialog's cost line, from the same estimate that refuses a run (lab.radiosity.estimate)."""
    from ..core.radiosity import cost as rad_cost
    from ..lab import radiosity
    key = (scene.name, round(max_edge, 9), bpy.data.is_dirty)
    if key not in _ESTIMATES:
        try:
            cost, best = radiosity.estimate(scene, max_edge)
            fits = "" if best is None else f", smallest size that fits: {best:.2g} m"
            _ESTIMATES.clear()
            _ESTIMATES[key] = (f"~{rad_cost.human_count(cost.patches)} patches, {rad_cost.human_bytes(cost.bytes)}, "
                               f"about {rad_cost.human_seconds(cost.seconds)}{fits}")
        except Exception as e:  # noqa: BLE001 - a label, never an error in a draw callback
            _ESTIMATES[key] = f"no estimate: {e}"[:120]
    return _ESTIMATES[key]


class IL_OT_build_cornell(bpy.types.Operator):
    """Build the Cornell-box-like radiosity scene as a new scene"""

    bl_idname = "illumination.build_cornell_box"
    bl_label = "Build Cornell Box"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        from ..lab import radiosity
        return common.open_built_scene(self, context, radiosity.build_cornell_scene)[0]


class IL_PT_envmap(bpy.types.Panel):
    bl_idname = "IL_PT_envmap"
    bl_label = "Environment & radiosity"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Illumination"
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
