"""What is measured of a light-map layout, never changing it: the charts' UV area (:func:`chart_area`, overlapping
charts counted once), the texels they cover (:func:`coverage`, :func:`coverage_ratio`), whether they cover their faces
(:func:`check_coverage`, MIN_COVERAGE) or share texels (:func:`check_overlap`, MAX_OVERLAP), how much of the map they
fill (:func:`fill`, :func:`low_fill`, :func:`baked_fill`) and how even their texel density is
(:func:`density_spread`). Figures are remembered per layout (``core.memo.FIGURES``); warnings go through
``core.errors.warn``, refusals raise InputError.
"""
import math

import numpy as np

from ..core import errors, lightmap
from ..core.memo import FIGURES, digest
from ..core.errors import InputError
from ..blender.scene import corner_triangles, corner_vertices, positions
from . import evaluated
from ..core.margins import footprint_gap, margin_from_gap
from ..core.pack import spacing
from .charts import chart_count, first_at_position, packed_side, side_for_fill
from .options import article
from .uv import (LIGHTMAP, corners as uv_corners, group_triangles_uv, mesh_triangles_uv, triangles_uv, window,
                 world_area, world_triangles)

MIN_COVERAGE = 0.5
"""A map is accepted when its covered texels (texel centres inside a chart) are at least this fraction of
side² × the charts' UV area inside the unit square (Σ |UV triangle area|, clipped): below it, charts are
thinner than a texel and most faces get no texel of their own."""
_OUTSIDE = 1e-4       # UVs this far outside [0, 1]: the packer failed
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


def coverage(tri_uv, width, height, stored=False):
    """``lightmap.coverage_mask`` of ``tri_uv`` in a ``width`` × ``height`` map (read-only), remembered per layout and
    size (the plan, the fill check, the bake's centre mask and the files ask for the same ones); kept in the figure
    store only when ``stored`` (a baked layout at its map's size: the UV search measures many trial layouts, a byte a
    texel each, that a rerun never asks for)."""
    return FIGURES.call(lightmap.coverage_mask, np.ascontiguousarray(tri_uv), int(width), int(height), stored=stored)


def coverage_ratio(tri_uv, width, height, stored=False):
    """(covered texels / (W H × chart area), chart area); (0, 0) for charts without area."""
    area = chart_area(tri_uv)
    if area <= 0:
        return 0.0, 0.0
    return float(coverage(tri_uv, width, height, stored).sum()) / (area * width * height), area


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
        ratio, area = coverage_ratio(tri, w, h, stored=True)      # the layout baked, at its map's size
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


def check_overlap(scene, objects, layers, size):
    """Fraction of each object's covered texels shared by several faces of its evaluated mesh
    (``core.lightmap.overlap_fraction``): ``({object name: fraction}, fraction over the whole group)``.

    Measured at the map's size, scaled down to OVERLAP_SIDE. Warns above MAX_OVERLAP, naming the Array / Mirror
    modifiers whose copies repeat the base mesh's UVs (the light-map layer is made on the base mesh, so every copy gets
    the same texels; Solidify's second shell is such a copy), else too few texels for the triangles
    (:func:`too_few_texels`), else a Boolean's operand that brings its own layer (:func:`_boolean_operands`), else
    the layer itself."""
    scale = min(1.0, OVERLAP_SIDE / max(size))
    w, h = max(1, round(size[0] * scale)), max(1, round(size[1] * scale))
    depsgraph = scene.view_layers[0].depsgraph
    fractions = {}
    for o in objects:
        layer = layers[o.name]
        fractions[o.name] = frac = _rendered_overlap(o, layer, depsgraph, w, h)
        if frac <= MAX_OVERLAP:
            continue
        copies = [m for m in o.modifiers if m.type in _COPIES and m.show_render]
        if copies and FIGURES.call(lightmap.overlap_fraction, triangles_uv(o, layer), w, h) <= MAX_OVERLAP:
            kinds = " and ".join(dict.fromkeys(_COPIES[m.type] for m in copies))
            names = ", ".join(f"'{m.name}'" for m in copies)
            errors.warn(f"'{o.name}': {kinds} copies share the light-map texels ({100 * frac:.0f} % of its texels "
                        f"hold several faces, modifier {names}): apply the modifier to give each copy its own")
        elif _rendered_overlap(o, layer, depsgraph, FINE_SIDE, FINE_SIDE) <= MAX_OVERLAP:
            errors.warn(too_few_texels(o, _rendered_uv(o, layer, depsgraph), size))
        elif operands := _boolean_operands(o, layer):
            names = ", ".join(f"'{x.name}'" for x in operands)
            way = (f"apply the modifier, or leave {names} out of the bake" if layer == LIGHTMAP else
                   f"apply the modifier, or give those faces their own place in '{layer}'")
            errors.warn(f"'{o.name}': the faces its Boolean modifier takes from {names} keep their own UV layer "
                        f"'{layer}' and share texels with its faces ({100 * frac:.0f} % of its texels hold several "
                        f"faces): {way}")
        else:
            errors.warn(f"'{o.name}': faces share texels of UV layer '{layer}' ({100 * frac:.0f} % of its texels "
                        f"hold several faces, which get one value): use a layer without overlapping charts, or let "
                        f"the bake generate one")
    if len(objects) == 1:
        return fractions, fractions[objects[0].name]
    every = np.concatenate([_rendered_uv(o, layers[o.name], depsgraph) for o in objects])
    return fractions, FIGURES.call(lightmap.overlap_fraction, every, w, h)


UNMAPPED = 0.01
"""Share of an object's surface (its evaluated mesh's area) on faces without area in the light-map layer above which
a bake warns: they hold no texel of their own and read whatever texel their collapsed UVs fall on."""


_MAKERS = ("BOOLEAN", "NODES", "SOLIDIFY", "SCREW", "SKIN", "REMESH", "WIREFRAME")
"""Modifiers that make faces of their own (a cutter's, a rim, a new surface): the base mesh's UV layer gives them
the operand's UVs, collapsed ones or none."""


def check_unmapped(scene, objects, layers):
    """{object name: warning line} of ``objects`` whose evaluated faces with no UV area in their light-map layer
    (``lightmap.unmapped_fraction``) cover more than UNMAPPED of their surface, naming the modifiers of :data:`_MAKERS` as the
    likely cause (faces the base mesh's layer does not reach); each line is warned."""
    depsgraph = scene.view_layers[0].depsgraph
    lines = {}
    for o in objects:
        frac = evaluated.figure(o, depsgraph, _unmapped, layers[o.name])
        if frac is None or frac <= UNMAPPED:
            continue
        made = [m for m in o.modifiers if m.show_render and m.type in _MAKERS]
        if made:
            cause = (f"faces its modifier {', '.join(repr(m.name) for m in made)} makes, which the base mesh's layer "
                     f"does not reach: apply the modifier before baking")
        elif layers[o.name] == LIGHTMAP:
            cause = "their light-map UVs collapse to points or lines"
        else:
            cause = "their UVs collapse to points or lines: unwrap them, or let the bake generate a layer"
        lines[o.name] = (f"'{o.name}': {100 * frac:.0f} % of its surface has no place in light-map layer "
                         f"'{layers[o.name]}' ({cause})")
        errors.warn(lines[o.name])
    return lines


def _unmapped(me, layer):
    """``lightmap.unmapped_fraction`` of evaluated mesh ``me``'s loop triangles in ``layer``; None when it lacks it."""
    if layer not in me.uv_layers:
        return None
    co = positions(me)[corner_vertices(me)[corner_triangles(me)]]
    return lightmap.unmapped_fraction(co, mesh_triangles_uv(me, layer))


def _boolean_operands(obj, layer):
    """The meshes whose faces a Boolean modifier of ``obj`` (shown in renders) adds to it with their own UV layer
    ``layer`` (Blender's Boolean keeps an operand's layer of the same name on its faces: a cutter baked too brings its
    light-map layout into ``obj``'s)."""
    out = []
    for m in obj.modifiers:
        if m.type == "BOOLEAN" and m.show_render:
            ops = [m.object] if m.operand_type == "OBJECT" else list(m.collection.all_objects if m.collection else ())
            out += [x for x in ops if x is not None and x.type == "MESH" and layer in x.data.uv_layers and x not in out]
    return out


def _rendered_overlap(obj, layer, depsgraph, w, h):
    """``lightmap.overlap_fraction`` in a ``w`` x ``h`` map of the triangles Cycles bakes of ``obj``
    (:func:`_rendered_uv`), a figure of its evaluated mesh (``evaluated.figure``)."""
    frac = evaluated.figure(obj, depsgraph, _overlap_fraction, layer, w, h)
    return frac if frac is not None else FIGURES.call(lightmap.overlap_fraction, triangles_uv(obj, layer), w, h)


def _overlap_fraction(me, layer, w, h):
    """``lightmap.overlap_fraction`` of evaluated mesh ``me``'s triangles in ``layer``; None when it lacks it."""
    if layer not in me.uv_layers:
        return None
    return FIGURES.call(lightmap.overlap_fraction, mesh_triangles_uv(me, layer), w, h)


def _rendered_uv(obj, layer, depsgraph):
    """The UVs in ``layer`` of the triangles Cycles bakes of ``obj``: its evaluated mesh's (``evaluated.Triangles``),
    else its mesh's."""
    tri = evaluated.figure(obj, depsgraph, evaluated.Triangles.of, layer)
    return tri.uv if tri is not None else triangles_uv(obj, layer)


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


def _overlap(group, side):
    """Fraction of the group's "Lightmap" texels (at ``side``, up to OVERLAP_SIDE) under several of its faces."""
    s = min(int(side), OVERLAP_SIDE)
    return FIGURES.call(lightmap.overlap_fraction, group_triangles_uv(group), s, s)


MIN_SHARED = 4
"""Texels under several faces an object needs besides MAX_OVERLAP to count as overlapping (:func:`_overlapping`): a
prop a few texels wide shares one texel between two slivers of its charts at some map sides (the full level's
monkeys at 10 texels/m, 2-3 % of about 40 texels)."""


def _overlapping(group, side):
    """Some object of ``group`` has more than MAX_OVERLAP of its "Lightmap" texels, and MIN_SHARED texels or more,
    under several of its faces."""
    s = min(int(side), OVERLAP_SIDE)
    for o in group:
        tri = triangles_uv(o, LIGHTMAP)
        shared = FIGURES.call(lightmap.overlap_fraction, tri, s, s)
        if shared > MAX_OVERLAP and shared * float(coverage(tri, s, s).sum()) >= MIN_SHARED - 0.5:
            return True
    return False


FILL = 0.55
"""Covered texels / map texels a generated layout should reach; below it :func:`low_fill` warns."""
FILL_HINT = 0.5
"""The fill the suggested resolution reaches."""
HINT_SLACK = 0.05
"""For a layout already above FILL_HINT, the suggested side is the one the fill model gives for FILL and this much
more (the model's side for FILL itself where that gives none): a layout's fill moves by a few points from one side to
the next (charts joined or not, packed in other places; measured on a cylinder with 2-texel margins: 0.508 at 6
texels/m with its charts joined, then 0.505, 0.525, 0.552 at 6.84, 7.5, 8)."""
SLACK_REACH = 2.0
"""The side for HINT_SLACK more is named only up to this many times the side for FILL: beyond, the layout is near the
fill its charts' shapes allow with no margins, where the model's side runs away (a UV sphere at 256², 0.536 of its map
in 2 charts: 7,633 for 60 %, 328 for 55 %, which fills 0.567)."""

HINT_REACH = 16
HINT_SIDE = 512
HINT_WORK = 20_000
"""Where the margin model finds no side (its charts would fill under the goal with no margins at all, as packed at
this side), the side named is measured: the charts placed by their texels (:func:`charts.packed_side`) at sides up to
HINT_REACH times the map's and at most HINT_SIDE (a packing's cost grows with the square of its side), while charts ×
side is at most HINT_WORK. The level's props 15-24 texels wide, their Smart UV Project charts packed by their boxes,
were told that no resolution fills 50 %; at 128-256 they fill 0.51-0.56."""


def fill(group, width, height=None):
    """Covered texels (centre rule) / map texels of the group's "Lightmap" layers in a width x height map (square
    without ``height``)."""
    return float(coverage(group_triangles_uv(group), width, height or width).mean())


def layout_margin(group, layers, size, asked):
    """The margin (texels) the group's layers keep at a map of ``size`` (w, h), at most the ``asked`` one: the
    largest whose packing rule their charts' footprints keep (:func:`core.margins.footprint_gap`,
    :func:`core.margins.margin_from_gap`; faces join through corners at one position with equal UVs, as
    :func:`charts.chart_count` counts charts). For layers the bake did not make (an earlier bake's "Lightmap" layer
    reused, ``--uv-layer``), whose margin is not known from their making."""
    tri, vert, offset = [], [], 0
    for o in group:
        me = o.data
        tri.append(triangles_uv(o, layers[o.name]))
        vert.append(first_at_position(positions(me))[corner_vertices(me)[uv_corners(me)]] + offset)
        offset += len(me.vertices)
    asked = float(asked)
    limit = spacing(asked)
    gap = FIGURES.call(footprint_gap, np.concatenate(tri), np.concatenate(vert), int(size[0]), int(size[1]), limit)
    return min(asked, margin_from_gap(gap))


def low_fill(group, size, margin, options):
    """The warning line (also warned) when the group's generated layout fills under FILL of its map of ``size``
    (width, height: the map's final size; ``margin`` the charts' margin in its texels), else None:
    its fill, covered texels per triangle or per chart, and the side (and texel density) that reaches FILL_HINT
    (FILL from above FILL_HINT, for HINT_SLACK more) by :func:`charts.side_for_fill` (of a square map of as many
    texels), or where that finds none, measured by :func:`charts.packed_side` (HINT_REACH, HINT_WORK). The texel
    density T is the one whose layout covers that fill of such a map: covered texels = T² × world area = goal × side²
    (the layout's chart area at the side it fills, not at this side, where margins take more of it)."""
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
    per_chart, asked = covered / max(charts, 1), float(options.margin)
    need = side_for_fill(have, side, per_chart, margin, asked, goal)
    if goal == FILL and need:
        more = side_for_fill(have, side, per_chart, margin, asked, goal + HINT_SLACK)
        need = more if more and more <= SLACK_REACH * need else need
    cause = (f"{covered / max(tris, 1):.2g} texels per triangle" if covered < 4 * tris else
             f"{covered / max(charts, 1):.3g} texels per chart, {charts} charts with {margin:g}-texel margins")
    if (not need or need > lightmap.MAX_RESOLUTION) and charts * 2 * side <= HINT_WORK:
        cap = min(lightmap.MAX_RESOLUTION, HINT_REACH * side, HINT_SIDE)
        need = packed_side(group, LIGHTMAP, size, asked, goal, cap, HINT_WORK)
    if need and need <= lightmap.MAX_RESOLUTION:
        area = sum(world_area(o) for o in group)
        density = f" (about {need * math.sqrt(goal / area):.3g} texels/m)" if area else ""
        hint = f"a resolution of about {need}{density} fills {100 * goal:.0f} %"
    else:
        hint = f"no resolution was found that fills {100 * goal:.0f} % (merge or simplify the faces, or use an atlas)"
    line = f"{label}: light-map charts cover only {100 * have:.1f} % of the {w}x{h} map ({cause}); {hint}"
    errors.warn(line)
    return line


def baked_fill(group, side, margin, cut):
    """Covered texels / texels of the map the group's "Lightmap" layout made for a ``side``² map is baked into:
    the square, or with ``cut`` the window :func:`uv._cut_window` would cut (``margin`` texels around the charts)."""
    tri = group_triangles_uv(group)
    covered = float(coverage(tri, side, side).sum())
    cut = window(tri, side, margin) if cut else None
    size = cut[1] if cut is not None else (side, side)
    return covered / float(size[0] * size[1])


def density_spread(group):
    """:func:`core.lightmap.density_spread` of the group's "Lightmap" layout on its world-space triangles."""
    return lightmap.density_spread(group_triangles_uv(group),
                                   np.concatenate([world_triangles(o) for o in group]))


def _fits(copies, group, side):
    for o in group:
        tri = triangles_uv(o, LIGHTMAP)
        if _outside(tri) or coverage_ratio(tri, side, side)[0] < MIN_COVERAGE:
            return False
    return True
