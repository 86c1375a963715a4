"""The surface a light map can show: a mesh whose edges are much shorter than a texel (a scan, a dense
subdivision) smoothed along its normals below the texel's size before it is unwrapped, so that the unwrapper
clusters faces by the shape the map resolves and not by sub-texel noise.

Each step moves every vertex along its normal n (the sum of its corners' cross products, area-weighted) by
λ the normal part of its umbrella Laplacian (Taubin 1995, "A signal processing approach to fair surface design",
eq. 1, here without the tangential part):

    p ← p + λ ((p̄ − p) · n̂) n̂,    p̄ the mean of p's edge neighbours,

so vertices keep their place on the surface (the layout's texel density follows the real triangles) and loose
triangles (a soup: all neighbours in the face's plane) do not move. k steps spread a displacement over about
√k edges: :func:`steps` picks k for a smoothing radius of two texels. Measured on the level benchmark's scan
(an ico sphere of 81,920 triangles, 2 % radial noise) at 10 texels per metre: Smart UV Project makes 21,530 charts
of it as it is, and tens once it is smoothed (docs/lightmaps.md).
"""
import math

import numpy as np

LAMBDA = 0.5
NORMAL_EVERY = 4
"""Steps between two computations of the vertex normals after the first NORMAL_EVERY² steps, where they are computed
at every step (four fifths of a step's cost; once the noise is gone they turn slowly)."""
MAX_STEPS = 64
"""Most smoothing steps (a radius of 8 edges); the cost is about 10 ms per step per 100k corners."""


RADIUS = 2.0
"""Smoothing radius in texels: a map resolves nothing finer than two texels (its Nyquist limit)."""


SIZE_FRACTION = 8.0
"""The radius is at most the mesh's size (√ of its area) over this: smoothed over more, a small prop's ears and nose
fold into its head and the unwrapper's charts of the blob overlap on the real mesh (the full level's monkeys, a
few texels wide: 1-4 % of their texels under several faces)."""


def steps(texel, edge, size=math.inf):
    """Smoothing steps k for a texel of ``texel``, a median edge of ``edge`` and a mesh of size ``size`` (one length
    unit): the radius √k · edge reaches RADIUS texels or size / SIZE_FRACTION; 0 below two steps or for a mesh under
    SIZE_FRACTION texels (a radius under a texel: its charts are a few texels whatever the unwrapper does), at most
    MAX_STEPS."""
    if not edge > 0 or not texel > 0 or size < SIZE_FRACTION * texel:
        return 0
    k = int((min(RADIUS * texel, size / SIZE_FRACTION) / edge) ** 2)
    return min(k, MAX_STEPS) if k >= 2 else 0


def corner_next(start, total):
    """(N,) the next corner of each corner in its face, for faces starting at ``start`` with ``total`` corners."""
    start, total = np.asarray(start, np.int64), np.asarray(total, np.int64)
    nxt = np.arange(int(total.sum()), dtype=np.int64) + 1
    if len(start):
        nxt[start + total - 1] = start
    return nxt


def median_edge(co, corner_vertex, nxt):
    """Median length of the face edges (corner to next corner) of vertices ``co`` (V, 3)."""
    if not len(corner_vertex):
        return 0.0
    return float(np.median(np.linalg.norm(co[corner_vertex[nxt]] - co[corner_vertex], axis=1)))


def surface_area(co, corner_vertex, nxt, start):
    """Area of the faces (corners ``corner_vertex``, next corners ``nxt``, faces' first corners ``start``,
    ascending) of vertices ``co`` (V, 3): half the norm of each face's Newell sum Σ p × p_next."""
    if not len(corner_vertex):
        return 0.0
    p = np.asarray(co, np.float64).reshape(-1, 3).T
    c = _cross(p[:, corner_vertex], p[:, corner_vertex[nxt]])
    per_face = np.add.reduceat(c, np.asarray(start, np.int64), axis=1)
    return float(0.5 * np.sqrt((per_face * per_face).sum(axis=0)).sum())


def _cross(a, b):
    """Row-wise cross products of (3, N) arrays (np.cross is 20 times slower on (N, 3) rows)."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def smoothed(co, corner_vertex, nxt, k, lam=LAMBDA):
    """Vertices ``co`` (V, 3) after ``k`` normal smoothing steps over the faces given by ``corner_vertex`` (N,)
    and each corner's next corner ``nxt`` (N,)."""
    p = np.array(co, np.float64).reshape(-1, 3).T.copy()
    if k <= 0 or not len(corner_vertex):
        return p.T
    n = p.shape[1]
    cv = np.asarray(corner_vertex, np.int64)
    nxt = np.asarray(nxt, np.int64)
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(nxt))
    cn, cp = cv[nxt], cv[prv]
    degree = np.bincount(cv, minlength=n) + np.bincount(cn, minlength=n)
    inverse = np.divide(1.0, degree, out=np.zeros(n), where=degree > 0)
    for step in range(k):
        lap = np.stack([(np.bincount(cv, x[cn], n) + np.bincount(cn, x[cv], n)) * inverse - x for x in p])
        lap[:, degree == 0] = 0.0
        if step < NORMAL_EVERY * NORMAL_EVERY or step % NORMAL_EVERY == 0:
            q = np.take(p, cv, axis=1)              # 5 times faster than p[:, cv]
            c = _cross(np.take(p, cn, axis=1) - q, np.take(p, cp, axis=1) - q)
            normal = np.stack([np.bincount(cv, c[i], n) for i in range(3)])
            length = np.sqrt((normal * normal).sum(axis=0))
            unit = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
        p += lam * (lap * unit).sum(axis=0) * unit
    return p.T
