"""Patches of the radiosity solver: convex planar polygons stored as quads (N, 4, 3).

A triangle repeats its last vertex (a zero-length edge adds nothing to any sum
here). Area, normal (Newell) and centroid; patches from mesh dicts; back sides
of open meshes.
"""
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError


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


def longest_edge(corners):
    """Longest edge length of each polygon (N,)."""
    return np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=-1).max(axis=1)


def bounding_radius(patches):
    """Largest distance from each patch's centre to its corners (N,)."""
    return np.linalg.norm(patches.corners - patches.center[:, None, :], axis=-1).max(axis=1)


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




def vertex_keys(points, scale=1e6):
    """Integer keys of positions rounded to 1/scale: equal keys = same vertex."""
    return np.round(np.asarray(points) * scale).astype(np.int64)
