"""Light-map UVs: an existing layer used as it is, or a generated non-overlapping "Lightmap" layer.

The generated layer comes from Blender's Smart UV Project (islands packed without
overlap, an island margin in UV units) run on that layer only: the user's other
layers, the active layer and the layer that renders are left as they were (the
caller's SavedState restores the active index).
"""
import bpy
import numpy as np

from ..core import lightmap
from ..core.errors import InputError

LIGHTMAP = "Lightmap"
MAX_UV_LAYERS = 8


def triangles_uv(obj, layer):
    """(T, 3, 2) UV coordinates of the mesh's loop triangles in ``layer``."""
    me = obj.data
    me.calc_loop_triangles()
    loops = np.zeros(len(me.loop_triangles) * 3, np.int64)
    me.loop_triangles.foreach_get("loops", loops)
    uv = np.zeros(len(me.loops) * 2, np.float32)
    me.uv_layers[layer].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)[loops].reshape(-1, 3, 2)


def world_area(obj):
    """Surface area in m² of the evaluated mesh in world space (object scale included)."""
    me = obj.data
    me.calc_loop_triangles()
    n = len(me.vertices)
    co = np.zeros(n * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(float)
    mw = np.array(obj.matrix_world, float)
    co = co @ mw[:3, :3].T + mw[:3, 3]
    tv = np.zeros(len(me.loop_triangles) * 3, np.int64)
    me.loop_triangles.foreach_get("vertices", tv)
    t = co[tv].reshape(-1, 3, 3)
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def check_layer(obj, name):
    if name not in obj.data.uv_layers:
        have = ", ".join(l.name for l in obj.data.uv_layers) or "none"
        raise InputError(f"object '{obj.name}' has no UV layer '{name}' (it has: {have})")


def prepare(scene, objects, state, uv_layer=None, margin_uv=0.01, together=False):
    """Return ``{object name: layer name}``; generate "Lightmap" where needed.

    An existing layer named "Lightmap" (from an earlier bake) is reused as it is.
    With ``together`` the objects that need a layer are unwrapped in one go, so
    their charts share one UV square (an atlas) without overlapping.
    """
    names = {}
    todo = []
    for o in objects:
        if uv_layer:
            names[o.name] = uv_layer
        elif LIGHTMAP in o.data.uv_layers and not together:
            names[o.name] = LIGHTMAP
        else:
            todo.append(o)
    groups = [todo] if together else [[o] for o in todo]
    for group in groups:
        if group:
            _generate(scene, group, state, margin_uv)
            for o in group:
                names[o.name] = LIGHTMAP
    return names


def _generate(scene, group, state, margin_uv):
    vl = scene.view_layers[0]
    for o in group:
        me = o.data
        if len(me.uv_layers) >= MAX_UV_LAYERS and LIGHTMAP not in me.uv_layers:
            raise InputError(f"mesh '{me.name}' already has {MAX_UV_LAYERS} UV layers: pass an existing one")
        if LIGHTMAP not in me.uv_layers:
            me.uv_layers.new(name=LIGHTMAP, do_init=False)
            state.created_uv(me, LIGHTMAP)
        me.uv_layers.active = me.uv_layers[LIGHTMAP]
        o.select_set(True, view_layer=vl)
    for o in vl.objects:
        if o not in group:
            o.select_set(False, view_layer=vl)
    lead = group[0]
    vl.objects.active = lead
    ctx = dict(scene=scene, view_layer=vl, active_object=lead, object=lead,
               selected_objects=list(group), selected_editable_objects=list(group))
    selections = [(o.data, _mesh_selection(o.data)) for o in group]
    for o in group:
        o.data.polygons.foreach_set("select", np.ones(len(o.data.polygons), bool))
    try:
        with bpy.context.temp_override(**ctx):
            bpy.ops.object.mode_set(mode="EDIT")
        try:
            with bpy.context.temp_override(edit_object=lead, **ctx):
                bpy.ops.uv.smart_project(angle_limit=1.15192, island_margin=float(margin_uv),
                                         area_weight=0.0, correct_aspect=True, scale_to_bounds=False)
        finally:
            with bpy.context.temp_override(**ctx):
                bpy.ops.object.mode_set(mode="OBJECT")
    finally:
        for me, saved in selections:
            for items, flags in saved:
                items.foreach_set("select", flags)


def _mesh_selection(me):
    """The user's vertex, edge and face selection flags of ``me`` (smart_project needs all faces selected)."""
    saved = []
    for items in (me.vertices, me.edges, me.polygons):
        flags = np.zeros(len(items), bool)
        items.foreach_get("select", flags)
        saved.append((items, flags))
    return saved


def resolution(objects, layers, options):
    """Map side for the objects sharing one map: the fixed resolution, or from the texel density."""
    if options.texel_density is None:
        return int(options.resolution)
    area = sum(world_area(o) for o in objects)
    coverage = sum(lightmap.uv_area(np.clip(triangles_uv(o, layers[o.name]), 0, 1)) for o in objects)
    return lightmap.resolution_for_density(area, min(coverage, 1.0), options.texel_density, options.max_resolution)
