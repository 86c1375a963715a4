"""Light-map UVs: an existing layer used as it is, or a generated non-overlapping "Lightmap" layer.

The generated layer comes from Blender's Smart UV Project run on that layer only (the user's
other layers, the active layer and the layer that renders are left as they were; the caller's
SavedState restores the active index). Its islands are packed with a margin given as a fraction
of the map ("FRACTION"): ``margin`` texels of empty space around every chart at the side the map
gets, so charts lie 2 × margin texels apart and the dilation by ``margin`` texels never reaches
into a neighbour's gutter.
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


def prepare(scene, objects, state, options, together=False):
    """Return ``({object name: layer name}, {object name: map side the generated layout was made for})``.

    ``options.uv_layer`` is used as it is; otherwise an existing "Lightmap" layer (from an earlier
    bake) is reused as it is, or one is generated. With ``together`` the objects are unwrapped in
    one go, so their charts share one UV square (an atlas) without overlapping.
    """
    names, sides = {}, {}
    todo = []
    for o in objects:
        if options.uv_layer:
            names[o.name] = options.uv_layer
        elif LIGHTMAP in o.data.uv_layers and not together:
            names[o.name] = LIGHTMAP
        else:
            todo.append(o)
    groups = [todo] if together else [[o] for o in todo]
    for group in groups:
        if group:
            for o in group:
                names[o.name] = LIGHTMAP
            side = _unwrap_with_margin(scene, group, state, options, names)
            sides.update((o.name, side) for o in group)
    return names, sides


def margin_fraction(margin, side):
    """Island margin as a fraction of the map: max(margin, 1/2) texels / side (charts at least a texel
    apart), at most 5 % of the map (a margin wider than that only wastes a tiny map)."""
    return min(max(float(margin), 0.5) / max(int(side), 1), 0.05)


def _unwrap_with_margin(scene, group, state, options, names):
    """Generate "Lightmap" for ``group`` so that its margin holds at the side the map gets; return that side.

    A fixed resolution gives the side at once. With a texel density the side N = T √(A / coverage)
    depends on the packing, which depends on the margin: start from the lower bound T √A (coverage 1)
    and re-unwrap for the side the last layout asks for, up to three times; the map then gets
    max(asked side, side the margin was made for), so the margin always holds.
    """
    fixed = options.sizes.get(group[0].name) if options.sizes else None
    side = max(fixed) if fixed else resolution(group, names, options, coverage=1.0)
    for _ in range(3):
        _generate(scene, group, state, margin_fraction(options.margin, side))
        if fixed or options.texel_density is None:
            return side
        need = resolution(group, names, options)
        if side <= need <= 1.05 * side:
            return need
        side = need
    return max(side, resolution(group, names, options))


def _generate(scene, group, state, margin_uv):
    vl = scene.view_layers[0]
    for o in group:
        me = o.data
        if len(me.uv_layers) >= MAX_UV_LAYERS and LIGHTMAP not in me.uv_layers:
            raise InputError(f"mesh '{me.name}' already has {MAX_UV_LAYERS} UV layers: pass an existing one")
        if LIGHTMAP not in me.uv_layers:
            me.uv_layers.new(name=LIGHTMAP, do_init=False)
            state.created_uv(me, LIGHTMAP)
        else:
            state.save_uv(me, LIGHTMAP)          # an earlier bake's layer, re-unwrapped: put back unless kept
        me.uv_layers.active = me.uv_layers[LIGHTMAP]
        o.select_set(True, view_layer=vl)
    for o in vl.objects:
        if o not in group:
            o.select_set(False, view_layer=vl)
    lead = group[0]
    vl.objects.active = lead
    ctx = dict(scene=scene, view_layer=vl, active_object=lead, object=lead,
               selected_objects=list(group), selected_editable_objects=list(group))
    saved = [(o.data, _mesh_flags(o.data)) for o in group]
    for o in group:                       # smart_project unwraps the visible, selected faces: all of them
        for items in (o.data.vertices, o.data.edges, o.data.polygons):
            items.foreach_set("hide", np.zeros(len(items), bool))
            items.foreach_set("select", np.ones(len(items), bool))
    try:
        with bpy.context.temp_override(**ctx):
            bpy.ops.object.mode_set(mode="EDIT")
        try:
            with bpy.context.temp_override(edit_object=lead, **ctx):
                bpy.ops.uv.smart_project(angle_limit=1.15192, island_margin=float(margin_uv), margin_method="FRACTION",
                                         area_weight=0.0, correct_aspect=True, scale_to_bounds=False)
        finally:
            with bpy.context.temp_override(**ctx):
                bpy.ops.object.mode_set(mode="OBJECT")
    finally:
        for me, (flags, names) in saved:
            _restore_flags(me, flags, names)


def _mesh_flags(me):
    """The user's select and hide flags of vertices, edges and faces, and the names of the mesh's attributes."""
    flags = []
    for items in (me.vertices, me.edges, me.polygons):
        for key in ("select", "hide"):
            values = np.zeros(len(items), bool)
            items.foreach_get(key, values)
            flags.append((items, key, values))
    return flags, {a.name for a in me.attributes}


def _restore_flags(me, flags, names):
    """Put the flags back and drop the internal attributes (".select_vert", ".uv_select_face", ...) that the
    edit-mode round trip added: absent, they read as all False, which is what they were."""
    for items, key, values in flags:
        items.foreach_set(key, values)
    for name in [a.name for a in me.attributes if a.name.startswith(".") and a.name not in names]:
        if name in me.attributes and not me.attributes[name].is_required:
            me.attributes.remove(me.attributes[name])


def resolution(objects, layers, options, coverage=None):
    """Map side for the objects sharing one map: the fixed resolution, or N = T √(A / coverage) from the
    texel density T, the world area A and the UV coverage of their layers (``coverage`` overrides it)."""
    if options.texel_density is None:
        return int(options.resolution)
    area = sum(world_area(o) for o in objects)
    if coverage is None:
        coverage = sum(lightmap.uv_area(np.clip(triangles_uv(o, layers[o.name]), 0, 1)) for o in objects)
    return lightmap.resolution_for_density(area, min(coverage, 1.0), options.texel_density, options.max_resolution)
