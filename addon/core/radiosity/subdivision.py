"""Subdivision of patches: to a size, near emitters (adaptive, graded), and where the solution changes fast."""
import numpy as np

from ..errors import InputError
from .atlas import texel_points
from .form_factors import NEAR_RATIO, seen_form_factors
from .patches import Patches, bounding_radius, longest_edge, vertex_keys


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


ADAPTIVE_FINEST = 16        # adaptive rounds split no patch of area below (max_edge / ADAPTIVE_FINEST)²


def adaptive_min_area(max_edge):
    """``min_area`` of :func:`refine_mask` in the adaptive rounds of a solve split to ``max_edge``."""
    return (max_edge / ADAPTIVE_FINEST) ** 2


def planned_patches_per_round(patches, max_edge, rounds):
    """Upper bound of the patch count of each adaptive round 0..``rounds`` (round 0: :func:`planned_patches`): every
    patch of :func:`subdivide_to_size` split in four in every round while :func:`refine_mask` allows it (area above
    4 × :func:`adaptive_min_area`, a quarter per split: at most 3 splits for a patch of edges ≤ max_edge); the
    near-emitter budget's patches, children of such patches, one split fewer."""
    k = subdivision_levels(patches, max_edge)
    ratio = np.asarray(patches.area, float) / 4.0 ** k / (4 * adaptive_min_area(max_edge))
    j = np.ceil(np.log(np.maximum(ratio, 1.0)) / np.log(4.0) - 1e-9).astype(int)
    n = estimate_patches(patches, max_edge)
    extra = refine_budget(patches, n)
    finest = int(j.max()) if len(j) else 0
    return [float(np.sum(4.0 ** (k + np.minimum(j, r)))) + extra * 4.0 ** min(r, max(finest - 1, 0))
            for r in range(int(rounds) + 1)]


EMITTER_SPREAD = 0.5        # split a patch when the direct light of a near emitter varies across it by more
EMITTER_LEVELS = 5          # than this fraction of its mean, at most this many times (edges down to 1/32)
BOUNCE_SOURCE = 0.25        # a "bright bounce": first-bounce radiance ρ E_direct / π above this fraction of the
                            # brightest emitter's L_e (a ceiling trapped between a lamp and the room)


EMITTER_PAIR_BLOCK = 1_000_000   # (receiver, emitter) candidates screened at once (about 100 B each)


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
        take = np.take                   # row gathers several times faster than fancy indexing
        d = take(patches.center, e, axis=0) - take(patches.center, i, axis=0)
        ok = ((np.einsum("mk,mk->m", d, take(patches.normal, i, axis=0)) > 1e-9)
              & (np.einsum("mk,mk->m", d, take(patches.normal, e, axis=0)) < -1e-9))
        i, e = i[ok], e[ok]
        gap = np.linalg.norm(take(patches.center, i, axis=0) - take(patches.center, e, axis=0), axis=1) - r[i] - r[e]
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
    x = np.take(pts.reshape(-1, 3), rr * m + tt, axis=0)
    v = seen_form_factors(patches, x, np.take(patches.normal, rr, axis=0), ee, visible)
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
        take = np.take
        d = take(patches.center, j, axis=0) - take(patches.center, i, axis=0)
        ok = (np.einsum("mk,mk->m", d, take(patches.normal, i, axis=0)) > 1e-9) & \
             (np.einsum("mk,mk->m", d, take(patches.normal, j, axis=0)) < -1e-9)
        i, j = i[ok], j[ok]
        gap = np.linalg.norm(take(patches.center, i, axis=0) - take(patches.center, j, axis=0), axis=1) - r[i] - r[j]
        mask[i[gap < NEAR_RATIO * 2 * r[j]]] = True
    return mask


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
