"""Light-map UVs, the pipeline's entry: :func:`prepare` gives each group (one object, or an atlas) the layer it
is baked through: ``--uv-layer`` as it is, a layout the UV cache holds, a linked duplicate's layer, an earlier
"Lightmap" layer reused (:func:`_reusable`), else one ``unwrap.py`` generates, carried with a texel density into the
window of its charts (:func:`_cut_window`: a w x h map), with the margin its report and dilation give
(:func:`dilation`). The layer readers (:func:`triangles_uv`, :func:`world_area`, ...) read each object once while the
layouts or the geometry are fixed (:func:`fixed_layouts`, :func:`fixed_geometry`). ``uvchecks.py`` and ``unwrap.py``
import these readers, so this module imports them inside its functions only.
"""
import contextlib
import dataclasses
import hashlib
import math

import bpy
import numpy as np

from ..blender.digest import shape_digest
from ..blender.scene import corner_triangles, corner_uv, corner_vertices, positions
from ..blender.state import remove_ids
from ..core import errors, lightmap
from ..core.memo import FIGURES, digest
from ..core.errors import InputError
from . import uvcache
from .unwrap_copy import Stretches, mesh_triangles
from .options import article

LIGHTMAP = "Lightmap"
MAX_UV_LAYERS = 8
OWN_LAYERS = 4
"""Most of a mesh's own UV layers whose charts a generated layout may take (:func:`own_layers`)."""
ADDED_BY_PREVIEW = "il_lightmap_added_uv"
"""ID property of a mesh whose light-map layer (the value: its name) a Preview added from a bake folder's UV cache:
Remove Preview takes the layer away again; a bake that keeps the layer as its product makes it its own."""


# ------------------------------------------------------------------ reading layers

def own_layers(me):
    """Names of mesh ``me``'s own UV layers, all but "Lightmap" (at most OWN_LAYERS, in their order): the charts an
    artist, an importer or a primitive operator gave it, which a generated layout may place again by their texels
    (``unwrap._Copies.try_own_layers``), so its layout depends on their UVs."""
    return [layer.name for layer in me.uv_layers if layer.name != LIGHTMAP][:OWN_LAYERS]


def own_uvs(me):
    """Bytes of the UVs of :func:`own_layers` of mesh ``me`` (name, then float32 UVs, each), for the digests a
    generated layout is keyed and hashed by."""
    return b"".join(name.encode() + b"\0" + corner_uv(me, name).astype(np.float32).tobytes() for name in own_layers(me))


_FIXED = None      # {(what, pointer, layer): value} while the layouts are fixed (:func:`fixed_layouts`), else None


@contextlib.contextmanager
def fixed_layouts():
    """A scope in which no mesh, UV layer or transform of the baked objects changes (after the UV step, through
    the bakes and files): :func:`triangles_uv` and :func:`world_area` are read once per object in it. The UV step's
    :func:`world_triangles` are let go (72 bytes a triangle)."""
    global _FIXED
    if _GEOMETRY is not None:
        for key in [k for k in _GEOMETRY if k[0] == "world"]:
            del _GEOMETRY[key]
    _FIXED = {}
    try:
        yield
    finally:
        _FIXED = None


_GEOMETRY = None   # {(what, pointer): value} while only UV layers change (:func:`fixed_geometry`), else None


@contextlib.contextmanager
def fixed_geometry():
    """A scope in which the objects' meshes and transforms do not change, only their UV layers (a bake, from its input
    checks to its last map; :func:`geometry_changed` when they do): :func:`geometry_key`, :func:`world_area`,
    :func:`world_triangles` (until the layouts are fixed) and the loop triangles are read once per mesh or object in
    it."""
    global _GEOMETRY
    if _GEOMETRY is not None:
        yield
        return
    _GEOMETRY = {}
    try:
        yield
    finally:
        _GEOMETRY = None


def geometry_changed(meshes):
    """Inside :func:`fixed_geometry`: ``meshes`` changed (their normals flipped for the bake), read them again."""
    changed = {me.as_pointer() for me in meshes}
    if _GEOMETRY is not None:
        for key in [k for k in _GEOMETRY if changed.intersection(k[1:])]:
            del _GEOMETRY[key]


def remembered(key, make, geometry=False):
    """``make()``, once per ``key`` inside :func:`fixed_layouts` (and, for ``geometry``, inside
    :func:`fixed_geometry`); every call outside them."""
    store = _GEOMETRY if geometry and _GEOMETRY is not None else _FIXED
    if store is None:
        return make()
    if key not in store:
        store[key] = make()
    return store[key]


def triangles_uv(obj, layer):
    """(T, 3, 2) UV coordinates of the mesh's loop triangles in ``layer`` (read-only inside :func:`fixed_layouts`)."""
    def make():
        tri = corner_uv(obj.data, layer)[corners(obj.data)]
        if _FIXED is not None:
            tri.flags.writeable = False
        return tri
    return remembered(("uv", obj.data.as_pointer(), layer), make)


def corners(me):
    """``corner_triangles`` of mesh ``me``, read once while the geometry is fixed (the UV step reads a mesh's UVs
    after each unwrap it tries; its triangles stay)."""
    def make():
        tris = corner_triangles(me)
        tris.flags.writeable = False
        return tris
    return remembered(("corners", me.as_pointer()), make, geometry=True)


def mesh_triangles_uv(me, layer):
    """(T, 3, 2) UV coordinates of mesh ``me``'s loop triangles in ``layer``."""
    return corner_uv(me, layer)[corner_triangles(me)]


def geometry_key(me):
    """16-byte digest of mesh ``me``'s shape (:func:`blender.digest.shape_digest`: positions, edges, faces, corners)
    and Blender's build: the figures of its shape (area, closed parts) are kept under it in the figure store, so a
    rerun does not read the mesh for them; what a bake writes (UV layers, colour attributes) leaves it unchanged.
    Read once per mesh while the geometry is fixed."""
    def make():
        h = hashlib.blake2b(repr((tuple(bpy.app.version), bpy.app.build_hash)).encode(), digest_size=16)
        shape_digest(h, me)
        return h.digest()
    return remembered(("geometry", me.as_pointer()), make, geometry=True)


def geometry_figure(me, make, *args):
    """``make()``, a figure of mesh ``me``'s shape and ``args`` (numbers, arrays), kept under :func:`geometry_key`."""
    return FIGURES.get(digest("geometry", geometry_key(me), *args), make)


def world_area(obj):
    """Surface area in m² of the mesh in world space (object scale included)."""
    return remembered(("area", obj.as_pointer(), obj.data.as_pointer()),
                      lambda: geometry_figure(obj.data, lambda: _world_area(obj), "area",
                                              np.array(obj.matrix_world, float)), geometry=True)


def _world_area(obj):
    t = world_triangles(obj)
    return float(lightmap.triangle_areas(t).sum())


def world_triangles(obj):
    """(T, 3, 3) world positions of the corners of the mesh's loop triangles (the order of :func:`triangles_uv`),
    read-only; remembered while the geometry is fixed, until the layouts are (:func:`fixed_layouts`)."""
    def make():
        t = _world_triangles(obj)
        t.flags.writeable = False
        return t
    return remembered(("world", obj.as_pointer(), obj.data.as_pointer()), make, geometry=_FIXED is None)


def _world_triangles(obj):
    me = obj.data
    co = positions(me).astype(float)
    mw = np.array(obj.matrix_world, float)
    co = co @ mw[:3, :3].T + mw[:3, 3]
    return co[corner_vertices(me)[corners(me)]]


def invalid_meshes(objects):
    """{object name: why} of ``objects`` whose mesh Blender itself reports invalid (``Mesh.validate`` on a
    throw-away copy, as it would change the mesh: a face repeating a vertex, an edge out of range, ...): Blender's
    edit mode hangs or crashes on such data. Each mesh is checked once; the copies are removed together."""
    copies, broken = {}, set()
    try:
        for o in objects:
            key = o.data.as_pointer()
            if key not in copies:
                copies[key] = o.data.copy()
                if copies[key].validate(verbose=False):
                    broken.add(key)
    finally:
        remove_ids((bpy.data.meshes, me) for me in copies.values())
    return {o.name: f"mesh '{o.data.name}' of '{o.name}' is invalid (e.g. a face that repeats a vertex): repair it "
                    f"first (Mesh > Clean Up, or mesh.validate() in Python)"
            for o in objects if o.data.as_pointer() in broken}


def check_layer(obj, name):
    if name not in obj.data.uv_layers:
        have = ", ".join(l.name for l in obj.data.uv_layers) or "none"
        raise InputError(f"object '{obj.name}' has no UV layer '{name}' (it has: {have})")


# ------------------------------------------------------------------ generated layouts

@dataclasses.dataclass
class Layouts:
    """The light-map layers of a set of objects, by object name: ``layers`` the UV layer each is baked through,
    ``sides`` the side a generated layout was made for, ``margins`` its margin in texels (possibly lowered to
    half a texel; else the asked one; :func:`dilation` gives the texels the map is dilated by), ``unwraps`` the
    unwrapper of a generated layout (unwrap.UNWRAPPERS), ``windows`` (width, height, side) of a
    generated layout carried into a window of its map (:func:`_cut_window`): its map is width x height; ``caches``
    (UV cache key, index of the object in the entry) of a layout the UV cache holds (generated or read from it), by
    which an export of a file that lacks the layer finds it again (report entries' "uv_cache")."""
    layers: dict = dataclasses.field(default_factory=dict)
    sides: dict = dataclasses.field(default_factory=dict)
    margins: dict = dataclasses.field(default_factory=dict)
    unwraps: dict = dataclasses.field(default_factory=dict)
    windows: dict = dataclasses.field(default_factory=dict)
    caches: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class _Made:
    """A generated layout: the side it was made for, its margin in texels, its unwrapper, the side asked before it
    was enlarged (0: not enlarged), the window (width, height, side) it was carried into (None: the square), the
    UV cache key it is kept under (None: no cache)."""
    side: int
    margin: float
    unwrap: str
    enlarged_from: int = 0
    welded: bool = False
    window: tuple = None
    key: str = None


def prepare(scene, objects, state, options, together=False, cache=None):
    """Return the objects' :class:`Layouts`.

    ``options.uv_layer`` is used as it is. Otherwise each group (one object, or all of them ``together``: an atlas,
    whose charts share one UV square without overlapping) gets, in this order: for one object whose mesh already
    got its layer in this run (a linked duplicate), that layer as it is (:func:`_shared`: a window of its own, also
    kept in ``cache`` for this object); the layout ``cache`` (:class:`uvcache.UVCache`) holds for the group (made before into
    this output folder: its maps on disk were baked through it); for one object, an existing "Lightmap" layer
    reused as it is when it covers a square map with square texels (:func:`_reusable`); else a generated layout,
    kept in ``cache``. Only generated and cached layouts have an entry in the sides (:func:`uvchecks.low_fill`
    checks them at the map's final size).
    """
    made = Layouts()
    for o in objects:
        made.layers[o.name] = options.uv_layer or LIGHTMAP
        made.margins[o.name] = float(options.margin)
    if options.uv_layer or not objects:
        return made
    with fixed_geometry():
        _prepare_groups(scene, objects, state, options, together, cache, made)
    return made


def _prepare_groups(scene, objects, state, options, together, cache, made):
    """The loop of :func:`prepare` over its groups, filling ``made``."""
    settled = cache.settled if cache is not None else {}
    stretches = cache.stretches if cache is not None else Stretches()
    for group in ([list(objects)] if together else [[o] for o in objects]):
        first = group[0]
        if not together and first.data.as_pointer() in settled:
            layout = settled[first.data.as_pointer()]
            if layout is not None:
                layout = _shared(first, layout, options)
                if cache is not None:           # a rerun that bakes only this object finds the layout
                    digest = uvcache.key(group, scene.view_layers[0].depsgraph, options, together,
                                         [stretches.of(first, together)])
                    if digest not in cache.memory:  # else its mesh's own key (moved, turned): that entry stays
                        cache.put(digest, uvcache.Entry([corner_uv(first.data, LIGHTMAP).ravel()],
                                                        layout.side, layout.margin, layout.unwrap, 0, layout.window,
                                                        uvcache.corners_of([first.data])))
                    layout.key = digest
        else:
            layout = _layout(scene, group, state, options, made.layers, together, cache, stretches)
            if not together:
                settled[first.data.as_pointer()] = layout
        if layout is None:
            continue
        for o in group:
            made.sides[o.name], made.margins[o.name], made.unwraps[o.name] = layout.side, layout.margin, layout.unwrap
            if layout.window:
                made.windows[o.name] = layout.window
        if layout.key:
            made.caches.update((o.name, (layout.key, i)) for i, o in enumerate(group))


def _shared(obj, layout, options):
    """The layout of another object of ``obj``'s mesh (its "Lightmap" layer as it is) for ``obj``, with its unwrapper.
    Without a window: the same side and margin (the plan never makes the map smaller than that side). With one: a
    window cut from the square side ``obj``'s texel density asks for that layer, scaled from the other's window (the
    same shape, square texels), capped by the maximum resolution and never so small that the charts come closer than
    a texel; a side below the layout's gives its margin in that side's texels (lowered below the asked one with the
    warning of :func:`_dilation`)."""
    from .uvchecks import chart_area
    if not layout.window:
        return _Made(layout.side, layout.margin, layout.unwrap)
    w, h, side = layout.window
    charted = chart_area(triangles_uv(obj, LIGHTMAP)) * w * h / side ** 2       # of the square it was cut from
    want = lightmap.resolution_for_density(world_area(obj), charted, options.texel_density, options.max_resolution)
    s = min(max(want, math.ceil(0.5 * layout.side / layout.margin)), int(options.max_resolution))
    window = (max(1, round(w * s / side)), max(1, round(h * s / side)), s)
    if s >= layout.side:            # the margin as the other object's report gives it: in the layout side's texels
        return _Made(layout.side, layout.margin, layout.unwrap, window=window)
    margin = _dilation(f"'{obj.name}'", options.margin, layout.margin * s / layout.side, s)
    return _Made(s, margin, layout.unwrap, window=window)


def _layout(scene, group, state, options, names, together, cache, stretches):
    """The group's layout (:class:`_Made`): from ``cache``, else None when one object's existing layer is reused
    (:func:`_reusable`), else generated (:func:`unwrap._unwrap_with_margin`, :func:`_cut_window`) and kept in
    ``cache``."""
    from .unwrap import _unwrap_with_margin
    digest = entry = None
    linears = [stretches.of(o, together) for o in group]
    if cache is not None:
        digest = uvcache.key(group, scene.view_layers[0].depsgraph, options, together, linears)
        entry = cache.get(digest, [o.data for o in group])
    if entry is not None:
        if entry.corners is None:       # written before the corners were kept: the key holds them as they are now
            entry = dataclasses.replace(entry, corners=uvcache.corners_of([o.data for o in group]))
            cache.put(digest, entry)
        return dataclasses.replace(_from_entry(group, entry, state, options), key=digest)
    if not together and LIGHTMAP in group[0].data.uv_layers and _reusable(group[0], options,
                                                                        stretches.shared_apart(group[0])):
        return None
    made = _cut_window(group, _unwrap_with_margin(group, state, options, names, linears), state, names, options)
    if cache is not None:
        uvs = [corner_uv(o.data, LIGHTMAP).ravel() for o in group]
        cache.put(digest, uvcache.Entry(uvs, made.side, made.margin, made.unwrap, made.enlarged_from, made.window,
                                        uvcache.corners_of([o.data for o in group])))
        made = dataclasses.replace(made, key=digest)
    return made


def _from_entry(group, entry, state, options):
    """The layout of a cache entry, written into the group's "Lightmap" layers where they differ (the same UVs,
    side, margin, unwrapper and warnings as unwrapping again)."""
    from .uvchecks import _disjoint
    label = ", ".join(f"'{o.name}'" for o in group)
    for o, uv in zip(group, entry.uvs):
        me = o.data
        if LIGHTMAP not in me.uv_layers or not np.array_equal(corner_uv(me, LIGHTMAP).ravel(),
                                                              uv):
            _write_layer(state, me, uv)
        _disjoint(triangles_uv(o, LIGHTMAP))
    if entry.enlarged_from:
        _say_enlarged(label, entry.enlarged_from, entry.side)
    return _Made(entry.side, _dilation(label, options.margin, entry.margin, entry.side), entry.unwrap,
                 entry.enlarged_from, window=entry.window)


WINDOW_AREA = 0.9
"""A layout is carried into a window of its map (:func:`_cut_window`) when the window holds at most this share of
the square's texels (Blender's packers fill one side of the square: a UV sphere's Smart UV Project layout 0.70 of
the other, a cylinder's 0.83; a mesh's own grid placed by its texels fills a square window in a corner: a torus at
40 texels/m 124² of 215², whose square map it filled 0.33 of)."""
REUSE_ANISOTROPY = 1.5
"""Most texel anisotropy (:func:`core.lightmap.texel_anisotropy`) on the mesh as it is of a layer reused for linked
duplicates that stand stretched differently (:func:`_reusable`): Smart UV Project's layouts 1.0, joined charts
1.1-1.26 on the primitives; a box's layer made for it scaled (1, 1, 4): 4."""
REUSE_ASPECT = 1.08
"""An earlier "Lightmap" layer is reused for a square map only when its texels are square to this ratio
(:func:`core.lightmap.texel_aspect`; measured 0.968-1.003 on Smart UV Project layouts made for a square, 1.065 on a
UV sphere's Lightmap Pack layout at 256², 0.71-0.83 on layouts carried into windows whose sides differ; a layout
carried into a square window has square texels in a square map, and is reused as such)."""


def window(tri, side, margin):
    """(lo, size) of :func:`core.lightmap.chart_window` of the charts ``tri`` at ``side`` with ``margin`` texels
    around them when it holds at most WINDOW_AREA of the ``side``² texels (the map is cut to it), else None (kept
    square)."""
    lo, size = lightmap.chart_window(tri, side, margin)
    return None if int(size[0]) * int(size[1]) > WINDOW_AREA * side * side else (lo, size)


def group_triangles_uv(group):
    """(T, 3, 2) "Lightmap" UVs of the loop triangles of every object of ``group`` (:func:`triangles_uv`)."""
    return np.concatenate([triangles_uv(o, LIGHTMAP) for o in group])


def _cut_window(group, made, state, names, options):
    """With a texel density (the bake chooses the map's size), carry the group's generated layout into the window
    of whole texels that holds its charts and their margins (:func:`core.lightmap.chart_window`) at the side S its
    map gets (the texel-density side, at least the layout's): the map becomes width x height, the same texels
    (every texel centre keeps its place against the charts) without the empty texels the packer left. Kept square
    when the window holds more than WINDOW_AREA of the square (a fixed resolution is always square)."""
    from .uvchecks import _disjoint
    if options.texel_density is None or options.sizes:
        return made
    side = baked_side(group, names, options, made.side)
    cut = window(group_triangles_uv(group), side, made.margin * side / made.side)
    if cut is None:
        return made
    lo, size = cut
    for o in group:
        uv = corner_uv(o.data, LIGHTMAP).ravel()
        _write_layer(state, o.data, lightmap.to_window(uv, side, lo, size).ravel())
        _disjoint(triangles_uv(o, LIGHTMAP))
    made.window = (int(size[0]), int(size[1]), int(side))
    return made


def baked_side(group, names, options, made_side, stored=False):
    """The side of the square map (or of the square its window is cut from) of a generated layout made at
    ``made_side``: the texel density's (:func:`resolution`, at least ``made_side``), or ``made_side`` when that
    larger side's texel centres miss the charts (uvchecks.MIN_COVERAGE: an object a few texels wide, whose layout
    was fitted at its side; the density's side may be up to 5 % larger). ``stored``: the coverage measured is kept in
    the figure store (the plan's, which the coverage check reads again; not a window's trial)."""
    from .uvchecks import MIN_COVERAGE, coverage_ratio
    side = max(resolution(group, names, options), made_side)
    if side > made_side and coverage_ratio(group_triangles_uv(group), side, side, stored)[0] < MIN_COVERAGE:
        return made_side
    return side


def _say_enlarged(label, asked, side):
    errors.warn(f"{label}: light map enlarged from a side of {asked} to {side} texels so that its charts cover their "
                f"faces")


def _write_layer(state, me, uv):
    """Flat UVs ``uv`` into mesh ``me``'s "Lightmap" layer, made (and recorded in ``state``) when missing, else
    saved to be put back unless kept."""
    if LIGHTMAP not in me.uv_layers:
        me.uv_layers.new(name=LIGHTMAP, do_init=False)
        state.created_uv(me, LIGHTMAP)
    else:
        state.save_uv(me, LIGHTMAP)   # an earlier bake's layer, re-unwrapped: put back unless kept
    me.uv_layers[LIGHTMAP].data.foreach_set("uv", uv)


def _reusable(obj, options, apart=False):
    """An earlier bake's "Lightmap" layer is reused when it covers the square map it will get and its texels are
    square on it (REUSE_ASPECT: a layout carried into a window is made again). For a mesh whose users stand
    stretched differently (``apart``: :meth:`unwrap_copy.Stretches.shared_apart`), whose layout is made on the mesh
    as it is, its texels must be square there, and not only on average (REUSE_ANISOTROPY: a layer made for one of
    them while it stood alone, stretched as it stands, is made again)."""
    from .uvchecks import MIN_COVERAGE, _outside, coverage_ratio
    tri = triangles_uv(obj, LIGHTMAP)
    if _outside(tri):
        return False
    surface = mesh_triangles(obj.data) if apart else world_triangles(obj)
    if abs(math.log(lightmap.texel_aspect(tri, surface))) > math.log(REUSE_ASPECT):
        return False
    if apart and lightmap.texel_anisotropy(tri, surface) > REUSE_ANISOTROPY:
        return False
    side = fixed_side(obj, options) or resolution([obj], {obj.name: LIGHTMAP}, options)
    return coverage_ratio(tri, side, side)[0] >= MIN_COVERAGE


def fixed_side(obj, options):
    size = options.sizes.get(obj.name) if options.sizes else None
    if size:
        return max(size)
    return None if options.texel_density is not None else int(options.resolution)


def _dilation(label, asked, margin, side):
    """The layout's margin ``margin`` (texels), with a warning when it is below the ``asked`` one; the message
    gives the numbers the report and the EXR header carry (margin, dilation)."""
    if margin < float(asked):
        d = dilation(asked, margin)
        errors.warn(f"{label}: light-map margin lowered from {asked} to {margin:g} texel(s) so that the charts "
                    f"fit and fill {article(f'{side}x{side}')} map (charts {2 * margin:g} texel(s) apart, dilated by "
                    f"{d} texel(s))")
    return margin


def dilation(asked, margin):
    """Texels a map is dilated by: the asked margin, at most the layout's ``margin`` rounded up (a half-texel
    layout is dilated by 1)."""
    return min(int(asked), math.ceil(float(margin)))


def margin_value(margin):
    """``margin`` (texels) as the report and the EXR header give it: an int when whole, else the float."""
    m = float(margin)
    return int(m) if m.is_integer() else m


def resolution(objects, layers, options, coverage=None):
    """Map side for the objects sharing one map: the fixed resolution, or N = T √(A / coverage) from the
    texel density T, the world area A and the UV coverage of their layers (``coverage`` overrides it)."""
    from .uvchecks import chart_area
    if options.texel_density is None:
        return int(options.resolution)
    area = sum(world_area(o) for o in objects)
    if coverage is None:
        coverage = sum(chart_area(triangles_uv(o, layers[o.name])) for o in objects)
    return lightmap.resolution_for_density(area, min(coverage, 1.0), options.texel_density, options.max_resolution)
