"""Making a group's light-map layout in its meshes' "Lightmap" layers: Smart UV Project (66°, or :data:`WIDE_ANGLE`
for a single mesh that fills under ``uvchecks.FILL``), or a single mesh's Lightmap Pack, each kept when it fills more
of the map as evenly (:func:`even_enough`); packed with a margin of ``margin`` texels (a fraction of the map: charts
lie 2 × margin apart, so the dilation never reaches a neighbour), halved down to half a texel until the charts lie
inside the unit square and cover the map (``uvchecks.MIN_COVERAGE``), at the side a texel density asks
(:func:`_search`); an atlas's layout, and a single mesh's that still fills under ``uvchecks.FILL``, then has its charts
placed again by their texels (:meth:`_Copies.try_raster_pack`, :mod:`core.pack`), and a single mesh's still under it
its charts joined and unwrapped again (:meth:`_Copies.try_merged`, :mod:`core.merging`); a dense mesh is also unwrapped
smoothed below the map's resolution (:meth:`_Copies.try_smoothed`). The unwrappers run on temporary canonical copies
(:class:`_Copies`, :func:`unwrap_copy.canonical_copy`): the user's meshes never enter edit mode and their select / hide
flags are never written, only the finished UVs are copied into their "Lightmap" layer (the other layers, the active one
and the one that renders stay as they were).
"""
import contextlib
import io
import math
import warnings

import bpy
from mathutils import Matrix
import numpy as np

from ..blender.scene import corner_triangles, corner_uv, corner_vertices, positions
from ..blender.state import remove_ids
from ..core import lightmap, merging, pack
from ..core.errors import InputError
from . import unwrap_merge, uvchecks
from .options import article
from .uv import (LIGHTMAP, MAX_UV_LAYERS, _Made, _dilation, _say_enlarged, _write_layer, fixed_side, own_layers,
                 resolution, triangles_uv, world_area, world_triangles)
from .unwrap_copy import Stretches, canonical_copy, smoothed_copy, unwrap_scale
from .uvchecks import (MIN_COVERAGE, _disjoint, _fits, _outside, _overlap, _overlapping, baked_fill, chart_area,
                       density_spread)

SMART, LIGHTMAP_PACK = "smart_project", "lightmap_pack"
"""The unwrappers a generated layout comes from (the report entries' "unwrap")."""
RASTER = "+raster_pack"
"""Added to the unwrapper's name when its charts were placed again by their texels (:mod:`core.pack`)."""
MERGED = "+merged_charts"
"""Added to the unwrapper's name when its charts were joined and unwrapped again (:mod:`core.merging`)."""
OWN = "own_uv"
"""A layout made of the charts of one of the mesh's own UV layers (:meth:`_Copies.try_own_layers`), always with
RASTER."""
CUT = "+cut_charts"
"""Added to OWN when its long charts were cut into pieces that stack (:func:`core.merging.cut_long`)."""
CUTS = (None, 3, 4)
"""The cuts of an own layer's long charts tried at a fixed side (:func:`core.merging.cut_long`'s ``pieces``; None:
the square stack, the only one tried with a texel density, whose window takes a strip's shape). A UV sphere's grid,
1.63 times longer than high, in 4 pieces: 0.500 -> 0.614 of a 128² map (2 pieces 0.45, 3 pieces 0.53)."""
STACKED = (0.85, 0.7)
"""The fills of the squares a texel-density map of cut charts is also packed in (:func:`core.pack.lowest`)."""
UNWRAPPERS = (SMART, LIGHTMAP_PACK, SMART + RASTER, LIGHTMAP_PACK + RASTER, SMART + MERGED + RASTER,
              LIGHTMAP_PACK + MERGED + RASTER, OWN + RASTER, OWN + CUT + RASTER, OWN + MERGED + RASTER)
PACK_CHARTS = 4096
PACK_WORK = 2_000_000
"""Most charts, and charts × map side, a layout is packed again for (:meth:`_Copies.try_raster_pack`; the packer
searches each chart's place in bands of rows across the map: a subdivided Suzanne's 64 charts at 256² take 2.7 s,
the quick level's atlas (270 charts, 217²) 1.0 s, 24,401 charts at 620² 44 s)."""
ANGLE = 1.15192
"""Smart UV Project's angle limit (66°, its default)."""
WIDE_ANGLE = math.radians(75)
"""The angle limit also tried on a single mesh's layout that fills under uvchecks.FILL (:meth:`_Copies.try_wide_angle`):
fewer, larger charts, hence fewer margins. Measured (fill of the window at the side, margin 1-2 texels; density
spread): an ico sphere (3 subdivisions) 0.44 -> 0.67 at 128², 0.32 -> 0.49 at 64², spread 0.92 both; a torus 0.31
-> 0.39 at 128²; a UV sphere 0.69 -> 0.55 and a cylinder unchanged (kept at 66°). 85° and 89° fill more by
foreshortening: spread 0.35-0.75."""
SMOOTH_OVERLAP = 0.001
"""Texels under several faces a smoothed layout may have (a tenth of uvchecks.MAX_OVERLAP, where a bake warns) when
the layout it replaces has fewer: the full level's atlas with its scan smoothed shares 1.0e-4 of its texels against
3.1e-5, and fills 0.76 of its map against 0.57."""
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
MERGE_SIDE = 32
"""Least side of a map whose layout's charts are joined (:meth:`_Copies.try_merged`). Measured on the full level's
props (maps 10-60 texels wide, 2-texel margins): joins on every map raised the median fill 0.359 -> 0.387 (200 of
207 maps still under 55 %, each with its line) for 6.1 s of the first run, 5.6 s of it on maps 16-31 texels wide:
outside / inside Cycles at 64 spp 1.15 against the target's 1."""
MERGE_LIGHTMAP_PACK_FACES = 1000
MERGE_LIGHTMAP_PACK_SIDE = 64
"""Most faces of a mesh, and least side of its map, for which Lightmap Pack's charts (one a face or two) are also
joined (:meth:`_Copies.try_merged`): each round's unwrap handles one island a pair, about 0.1 ms an island (a
1,152-face torus joined from its faces: 0.7 s at a 22² map, mostly the unwraps). Measured on the full level's props
(maps 10-60 texels wide): joins from Lightmap Pack won no map there and took 16 s of the 22 s the joins took; on the
primitives at 128²-512² they give the torus's, Suzanne's and the ico sphere's best layouts."""
OWN_FLOOR = 0.25
"""Least texel density of a triangle of a mesh's own layer's layout over the median (a texture unwrap shrinks hidden
faces to next to nothing: they would get no texel of their own)."""
OWN_ANISOTROPY = 1.5
"""Most texel anisotropy (:func:`core.lightmap.texel_anisotropy`) of a layout of a mesh's own layer once its charts
are made isotropic (``uv.REUSE_ANISOTROPY``'s bound; a UV sphere's grid 1.2 at 128²: its rows near the poles keep
texels narrower around than high, which no linear map of the chart undoes)."""
MIN_CHART_AREA = 0.2
"""A margin is lowered (down to half a texel) until the charts fill at least this fraction of the map: a
margin wider than that wastes most texels of a small map."""


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


def _unwrap_with_margin(group, state, options, names, linears=None):
    """Generate "Lightmap" for ``group``; return its :class:`_Made` (side, margin in texels, unwrapper): by
    :func:`_search` on copies whose coincident vertices are welded (:func:`unwrap_copy.welded_vertices`), or again on
    copies as the meshes are when the weld joined faces that cover each other (the welded layout fails, or puts texels
    of a welded object under several of its faces: MAX_OVERLAP at the map's side, up to OVERLAP_SIDE; an object the weld
    left as it was lays out alike either way); the warnings of the layout not kept are dropped."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        try:
            made, welded = _search(group, state, options, names, weld=True, linears=linears), None
        except InputError as e:
            made, welded = None, e
    if made is not None and not (made.welded and _overlapping(made.welded, made.side)):
        for w in said:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        return made
    if made is None and welded is not None and not getattr(welded, "welded", False):
        raise welded
    return _search(group, state, options, names, weld=False, linears=linears)


def _search(group, state, options, names, weld=True, linears=None):
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
    with _Copies(group, state, weld, texel_size(group, options, fixed), linears, options.atlas) as copies:
        try:
            made = _search_copies(copies, group, options, names, label, fixed)
        except InputError as e:
            e.welded = copies.welded
            raise
        made.welded = copies.welded
        return made


def _search_copies(copies, group, options, names, label, fixed):
    """The search of :func:`_search` on the open ``copies`` (``fixed``: the fixed side, or None); the layout of the
    side found is then packed again by its texels where that fills more (:meth:`_Copies.try_raster_pack`)."""
    if fixed:
        margin = _fit(copies, group, fixed, options.margin, cut=False)
        if margin is None:
            need = _fit_side(copies, group, fixed)
            hint = (f"use a resolution of at least {need}" if need else
                    "the charts do not fit even the largest map: bake the parts separately")
            raise InputError(f"{label}: the light-map charts do not fit {article(f'{fixed}x{fixed}')} map (they would "
                             f"cover under {100 * MIN_COVERAGE:.0f} % of their UV area; {copies.per_texel(fixed)}): "
                             f"{hint}")
        copies.try_raster_pack(fixed, margin, cut=False)
        copies.try_own_layers(fixed, margin, cut=False)
        copies.try_merged(fixed, margin, cut=False)
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
                             f"of their UV area; {copies.per_texel(side)}): raise the maximum resolution or the "
                             f"texel density")
        _say_enlarged(label, asked, side)
        made = side
    else:
        asked = 0
    side = made
    copies.try_raster_pack(side, margin, cut=True)
    copies.try_own_layers(side, margin, cut=True)
    copies.try_merged(side, margin, cut=True)
    return _Made(side, _dilation(label, options.margin, margin, side), copies.unwrapper, asked)


def texel_size(group, options, fixed):
    """The size in metres of a texel of the group's map: 1 / the texel density, or at a fixed side the size at
    which the group's world area fills uvchecks.FILL of the map (what the smoothing of :class:`_Copies` needs)."""
    if not fixed:
        return 1.0 / float(options.texel_density)
    return math.sqrt(sum(world_area(o) for o in group) / (uvchecks.FILL * fixed * fixed))


def _fit(copies, group, side, margin, cut):
    """Unwrap at ``side`` with the largest margin (texels) of :func:`_margins` whose layout fits and whose charts fill
    at least MIN_CHART_AREA of the map (else the fitting layout that fills most; when no layout of the copies as they
    are fits, the dense copies are smoothed at once, :meth:`_Copies.use_smoothed`); leave it in place and return that
    margin, or None when none fits. A single mesh's layout is then also tried by Smart UV Project at WIDE_ANGLE
    (:meth:`_Copies.try_wide_angle`) and by Lightmap Pack with that margin (:meth:`_Copies.try_lightmap_pack`), and the
    layout with the dense copies smoothed (:meth:`_Copies.try_smoothed`), each kept when it fills more of the map as it
    is baked (``cut``: cut to its window, :func:`baked_fill`)."""
    best = _fit_margins(copies, group, side, margin)
    if best is None and copies.smoothed is None and any(copies.smooth):    # no layout of the dense copies fits
        copies.smoothed = True
        copies.use_smoothed(True)
        best = _fit_margins(copies, group, side, margin)
        if best is None:
            copies.smoothed = None
            copies.use_smoothed(False)
    if best is None:
        return None
    copies.try_wide_angle(margin_fraction(best[0], side), side, best[0], cut)
    copies.try_lightmap_pack(margin_fraction(best[0], side), side, best[0], cut)
    copies.try_smoothed(margin_fraction(best[0], side), side, best[0], cut)
    return best[0]


def _fit_margins(copies, group, side, margin):
    """The layout of the largest margin (texels) of :func:`_margins` that fits at ``side`` and fills at least
    MIN_CHART_AREA (else the fitting one that fills most), left in place: (margin, chart area), or None."""
    best = None
    for m in _margins(margin):
        copies.unwrap(margin_fraction(m, side), side)
        if _fits(copies, group, side):
            area = sum(chart_area(triangles_uv(o, LIGHTMAP)) for o in group)
            if area >= MIN_CHART_AREA:
                return m, area
            if best is None or area > best[1]:
                best = (m, area)
    if best is not None and best[0] != _margins(margin)[-1]:
        copies.unwrap(margin_fraction(best[0], side), side)
    return best


def _fit_side(copies, group, side):
    """Smallest 2^k · side whose half-texel layout fits, or None."""
    while side < lightmap.MAX_RESOLUTION:
        side = min(2 * side, lightmap.MAX_RESOLUTION)
        copies.unwrap(margin_fraction(0.5, side), side)
        if _fits(copies, group, side):
            return side
    return None


class _Copies:
    """Temporary objects with canonical copies of the group's meshes (:func:`unwrap_copy.canonical_copy`: all faces
    revealed and selected, one UV layer, scaled by :func:`unwrap_copy.unwrap_scale`, faces in an order given by their
    vertices), where the unwrappers run; :meth:`unwrap` copies the result into each mesh's "Lightmap" layer (through the
    copy's map to the original loops). ``unwrapper`` names the layout in place (SMART or LIGHTMAP_PACK). A copy whose
    edges are shorter than a texel of ``texel`` metres is also unwrapped smoothed below the map's resolution
    (:meth:`try_smoothed`). The copies live in a scene of their own, removed with them on exit (also on errors): the
    user's scene, its selection and its depsgraph never see them, and an edit session or a removal costs what it costs
    in an empty scene (measured in the full level's scene: an unwrap of a quad with its two mode switches 2.9 -> 0.5 ms,
    a removal with the view layer's update 7.4 -> 0.9 ms)."""

    def __init__(self, group, state, weld=True, texel=None, linears=None, atlas=False):
        self.group, self.state, self.weld, self.texel = list(group), state, weld, texel
        self.atlas = atlas           # an atlas's layout (of one object too) never takes the meshes' own layers
        self.linears = linears   # per copy: its stretch (unwrap_copy.Stretches.of; made here when not given)
        self.scratch = None      # the scene the copies live in (the user's scene and its depsgraph never see them)
        self.copies = []
        self.loops = []          # per copy: the original mesh's loop of each of the copy's loops
        self.unwrapper = SMART
        self.welded = []         # the objects whose copies the weld joined vertices of
        self.angle = None        # Smart UV Project's angle limit once :meth:`try_wide_angle` decided it
        self.smooth = []         # per copy: its Smoothing when it is dense, else None
        self.smoothed = None     # the copies' unwraps use the smoothed positions, once :meth:`try_smoothed` decided
        self.placed = ()         # per copy: its smoothed positions are in place
        self.layouts = {}        # a single copy's Smart UV Project layouts (:meth:`unwrap`), the oldest dropped

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
            self.scratch = self.state.track(bpy.data.scenes, bpy.data.scenes.new("IL unwrap"))
            shared = Stretches()
            linears = self.linears or [shared.of(o, len(self.group) > 1) for o in self.group]
            scale = unwrap_scale([o.data for o in self.group], linears)
            for o, stretched in zip(self.group, linears):
                tmp = self.state.track(bpy.data.meshes, bpy.data.meshes.new(f"IL unwrap {o.data.name}"))
                loops, welded = canonical_copy(o.data, tmp, scale, self.weld, stretched)
                matrix = o.matrix_world.copy()
                if stretched is not None:            # the copy's world is the object's: M S⁻¹ on S-stretched vertices
                    matrix = matrix @ Matrix(np.linalg.inv(stretched).tolist()).to_4x4()
                self.smooth.append(smoothed_copy(tmp, matrix, scale, self.texel))
                self.loops.append(loops)
                if welded:
                    self.welded.append(o)
                tmp.uv_layers.new(name=LIGHTMAP, do_init=False)
                tmp.uv_layers.active_index = 0
                obj = self.state.track(bpy.data.objects, bpy.data.objects.new(f"IL unwrap {o.name}", tmp))
                obj.matrix_world = matrix
                self.scratch.collection.objects.link(obj)
                self.copies.append((o, obj))
            self.placed = (False,) * len(self.copies)
        except BaseException:
            self._remove()
            raise
        return self

    def __exit__(self, *exc):
        self._remove()
        return False

    def per_texel(self, side):
        """'N triangles, t texels each' of the copies in a side² map: the cause a refusal names."""
        tris = sum(len(obj.data.loops) - 2 * len(obj.data.polygons) for _, obj in self.copies)
        each = side * side / max(tris, 1)
        return f"{tris:,} triangles, {f'{each:,.0f}' if each >= 100 else f'{each:.2g}'} texels each"

    def use_smoothed(self, smoothed):
        """Put the dense copies' smoothed (or own) positions in place (``placed``: per copy, smoothed ones)."""
        for (_, obj), dense in zip(self.copies, self.smooth):
            if dense is not None:
                obj.data.vertices.foreach_set("co", dense.positions(smoothed))
                obj.data.update()
        self.placed = tuple(bool(smoothed) and dense is not None for dense in self.smooth)

    def try_smoothed(self, margin_uv, side, margin, cut):
        """When a copy is dense (:func:`unwrap_copy.smoothed_copy`): the unwrap again with the dense copies smoothed, at
        the same margin and angle. Each layout is first packed by its texels as the search would end it
        (:meth:`try_raster_pack`: a scan's thousands of tiny charts fill the gaps between an atlas's boxes with texels
        of no use, which their boxes alone would count as fill); the smoothed one is kept when it fits a ``side``² map,
        fills more of it as baked (:func:`baked_fill`), its texel density is as even (:func:`even_enough`: smoothing
        rounds a dense hard-surface mesh's edges, and its faces there get fewer texels) and no more of its texels lie
        under several faces (or at most SMOOTH_OVERLAP). A copy whose own texels come to lie under several of its faces
        (more than uvchecks.MAX_OVERLAP; smoothed over its features) is unwrapped as it is, the others smoothed again.
        Decided once per copies, at the first side the search tries."""
        if self.smoothed is not None or not any(self.smooth):
            return
        self.try_raster_pack(side, margin, cut)
        have = baked_fill(self.group, side, margin, cut)
        spread, shared = density_spread(self.group), _overlap(self.group, side)
        clear = [not _overlapping([o], side) for o in self.group]
        before, unwrapper = self._kept(), self.unwrapper
        self.use_smoothed(True)
        self.unwrap(margin_uv, side)
        folded = [i for i, o in enumerate(self.group) if self.smooth[i] and clear[i] and _overlapping([o], side)]
        if folded:                 # smoothed over their features (a small prop's ears): unwrapped as they are
            self.use_smoothed(False)
            for i in folded:
                self.smooth[i] = None
            if not any(self.smooth):
                self._restore(before, unwrapper)
                self.smoothed = False
                return
            self.use_smoothed(True)
            self.unwrap(margin_uv, side)
        self.try_raster_pack(side, margin, cut)
        if (_fits(self, self.group, side) and baked_fill(self.group, side, margin, cut) > have
                and even_enough(density_spread(self.group), spread)
                and _overlap(self.group, side) <= max(shared, SMOOTH_OVERLAP)):
            self.smoothed = True
            return
        self.use_smoothed(False)
        self._restore(before, unwrapper)
        self.smoothed = False

    def _kept(self):
        """[(flat float32 UVs,)] per copy of the layout kept so far, in the copy's loop order, read from the user's
        meshes (a copy may still hold a layout a try did not keep: Lightmap Pack's, an atlas's last re-pack)."""
        return [(corner_uv(o.data, LIGHTMAP)[loops].astype(np.float32).ravel(),)
                for (o, _), loops in zip(self.copies, self.loops)]

    def _restore(self, before, unwrapper):
        """Put back the layout ``before`` (:meth:`_kept`) made by ``unwrapper``, in the copies and the meshes."""
        self.unwrapper = unwrapper
        for (_, obj), (uv, *_) in zip(self.copies, before):
            obj.data.uv_layers[LIGHTMAP].data.foreach_set("uv", uv)
        self._write(before)

    def _remove(self):
        tracked = [pair for _, obj in self.copies for pair in ((bpy.data.objects, obj), (bpy.data.meshes, obj.data))]
        remove_ids(tracked + ([(bpy.data.scenes, self.scratch)] if self.scratch is not None else []))
        self.scratch = None
        self.copies = []
        self.loops = []

    REPACKS = 3
    """Most re-packs of an atlas layout by ``uv.pack_islands`` (each kept only when it covers more texels)."""
    LAYOUT_BYTES = 64 << 20
    """Most bytes of layouts :meth:`unwrap` remembers (a scan of a million corners: 8 MB a layout)."""

    def unwrap(self, margin_uv, side, angle=None):
        """Smart UV Project of every copy in one edit session (one UV square) into "Lightmap"; for several copies
        (an atlas) the charts are then re-packed by ``uv.pack_islands`` (bounding boxes, rotation, the same margin
        as a fraction of the map) while a re-pack covers more texel centres of a ``side``² map (up to REPACKS
        times), so the layout kept covers at least as many as ``pack_islands`` of it. Measured on the quick level's
        atlas (29 meshes, 273², 1-texel margins): convex and concave shapes cover the same texels as bounding boxes
        for 10x the time; margin_method ADD or SCALED does not keep the margin in texels. ``angle``: Smart UV
        Project's angle limit (radians, ANGLE by default). A single copy's layout is remembered by its positions,
        angle and margin (Smart UV Project makes the same one again: the quick level's search asks 25 of its 174
        unwraps twice, a margin of 1 texel at a side of 7 is one of 2 at 14)."""
        temps = [obj for _, obj in self.copies]
        lead = temps[0]
        self.unwrapper = SMART
        key = (self.placed, angle or self.angle or ANGLE, float(margin_uv))
        if len(temps) == 1 and key in self.layouts:
            best = self.layouts[key]
            lead.data.uv_layers[LIGHTMAP].data.foreach_set("uv", best[0][0])
            self._write(best)
            return
        ctx = self._context()
        with _edit(ctx, lead):
            bpy.ops.uv.smart_project(angle_limit=key[1], island_margin=key[2],
                                     margin_method="FRACTION", area_weight=0.0, correct_aspect=True,
                                     scale_to_bounds=False)
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
        else:
            best[0][0].flags.writeable = False
            self.layouts[key] = best
            while sum(layout[0][0].nbytes for layout in self.layouts.values()) > self.LAYOUT_BYTES:
                del self.layouts[next(iter(self.layouts))]
        self._write(best)

    def _context(self):
        """The copies selected (and nothing else), the first active: the context override of their edit session."""
        vl = self.scratch.view_layers[0]
        temps = [obj for _, obj in self.copies]
        for o in filter(None, vl.objects):
            want = o in temps
            if o.select_get(view_layer=vl) != want:
                o.select_set(want, view_layer=vl)
        lead = temps[0]
        vl.objects.active = lead
        return dict(scene=self.scratch, view_layer=vl, active_object=lead, object=lead,
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
        if have >= uvchecks.FILL:
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
        pack = self._lightmap_packed(margin_uv)
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

    def _lightmap_packed(self, margin_uv):
        """Blender's Lightmap Pack of the (single) copy with margin ``margin_uv`` (at most _LIGHTMAP_PACK_MAX_MARGIN),
        left in the copy: [(flat float32 UVs,)]."""
        # in object mode it unwraps the selected objects (in edit mode the window's scene's objects in edit mode,
        # not the context's: a bake of another scene than the window's would find none); it prints its steps
        with bpy.context.temp_override(**self._context()), contextlib.redirect_stdout(io.StringIO()):
            # the operator's margin is a percentage p of the square, applied as 1 / int(100 / p): at least p / 100
            bpy.ops.uv.lightmap_pack(PREF_CONTEXT="ALL_FACES", PREF_PACK_IN_ONE=True, PREF_NEW_UVLAYER=False,
                                     PREF_BOX_DIV=12, PREF_MARGIN_DIV=float(100.0 * margin_uv))
        return self._uvs([self.copies[0][1]])

    def try_raster_pack(self, side, margin, cut):
        """For an atlas, or one copy whose layout fills under FILL of its map as baked (:func:`baked_fill`): the charts
        of the layout in place (of every copy of an atlas) placed again by their texels (:meth:`_raster_packed`). Kept
        when it fits and fills more of its map as baked. The texel density stays as even (one scale for every chart)
        and no chart comes nearer another than the unwrappers' margins let it."""
        if self.unwrapper.endswith(RASTER):
            return
        have = baked_fill(self.group, side, margin, cut)
        if have >= uvchecks.FILL and len(self.copies) == 1:
            return
        layouts = [corner_uv(o.data, LIGHTMAP)[loops] for (o, _), loops in zip(self.copies, self.loops)]
        new = self._raster_packed(layouts, side, margin, cut)     # the layout kept so far (a copy may hold another)
        if new is None:
            return
        self._write(new)
        if _fits(self, self.group, side) and baked_fill(self.group, side, margin, cut) > have:
            for (_, obj), (uv,) in zip(self.copies, new):
                obj.data.uv_layers[LIGHTMAP].data.foreach_set("uv", uv)
            self.unwrapper += RASTER
            return
        self._write([(uv.ravel(),) for uv in layouts])

    def _raster_packed(self, layouts, side, margin, cut, squares=()):
        """The copies' corner UVs ``layouts`` (per copy (N, 2), in its loop order) with their charts (as the welded
        copies join them) placed again by their texels with the same margin, [(flat float32 UVs,)] per copy, or None
        (more than PACK_CHARTS charts, charts × map side over PACK_WORK, or no place): at a fixed side scaled as far
        as they fit (:func:`core.pack.largest`), with a texel density (``cut``) at their size in the fewest rows they
        fit (:func:`core.pack.lowest`: the map is cut to its window, the density asked, fewer texels; also in the
        smaller squares their texels fill to ``squares``)."""
        tri, labels, charts, count = [], [], [], 0
        for (_, obj), uv in zip(self.copies, layouts):
            tris = corner_triangles(obj.data)
            corners = tris.ravel()
            label = pack.chart_labels(np.repeat(np.arange(len(tris)), 3), corner_vertices(obj.data)[corners],
                                      uv[corners])
            chart = np.full(len(uv), -1)
            chart[corners] = np.repeat(label, 3)
            if (chart < 0).any():
                return None
            charts.append(chart + count)
            tri.append(uv[tris])
            labels.append(label + count)
            count += int(label.max()) + 1 if len(label) else 0
        if not count or count > PACK_CHARTS or count * side > PACK_WORK:
            return None
        tri, labels = np.concatenate(tri), np.concatenate(labels)
        packing = pack.lowest(tri, labels, side, margin, squares) if cut else pack.largest(tri, labels, side, margin)
        if packing is None:
            return None
        return [(pack.moved(uv, chart, packing, side).astype(np.float32).ravel(),) for uv, chart in zip(layouts, charts)]

    def try_own_layers(self, side, margin, cut):
        """For one copy (whatever its layout fills: one packing a layer): the charts of each of its mesh's own UV
        layers (:func:`uv.own_layers`: an artist's or an importer's unwrap, a primitive's own grid), each made of
        square texels on average (:func:`core.lightmap.isotropic`: a torus's grid on the unit square becomes a 4 × 1
        rectangle), scaled to the UV area of the layout in place (its texel density) and placed by their texels
        (:meth:`_raster_packed`: charts stacked or mirrored onto one another get places of their own), as they are
        and with their long charts cut into pieces (:func:`core.merging.cut_long`, CUT, as many as CUTS names: that
        torus's strip in 2 pieces that stack fills 0.87 of a 256² map, against 0.22 whole and 0.48 for its merged
        Smart UV Project charts). The best is
        kept when it fits a ``side``² map, fills more of it as baked, gives every face texels
        (:func:`core.lightmap.unmapped_fraction` 0, no triangle under OWN_FLOOR of the median density), has no chart
        across an edge sharper than ``core.merging.CREASE`` (a cube's cross: its light would blend across it), texels
        square to OWN_ANISOTROPY, a texel density as even (:func:`even_enough`) and no more texels under several
        faces (a chart folded over itself). Unreal Engine makes its light-map UVs so, from UV channel 0. Not for an
        atlas (``atlas``: its key and hash leave the layers out)."""
        if len(self.copies) != 1 or self.atlas:
            return
        o = self.group[0]
        names = own_layers(o.data)
        area = lightmap.uv_area(triangles_uv(o, LIGHTMAP)) if names else 0.0
        if not area > 0:
            return
        have = baked_fill(self.group, side, margin, cut)
        before, unwrapper = self._kept(), self.unwrapper
        copy, loops = self.copies[0][1].data, self.loops[0]
        tris = corner_triangles(copy)
        surf = spread = shared = best = None
        for name in names:
            uv = corner_uv(o.data, name)[loops].astype(float)
            if not np.isfinite(uv).all():
                continue
            surf = surf or unwrap_merge.surface_of(copy)
            charts = pack.chart_labels(surf.owner, surf.vertex, uv)
            if merging.crosses_crease(surf, charts):
                continue
            uv = lightmap.isotropic(uv, tris, charts[surf.owner], positions(copy)[surf.vertex])
            own = lightmap.uv_area(uv[tris])
            if not own > 0:
                continue
            tried = []
            variants = [(uv, OWN, ())] + [(merging.cut_long(uv, surf.owner, charts[surf.owner], k), OWN + CUT, STACKED)
                                          for k in (CUTS[:1] if cut else CUTS)]
            for layout, label, squares in variants:
                if layout is None or any(np.array_equal(layout, t) for t in tried):
                    continue
                tried.append(layout)
                new = self._raster_packed([layout * math.sqrt(area / own)], side, margin, cut, squares)
                if new is None:
                    continue
                if spread is None:                  # of the layout in place, before a layer's is written
                    spread, shared = density_spread(self.group), _overlap(self.group, side)
                self._write(new)
                fill = baked_fill(self.group, side, margin, cut)
                tri_uv, tri_world = triangles_uv(o, LIGHTMAP), world_triangles(o)
                if (fill > (best[0] if best else have) and _fits(self, self.group, side)
                        and lightmap.unmapped_fraction(tri_world, tri_uv) == 0
                        and lightmap.density_floor(tri_uv, tri_world) >= OWN_FLOOR
                        and lightmap.texel_anisotropy(tri_uv, tri_world) <= OWN_ANISOTROPY
                        and even_enough(density_spread(self.group), spread) and _overlap(self.group, side) <= shared):
                    best = (fill, new, label)
        if best is None:
            self._restore(before, unwrapper)
            return
        self._restore(best[1], best[2] + RASTER)

    def try_merged(self, side, margin, cut):
        """For one copy whose layout (packed by its texels where that fills more) fills under FILL of its map (of at
        least MERGE_SIDE) as baked: its charts joined round by round (:func:`unwrap_merge.layouts`), and those of Lightmap Pack (one chart
        a face or two; a mesh of at most MERGE_LIGHTMAP_PACK_FACES whose layout is not Lightmap Pack's, on a map of
        at least MERGE_LIGHTMAP_PACK_SIDE), each round's
        layout packed by its texels (:meth:`_raster_packed`); the round that fills most is kept when it fits a
        ``side``² map, fills more of it as baked, its texel density is as even (:func:`even_enough`) and no more of
        its texels lie under several faces.
        Fewer, larger charts pay fewer margins but pack less tightly, and the fill moves from round to round, hence
        the best round, looked for from the last (fewest charts, quickest to pack) back while a round fills more
        than the one after it. Measured at 128² / 256², 4-texel margins (2 for Suzanne at 128²), fill before ->
        after: Suzanne 0.45 / 0.38 -> 0.59 / 0.56, a torus 0.45 / 0.42 -> 0.55 / 0.50, an ico sphere 0.39 / 0.46 ->
        0.50 / 0.57; a cube unchanged (its joins would cross hard edges: merging.CREASE)."""
        if len(self.copies) != 1 or side < MERGE_SIDE:
            return
        have = baked_fill(self.group, side, margin, cut)
        if have >= uvchecks.FILL:
            return
        spread, shared = density_spread(self.group), _overlap(self.group, side)
        before, unwrapper = self._kept(), self.unwrapper
        obj = self.copies[0][1]
        starts = [(before[0][0], unwrapper.split("+")[0])]
        if (not unwrapper.startswith(LIGHTMAP_PACK) and len(obj.data.polygons) <= MERGE_LIGHTMAP_PACK_FACES
                and side >= MERGE_LIGHTMAP_PACK_SIDE):
            starts.append((self._lightmap_packed(min(margin_fraction(margin, side), _LIGHTMAP_PACK_MAX_MARGIN))[0][0],
                           LIGHTMAP_PACK))
        best = None
        for start, name in starts:
            obj.data.uv_layers[LIGHTMAP].data.foreach_set("uv", start)
            later = -1.0
            for uv in reversed(unwrap_merge.layouts(obj, lambda: _edit(self._context(), obj), before[0][0])):
                new = self._raster_packed([uv], side, margin, cut)
                if new is None:
                    continue
                self._write(new)
                fill = baked_fill(self.group, side, margin, cut)
                if (fill > (best[0] if best else have) and _fits(self, self.group, side)
                        and even_enough(density_spread(self.group), spread) and _overlap(self.group, side) <= shared):
                    best = (fill, new, name)
                if fill <= later:
                    break
                later = fill
        if best is None:
            self._restore(before, unwrapper)
            return
        self._restore(best[1], best[2] + MERGED + RASTER)

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
        """[(flat float32 "Lightmap" UVs,)] of the copies (the shape :meth:`_write` takes)."""
        return [(corner_uv(obj.data, LIGHTMAP).ravel(),) for obj in temps]


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
    return corner_triangles(me).astype(np.int64)


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
