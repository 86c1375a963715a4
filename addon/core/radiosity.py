"""Radiosity (seed 004; Goral et al. 1984; Cohen et al. 1988; REFERENCE.md §3).

Discrete radiosity equation, per colour channel:

    B_i = E_i + ρ_i Σ_j F_ij B_j

B_i radiosity (exitance, W/m²), E_i emitted exitance (π L_e for a Lambertian
emitter of radiance L_e), ρ_i diffuse albedo, F_ij the form factor from patch i
to patch j. The irradiance arriving on patch i is H_i = Σ_j F_ij B_j (what a
Cycles irradiance bake measures: E = π × DIFFUSE bake, REFERENCE.md §1).

Patches are convex planar polygons stored as quads (F, 4, 3); a triangle
repeats its last vertex (a zero-length edge adds nothing to any sum here).
"""
import time
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError


# ----------------------------------------------------------------------------
# Patches


@dataclass
class Patches:
    """Flat list of patches. ``corners`` (N, 4, 3); ``rho``, ``emission`` (N, 3); ``owner`` (N,) object index;
    ``is_tri`` (N,) bool; ``source`` (N,) index of the input face each patch came from."""
    corners: np.ndarray
    rho: np.ndarray
    emission: np.ndarray
    owner: np.ndarray
    is_tri: np.ndarray
    source: np.ndarray
    names: list = field(default_factory=list)

    def __post_init__(self):
        self.area, self.normal = polygon_area_normal(self.corners)
        self.center = polygon_centroid(self.corners, self.is_tri)

    def __len__(self):
        return len(self.corners)

    def take(self, idx):
        """The patches at ``idx`` (index array or mask), object names kept."""
        return Patches(self.corners[idx], self.rho[idx], self.emission[idx], self.owner[idx],
                       self.is_tri[idx], self.source[idx], self.names)


def polygon_area_normal(corners):
    """Newell's method: area = |Σ v_m × v_{m+1}|/2, unit normal along it (right-hand winding)."""
    c = np.asarray(corners, np.float64)
    s = np.cross(c, np.roll(c, -1, axis=-2)).sum(axis=-2) / 2
    area = np.linalg.norm(s, axis=-1)
    return area, s / np.maximum(area, 1e-300)[..., None]


def polygon_centroid(corners, is_tri):
    """Area centroid of a triangle (mean of 3 vertices) or a convex quad (area-weighted triangle centroids)."""
    c = np.asarray(corners, np.float64)
    t1 = (c[:, 0] + c[:, 1] + c[:, 2]) / 3
    t2 = (c[:, 0] + c[:, 2] + c[:, 3]) / 3
    a1 = np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=-1)
    a2 = np.linalg.norm(np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 0]), axis=-1)
    a2 = np.where(is_tri, 0.0, a2)
    return (t1 * a1[:, None] + t2 * a2[:, None]) / np.maximum(a1 + a2, 1e-300)[:, None]


def patches_from_meshes(meshes):
    """``meshes``: list of dicts {"name", "vertices" (V, 3), "faces" (list of 3- or 4-index tuples),
    "rho" (3,) or (F, 3), "emission" (3,) or (F, 3) emitted RADIANCE L_e} -> :class:`Patches`.

    Emitted exitance E_i = π L_e (Lambertian emitter). Polygons with more than four
    corners are fanned into triangles.
    """
    corners, rho, em, owner, tri, source, names = [], [], [], [], [], [], []
    for k, m in enumerate(meshes):
        v = np.asarray(m["vertices"], np.float64)
        faces = m["faces"]
        r = np.broadcast_to(np.asarray(m.get("rho", 0.5), np.float64), (len(faces), 3))
        e = np.broadcast_to(np.asarray(m.get("emission", 0.0), np.float64), (len(faces), 3))
        names.append(m.get("name", f"mesh{k}"))
        for fi, f in enumerate(faces):
            f = list(f)
            pieces = [f] if len(f) <= 4 else [[f[0], f[i], f[i + 1]] for i in range(1, len(f) - 1)]
            for p in pieces:
                if len(p) < 3:
                    raise InputError(f"{names[-1]}: face {fi} has fewer than 3 vertices")
                q = p + [p[-1]] if len(p) == 3 else p
                corners.append(v[q])
                rho.append(r[fi])
                em.append(e[fi] * np.pi)
                owner.append(k)
                tri.append(len(p) == 3)
                source.append(fi)
    if not corners:
        raise InputError("no faces to make patches from")
    p = Patches(np.array(corners), np.array(rho), np.array(em), np.array(owner),
                np.array(tri), np.array(source), names)
    if np.any(p.area <= 0):
        raise InputError(f"{int(np.sum(p.area <= 0))} faces have zero area")
    if np.any((p.rho < 0) | (p.rho >= 1)):
        raise InputError("albedo rho must be in [0, 1) for the solution to exist")
    return p


def split(patches, mask=None):
    """Split the masked patches (all by default) into four: quads at edge midpoints and centre,
    triangles at edge midpoints. Returns (new patches, parent index of each new patch)."""
    n = len(patches)
    mask = np.ones(n, bool) if mask is None else np.asarray(mask, bool)
    c = patches.corners
    keep = np.flatnonzero(~mask)
    quads = np.flatnonzero(mask & ~patches.is_tri)
    tris = np.flatnonzero(mask & patches.is_tri)
    parts, parents, tri_flags = [c[keep]], [keep], [patches.is_tri[keep]]
    if len(quads):
        q = c[quads]
        m01, m12, m23, m30 = [(q[:, i] + q[:, (i + 1) % 4]) / 2 for i in range(4)]
        mid = q.mean(axis=1)
        for a in ((q[:, 0], m01, mid, m30), (m01, q[:, 1], m12, mid),
                  (mid, m12, q[:, 2], m23), (m30, mid, m23, q[:, 3])):
            parts.append(np.stack(a, axis=1))
            parents.append(quads)
            tri_flags.append(np.zeros(len(quads), bool))
    if len(tris):
        t = c[tris]
        m01, m12, m20 = (t[:, 0] + t[:, 1]) / 2, (t[:, 1] + t[:, 2]) / 2, (t[:, 2] + t[:, 0]) / 2
        for a in ((t[:, 0], m01, m20), (m01, t[:, 1], m12), (m20, m12, t[:, 2]), (m01, m12, m20)):
            parts.append(np.stack(a + (a[-1],), axis=1))
            parents.append(tris)
            tri_flags.append(np.ones(len(tris), bool))
    parent = np.concatenate(parents)
    out = Patches(np.concatenate(parts), patches.rho[parent], patches.emission[parent],
                  patches.owner[parent], np.concatenate(tri_flags), patches.source[parent], patches.names)
    order = np.argsort(parent, kind="stable")  # keep each object's patches together, in input order
    return out.take(order), parent[order]


def subdivide_to_size(patches, max_edge):
    """Split every patch in four until its longest edge is at most ``max_edge``."""
    if max_edge <= 0:
        raise InputError(f"max_edge must be positive, got {max_edge}")
    for _ in range(20):
        mask = longest_edge(patches.corners) > max_edge
        if not mask.any():
            return patches
        patches, _ = split(patches, mask)
    return patches


def longest_edge(corners):
    """Longest edge length of each polygon (N,)."""
    return np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=-1).max(axis=1)


# ----------------------------------------------------------------------------
# Form factors


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


def point_polygon_form_factors(points, normals, polys, chunk_elems=4_000_000):
    """F(dA_p -> polygon j) for every point (P, 3) with normal (P, 3) and polygon (Q, k, 3): (P, Q).

    Only the front side of polygon j emits (the point must lie in front of j's
    plane); polygons crossing the point's tangent plane are clipped to its
    hemisphere; coplanar and behind polygons give 0.
    """
    points, normals, polys = (np.asarray(a, np.float64) for a in (points, normals, polys))
    P, Q, k = len(points), len(polys), polys.shape[1]
    _, pn = polygon_area_normal(polys)
    out = np.zeros((P, Q))
    step = max(1, int(chunk_elems // (Q * k)))
    for s in range(0, P, step):
        p, n = points[s:s + step], normals[s:s + step]
        r = polys[None] - p[:, None, None, :]                          # (p, Q, k, 3)
        d = r[..., 0] * n[:, None, None, 0] + r[..., 1] * n[:, None, None, 1] + r[..., 2] * n[:, None, None, 2]
        facing = -(r[..., 0, 0] * pn[None, :, 0] + r[..., 0, 1] * pn[None, :, 1] + r[..., 0, 2] * pn[None, :, 2]) > 1e-9
        front = (d > 1e-9).any(axis=-1) & facing
        simple = front & (d >= -1e-9).all(axis=-1)
        block = np.zeros(front.shape)
        block[simple] = lambert_polygon(r[simple], np.broadcast_to(n[:, None, :], front.shape + (3,))[simple])
        clip = front & ~simple
        if clip.any():
            pi, qi = np.nonzero(clip)
            rel, _ = clip_to_hemisphere(polys[qi], p[pi], n[pi])
            block[pi, qi] = lambert_polygon(rel, n[pi])
        out[s:s + step] = block
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

    ``visibility`` (N, N) in [0, 1] (1 = unoccluded; None = all visible) is
    supplied by the caller (the bpy side casts the rays). ``quadrature`` q
    integrates over patch i with q×q points: reciprocity A_i F_ij = A_j F_ji
    improves as q grows. The diagonal is 0 (planar patches).
    """
    n = len(patches)
    pts, w = quadrature_points(patches, quadrature)
    m = pts.shape[1]
    ff = point_polygon_form_factors(pts.reshape(-1, 3), np.repeat(patches.normal, m, axis=0), patches.corners)
    F = (ff.reshape(n, m, n) * w[..., None]).sum(axis=1)
    np.fill_diagonal(F, 0.0)
    if visibility is not None:
        V = np.asarray(visibility, np.float64)
        if V.shape != (n, n):
            raise InputError(f"visibility must be {n}x{n}, got {V.shape}")
        F *= V
    return F


def candidate_pairs(patches):
    """Pairs i < j that can exchange light (each in front of the other's plane): the rays worth casting."""
    c, nrm = patches.center, patches.normal
    d = c[None, :, :] - c[:, None, :]
    front_j = np.einsum("ijk,ik->ij", d, nrm) > 1e-9       # j in front of i
    front_i = np.einsum("ijk,jk->ij", -d, nrm) > 1e-9      # i in front of j
    i, j = np.nonzero(np.triu(front_j & front_i, 1))
    return i, j


def ray_triangle_hits(origins, targets, tris, eps=1e-7):
    """Möller-Trumbore: does the open segment origin->target hit any triangle (T, 3, 3)? (S,) bool.

    A brute-force numpy occlusion test for small scenes and tests; Blender's
    BVHTree does the same for big ones.
    """
    o = np.asarray(origins, np.float64)
    dvec = np.asarray(targets, np.float64) - o
    tris = np.asarray(tris, np.float64)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    hit = np.zeros(len(o), bool)
    for s in range(0, len(o), 2048):
        D, O = dvec[s:s + 2048, None, :], o[s:s + 2048, None, :]
        pv = np.cross(D, e2[None])
        det = np.einsum("stk,tk->st", pv, e1)
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = O - tris[None, :, 0]
        u = np.einsum("stk,stk->st", tv, pv) * inv
        qv = np.cross(tv, e1[None])
        v = np.einsum("stk,sk->st", qv, dvec[s:s + 2048]) * inv
        t = np.einsum("stk,tk->st", qv, e2) * inv
        h = ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 1e-6) & (t < 1 - 1e-6)
        hit[s:s + 2048] = h.any(axis=1)
    return hit


def patch_triangles(patches):
    """Each patch as one (triangle) or two (quad) triangles (T, 3, 3), for occlusion tests."""
    c = patches.corners
    t1 = c[:, [0, 1, 2]]
    t2 = c[~patches.is_tri][:, [0, 2, 3]]
    return np.concatenate([t1, t2])


def visibility_numpy(patches, offset=1e-6):
    """Centre-to-centre visibility matrix (N, N) by brute-force ray casting against the patches themselves."""
    n = len(patches)
    V = np.zeros((n, n))
    i, j = candidate_pairs(patches)
    if len(i):
        o = patches.center[i] + offset * patches.normal[i]
        t = patches.center[j] + offset * patches.normal[j]
        vis = ~ray_triangle_hits(o, t, patch_triangles(patches))
        V[i, j] = V[j, i] = vis
    return V


# ----------------------------------------------------------------------------
# Solvers


@dataclass
class Solution:
    """B (N, 3) radiosity in W/m²; ``residuals``: relative residual |E + ρFB − B|/|E| after each iteration."""
    B: np.ndarray
    solver: str
    iterations: int
    residuals: list
    seconds: float
    converged: bool


def residual(F, rho, E, B, FB=None):
    """Relative residual of the radiosity equation: ‖E + ρ ∘ (F B) − B‖ / ‖E‖ (``FB`` = F B if already known)."""
    FB = F @ B if FB is None else FB
    return float(np.linalg.norm(E + rho * FB - B) / max(np.linalg.norm(E), 1e-300))


def _check(F, rho, E):
    F, rho, E = (np.asarray(a, np.float64) for a in (F, rho, E))
    if F.ndim != 2 or F.shape[0] != F.shape[1] or E.shape != rho.shape or E.shape[0] != F.shape[0]:
        raise InputError(f"shapes do not match: F {F.shape}, rho {rho.shape}, E {E.shape}")
    if not np.any(E):
        raise InputError("nothing emits light: every E_i is 0")
    return F, rho, E


def solve_direct(F, rho, E):
    """B = (I − diag(ρ) F)⁻¹ E per channel (the reference answer)."""
    F, rho, E = _check(F, rho, E)
    t = time.perf_counter()
    n = len(F)
    B = np.stack([np.linalg.solve(np.eye(n) - rho[:, c, None] * F, E[:, c]) for c in range(E.shape[1])], axis=1)
    return Solution(B, "direct", 1, [residual(F, rho, E, B)], time.perf_counter() - t, True)


def solve_jacobi(F, rho, E, tol=1e-6, max_iter=10000):
    """Jacobi: B^{k+1} = E + ρ ∘ (F B^k) from B⁰ = E; iteration k adds the k-th bounce."""
    F, rho, E = _check(F, rho, E)
    t = time.perf_counter()
    B, res = E.copy(), []
    FB = F @ B
    for k in range(1, max_iter + 1):
        B = E + rho * FB
        FB = F @ B                                    # the residual's product is the next sweep's
        res.append(residual(F, rho, E, B, FB))
        if res[-1] < tol:
            break
    return Solution(B, "jacobi", len(res), res, time.perf_counter() - t, res[-1] < tol)


def solve_gauss_seidel(F, rho, E, tol=1e-6, max_iter=10000):
    """Gauss-Seidel: one sweep updates every B_i in place, in order, with the newest B_j:

        B_i ← (E_i + ρ_i Σ_{j≠i} F_ij B_j) / (1 − ρ_i F_ii)

    i.e. (I − D − L) B^{k+1} = E + U B^k with ρF = L + D + U (strictly lower, diagonal,
    strictly upper); F_ii = 0 for flat patches.
    """
    F, rho, E = _check(F, rho, E)
    t = time.perf_counter()
    B, res = E.copy(), []
    off = F.copy()
    np.fill_diagonal(off, 0.0)
    scale = rho / (1.0 - rho * np.diag(F)[:, None])    # ρ_i / (1 − ρ_i F_ii), per channel
    base = E / (1.0 - rho * np.diag(F)[:, None])
    for k in range(1, max_iter + 1):
        for i in range(len(F)):
            B[i] = base[i] + scale[i] * (off[i] @ B)
        res.append(residual(F, rho, E, B))
        if res[-1] < tol:
            break
    return Solution(B, "gauss_seidel", len(res), res, time.perf_counter() - t, res[-1] < tol)


def solve_progressive(F, rho, E, area, tol=1e-6, max_iter=None, record_every=None):
    """Progressive refinement (Cohen et al. 1988): shoot the patch with the most unshot power ΔB_i A_i;
    every j receives ΔB_j += ρ_j F_ji ΔB_i. One iteration = one shot.

    Stops when the unshot power is below ``tol`` times the emitted power; the
    residual equals ‖ρ ∘ F ΔB‖/‖E‖, recorded every ``record_every`` shots.
    """
    F, rho, E = _check(F, rho, E)
    area = np.asarray(area, np.float64)
    t = time.perf_counter()
    n = len(F)
    max_iter = max_iter or 200 * n
    record_every = record_every or max(1, n // 10)
    B, dB = E.copy(), E.copy()
    total = float((E.sum(axis=1) * area).sum())
    power = dB.sum(axis=1) * area
    res, shots, done = [], 0, False
    nE = max(np.linalg.norm(E), 1e-300)
    for shots in range(1, max_iter + 1):
        i = int(np.argmax(power))
        shoot = dB[i].copy()
        gain = rho * (F[:, i, None] * shoot[None, :])
        B += gain
        dB += gain
        dB[i] = 0.0
        power = dB.sum(axis=1) * area
        if shots % record_every == 0 or power.sum() <= tol * total:
            res.append(float(np.linalg.norm(rho * (F @ dB)) / nE))
        if power.sum() <= tol * total:
            done = True
            break
    return Solution(B, "progressive", shots, res, time.perf_counter() - t, done)


SOLVERS = ("jacobi", "gauss_seidel", "progressive")


def solve(F, rho, E, area, solver="jacobi", tol=1e-6, max_iter=None):
    """Dispatch by name: jacobi, gauss_seidel, progressive (or direct)."""
    if solver == "jacobi":
        return solve_jacobi(F, rho, E, tol, max_iter or 10000)
    if solver == "gauss_seidel":
        return solve_gauss_seidel(F, rho, E, tol, max_iter or 10000)
    if solver == "progressive":
        return solve_progressive(F, rho, E, area, tol, max_iter)
    if solver == "direct":
        return solve_direct(F, rho, E)
    raise InputError(f"unknown solver {solver!r}; choose from {', '.join(SOLVERS)}")


def irradiance(F, B):
    """Incident irradiance H_i = Σ_j F_ij B_j (W/m²): what a white Lambertian patch receives."""
    return F @ B


# ----------------------------------------------------------------------------
# Adaptive subdivision


def vertex_keys(points, scale=1e6):
    """Integer keys of positions rounded to 1/scale: equal keys = same vertex."""
    return np.round(np.asarray(points) * scale).astype(np.int64)


def neighbours(patches):
    """Pairs (a, b), a < b, of patches that share a corner position (same object)."""
    keys = vertex_keys(patches.corners.reshape(-1, 3))
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    pid = np.repeat(np.arange(len(patches)), 4)
    order = np.argsort(inv, kind="stable")
    inv_s, pid_s = inv[order], pid[order]
    pairs = set()
    starts = np.flatnonzero(np.r_[True, inv_s[1:] != inv_s[:-1]])
    ends = np.r_[starts[1:], len(inv_s)]
    for s, e in zip(starts, ends):
        ids = np.unique(pid_s[s:e])
        for x in range(len(ids)):
            for y in range(x + 1, len(ids)):
                if patches.owner[ids[x]] == patches.owner[ids[y]]:
                    pairs.add((int(ids[x]), int(ids[y])))
    if not pairs:
        return np.zeros((0, 2), int)
    return np.array(sorted(pairs))


def refine_mask(patches, values, threshold=0.2, min_area=0.0):
    """Patches to split: where the solution changes fast, i.e. some neighbour differs by more than
    ``threshold`` times the pair's mean (luminance of ``values`` (N, 3)); never below ``min_area``."""
    y = np.asarray(values, np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    pairs = neighbours(patches)
    mask = np.zeros(len(patches), bool)
    if len(pairs):
        a, b = pairs[:, 0], pairs[:, 1]
        jump = np.abs(y[a] - y[b]) > threshold * np.maximum((y[a] + y[b]) / 2, 1e-12)
        mask[a[jump]] = True
        mask[b[jump]] = True
    return mask & (patches.area > 4 * min_area)


# ----------------------------------------------------------------------------
# Outputs: per-vertex values and the light-map atlas


def vertex_average(patches, values):
    """Area-weighted average of patch ``values`` at each welded corner position, per object.

    Returns (corner values (N, 4, C), unique positions (V, 3), corner -> unique index (N, 4)).
    """
    values = np.asarray(values, np.float64)
    keys = np.concatenate([vertex_keys(patches.corners.reshape(-1, 3)),
                           np.repeat(patches.owner, 4)[:, None]], axis=1)
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    w = np.repeat(patches.area, 4)
    acc = np.zeros((len(uniq), values.shape[1]))
    np.add.at(acc, inv, values.repeat(4, axis=0) * w[:, None])
    den = np.zeros(len(uniq))
    np.add.at(den, inv, w)
    vv = acc / den[:, None]
    pos = np.zeros((len(uniq), 3))
    pos[inv] = patches.corners.reshape(-1, 3)
    return vv[inv].reshape(len(patches), 4, -1), pos, inv.reshape(len(patches), 4)


@dataclass
class Atlas:
    """One square cell of ``cell`` texels per patch, ``gutter`` texels apart, row-major from the top-left."""
    count: int
    cell: int
    gutter: int
    columns: int
    rows: int

    @property
    def size(self):
        """(width, height) in texels."""
        pitch = self.cell + self.gutter
        return self.columns * pitch, self.rows * pitch

    def origin(self, k):
        """Top-left texel (x, y) of cell k (row 0 = top)."""
        pitch = self.cell + self.gutter
        k = np.asarray(k)
        return (k % self.columns) * pitch + self.gutter // 2, (k // self.columns) * pitch + self.gutter // 2


def make_atlas(count, cell=4, gutter=2):
    """A near-square atlas for ``count`` patches."""
    if count <= 0:
        raise InputError("an atlas needs at least one patch")
    cols = int(np.ceil(np.sqrt(count)))
    return Atlas(int(count), int(cell), int(gutter), cols, int(np.ceil(count / cols)))


def atlas_uvs(atlas, is_tri):
    """UV (N, 4, 2) of each patch's corners in its cell (v up, Blender's UV convention).

    Corner order 0..3 maps to the cell's bottom-left, bottom-right, top-right,
    top-left; a triangle uses the first three (its lower-right half).
    """
    w, h = atlas.size
    x0, y0 = atlas.origin(np.arange(atlas.count))
    x1, y1 = x0 + atlas.cell, y0 + atlas.cell
    u0, u1 = x0 / w, x1 / w
    v_top, v_bot = 1 - y0 / h, 1 - y1 / h
    uv = np.stack([np.stack([u0, v_bot], -1), np.stack([u1, v_bot], -1),
                   np.stack([u1, v_top], -1), np.stack([u0, v_top], -1)], axis=1)
    uv[is_tri, 3] = uv[is_tri, 2]
    return uv


def _cell_masks(atlas):
    """Texel masks inside a cell (cell, cell): whole cell for quads, lower-right half (with the diagonal) for
    triangles; texel centres only, so a bake's edge bleeding does not count."""
    c = atlas.cell
    yy, xx = np.mgrid[0:c, 0:c]
    u, v = (xx + 0.5) / c, 1 - (yy + 0.5) / c
    return np.ones((c, c), bool), v <= u


def paint_atlas(atlas, values, is_tri):
    """Image (H, W, C) with every patch's cell filled with its value; A channel = coverage. Row 0 = top."""
    values = np.asarray(values, np.float64)
    w, h = atlas.size
    img = np.zeros((h, w, values.shape[1] + 1), np.float32)
    quad_m, tri_m = _cell_masks(atlas)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    for k in range(atlas.count):
        m = tri_m if is_tri[k] else quad_m
        block = img[y0[k]:y0[k] + c, x0[k]:x0[k] + c]
        block[m, :-1] = values[k]
        block[m, -1] = 1.0
    return img


def atlas_means(atlas, image, is_tri):
    """Per-patch mean of an atlas image (H, W, C), row 0 = top: the inverse of :func:`paint_atlas`."""
    image = np.asarray(image, np.float64)
    quad_m, tri_m = _cell_masks(atlas)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    out = np.empty((atlas.count, image.shape[2]))
    for k in range(atlas.count):
        m = tri_m if is_tri[k] else quad_m
        out[k] = image[y0[k]:y0[k] + c, x0[k]:x0[k] + c][m].mean(axis=0)
    return out


# ----------------------------------------------------------------------------
# Built-in scene


def cornell_box(light_radiance=15.0, size=2.0):
    """A closed Cornell-box-like room (x, y in [−s/2, s/2], z in [0, s]) with a square ceiling light and two
    rotated boxes, as ``patches_from_meshes`` input. Walls face inward, boxes outward; white 0.7, red, green."""
    h = size / 2
    white, red, green = (0.7, 0.7, 0.7), (0.65, 0.08, 0.06), (0.12, 0.55, 0.1)
    L = 0.25 * size / 2
    meshes = []

    def quad(name, verts, rho, emission=(0.0, 0.0, 0.0)):
        meshes.append({"name": name, "vertices": np.array(verts, float), "faces": [(0, 1, 2, 3)],
                       "rho": rho, "emission": emission})

    s = size
    quad("Floor", [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], white)
    quad("Back", [(-h, h, 0), (h, h, 0), (h, h, s), (-h, h, s)], white)
    quad("Front", [(-h, -h, 0), (-h, -h, s), (h, -h, s), (h, -h, 0)], white)
    quad("Left", [(-h, -h, 0), (-h, h, 0), (-h, h, s), (-h, -h, s)], red)
    quad("Right", [(h, -h, 0), (h, -h, s), (h, h, s), (h, h, 0)], green)
    # ceiling: a 3x3 grid around the light, facing down
    xs = [-h, -L, L, h]
    verts, faces = [], []
    for j in range(4):
        for i in range(4):
            verts.append((xs[i], xs[j], s))
    for j in range(3):
        for i in range(3):
            if i == 1 and j == 1:
                continue
            a = j * 4 + i
            faces.append((a, a + 4, a + 5, a + 1))
    meshes.append({"name": "Ceiling", "vertices": np.array(verts), "faces": faces, "rho": white,
                   "emission": (0.0, 0.0, 0.0)})
    quad("Light", [(-L, -L, s), (-L, L, s), (L, L, s), (L, -L, s)], (0.0, 0.0, 0.0),
         (light_radiance,) * 3)
    meshes.append(_box("ShortBox", (0.3 * s / 2, -0.25 * s / 2), 0.3 * s, 0.3 * s, np.radians(-17), white))
    meshes.append(_box("TallBox", (-0.3 * s / 2, 0.3 * s / 2), 0.3 * s, 0.6 * s, np.radians(17), white))
    return meshes


def _box(name, xy, side, height, angle, rho):
    c, s = np.cos(angle), np.sin(angle)
    e = side / 2
    base = [(-e, -e), (e, -e), (e, e), (-e, e)]
    pts = [(xy[0] + c * x - s * y, xy[1] + s * x + c * y) for x, y in base]
    verts = [(x, y, 0.0) for x, y in pts] + [(x, y, height) for x, y in pts]
    faces = [(4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return {"name": name, "vertices": np.array(verts), "faces": faces, "rho": rho, "emission": (0.0, 0.0, 0.0)}


def cornell_patches(max_edge=0.25, light_radiance=15.0):
    """The built-in scene split into patches no longer than ``max_edge``."""
    return subdivide_to_size(patches_from_meshes(cornell_box(light_radiance)), max_edge)
