"""Seams of a light map: the jump an engine's bilinear sampler reads across a chart border, beside the map's own
neighbour-to-neighbour variation and the jump its Monte Carlo noise alone gives, and a least-squares stitch
(Iwanicki 2013, "Lighting technology of The Last of Us": texels along seams moved so that both sides' bilinear
samples agree, each held to its baked value).

Coordinates are texel units of the map (u W, v H; texel (r, c) has its centre at (c + ½, r + ½), row 0 at v = 0,
as :func:`lightmap.bilinear` reads it). numpy only.
"""
import dataclasses
import math

import numpy as np

from .brdf import normalize
from .memo import storable
from .rows import unique_rows


UV_TOLERANCE = 1e-3       # texels: corners this close in UV are one corner (no seam)
NORMAL_TOLERANCE = 1e-4   # 1 − n_a·n_b: corner normals this close are one (a smooth edge)
SPACING = 1.0             # texels between sample points of the figure
INSET = 1.5               # texels from the border to the interior points (their footprint stays inside)
STITCH_SPACING = 0.5      # texels between the stitch's constraint points
STITCH_WEIGHT = 0.05      # λ: weight of a texel's baked value against the seam constraints


@storable
@dataclasses.dataclass
class Seams:
    """Seam edges of a mesh: ``a``, ``b`` (E, 2, 2) the two faces' UVs (texels) at the edge's two vertices, in the
    same vertex order; ``a_in``, ``b_in`` (E, 2) the UV of each face's third corner (the side the chart lies on);
    ``creases`` the UV-split edges left out because the surface is not smooth there (corner normals differ: the
    shading is discontinuous on the surface itself)."""
    a: np.ndarray
    b: np.ndarray
    a_in: np.ndarray
    b_in: np.ndarray
    creases: int = 0

    def __len__(self):
        return len(self.a)


def welded(positions, tolerance=1e-6):
    """Vertex ids (N,) with vertices at the same position (within ``tolerance`` × the mesh's extent) merged: an
    imported mesh (glTF, OBJ) splits its vertices where UVs or normals differ, so its chart borders are open edges
    until the coincident vertices are joined."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    if not len(p):
        return np.zeros(0, np.int64)
    step = tolerance * max(float(np.ptp(p, axis=0).max()), 1e-12)
    return unique_rows(np.round((p - p.min(axis=0)) / step).astype(np.int64))


def seam_edges(tri_vertices, tri_uv, tri_normals=None, uv_tolerance=UV_TOLERANCE, normal_tolerance=NORMAL_TOLERANCE):
    """The seams of a triangle mesh: edges (vertex pairs) shared by exactly two triangles whose UVs differ at either
    vertex by more than ``uv_tolerance`` texels, and (with ``tri_normals`` (T, 3, 3) corner normals) whose corner
    normals agree at both vertices (1 − n_a·n_b ≤ ``normal_tolerance``). ``tri_vertices`` (T, 3) vertex indices
    (0 ≤ i < 2³¹, as Blender's), ``tri_uv`` (T, 3, 2) in texels. Edges inside an n-gon's triangulation share their UVs
    and are no seams."""
    tv = np.asarray(tri_vertices, np.int64)
    uv = np.asarray(tri_uv, float).reshape(-1, 2)     # by corner 3 t + c
    nxt = np.array([1, 2, 0])
    v0, v1 = tv.ravel(), tv[:, nxt].ravel()           # each corner's edge, to the next corner
    lo, hi = np.minimum(v0, v1), np.maximum(v0, v1)
    order = np.argsort(lo * (int(hi.max(initial=0)) + 1) + hi, kind="stable")     # by lo, then hi (i < 2³¹)
    lo, hi = lo[order], hi[order]
    starts = np.flatnonzero(np.r_[True, (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])])
    first = starts[np.diff(np.r_[starts, len(lo)]) == 2]
    i, j = order[first], order[first + 1]            # the corners starting the edge on either side
    i1, i2 = i - i % 3 + nxt[i % 3], i - i % 3 + nxt[nxt[i % 3]]
    j1, j2 = j - j % 3 + nxt[j % 3], j - j % 3 + nxt[nxt[j % 3]]
    same = v0[i] == v0[j]                       # side b runs the edge the same way round (else reversed)
    b0, b1 = np.where(same, j, j1), np.where(same, j1, j)
    a = np.stack([uv[i], uv[i1]], axis=1)
    b = np.stack([uv[b0], uv[b1]], axis=1)
    d = np.abs(a - b)
    split = np.maximum(np.maximum(d[:, 0, 0], d[:, 0, 1]), np.maximum(d[:, 1, 0], d[:, 1, 1])) > uv_tolerance
    smooth = np.ones(len(i), bool)
    if tri_normals is not None:
        n = np.asarray(tri_normals, float).reshape(-1, 3)
        dot0 = np.sum(normalize(n[i]) * normalize(n[b0]), axis=-1)
        dot1 = np.sum(normalize(n[i1]) * normalize(n[b1]), axis=-1)
        smooth = (1.0 - np.minimum(dot0, dot1)) <= normal_tolerance
    keep = split & smooth
    return Seams(a[keep], b[keep], uv[i2][keep], uv[j2][keep], int((split & ~smooth).sum()))


def seam_points(seams, spacing=SPACING):
    """Matched points (pa, pb, edge) along the seams: ⌈max(|a|, |b|)/spacing⌉ points per edge at t = (k + ½)/n,
    pa = a₀ + t (a₁ − a₀) on one side and pb at the same t (the same surface point) on the other."""
    if not len(seams):
        z = np.zeros((0, 2))
        return z, z, np.zeros(0, np.int64)
    la = np.linalg.norm(seams.a[:, 1] - seams.a[:, 0], axis=1)
    lb = np.linalg.norm(seams.b[:, 1] - seams.b[:, 0], axis=1)
    n = np.maximum(1, np.ceil(np.maximum(la, lb) / spacing)).astype(np.int64)
    edge = np.repeat(np.arange(len(n)), n)
    k = np.arange(edge.size) - np.repeat(np.cumsum(n) - n, n)
    t = ((k + 0.5) / n[edge])[:, None]
    pa = seams.a[edge, 0] + t * (seams.a[edge, 1] - seams.a[edge, 0])
    pb = seams.b[edge, 0] + t * (seams.b[edge, 1] - seams.b[edge, 0])
    return pa, pb, edge


def footprint(points, height, width):
    """(index (N, 4) flat texel indices, weights (N, 4)) of the bilinear lookups at ``points`` (N, 2) in texels:
    the four texels and weights :func:`lightmap.bilinear` reads (clamped at the map's border)."""
    p = np.asarray(points, float).reshape(-1, 2)
    x = np.clip(p[:, 0] - 0.5, 0, width - 1)
    y = np.clip(p[:, 1] - 0.5, 0, height - 1)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, width - 1), np.minimum(y0 + 1, height - 1)
    fx, fy = x - x0, y - y0
    index = np.stack([y0 * width + x0, y0 * width + x1, y1 * width + x0, y1 * width + x1], axis=1)
    weights = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], axis=1)
    return index, weights


def _read(flat, index, weights):
    return np.einsum("nk,nkc->nc", weights, flat[index])


def _rms(d):
    return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")


def _noise_factor(index_a, weights_a, index_b, weights_b, source):
    """√(mean over pairs of Σ_j c_j²), c the coefficients of (sample a − sample b) on the texels whose independent
    noise they carry (a dilated texel is its source texel; a texel holding no baked value carries none): the RMS
    jump per unit of texel noise σ."""
    if not len(index_a):
        return float("nan")
    src = np.asarray(source).ravel()
    idx = src[np.concatenate([index_a, index_b], axis=1)]
    w = np.concatenate([weights_a, -weights_b], axis=1)
    w = np.where(idx >= 0, w, 0.0)
    order = np.argsort(idx, axis=1, kind="stable")
    idx, w = np.take_along_axis(idx, order, 1), np.take_along_axis(w, order, 1)
    group = np.concatenate([np.ones((len(idx), 1), bool), idx[:, 1:] != idx[:, :-1]], axis=1)
    row = np.repeat(np.arange(len(idx)), idx.shape[1])
    label = np.cumsum(group.ravel()) - 1
    sums = np.bincount(label, weights=w.ravel())
    per_row = np.bincount(row[group.ravel()], weights=sums ** 2, minlength=len(idx))
    return float(math.sqrt(per_row.mean()))


@dataclasses.dataclass
class Figure:
    """The seam figure of a map: over ``samples`` matched points on ``edges`` seam edges, ``rms`` and ``max`` of
    |value_a − value_b| (every channel); ``interior_rms`` of |f(q) − f(q + spacing t̂)| at points q ``INSET``
    texels inside each side's chart (both footprints on covered texels; ``interior_samples`` pairs); ``noise_factor``
    the RMS jump per unit of per-texel noise σ (:func:`_noise_factor`), so the jump its noise alone gives is
    σ × noise_factor."""
    edges: int
    samples: int
    rms: float
    max: float
    interior_rms: float
    interior_samples: int
    noise_factor: float
    creases: int = 0


@dataclasses.dataclass
class Sampling:
    """Where :func:`measure` reads the maps of one layout: the bilinear footprints (index, weights) of the matched
    seam points on side a and side b, and of the interior pairs q, q + spacing t̂ whose footprints lie on covered
    texels (side a's, then side b's)."""
    edges: int
    creases: int
    a: tuple
    b: tuple
    q: tuple
    q2: tuple
    _noise: tuple = (None, None)

    def noise_factor(self, source):
        """:func:`_noise_factor` of these seam points for ``source`` (remembered for the last one)."""
        if self._noise[0] is not source:
            self._noise = (source, _noise_factor(*self.a, *self.b, source))
        return self._noise[1]


def sampling(seams, mask, spacing=SPACING, inset=INSET):
    """The :class:`Sampling` of ``seams`` on a map with covered texels ``mask`` (H, W)."""
    m = np.asarray(mask, bool)
    h, w = m.shape
    pa, pb, edge = seam_points(seams, spacing)
    inner = []
    for ends, inside, p in ((seams.a, seams.a_in, pa), (seams.b, seams.b_in, pb)):
        if not len(p):
            continue
        d = ends[edge, 1] - ends[edge, 0]
        t = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        normal = np.stack([-t[:, 1], t[:, 0]], axis=1)
        normal *= np.sign(np.sum((inside[edge] - ends[edge, 0]) * normal, axis=1))[:, None]
        q = p + inset * normal
        iq, wq = footprint(q, h, w)
        iq2, wq2 = footprint(q + spacing * t, h, w)
        ok = m.ravel()[iq].all(axis=1) & m.ravel()[iq2].all(axis=1)
        inner.append((iq[ok], wq[ok], iq2[ok], wq2[ok]))
    if inner:
        iq, wq, iq2, wq2 = (np.concatenate(x) for x in zip(*inner))
    else:
        iq, iq2 = np.zeros((0, 4), np.int64), np.zeros((0, 4), np.int64)
        wq, wq2 = np.zeros((0, 4)), np.zeros((0, 4))
    return Sampling(len(seams), seams.creases, footprint(pa, h, w), footprint(pb, h, w), (iq, wq), (iq2, wq2))


def measure(values, seams, mask, source=None, spacing=SPACING, inset=INSET, at=None):
    """The :class:`Figure` of map ``values`` (H, W[, C]) with covered texels ``mask`` (H, W). ``source`` (H, W): flat
    index of the covered texel each texel holds (dilation), −1 where it holds no baked value; default the covered
    texels themselves. ``at``: the :func:`sampling` of ``seams`` and ``mask`` (made here when None)."""
    v = np.asarray(values, float)
    h, w = v.shape[:2]
    flat = v.reshape(h * w, -1)
    if source is None:
        source = np.where(np.asarray(mask, bool).ravel(), np.arange(h * w), -1)
    at = at or sampling(seams, mask, spacing, inset)
    jump = np.abs(_read(flat, *at.a) - _read(flat, *at.b))
    inner = _read(flat, *at.q) - _read(flat, *at.q2)
    return Figure(edges=at.edges, samples=len(at.a[0]), rms=_rms(jump), max=float(jump.max()) if jump.size else 0.0,
                  interior_rms=_rms(inner), interior_samples=len(inner),
                  noise_factor=at.noise_factor(source), creases=at.creases)


def stitch(values, seams, weight=STITCH_WEIGHT, spacing=STITCH_SPACING, iterations=200, tolerance=1e-6):
    """Seam stitch: the texels ``x`` read at the seams' matched points (spacing ``spacing`` texels) minimise
    Σ_k (S_a(p_k) − S_b(p_k))² + λ Σ_j (x_j − x⁰_j)², S the bilinear sample, x⁰ the baked values, λ = ``weight``;
    the normal equations (CᵀC + λI) δ = −Cᵀ C x⁰ are solved by conjugate gradients, every channel at once (until
    |r|² ≤ ``tolerance`` |Cᵀ C x⁰|², at most ``iterations``). Texels no seam point reads are returned unchanged.
    Returns the stitched copy of ``values`` (H, W[, C])."""
    v = np.array(values, np.float64)
    if not len(seams):
        return v.astype(np.asarray(values).dtype)
    h, w = v.shape[:2]
    flat = v.reshape(h * w, -1)
    pa, pb, _ = seam_points(seams, spacing)
    ia, wa = footprint(pa, h, w)
    ib, wb = footprint(pb, h, w)
    index = np.concatenate([ia, ib], axis=1)
    coeff = np.concatenate([wa, -wb], axis=1)
    used, local = np.unique(index, return_inverse=True)
    local = local.reshape(index.shape)
    x0 = flat[used]

    def c(x):
        return np.einsum("nk,nkc->nc", coeff, x[local])

    def ct(r):
        out = np.zeros((len(used), r.shape[1]))
        for ch in range(r.shape[1]):
            out[:, ch] = np.bincount(local.ravel(), weights=(coeff * r[:, ch:ch + 1]).ravel(), minlength=len(used))
        return out

    def a(x):
        return ct(c(x)) + weight * x

    rhs = -ct(c(x0))
    delta = np.zeros_like(x0)
    r = rhs.copy()
    p = r.copy()
    rr = np.sum(r * r, axis=0)
    stop = tolerance * max(float(np.sum(rhs * rhs)), 1e-300)
    for _ in range(iterations):
        if float(rr.sum()) <= stop:
            break
        ap = a(p)
        alpha = rr / np.maximum(np.sum(p * ap, axis=0), 1e-300)
        delta += alpha * p
        r -= alpha * ap
        new = np.sum(r * r, axis=0)
        p = r + (new / np.maximum(rr, 1e-300)) * p
        rr = new
    flat[used] = x0 + delta
    return flat.reshape(v.shape).astype(np.asarray(values).dtype)
