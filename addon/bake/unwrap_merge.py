"""Merged charts on an unwrap copy (:mod:`core.merging`): each round marks seams between the charts as they will be
once this round's pairs are joined, unwraps the faces of its pairs with Blender's minimum-stretch unwrap (ABF where
Blender lacks it; edit mode selects by vertices, so a face whose corners all lie on the pairs' faces is unwrapped too,
and not read), and keeps the joins :func:`core.merging.chart_ok` passes. The copy's layer "Lightmap" holds each
round's unwrap; the layouts are returned, the copy's seams cleared and its faces selected again."""
import bmesh
import bpy
import numpy as np

from ..blender import chatter
from ..blender.scene import corner_triangles, corner_uv, corner_vertices, face_starts, positions
from ..core import merging
from ..core.pack import chart_labels
from ..core.smoothing import corner_next
from .uv import LIGHTMAP

ROUNDS = 10
"""Most rounds of joins (each joins up to half the charts: 100 charts become 15 in 5; from Lightmap Pack's charts
(a face or two each), a 320-face ico sphere's joins go on past the sixth round, and fill a 256² map 0.57 instead of 0.51)."""
MERGE_TRIANGLES = 10000
"""Most triangles of a copy whose charts are merged (a round's unwrap of a 1,152-face torus cut into single faces
takes 0.08 s)."""
METHOD = "MINIMUM_STRETCH" if "MINIMUM_STRETCH" in {
    e.identifier for e in bpy.ops.uv.unwrap.get_rna_type().properties["method"].enum_items} else "ANGLE_BASED"
ITERATIONS = {"iterations": 3} if METHOD == "MINIMUM_STRETCH" else {}
"""The minimum-stretch unwrap's iterations (10 by default): measured on the primitives at 128² and 256², 3 fill
within ±0.02 of 10 (each joined chart is checked for evenness either way) at 60 % of the time on a 1,152-face torus
cut into single faces (78 against 126 ms an unwrap)."""


def surface_of(me):
    """:class:`core.merging.Surface` of the copy mesh ``me`` (corners, edges as vertex pairs, loop triangles)."""
    start = face_starts(me).astype(np.int64)
    total = np.diff(np.append(start, len(me.loops)))
    owner = np.repeat(np.arange(len(start)), total)
    lv = corner_vertices(me).astype(np.int64)
    tri = corner_triangles(me).astype(np.int64)
    return merging.surface(owner, lv, lv[corner_next(start, total)], positions(me), tri, owner[tri[:, 0]])


def layouts(obj, edit, reference):
    """[corner UVs (N, 2) float32] of the copy ``obj`` after each round that joined charts, starting from
    the layout in its "Lightmap" layer, the joined charts at the UV area per 3D area of the corner UVs ``reference``
    (the layout kept, whose texel density the map is baked at; ``edit``: a context manager putting the copy in edit
    mode, ``unwrap._edit``); the layer holds the last round's raw unwrap after (the layouts are what is returned)."""
    me = obj.data
    me.calc_loop_triangles()
    if len(me.loop_triangles) > MERGE_TRIANGLES:
        return []
    surf = surface_of(me)
    uv = corner_uv(me, LIGHTMAP).astype(float)
    labels = chart_labels(surf.owner, surf.vertex, uv)
    k = merging.density(np.asarray(reference, float).reshape(-1, 2), surf)
    cursor, out = 2.0, []
    edges = _edge_keys(me, surf)
    try:
        for _ in range(ROUNDS):
            pairs = merging.pairs(surf, labels)
            if not pairs or k <= 0:
                break
            _seams(me, edges, surf, merging.joined(labels, pairs), np.isin(labels, np.array(pairs).ravel()))
            with edit(), chatter.captured():        # "Info: Object has non-uniform scale ..." kept off the output
                bpy.ops.uv.unwrap(method=METHOD, fill_holes=True, correct_aspect=True, margin=0.0, **ITERATIONS)
            uv, labels, cursor, kept = merging.placed(uv, corner_uv(me, LIGHTMAP), surf, labels, pairs, k, cursor)
            if not kept:
                break
            out.append(uv.astype(np.float32))
    finally:
        _seams(me, edges, surf, None, None)
    return out


def _edge_keys(me, surf):
    """Each bmesh edge's :class:`core.merging.Surface` edge (by its two vertices)."""
    number = {(int(a), int(b)): e for e, (a, b) in enumerate(surf.edge_vertices)}
    bm = bmesh.new()
    try:
        bm.from_mesh(me)
        return [number.get(tuple(sorted((e.verts[0].index, e.verts[1].index))), -1) for e in bm.edges]
    finally:
        bm.free()


def _seams(me, edges, surf, labels, selected):
    """Seams on the edges between faces of different ``labels`` (and on border edges), the faces ``selected`` (F,)
    selected (the unwrap's), the others not; no seams and every face selected with None. Written through bmesh (see
    :func:`unwrap_copy.canonical_copy`)."""
    if labels is None:
        seam = np.zeros(len(surf.edge_faces), bool)
    else:
        f = surf.edge_faces
        seam = (f < 0).any(axis=1) | (labels[np.maximum(f[:, 0], 0)] != labels[np.maximum(f[:, 1], 0)])
    bm = bmesh.new()
    try:
        bm.from_mesh(me)
        for e, k in zip(bm.edges, edges):
            e.seam = bool(seam[k]) if k >= 0 else True
        if selected is None:
            for seq in (bm.verts, bm.edges, bm.faces):
                for item in seq:
                    item.select = True
        else:
            for seq in (bm.verts, bm.edges):
                for item in seq:
                    item.select = False
            for f, on in zip(bm.faces, selected):
                f.select_set(bool(on))
        bm.to_mesh(me)
    finally:
        bm.free()
