"""Light-map UVs: an existing layer used as it is, or a generated non-overlapping "Lightmap" layer.

The generated layer comes from Blender's Smart UV Project (at its 66° angle limit, or for a single mesh that fills
under :data:`FILL` of its map at :data:`WIDE_ANGLE`), or for a single mesh its Lightmap Pack, each kept when it
fills more of the map with as even a texel density (:func:`even_enough`); with a texel density the layout is then
carried into the window of its charts (:func:`_cut_window`: a w x h map). They run on temporary canonical copies of the meshes (faces in an order given by their
vertices, every face revealed and selected through bmesh, one UV layer): the user's meshes never enter
edit mode and their select / hide flags are never written, only the finished UVs are copied into
their "Lightmap" layer (the other layers, the active layer and the layer that renders stay as they
were). Writing those flags through RNA is unsafe: in bpy 5.0 (``compat.MISTYPED_SELECT_EDGE``) a mesh
made by ``Mesh.from_pydata`` (``Mesh.update(calc_edges=True)``; the torus primitive is one) carries a
``.select_edge`` attribute typed INT32_2D instead of BOOLEAN, and ``edges.foreach_set("select", ...)``
(or ``edge.select = ...``) on it kills Blender with signal 11.

Islands are packed with a margin given as a fraction of the map ("FRACTION"): ``margin`` texels of
empty space around every chart at the side the map gets, so charts lie 2 × margin texels apart and
the dilation by ``margin`` texels never reaches into a neighbour's chart. When the asked margin does
not fit (Blender's packer then leaves charts outside the unit square, or shrinks them below a texel)
the margin is halved down to half a texel; a layout is accepted only when its charts cover the map
(:data:`MIN_COVERAGE`).
"""
import contextlib
import dataclasses
import io
import math
import warnings

import bmesh
import bpy
import numpy as np

from ..blender.scene import evaluated_mesh, read
from ..core import errors, lightmap
from ..core.memo import FIGURES, digest
from ..core.errors import InputError
from . import uvcache
from .charts import chart_count, first_at_position, side_for_fill
from .options import article

LIGHTMAP = "Lightmap"
MAX_UV_LAYERS = 8
MIN_COVERAGE = 0.5
"""A map is accepted when its covered texels (texel centres inside a chart) are at least this fraction of
side² × the charts' UV area inside the unit square (Σ |UV triangle area|, clipped): below it, charts are
thinner than a texel and most faces get no texel of their own."""
MIN_CHART_AREA = 0.2
"""A margin is lowered (down to half a texel) until the charts fill at least this fraction of the map: a
margin wider than that wastes most texels of a small map."""
_OUTSIDE = 1e-4       # UVs this far outside [0, 1]: the packer failed
SMART, LIGHTMAP_PACK = "smart_project", "lightmap_pack"
"""The unwrappers a generated layout comes from (the report entries' "unwrap")."""
ANGLE = 1.15192
"""Smart UV Project's angle limit (66°, its default)."""
WIDE_ANGLE = math.radians(75)
"""The angle limit also tried on a single mesh's layout that fills under FILL (:meth:`_Copies.try_wide_angle`):
fewer, larger charts, hence fewer margins. Measured (fill of the window at the side, margin 1-2 texels; density
spread): an ico sphere (3 subdivisions) 0.44 -> 0.67 at 128², 0.32 -> 0.49 at 64², spread 0.92 both; a torus 0.31
-> 0.39 at 128²; a UV sphere 0.69 -> 0.55 and a cylinder unchanged (kept at 66°). 85° and 89° fill more by
foreshortening: spread 0.35-0.75."""
SPREAD_SLACK = 0.05
MIN_SPREAD = 0.8
"""A layout that would replace another (:meth:`_Copies.try_wide_angle`, :meth:`_Copies.try_lightmap_pack`) must be
about as even (:func:`density_spread`): at least the other's less SPREAD_SLACK, or at least MIN_SPREAD. Measured:
Smart UV Project 0.90-0.93 on the primitives; Lightmap Pack 0.83 (UV sphere), 0.89 (torus), 0.95 (ico sphere),
0.45-0.46 (cylinder: its caps get half the density of its side); Smart UV Project at 85-89° 0.35-0.75."""


def even_enough(spread, other):
    """A layout of density spread ``spread`` may replace one of ``other`` (SPREAD_SLACK, MIN_SPREAD)."""
    return spread >= min(other - SPREAD_SLACK, MIN_SPREAD)
LIGHTMAP_PACK_TRIANGLES = 10000
"""Lightmap Pack (Python: measured 0.06 s for 1,280 triangles, 0.28 s for 5,120, 0.31 s for 10,000 quads, 1.6 s
for 40,000 quads, against 0.001-0.07 s for Smart UV Project) is tried only on single meshes up to this many
triangles, at most about 0.6 s a try (one try per layout the margin and texel-density search keeps)."""
_LIGHTMAP_PACK_MAX_MARGIN = 0.01   # the operator's largest margin: 1 % of the square


# ------------------------------------------------------------------ reading layers

_FIXED = None      # {(what, pointer, layer): value} while the layouts are fixed (:func:`fixed_layouts`), else None


@contextlib.contextmanager
def fixed_layouts():
    """A scope in which no mesh, UV layer or transform of the baked objects changes (after the UV step, through
    the bakes and files): :func:`triangles_uv` and :func:`world_area` are read once per object in it."""
    global _FIXED
    _FIXED = {}
    try:
        yield
    finally:
        _FIXED = None


_GEOMETRY = None   # {(what, pointer): value} while only UV layers change (:func:`fixed_geometry`), else None


@contextlib.contextmanager
def fixed_geometry():
    """A scope in which the objects' meshes and transforms do not change, only their UV layers (the UV step):
    :func:`world_area` and :func:`world_triangles` are read once per object in it."""
    global _GEOMETRY
    if _GEOMETRY is not None:
        yield
        return
    _GEOMETRY = {}
    try:
        yield
    finally:
        _GEOMETRY = None


def remembered(key, make, geometry=False):
    """``make()``, once per ``key`` inside :func:`fixed_layouts` (and, for ``geometry``, inside
    :func:`fixed_geometry`); every call outside them."""
    store = _FIXED if _FIXED is not None else (_GEOMETRY if geometry else None)
    if store is None:
        return make()
    if key not in store:
        store[key] = make()
    return store[key]


def triangles_uv(obj, layer):
    """(T, 3, 2) UV coordinates of the mesh's loop triangles in ``layer`` (read-only inside :func:`fixed_layouts`)."""
    def make():
        tri = mesh_triangles_uv(obj.data, layer)
        if _FIXED is not None:
            tri.flags.writeable = False
        return tri
    return remembered(("uv", obj.data.as_pointer(), layer), make)


def mesh_triangles_uv(me, layer):
    """(T, 3, 2) UV coordinates of mesh ``me``'s loop triangles in ``layer``."""
    me.calc_loop_triangles()
    loops = read(me.loop_triangles, "loops", np.int64, 3)
    uv = read(me.uv_layers[layer].data, "uv", np.float32, 2)
    return uv.reshape(-1, 2)[loops].reshape(-1, 3, 2)


def world_area(obj):
    """Surface area in m² of the mesh in world space (object scale included)."""
    return remembered(("area", obj.as_pointer(), obj.data.as_pointer()), lambda: _world_area(obj), geometry=True)


def _world_area(obj):
    t = world_triangles(obj)
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def world_triangles(obj):
    """(T, 3, 3) world positions of the corners of the mesh's loop triangles (the order of :func:`triangles_uv`),
    read-only."""
    def make():
        t = _world_triangles(obj)
        t.flags.writeable = False
        return t
    return remembered(("world", obj.as_pointer(), obj.data.as_pointer()), make, geometry=True)


def _world_triangles(obj):
    me = obj.data
    me.calc_loop_triangles()
    co = read(me.vertices, "co", np.float32, 3).reshape(-1, 3).astype(float)
    mw = np.array(obj.matrix_world, float)
    co = co @ mw[:3, :3].T + mw[:3, 3]
    return co[read(me.loop_triangles, "vertices", np.int64, 3)].reshape(-1, 3, 3)


def check_valid(obj):
    """Refuse a mesh Blender itself reports invalid (``Mesh.validate`` on a throw-away copy would change it: a
    face repeating a vertex, an edge out of range, ...): Blender's edit mode hangs or crashes on such data."""
    tmp = obj.data.copy()
    try:
        broken = tmp.validate(verbose=False)
    finally:
        bpy.data.meshes.remove(tmp)
    if broken:
        raise InputError(f"mesh '{obj.data.name}' of '{obj.name}' is invalid (e.g. a face that repeats a vertex): "
                         f"repair it first (Mesh > Clean Up, or mesh.validate() in Python)")


def check_layer(obj, name):
    if name not in obj.data.uv_layers:
        have = ", ".join(l.name for l in obj.data.uv_layers) or "none"
        raise InputError(f"object '{obj.name}' has no UV layer '{name}' (it has: {have})")


# ------------------------------------------------------------------ coverage (numpy only)

UNION_SIDE = 1024
"""Side of the raster that measures the area of overlapping charts (their union)."""


_DISJOINT = {}    # digest -> Σ |triangle area| of the layouts an unwrapper made (charts that never overlap)


def chart_area(tri_uv):
    """The charts' UV area inside the unit square, overlapping charts counted once: Σ |triangle area| of the
    clipped UVs, or, when that exceeds the fraction of a UNION_SIDE² raster's texel centres they cover (a
    user's layer with mirrored or tiled charts), that fraction; a layout an unwrapper made here (its charts do not
    overlap: :func:`_disjoint`) gets Σ |triangle area| without the raster. Remembered per layout (the unwrap, the
    side and the files ask for the same layout several times)."""
    tri = np.ascontiguousarray(np.clip(tri_uv, 0.0, 1.0), np.float32)
    key = digest(tri)
    if key in _DISJOINT:
        return _DISJOINT[key]
    return FIGURES.call(_union_area, tri)


def _union_area(tri):
    total = lightmap.uv_area(tri)
    union = float(lightmap.coverage_mask(tri, UNION_SIDE, UNION_SIDE).mean()) if total > 0 else 0.0
    return total if total <= union * 1.02 else union


def _disjoint(tri_uv):
    """Remember the layout ``tri_uv`` as one whose charts do not overlap (Smart UV Project's, Lightmap Pack's,
    pack_islands'): its chart area is Σ |triangle area| (kept for the process: the same layout always gets the same
    area, whatever else was measured in between)."""
    tri = np.ascontiguousarray(np.clip(tri_uv, 0.0, 1.0), np.float32)
    _DISJOINT[digest(tri)] = lightmap.uv_area(tri)


def coverage(tri_uv, width, height):
    """``lightmap.coverage_mask`` of ``tri_uv`` in a ``width`` × ``height`` map (read-only), remembered per layout and
    size (the plan, the fill check, the bake's centre mask and the files ask for the same ones)."""
    return FIGURES.call(lightmap.coverage_mask, np.ascontiguousarray(tri_uv), int(width), int(height))


def coverage_ratio(tri_uv, width, height):
    """(covered texels / (W H × chart area), chart area); (0, 0) for charts without area."""
    area = chart_area(tri_uv)
    if area <= 0:
        return 0.0, 0.0
    return float(coverage(tri_uv, width, height).sum()) / (area * width * height), area


def _outside(tri_uv):
    return bool(len(tri_uv)) and (tri_uv.min() < -_OUTSIDE or tri_uv.max() > 1 + _OUTSIDE)


def check_coverage(objects, layers, size):
    """Raise InputError unless every object's charts in its layer cover its faces in a ``size`` = (W, H) map.

    Returns ``{object name: chart area}``."""
    w, h = size
    areas = {}
    for o in objects:
        layer = layers[o.name]
        tri = triangles_uv(o, layer)
        ratio, area = coverage_ratio(tri, w, h)
        if area <= 0:
            raise InputError(f"UV layer '{layer}' of '{o.name}' has no area inside the unit square (its faces "
                             f"collapse to points or lines, or lie outside 0..1): unwrap it, or let the bake "
                             f"generate a light-map layer")
        if ratio < MIN_COVERAGE:
            need = _side_that_fits(tri, w, h)
            hint = f"use a resolution of at least {need}" if need else "use a layer with larger charts"
            raise InputError(f"UV layer '{layer}' of '{o.name}' covers only {100 * ratio:.0f} % of its charts' "
                             f"area in {article(f'{w}x{h}')} map (minimum {100 * MIN_COVERAGE:.0f} %): {hint}")
        areas[o.name] = area
    return areas


MAX_OVERLAP = 0.01
"""Covered texels shared by several faces of the rendered mesh above which a bake warns (the bake writes such a
texel once for all of them: one value for faces that see different light)."""
OVERLAP_SIDE = 1024
"""Overlap is a fraction of the charts' area: measured on a map of at most this side (same aspect), which
bounds its cost (about 0.7 s for 7200 triangles filling a 1024² map)."""
_COPIES = {"ARRAY": "Array", "MIRROR": "Mirror", "SOLIDIFY": "Solidify"}


def evaluated_triangles_uv(obj, layer, depsgraph):
    """(T, 3, 2) UVs in ``layer`` of the loop triangles of ``obj``'s evaluated mesh (modifiers applied, what
    Cycles bakes), or None when the evaluated mesh does not carry the layer."""
    with evaluated_mesh(obj, depsgraph) as me:
        return mesh_triangles_uv(me, layer) if me is not None and layer in me.uv_layers else None


def check_overlap(scene, objects, layers, size):
    """Fraction of each object's covered texels shared by several faces of its evaluated mesh
    (``core.lightmap.overlap_fraction``): ``({object name: fraction}, fraction over the whole group)``.

    Measured at the map's size, scaled down to OVERLAP_SIDE. Warns above MAX_OVERLAP, naming the Array / Mirror modifiers whose copies repeat the base mesh's UVs (the
    light-map layer is made on the base mesh, so every copy gets the same texels; Solidify's second shell is such a
    copy), else too few texels for the triangles (:func:`too_few_texels`), else the layer itself."""
    scale = min(1.0, OVERLAP_SIDE / max(size))
    w, h = max(1, round(size[0] * scale)), max(1, round(size[1] * scale))
    depsgraph = scene.view_layers[0].depsgraph
    fractions, every = {}, []
    for o in objects:
        layer = layers[o.name]
        tri = evaluated_triangles_uv(o, layer, depsgraph)
        if tri is None:
            tri = triangles_uv(o, layer)
        every.append(tri)
        fractions[o.name] = frac = FIGURES.call(lightmap.overlap_fraction, tri, w, h)
        if frac <= MAX_OVERLAP:
            continue
        copies = [m for m in o.modifiers if m.type in _COPIES and m.show_render]
        if copies and FIGURES.call(lightmap.overlap_fraction, triangles_uv(o, layer), w, h) <= MAX_OVERLAP:
            kinds = " and ".join(dict.fromkeys(_COPIES[m.type] for m in copies))
            names = ", ".join(f"'{m.name}'" for m in copies)
            errors.warn(f"'{o.name}': {kinds} copies share the light-map texels ({100 * frac:.0f} % of its texels "
                        f"hold several faces, modifier {names}): apply the modifier to give each copy its own")
        elif FIGURES.call(lightmap.overlap_fraction, tri, FINE_SIDE, FINE_SIDE) <= MAX_OVERLAP:
            errors.warn(too_few_texels(o, tri, size))
        else:
            errors.warn(f"'{o.name}': faces share texels of UV layer '{layer}' ({100 * frac:.0f} % of its texels "
                        f"hold several faces, which get one value): use a layer without overlapping charts, or let "
                        f"the bake generate one")
    group = FIGURES.call(lightmap.overlap_fraction, np.concatenate(every), w, h) if len(objects) > 1 else fractions[objects[0].name]
    return fractions, group


FINE_SIDE = 2048
"""Side at which a layout whose charts overlap at the map's size is measured again: overlap that vanishes there
comes from too few texels (several tiny triangles around one texel centre), not from charts over each other."""
TEXELS_PER_TRIANGLE = 4
"""Covered texels per triangle the suggested side gives (a texel per triangle at least, with room)."""


def too_few_texels(obj, tri, size):
    """The warning for a layout whose faces share texels only because the map is too small for the mesh: covered
    texels against triangles, and the side (and texel density) that gives each triangle TEXELS_PER_TRIANGLE."""
    w, h = size
    covered = max(1, int(coverage(tri, w, h).sum()))
    n = len(tri)
    side = min(lightmap.MAX_RESOLUTION, math.ceil(max(w, h) * math.sqrt(TEXELS_PER_TRIANGLE * n / covered)))
    area = world_area(obj)
    density = side * math.sqrt(chart_area(tri) / area) if area > 0 else 0.0
    return (f"'{obj.name}': {covered} texels for {n} triangles in {article(f'{w}x{h}')} map "
            f"({covered / n:.2g} per triangle): the map is too small for the mesh, so neighbouring faces share "
            f"texels; a resolution of {side} (about {density:.3g} texels/m) gives each triangle about "
            f"{TEXELS_PER_TRIANGLE} texels")


def _side_that_fits(tri, w, h, cap=4096):
    """Smallest side 2^k · max(w, h) ≤ cap at which the layout ``tri`` meets MIN_COVERAGE, or None."""
    side = max(w, h)
    while side < cap:
        side = min(2 * side, cap)
        if coverage_ratio(tri, side, side)[0] >= MIN_COVERAGE:
            return side
    return None


# ------------------------------------------------------------------ generated layouts

@dataclasses.dataclass
class Layouts:
    """The light-map layers of a set of objects, by object name: ``layers`` the UV layer each is baked through,
    ``sides`` the side a generated layout was made for, ``margins`` its margin in texels (possibly lowered to
    half a texel; else the asked one; :func:`dilation` gives the texels the map is dilated by), ``unwraps`` the
    unwrapper of a generated layout (SMART or LIGHTMAP_PACK), ``windows`` (width, height, side) of a generated
    layout carried into a window of its map (:func:`_cut_window`): its map is width x height."""
    layers: dict = dataclasses.field(default_factory=dict)
    sides: dict = dataclasses.field(default_factory=dict)
    margins: dict = dataclasses.field(default_factory=dict)
    unwraps: dict = dataclasses.field(default_factory=dict)
    windows: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class _Made:
    """A generated layout: the side it was made for, its margin in texels, its unwrapper, the side asked before it
    was enlarged (0: not enlarged), the window (width, height, side) it was carried into (None: the square)."""
    side: int
    margin: float
    unwrap: str
    enlarged_from: int = 0
    welded: bool = False
    window: tuple = None


def prepare(scene, objects, state, options, together=False, cache=None):
    """Return the objects' :class:`Layouts`.

    ``options.uv_layer`` is used as it is. Otherwise each group (one object, or all of them ``together``: an atlas,
    whose charts share one UV square without overlapping) gets, in this order: for one object whose mesh already
    got its layer in this run (a linked duplicate), that layer as it is (:func:`_shared`: a window of its own, also
    kept in ``cache`` for this object); the layout ``cache`` (:class:`uvcache.UVCache`) holds for the group (made before into
    this output folder: its maps on disk were baked through it); for one object, an existing "Lightmap" layer
    reused as it is when it covers a square map with square texels (:func:`_reusable`); else a generated layout,
    kept in ``cache``. Only generated and cached layouts have an entry in the sides (:func:`low_fill` checks them
    at the map's final size).
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
    for group in ([list(objects)] if together else [[o] for o in objects]):
        first = group[0]
        if not together and first.data.as_pointer() in settled:
            layout = settled[first.data.as_pointer()]
            if layout is not None:
                layout = _shared(first, layout, options)
                if cache is not None:           # a rerun that bakes only the other object finds this one's layout
                    cache.put(uvcache.key(group, scene.view_layers[0].depsgraph, options, together),
                              uvcache.Entry([read(first.data.uv_layers[LIGHTMAP].data, "uv", np.float32, 2)],
                                            layout.side, layout.margin, layout.unwrap, 0, layout.window))
        else:
            layout = _layout(scene, group, state, options, made.layers, together, cache)
            if not together:
                settled[first.data.as_pointer()] = layout
        if layout is None:
            continue
        for o in group:
            made.sides[o.name], made.margins[o.name], made.unwraps[o.name] = layout.side, layout.margin, layout.unwrap
            if layout.window:
                made.windows[o.name] = layout.window


def _shared(obj, layout, options):
    """The layout of another object of ``obj``'s mesh (its "Lightmap" layer as it is) for ``obj``, with its unwrapper.
    Without a window: the same side and margin (the plan never makes the map smaller than that side). With one: a
    window cut from the square side ``obj``'s texel density asks for that layer, scaled from the other's window (the
    same shape, square texels), capped by the maximum resolution and never so small that the charts come closer than
    a texel; a side below the layout's gives its margin in that side's texels (lowered below the asked one with the
    warning of :func:`_dilation`)."""
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


def _layout(scene, group, state, options, names, together, cache):
    """The group's layout (:class:`_Made`): from ``cache``, else None when one object's existing layer is reused
    (:func:`_reusable`), else generated (:func:`_unwrap_with_margin`, :func:`_cut_window`) and kept in ``cache``."""
    digest = entry = None
    if cache is not None:
        digest = uvcache.key(group, scene.view_layers[0].depsgraph, options, together)
        entry = cache.get(digest, [o.data for o in group])
    if entry is not None:
        return _from_entry(group, entry, state, options)
    if not together and LIGHTMAP in group[0].data.uv_layers and _reusable(group[0], options):
        return None
    made = _cut_window(group, _unwrap_with_margin(scene, group, state, options, names), state, names, options)
    if cache is not None:
        uvs = [read(o.data.uv_layers[LIGHTMAP].data, "uv", np.float32, 2) for o in group]
        cache.put(digest, uvcache.Entry(uvs, made.side, made.margin, made.unwrap, made.enlarged_from, made.window))
    return made


def _from_entry(group, entry, state, options):
    """The layout of a cache entry, written into the group's "Lightmap" layers where they differ (the same UVs,
    side, margin, unwrapper and warnings as unwrapping again)."""
    label = ", ".join(f"'{o.name}'" for o in group)
    for o, uv in zip(group, entry.uvs):
        me = o.data
        if LIGHTMAP not in me.uv_layers or not np.array_equal(read(me.uv_layers[LIGHTMAP].data, "uv", np.float32, 2),
                                                              uv):
            _write_layer(state, me, uv)
        _disjoint(triangles_uv(o, LIGHTMAP))
    if entry.enlarged_from:
        _say_enlarged(label, entry.enlarged_from, entry.side)
    return _Made(entry.side, _dilation(label, options.margin, entry.margin, entry.side), entry.unwrap,
                 entry.enlarged_from, window=entry.window)


WINDOW_ASPECT = 0.9
"""A layout is carried into a window of its map (:func:`_cut_window`) when the window's sides differ by more than
this ratio (Blender's packers fill one side of the square: a UV sphere's Smart UV Project layout 0.70 of the other,
a cylinder's 0.83)."""
REUSE_ASPECT = 1.08
"""An earlier "Lightmap" layer is reused for a square map only when its texels are square to this ratio
(:func:`core.lightmap.texel_aspect`; measured 0.968-1.003 on Smart UV Project layouts made for a square, 1.065 on a
UV sphere's Lightmap Pack layout at 256², 0.71-0.83 on layouts carried into windows, which are at least
1 / WINDOW_ASPECT = 1.11 from square)."""


def window(tri, side, margin):
    """(lo, size) of :func:`core.lightmap.chart_window` of the charts ``tri`` at ``side`` with ``margin`` texels
    around them when its sides differ by more than WINDOW_ASPECT (the map is cut to it), else None (kept square)."""
    lo, size = lightmap.chart_window(tri, side, margin)
    return None if min(size) > WINDOW_ASPECT * max(size) else (lo, size)


def group_triangles_uv(group):
    """(T, 3, 2) "Lightmap" UVs of the loop triangles of every object of ``group`` (:func:`triangles_uv`)."""
    return np.concatenate([triangles_uv(o, LIGHTMAP) for o in group])


def _cut_window(group, made, state, names, options):
    """With a texel density (the bake chooses the map's size), carry the group's generated layout into the window
    of whole texels that holds its charts and their margins (:func:`core.lightmap.chart_window`) at the side S its
    map gets (the texel-density side, at least the layout's): the map becomes width x height, the same texels
    (every texel centre keeps its place against the charts) without the empty strip the packer left. Kept square
    when the window's sides are within WINDOW_ASPECT (a fixed resolution is always square)."""
    if options.texel_density is None or options.sizes:
        return made
    side = max(resolution(group, names, options), made.side)
    cut = window(group_triangles_uv(group), side, made.margin * side / made.side)
    if cut is None:
        return made
    lo, size = cut
    for o in group:
        uv = read(o.data.uv_layers[LIGHTMAP].data, "uv", np.float32, 2)
        _write_layer(state, o.data, lightmap.to_window(uv, side, lo, size).ravel())
        _disjoint(triangles_uv(o, LIGHTMAP))
    made.window = (int(size[0]), int(size[1]), int(side))
    return made


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


def _reusable(obj, options):
    """An earlier bake's "Lightmap" layer is reused when it covers the square map it will get and its texels are
    square on it (REUSE_ASPECT: a layout carried into a window is made again)."""
    tri = triangles_uv(obj, LIGHTMAP)
    if _outside(tri):
        return False
    if abs(math.log(lightmap.texel_aspect(tri, world_triangles(obj)))) > math.log(REUSE_ASPECT):
        return False
    side = fixed_side(obj, options) or resolution([obj], {obj.name: LIGHTMAP}, options)
    return coverage_ratio(tri, side, side)[0] >= MIN_COVERAGE


def fixed_side(obj, options):
    size = options.sizes.get(obj.name) if options.sizes else None
    if size:
        return max(size)
    return None if options.texel_density is not None else int(options.resolution)


def margin_fraction(margin, side):
    """Island margin as a fraction of the map: max(margin, 1/2) texels / side (charts at least a texel apart)."""
    return max(float(margin), 0.5) / max(int(side), 1)


def _margins(margin):
    """The margins tried, in texels: the asked one, halved down to half a texel."""
    m, out = float(margin), []
    while m >= 1:
        out.append(m)
        m = m / 2 if m > 1 else 0
    return out + [0.5]


def _unwrap_with_margin(scene, group, state, options, names):
    """Generate "Lightmap" for ``group``; return its :class:`_Made` (side, margin in texels, unwrapper): by
    :func:`_search` on copies whose coincident vertices are welded (:func:`_welded`), or again on copies as the
    meshes are when the weld joined faces that cover each other (the welded layout fails, or puts texels under
    several faces: MAX_OVERLAP at the map's side, up to OVERLAP_SIDE); the warnings of the layout not kept are
    dropped."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        try:
            made, welded = _search(scene, group, state, options, names, weld=True), None
        except InputError as e:
            made, welded = None, e
    if made is not None and not (made.welded and _overlapping(group, made.side)):
        for w in said:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return made
    if made is None and welded is not None and not getattr(welded, "welded", False):
        raise welded
    return _search(scene, group, state, options, names, weld=False)


def _overlap(group, side):
    """Fraction of the group's "Lightmap" texels (at ``side``, up to OVERLAP_SIDE) under several of its faces."""
    s = min(int(side), OVERLAP_SIDE)
    return FIGURES.call(lightmap.overlap_fraction, group_triangles_uv(group), s, s)


def _overlapping(group, side):
    """Some object of ``group`` has more than MAX_OVERLAP of its "Lightmap" texels under several of its faces."""
    s = min(int(side), OVERLAP_SIDE)
    return any(FIGURES.call(lightmap.overlap_fraction, triangles_uv(o, LIGHTMAP), s, s) > MAX_OVERLAP
               for o in group)


def _search(scene, group, state, options, names, weld=True):
    """Generate "Lightmap" for ``group`` on its unwrap copies (welded with ``weld``); return its :class:`_Made`.

    A fixed resolution gives the side at once; the margin is lowered (down to half a texel, with a
    warning) until the charts lie inside the unit square and cover the map (MIN_COVERAGE), else the
    bake is refused with the side that would fit. With a texel density the side N = T √(A / coverage)
    depends on the packing: start from the lower bound T √A (coverage 1) and re-unwrap for the side the
    last layout asks for, up to three times; when even half a texel of margin does not fit, the side is
    doubled (more texels than asked, with a warning) up to the maximum resolution.
    """
    label = ", ".join(f"'{o.name}'" for o in group)
    fixed = fixed_side(group[0], options)
    with _Copies(scene, group, state, weld) as copies:
        try:
            made = _search_copies(copies, group, options, names, label, fixed)
        except InputError as e:
            e.welded = copies.welded
            raise
        made.welded = copies.welded
        return made


def _search_copies(copies, group, options, names, label, fixed):
    """The search of :func:`_search` on the open ``copies`` (``fixed``: the fixed side, or None)."""
    if fixed:
        margin = _fit(copies, group, fixed, options.margin, cut=False)
        if margin is None:
            need = _fit_side(copies, group, fixed)
            hint = (f"use a resolution of at least {need}" if need else
                    "the charts do not fit even the largest map: bake the parts separately")
            raise InputError(f"{label}: the light-map charts do not fit {article(f'{fixed}x{fixed}')} map (they would "
                             f"cover under {100 * MIN_COVERAGE:.0f} % of their UV area): {hint}")
        return _Made(fixed, _dilation(label, options.margin, margin, fixed), copies.unwrapper)
    side = resolution(group, names, options, coverage=1.0)
    made = None
    for _ in range(3):
        margin = _fit(copies, group, side, options.margin, cut=True)
        if margin is None:
            break
        made = side
        need = resolution(group, names, options)
        if side <= need <= 1.05 * side:
            if len(group) > 1 and need > side:     # an atlas packed for the side its map gets
                refit = _fit(copies, group, need, options.margin, cut=True)
                if refit is not None:
                    made, margin = need, refit
                else:
                    margin = _fit(copies, group, side, options.margin, cut=True)
            break
        side = need
    if margin is None:
        asked = side
        while margin is None and side < int(options.max_resolution):
            side = min(2 * side, int(options.max_resolution))
            margin = _fit(copies, group, side, options.margin, cut=True)
        if margin is None:
            raise InputError(f"{label}: the light-map charts do not fit a map of the maximum resolution "
                             f"{options.max_resolution} (they would cover under {100 * MIN_COVERAGE:.0f} % "
                             f"of their UV area): raise the maximum resolution or the texel density")
        _say_enlarged(label, asked, side)
        made = side
    else:
        asked = 0
    side = made
    return _Made(side, _dilation(label, options.margin, margin, side), copies.unwrapper, asked)


FILL = 0.55
"""Covered texels / map texels a generated layout should reach; below it :func:`low_fill` warns."""
FILL_HINT = 0.5
"""The fill the suggested resolution reaches."""


def fill(group, width, height=None):
    """Covered texels (centre rule) / map texels of the group's "Lightmap" layers in a width x height map (square
    without ``height``)."""
    return float(coverage(group_triangles_uv(group), width, height or width).mean())


def low_fill(group, size, margin, options):
    """The warning line (also warned) when the group's generated layout fills under FILL of its map of ``size``
    (width, height: the map's final size; ``margin`` the charts' margin in its texels), else None:
    its fill, covered texels per triangle or per chart, and the side (and texel density) that reaches FILL_HINT
    (FILL from above FILL_HINT) by :func:`charts.side_for_fill` (of a square map of as many texels)."""
    w, h = size
    have = fill(group, w, h)
    if have >= FILL:
        return None
    side = max(1, round(math.sqrt(w * h)))
    label = ", ".join(f"'{o.name}'" for o in group)
    tris = sum(len(o.data.loop_triangles) for o in group)
    charts = sum(chart_count(o.data, LIGHTMAP) for o in group)
    covered = have * w * h
    goal = FILL_HINT if have < FILL_HINT else FILL
    need = side_for_fill(have, side, covered / max(charts, 1), margin, float(options.margin), goal)
    cause = (f"{covered / max(tris, 1):.2g} texels per triangle" if covered < 4 * tris else
             f"{covered / max(charts, 1):.3g} texels per chart, {charts} charts with {margin:g}-texel margins")
    if need and need <= lightmap.MAX_RESOLUTION:
        area = sum(world_area(o) for o in group)
        charted = sum(chart_area(triangles_uv(o, LIGHTMAP)) for o in group)
        density = f" (about {need * math.sqrt(charted / area):.3g} texels/m)" if area else ""
        hint = f"a resolution of about {need}{density} fills {100 * goal:.0f} %"
    else:
        hint = f"no resolution fills {100 * goal:.0f} % (merge or simplify the faces, or use an atlas)"
    line = f"{label}: light-map charts cover only {100 * have:.1f} % of the {w}x{h} map ({cause}); {hint}"
    errors.warn(line)
    return line


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


def _fit(copies, group, side, margin, cut):
    """Unwrap at ``side`` with the largest margin (texels) of :func:`_margins` whose layout fits and whose charts
    fill at least MIN_CHART_AREA of the map (else the fitting layout that fills most); leave it in place and
    return that margin, or None when none fits. A single mesh's layout is then also tried by Smart UV Project at
    WIDE_ANGLE (:meth:`_Copies.try_wide_angle`) and by Lightmap Pack with that margin
    (:meth:`_Copies.try_lightmap_pack`), each kept when it fills more of the map as it is baked (``cut``: cut to
    its window, :func:`baked_fill`)."""
    best = None
    for m in _margins(margin):
        copies.unwrap(margin_fraction(m, side), side)
        if _fits(copies, group, side):
            area = sum(chart_area(triangles_uv(o, LIGHTMAP)) for o in group)
            if area >= MIN_CHART_AREA:
                best = (m, area)
                break
            if best is None or area > best[1]:
                best = (m, area)
    else:
        if best is not None and best[0] != _margins(margin)[-1]:
            copies.unwrap(margin_fraction(best[0], side), side)
    if best is None:
        return None
    copies.try_wide_angle(margin_fraction(best[0], side), side, best[0], cut)
    copies.try_lightmap_pack(margin_fraction(best[0], side), side, best[0], cut)
    return best[0]


def baked_fill(group, side, margin, cut):
    """Covered texels / texels of the map the group's "Lightmap" layout made for a ``side``² map is baked into:
    the square, or with ``cut`` the window :func:`_cut_window` would cut (``margin`` texels around the charts)."""
    tri = group_triangles_uv(group)
    covered = float(coverage(tri, side, side).sum())
    cut = window(tri, side, margin) if cut else None
    size = cut[1] if cut is not None else (side, side)
    return covered / float(size[0] * size[1])


def density_spread(group):
    """:func:`core.lightmap.density_spread` of the group's "Lightmap" layout on its world-space triangles."""
    return lightmap.density_spread(group_triangles_uv(group),
                                   np.concatenate([world_triangles(o) for o in group]))


def _fit_side(copies, group, side):
    """Smallest 2^k · side whose half-texel layout fits, or None."""
    while side < lightmap.MAX_RESOLUTION:
        side = min(2 * side, lightmap.MAX_RESOLUTION)
        copies.unwrap(margin_fraction(0.5, side), side)
        if _fits(copies, group, side):
            return side
    return None


def _fits(copies, group, side):
    for o in group:
        tri = triangles_uv(o, LIGHTMAP)
        if _outside(tri) or coverage_ratio(tri, side, side)[0] < MIN_COVERAGE:
            return False
    return True


UNWRAP_BAND = 64.0
"""Meshes whose size (√ of their area in object space, where Smart UV Project works) lies within
[1 / UNWRAP_BAND, UNWRAP_BAND] m are unwrapped as they are; others on a copy scaled by a power of two to about
1 m. Measured: Smart UV Project loses the charts of a 1e-6 m cube and of a 1e5 m one (no chart fits any map),
1e-5 to 1e4 m unwrap alike."""


def mesh_area(me):
    """Surface area of mesh ``me`` in object space (its own units, no transform)."""
    me.calc_loop_triangles()
    co = np.zeros(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    tv = np.zeros(len(me.loop_triangles) * 3, np.int64)
    me.loop_triangles.foreach_get("vertices", tv)
    t = co.reshape(-1, 3).astype(float)[tv].reshape(-1, 3, 3)
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def unwrap_scale(meshes):
    """The factor the unwrap copies of ``meshes`` (one UV square) are scaled by: 1 within UNWRAP_BAND, else the
    power of two (exact in floating point) that brings √(their total area) nearest to 1 m. Charts come out the
    same shape at any scale, so UV coverage, chart areas and the texel density (from the real world area) are
    scale-free."""
    size = math.sqrt(sum(mesh_area(me) for me in meshes))
    if size <= 0 or 1.0 / UNWRAP_BAND <= size <= UNWRAP_BAND:
        return 1.0
    return 2.0 ** -round(math.log2(size))


class _Copies:
    """Temporary objects with canonical copies of the group's meshes (:func:`_canonical_copy`: all faces revealed
    and selected, one UV layer, scaled by :func:`unwrap_scale`, faces in an order given by their vertices), where
    the unwrappers run; :meth:`unwrap` copies the result into each mesh's "Lightmap" layer (through the copy's
    map to the original loops). ``unwrapper`` names the layout in place (SMART or LIGHTMAP_PACK). Removed on
    exit, also on errors."""

    def __init__(self, scene, group, state, weld=True):
        self.scene, self.group, self.state, self.weld = scene, list(group), state, weld
        self.copies = []
        self.loops = []          # per copy: the original mesh's loop of each of the copy's loops
        self.unwrapper = SMART
        self.welded = False      # the weld joined vertices of some copy
        self.angle = None        # Smart UV Project's angle limit once :meth:`try_wide_angle` decided it

    def __enter__(self):
        for o in self.group:
            me = o.data
            if LIGHTMAP not in me.uv_layers:
                if len(me.uv_layers) >= MAX_UV_LAYERS:
                    raise InputError(f"mesh '{me.name}' already has {MAX_UV_LAYERS} UV layers: pass an existing one")
                if me.library is not None or o.library is not None:
                    raise InputError(f"mesh '{me.name}' is linked from a library: it cannot get a light-map "
                                     f"UV layer (make it local)")
        try:
            scale = unwrap_scale(o.data for o in self.group)
            for o in self.group:
                tmp = self.state.track(bpy.data.meshes, bpy.data.meshes.new(f"IL unwrap {o.data.name}"))
                loops, welded = _canonical_copy(o.data, tmp, scale, self.weld)
                self.loops.append(loops)
                self.welded |= welded
                tmp.uv_layers.new(name=LIGHTMAP, do_init=False)
                tmp.uv_layers.active_index = 0
                obj = self.state.track(bpy.data.objects, bpy.data.objects.new(f"IL unwrap {o.name}", tmp))
                obj.matrix_world = o.matrix_world
                self.scene.collection.objects.link(obj)
                self.copies.append((o, obj))
        except BaseException:
            self._remove()
            raise
        return self

    def __exit__(self, *exc):
        self._remove()
        return False

    def _remove(self):
        for _, obj in self.copies:
            me = obj.data
            bpy.data.objects.remove(obj)
            bpy.data.meshes.remove(me)
        if self.copies:
            self.scene.view_layers[0].update()   # no stale base of a removed copy is left for the Cycles bake
        self.copies = []
        self.loops = []

    REPACKS = 3
    """Most re-packs of an atlas layout by ``uv.pack_islands`` (each kept only when it covers more texels)."""

    def unwrap(self, margin_uv, side, angle=None):
        """Smart UV Project of every copy in one edit session (one UV square) into "Lightmap"; for several copies
        (an atlas) the charts are then re-packed by ``uv.pack_islands`` (bounding boxes, rotation, the same margin
        as a fraction of the map) while a re-pack covers more texel centres of a ``side``² map (up to REPACKS
        times), so the layout kept covers at least as many as ``pack_islands`` of it. Measured on the quick level's
        atlas (29 meshes, 273², 1-texel margins): convex and concave shapes cover the same texels as bounding boxes
        for 10x the time; margin_method ADD or SCALED does not keep the margin in texels. ``angle``: Smart UV
        Project's angle limit (radians, ANGLE by default)."""
        temps = [obj for _, obj in self.copies]
        lead = temps[0]
        ctx = self._context()
        self.unwrapper = SMART
        with _edit(ctx, lead):
            bpy.ops.uv.smart_project(angle_limit=angle or self.angle or ANGLE, island_margin=float(margin_uv), margin_method="FRACTION",
                                     area_weight=0.0, correct_aspect=True, scale_to_bounds=False)
        best = self._uvs(temps)
        if len(temps) > 1:
            tris = [_copy_triangles(o.data) for o, _ in self.copies]     # the triangles each mesh is baked with
            have = _covered(best, tris, side, self.loops)
            for _ in range(self.REPACKS):
                with _edit(ctx, lead):
                    bpy.ops.uv.select_all(action="SELECT")
                    bpy.ops.uv.pack_islands(margin=float(margin_uv), margin_method="FRACTION", rotate=True,
                                            shape_method="AABB", udim_source="CLOSEST_UDIM")
                packed = self._uvs(temps)
                covered = _covered(packed, tris, side, self.loops)
                if covered <= have:
                    break
                best, have = packed, covered
        self._write(best)

    def _context(self):
        """The copies selected (and nothing else), the first active: the context override of their edit session."""
        vl = self.scene.view_layers[0]
        temps = [obj for _, obj in self.copies]
        for o in filter(None, vl.objects):
            want = o in temps
            if o.select_get(view_layer=vl) != want:
                o.select_set(want, view_layer=vl)
        lead = temps[0]
        vl.objects.active = lead
        return dict(scene=self.scene, view_layer=vl, active_object=lead, object=lead,
                    selected_objects=temps, selected_editable_objects=temps)

    def try_wide_angle(self, margin_uv, side, margin, cut):
        """For one copy whose layout fills under FILL of its map as baked (:func:`baked_fill`): Smart UV Project at
        WIDE_ANGLE (fewer, larger charts) with the same margin; kept when it fits a ``side``² map, fills more of it
        as baked, its texel density is as even (:func:`even_enough`) and no more of its texels lie under several
        faces (a wider chart may fold over itself in its projection: Suzanne's ears). Decided once per copies, at
        the first side the search tries: the later unwraps of the search use the angle kept."""
        if len(self.copies) != 1 or self.unwrapper != SMART or self.angle is not None:
            return
        have = baked_fill(self.group, side, margin, cut)
        if have >= FILL:
            return
        spread, shared = density_spread(self.group), _overlap(self.group, side)
        before = self._uvs([self.copies[0][1]])
        self.unwrap(margin_uv, side, WIDE_ANGLE)
        if (_fits(self, self.group, side) and baked_fill(self.group, side, margin, cut) > have
                and even_enough(density_spread(self.group), spread) and _overlap(self.group, side) <= shared):
            self.angle = WIDE_ANGLE
            return
        self.angle = ANGLE
        self.copies[0][1].data.uv_layers[LIGHTMAP].data.foreach_set("uv", before[0][0])
        self._write(before)

    def try_lightmap_pack(self, margin_uv, side, margin=None, cut=False):
        """For one copy of at most LIGHTMAP_PACK_TRIANGLES triangles: Blender's Lightmap Pack with the same margin
        (its margin, a whole fraction 1/k of the square, at least ``margin_uv``); its layout replaces Smart UV
        Project's (in place) when it fits a ``side``² map, fills more of it as baked (:func:`baked_fill`, cut
        to its window with ``cut``, ``margin`` texels around the charts) and its texel density is as even
        (:func:`even_enough`: Lightmap Pack gives a cylinder's caps about half the density of
        its side, spread 0.45 against Smart UV Project's 0.92). Return the fills (smart, lightmap pack;
        None for what was not measured)."""
        if len(self.copies) != 1 or self.unwrapper != SMART or not 0 < margin_uv <= _LIGHTMAP_PACK_MAX_MARGIN:
            return None, None
        lead = self.copies[0][1]
        lead.data.calc_loop_triangles()
        if len(lead.data.loop_triangles) > LIGHTMAP_PACK_TRIANGLES:
            return None, None
        margin = margin_uv * side if margin is None else margin
        smart_fill = baked_fill(self.group, side, margin, cut)
        smart = self._uvs([lead])
        # in object mode it unwraps the selected objects (in edit mode the window's scene's objects in edit mode,
        # not the context's: a bake of another scene than the window's would find none); it prints its steps
        with bpy.context.temp_override(**self._context()), contextlib.redirect_stdout(io.StringIO()):
            # the operator's margin is a percentage p of the square, applied as 1 / int(100 / p): at least p / 100
            bpy.ops.uv.lightmap_pack(PREF_CONTEXT="ALL_FACES", PREF_PACK_IN_ONE=True, PREF_NEW_UVLAYER=False,
                                     PREF_BOX_DIV=12, PREF_MARGIN_DIV=float(100.0 * margin_uv))
        pack = self._uvs([lead])
        self._write(pack)
        packed = baked_fill(self.group, side, margin, cut) if _fits(self, self.group, side) else None
        if packed is not None and packed > smart_fill:
            pack_spread = density_spread(self.group)
            self._write(smart)
            if even_enough(pack_spread, density_spread(self.group)):
                self._write(pack)
                self.unwrapper = LIGHTMAP_PACK
        else:
            self._write(smart)
        return smart_fill, packed

    def _write(self, uvs):
        """The copies' UVs (:meth:`_uvs`) into their meshes' "Lightmap" layers (each copy loop to its original),
        remembered as a layout without overlapping charts (:func:`_disjoint`)."""
        for (o, obj), (uv, *_), loops in zip(self.copies, uvs, self.loops):
            out = np.empty_like(uv).reshape(-1, 2)
            out[loops] = uv.reshape(-1, 2)
            _write_layer(self.state, o.data, out.ravel())
            _disjoint(triangles_uv(o, LIGHTMAP))

    @staticmethod
    def _uvs(temps):
        """[(flat float32 "Lightmap" UVs, each loop's next loop in its face, each face's first loop)] of the copies."""
        out = []
        for obj in temps:
            me = obj.data
            uv = np.zeros(len(me.loops) * 2, np.float32)
            me.uv_layers[LIGHTMAP].data.foreach_get("uv", uv)
            start, total = np.zeros(len(me.polygons), np.int64), np.zeros(len(me.polygons), np.int64)
            me.polygons.foreach_get("loop_start", start)
            me.polygons.foreach_get("loop_total", total)
            nxt = np.arange(len(me.loops)) + 1
            nxt[start + total - 1] = start
            out.append((uv, nxt, start))
        return out


def _canonical_copy(me, tmp, scale, weld=True):
    """Fill the empty mesh ``tmp`` with ``me``'s vertices (× ``scale``) and faces, every face starting at its
    lowest vertex index and the faces sorted by their first three vertices (then corner count, then their order),
    all revealed and selected (through bmesh: see the module's note on ``.select_edge``); return, for each of
    ``tmp``'s loops, ``me``'s loop it copies, and whether ``weld`` joined any vertices at one position
    (:func:`_welded`).

    The unwrappers' layouts depend on face order and on each face's first corner: Blender 5.3's UV sphere
    primitive makes the same faces in a different order in every process, and Smart UV Project then packs
    different charts; on the canonical copy the same vertices and faces give the same layout."""
    nv, nl, nf = len(me.vertices), len(me.loops), len(me.polygons)
    co = np.zeros(nv * 3, np.float32)
    me.vertices.foreach_get("co", co)
    lv = np.zeros(nl, np.int64)
    me.loops.foreach_get("vertex_index", lv)
    start, total = np.zeros(nf, np.int64), np.zeros(nf, np.int64)
    me.polygons.foreach_get("loop_start", start)
    me.polygons.foreach_get("loop_total", total)
    welded_co, welded_lv = _welded(co, lv, start, total) if weld else (co, lv)
    changed = welded_lv is not lv
    co, lv, nv = welded_co, welded_lv, len(welded_co) // 3
    if nf:
        face_of = np.repeat(np.arange(nf), total)          # face offsets ascend (Blender 4+)
        low = np.full(nf, np.iinfo(np.int64).max)
        np.minimum.at(low, face_of, lv)
        first = np.full(nf, np.iinfo(np.int64).max)
        np.minimum.at(first, face_of, np.where(lv == low[face_of], np.arange(nl), np.iinfo(np.int64).max))
        rot = first - start
        corner = [lv[start + (rot + k) % total] for k in range(3)]
        perm = np.lexsort((total, corner[2], corner[1], corner[0]))
    else:
        rot, perm = np.zeros(0, np.int64), np.zeros(0, np.int64)
    new_total = total[perm]
    new_start = np.concatenate([[0], np.cumsum(new_total)[:-1]]).astype(np.int64) if nf else new_total
    face = np.repeat(np.arange(nf), new_total)
    k = np.arange(nl) - new_start[face]
    f = perm[face]
    loops = start[f] + (rot[f] + k) % total[f]
    tmp.vertices.add(nv)
    tmp.vertices.foreach_set("co", co * np.float32(scale))
    tmp.loops.add(nl)
    tmp.loops.foreach_set("vertex_index", lv[loops])
    tmp.polygons.add(nf)
    tmp.polygons.foreach_set("loop_start", new_start)
    tmp.update(calc_edges=True)
    bm = bmesh.new()
    try:
        bm.from_mesh(tmp)
        for seq in (bm.verts, bm.edges, bm.faces):
            for item in seq:
                item.hide = False
                item.select = True
        bm.to_mesh(tmp)
    finally:
        bm.free()
    while len(tmp.uv_layers):
        tmp.uv_layers.remove(tmp.uv_layers[0])
    return loops, changed


def _welded(co, lv, start, total):
    """(positions, loop vertices) of the unwrap copy: every vertex replaced by the first vertex at its position
    (``first_at_position``), so that a triangle soup (an imported mesh whose faces share no vertex) is unwrapped as
    the surface it is. Measured on the level benchmark's 1,280-triangle soup: 1,280 one-triangle charts become 6,
    and the quick level's atlas covers 0.63 of its map instead of 0.49.

    A face that would repeat a vertex keeps its own vertices. The k-th face over the same welded vertices (a
    double-sided copy, a duplicate) is welded into a k-th copy of the vertices, so that faces over the same
    vertices never join one surface (joined, Smart UV Project lays them over each other or fails to fit a map);
    faces that cover each other but are split differently are caught after the unwrap (:func:`_unwrap_with_margin`).
    Meshes without coincident vertices are unchanged (their layouts too)."""
    nv = len(co) // 3
    if not len(lv):
        return co, lv
    rep = first_at_position(co)
    if np.array_equal(rep, np.arange(nv)):
        return co, lv
    welded = rep[lv]
    nf = len(start)
    face_of = np.repeat(np.arange(nf), total)
    order = np.lexsort((welded, face_of))
    ws, fs = welded[order], face_of[order]
    repeat = np.zeros(nf, bool)
    repeat[fs[1:][(ws[1:] == ws[:-1]) & (fs[1:] == fs[:-1])]] = True
    width = int(min(total.max(), _FACE_KEY))
    rank = np.arange(len(lv)) - start[fs]          # each corner's place among its face's sorted vertices
    key = np.full((nf, width + 2), -1, np.int64)
    keep = rank < width
    key[fs[keep], rank[keep]] = ws[keep]
    key[:, width] = total
    key[:, width + 1] = np.bincount(face_of, welded, nf).astype(np.int64)
    key[repeat, width] = -2 - np.flatnonzero(repeat)            # never a duplicate of another face
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.ravel()
    by_group = np.argsort(group, kind="stable")
    g = group[by_group]
    run_start = np.r_[0, np.flatnonzero(g[1:] != g[:-1]) + 1]
    seen = np.zeros(nf, np.int64)                     # earlier faces over the same vertices
    seen[by_group] = np.arange(nf) - np.repeat(run_start, np.diff(np.r_[run_start, nf]))
    corner_copy = np.where(repeat, -1, seen)[face_of]
    vertex = np.where(corner_copy < 0, lv, welded)
    _, first, ids = np.unique(np.stack([vertex, corner_copy], 1), axis=0, return_index=True, return_inverse=True)
    return co.reshape(-1, 3)[vertex[first]].ravel(), ids.ravel()


_FACE_KEY = 16
"""Sorted vertices of a face that tell duplicates apart (with its corner count and vertex sum): a longer face
matching another on them only goes to another copy of the vertices."""


@contextlib.contextmanager
def _edit(ctx, lead):
    """The copies in one multi-object edit session (back in object mode also on errors)."""
    with bpy.context.temp_override(**ctx):
        bpy.ops.object.mode_set(mode="EDIT")
    try:
        with bpy.context.temp_override(edit_object=lead, **ctx):
            yield
    finally:
        with bpy.context.temp_override(**ctx):
            bpy.ops.object.mode_set(mode="OBJECT")


def _copy_triangles(me):
    """(T, 3) loop indices of mesh ``me``'s loop triangles."""
    me.calc_loop_triangles()
    loops = np.zeros(len(me.loop_triangles) * 3, np.int64)
    me.loop_triangles.foreach_get("loops", loops)
    return loops.reshape(-1, 3)


def _covered(uvs, tris, side, loops):
    """Texel centres of a ``side``² map inside the charts of :meth:`_Copies._uvs` arrays carried to the original
    meshes' loops (``loops``: per copy, the original loop of each of its loops) and their loop triangles ``tris``, -1
    when a UV lies outside the unit square (the packer failed)."""
    parts = []
    for (uv, *_), t, back in zip(uvs, tris, loops):
        out = np.empty_like(uv).reshape(-1, 2)
        out[back] = uv.reshape(-1, 2)
        parts.append(out[t])
    tri = np.concatenate(parts)
    if _outside(tri):
        return -1
    return int(lightmap.coverage_mask(tri, side, side).sum())


def resolution(objects, layers, options, coverage=None):
    """Map side for the objects sharing one map: the fixed resolution, or N = T √(A / coverage) from the
    texel density T, the world area A and the UV coverage of their layers (``coverage`` overrides it)."""
    if options.texel_density is None:
        return int(options.resolution)
    area = sum(world_area(o) for o in objects)
    if coverage is None:
        coverage = sum(chart_area(triangles_uv(o, layers[o.name])) for o in objects)
    return lightmap.resolution_for_density(area, min(coverage, 1.0), options.texel_density, options.max_resolution)
