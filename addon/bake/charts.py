"""Charts of a UV layout: how many there are, and the side at which they fill a map (issue 27's fill warning)."""
import math

import numpy as np

from ..blender.scene import corner_triangles, corner_uv, corner_vertices, face_starts, positions
from ..core.memo import FIGURES
from ..core.pack import chart_labels, side_that_fills
from ..core.seams import welded


def first_at_position(co):
    """For each vertex (``co`` flat or (V, 3)), the first vertex at its position (``core.seams.welded``: within 1e-6
    of the mesh's extent; itself when alone)."""
    ids = welded(co)
    _, first = np.unique(ids, return_index=True)
    return first[ids]


def chart_count(me, layer):
    """Charts (faces joined through corners at one position with equal UVs: a triangle soup's faces join as the
    unwrap's welded copy joins them) of ``layer`` in mesh ``me``."""
    n = len(me.loops)
    if not n:
        return 0
    vert = corner_vertices(me).astype(np.int64)
    poly = face_starts(me).astype(np.int64)
    return FIGURES.call(_charts, positions(me).ravel(), vert, poly, corner_uv(me, layer).ravel())


def _charts(co, vert, poly, uv):
    face = np.repeat(np.arange(len(poly)), np.diff(np.append(poly, len(vert))))
    return int(chart_labels(face, first_at_position(co)[vert], uv).max()) + 1


def side_for_fill(have, side, per_chart, margin, asked, goal):
    """Side at which a layout filling ``have`` of a ``side``² map (``per_chart`` covered texels a chart, ``margin``
    texels around each) fills ``goal`` with the ``asked`` margin, or None: each chart of s texels takes (s + 2m)²,
    so the packing's fill without margins is e = have (s + 2m)² / s²; charts grow with the side, margins stay."""
    s = math.sqrt(max(per_chart, 1e-9))
    e = have * (s + 2 * margin) ** 2 / s ** 2
    if e <= goal:
        return None
    r = math.sqrt(goal / e)
    want = 2 * max(asked, 0.5) * r / (1 - r)
    return max(side + 1, math.ceil(side * want / s))


def packed_side(group, layer, size, margin, goal, cap, work):
    """:func:`core.pack.side_that_fills` of the group's charts in ``layer`` (faces joined as :func:`chart_count`
    joins them) on a map of ``size`` (w, h; a window's UVs are taken to its texels, so the charts keep their shape in
    a square map of as many texels): the side up to ``cap`` at which they, placed by their texels with ``margin``
    texels, cover ``goal`` of the map, or None."""
    w, h = size
    side = max(1, round(math.sqrt(w * h)))
    tri, labels, count = [], [], 0
    for o in group:
        me = o.data
        tris = corner_triangles(me).astype(np.int64)
        if not len(tris):
            continue
        corners = tris.ravel()
        vert = first_at_position(positions(me))[corner_vertices(me)]
        uv = corner_uv(me, layer)
        label = chart_labels(np.repeat(np.arange(len(tris)), 3), vert[corners], uv[corners])
        tri.append(uv[tris] * (w / side, h / side))
        labels.append(label + count)
        count += int(label.max()) + 1
    if not count:
        return None
    return FIGURES.call(side_that_fills, np.concatenate(tri), np.concatenate(labels), side, float(margin),
                        float(goal), int(cap), float(work)) or None
