"""Merging a layout's charts (issue 27): neighbouring charts are joined two at a time, each chart once a round, the
pairs with the longest shared border for their size first, and the joined chart is unwrapped again as one (Blender's
minimum-stretch unwrap, in the adapter); a join is kept when the new chart is as even as a light map needs
(:func:`chart_ok`), else both charts keep their layout. Fewer charts mean fewer margins: Suzanne's 500 faces joined
so fill a 256² map with 4-texel margins 0.56 instead of the 0.38 of its 100 Smart UV Project charts, both packed by
their texels.

Numpy only: the mesh is given as corner arrays (``owner``: the face of each corner, ``vertex``: its vertex, ``after``:
the vertex of the next corner of its face)."""
import dataclasses

import numpy as np

from .lightmap import triangle_areas, triangle_counts
from .rows import unique_rows

CREASE = 88.0
"""Charts are joined only along borders whose faces' normals are less than this many degrees apart (Unity's "Hard
Angle" of its light-map UVs, 88° by default): a box's edges and a cylinder's rims stay chart borders, so a lookup
never blends the light of two sides of a hard edge, and the seam figure keeps counting them as creases. Measured on
Suzanne at 128² / 256² (4-texel margins; up to 6 rounds of joins then): fill 0.55 / 0.51 at 88°, 0.49 / 0.43 at 45°,
0.57 / 0.56 without."""
EVEN = 0.8
"""Texel density of the lowest tenth of a joined chart's area over its median, and of its median over its highest
tenth, at least this (a chart unwrapped by its minimum stretch; Smart UV Project's projections give 0.90-0.93 over a
whole layout, :data:`addon.bake.unwrap.MIN_SPREAD` 0.8)."""
CHECK_SIDE = 64
"""Side of the raster a joined chart of more than CHECK_TRIANGLES triangles is checked on for folds over itself (its
box scaled to it); a smaller one none of whose triangles is turned over is taken as flat (the layout a round keeps
is checked whole for texels under several faces, :meth:`addon.bake.unwrap._Copies.try_merged`)."""
CHECK_TRIANGLES = 16
FOLDED = 0.002
"""Most texel centres of that raster under two triangles of the chart's interiors (strict) per covered one."""


@dataclasses.dataclass
class Surface:
    """A mesh as a merge reads it: per corner its face (``owner``) and vertex, per edge (numbered by :func:`surface`)
    its two vertices (lower first), the two faces that share it (-1: a border or non-manifold edge), its length and
    the cosine of the angle between those faces' normals (-1 without two faces), per triangle (corner indices
    ``tri``) its face and 3D area."""
    owner: np.ndarray
    vertex: np.ndarray
    corner_edge: np.ndarray
    edge_vertices: np.ndarray
    edge_faces: np.ndarray
    edge_length: np.ndarray
    edge_cos: np.ndarray
    tri: np.ndarray
    tri_face: np.ndarray
    tri_area: np.ndarray


def surface(owner, vertex, after, co, tri, tri_face):
    """:class:`Surface` of corner arrays ``owner``, ``vertex``, ``after`` (see the module), positions ``co`` (V, 3),
    triangles ``tri`` (T, 3 corners) and their faces ``tri_face``."""
    owner, vertex, after = (np.asarray(a, np.int64) for a in (owner, vertex, after))
    co = np.asarray(co, float).reshape(-1, 3)
    ends = np.sort(np.stack([vertex, after], axis=1), axis=1)
    first, corner_edge = unique_rows(ends, return_index=True)
    count = np.bincount(corner_edge, minlength=len(first))
    order = np.argsort(corner_edge, kind="stable")
    start = np.searchsorted(corner_edge[order], np.arange(len(first)))
    edge_faces = np.full((len(first), 2), -1, np.int64)
    two = count == 2
    edge_faces[two, 0] = owner[order[start[two]]]
    edge_faces[two, 1] = owner[order[start[two] + 1]]
    edge_faces[edge_faces[:, 0] == edge_faces[:, 1]] = -1
    v = ends[first]
    length = np.linalg.norm(co[v[:, 0]] - co[v[:, 1]], axis=1)
    tri = np.asarray(tri, np.int64).reshape(-1, 3)
    return Surface(owner, vertex, corner_edge, v, edge_faces, length, _edge_cos(co, owner, vertex, after, edge_faces),
                   tri, np.asarray(tri_face, np.int64), triangle_areas(co[vertex[tri]]))


def _edge_cos(co, owner, vertex, after, edge_faces):
    """Per edge, n_a · n_b of its two faces' unit normals (Newell's: Σ over a face's corners of p_i × p_next), -1
    for an edge without two faces or a face without area."""
    normal = np.zeros((int(owner.max()) + 1 if len(owner) else 0, 3))
    np.add.at(normal, owner, np.cross(co[vertex], co[after]))
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 0, normal / np.where(length > 0, length, 1.0), 0.0)
    two = (edge_faces >= 0).all(axis=1)
    out = np.full(len(edge_faces), -1.0)
    out[two] = np.einsum("ij,ij->i", normal[edge_faces[two, 0]], normal[edge_faces[two, 1]])
    return np.where(two & (length[np.maximum(edge_faces[:, 0], 0), 0] > 0)
                    & (length[np.maximum(edge_faces[:, 1], 0), 0] > 0), out, -1.0)


def pairs(surf, labels):
    """The charts to join this round, [(a, b)] with a < b, each chart in one pair at most: neighbours (sharing an
    edge) whose shared border is one path (shared vertices − shared edges = 1, so a disc joined to a disc stays a
    disc and no chart closes around a hole) without a crease (:data:`CREASE`), by shared length / √(smaller chart's
    area), longest first."""
    labels = np.asarray(labels, np.int64)
    inner = (surf.edge_faces >= 0).all(axis=1)
    fa, fb = labels[surf.edge_faces[inner, 0]], labels[surf.edge_faces[inner, 1]]
    cross = fa != fb
    if not cross.any():
        return []
    key = np.sort(np.stack([fa[cross], fb[cross]], axis=1), axis=1)
    first, pair = unique_rows(key, return_index=True)
    shared_len = np.bincount(pair, weights=surf.edge_length[inner][cross])
    shared_edges = np.bincount(pair)
    flattest = np.full(len(first), 1.0)
    np.minimum.at(flattest, pair, surf.edge_cos[inner][cross])
    candidates = key[first]
    shared_verts = _shared_vertices(surf, labels, candidates)
    area = np.bincount(labels[surf.tri_face], weights=surf.tri_area, minlength=int(labels.max()) + 1)
    smaller = np.sqrt(np.maximum(np.minimum(area[candidates[:, 0]], area[candidates[:, 1]]), 1e-30))
    score = shared_len / smaller
    path = (shared_verts - shared_edges == 1) & (flattest >= np.cos(np.radians(CREASE)))
    out, used = [], set()
    for i in np.lexsort((candidates[:, 1], candidates[:, 0], -score)):
        a, b = (int(x) for x in candidates[i])
        if path[i] and a not in used and b not in used:
            used.update((a, b))
            out.append((a, b))
    return out


def _shared_vertices(surf, labels, candidates):
    """(P,) vertices that both charts of each candidate pair (P, 2) have."""
    at = np.stack([surf.vertex, labels[surf.owner]], axis=1)
    first = unique_rows(at, return_index=True)[0]
    vl = at[first]                                    # (vertex, chart) once each, sorted by vertex then chart
    start = np.flatnonzero(np.r_[True, vl[1:, 0] != vl[:-1, 0]])
    size = np.diff(np.r_[start, len(vl)])
    index = {(int(a), int(b)): i for i, (a, b) in enumerate(candidates)}
    out = np.zeros(len(candidates), np.int64)
    for s, n in zip(start[size > 1], size[size > 1]):
        charts = vl[s:s + n, 1]
        for i in range(n):
            for j in range(i + 1, n):
                k = index.get((int(charts[i]), int(charts[j])))
                if k is not None:
                    out[k] += 1
    return out


def crosses_crease(surf, labels):
    """Whether a chart of face ``labels`` holds an edge whose two faces' normals are :data:`CREASE` or more degrees
    apart (both faces in the chart: a layout given to the bake, whose charts the joins here would never make)."""
    labels = np.asarray(labels, np.int64)
    inner = (surf.edge_faces >= 0).all(axis=1)
    same = labels[surf.edge_faces[inner, 0]] == labels[surf.edge_faces[inner, 1]]
    return bool((surf.edge_cos[inner][same] < np.cos(np.radians(CREASE))).any())


LONG = 1.5
"""A chart at least this many times longer (along its principal axis) than wide is cut by :func:`cut_long`."""


def cut_long(uv, owner, chart, pieces=None, longest=LONG):
    """Corner UVs ``uv`` (N, 2) with each chart (``chart``: its label per corner, ``owner``: the face of each
    corner) of length L along its principal axis (of its corners' covariance) and width W across it, L ≥ ``longest``
    · W, cut across that axis into k pieces of whole faces (a face goes by its mean corner along the axis) and each
    piece i moved 2 i L along it, so that the pieces are charts of their own (:func:`core.pack.chart_labels`).
    k = ``pieces``, by default max(2, round(√(L / W))): k pieces of L / k × W stack into a square, L / k = k W (a
    torus's own grid made isotropic is a 4 × 1 strip: 2 pieces fill a square map). Or None when no chart is so
    long, is a line (no width) or a face alone, or when no chart's faces fall in two pieces."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    owner = np.asarray(owner, np.int64)
    chart = np.asarray(chart, np.int64)
    if not len(chart):
        return None
    n = int(chart.max()) + 1
    count = np.maximum(np.bincount(chart, minlength=n), 1)
    mean = np.stack([np.bincount(chart, uv[:, i], n) for i in (0, 1)], axis=1) / count[:, None]
    d = uv - mean[chart]
    cov = np.zeros((n, 2, 2))
    np.add.at(cov, chart, d[:, :, None] * d[:, None, :])
    axes = np.linalg.eigh(cov)[1]                     # columns by ascending variance: the principal axis last
    along = np.einsum("ni,ni->n", d, axes[chart, :, 1])
    across = np.einsum("ni,ni->n", d, axes[chart, :, 0])
    extent = []
    for v in (along, across):
        lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
        np.minimum.at(lo, chart, v)
        np.maximum.at(hi, chart, v)
        extent.append((lo, hi - lo))
    (low, length), (_, width) = extent
    faces = int(owner.max()) + 1
    face_chart = np.zeros(faces, np.int64)
    face_chart[owner] = chart
    used = np.unique(owner)
    sizes = np.bincount(face_chart[used], minlength=n)                       # faces of each chart
    cut = (length >= longest * width) & (width > 1e-9 * length) & (sizes >= 2)
    k = np.where(cut, np.maximum(2.0, np.rint(np.sqrt(length / np.maximum(width, 1e-300))))
                 if pieces is None else float(pieces), 1.0)
    if not (k >= 2).any():
        return None
    k = np.minimum(k, sizes)
    face_along = np.bincount(owner, along, faces) / np.maximum(np.bincount(owner, minlength=faces), 1)
    c = face_chart
    piece = np.clip(np.floor((face_along - low[c]) / np.maximum(length[c], 1e-300) * k[c]), 0, k[c] - 1)
    first = np.full(n, np.inf)
    np.minimum.at(first, c[used], piece[used])
    last = np.full(n, -np.inf)
    np.maximum.at(last, c[used], piece[used])
    if not (last > first).any():                       # every chart's faces in one piece: nothing is cut
        return None
    return uv + (2.0 * piece[owner] * length[chart])[:, None] * axes[chart, :, 1]


def joined(labels, pairs_):
    """Face labels with each pair's second chart joined to its first."""
    out = np.asarray(labels, np.int64).copy()
    remap = np.arange(int(out.max()) + 1)
    for a, b in pairs_:
        remap[b] = a
    return remap[out]


def _signed(tri_uv):
    e1, e2 = tri_uv[:, 1] - tri_uv[:, 0], tri_uv[:, 2] - tri_uv[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def chart_ok(tri_uv, tri_area):
    """A joined chart's new layout (its triangles' UVs ``tri_uv`` (T, 3, 2), their 3D areas ``tri_area``) is kept:
    no triangle turned over (all signed UV areas of one sign, slivers aside), its density √(UV area / 3D area) even
    (:data:`EVEN`, area-weighted tenths) and no fold over itself (:data:`FOLDED` on a :data:`CHECK_SIDE` raster,
    above :data:`CHECK_TRIANGLES`)."""
    tri_uv = np.asarray(tri_uv, float).reshape(-1, 3, 2)
    if not np.isfinite(tri_uv).all():
        return False
    signed = _signed(tri_uv)
    total = signed.sum()
    if not np.isfinite(total) or total == 0:
        return False
    signed = signed * np.sign(total)
    if (signed < -1e-9 * abs(total)).any():
        return False
    keep = tri_area > 0
    density = np.sqrt(np.maximum(signed[keep], 0) / tri_area[keep])
    order = np.argsort(density, kind="stable")
    c = np.cumsum(tri_area[keep][order])
    at = lambda q: density[order][min(np.searchsorted(c, q * c[-1]), len(c) - 1)]
    low, mid, high = at(0.1), at(0.5), at(0.9)
    if not (mid > 0 and low >= EVEN * mid and mid >= EVEN * high):
        return False
    if len(tri_uv) <= CHECK_TRIANGLES:
        return True
    lo, hi = tri_uv.reshape(-1, 2).min(axis=0), tri_uv.reshape(-1, 2).max(axis=0)
    fit = (tri_uv - lo) / max(float((hi - lo).max()), 1e-30) * 0.98 + 0.01
    counts = triangle_counts(fit, CHECK_SIDE, CHECK_SIDE, strict=True)
    return (counts >= 2).sum() <= FOLDED * max((counts > 0).sum(), 1)


def density(uv, surf):
    """UV area per 3D area of a layout ``uv`` (N, 2 corner UVs) over the whole surface."""
    return float(np.abs(_signed(np.asarray(uv, float)[surf.tri])).sum() / max(surf.tri_area.sum(), 1e-30))


def placed(old, new, surf, labels, pairs_, k, cursor):
    """Join ``pairs_`` of face ``labels`` where :func:`chart_ok` keeps the joined chart's layout ``new`` (N, 2 corner
    UVs): its UVs scaled to the UV area per 3D area ``k``, mirrored back when its unwrap turned it over, and put in
    a row from x = ``cursor`` (past the unit square and every chart placed before, so no two charts meet); the other
    corners keep ``old``. Return (corner UVs, face labels with the kept pairs joined, cursor, pairs kept)."""
    out = np.array(old, float).reshape(-1, 2)
    new = np.asarray(new, float).reshape(-1, 2)
    labels = np.asarray(labels, np.int64)
    together = joined(labels, pairs_)
    tri_label, corner_label = together[surf.tri_face], together[surf.owner]
    kept = []
    for a, b in pairs_:
        sel = tri_label == a
        tri = new[surf.tri[sel]]
        if not chart_ok(tri, surf.tri_area[sel]):
            continue
        corners = corner_label == a
        uv = new[corners] * ((-1.0, 1.0) if _signed(tri).sum() < 0 else (1.0, 1.0))
        scale = np.sqrt(k * surf.tri_area[sel].sum() / abs(_signed(tri).sum()))
        uv = (uv - uv.min(axis=0)) * scale
        out[corners] = uv + (cursor, 2.0)
        cursor += float(uv[:, 0].max()) + 0.25
        kept.append((a, b))
    return out, joined(labels, kept), cursor, len(kept)

