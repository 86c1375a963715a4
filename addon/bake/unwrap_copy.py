"""The unwrap copy of a mesh (:class:`unwrap._Copies` makes one per object of a group): its vertices and faces in a
canonical order, coincident vertices welded, scaled to about a metre, and its smoothing below the map's resolution
when it is dense. The unwrappers run on these copies; the user's meshes never enter edit mode."""
import dataclasses
import math

import bmesh
import bpy
import numpy as np

from ..blender.scene import corner_triangles, corner_vertices, positions
from ..core import smoothing
from ..core.lightmap import triangle_areas
from ..core.rows import unique_rows
from .charts import first_at_position


UNWRAP_BAND = 64.0
"""Meshes whose size (√ of their area in object space, where Smart UV Project works) lies within
[1 / UNWRAP_BAND, UNWRAP_BAND] m are unwrapped as they are; others on a copy scaled by a power of two to about
1 m. Measured: Smart UV Project loses the charts of a 1e-6 m cube and of a 1e5 m one (no chart fits any map),
1e-5 to 1e4 m unwrap alike."""


def mesh_triangles(me, linear=None):
    """(T, 3, 3) loop triangles of mesh ``me`` in object space (its own units, no transform), or with its vertices ×
    the 3 x 3 ``linear``."""
    co = positions(me).astype(float)
    if linear is not None:
        co = co @ linear.T
    return co[corner_vertices(me)[corner_triangles(me)]]


def mesh_area(me, linear=None):
    """Surface area of :func:`mesh_triangles`."""
    return float(triangle_areas(mesh_triangles(me, linear)).sum())


def unwrap_scale(meshes, linears=None):
    """The factor the unwrap copies of ``meshes`` (one UV square; each stretched by its 3 x 3 of ``linears``, None
    for none) are scaled by: 1 within UNWRAP_BAND, else the
    power of two (exact in floating point) that brings √(their total area) nearest to 1 m. Charts come out the
    same shape at any scale, so UV coverage, chart areas and the texel density (from the real world area) are
    scale-free."""
    meshes = list(meshes)
    linears = linears or [None] * len(meshes)
    size = math.sqrt(sum(mesh_area(me, lin) for me, lin in zip(meshes, linears)))
    if size <= 0 or 1.0 / UNWRAP_BAND <= size <= UNWRAP_BAND:
        return 1.0
    return 2.0 ** -round(math.log2(size))


STRETCH_TOLERANCE = 1e-6
"""A world matrix whose linear part is a rotation and one scale within this (relative) has no :func:`stretch`."""


def stretch(matrix, scaled=False):
    """The 3 x 3 stretch S of an object's world ``matrix`` M = R c S (R a rotation or a reflection, c > 0 its mean
    scale, S symmetric positive definite with det S = 1: S = P / ∛det P for P = √(MᵀM), the polar decomposition),
    or with ``scaled`` P = c S itself; None when that is the identity (within STRETCH_TOLERANCE) or M flattens an
    axis. An unwrap copy stretched by S has the object's shape in the world (up to a turn and one scale), so the
    unwrappers, which work on a mesh as it is, give a box scaled (1, 1, 4) in Object Mode four times the texels
    along its length instead of square charts, and the joins read its creases and areas as baked; the copies of an
    atlas are stretched by P, so that each object's charts also take its size in the world."""
    m = np.array(matrix, float)[:3, :3]
    lam, vec = np.linalg.eigh(m.T @ m)
    if not np.isfinite(lam).all() or lam.min() <= 1e-12 * lam.max():
        return None
    root = np.sqrt(lam)
    if not scaled:
        root /= np.cbrt(root.prod())
    if np.abs(root - 1.0).max() <= STRETCH_TOLERANCE:
        return None
    return (vec * root) @ vec.T


def same_stretch(a, b):
    """Whether two stretches (:func:`stretch`, or None) are one, to STRETCH_TOLERANCE of the larger's largest entry
    (float32 world matrices of one scale turned differently differ by their round-off)."""
    if a is None or b is None:
        return a is None and b is None
    return float(np.abs(a - b).max()) <= STRETCH_TOLERANCE * max(float(np.abs(a).max()), float(np.abs(b).max()))


class Stretches:
    """The stretch of each object's unwrap copy in one run (:func:`stretch`; ``scaled`` for an atlas). Objects that
    share a mesh share its one light-map layer: they get one only when every object of the file using that mesh
    stands stretched alike, else None (their layout is made in object space, as for a mesh of its own before the
    stretch), so that baking one never rewrites the layer another one's map was baked on. The file's objects are
    read once, when a mesh with several users is first asked about."""

    def __init__(self):
        self._users = None
        self._alike = {}

    def users(self, me):
        """The objects of the file whose data is the mesh ``me``."""
        if self._users is None:
            self._users = {}
            for o in bpy.data.objects:
                if o.type == "MESH" and o.data is not None:
                    self._users.setdefault(o.data.as_pointer(), []).append(o)
        return self._users.get(me.as_pointer(), [])

    def of(self, obj, scaled):
        """The stretch of ``obj``'s unwrap copy (duplicates compared by their shape S alone: an atlas bakes one object
        of a mesh, at its own scale)."""
        return None if self.shared_apart(obj) else stretch(obj.matrix_world, scaled)

    def shared_apart(self, obj):
        """Whether ``obj``'s mesh is shared by objects stretched differently (its layout made in object space)."""
        if obj.data.users <= 1:
            return False
        key = obj.data.as_pointer()
        if key not in self._alike:
            theirs = [stretch(o.matrix_world) for o in self.users(obj.data)]
            self._alike[key] = all(same_stretch(t, theirs[0]) for t in theirs)
        return not self._alike[key]


def canonical_copy(me, tmp, scale, weld=True, stretched=None):
    """Fill the empty mesh ``tmp`` with ``me``'s vertices (× the 3 x 3 ``stretched``, :func:`stretch`, then
    × ``scale``) and faces, every face starting at its
    lowest vertex index and the faces sorted by their first three vertices (then corner count, then their order),
    all revealed and selected; return, for each of ``tmp``'s loops, ``me``'s loop it copies, and whether ``weld``
    joined any vertices at one position (:func:`welded_vertices`).

    The flags are written through bmesh: in bpy 5.0 (``compat.MISTYPED_SELECT_EDGE``) a mesh made by
    ``Mesh.from_pydata`` (``Mesh.update(calc_edges=True)``; the torus primitive is one) carries a ``.select_edge``
    attribute typed INT32_2D instead of BOOLEAN, and ``edges.foreach_set("select", ...)`` (or ``edge.select = ...``)
    on it kills Blender with signal 11.

    The unwrappers' layouts depend on face order and on each face's first corner: Blender 5.3's UV sphere
    primitive makes the same faces in a different order in every process, and Smart UV Project then packs
    different charts; on the canonical copy the same vertices and faces give the same layout."""
    nv, nl, nf = len(me.vertices), len(me.loops), len(me.polygons)
    co = positions(me).ravel()
    lv = corner_vertices(me).astype(np.int64)
    start, total = np.zeros(nf, np.int64), np.zeros(nf, np.int64)
    me.polygons.foreach_get("loop_start", start)
    me.polygons.foreach_get("loop_total", total)
    welded_co, welded_lv = welded_vertices(co, lv, start, total) if weld else (co, lv)
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
    if stretched is not None:
        co = (co.reshape(-1, 3).astype(np.float64) @ stretched.T).astype(np.float32).ravel()
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


def smoothed_copy(tmp, matrix, scale, texel):
    """A :class:`Smoothing` of the unwrap copy ``tmp`` (vertices × ``scale`` of an object at ``matrix``) when it is
    dense: to be smoothed along its normals over two texels of ``texel`` metres, at most an eighth of its size
    (:func:`core.smoothing.steps`: its median edge in the world under about 1.4 texels); else None. Unwrapped
    smoothed, the copy is charted by the shape the map resolves; the UVs go to the real mesh, whose vertices kept
    their place on the surface (:meth:`unwrap._Copies.try_smoothed`)."""
    if not texel or not len(tmp.loops):
        return None
    co = positions(tmp).astype(np.float64)
    lv = corner_vertices(tmp).astype(np.int64)
    start, total = np.zeros(len(tmp.polygons), np.int64), np.zeros(len(tmp.polygons), np.int64)
    tmp.polygons.foreach_get("loop_start", start)
    tmp.polygons.foreach_get("loop_total", total)
    nxt = smoothing.corner_next(start, total)
    world = co @ (np.array(matrix, float)[:3, :3].T / scale)
    k = smoothing.steps(texel, smoothing.median_edge(world, lv, nxt),
                        math.sqrt(smoothing.surface_area(world, lv, nxt, start)))
    return Smoothing(co, lv, nxt, k) if k else None


@dataclasses.dataclass
class Smoothing:
    """A dense copy's own positions ``co`` (V, 3), its faces (corner vertices ``lv``, next corners ``nxt``) and the
    ``steps`` that smooth it; :meth:`positions` computes the smoothed ones once, when first asked."""
    co: np.ndarray
    lv: np.ndarray
    nxt: np.ndarray
    steps: int
    _smoothed: np.ndarray = None

    def positions(self, smoothed):
        """Flat float32 positions: smoothed, or the copy's own."""
        if not smoothed:
            return self.co.astype(np.float32).ravel()
        if self._smoothed is None:
            self._smoothed = smoothing.smoothed(self.co, self.lv, self.nxt, self.steps).astype(np.float32).ravel()
        return self._smoothed


def welded_vertices(co, lv, start, total):
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
    group = unique_rows(key)
    by_group = np.argsort(group, kind="stable")
    g = group[by_group]
    run_start = np.r_[0, np.flatnonzero(g[1:] != g[:-1]) + 1]
    seen = np.zeros(nf, np.int64)                     # earlier faces over the same vertices
    seen[by_group] = np.arange(nf) - np.repeat(run_start, np.diff(np.r_[run_start, nf]))
    corner_copy = np.where(repeat, -1, seen)[face_of]
    vertex = np.where(corner_copy < 0, lv, welded)
    first, ids = unique_rows(np.stack([vertex, corner_copy], 1), return_index=True)
    return co.reshape(-1, 3)[vertex[first]].ravel(), ids


_FACE_KEY = 16
"""Sorted vertices of a face that tell duplicates apart (with its corner count and vertex sum): a longer face
matching another on them only goes to another copy of the vertices."""
