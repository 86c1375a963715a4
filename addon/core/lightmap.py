"""Light maps in numpy: texel budget, coverage, dilation, Monte Carlo error, closed forms.

Conventions: a light map array is (H, W) or (H, W, C) with row 0 at v = 0 (Blender's
pixel order, bottom row first) unless a function says otherwise; texel (i, j) has
its centre at uv = ((j + 0.5)/W, (i + 0.5)/H). k_A in [0, 1] with 1 = open
(REFERENCE.md §1); irradiance E in W/m².
"""
import math

import numpy as np

from .graph import components

MAX_RESOLUTION = 16384


# ---------------------------------------------------------------- texel budget

def resolution_for_density(area_m2, uv_coverage, texels_per_metre, cap=4096, minimum=4):
    """Square map side N so that a metre of surface gets ``texels_per_metre`` texels.

    N² · coverage = T² · A  ->  N = T √(A / coverage), rounded up, clamped to [minimum, cap].
    ``uv_coverage`` is the fraction of the unit UV square the charts cover.
    """
    if area_m2 <= 0 or uv_coverage <= 0:
        return int(minimum)
    n = math.ceil(texels_per_metre * math.sqrt(area_m2 / uv_coverage))
    return int(min(max(n, minimum), cap))


def uv_areas(tri_uv):
    """|Triangle areas| in UV space, (T,) of ``tri_uv`` (T, 3, 2)."""
    t = np.asarray(tri_uv, float)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def triangle_areas(tri_co):
    """Areas of the triangles ``tri_co`` (T, 3, 3), (T,)."""
    t = np.asarray(tri_co, float)
    return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)


def uv_area(tri_uv):
    """Sum of |triangle areas| in UV space; ``tri_uv`` is (T, 3, 2)."""
    return float(uv_areas(tri_uv).sum())


def unmapped_fraction(tri_co, tri_uv):
    """Share of the area of triangles ``tri_co`` (T, 3, 3) on those whose UV area (``tri_uv`` (T, 3, 2)) is below a
    millionth of what the mean density (Σ UV area / Σ area) gives their area: faces a layout leaves without a texel."""
    area = triangle_areas(tri_co)
    total = float(area.sum())
    if total <= 0:
        return 0.0
    flat = uv_areas(tri_uv)
    lost = (area > 0) & (flat <= 1e-6 * float(flat.sum()) / total * area)
    return float(area[lost].sum() / total)


def chart_window(tri_uv, side, margin):
    """(lo, size), each (x, y) ints: the window [lo, lo + size) of whole texels of a ``side``² map that holds every
    chart of ``tri_uv`` (T, 3, 2) with ``margin`` texels around it (clipped to the map)."""
    p = np.asarray(tri_uv, float).reshape(-1, 2) * side
    if not len(p):
        return np.zeros(2, np.int64), np.full(2, int(side), np.int64)
    lo = np.clip(np.floor(p.min(0) - margin), 0, side).astype(np.int64)
    hi = np.clip(np.ceil(p.max(0) + margin), 0, side).astype(np.int64)
    return lo, np.maximum(hi - lo, 1)


def to_window(uv, side, lo, size):
    """UVs (..., 2) of a ``side``² map carried into its :func:`chart_window` (lo, size): u' = (u side - lo) / size.
    The window's texels are the map's texels: every texel centre keeps its place relative to the charts."""
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    return ((uv * side - lo) / size).astype(np.float32)


def density_spread(tri_uv, tri_world, quantile=0.1):
    """Texel density of the surface's lowest ``quantile`` (by area) over its median: densities √(UV area / world
    area) per triangle, area-weighted quantiles; 1 for a layout of uniform density, lower where charts are
    foreshortened (a projection onto a plane at an angle θ to the surface gives √cos θ)."""
    world = triangle_areas(tri_world)
    uv = uv_areas(tri_uv)
    keep = world > 0
    if not keep.any():
        return 1.0
    density = np.sqrt(uv[keep] / world[keep])
    order = np.argsort(density)
    c = np.cumsum(world[keep][order])
    at = lambda q: density[order][min(np.searchsorted(c, q * c[-1]), len(c) - 1)]
    median = at(0.5)
    return float(at(quantile) / median) if median > 0 else 0.0


def _surface_gradients(tri_uv, tri_xyz):
    """Per triangle with area, the UVs' derivatives along the surface (``gx``, ``gy``: (T', 2) along the frame
    e1 / |e1|, n x e1 / |e1|: J [|e1|, x2; 0, y2] = [f1 f2]) and twice its area, or None when no triangle has any."""
    t = np.asarray(tri_xyz, float)
    d = np.asarray(tri_uv, float)
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    n1 = np.linalg.norm(e1, axis=1)
    cross = np.linalg.norm(np.cross(e1, e2), axis=1)
    ok = (n1 > 0) & (cross > 1e-12 * np.maximum(n1, 1e-30) ** 2)
    if not ok.any():
        return None
    e1, e2, n1, cross, d = e1[ok], e2[ok], n1[ok], cross[ok], d[ok]
    x2 = np.einsum("ij,ij->i", e1, e2) / n1
    y2 = cross / n1
    f1, f2 = d[:, 1] - d[:, 0], d[:, 2] - d[:, 0]
    gx = f1 / n1[:, None]
    return gx, (f2 - gx * x2[:, None]) / y2[:, None], cross


def _weighted_median(values, weights):
    order = np.argsort(values)
    c = np.cumsum(weights[order])
    return values[order][min(np.searchsorted(c, 0.5 * c[-1]), len(c) - 1)]


def isotropic(uv, tri, chart, co):
    """Corner UVs ``uv`` (N, 2) with each chart (``chart``: its label per corner) mapped by L = Ḡ^½: Ḡ the chart's
    mean metric G = MᵀM over its triangles ``tri`` (T, 3 corner indices), weighted by their area, M the map from UV
    to the corner positions ``co`` (N, 3) (3D edges = M × UV edges). Under L a unit of UV is a metre on average in
    every direction: a grid laid on the unit square over a surface 4 times longer than wide becomes a 4 × 1
    rectangle of square texels."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    tri = np.asarray(tri, np.int64).reshape(-1, 3)
    chart = np.asarray(chart, np.int64)
    p = np.asarray(co, float).reshape(-1, 3)[tri]
    d = uv[tri]
    e = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)              # (T, 3, 2)
    f = np.stack([d[:, 1] - d[:, 0], d[:, 2] - d[:, 0]], axis=2)              # (T, 2, 2)
    det = f[:, 0, 0] * f[:, 1, 1] - f[:, 0, 1] * f[:, 1, 0]
    area = 0.5 * np.linalg.norm(np.cross(e[:, :, 0], e[:, :, 1]), axis=1)
    ok = (np.abs(det) > 1e-12 * np.maximum((f ** 2).sum(axis=(1, 2)), 1e-30)) & (area > 0)
    m = e[ok] @ np.linalg.inv(f[ok])                                           # (T', 3, 2)
    g = np.einsum("tki,tkj->tij", m, m) * area[ok][:, None, None]
    k = chart[tri[ok, 0]]
    total = np.zeros((int(chart.max()) + 1 if len(chart) else 0, 2, 2))
    np.add.at(total, k, g)
    weight = np.bincount(k, weights=area[ok], minlength=len(total))
    root = np.broadcast_to(np.eye(2), total.shape).copy()      # a chart without a metric keeps its UVs
    w, v = np.linalg.eigh(total / np.maximum(weight, 1e-300)[:, None, None])
    good = (weight > 0) & (w.min(axis=1) > 0)
    root[good] = np.einsum("kij,kj,klj->kil", v[good], np.sqrt(w[good]), v[good])
    return np.einsum("nij,nj->ni", root[chart], uv)


def density_floor(tri_uv, tri_xyz):
    """The least texel density √(UV area / area) of a triangle over the area-weighted median (triangles with area):
    1 for uniform texels, near 0 where a layout shrinks some faces to next to nothing (a texture unwrap's hidden
    faces)."""
    world = triangle_areas(tri_xyz)
    keep = world > 1e-12 * max(float(world.max()) if len(world) else 0.0, 1e-30)
    if not keep.any():
        return 1.0
    density = np.sqrt(uv_areas(tri_uv)[keep] / world[keep])
    median = _weighted_median(density, world[keep])
    return float(density.min() / median) if median > 0 else 0.0


def texel_anisotropy(tri_uv, tri_xyz):
    """Area-weighted median over triangles of σ₁ / σ₂, the singular values of the map from the surface (positions
    (T, 3, 3)) to the UVs: 1 where texels are square on the surface, whatever their orientation (a box's side laid
    out as a square though it is 4 times longer than wide: 4)."""
    grads = _surface_gradients(tri_uv, tri_xyz)
    if grads is None:
        return 1.0
    gx, gy, area = grads
    frob = (gx ** 2).sum(1) + (gy ** 2).sum(1)
    det = np.abs(gx[:, 0] * gy[:, 1] - gx[:, 1] * gy[:, 0])
    root = np.sqrt(np.maximum(frob ** 2 - 4 * det ** 2, 0.0))
    s1, s2 = np.sqrt(0.5 * (frob + root)), np.sqrt(np.maximum(0.5 * (frob - root), 0.0))
    keep = s2 > 0
    if not keep.any():
        return float("inf")
    return float(_weighted_median(s1[keep] / s2[keep], area[keep]))


def texel_aspect(tri_uv, tri_world):
    """Area-weighted median over triangles of |∇u| / |∇v| (∇ on the surface, UVs against positions (T, 3, 3)):
    the ratio h / w of the map sides that gives square texels on the surface. 1 for a layout made for a square map
    from isometric charts; h / w for such a layout carried into a w x h window (:func:`to_window`)."""
    grads = _surface_gradients(tri_uv, tri_world)
    if grads is None:
        return 1.0
    gx, gy, area = grads
    grad_u = np.hypot(gx[:, 0], gy[:, 0])
    grad_v = np.hypot(gx[:, 1], gy[:, 1])
    keep = (grad_u > 0) & (grad_v > 0)
    if not keep.any():
        return 1.0
    return float(np.exp(_weighted_median(np.log(grad_u[keep] / grad_v[keep]), area[keep])))


def _texels_inside(tri_uv, width, height, strict=False, chunk=1 << 20):
    """Yield flat texel indices (row · W + column, row 0 at v = 0) of the texel centres inside each UV triangle,
    a block of triangles at a time (a centre inside k triangles is yielded k times).

    A centre p is inside triangle abc when its barycentric coordinates w1, w2 (of b, c) satisfy
    w1 ≥ 0, w2 ≥ 0, w1 + w2 ≤ 1 within 1e-6 (edges included), or, with ``strict``, w1, w2 > 1e-6 and
    w1 + w2 < 1 − 1e-6 (interiors only). Triangles without area are skipped. Vectorised: triangles are
    grouped by the power of two k ≥ their texel bounding box, and each group tests its k × k candidate
    texels at once (work about 4 × Σ bounding-box areas, memory bounded by ``chunk`` candidates); a triangle whose
    k is over ROW_BOXES and which covers under ROW_FILL of its box tests only the texels of each of its rows between
    the bounds the three inequalities give that row (:func:`_texels_by_rows`: a cap's fan of slivers).

    The box holds the centres within 1e-5 of the triangle's extent E (texels) of its bounding box: the 1e-6
    tolerance moves a vertex by at most 3e-6 E, and the test's rounding stays far below the rest (2.5e-9 at worst,
    on needles just above the sliver bound); a sliver (|2 · area| < 1e-4 E (E + 1)), whose rounding may be larger,
    keeps the centres within a texel. A scan's triangles, far smaller than a texel, mostly have no candidate.
    Minima and maxima are taken vertex by vertex (numpy's reduction over an axis of 3 is 10 times slower)."""
    t = np.asarray(tri_uv, float).reshape(-1, 3, 2) * (width, height)
    if not len(t):
        return
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    low, high = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    d = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    extent = np.maximum(high[:, 0] - low[:, 0], high[:, 1] - low[:, 1])
    sure = (np.abs(d) >= 1e-4 * extent * (extent + 1))[:, None]
    tol = (1e-5 * extent + 1e-9)[:, None]
    lo = np.maximum(np.where(sure, np.ceil(low - 0.5 - tol), np.floor(low - 0.5)), 0).astype(np.int64)
    hi = np.minimum(np.where(sure, np.floor(high - 0.5 + tol), np.ceil(high - 0.5)),
                    (width - 1, height - 1)).astype(np.int64)
    del low, high, extent, sure, tol                   # about 30 MB for 600k triangles
    span = hi - lo + 1
    ok = (np.minimum(span[:, 0], span[:, 1]) > 0) & (np.abs(d) >= 1e-12)
    k = np.where(ok, 2 ** np.ceil(np.log2(np.maximum(np.maximum(span[:, 0], span[:, 1]), 1))).astype(np.int64), 0)
    eps = 1e-6 if strict else -1e-6
    room = np.minimum(0.5 * np.abs(d), span[:, 0] * span[:, 1])          # at most, of the (clipped) box
    wide = ok & (k > ROW_BOXES) & (room < ROW_FILL * k * k)
    if wide.any():
        yield from _texels_by_rows(np.flatnonzero(wide), a, b, c, d, lo, hi, width, eps, chunk)
    ok &= ~wide
    for size in np.unique(k[ok]):
        size = int(size)
        idx = np.flatnonzero(ok & (k == size))
        rows = min(size, max(1, chunk // size))          # a box larger than chunk is tested in bands of rows
        step = max(1, chunk // max(rows * size, 4))     # at most chunk / 4 triangles at once
        r = np.arange(size)
        for s in range(0, len(idx), step):
            i = idx[s:s + step]
            xs = lo[i, 0][:, None, None] + r[None, None, :]
            e1, e2 = (b[i] - a[i])[:, :, None, None], (c[i] - a[i])[:, :, None, None]
            dd = d[i][:, None, None]
            for y0 in range(0, size, rows):
                ys = lo[i, 1][:, None, None] + r[None, y0:y0 + rows, None]
                valid = (xs <= hi[i, 0][:, None, None]) & (ys <= hi[i, 1][:, None, None])
                px, py = xs + 0.5 - a[i, 0][:, None, None], ys + 0.5 - a[i, 1][:, None, None]
                inside = valid & _inside(px, py, e1[:, 0], e1[:, 1], e2[:, 0], e2[:, 1], dd, eps)
                yield np.broadcast_to(ys, inside.shape)[inside] * width + np.broadcast_to(xs, inside.shape)[inside]


def _inside(px, py, e1x, e1y, e2x, e2y, d, eps):
    """The test of :func:`_texels_inside` for centres (px, py) taken from vertex a, edges e1 = b − a and e2 = c − a,
    d = e1 × e2: w1 = (p × e2) / d, w2 = (e1 × p) / d, w1 ≥ eps, w2 ≥ eps and w1 + w2 ≤ 1 − eps."""
    w1 = (px * e2y - py * e2x) / d
    w2 = (e1x * py - e1y * px) / d
    return (w1 >= eps) & (w2 >= eps) & (w1 + w2 <= 1 - eps)


ROW_BOXES = 16
ROW_FILL = 0.1
"""Triangles whose candidate square (:func:`_texels_inside`, k × k texels) is wider than ROW_BOXES texels and of which
at most ROW_FILL can be inside the triangle (its area, or its box cut to the map) are tested row by row: a sliver's
square is mostly empty (a cap's fan of 32 at 384², 0.02-0.1 of it: 3 times faster), as is that of a triangle
mostly beyond the map, a well-shaped triangle's is not (0.3-0.45: twice slower by rows)."""


def _texels_by_rows(idx, a, b, c, d, lo, hi, width, eps, chunk):
    """The texels of :func:`_texels_inside` for triangles ``idx`` (vertices ``a``, ``b``, ``c`` in texels, ``d`` twice
    their signed areas, ``lo``/``hi`` their candidate boxes): in each row y of a box, w1, w2 and 1 − w1 − w2 are
    linear in the centre's x, so the inequalities bound x to an interval; the texels of that interval widened by one
    and clipped to the box are tested as :func:`_texels_inside` tests them, in the same arithmetic, so the same centres
    are found. A bound is used only where its slope is over 1e-9 of the magnitude of the terms the test adds (its
    rounding then moves the bound by under 1e-6 texel); a slope below that (an edge a few ulps from horizontal)
    leaves that side to the box. Rows are taken ``chunk`` // 32 at a time."""
    ends = np.cumsum(hi[idx, 1] - lo[idx, 1] + 1)
    first = 0
    while first < len(idx):
        last = max(int(np.searchsorted(ends, (ends[first - 1] if first else 0) + max(chunk // 32, 1), "right")),
                   first + 1)
        yield from _rows_of(idx[first:last], a, b, c, d, lo, hi, width, eps, chunk)
        first = last


def _rows_of(idx, a, b, c, d, lo, hi, width, eps, chunk):
    """:func:`_texels_by_rows` for one block of triangles."""
    rows = hi[idx, 1] - lo[idx, 1] + 1
    tri = np.repeat(idx, rows)
    ys = lo[tri, 1] + np.arange(len(tri)) - np.repeat(np.cumsum(rows) - rows, rows)
    e1, e2, dd, at = b[tri] - a[tri], c[tri] - a[tri], d[tri], a[tri]
    py = ys + 0.5 - at[:, 1]
    slope = np.stack([e2[:, 1] / dd, -e1[:, 1] / dd], 1)                  # of w1, w2 in u = x + 0.5 - a_x
    base = np.stack([-py * e2[:, 0] / dd, e1[:, 0] * py / dd], 1)
    size = np.abs(base).sum(1) + np.abs(slope).sum(1) * (hi[tri, 0] - lo[tri, 0] + 2) + 1
    slope = np.concatenate([slope, -slope.sum(1, keepdims=True)], 1)     # 1 - w1 - w2
    base = np.concatenate([base, 1 - base.sum(1, keepdims=True)], 1)
    tight = np.abs(slope) > 1e-9 * size[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = (eps - base) / slope
    u_lo = np.where(tight & (slope > 0), bound, -np.inf).max(1)
    u_hi = np.where(tight & (slope < 0), bound, np.inf).min(1)
    x_lo = np.maximum(np.ceil(np.nan_to_num(u_lo + at[:, 0] - 0.5, neginf=-1e18)) - 1, lo[tri, 0])
    x_hi = np.minimum(np.floor(np.nan_to_num(u_hi + at[:, 0] - 0.5, posinf=1e18)) + 1, hi[tri, 0])
    count = np.maximum(x_hi - x_lo + 1, 0).astype(np.int64)
    ends = np.cumsum(count)
    start = 0
    while start < len(count):                                   # blocks of rows of at most ``chunk`` candidates
        stop = max(int(np.searchsorted(ends, (ends[start - 1] if start else 0) + chunk, "right")), start + 1)
        n = count[start:stop]
        row = np.repeat(np.arange(start, stop), n)
        xs = x_lo[row].astype(np.int64) + np.arange(len(row)) - np.repeat(np.cumsum(n) - n, n)
        y = ys[row]
        px, pyr = xs + 0.5 - at[row, 0], y + 0.5 - at[row, 1]
        inside = _inside(px, pyr, e1[row, 0], e1[row, 1], e2[row, 0], e2[row, 1], dd[row], eps)
        yield y[inside] * width + xs[inside]
        start = stop


def triangle_counts(tri_uv, width, height, strict=False):
    """(H, W) int32: how many UV triangles contain each texel centre (rule of :func:`_texels_inside`; with
    ``strict`` only interiors count, so triangles of one chart sharing an edge never both count a centre on
    it and a count ≥ 2 means overlapping charts)."""
    counts = np.zeros(height * width, np.int32)
    for flat in _texels_inside(tri_uv, width, height, strict):
        if 8 * len(flat) >= len(counts):                  # a block about the map's size: one pass over it
            counts += np.bincount(flat, minlength=len(counts)).astype(np.int32)
        else:
            np.add.at(counts, flat, 1)
    return counts.reshape(height, width)


def coverage_mask(tri_uv, width, height):
    """Boolean (H, W) mask of texels whose centre lies in at least one UV triangle (edges included)."""
    mask = np.zeros(height * width, bool)
    for flat in _texels_inside(tri_uv, width, height):
        mask[flat] = True
    return mask.reshape(height, width)


def overlap_fraction(tri_uv, width, height):
    """Fraction of the covered texels (:func:`coverage_mask`) whose centre lies inside two or more UV
    triangles (interiors, :func:`triangle_counts` ``strict``): texels the bake writes once for several
    faces. 0.0 for a layout without covered texels."""
    covered = int(coverage_mask(tri_uv, width, height).sum())
    if covered == 0:
        return 0.0
    return float((triangle_counts(tri_uv, width, height, strict=True) >= 2).sum()) / covered


# ---------------------------------------------------------------- closed shells

def shell_labels(tris, vertices=None):
    """(T,) shell index 0..K-1 of each triangle: triangles sharing a vertex belong to one shell
    (:func:`graph.components` of the vertices joined by the triangles' edges). Returns ``(labels, K)``."""
    tris = np.asarray(tris, np.int64).reshape(-1, 3)
    if not len(tris):
        return np.zeros(0, np.int64), 0
    n = int(tris.max()) + 1 if vertices is None else int(vertices)
    roots = components(tris.ravel(), np.repeat(tris[:, 0], 3), n)[tris[:, 0]]
    _, labels = np.unique(roots, return_inverse=True)
    return labels.ravel(), int(labels.max()) + 1


def closed_shells(tris, labels, count):
    """(K,) bool: shell k is closed and consistently wound: every directed edge (i, j) of its triangles
    appears once and its reverse (j, i) once (a watertight, orientable surface)."""
    tris = np.asarray(tris, np.int64).reshape(-1, 3)
    closed = np.ones(count, bool)
    if not len(tris):
        return closed
    i = tris.ravel()
    j = np.roll(tris, -1, axis=1).ravel()
    lab = np.repeat(labels, 3)
    n = int(tris.max()) + 1
    key = i * n + j
    rev = j * n + i
    order = np.sort(key)
    dup = np.zeros(len(key), bool)
    dup_keys = order[1:][order[1:] == order[:-1]]
    dup[np.isin(key, dup_keys)] = True
    open_ = ~np.isin(rev, key) | dup | (i == j)
    closed[np.unique(lab[open_])] = False
    return closed


def signed_volumes(co, tris, labels, count):
    """(K,) signed volume of each shell, V = Σ a·(b × c)/6 over its triangles abc: positive for a closed
    surface whose triangles wind counter-clockwise seen from outside (normals pointing out)."""
    co = np.asarray(co, float).reshape(-1, 3)
    t = co[np.asarray(tris, np.int64).reshape(-1, 3)]
    v = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6.0
    return np.bincount(labels, weights=v, minlength=count)


def inward_shells(co, tris):
    """Closed shells of a mesh whose normals point inward (negative :func:`signed_volumes`): their baked
    side faces the inside of a closed surface. Returns ``(labels (T,), inward (K,) bool, volumes (K,))``."""
    labels, count = shell_labels(tris, len(np.asarray(co).reshape(-1, 3)))
    if count == 0:
        return labels, np.zeros(0, bool), np.zeros(0)
    vol = signed_volumes(co, tris, labels, count)
    return labels, closed_shells(tris, labels, count) & (vol < 0), vol


# ---------------------------------------------------------------- dilation

_NEIGHBOURS = tuple((dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx)


def nearest_covered(mask, max_distance=None):
    """Flat index of a nearest covered texel for every texel (chessboard distance), -1 beyond ``max_distance``.

    Grows the covered set one 8-neighbour ring at a time; ring k holds exactly the texels at
    chessboard distance k, and a texel of ring k copies the source of a ring-(k−1) neighbour,
    which lies at distance ≤ (k−1) + 1 = k from it, hence is a nearest one. Only the frontier
    ring is touched, so the cost is proportional to the texels grown. Returns an (H, W) int array.
    """
    m = np.asarray(mask, bool)
    h, w = m.shape
    W = w + 2                                     # padded grid: a border ring (-2) is never free
    idx = np.int32 if (h + 2) * W < 2 ** 31 else np.int64
    src = np.full((h + 2, W), -2, idx)
    src[1:-1, 1:-1] = -1
    src = src.ravel()
    pm = np.zeros((h + 2, W), bool)
    pm[1:-1, 1:-1] = m
    covered = np.flatnonzero(pm).astype(idx)
    src[covered] = covered
    free = np.zeros((h + 2, W), bool)
    free[1:-1, 1:-1] = ~m
    edge = np.zeros((h + 2, W), bool)             # covered texels with an uncovered neighbour
    for dy, dx in _NEIGHBOURS:
        edge[1:-1, 1:-1] |= free[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
    front = np.flatnonzero(edge & pm).astype(idx)
    offsets = np.array([dy * W + dx for dy, dx in _NEIGHBOURS], idx)[:, None]
    rings = math.inf if max_distance is None else math.floor(max_distance)
    stamp = np.empty(src.size, idx)
    k = 0
    while front.size and k < rings:
        cand = (front[None, :] + offsets).ravel()
        parent = np.broadcast_to(src[front], (len(offsets), front.size)).ravel()
        keep = src[cand] == -1
        cand, parent = cand[keep], parent[keep]
        order = np.arange(cand.size, dtype=idx)
        stamp[cand] = order                       # one winner per texel (any parent is a nearest one)
        first = stamp[cand] == order
        front = cand[first]
        src[front] = parent[first]
        k += 1
    src = src.reshape(h + 2, W)[1:-1, 1:-1]
    # padded p = (r + 1) W + (c + 1)  ->  r w + c = p − 2 (p // W) − w − 1
    return np.where(src >= 0, src - 2 * (src // W) - (w + 1), -1)


def nearest_fill(values, mask, max_distance=None, source=None):
    """Copy each uncovered texel from its nearest covered texel (chessboard distance, in texels).

    Texels farther than ``max_distance`` keep their value. ``source``: :func:`nearest_covered` of ``mask`` and
    ``max_distance`` when the caller has it. Returns ``(values, filled_mask)``.
    """
    m = np.asarray(mask, bool)
    v = np.array(values, dtype=np.float32, copy=True)
    if not m.any() or m.all():
        return v, m.copy()
    src = (nearest_covered(m, max_distance) if source is None else source).ravel()
    grow = (src >= 0) & ~m.ravel()
    flat = v.reshape(m.size, -1)                  # a view of the fresh copy
    flat[grow] = flat[src[grow]]
    return v, (src >= 0).reshape(m.shape)


def dilate(values, mask, pixels, source=None):
    """Dilation by ``pixels`` texels beyond the covered ones (nearest covered value; ``source``: :func:`dilation_source`
    when the caller has it).

    A bilinear lookup across a UV seam then reads the chart's own border instead of
    black. Returns ``(values, grown_mask)``; covered texels keep their values.
    """
    return nearest_fill(values, mask, float(pixels) + 1e-6, source)


def dilation_source(mask, pixels):
    """:func:`nearest_covered` as :func:`dilate` by ``pixels`` texels reads it."""
    return nearest_covered(mask, float(pixels) + 1e-6)


def bilinear(image, uv):
    """Bilinear lookup of ``image`` (H, W[, C], row 0 at v = 0) at uv (N, 2), clamped at the border."""
    img = np.asarray(image, float)
    h, w = img.shape[:2]
    x = np.clip(np.asarray(uv, float)[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(np.asarray(uv, float)[:, 1] * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    if img.ndim == 3:
        fx, fy = fx[:, None], fy[:, None]
    return ((img[y0, x0] * (1 - fx) + img[y0, x1] * fx) * (1 - fy)
            + (img[y1, x0] * (1 - fx) + img[y1, x1] * fx) * fy)


# ---------------------------------------------------------------- Monte Carlo error (REFERENCE.md §3)

def binomial_sd(k_a, samples):
    """Standard deviation of a k_A estimate from N binary cosine samples: √(k_A(1 - k_A)/N)."""
    k = np.clip(np.asarray(k_a, float), 0.0, 1.0)
    return np.sqrt(k * (1.0 - k) / samples)


def rms(values, reference, mask=None):
    """Root-mean-square difference over ``mask`` (all texels when None)."""
    d = np.asarray(values, float) - np.asarray(reference, float)
    if mask is not None:
        d = d[np.asarray(mask, bool)]
    return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")


def per_sample_variance_ao(k_a, mask):
    """Mean over covered texels of k_A(1 - k_A): the variance of one binary AO sample (the binomial bound's σ²)."""
    k = np.clip(np.asarray(k_a, float)[np.asarray(mask, bool)], 0.0, 1.0)
    return float(np.mean(k * (1.0 - k))) if k.size else 0.0


def per_sample_variance_pair(a, b, samples_a, samples_b, mask):
    """Per-sample variance from two independent estimates a (N_a samples) and b (N_b) of one map.

    Var(a - b) = σ² (1/N_a + 1/N_b) per texel, so σ² = mean((a - b)²) / (1/N_a + 1/N_b)
    (mean over covered texels and channels).
    """
    m = np.asarray(mask, bool)
    d = (np.asarray(a, float) - np.asarray(b, float))[m]
    return float(np.mean(d * d) / (1.0 / samples_a + 1.0 / samples_b)) if d.size else 0.0


def samples_for_error(error_ref, samples_ref, target_error, alpha=0.5, minimum=1, maximum=65536):
    """Smallest N whose predicted RMS error meets ``target_error``, clamped to [minimum, maximum].

    err(N) = err_ref (N / N_ref)^-α  ->  N = ⌈N_ref (err_ref / target)^(1/α)⌉. α = 1/2 for independent
    samples (then N = σ²/E² with σ² = N_ref err_ref²); Cycles' stratified sampler converges faster
    (see :func:`convergence_exponent`).
    """
    if target_error <= 0:
        raise ValueError("target error must be positive")
    if error_ref <= 0:
        return int(min(max(samples_ref, minimum), maximum))
    log_n = math.log(samples_ref) + (math.log(error_ref) - math.log(target_error)) / alpha
    n = math.ceil(math.exp(min(log_n, math.log(maximum) + 1.0)) - 1e-9)
    return int(min(max(n, minimum), maximum))


SMALLEST_TARGET_ERROR = float(np.finfo(np.float32).tiny)
"""No target error below the smallest normal float32 (the maps' type): its square stays a normal float64."""


def smallest_target_error_binary(max_samples):
    """The smallest RMS error a target-error bake of a binary quantity (k_A) may ask for, before any bake.

    One binary sample has variance k_A(1 - k_A) ≤ 1/4, so err(1) ≤ 1/2, and stratified sampling improves it
    at most as N^-1 (:func:`convergence_exponent`'s upper clamp; Cycles measures N^-0.7): below 0.5 / max_samples
    no map but one of k_A = 0 or 1 everywhere reaches the target. The binomial bound of one bake,
    0.5 / √max_samples, is what max_samples guarantees; targets between the two are tried and reported capped
    when missed.
    """
    return max(0.5 / max(int(max_samples), 1), SMALLEST_TARGET_ERROR)


def smallest_target_error_unbounded(max_samples):
    """The smallest RMS error of a quantity without an a-priori bound on its variance (irradiance):
    SMALLEST_TARGET_ERROR (the pilot says the rest)."""
    return SMALLEST_TARGET_ERROR


def convergence_exponent(error_1, samples_1, error_2, samples_2, lowest=0.5, highest=1.0):
    """α of err(N) ∝ N^-α from two measured errors: α = ln(e_1/e_2) / ln(N_2/N_1), clamped to [lowest, highest].

    The lower clamp 1/2 is independent sampling (the safe assumption: it never predicts too few samples for a
    sampler at least as good); the upper clamp 1 is the best rate of stratified sampling of a smooth integrand.
    """
    if error_1 <= 0 or error_2 <= 0 or samples_2 == samples_1:
        return highest
    alpha = math.log(error_1 / error_2) / math.log(samples_2 / samples_1)
    return float(min(max(alpha, lowest), highest))


def expected_error(per_sample_variance, samples):
    """RMS Monte Carlo error √(σ²/N) of an N-sample estimate."""
    return math.sqrt(max(per_sample_variance, 0.0) / max(samples, 1))


def combine(estimates, weights):
    """Weighted mean Σ w_i x_i / Σ w_i of independent estimates x_i (w_i = N_i: all samples count alike)."""
    total = float(sum(weights))
    return sum(np.asarray(x, float) * (w / total) for x, w in zip(estimates, weights))


def inverse_variance_weights(errors):
    """Weights w_i = 1/e_i² for estimates of RMS errors e_i, and the error of their weighted mean.

    With these weights :func:`combine` has RMS error (Σ 1/e_i²)^(-1/2), the least of any weighting.
    A noise-free estimate (e_i = 0) takes all the weight. Returns ``(weights, error)``.
    """
    errors = [float(e) for e in errors]
    if min(errors) <= 0.0:
        first = errors.index(min(errors))
        return [1.0 if i == first else 0.0 for i in range(len(errors))], 0.0
    weights = [1.0 / (e * e) for e in errors]
    return weights, math.sqrt(1.0 / sum(weights))


# ---------------------------------------------------------------- closed forms (REFERENCE.md §3)

def view_factor_rect_corner(a, b, c):
    """Howell B-3: point under one corner of a parallel a × b rectangle at height c.

    X = a/c, Y = b/c, F = (1/2π)[X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))].
    """
    x, y = a / c, b / c
    sx, sy = math.sqrt(1 + x * x), math.sqrt(1 + y * y)
    return (x / sx * math.atan(y / sx) + y / sy * math.atan(x / sy)) / (2 * math.pi)


def view_factor_rect_centered(a, b, c):
    """Parallel a × b rectangle centred over the point at height c: four B-3 corners of a/2 × b/2."""
    return 4.0 * view_factor_rect_corner(a / 2.0, b / 2.0, c)


def view_factor_polygon(point, normal, vertices):
    """Lambert's formula: F = (1/2π) |Σ γ_i n·(R_i × R_{i+1})/|R_i × R_{i+1}||.

    ``vertices`` (K, 3) of a planar polygon wholly above the point's tangent plane;
    γ_i = angle between successive vertex directions R_i, R_{i+1}.
    """
    r = np.asarray(vertices, float) - np.asarray(point, float)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    r2 = np.roll(r, -1, axis=0)
    cross = np.cross(r, r2)
    norm = np.linalg.norm(cross, axis=1)
    gamma = np.arctan2(norm, np.einsum("ij,ij->i", r, r2))
    ok = norm > 1e-15
    s = np.sum(gamma[ok] * (cross[ok] @ np.asarray(normal, float)) / norm[ok])
    return float(abs(s) / (2 * math.pi))


def view_factor_convex(point, normal, faces):
    """View factor of a convex polyhedron: sum of Lambert's formula over the faces facing the point.

    ``faces`` is a list of (K, 3) vertex arrays wound counter-clockwise seen from outside.
    """
    p = np.asarray(point, float)
    total = 0.0
    for f in faces:
        f = np.asarray(f, float)
        n = np.cross(f[1] - f[0], f[2] - f[0])
        if np.dot(n, p - f[0]) > 1e-12:
            total += view_factor_polygon(p, normal, f)
    return total


def view_factors_convex(points, normal, faces):
    """:func:`view_factor_convex` at many ``points`` (N, 3) sharing one ``normal``, as an (N,) array: the same
    terms, summed in the same order."""
    p = np.asarray(points, float).reshape(-1, 3)
    nrm = np.asarray(normal, float)
    total = np.zeros(len(p))
    for f in faces:
        f = np.asarray(f, float)
        n = np.cross(f[1] - f[0], f[2] - f[0])
        facing = (p - f[0]) @ n > 1e-12
        if not facing.any():
            continue
        r = f[None] - p[facing, None]
        r /= np.linalg.norm(r, axis=2, keepdims=True)
        r2 = np.roll(r, -1, axis=1)
        cross = np.cross(r, r2)
        norm = np.linalg.norm(cross, axis=2)
        gamma = np.arctan2(norm, np.einsum("pij,pij->pi", r, r2))
        ok = norm > 1e-15
        terms = np.where(ok, gamma * (cross @ nrm) / np.where(ok, norm, 1.0), 0.0)
        total[facing] += np.abs(terms.sum(axis=1)) / (2 * math.pi)
    return total


def view_factor_long_wall(d, height):
    """Infinitely long wall of height H at distance d, parallel to the edge: F = (1 - d/√(d² + H²))/2."""
    return 0.5 * (1.0 - d / math.sqrt(d * d + height * height))


def view_factor_disk(radius, height):
    """Coaxial parallel disk of radius R at height h: F = R²/(R² + h²)."""
    return radius * radius / (radius * radius + height * height)


def view_factor_sphere(distance, cos_theta, radius):
    """Sphere of radius R whose centre is at ``distance`` D, angle θ from the normal, wholly above
    the tangent plane: F = (R/D)² cos θ (Howell B-? sphere from a tilted element, visible case)."""
    return (radius / distance) ** 2 * cos_theta


def irradiance_uniform_sky(radiance, k_a=1.0):
    """Uniform sky of radiance L seen over an unoccluded fraction k_A: E = π L k_A."""
    return math.pi * radiance * k_a


def irradiance_sun(strength, theta):
    """Sun of strength S (W/m² facing it) at angle θ from the normal: E = S cos θ."""
    return strength * np.maximum(np.cos(theta), 0.0)


def irradiance_point(power, distance, cos_theta):
    """Point light of power P W at distance d: E = P cos θ / (4π d²) (REFERENCE.md §1)."""
    return power * np.maximum(cos_theta, 0.0) / (4 * math.pi * np.square(distance))


def irradiance_enclosure(radiance, albedo, bounces):
    """Inside a closed diffuse enclosure of emitted radiance Le and albedo ρ, K diffuse bounces:
    E = π Le (1 - ρ^(K+1)) / (1 - ρ)  (π Le (K + 1) when ρ = 1)."""
    if albedo == 1.0:
        return math.pi * radiance * (bounces + 1)
    return math.pi * radiance * (1.0 - albedo ** (bounces + 1)) / (1.0 - albedo)
