"""Visibility between patches: against the scene's faces (:func:`visibility_faces`, :func:`visible_faces`, the
default of lab.radiosity), and by brute-force numpy rays against every patch triangle
(core.geometry.ray_triangle_hits; small scenes, tests). Blender's BVHTree casts the same rays where too many
faces can block (lab.radiosity)."""
import numpy as np

from ..geometry import ray_triangle_hits
from .parallel import ordered_map
from .form_factors import NEAR_RATIO, near_pairs


def visible_numpy(patches, offset=1e-6):
    """A ``visible`` callback for :func:`core.radiosity.form_factors.seen_form_factors` by brute-force numpy rays (small scenes,
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


def near_candidate_pairs(patches, ratio=NEAR_RATIO, leaf=64):
    """:func:`near_pairs` of the :func:`candidate_pairs`: the candidates within pairs of :func:`clusters` whose
    boxes are close enough to hold a near pair (a near pair's centres lie within r_i + r_j + 2 ratio max(r_i,
    r_j) of each other), so that the work grows with the near pairs, not N²."""
    from .patches import bounding_radius
    c, nrm = patches.center, patches.normal
    if not len(c):
        return np.zeros(0, int), np.zeros(0, int)
    r = bounding_radius(patches)
    groups = clusters(c, leaf)
    lo = np.array([c[g].min(axis=0) for g in groups])
    hi = np.array([c[g].max(axis=0) for g in groups])
    rmax = np.array([r[g].max() for g in groups])
    parts = []
    for a, ia in enumerate(groups):
        gap = np.linalg.norm(np.maximum(np.maximum(lo[a:] - hi[a], lo[a] - hi[a:]), 0.0), axis=1)
        reach = (1 + 2 * ratio) * np.maximum(rmax[a], rmax[a:]) + np.minimum(rmax[a], rmax[a:])
        close = a + np.flatnonzero(gap <= reach * (1 + 1e-9))
        ib = np.concatenate([groups[b] for b in close])
        later = np.repeat(close > a, [len(groups[b]) for b in close])
        d = np.take(c, ib, axis=0)[None, :, :] - c[ia][:, None, :]
        ok = ((np.einsum("abk,ak->ab", d, nrm[ia]) > 1e-9)
              & (np.einsum("abk,bk->ab", d, np.take(nrm, ib, axis=0)) < -1e-9))
        ok &= later[None, :] | (ib[None, :] > ia[:, None])
        ra, rb = np.nonzero(ok)
        i, j = ia[ra], ib[rb]
        parts.append(near_pairs(patches, np.minimum(i, j), np.maximum(i, j), ratio))
    recv = np.concatenate([p[0] for p in parts])
    src = np.concatenate([p[1] for p in parts])
    order = np.lexsort((src, recv))
    return recv[order], src[order]


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


# ----------------------------------------------------------------------------- occluder faces
# A ray between two patches is blocked by the scene's faces, not by the patches they were cut into: the
# patches of a planar face tile it. Testing every ray against the few faces that can block anything (a face
# with points on both sides of its plane) replaces a BVH ray per pair (a Python call each, ~3 µs) by
# vectorised plane and edge tests, about 5 ns a ray and face.
PLANAR_TOL = 1e-7          # a quad is planar (and kept whole) when its 4th corner is this close to the plane
                           # of the other three, relative to its size
OCCLUDER_PAIR_BLOCK = 4_000_000     # ray-face tests held at once
CLUSTER_LEAF = 32                   # points per cluster of visibility_faces


class Occluders:
    """Convex planar polygons (F, 4, 3) as planes n·x = d and inward edge planes m_k·x >= h_k (triangles
    repeat an edge): the blockers of :func:`visibility_faces` and :func:`visible_faces`. ``group`` (F,): the
    non-planar face a triangle was cut from (-1: a whole face), whose triangles all lie in one slab."""

    def __init__(self, polys, group=None):
        polys = np.asarray(polys, np.float64).reshape(-1, 4, 3)
        self.group = np.full(len(polys), -1) if group is None else np.asarray(group, int)
        e = np.roll(polys, -1, axis=1) - polys
        n = np.cross(polys[:, 2] - polys[:, 0], polys[:, 3] - polys[:, 1])
        n = np.where((np.linalg.norm(n, axis=1) > 0)[:, None], n, np.cross(e[:, 0], e[:, 1]))
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        self.polys, self.normal = polys, n
        self.d = np.einsum("fk,fk->f", n, polys[:, 0])
        self.m = np.cross(n[:, None, :], e)                       # inward for counter-clockwise corners
        self.h = np.einsum("fmk,fmk->fm", self.m, polys)
        self._side = None

    def __len__(self):
        return len(self.polys)

    def take(self, idx):
        return Occluders(self.polys[idx], self.group[idx])

    def side(self, points):
        """Signed distances (P, F) of points to the occluders' planes (the last points' kept: blocking,
        visibility_faces and visible_faces ask for the same patch points in turn). Read only."""
        if getattr(self, "_side", None) is not None and np.array_equal(self._side[0], points):
            return self._side[1]
        S = points @ self.normal.T
        S -= self.d
        self._side = (np.array(points), S)
        return S

    def edges(self, points):
        """m_k·x − h_k (P, F, 4): all >= 0 where x's projection lies inside the polygon."""
        return (points @ self.m.reshape(-1, 3).T).reshape(len(points), *self.h.shape) - self.h


def whole_faces(base):
    """(N,) bool: the faces of ``base`` that block as one polygon in :func:`occluders` (triangles, planar convex
    quads; back sides False)."""
    c = base.corners
    size = np.linalg.norm(c.max(axis=1) - c.min(axis=1), axis=1)
    _, nrm = _plane(c)
    off = np.abs(np.einsum("fk,fk->f", c[:, 3] - c[:, 0], nrm))
    e = np.roll(c, -1, axis=1) - c
    turn = np.einsum("fmk,fk->fm", np.cross(e, np.roll(e, -1, axis=1)), nrm)
    convex = base.is_tri | (turn >= -1e-12 * size[:, None] ** 2).all(axis=1)
    return ~base.back & (base.is_tri | ((off <= PLANAR_TOL * size) & convex))


def occluders(base, patches=None):
    """The faces that can block a ray between ``patches`` (default ``base``): every front-side face of
    ``base`` (the unsplit patches) that is planar and convex as a whole polygon, and for the others the
    triangles of the ``patches`` cut from them (matched by owner and source face)."""
    patches = base if patches is None else patches
    whole_all = whole_faces(base)
    front = np.flatnonzero(~base.back)
    c, whole = base.corners[front], whole_all[front]
    polys = [c[whole]]
    rest = sorted({(int(base.owner[k]), int(base.source[k])) for k in front[~whole]})
    group = [np.full(len(polys[0]), -1)]
    if rest:
        key = {k: g for g, k in enumerate(rest)}
        gid = np.array([key.get((int(o), int(s)), -1) for o, s in zip(patches.owner, patches.source)])
        sel = (gid >= 0) & ~patches.back
        pc = patches.corners[sel]
        polys.append(pc[:, [0, 1, 2, 2]])
        group.append(gid[sel])
        q = ~patches.is_tri[sel]
        polys.append(pc[q][:, [0, 2, 3, 3]])
        group.append(gid[sel][q])
    return Occluders(np.concatenate(polys), np.concatenate(group))


def _plane(c):
    n = np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1])
    bad = np.linalg.norm(n, axis=1) == 0
    n[bad] = np.cross(c[bad, 1] - c[bad, 0], c[bad, 2] - c[bad, 0])
    return c.mean(axis=1), n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def blocking(occ, points, eps=1e-12):
    """The occluders that can block a segment between two of ``points``: those with points strictly on both
    sides of their plane."""
    pos, neg = np.zeros(len(occ), bool), np.zeros(len(occ), bool)
    for k in range(0, len(points), 2048):
        s = points[k:k + 2048] @ occ.normal.T
        s -= occ.d
        pos |= (s > eps).any(axis=0)
        neg |= (s < -eps).any(axis=0)
    out = occ.take(np.flatnonzero(pos & neg))
    out.side(points)
    return out


def _blocked(so, st, go, gt, o, t, end):
    """Segments o -> t (M, 3) with signed distances so, st (M, F) to the occluders' planes: True where one
    crosses an occluder's polygon before ``end`` short of t. ``go(p, f)``, ``gt(p, f)`` give the edge values
    (K, 4) of the segments' ends for the crossings (p, f) only."""
    hit = np.zeros(len(so), bool)
    p, f = np.nonzero(so * st < 0)
    if not len(p):
        return hit
    u = so[p, f] / (so[p, f] - st[p, f])
    a = go(p, f)
    inside = (a + u[:, None] * (gt(p, f) - a) >= 0).all(axis=1)
    if end > 0 and inside.any():
        k = np.flatnonzero(inside)
        dist = np.linalg.norm(t[p[k]] - o[p[k]], axis=1)
        inside[k] = u[k] * dist < dist - end
    hit[p[inside]] = True
    return hit


def visible_faces(patches, occ, offset=1e-4):
    """The ``visible(points, normals, src)`` callback of core.radiosity.form_factors.seen_form_factors by
    :class:`Occluders`: 1 where the segment from the point (lifted ``offset`` along its normal) to the source
    patch's centre (lifted likewise), ``2 offset`` short of it, crosses no occluder (as lab.radiosity.visible_bvh
    casts it)."""
    tc = patches.center + offset * patches.normal
    st_all = occ.side(tc)
    centre = occ.polys.mean(axis=1)
    radius = np.linalg.norm(occ.polys - centre[:, None], axis=2).max(axis=1)

    def visible(points, normals, src):
        out = np.ones(len(points))
        if not len(occ):
            return out
        step = max(1, OCCLUDER_PAIR_BLOCK // (5 * len(occ)))
        for s in range(0, len(points), step):
            o = points[s:s + step] + offset * normals[s:s + step]
            j = src[s:s + step]
            ends = np.concatenate([o, tc[j]])
            lo, hi = ends.min(axis=0), ends.max(axis=0)
            near = np.linalg.norm(np.maximum(np.maximum(lo - centre, centre - hi), 0.0), axis=1) <= radius
            box = _box(ends)
            sb = box @ occ.normal[near].T - occ.d[near]
            f = np.flatnonzero(near)[(sb.min(axis=0) < 0) & (sb.max(axis=0) > 0)]
            if not len(f):
                continue
            sub = occ.take(f)
            out[s:s + step] = ~_blocked(sub.side(o), st_all[j[:, None], f],
                                        lambda p, k: np.einsum("kc,kmc->km", o[p], sub.m[k]) - sub.h[k],
                                        lambda p, k: np.einsum("kc,kmc->km", tc[j[p]], sub.m[k]) - sub.h[k],
                                        o, tc[j], 2 * offset)
        return out
    visible.threadsafe = True                   # numpy only, no state shared between calls
    return visible


def clusters(points, leaf=CLUSTER_LEAF, keys=None):
    """Index arrays of spatially compact groups of at most ``leaf`` points (median splits along the longest
    side of the points' box), within the groups of equal ``keys`` (e.g. the face a patch was cut from: a
    cluster on one plane has tight bounds against the occluders) when given."""
    keys = np.zeros(len(points), int) if keys is None else np.asarray(keys)
    out, todo = [], [np.flatnonzero(keys == k) for k in np.unique(keys)]
    while todo:
        idx = todo.pop()
        if len(idx) <= leaf:
            out.append(idx)
            continue
        p = points[idx]
        axis = int(np.argmax(p.max(axis=0) - p.min(axis=0)))
        order = idx[np.argsort(p[:, axis], kind="stable")]
        todo += [order[:len(order) // 2], order[len(order) // 2:]]
    return out


class _ClusterBounds:
    """Per cluster and occluder (C, F): the extremes of the cluster's signed distances (lo, hi), the smallest
    distance of its points strictly in front (pos) and strictly behind (neg; inf where none), and the gap from
    its box to the occluder's bounding sphere (gap); per cluster its box's corners, centre and half-diagonal."""

    def __init__(self, occ, pts, S, groups):
        C, F = len(groups), len(occ)
        self.lo, self.hi = np.empty((C, F)), np.empty((C, F))
        self.pos, self.neg = np.empty((C, F)), np.empty((C, F))
        self.box = np.empty((C, 8, 3))
        lo3, hi3 = np.empty((C, 3)), np.empty((C, 3))
        for g, idx in enumerate(groups):
            s = S[idx]
            self.lo[g], self.hi[g] = s.min(axis=0), s.max(axis=0)
            self.pos[g] = np.where(s > 0, s, np.inf).min(axis=0)
            self.neg[g] = np.where(s < 0, -s, np.inf).min(axis=0)
            lo3[g], hi3[g] = pts[idx].min(axis=0), pts[idx].max(axis=0)
            self.box[g] = _box(pts[idx])
        self.lo3, self.hi3 = lo3, hi3
        self.centre, self.radius = (lo3 + hi3) / 2, np.linalg.norm(hi3 - lo3, axis=1) / 2
        centre = occ.polys.mean(axis=1)
        self.occ_centre = centre
        self.occ_radius = np.linalg.norm(occ.polys - centre[:, None], axis=2).max(axis=1)
        out = np.maximum(np.maximum(lo3[:, None] - centre[None], centre[None] - hi3[:, None]), 0.0)
        self.gap = np.linalg.norm(out, axis=2) - self.occ_radius[None]
        groups_f = occ.group
        G = int(groups_f.max()) + 1 if len(groups_f) else 0
        self.slab_lo, self.slab_hi = np.zeros(G), np.zeros(G)
        self.cl_lo, self.cl_hi = np.zeros((C, G)), np.zeros((C, G))
        for g in range(G):
            mine = groups_f == g
            if not mine.any():
                continue
            n = occ.normal[mine].sum(axis=0)
            n /= max(np.linalg.norm(n), 1e-300)
            h = occ.polys[mine].reshape(-1, 3) @ n
            self.slab_lo[g], self.slab_hi[g] = h.min(), h.max()
            for k, idx in enumerate(groups):
                e = pts[idx] @ n
                self.cl_lo[k, g], self.cl_hi[k, g] = e.min(), e.max()
        # per cluster and occluder: all points on one side of its plane (above, below); per cluster and
        # non-planar face: all on one side of its slab, clear of it (gabove, gbelow)
        self.above, self.below = self.lo >= 0, self.hi <= 0
        self.gabove = self.cl_lo > self.slab_hi[None] + CULL_MARGIN
        self.gbelow = self.cl_hi < self.slab_lo[None] - CULL_MARGIN
        self.whole = np.flatnonzero(groups_f < 0)
        self.members = [np.flatnonzero(groups_f == g) for g in range(G)]


CULL_MARGIN = 1e-9       # metres: a bound of _classify must clear the occluder by this much to rule it out


def _longest(cb, a, bs):
    """(B,) the longest segment between a point of cluster a's box and one of each of ``bs``'."""
    return np.linalg.norm(np.maximum(np.abs(cb.hi3[bs] - cb.lo3[a]), np.abs(cb.hi3[a] - cb.lo3[bs])), axis=1)


def _reach(xlo, xhi, ylo, yhi, lo, hi):
    """For segments x -> y with x's heights in [xlo, xhi], y's in [ylo, yhi] < lo (below the slab [lo, hi]):
    bounds (Rx, Ry), relative to the segment's length, of the distance from x and from y of any point of the
    segment inside the slab. A point at height h lies |h_x − h| / (h_x − h_y) of the way from x, at most
    (h_x − lo) / (h_x − h_y), largest at h_x = xhi, h_y = yhi; from y (h − h_y) / (h_x − h_y) with
    h <= min(hi, h_x), largest at h_x = max(xlo, hi), h_y = ylo."""
    return (np.maximum(xhi - lo, 0.0) / (xhi - yhi),
            np.minimum((hi - ylo) / (np.maximum(xlo, hi) - ylo), 1.0))


def _candidates(cb, a, bs):
    """(bi, f): the pairs (cluster bs[bi], occluder f) that :func:`_classify` looks at for cluster a. A whole
    face: unless both clusters lie on one side of its plane. A triangle of a non-planar face: unless both
    clusters lie clear of the face's slab on one side; and where one of them lies clear of it, only the
    triangles within reach of both ends (:func:`_reach`: every triangle lies inside the slab, so a segment
    can cross one only where it runs inside the slab)."""
    parts_b, parts_f = [], []
    w = cb.whole
    if len(w):
        same = (cb.above[a, w][None] & cb.above[bs][:, w]) | (cb.below[a, w][None] & cb.below[bs][:, w])
        bi, k = np.nonzero(~same)
        parts_b.append(bi)
        parts_f.append(w[k])
    L = None
    for g, mem in enumerate(cb.members):
        if not len(mem):
            continue
        ua, da = cb.gabove[a, g], cb.gbelow[a, g]
        ub, db = cb.gabove[bs, g], cb.gbelow[bs, g]
        keep = np.flatnonzero(~((ua & ub) | (da & db)))
        if not len(keep):
            continue
        if L is None:
            L = _longest(cb, a, bs)
        lo, hi = cb.slab_lo[g], cb.slab_hi[g]
        alo, ahi = cb.cl_lo[a, g], cb.cl_hi[a, g]
        blo, bhi = cb.cl_lo[bs[keep], g], cb.cl_hi[bs[keep], g]
        ra, rb = np.full(len(keep), np.inf), np.full(len(keep), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            for (clear_b, clear_a, sgn) in ((db[keep], da, 1.0), (ub[keep], ua, -1.0)):
                xlo, xhi, ylo, yhi = (alo, ahi, blo, bhi) if sgn > 0 else (-ahi, -alo, -bhi, -blo)
                slo, shi = (lo, hi) if sgn > 0 else (-hi, -lo)
                r1, r2 = _reach(xlo, xhi, ylo, yhi, slo, shi)          # b clear of the slab: a the x end
                ra = np.where(clear_b, np.minimum(ra, r1), ra)
                rb = np.where(clear_b, np.minimum(rb, r2), rb)
                if clear_a:                                          # a clear of it: b the x end
                    r1, r2 = _reach(ylo, yhi, xlo, xhi, slo, shi)
                    rb, ra = np.minimum(rb, r1), np.minimum(ra, r2)
        lk = L[keep]
        ok = ((cb.gap[a, mem][None] <= (ra * lk)[:, None] + CULL_MARGIN)
              & (cb.gap[bs[keep]][:, mem] <= (rb * lk)[:, None] + CULL_MARGIN))
        bi, k = np.nonzero(ok)
        parts_b.append(keep[bi])
        parts_f.append(mem[k])
    if not parts_b:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(parts_b), np.concatenate(parts_f)


def _classify(occ, cb, a, bs, end):
    """(bi, f, v): per cluster b = bs[bi] and occluder f, for every segment between a point of cluster a and one
    of cluster b (:class:`_ClusterBounds` ``cb``), v = 1 all cross it (before ``end`` of either end) or 2
    undecided; the pairs left out none crosses (among them every pair :func:`_candidates` leaves out).

    None: both clusters on one side of the plane, or outside the slab of the non-planar face the occluder was
    cut from (on one side of it); or the occluder's bounding sphere misses the capsule of
    radius max(r_a, r_b) around the segment between the boxes' centres (it holds the hull of both boxes); or it
    lies beyond the reach of every crossing: a segment p -> q with s_p < 0 < s_q crosses the plane at
    |x − p| = |s_p| |q − p| / (|s_p| + s_q) <= M_a L / (M_a + m_b) from p (M_a the deepest of a's points behind,
    m_b the nearest of b's in front, L the longest segment between the boxes), likewise from q, and x must lie
    on the polygon, no nearer to a's box than its bounding sphere (either orientation); or the 64 segments
    between the boxes' corners (when the boxes lie on opposite sides) all cross outside one edge. All: the
    boxes on opposite sides and those 64 crossings all inside the polygon (the plane's section of the hull of
    both boxes is the hull of those 64 crossings)."""
    bs = np.asarray(bs)
    bi, f = _candidates(cb, a, bs)
    if not len(f):
        return bi, f, np.zeros(0, np.int8)
    b = bs[bi]
    ca = cb.centre[a]
    seg = cb.centre[b] - ca                                                         # (K, 3)
    t = np.clip(np.einsum("kc,kc->k", cb.occ_centre[f] - ca, seg) / np.maximum(np.einsum("kc,kc->k", seg, seg),
                                                                                1e-300), 0.0, 1.0)
    dist = np.linalg.norm(cb.occ_centre[f] - (ca + t[:, None] * seg), axis=1)
    miss = dist > np.maximum(cb.radius[a], cb.radius[b]) + cb.occ_radius[f] + CULL_MARGIN
    L = np.linalg.norm(np.maximum(np.abs(cb.hi3[b] - cb.lo3[a]), np.abs(cb.hi3[a] - cb.lo3[b])), axis=1)
    ga, gb = cb.gap[a, f] - CULL_MARGIN, cb.gap[b, f] - CULL_MARGIN
    la, ha, lb, hb = cb.lo[a, f], cb.hi[a, f], cb.lo[b, f], cb.hi[b, f]
    with np.errstate(invalid="ignore", divide="ignore"):
        one = ((la < 0) & (hb > 0) & (ga <= -la * L / (-la + cb.pos[b, f])) & (gb <= hb * L / (hb + cb.neg[a, f])))
        two = ((ha > 0) & (lb < 0) & (ga <= ha * L / (ha + cb.neg[b, f])) & (gb <= -lb * L / (-lb + cb.pos[a, f])))
    keep = ~miss & (one | two)
    bi, f, b = bi[keep], f[keep], b[keep]
    v = np.full(len(f), 2, np.int8)
    if not len(f):
        return bi, f, v
    box_a, box_b = cb.box[a], cb.box[b]                                             # (8, 3), (K, 8, 3)
    ca8 = (box_a @ occ.normal.T - occ.d)[:, f]                                      # (8, K)
    cb8 = (np.einsum("kec,kc->ek", box_b, occ.normal[f]) - occ.d[f])                # (8, K)
    apart = np.flatnonzero(((ca8.min(axis=0) > 0) & (cb8.max(axis=0) < 0))
                           | ((ca8.max(axis=0) < 0) & (cb8.min(axis=0) > 0)))
    if not len(apart):
        return bi, f, v
    fa, ba, ca8, cb8, box_b = f[apart], b[apart], ca8[:, apart], cb8[:, apart], box_b[apart]
    u = ca8[:, None] / (ca8[:, None] - cb8[None, :])                               # (8, 8, K)
    x = box_a[:, None, None, :] + u[..., None] * (np.moveaxis(box_b, 1, 0)[None] - box_a[:, None, None, :])
    g = np.einsum("abkc,kmc->abkm", x, occ.m[fa]) - occ.h[fa]                       # (8, 8, K, 4)
    inside = (g >= 0).all(axis=(0, 1, 3))
    far = np.minimum(np.minimum(cb.pos[a, fa], cb.neg[a, fa]), np.minimum(cb.pos[ba, fa], cb.neg[ba, fa])) > end
    v[apart[inside & far]] = 1
    outside = (g < 0).all(axis=(0, 1)).any(axis=-1)
    v[apart[outside]] = 0
    keep = v > 0
    return bi[keep], f[keep], v[keep]


def _crossed(sa, sb, ga, gb, pa, pb, end, ia, ib):
    """(A, B) bool: the segment between point a and point b crosses one of the occluders, given signed
    distances sa (A, F), sb (B, F) and edge values ga (A, F, 4), gb (B, F, 4) of their ends. At the crossing
    x = a + u (b − a), u = sa / (sa − sb), the edge value is (sa gb − sb ga) / (sa − sb): inside where
    sign(sa) (sa gb − sb ga) >= 0 on every edge, no division. The ray runs from the point of the smaller index
    (``ia``, ``ib``: the points' patch indices) to the other, as lab.radiosity.visibility_bvh casts it: a
    crossing within ``end`` of its target does not count, one at its origin does (looked at only for the
    occluders that close to a point)."""
    sg = np.sign(sa)
    abs_a, ga = (sa * sg)[:, None, :], (ga * sg[..., None])[:, None]
    sb2, gb2 = sb[None], gb[None]
    hit = (sa[:, None, :] * sb2) < 0
    for k in range(4):
        hit &= abs_a * gb2[..., k] - sb2 * ga[..., k] >= 0
    close = (np.abs(sa).min(axis=0) <= end) | (np.abs(sb).min(axis=0) <= end)
    if close.any():
        h = hit[..., close]
        i, j, f = np.nonzero(h)
        if len(i):
            sa_c, sb_c = sa[:, close], sb[:, close]
            u = sa_c[i, f] / (sa_c[i, f] - sb_c[j, f])
            dist = np.linalg.norm(pb[j] - pa[i], axis=1)
            h[i, j, f] = np.where(ia[i] < ib[j], u * dist < dist - end, u * dist > end)
            hit[..., close] = h
    return hit.any(axis=2)


def _box(p):
    lo, hi = p.min(axis=0), p.max(axis=0)
    return np.stack(np.meshgrid(*zip(lo, hi), indexing="ij"), -1).reshape(8, 3)


def visibility_faces(patches, occ, offset=1e-4, progress=None, leaf=CLUSTER_LEAF):
    """Centre-to-centre visibility (N, N) bool against :class:`Occluders` ``occ`` (:func:`occluders`): the
    pairs each in front of the other's plane (as :func:`candidate_pair_blocks`), each segment from centre to
    centre lifted ``offset`` along the normals, the ray from the smaller index to the larger, a crossing within
    ``2 offset`` of its target not counted (as lab.radiosity.visibility_bvh casts it). Only the occluders with
    points on both sides of their plane count. The points are grouped in :func:`clusters`; every pair of
    clusters with a candidate pair is first classified against the occluders (:func:`_classify`, a non-planar
    face's triangles first as one slab, :func:`_candidates`), and its rays are tested only against the
    occluders it leaves undecided, the cluster pairs with the same undecided occluders in one go. The rows run
    in a fixed shuffled order (each writes its own part of the matrix), so the time of the first rows tells that
    of the whole: ``progress(rows done, rows, share of the candidate pairs done)`` is called after each."""
    n = len(patches)
    pts = patches.center + offset * patches.normal
    S = occ.side(pts)
    keep = np.flatnonzero((S > 1e-12).any(axis=0) & (S < -1e-12).any(axis=0))      # as blocking()
    if len(keep) < len(occ):
        occ, S = occ.take(keep), S[:, keep]
    groups = clusters(pts, leaf, patches.owner * (int(patches.source.max()) + 1) * 2
                      + patches.source * 2 + patches.back) if n else []
    cb = _ClusterBounds(occ, pts, S, groups)
    m3 = occ.m.reshape(-1, 3)
    end = 2 * offset
    # W: rows in cluster order (a cluster's pairs with the clusters after it are one block), columns the
    # patches'
    order = np.concatenate(groups) if n else np.zeros(0, int)
    start = np.concatenate([[0], np.cumsum([len(g) for g in groups])]).astype(int)
    c, nrm = patches.center[order], patches.normal[order]
    own = np.einsum("ik,ik->i", c, nrm)
    W = np.zeros((n, n), bool)

    def row(a):
        """Row block a: its pairs with the clusters from a on (rows s0:s1 and their transposes, which no
        other row block writes: rows run in two threads)."""
        ia = groups[a]
        s0, s1 = start[a], start[a + 1]
        # j in front of i: (c_j − c_i)·n_i > 0; i in front of j: (c_j − c_i)·n_j < 0
        ok = (c[s0:] @ nrm[s0:s1].T).T - own[s0:s1, None] > 1e-9
        ok &= (c[s0:s1] @ nrm[s0:].T) - own[None, s0:] > 1e-9
        ok[:, :s1 - s0] &= np.tri(s1 - s0, k=-1, dtype=bool).T
        width = np.diff(start[a:])
        live = np.flatnonzero(np.logical_or.reduceat(ok.any(axis=0), start[a:-1] - s0))
        if len(occ) and len(live):
            bi, fi, v = _classify(occ, cb, a, a + live, end)
            bi = live[bi]
            blocked = np.bincount(bi[v == 1], minlength=len(width)) > 0
            und = v == 2
            by = np.argsort(bi[und], kind="stable")
            ub, uf = bi[und][by], fi[und][by]
            cut = np.searchsorted(ub, np.arange(len(width) + 1))
        else:
            blocked, cut = np.zeros(len(width), bool), np.zeros(len(width) + 1, int)
        ok[:, np.repeat(blocked, width)] = False
        # the undecided cluster pairs by the occluders left to test: one call a set (their points side by side)
        todo = {}
        for k in np.flatnonzero(~blocked & (np.diff(cut) > 0)):
            todo.setdefault(uf[cut[k]:cut[k + 1]].tobytes(), []).append(k)
        ga = (pts[ia] @ m3.T).reshape(len(ia), len(occ), 4) - occ.h if todo else None
        for ks in todo.values():
            f = uf[cut[ks[0]]:cut[ks[0] + 1]]
            cols = np.concatenate([np.arange(start[a + k], start[a + k + 1]) for k in ks]) - s0
            cols = cols[ok[:, cols].any(axis=0)]
            if not len(cols):
                continue
            jb = order[s0 + cols]
            gb = (pts[jb] @ occ.m[f].reshape(-1, 3).T).reshape(len(jb), len(f), 4) - occ.h[f]
            ok[:, cols] &= ~_crossed(S[ia[:, None], f], S[jb[:, None], f], ga[:, f], gb, pts[ia], pts[jb], end,
                                     ia, jb)
        W[s0:s1, order[s0:]] = ok
        W[s1:, ia] = ok[:, s1 - s0:].T
        W[s0:s1, ia] |= ok[:, :s1 - s0].T

    rows = np.random.default_rng(0).permutation(len(groups))
    sizes = np.diff(start).astype(np.float64)
    pairs = sizes * (n - start[:-1])
    share = np.cumsum(pairs[rows]) / max(pairs.sum(), 1.0)
    for k, _ in enumerate(ordered_map(row, rows)):
        if progress:
            progress(k + 1, len(groups), float(share[k]))
    inv = np.empty(n, int)
    inv[order] = np.arange(n)
    return W[inv]
