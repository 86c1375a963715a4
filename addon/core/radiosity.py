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

from .budget import memory_budget
from .errors import InputError


# ----------------------------------------------------------------------------
# Patches


@dataclass
class Patches:
    """Flat list of patches. ``corners`` (N, 4, 3); ``rho``, ``emission`` (N, 3); ``owner`` (N,) object index;
    ``is_tri`` (N,) bool; ``source`` (N,) index of the input face each patch came from; ``back`` (N,) bool:
    the patch is the back side of its face (corners in reversed order, see :func:`with_back_sides`)."""
    corners: np.ndarray
    rho: np.ndarray
    emission: np.ndarray
    owner: np.ndarray
    is_tri: np.ndarray
    source: np.ndarray
    names: list = field(default_factory=list)
    back: np.ndarray = None

    def __post_init__(self):
        if self.back is None:
            self.back = np.zeros(len(self.corners), bool)
        self.area, self.normal = polygon_area_normal(self.corners)
        self.center = polygon_centroid(self.corners, self.is_tri)

    def __len__(self):
        return len(self.corners)

    def take(self, idx):
        """The patches at ``idx`` (index array or mask), object names kept."""
        return Patches(self.corners[idx], self.rho[idx], self.emission[idx], self.owner[idx],
                       self.is_tri[idx], self.source[idx], self.names, self.back[idx])


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


def patches_from_meshes(meshes, drop_degenerate=False):
    """``meshes``: list of dicts {"name", "vertices" (V, 3), "faces" (list of 3- or 4-index tuples),
    "rho" (3,) or (F, 3), "emission" (3,) or (F, 3) emitted RADIANCE L_e} -> :class:`Patches`.

    Emitted exitance E_i = π L_e (Lambertian emitter). Polygons with more than four
    corners are fanned into triangles. Zero-area faces are refused, or dropped with
    ``drop_degenerate`` (then ``patches.dropped`` counts them).
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
    bad = ~(p.area > 1e-12 * max(float(np.max(p.area)), 1e-300))
    if bad.any():
        if not drop_degenerate or bad.all():
            raise InputError(f"{int(np.sum(bad))} faces have zero area")
        p = p.take(~bad)
    p.dropped = int(np.sum(bad))
    if np.any((p.rho < 0) | (p.rho >= 1)):
        raise InputError("albedo rho must be in [0, 1) for the solution to exist")
    return p


def reversed_corners(corners, is_tri):
    """The same polygons wound the other way (normal flipped): quads (0, 3, 2, 1), triangles (0, 2, 1, 1)."""
    return np.where(is_tri[:, None, None], corners[:, [0, 2, 1, 1]], corners[:, [0, 3, 2, 1]])


def back_side_needed(patches, open_owner, eps=1e-6):
    """Which faces need their back side as a patch of its own (N,) bool.

    Cycles shades both sides of a surface: a diffuse face reflects light arriving on either side and an
    emitting face emits from both (the Emission closure is two-sided; the material's emission sampling
    setting only chooses which side light sampling aims at). A face's back matters when some vertex of
    the scene lies strictly behind its plane (farther than ``eps`` times the scene size) and its mesh is
    open (``open_owner[owner]``): the back of a closed mesh faces its own inside, which no light reaches.
    """
    c = patches.corners.reshape(-1, 3)
    pts = np.unique(np.round(c, 12), axis=0)
    size = max(float(np.ptp(pts, axis=0).max()), 1e-300)
    need = np.zeros(len(patches), bool)
    cand = np.flatnonzero(np.asarray(open_owner, bool)[patches.owner])
    offs = np.einsum("nk,nk->n", patches.normal[cand], patches.center[cand])
    step = max(1, int(4_000_000 // max(len(pts), 1)))
    for s in range(0, len(cand), step):
        d = patches.normal[cand[s:s + step]] @ pts.T - offs[s:s + step, None]
        need[cand[s:s + step]] = (d < -eps * size).any(axis=1)
    return need


def with_back_sides(patches, need):
    """``patches`` plus a back-side copy of every patch where ``need``: reversed corners, the same ρ and
    emission (both sides of a Cycles surface reflect and emit alike), ``back`` True."""
    idx = np.flatnonzero(need)
    if not len(idx):
        return patches
    b = patches.take(idx)
    flipped = Patches(reversed_corners(b.corners, b.is_tri), b.rho, b.emission, b.owner, b.is_tri, b.source,
                      patches.names, np.ones(len(idx), bool))
    both = Patches(np.concatenate([patches.corners, flipped.corners]), np.concatenate([patches.rho, b.rho]),
                   np.concatenate([patches.emission, b.emission]), np.concatenate([patches.owner, b.owner]),
                   np.concatenate([patches.is_tri, b.is_tri]), np.concatenate([patches.source, b.source]),
                   patches.names, np.concatenate([patches.back, flipped.back]))
    both.dropped = getattr(patches, "dropped", 0)
    return both


def open_meshes(meshes):
    """Per mesh: True when some edge is not shared by exactly two faces (a boundary or non-manifold edge)."""
    out = []
    for m in meshes:
        count = {}
        for f in m["faces"]:
            f = list(f)
            for a, b in zip(f, f[1:] + f[:1]):
                key = (a, b) if a < b else (b, a)
                count[key] = count.get(key, 0) + 1
        out.append(any(c != 2 for c in count.values()) or not count)
    return np.array(out, bool)


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
                  patches.owner[parent], np.concatenate(tri_flags), patches.source[parent], patches.names,
                  patches.back[parent])
    order = np.argsort(parent, kind="stable")  # keep each object's patches together, in input order
    return out.take(order), parent[order]


def subdivide_to_size(patches, max_edge):
    """Split every patch in four until its longest edge is at most ``max_edge``."""
    if not max_edge > 0:
        raise InputError(f"max_edge must be a positive number, got {max_edge}")
    for _ in range(MAX_LEVELS):
        mask = longest_edge(patches.corners) > max_edge
        if not mask.any():
            return patches
        patches, _ = split(patches, mask)
    return patches


MAX_LEVELS = 20


def subdivision_levels(patches, max_edge):
    """Levels k of four-way splits each patch gets from :func:`subdivide_to_size` (edges halve per level):
    k = ceil(log2(longest edge / max_edge)), 0..MAX_LEVELS."""
    ratio = longest_edge(patches.corners) / max_edge
    k = np.ceil(np.log2(np.maximum(ratio, 1.0)) - 1e-12)
    return np.clip(k, 0, MAX_LEVELS).astype(int)


def estimate_patches(patches, max_edge):
    """Patch count :func:`subdivide_to_size` makes, without making them: Σ 4^k (float, may be huge)."""
    return float(np.sum(4.0 ** subdivision_levels(patches, max_edge)))


REFINE_SHARE = 0.5          # subdivision near emitters adds at most max(REFINE_MIN, REFINE_SHARE × n) patches
REFINE_MIN = 4096           # to the n of subdivide_to_size (measured: 1.3k-4.2k on the scenes of the tests)


def refine_budget(patches, n):
    """Most patches the subdivision near emitters may add to ``n`` (0 when nothing in ``patches`` emits)."""
    return max(REFINE_MIN, REFINE_SHARE * n) if np.any(patches.emission > 0) else 0.0


def planned_patches(patches, max_edge):
    """Upper bound of a solve's patch count: :func:`estimate_patches` plus :func:`refine_budget` (the
    subdivision near emitters stops at that budget)."""
    n = estimate_patches(patches, max_edge)
    return n + refine_budget(patches, n)


def longest_edge(corners):
    """Longest edge length of each polygon (N,)."""
    return np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=-1).max(axis=1)


# ----------------------------------------------------------------------------
# Cost of a solve: refuse what cannot finish before allocating anything

# Peak memory of a solve with N patches, per patch pair: measured with tracemalloc on the Cornell box at
# N = 7104: form factors with the visibility matrix alive 21.3 B (F float64, V bool and their temporaries),
# near pairs beside F 11.6 B (found block by block), a solve 8.0 B, the emitter split mask 8.8 B; plus bounded
# chunks. Rounded up.
BYTES_PER_PAIR = 24.0
OVERHEAD_BYTES = 600e6                  # Blender, numpy and the chunked temporaries
# Seconds per patch pair (visibility ray + form factor + the three solvers of the convergence chart),
# measured on the 2-core reference machine (tests/test_radiosity.py states the run it comes from).
SECONDS_PER_PAIR = 4e-6
# The near field (:func:`near_field_form_factors`): at most NEAR_EVALS_PER_PATCH evaluations (point form
# factor + a visibility ray) per patch, measured at this many seconds each on the same machine.
SECONDS_PER_NEAR_EVAL = 4e-6
MAX_SECONDS = 3600.0


@dataclass
class Cost:
    """Estimated size of a solve: patches, peak bytes, seconds."""
    patches: float
    bytes: float
    seconds: float


def solve_cost(n):
    """:class:`Cost` of solving ``n`` patches: N² form factors and visibility, plus the near field's bounded
    work (NEAR_EVALS_PER_PATCH evaluations a patch, NEAR_PEAK_BYTES at most)."""
    n = float(n)
    return Cost(n, BYTES_PER_PAIR * n * n + OVERHEAD_BYTES + NEAR_PEAK_BYTES,
                SECONDS_PER_PAIR * n * n + SECONDS_PER_NEAR_EVAL * NEAR_EVALS_PER_PATCH * n)


def human_bytes(b):
    """1.2 GB style (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB", "TB", "PB", "EB"):
        if b < 1000 or unit == "EB":
            return f"{b:.3g} {unit}" if unit != "B" else f"{b:.0f} B"
        b /= 1000


def human_count(n):
    """2.1M style."""
    for unit, f in (("", 1), ("k", 1e3), ("M", 1e6), ("G", 1e9), ("T", 1e12)):
        if n < 1000 * f or unit == "T":
            return f"{n / f:.3g}{unit}"


def human_seconds(s):
    """'40 s', '12 min', '3.1 h', '9.5 days'."""
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    if s < 172800:
        return f"{s / 3600:.1f} h"
    return f"{s / 86400:.3g} days"


def smallest_edge_that_fits(patches, memory, max_seconds=MAX_SECONDS):
    """The smallest max_edge whose estimated solve fits in ``memory`` bytes and ``max_seconds`` (None when
    even the unsplit faces do not fit)."""
    def fits(e):
        c = solve_cost(planned_patches(patches, e))
        return c.bytes <= memory and c.seconds <= max_seconds
    hi = float(longest_edge(patches.corners).max()) * 1.0000001
    if not fits(hi):
        return None
    lo = hi / 2 ** MAX_LEVELS
    if fits(lo):
        return lo
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return hi


def check_cost(patches, max_edge, memory=None, max_seconds=MAX_SECONDS, option="--max-edge"):
    """Estimate the solve of ``patches`` split to ``max_edge`` (an upper bound: :func:`planned_patches`) and
    refuse (InputError, one line naming the
    limit and the smallest edge that fits) what needs more than ``memory`` bytes (default: the memory
    a job may plan to use, core.budget) or more than ``max_seconds``. Returns the :class:`Cost`."""
    memory = memory_budget() if memory is None else memory
    cost = solve_cost(planned_patches(patches, max_edge))
    over_mem = memory is not None and cost.bytes > memory
    over_time = max_seconds is not None and cost.seconds > max_seconds
    if not (over_mem or over_time):
        return cost
    mem = memory if memory is not None else float("inf")
    secs = max_seconds if max_seconds is not None else float("inf")
    best = smallest_edge_that_fits(patches, mem, secs)
    limits = " and ".join(x for x in (f"{human_bytes(mem)} of usable memory" if memory is not None else "",
                                      f"{human_seconds(secs)} (at {SECONDS_PER_PAIR * 1e6:g} µs a patch pair)"
                                      if max_seconds is not None else "") if x)
    hint = (f"the smallest edge that fits in {limits} is {best:.2g}" if best is not None
            else f"even the unsplit faces do not fit in {limits}: simplify the scene")
    need = f"needing {human_bytes(cost.bytes)}" + (f" and about {human_seconds(cost.seconds)}" if over_time else "")
    raise InputError(f"{option} {max_edge:g} gives ~{human_count(cost.patches)} patches {need}; {hint}")


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


# ----------------------------------------------------------------------------
# Near field: the patch average where one point per receiver is not enough

# A pair (receiver i, source j) is near when the gap between their bounding spheres is below NEAR_RATIO
# times i's diameter: there F(dA_x -> P_j) changes over patch i by more than its centre value can stand for
# (the midpoint rule's relative error grows as (diameter / distance)²; for touching or overlapping patches,
# e.g. a light 1 mm under a ceiling, the integrand is a step). Those pairs get the patch average by adaptive
# cubature (:func:`near_field_form_factors`), within NEAR_EVALS_PER_PATCH evaluations per patch on average.
NEAR_RATIO = 1.0
NEAR_TOL = 2e-4            # absolute error in F allowed per cell before it is split in four
NEAR_START = 2             # the first level: NEAR_START² cells per receiver
NEAR_DEPTH = 6             # at most 6 halvings: cells down to 1/128 of the receiver's side
NEAR_EVALS_PER_PATCH = 600
NEAR_CHUNK = 5000          # pairs per chunk, at most NEAR_CHUNK_EVALS evaluations each: bounded memory
NEAR_CHUNK_EVALS = 600_000
NEAR_PEAK_BYTES = 400e6    # the arrays of one chunk's evaluations (about 600 B each)
EMITTER_PAIR_BLOCK = 1_000_000   # (receiver, emitter) candidates screened at once (about 100 B each)


def bounding_radius(patches):
    """Largest distance from each patch's centre to its corners (N,)."""
    return np.linalg.norm(patches.corners - patches.center[:, None, :], axis=-1).max(axis=1)


def near_pairs(patches, i, j, ratio=NEAR_RATIO):
    """Ordered (receiver, source) index arrays, both ways round, of the pairs among (i, j) that are near:
    bounding-sphere gap |c_i − c_j| − r_i − r_j below ``ratio`` × the receiver's diameter 2 r_i."""
    i, j = np.asarray(i, int), np.asarray(j, int)
    r = bounding_radius(patches)
    gap = np.linalg.norm(patches.center[i] - patches.center[j], axis=1) - r[i] - r[j]
    a = gap < ratio * 2 * r[i]
    b = gap < ratio * 2 * r[j]
    return np.concatenate([i[a], j[b]]), np.concatenate([j[a], i[b]])


def bilinear(corners, s, t):
    """Points of the patches' bilinear maps of the unit square (corner 0 at (0, 0), 1 at (1, 0), 2 at (1, 1),
    3 at (0, 1); a triangle's repeated corner collapses the edge t = 1) and |∂x/∂s × ∂x/∂t| there.
    ``corners`` (M, 4, 3), ``s``, ``t`` (M,). For a planar quad the Jacobian is linear in s and t, so the
    midpoint rule integrates the area exactly."""
    c0, c1, c2, c3 = corners[:, 0], corners[:, 1], corners[:, 2], corners[:, 3]
    s, t = s[:, None], t[:, None]
    x = (1 - s) * (1 - t) * c0 + s * (1 - t) * c1 + s * t * c2 + (1 - s) * t * c3
    ds = (1 - t) * (c1 - c0) + t * (c2 - c3)
    dt = (1 - s) * (c3 - c0) + s * (c2 - c1)
    return x, np.linalg.norm(np.cross(ds, dt), axis=-1)


def pointwise_form_factors(points, normals, polys):
    """F(dA_m -> polygon m) for matching rows: points (M, 3), normals (M, 3), polygons (M, k, 3) -> (M,).
    The same rules as :func:`point_polygon_form_factors` (front side only, clipped to the hemisphere)."""
    points, normals, polys = (np.asarray(a, np.float64) for a in (points, normals, polys))
    _, pn = polygon_area_normal(polys)
    r = polys - points[:, None, :]
    d = np.einsum("mkc,mc->mk", r, normals)
    facing = -np.einsum("mc,mc->m", r[:, 0], pn) > 1e-9
    front = (d > 1e-9).any(axis=-1) & facing
    simple = front & (d >= -1e-9).all(axis=-1)
    out = np.zeros(len(points))
    if simple.any():
        out[simple] = lambert_polygon(r[simple], normals[simple])
    clip = front & ~simple
    if clip.any():
        rel, _ = clip_to_hemisphere(polys[clip], points[clip], normals[clip])
        out[clip] = lambert_polygon(rel, normals[clip])
    return out


def near_field_form_factors(patches, recv, src, visible=None, tol=NEAR_TOL, start=NEAR_START, depth=NEAR_DEPTH,
                            budget=None):
    """Patch-average form factors of the pairs (recv, src):

        F_ij = (1 / A_i) ∫_{A_i} F(dA_x -> P_j) V(x, j) dA_x

    with the inner integral exact (:func:`lambert_polygon`) and the outer one adaptive: the receiver's
    parameter square starts as ``start``² cells; a cell whose four children's midpoint sum differs from its
    own by more than ``tol`` is split, down to ``depth`` halvings (the children's sum is kept either way).
    ``visible(points, normals, src) -> (M,)`` in [0, 1] is the visibility from each point to the source
    (None: all visible). ``budget``: most evaluations (default NEAR_EVALS_PER_PATCH per patch of the scene);
    the cells with the largest error are split first. Returns (F (P,), evaluations made).
    """
    recv, src = np.asarray(recv, int), np.asarray(src, int)
    n_pairs = len(recv)
    budget = NEAR_EVALS_PER_PATCH * len(patches) if budget is None else budget
    out = np.zeros(n_pairs)
    evals = 0
    for s in range(0, n_pairs, NEAR_CHUNK):
        sl = slice(s, min(s + NEAR_CHUNK, n_pairs))
        share = min(int(budget * (sl.stop - sl.start) / max(n_pairs, 1)), NEAR_CHUNK_EVALS)
        out[sl], e = _adaptive_chunk(patches, recv[sl], src[sl], visible, tol, start, depth, share)
        evals += e
    return out, evals


def edge_distance(points, polys):
    """Distance from each point (M, 3) to the nearest edge of its polygon (M, k, 3) (M,)."""
    a, b = polys, np.roll(polys, -1, axis=1)
    ab = b - a
    ap = points[:, None, :] - a
    t = np.clip(np.einsum("mkc,mkc->mk", ap, ab) / np.maximum(np.einsum("mkc,mkc->mk", ab, ab), 1e-300), 0, 1)
    return np.linalg.norm(ap - t[..., None] * ab, axis=-1).min(axis=1)


def _adaptive_chunk(patches, recv, src, visible, tol, start, depth, budget):
    diam = 2 * bounding_radius(patches)

    def f(pair, s, t, h):
        i, j = recv[pair], src[pair]
        x, jac = bilinear(patches.corners[i], s, t)
        v = pointwise_form_factors(x, patches.normal[i], patches.corners[j])
        if visible is not None:
            hit = v > 0
            if hit.any():
                v[hit] = v[hit] * visible(x[hit], patches.normal[i][hit], j[hit])
        return v * jac * h * h / patches.area[i], x

    g = (np.arange(start) + 0.5) / start
    gs, gt = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    pair = np.repeat(np.arange(len(recv)), start * start)
    s, t = np.tile(gs, len(recv)), np.tile(gt, len(recv))
    h = np.full(len(pair), 1.0 / start)
    val, x = f(pair, s, t, h)
    evals = len(pair)
    total = np.zeros(len(recv))
    prio = np.full(len(pair), np.inf)
    offs = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)]) / 4.0
    for level in range(depth):
        if not len(pair):
            break
        room = (budget - evals) // 4
        if room < len(pair):                         # out of budget: split the most promising cells only
            keep = np.argsort(-prio, kind="stable")[:max(room, 0)]
            rest = np.ones(len(pair), bool)
            rest[keep] = False
            np.add.at(total, pair[rest], val[rest])
            pair, s, t, h, val, x, prio = (a[keep] for a in (pair, s, t, h, val, x, prio))
            if not len(pair):
                break
        cp = np.repeat(pair, 4)
        cs = np.repeat(s, 4) + np.tile(offs[:, 0], len(pair)) * np.repeat(h, 4)
        ct = np.repeat(t, 4) + np.tile(offs[:, 1], len(pair)) * np.repeat(h, 4)
        ch = np.repeat(h / 2, 4)
        cv, cx = f(cp, cs, ct, ch)
        evals += len(cp)
        est = cv.reshape(-1, 4).sum(axis=1)
        err = np.abs(est - val)
        # a step the children's centres straddle shows in err; one between them and the cell's border does not:
        # cells closer to an edge of the source than their own size are split regardless (the step lies there)
        near_edge = h * diam[recv[pair]] > edge_distance(x, patches.corners[src[pair]])
        if level == depth - 1:
            split = np.zeros(len(pair), bool)
        else:
            split = (err > tol) | near_edge
        np.add.at(total, pair[~split], est[~split])
        spread = np.ptp(cv.reshape(-1, 4), axis=1) * 4
        prio = np.repeat(np.maximum(err, spread)[split] / 4, 4)
        m = np.repeat(split, 4)
        pair, s, t, h, val, x = cp[m], cs[m], ct[m], ch[m], cv[m], cx[m]
    np.add.at(total, pair, val)
    return total, evals


EMITTER_SPREAD = 0.5        # split a patch when the direct light of a near emitter varies across it by more
EMITTER_LEVELS = 5          # than this fraction of its mean, at most this many times (edges down to 1/32)
BOUNCE_SOURCE = 0.25        # a "bright bounce": first-bounce radiance ρ E_direct / π above this fraction of the
                            # brightest emitter's L_e (a ceiling trapped between a lamp and the room)


def emitter_refine_mask(patches, visible=None, threshold=EMITTER_SPREAD, min_edge=0.0, points=4):
    """Patches to split because the direct irradiance from the emitters near them varies across them
    (adaptive subdivision near emitters): Σ_e F(dA_x -> P_e) V(x, e) E_e (luminance) at ``points``² points
    of each patch and at its :func:`rim_points`, for the near (receiver, emitter) pairs only; split where
    max − min exceeds ``threshold`` times the patch's mean and the patch's longest edge is above ``min_edge``.
    Without the rim points a ceiling whose patch edges lie over a lamp's edges 2 cm below stayed unsplit over
    the lamp (measured on the corpus' emissive.blend: −5 % over the lamp, +17 % just outside it).

    A constant radiosity per patch cannot hold a patch lit on one part only (a ceiling patch half over a
    light just below it): it would spread that part's light over the whole patch and send it back into the
    room, and lose the light bouncing in the gap.

    Grading near bright bounces: a patch is also split when it faces, near it (gap below the source's
    diameter), a patch more than twice smaller whose first bounce ρ Ē_direct / π exceeds BOUNCE_SOURCE × the
    brightest L_e. In a gap the lamp's back and the ceiling light each other many times (1 / (1 − ρ ρ')); a
    lamp left as one patch would get one mean radiosity for its back, too bright at its rim and too dark
    inside, and the ceiling above it would follow (measured: +7 % at the rim, −4 % inside, 1 mm gap).
    """
    lum = patches.emission @ np.array([0.2126, 0.7152, 0.0722])
    em = np.flatnonzero(lum > 0)
    n = len(patches)
    mask = np.zeros(n, bool)
    if not len(em):
        return mask
    r = bounding_radius(patches)
    rows = max(1, EMITTER_PAIR_BLOCK // len(em))
    parts = []
    for s in range(0, n, rows):             # (receiver, emitter) pairs in blocks: memory bounded, not n x emitters
        i = np.repeat(np.arange(s, min(s + rows, n)), len(em))
        e = np.tile(em, len(i) // len(em))
        d = patches.center[e] - patches.center[i]
        ok = ((np.einsum("mk,mk->m", d, patches.normal[i]) > 1e-9)
              & (np.einsum("mk,mk->m", d, patches.normal[e]) < -1e-9))
        i, e = i[ok], e[ok]
        gap = np.linalg.norm(patches.center[i] - patches.center[e], axis=1) - r[i] - r[e]
        near = gap < NEAR_RATIO * 2 * r[i]
        parts.append((i[near], e[near]))
    i = np.concatenate([p[0] for p in parts])
    e = np.concatenate([p[1] for p in parts])
    if not len(i):
        return mask
    pts, pmask = texel_points(patches, points)
    rim = rim_points(patches)
    pts = np.concatenate([pts, rim], axis=1)
    pmask = np.concatenate([pmask, np.ones(rim.shape[:2], bool)], axis=1)
    m = pts.shape[1]
    rr, tt = np.repeat(i, m), np.tile(np.arange(m), len(i))
    ee = np.repeat(e, m)
    x = pts[rr, tt]
    v = pointwise_form_factors(x, patches.normal[rr], patches.corners[ee])
    if visible is not None:
        hit = v > 0
        if hit.any():
            v[hit] = v[hit] * visible(x[hit], patches.normal[rr][hit], ee[hit])
    E = np.zeros((n, m))
    np.add.at(E, (rr, tt), v * lum[ee])
    E = np.where(pmask, E, np.nan)
    rows = np.unique(i)
    spread = np.nanmax(E[rows], axis=1) - np.nanmin(E[rows], axis=1)
    mean = np.nanmean(E[rows], axis=1)
    mask[rows] = spread > threshold * np.maximum(mean, 1e-300)
    bounce = np.zeros(n)
    bounce[rows] = (patches.rho[rows] @ np.array([0.2126, 0.7152, 0.0722])) * mean
    mask |= graded_mask(patches, np.flatnonzero(bounce > BOUNCE_SOURCE * lum[em].max()))
    return mask & (longest_edge(patches.corners) > min_edge)


RIM_INSET = 0.02            # rim points lie this fraction of the way from a corner / edge midpoint to the centre


def rim_points(patches, inset=RIM_INSET):
    """The corners and edge midpoints of each patch pulled ``inset`` of the way to its centroid (N, 8, 3): where
    a light's edge lies under a patch's edge, the direct light changes within the gap's height of it, between
    the texel centres (a ceiling over a lamp 2 cm below it)."""
    c = patches.corners
    mids = (c + np.roll(c, -1, axis=1)) / 2
    rim = np.concatenate([c, mids], axis=1)
    return rim + inset * (patches.center[:, None, :] - rim)


def graded_mask(patches, sources, ratio=2.0, chunk=2_000_000):
    """Patches facing one of ``sources``, near it (bounding-sphere gap below the source's diameter), and with
    a longest edge above ``ratio`` times the source's (N,) bool: the mesh grading rule."""
    n = len(patches)
    mask = np.zeros(n, bool)
    sources = np.asarray(sources, int)
    if not len(sources):
        return mask
    edge, r = longest_edge(patches.corners), bounding_radius(patches)
    step = max(1, chunk // max(n, 1))
    for s in range(0, len(sources), step):
        j = np.tile(sources[s:s + step], n)
        i = np.repeat(np.arange(n), len(sources[s:s + step]))
        ok = edge[i] > ratio * edge[j]
        i, j = i[ok], j[ok]
        d = patches.center[j] - patches.center[i]
        ok = (np.einsum("mk,mk->m", d, patches.normal[i]) > 1e-9) & \
             (np.einsum("mk,mk->m", d, patches.normal[j]) < -1e-9)
        i, j = i[ok], j[ok]
        gap = np.linalg.norm(patches.center[i] - patches.center[j], axis=1) - r[i] - r[j]
        mask[i[gap < NEAR_RATIO * 2 * r[j]]] = True
    return mask


def texel_points(patches, cell):
    """The surface points a ``cell``×``cell`` atlas cell bakes (texel centres, see :func:`atlas_uvs`):
    (N, cell², 3) and a mask (N, cell²) of the texels Cycles bakes (a triangle's: strictly inside its half), row-major from the cell's top row.
    Quads: the bilinear map of the cell; triangles: u, v barycentric over corners (0,0), (1,0), (1,1)."""
    yy, xx = np.mgrid[0:cell, 0:cell]
    u, v = ((xx + 0.5) / cell).ravel(), (1 - (yy + 0.5) / cell).ravel()
    n = len(patches)
    c = patches.corners
    q, _ = bilinear(np.repeat(c, len(u), axis=0), np.tile(u, n), np.tile(v, n))
    q = q.reshape(n, len(u), 3)
    tri = ((1 - u)[None, :, None] * c[:, None, 0] + (u - v)[None, :, None] * c[:, None, 1]
           + v[None, :, None] * c[:, None, 2])
    pts = np.where(patches.is_tri[:, None, None], tri, q)
    mask = np.where(patches.is_tri[:, None], (v < u)[None, :], True)
    return pts, mask


def point_irradiance(patches, F, B, recv, src, points, mask, visible=None):
    """Irradiance H(x) = Σ_j F(dA_x -> P_j) V(x, j) B_j at ``points`` (N, m, 3) of every patch (NaN where not
    ``mask``): exact point form factors and per-point visibility for the near pairs (recv, src), the
    patch's form factor F_ij for the others (whose variation over the patch is below the near criterion)."""
    n, m = points.shape[:2]
    saved = F[recv, src].copy()
    F[recv, src] = 0.0
    try:
        H = np.repeat((F @ B)[:, None, :], m, axis=1)
    finally:
        F[recv, src] = saved
    step = max(1, NEAR_CHUNK_EVALS // 4 // m)
    for s in range(0, len(recv), step):
        r, j = recv[s:s + step], src[s:s + step]
        rr, tt = np.repeat(r, m), np.tile(np.arange(m), len(r))
        ok = mask[rr, tt]
        rr, tt, jj = rr[ok], tt[ok], np.repeat(j, m)[ok]
        x = points[rr, tt]
        v = pointwise_form_factors(x, patches.normal[rr], patches.corners[jj])
        if visible is not None:
            hit = v > 0
            if hit.any():
                v[hit] = v[hit] * visible(x[hit], patches.normal[rr][hit], jj[hit])
        np.add.at(H, (rr, tt), v[:, None] * B[jj])
    H[~mask] = np.nan
    return H


def visible_numpy(patches, offset=1e-6):
    """A ``visible`` callback for :func:`near_field_form_factors` by brute-force numpy rays (small scenes,
    tests): 1 where the segment from the point to the source's centre crosses no patch."""
    tris = patch_triangles(patches)

    def visible(points, normals, src):
        o = points + offset * normals
        t = patches.center[src] + offset * patches.normal[src]
        return (~ray_triangle_hits(o, t, tris)).astype(float)
    return visible


def candidate_pair_blocks(patches, rows=None):
    """Yield (i, j) index arrays, i < j, of the pairs that can exchange light (each in front of the other's
    plane), a block of rows at a time so that memory stays bounded: the rays worth casting."""
    c, nrm = patches.center, patches.normal
    n = len(c)
    rows = rows or max(1, int(2_000_000 // max(n, 1)))
    for s in range(0, n, rows):
        i0 = np.arange(s, min(s + rows, n))
        d = c[None, :, :] - c[i0, None, :]                          # (b, N, 3): j - i
        front_j = np.einsum("ijk,ik->ij", d, nrm[i0]) > 1e-9       # j in front of i
        front_i = np.einsum("ijk,jk->ij", d, nrm) < -1e-9          # i in front of j
        ok = front_j & front_i
        ok &= np.arange(n)[None, :] > i0[:, None]
        bi, j = np.nonzero(ok)
        yield i0[bi], j


def candidate_pairs(patches):
    """Pairs i < j that can exchange light (each in front of the other's plane): the rays worth casting."""
    blocks = list(candidate_pair_blocks(patches))
    return (np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks]))


def near_candidate_pairs(patches, ratio=NEAR_RATIO):
    """:func:`near_pairs` of the :func:`candidate_pairs`, one block at a time: memory bounded by a block and
    the near pairs, never the O(N²) candidate list."""
    parts = [near_pairs(patches, i, j, ratio) for i, j in candidate_pair_blocks(patches)]
    if not parts:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


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
    """Centre-to-centre visibility matrix (N, N) bool by brute-force ray casting against the patches themselves."""
    n = len(patches)
    V = np.zeros((n, n), bool)
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
    diag = np.diag(F).copy()
    scale = rho / (1.0 - rho * diag[:, None])    # ρ_i / (1 − ρ_i F_ii), per channel
    base = E / (1.0 - rho * diag[:, None])
    for k in range(1, max_iter + 1):
        for i in range(len(F)):
            B[i] = base[i] + scale[i] * (F[i] @ B - diag[i] * B[i])
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


def _cell_masks(atlas, diagonal=True):
    """Texel masks inside a cell (cell, cell): whole cell for quads, lower-right half for triangles, with the
    texels centred on the diagonal when ``diagonal`` (painting) or without them (reading a bake: Cycles does
    not bake a texel whose centre lies on a triangle's edge, it stays 0 with alpha 0); texel centres only, so a
    bake's edge bleeding does not count."""
    c = atlas.cell
    yy, xx = np.mgrid[0:c, 0:c]
    u, v = (xx + 0.5) / c, 1 - (yy + 0.5) / c
    return np.ones((c, c), bool), (v <= u) if diagonal else (v < u)


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
    """Per-patch mean of an atlas image (H, W, C), row 0 = top, over the texels a bake covers (a triangle's
    strictly inside its half): the inverse of :func:`paint_atlas`."""
    image = np.asarray(image, np.float64)
    quad_m, tri_m = _cell_masks(atlas, diagonal=False)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    out = np.empty((atlas.count, image.shape[2]))
    for k in range(atlas.count):
        m = tri_m if is_tri[k] else quad_m
        out[k] = image[y0[k]:y0[k] + c, x0[k]:x0[k] + c][m].mean(axis=0)
    return out


def atlas_texels(atlas, image, is_tri):
    """Every patch's texels of an atlas image (H, W, C), row 0 = top: (N, cell², C), row-major from the cell's
    top row as :func:`texel_points` orders them, NaN outside a triangle's half."""
    image = np.asarray(image, np.float64)
    quad_m, tri_m = _cell_masks(atlas, diagonal=False)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    out = np.empty((atlas.count, c * c, image.shape[2]))
    for k in range(atlas.count):
        out[k] = image[y0[k]:y0[k] + c, x0[k]:x0[k] + c].reshape(c * c, -1)
        out[k][~(tri_m if is_tri[k] else quad_m).ravel()] = np.nan
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
