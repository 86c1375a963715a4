"""A bounding-volume hierarchy over triangles and its numpy traversal (closest hit, any hit).

Built top-down with a median split of the triangle centroids along the widest axis (pbrt-v3 §4.3,
"SplitMethod::EqualCounts"); leaves hold at most ``leaf_size`` triangles. Traversal is breadth-first
over (ray, node) pairs, all rays at once: each round keeps the pairs whose ray enters the node's box
before its current closest hit (the slab test, Kay & Kajiya 1986), expands inner nodes into their two
children and intersects leaves with :func:`core.geometry.ray_triangle` (Möller & Trumbore 1997).
"""
import numpy as np

from ..geometry import ray_triangle

#: Triangles per leaf at most.
LEAF_SIZE = 8
#: (ray, triangle) pairs intersected at once (memory: ~40 arrays of this many float64).
PAIR_CHUNK = 1 << 18


class BVH:
    """``BVH(tris)`` over (T, 3, 3) world-space triangles; ``closest(o, d)`` and ``occluded(o, d, tmax)``."""

    def __init__(self, tris, leaf_size=LEAF_SIZE):
        tris = np.asarray(tris, np.float64).reshape(-1, 3, 3)
        self.tris = tris
        lo_t, hi_t = tris.min(1), tris.max(1)
        cent = (lo_t + hi_t) / 2
        order = np.arange(len(tris))
        lo, hi, left, right, start, count = [], [], [], [], [], []

        def node(idx):
            i = len(lo)
            lo.append(lo_t[idx].min(0) if len(idx) else np.zeros(3))
            hi.append(hi_t[idx].max(0) if len(idx) else -np.ones(3))
            left.append(-1), right.append(-1), start.append(0), count.append(0)
            return i

        root = node(order)
        stack = [(root, order)]
        leaves = []
        while stack:
            i, idx = stack.pop()
            if len(idx) <= leaf_size:
                leaves.append((i, idx))
                continue
            c = cent[idx]
            axis = int(np.argmax(c.max(0) - c.min(0)))
            half = len(idx) // 2
            part = idx[np.argpartition(c[:, axis], half)]
            a, b = part[:half], part[half:]
            left[i], right[i] = node(a), node(b)
            stack += [(left[i], a), (right[i], b)]
        perm = []
        for i, idx in leaves:
            start[i], count[i] = len(perm), len(idx)
            perm.extend(idx.tolist())
        self.perm = np.asarray(perm, np.int64)
        self.leaf_tris = tris[self.perm]
        self.lo, self.hi = np.asarray(lo), np.asarray(hi)
        self.left, self.right = np.asarray(left, np.int64), np.asarray(right, np.int64)
        self.start, self.count = np.asarray(start, np.int64), np.asarray(count, np.int64)
        self.tests = 0          # ray-triangle tests of the last query (for the report)

    def __len__(self):
        return len(self.tris)

    def _slab(self, o, inv, nodes, t_hi):
        """Slab test: does each ray (o, 1/d) enter box ``nodes`` at some t in [0, t_hi]?"""
        with np.errstate(invalid="ignore"):
            t0 = (self.lo[nodes] - o) * inv
            t1 = (self.hi[nodes] - o) * inv
        t0 = np.nan_to_num(t0, nan=-np.inf)
        t1 = np.nan_to_num(t1, nan=np.inf)
        near = np.minimum(t0, t1).max(1)
        far = np.maximum(t0, t1).min(1)
        return (near <= far) & (far >= 0.0) & (near <= t_hi)

    def _traverse(self, o, d, tmin, tmax, any_hit):
        n = len(o)
        best = np.array(tmax, np.float64, copy=True)
        tri = np.full(n, -1, np.int64)
        self.tests = 0
        if not len(self.tris) or not n:
            return best, tri
        with np.errstate(divide="ignore"):
            inv = 1.0 / d
        rays = np.arange(n)
        nodes = np.zeros(n, np.int64)
        while len(rays):
            keep = self._slab(o[rays], inv[rays], nodes, best[rays])
            if any_hit:
                keep &= tri[rays] < 0
            rays, nodes = rays[keep], nodes[keep]
            leaf = self.left[nodes] < 0
            self._leaves(o, d, tmin, rays[leaf], nodes[leaf], best, tri, any_hit)
            inner_r, inner_n = rays[~leaf], nodes[~leaf]
            rays = np.concatenate([inner_r, inner_r])
            nodes = np.concatenate([self.left[inner_n], self.right[inner_n]])
        return best, tri

    def _leaves(self, o, d, tmin, rays, nodes, best, tri, any_hit):
        """Intersect every (ray, leaf) pair's triangles; keep each ray's nearest hit in (tmin, best)."""
        if not len(rays):
            return
        cnt = self.count[nodes]
        pr = np.repeat(rays, cnt)
        first = np.repeat(self.start[nodes], cnt)
        offs = np.arange(len(pr)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        pt = first + offs
        self.tests += len(pr)
        for s in range(0, len(pr), PAIR_CHUNK):
            r, t_idx = pr[s:s + PAIR_CHUNK], pt[s:s + PAIR_CHUNK]
            v = self.leaf_tris[t_idx]
            t = ray_triangle(o[r], d[r], v[:, 0], v[:, 1], v[:, 2], eps=1e-14, edge_eps=1e-9)
            ok = np.isfinite(t) & (t > tmin[r]) & (t < best[r])
            r, t, t_idx = r[ok], t[ok], t_idx[ok]
            if not len(r):
                continue
            order = np.lexsort((t, r))
            r, t, t_idx = r[order], t[order], t_idx[order]
            firsts = np.r_[True, r[1:] != r[:-1]]
            r, t, t_idx = r[firsts], t[firsts], t_idx[firsts]
            closer = t < best[r]
            best[r[closer]] = t[closer]
            tri[r[closer]] = self.perm[t_idx[closer]]

    def closest(self, origins, dirs, tmin=1e-6, tmax=np.inf):
        """(t, triangle index) of the nearest hit of each ray o + t d with tmin < t < tmax; (tmax, -1) on a miss."""
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(dirs, np.float64).reshape(-1, 3)
        return self._traverse(o, d, np.broadcast_to(np.asarray(tmin, np.float64), len(o)),
                              np.broadcast_to(np.asarray(tmax, np.float64), len(o)), False)

    def occluded(self, origins, dirs, tmax, tmin=1e-6):
        """(R,) bool: does anything lie on o + t d for tmin < t < tmax (a shadow ray)?"""
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(dirs, np.float64).reshape(-1, 3)
        _, tri = self._traverse(o, d, np.broadcast_to(np.asarray(tmin, np.float64), len(o)),
                                np.broadcast_to(np.asarray(tmax, np.float64), len(o)), True)
        return tri >= 0


def brute_closest(origins, dirs, tris, tmin=1e-6):
    """Every ray against every triangle (the oracle the BVH is tested against): (t, triangle) or (inf, -1)."""
    tris = np.asarray(tris, np.float64)
    t = ray_triangle(np.asarray(origins, np.float64)[:, None], np.asarray(dirs, np.float64)[:, None],
                     tris[None, :, 0], tris[None, :, 1], tris[None, :, 2], eps=1e-14, edge_eps=1e-9)
    t = np.where(np.isfinite(t) & (t > tmin), t, np.inf)
    idx = np.argmin(t, axis=1)
    best = t[np.arange(len(t)), idx]
    return best, np.where(np.isfinite(best), idx, -1)
