"""Two-level radiosity: the near field at texel resolution on top of the patch solution (a final gather).

A patch-constant B cannot follow a field that changes within a patch: a ceiling 1 mm above a light's back
side is lit through the gap with a step at the light's outline, and the light and the ceiling bounce light
between them 1 / (1 − ρρ') times. Every patch is cut along its atlas cell's texel grid
(:func:`core.radiosity.atlas.texel_elements`). Near pairs (the pairs whose form factor changes across the
receiver, :func:`core.radiosity.form_factors.near_pairs`) exchange light from each texel centre of the
receiver, element to element where the two patches overlap, to the whole source elsewhere (:class:`NearField`);
the other pairs through the patch form factors F_ij:

    B_a = E_i + ρ_i (Σ_{j far from i} F_ij B̄_j + Σ_{j near i} Σ_{b in j} F(dA_a -> A_b) V(a, j) B_b),  a in i

collocated at the elements' points (the texel centres a light-map bake samples), F(dA_a -> A_b) the exact
point-to-polygon form factor, B̄_j the area-weighted mean of j's elements. Solved by Jacobi sweeps from the
patch solution. The irradiance at the elements (the bracket, H_a) is what the light maps hold.
"""
from dataclasses import dataclass

import numpy as np

from .atlas import texel_elements
from .form_factors import pair_form_factors
from .parallel import ordered_map
from .patches import bounding_radius, longest_edge
from .solvers import product

GATHER_CHUNK_EVALS = 50_000       # point-to-polygon evaluations per chunk (about 500 B each at peak)


@dataclass
class Gather:
    """H, B (N, m, 3) at the texel elements (NaN where a triangle's cell has none), the elements' areas and
    mask (N, m), Jacobi sweeps made and whether the last changed B by less than ``tol``."""
    H: np.ndarray
    B: np.ndarray
    area: np.ndarray
    mask: np.ndarray
    iterations: int
    converged: bool

    def patch_mean(self):
        """The patch-average irradiance Σ_a A_a H_a / A_i (N, 3)."""
        w = self.area / np.maximum(self.area.sum(axis=1, keepdims=True), 1e-300)
        return np.einsum("nm,nmc->nc", w, np.where(self.mask[..., None], self.H, 0.0))


def element_form_factors(patches, elements, recv, src, visible=None, chunk_evals=GATHER_CHUNK_EVALS,
                         src_elements=None):
    """K (P, m, m') float32: F(dA_a -> A_b) V(a, src_p) from every element point a of patch recv_p to every
    element b of patch src_p (by the rules of :func:`core.radiosity.form_factors.polygon_form_factors`; 0 for elements that do not exist).
    ``elements`` is :func:`texel_elements`' (polys, points, area, mask), ``src_elements`` the sources' when
    they differ; ``visible(points, normals, src)`` as in
    :func:`core.radiosity.form_factors.seen_form_factors` (None: all visible; called in the worker threads of
    core.radiosity.parallel when it has a true ``threadsafe`` attribute, else in the caller's)."""
    _, pts, _, mask = elements
    polys, _, _, smask = elements if src_elements is None else src_elements
    n, m, ms = len(patches), pts.shape[1], polys.shape[1]
    recv, src = np.asarray(recv, int), np.asarray(src, int)
    K = np.zeros((len(recv), m, ms), np.float32)
    flat = polys.reshape(n * ms, 4, 3)
    cx, cy, cz = (np.ascontiguousarray(flat[..., k]) for k in range(3))
    pn = np.repeat(patches.normal, ms, axis=0)
    step = max(1, chunk_evals // (m * ms))

    def seen(k, r, j):
        if visible is not None:
            hit = k.any(axis=2)
            if hit.any():
                hp, ha = np.nonzero(hit)
                v = np.ones(hit.shape)
                v[hp, ha] = visible(pts[r][hp, ha], patches.normal[r][hp], j[hp])
                k *= v[:, :, None]
        return k
    threads = getattr(visible, "threadsafe", False)

    def chunk(s):
        r, j = recv[s:s + step], src[s:s + step]
        live = mask[r][:, :, None] & smask[j][:, None, :]                          # (p, m, m')
        pp, aa, bb = np.nonzero(live)
        k = np.zeros((len(r), m, ms))
        k[pp, aa, bb] = pair_form_factors(cx, cy, cz, pn, pts[r][pp, aa], patches.normal[r][pp],
                                           j[pp] * ms + bb)
        return seen(k, r, j) if threads else k
    for s, k in zip(range(0, len(recv), step), ordered_map(chunk, range(0, len(recv), step))):
        if not threads:
            k = seen(k, recv[s:s + step], src[s:s + step])
        K[s:s + step] = k
    return K


def fine_patches(patches, recv, src, cell):
    """Patches that get (2 cell)² elements (N,) bool: emitters facing a near patch (normals opposed) closer to
    their plane than their elements are wide (longest edge / cell), e.g. the back of a light 1 mm under a
    ceiling: their radiosity (emission plus the light trapped in the gap) falls toward their rim within the
    gap's height, and the surface beyond the rim sees mostly that rim."""
    recv, src = np.asarray(recv, int), np.asarray(src, int)
    emits = np.any(patches.emission > 0, axis=1)
    h = np.abs(np.einsum("pk,pk->p", patches.center[src] - patches.center[recv], patches.normal[recv]))
    facing = np.einsum("pk,pk->p", patches.normal[recv], patches.normal[src]) < -0.9
    near = emits[recv] & facing & (h < longest_edge(patches.corners)[recv] / cell)
    out = np.zeros(len(patches), bool)
    out[recv[near]] = True
    return out


class NearField:
    """The element exchange of the near pairs (recv, src), in groups by (receiver level, source level), each
    sorted by receiver, with their :func:`element_form_factors`. Levels: "texel" (``cell``² texel elements),
    "fine" ((2 cell)² elements, the ``fine`` patches) and, for sources, "patch" (the whole patch at its mean
    radiosity). Patches whose bounding spheres overlap (they touch, or one lies over the other) exchange
    element to element, at the fine level where a side is fine; the other near pairs from the receiver's
    texel centres to the whole source (its form factor still changes across the receiver, its radiosity
    hardly matters at the source's scale)."""

    def __init__(self, patches, recv, src, cell, visible=None, fine=None):
        self.patches, self.cell = patches, int(cell)
        self.recv, self.src = np.asarray(recv, int), np.asarray(src, int)
        self.fine = np.zeros(len(patches), bool) if fine is None else np.asarray(fine, bool)
        n = len(patches)
        self.elements = {"texel": texel_elements(patches, cell),
                         "patch": (patches.corners[:, None], patches.center[:, None], patches.area[:, None],
                                   np.ones((n, 1), bool))}
        r, j = self.recv, self.src
        rad = bounding_radius(patches)
        overlap = np.linalg.norm(patches.center[j] - patches.center[r], axis=1) < rad[r] + rad[j]
        lr = np.where(overlap & self.fine[r], "fine", "texel")
        ls = np.where(overlap, np.where(self.fine[j], "fine", "texel"), "patch")
        if (lr == "fine").any() or (ls == "fine").any():
            self.elements["fine"] = _rows_of(n, np.flatnonzero(self.fine),
                                             texel_elements(patches.take(np.flatnonzero(self.fine)), 2 * cell))
        self.groups = []
        for fr in ("texel", "fine"):
            for fs in ("patch", "texel", "fine"):
                idx = np.flatnonzero((lr == fr) & (ls == fs))
                if not len(idx):
                    continue
                idx = idx[np.argsort(r[idx], kind="stable")]
                K = element_form_factors(patches, self.elements[fr], r[idx], j[idx], visible,
                                         src_elements=self.elements[fs])
                self.groups.append((fr, fs, idx, K))

    @property
    def evaluations(self):
        return int(sum(K.size for *_, K in self.groups))

    def weights(self, level):
        area = self.elements[level][2]
        return area / np.maximum(area.sum(axis=1, keepdims=True), 1e-300)

    def patch_form_factors(self):
        """F_ij of the pairs (in their given order) from the element exchange: Σ_a (A_a / A_i) Σ_b K_ab, the
        receiver's integral by the elements' midpoint rule, the source's exact."""
        out = np.zeros(len(self.recv))
        for fr, _, idx, K in self.groups:
            out[idx] = np.einsum("pa,pa->p", self.weights(fr)[self.recv[idx]], K.sum(axis=2, dtype=np.float64))
        return out

    def box(self, values, rows):
        """Fine element values (R, (2c)², C) of the patches ``rows`` to their texels' area-weighted means
        (R, c², C)."""
        n, c = len(rows), self.cell
        a2 = self.elements["fine"][2][rows].reshape(n, c, 2, c, 2)
        den = np.maximum(a2.sum(axis=(2, 4)), 1e-300).reshape(n, c * c, 1)
        return (values.reshape(n, c, 2, c, 2, -1) * a2[..., None]).sum(axis=(2, 4)).reshape(n, c * c, -1) / den

    def spread(self, values):
        """Texel values (R, c², C) to their fine elements (R, (2c)², C)."""
        n, c = len(values), self.cell
        v = values.reshape(n, c, 1, c, 1, -1)
        return np.broadcast_to(v, (n, c, 2, c, 2, v.shape[-1])).reshape(n, 4 * c * c, -1)


def _rows_of(n, rows, arrays):
    """Arrays of ``rows`` of n patches as arrays of all n (zero, False elsewhere)."""
    out = []
    for a in arrays:
        full = np.zeros((n,) + a.shape[1:], a.dtype)
        full[rows] = a
        out.append(full)
    return tuple(out)


def near_field_gather(patches, F, B, near, tol=1e-5, max_iter=1000):
    """The two-level solution of the module docstring from the patch solution B (N, 3) of the system F
    (N, N) and a :class:`NearField` ``near`` whose pairs' F entries the element exchange replaces (F is
    restored on return). A fine patch's texel is the area-weighted mean of its 2 × 2 elements in it (the
    texel's box average, as Cycles' bake jitters its samples over the texel); the light it gets from the
    sources it does not overlap is taken at the texel's centre. Returns a :class:`Gather`."""
    recv, src = near.recv, near.src
    has_fine = "fine" in near.elements
    fine = np.flatnonzero(near.fine) if has_fine else np.zeros(0, int)      # the fine level: these patches only
    pos = np.full(len(patches), -1)
    pos[fine] = np.arange(len(fine))
    E, rho = patches.emission[:, None, :], patches.rho[:, None, :]
    area, tmask = near.elements["texel"][2], near.elements["texel"][3]
    w = near.weights("texel")
    B0 = np.asarray(B, np.float64)[:, None, :]
    Be = {"texel": np.where(tmask[..., None], B0, 0.0)}
    if has_fine:
        fmask = near.elements["fine"][3][fine]
        Be["fine"] = np.where(fmask[..., None], B0[fine], 0.0)
    scale = max(float(np.abs(E).max()), 1e-300)
    saved = F[recv, src].copy()
    F[recv, src] = 0.0
    converged, it = False, 0
    try:
        for it in range(1, max_iter + 1):
            Be["patch"] = np.einsum("nm,nmc->nc", w, Be["texel"])[:, None, :]
            far = product(F, Be["patch"][:, 0])
            H = {f: np.zeros_like(Be[f]) for f in ("texel", "fine") if f in Be}
            for fr, fs, idx, K in near.groups:
                r = recv[idx]
                first = np.flatnonzero(np.r_[True, r[1:] != r[:-1]])
                rows = r[first] if fr == "texel" else pos[r[first]]
                H[fr][rows] += np.add.reduceat(np.matmul(K, Be[fs][src[idx] if fs != "fine" else pos[src[idx]]]),
                                               first, axis=0)
            Ht = H["texel"] + far[:, None, :]
            Bn = {"texel": np.where(tmask[..., None], E + rho * Ht, 0.0)}
            if has_fine:
                Hf = H["fine"] + near.spread(H["texel"][fine]) + far[fine, None, :]
                Bn["fine"] = np.where(fmask[..., None], E[fine] + rho[fine] * Hf, 0.0)
                Bn["texel"][fine] = near.box(Bn["fine"], fine)
            delta = max(float(np.abs(Bn[f] - Be[f]).max()) for f in Bn) / max(float(np.abs(Bn["texel"]).max()), scale)
            Be.update(Bn)
            if delta < tol:
                converged = True
                break
    finally:
        F[recv, src] = saved
    if has_fine:
        Ht[fine] = near.box(Hf, fine)
    return Gather(np.where(tmask[..., None], Ht, np.nan), np.where(tmask[..., None], Be["texel"], np.nan), area,
                  tmask, it, converged)
