"""Form factors (REFERENCE.md §3): point to polygon (Lambert), patch to patch, and the near field.

F_ij, the fraction of the energy leaving patch i that arrives on patch j. The
point form factor is exact (:func:`lambert_polygon`); the patch average uses
quadrature, adaptive where the pair is near (a pair whose bounding spheres are
closer than NEAR_RATIO times the receiver's diameter).
"""
import numpy as np

from ..errors import InputError
from .parallel import ordered_map
from .patches import bilinear, bounding_radius, polygon_area_normal


def clip_to_hemisphere(poly, point, normal, eps=1e-9):
    """Sutherland-Hodgman clip of polygons (..., k, 3) to the half-space n·(x - p) >= 0.

    Returns (..., 2k, 3) corners relative to ``point`` (invalid slots repeat the
    previous valid corner, so they form zero-length edges) and a mask of pairs
    with anything left in front of the plane.
    """
    r = poly - point[..., None, :]
    d = np.einsum("...mk,...k->...m", r, normal)
    rb, db = np.roll(r, -1, axis=-2), np.roll(d, -1, axis=-1)
    keep = d >= -eps
    cross = ((d > eps) & (db < -eps)) | ((d < -eps) & (db > eps))
    t = np.where(cross, d / np.where(cross, d - db, 1.0), 0.0)
    inter = r + (rb - r) * t[..., None]
    k = poly.shape[-2]
    slots = np.stack([r, inter], axis=-2).reshape(r.shape[:-2] + (2 * k, 3))
    valid = np.stack([keep, cross], axis=-1).reshape(d.shape[:-1] + (2 * k,))
    idx = np.where(valid, np.arange(2 * k), -1)
    idx = np.maximum.accumulate(idx, axis=-1)
    last = idx[..., -1:]
    idx = np.where(idx < 0, last, idx)
    idx = np.maximum(idx, 0)
    front = (d > eps).any(axis=-1)
    return np.take_along_axis(slots, idx[..., None], axis=-2), front


def lambert_polygon(rel, normal):
    """Point-to-polygon form factor (Lambert; REFERENCE.md §3): |Σ γ_m n·(R_m × R_{m+1})/|R_m × R_{m+1}|| / 2π.

    ``rel`` (..., k, 3): polygon corners relative to the point, all in front of it; ``normal`` (..., 3).
    Written on component arrays: it is the hot loop of the form factors.
    """
    rel = np.asarray(rel, np.float64)
    n = np.broadcast_to(normal, rel.shape[:-2] + (3,))
    x, y, z = rel[..., 0], rel[..., 1], rel[..., 2]
    inv = 1.0 / np.maximum(np.sqrt(x * x + y * y + z * z), 1e-300)
    x, y, z = x * inv, y * inv, z * inv
    x2, y2, z2 = np.roll(x, -1, -1), np.roll(y, -1, -1), np.roll(z, -1, -1)
    cx, cy, cz = y * z2 - z * y2, z * x2 - x * z2, x * y2 - y * x2
    s = np.sqrt(cx * cx + cy * cy + cz * cz)
    gamma = np.arctan2(s, x * x2 + y * y2 + z * z2)
    proj = cx * n[..., None, 0] + cy * n[..., None, 1] + cz * n[..., None, 2]
    term = np.where(s > 1e-12, gamma * proj / np.maximum(s, 1e-300), 0.0)
    return np.abs(term.sum(axis=-1)) / (2 * np.pi)


def polygon_form_factors(rel, normals, polygon_normals):
    """F(dA_p -> polygon) of points to polygons given by their corners relative to the point: ``rel``
    (..., k, 3), the points' ``normals`` and the polygons' ``polygon_normals`` broadcasting to (..., 3) -> (...).

    The rules of every point form factor here: only the front side of a polygon emits (the point must
    lie in front of its plane); polygons crossing the point's tangent plane are clipped to its
    hemisphere (:func:`clip_to_hemisphere`); coplanar and behind polygons give 0.
    """
    shape = rel.shape[:-2]
    n = np.broadcast_to(normals, shape + (3,))
    pn = np.broadcast_to(polygon_normals, shape + (3,))
    d = rel[..., 0] * n[..., None, 0] + rel[..., 1] * n[..., None, 1] + rel[..., 2] * n[..., None, 2]
    facing = -(rel[..., 0, 0] * pn[..., 0] + rel[..., 0, 1] * pn[..., 1] + rel[..., 0, 2] * pn[..., 2]) > 1e-9
    front = (d > 1e-9).any(axis=-1) & facing
    simple = front & (d >= -1e-9).all(axis=-1)
    out = np.zeros(shape)
    if simple.any():
        out[simple] = lambert_polygon(rel[simple], n[simple])
    clip = front & ~simple
    if clip.any():
        clipped, _ = clip_to_hemisphere(rel[clip], np.zeros((int(clip.sum()), 3)), n[clip])
        out[clip] = lambert_polygon(clipped, n[clip])
    return out


def point_polygon_form_factors(points, normals, polys, chunk_elems=4_000_000):
    """F(dA_p -> polygon j) for every point (P, 3) with normal (P, 3) and polygon (Q, k, 3): (P, Q),
    by the rules of :func:`polygon_form_factors`."""
    points, normals, polys = (np.asarray(a, np.float64) for a in (points, normals, polys))
    P, Q, k = len(points), len(polys), polys.shape[1]
    _, pn = polygon_area_normal(polys)
    out = np.zeros((P, Q))
    step = max(1, int(chunk_elems // (Q * k)))
    for s in range(0, P, step):
        p, n = points[s:s + step], normals[s:s + step]
        r = polys[None] - p[:, None, None, :]                          # (p, Q, k, 3)
        out[s:s + step] = polygon_form_factors(r, n[:, None, :], pn[None])
    return out


def quadrature_points(patches, q):
    """q×q points per patch and their weights (N, q², 3), (N, q²) summing to 1 (area-weighted cells)."""
    c = patches.corners
    if q <= 1:
        return patches.center[:, None, :], np.ones((len(c), 1))
    g = (np.arange(q) + 0.5) / q
    s, t = np.meshgrid(g, g, indexing="ij")
    s, t = s.ravel(), t.ravel()
    # quads: bilinear map of the unit square, weight = |Jacobian| at the cell centre
    pq = (((1 - s) * (1 - t))[None, :, None] * c[:, 0, None] + (s * (1 - t))[None, :, None] * c[:, 1, None]
          + (s * t)[None, :, None] * c[:, 2, None] + ((1 - s) * t)[None, :, None] * c[:, 3, None])
    ds = ((1 - t)[None, :, None] * (c[:, 1, None] - c[:, 0, None]) + t[None, :, None] * (c[:, 2, None] - c[:, 3, None]))
    dt = ((1 - s)[None, :, None] * (c[:, 3, None] - c[:, 0, None]) + s[None, :, None] * (c[:, 2, None] - c[:, 1, None]))
    wq = np.linalg.norm(np.cross(ds, dt), axis=-1)
    # triangles: centroids of the q² sub-triangles of a regular split (equal areas)
    bary = []
    for i in range(q):
        for j in range(q - i):
            bary.append(((i + 1 / 3) / q, (j + 1 / 3) / q))
            if i + j < q - 1:
                bary.append(((i + 2 / 3) / q, (j + 2 / 3) / q))
    b = np.array(bary)
    pt = (c[:, 0, None] + b[None, :, 0, None] * (c[:, 1, None] - c[:, 0, None])
          + b[None, :, 1, None] * (c[:, 2, None] - c[:, 0, None]))
    tri = patches.is_tri[:, None]
    pts = np.where(tri[..., None], pt, pq)
    w = np.where(tri, 1.0, wq)
    return pts, w / w.sum(axis=1, keepdims=True)


def form_factors(patches, visibility=None, quadrature=1):
    """F_ij = Σ_q w_q F(dA_q -> P_j) · V_ij (seed 004's double integral with the inner one exact).

    ``visibility`` (N, N) in [0, 1] or bool (1 = unoccluded; None = all visible) is
    supplied by the caller (the bpy side casts the rays). ``quadrature`` q
    integrates over patch i with q×q points: reciprocity A_i F_ij = A_j F_ji
    improves as q grows. The diagonal is 0 (planar patches). Memory: the (N, N)
    result plus bounded chunks.
    """
    n = len(patches)
    if visibility is not None and np.shape(visibility) != (n, n):
        raise InputError(f"visibility must be {n}x{n}, got {np.shape(visibility)}")
    pts, w = quadrature_points(patches, quadrature)
    m = pts.shape[1]
    if m == 1:
        F = point_polygon_form_factors(pts[:, 0], patches.normal, patches.corners)
    else:
        ff = point_polygon_form_factors(pts.reshape(-1, 3), np.repeat(patches.normal, m, axis=0), patches.corners)
        F = (ff.reshape(n, m, n) * w[..., None]).sum(axis=1)
        del ff
    np.fill_diagonal(F, 0.0)
    if visibility is not None:
        V = np.asarray(visibility)
        np.multiply(F, V, out=F, casting="unsafe")
    return F


def pair_form_factors(cx, cy, cz, pn, p, n, j):
    """F(dA_p -> polygon j) for matching rows (polygon corners cx, cy, cz (N, 4) by component, their normals
    pn; points p and normals n (M, 3); source indices j (M,)) by the rules of :func:`polygon_form_factors`,
    on component arrays (:func:`lambert_polygon` without its temporaries); pairs whose polygon crosses the
    point's tangent plane go through :func:`polygon_form_factors` (clipped)."""
    x = np.take(cx, j, axis=0) - p[:, 0:1]           # np.take: a row gather several times faster than cx[j]
    y = np.take(cy, j, axis=0) - p[:, 1:2]
    z = np.take(cz, j, axis=0) - p[:, 2:3]
    nx, ny, nz = n[:, 0:1], n[:, 1:2], n[:, 2:3]
    d = x * nx + y * ny + z * nz
    pj = np.take(pn, j, axis=0)
    facing = -(x[:, 0] * pj[:, 0] + y[:, 0] * pj[:, 1] + z[:, 0] * pj[:, 2]) > 1e-9
    front = (d > 1e-9).any(axis=1) & facing
    simple = front & (d >= -1e-9).all(axis=1)
    inv = 1.0 / np.maximum(np.sqrt(x * x + y * y + z * z), 1e-300)
    x *= inv
    y *= inv
    z *= inv
    out = np.zeros(len(j))
    for m in range(4):
        k = (m + 1) % 4
        ax, ay, az, bx, by, bz = x[:, m], y[:, m], z[:, m], x[:, k], y[:, k], z[:, k]
        qx, qy, qz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        sn = np.sqrt(qx * qx + qy * qy + qz * qz)
        g = np.arctan2(sn, ax * bx + ay * by + az * bz)
        proj = qx * nx[:, 0] + qy * ny[:, 0] + qz * nz[:, 0]
        out += np.where(sn > 1e-12, g * proj / np.maximum(sn, 1e-300), 0.0)
    out = np.where(simple, np.abs(out) / (2 * np.pi), 0.0)
    clip = front & ~simple
    if clip.any():
        rel = np.stack([cx[j[clip]], cy[j[clip]], cz[j[clip]]], -1) - p[clip][:, None, :]
        out[clip] = polygon_form_factors(rel, n[clip], pn[j[clip]])
    return out


def visible_form_factors(patches, visibility, reciprocal=True, chunk_pairs=50_000, dtype=np.float64, progress=None):
    """:func:`form_factors` (quadrature 1) with boolean ``visibility`` (N, N, symmetric), evaluated only for
    the visible pairs (the rest are 0 in both: pairs behind each other's plane, occluded, or on one plane).

    ``reciprocal``: each pair once, from the smaller patch's centre s to the larger patch b, and the other way
    by reciprocity, F_bs = A_s F_sb / A_b: half the work, A_i F_ij = A_j F_ji exactly, and the collocation
    error of the centre rule O((r_s / d)²) set by the smaller patch instead of O((r_b / d)²) by the larger.
    Otherwise every visible ordered pair from its receiver's centre, equal to :func:`form_factors`. About
    ``chunk_pairs`` pairs at a time. ``dtype``: F's storage (float32 halves its memory and the solvers' memory
    traffic, core.radiosity.solvers.product). ``progress(done, total)`` is called after each chunk."""
    n = len(patches)
    V = np.asarray(visibility, bool)
    if V.shape != (n, n):
        raise InputError(f"visibility must be {n}x{n}, got {V.shape}")
    F = np.zeros((n, n), dtype)
    _, pn = polygon_area_normal(patches.corners)
    c, area = patches.corners, patches.area
    cx, cy, cz = (np.ascontiguousarray(c[..., k]) for k in range(3))
    per_row = V.sum(axis=1) if not reciprocal else np.array([V[r, r + 1:].sum() for r in range(n)])
    cum = np.concatenate([[0], np.cumsum(per_row)])
    bounds, s = [], 0
    while s < n:
        e = max(s + 1, int(np.searchsorted(cum, cum[s] + chunk_pairs, side="right")) - 1)
        bounds.append((s, e))
        s = e

    def chunk(se):
        s, e = se
        i, j = np.nonzero(V[s:e])
        i += s
        if reciprocal:
            up = j > i
            i, j = i[up], j[up]
            small = area[i] <= area[j]
            i, j = np.where(small, i, j), np.where(small, j, i)
        return i, j, pair_form_factors(cx, cy, cz, pn, np.take(patches.center, i, axis=0),
                                       np.take(patches.normal, i, axis=0), j)
    for k, (r, q, f) in enumerate(ordered_map(chunk, bounds)):
        F[r, q] = f
        if reciprocal:
            F[q, r] = f * area[r] / area[q]
        if progress:
            progress(k + 1, len(bounds))
    np.fill_diagonal(F, 0.0)
    return F


# A pair (receiver i, source j) is near when the gap between their bounding spheres is below NEAR_RATIO
# times i's diameter: there F(dA_x -> P_j) changes over patch i by more than its centre value can stand for
# (the midpoint rule's relative error grows as (diameter / distance)²; for touching or overlapping patches,
# e.g. a light 1 mm under a ceiling, the integrand is a step). Those pairs are gathered texel by texel
# (core.radiosity.gather).
NEAR_RATIO = 1.0
NEAR_PEAK_BYTES = 400e6    # the arrays of one chunk of element form factors


def near_pairs(patches, i, j, ratio=NEAR_RATIO):
    """Ordered (receiver, source) index arrays, both ways round, of the pairs among (i, j) that are near:
    bounding-sphere gap |c_i − c_j| − r_i − r_j below ``ratio`` × the receiver's diameter 2 r_i."""
    i, j = np.asarray(i, int), np.asarray(j, int)
    r = bounding_radius(patches)
    gap = np.linalg.norm(np.take(patches.center, i, axis=0) - np.take(patches.center, j, axis=0), axis=1) - r[i] - r[j]
    a = gap < ratio * 2 * r[i]
    b = gap < ratio * 2 * r[j]
    return np.concatenate([i[a], j[b]]), np.concatenate([j[a], i[b]])


def pointwise_form_factors(points, normals, polys):
    """F(dA_m -> polygon m) for matching rows: points (M, 3), normals (M, 3), polygons (M, k, 3) -> (M,),
    by the rules of :func:`polygon_form_factors`."""
    points, normals, polys = (np.asarray(a, np.float64) for a in (points, normals, polys))
    _, pn = polygon_area_normal(polys)
    return polygon_form_factors(polys - points[:, None, :], normals, pn)


def seen_form_factors(patches, points, normals, src, visible=None):
    """F(dA_m -> patch src_m) V(x_m, src_m) for matching rows: points (M, 3), normals (M, 3), source patch
    indices (M,) -> (M,). ``visible(points, normals, src)`` (1 where the ray reaches the source) is asked
    only where the form factor is not 0; None: all visible."""
    v = pointwise_form_factors(points, normals, patches.corners[src])
    if visible is not None:
        hit = v > 0
        if hit.any():
            v[hit] = v[hit] * visible(points[hit], normals[hit], src[hit])
    return v
