"""Visibility between patches: against the scene's faces (:func:`visibility_faces`, :func:`visible_faces`, the
default of lab.radiosity), and by brute-force numpy rays against every patch triangle
(core.geometry.ray_triangle_hits; small scenes, tests). Blender's BVHTree casts the same rays where too many
faces can block (lab.radiosity)."""
import numpy as np

from ..geometry import ray_triangle_hits
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


def near_candidate_pairs(patches, ratio=NEAR_RATIO):
    """:func:`near_pairs` of the :func:`candidate_pairs`, one block at a time: memory bounded by a block and
    the near pairs, never the O(N²) candidate list."""
    parts = [near_pairs(patches, i, j, ratio) for i, j in candidate_pair_blocks(patches)]
    if not parts:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


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
CLUSTER_LEAF = 64                   # points per cluster of visibility_faces


class Occluders:
    """Convex planar polygons (F, 4, 3) as planes n·x = d and inward edge planes m_k·x >= h_k (triangles
    repeat an edge): the blockers of :func:`visibility_faces` and :func:`visible_faces`."""

    def __init__(self, polys):
        polys = np.asarray(polys, np.float64).reshape(-1, 4, 3)
        e = np.roll(polys, -1, axis=1) - polys
        n = np.cross(polys[:, 2] - polys[:, 0], polys[:, 3] - polys[:, 1])
        n = np.where((np.linalg.norm(n, axis=1) > 0)[:, None], n, np.cross(e[:, 0], e[:, 1]))
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        self.polys, self.normal = polys, n
        self.d = np.einsum("fk,fk->f", n, polys[:, 0])
        self.m = np.cross(n[:, None, :], e)                       # inward for counter-clockwise corners
        self.h = np.einsum("fmk,fmk->fm", self.m, polys)

    def __len__(self):
        return len(self.polys)

    def take(self, idx):
        return Occluders(self.polys[idx])

    def side(self, points):
        """Signed distances (P, F) of points to the occluders' planes."""
        return points @ self.normal.T - self.d

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
    rest = {(int(base.owner[k]), int(base.source[k])) for k in front[~whole]}
    if rest:
        sel = np.array([(int(o), int(s)) in rest for o, s in zip(patches.owner, patches.source)]) & ~patches.back
        pc = patches.corners[sel]
        polys.append(pc[:, [0, 1, 2, 2]])
        q = pc[~patches.is_tri[sel]]
        polys.append(q[:, [0, 2, 3, 3]])
    return Occluders(np.concatenate(polys))


def _plane(c):
    n = np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1])
    bad = np.linalg.norm(n, axis=1) == 0
    n[bad] = np.cross(c[bad, 1] - c[bad, 0], c[bad, 2] - c[bad, 0])
    return c.mean(axis=1), n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def blocking(occ, points, eps=1e-12):
    """The occluders that can block a segment between two of ``points``: those with points strictly on both
    sides of their plane."""
    s = occ.side(points)
    return occ.take(np.flatnonzero((s > eps).any(axis=0) & (s < -eps).any(axis=0)))


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
    st_all, gt_all = occ.side(tc), occ.edges(tc)

    def visible(points, normals, src):
        out = np.ones(len(points))
        if not len(occ):
            return out
        step = max(1, OCCLUDER_PAIR_BLOCK // (5 * len(occ)))
        for s in range(0, len(points), step):
            o = points[s:s + step] + offset * normals[s:s + step]
            j = src[s:s + step]
            out[s:s + step] = ~_blocked(occ.side(o), st_all[j],
                                        lambda p, f: np.einsum("kc,kmc->km", o[p], occ.m[f]) - occ.h[f],
                                        lambda p, f: gt_all[j[p], f], o, tc[j], 2 * offset)
        return out
    return visible


def clusters(points, leaf=CLUSTER_LEAF):
    """Index arrays of spatially compact groups of at most ``leaf`` points (median splits along the longest
    side of the points' box)."""
    out, todo = [], [np.arange(len(points))]
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


def _classify(occ, box_a, box_b, s_a, s_b, end):
    """Per occluder (F,), for every segment between a point of cluster a and one of cluster b (boxes (8, 3)
    holding them; signed distances s (P, F) of their points): 0 none crosses it, 1 all do (before ``end`` of
    either end), 2 undecided. All cross when the boxes lie on opposite sides of the plane and the 64 segments
    between their corners cross inside the polygon (the plane's section of the hull of both boxes is the hull
    of those 64 crossings); none when both clusters are on one side, or the 64 crossings are all outside one
    edge."""
    F = len(occ)
    out = np.full(F, 2, np.int8)
    lo_a, hi_a, lo_b, hi_b = s_a.min(axis=0), s_a.max(axis=0), s_b.min(axis=0), s_b.max(axis=0)
    same = ((lo_a >= 0) & (lo_b >= 0)) | ((hi_a <= 0) & (hi_b <= 0))
    out[same] = 0
    ca, cb = occ.side(box_a), occ.side(box_b)                            # (8, F)
    apart = ((ca.min(axis=0) > 0) & (cb.max(axis=0) < 0)) | ((ca.max(axis=0) < 0) & (cb.min(axis=0) > 0))
    f = np.flatnonzero(apart & ~same)
    if not len(f):
        return out
    u = ca[:, None, f] / (ca[:, None, f] - cb[None, :, f])             # (8, 8, f)
    x = box_a[:, None, None, :] + u[..., None] * (box_b[None, :, None, :] - box_a[:, None, None, :])
    g = np.einsum("abfk,fmk->abfm", x, occ.m[f]) - occ.h[f]            # (8, 8, f, 4)
    inside = (g >= 0).all(axis=(0, 1, 3))
    far = (np.minimum(np.abs(s_a[:, f]).min(axis=0), np.abs(s_b[:, f]).min(axis=0)) > end)
    out[f[inside & far]] = 1
    outside = (g < 0).all(axis=(0, 1)).any(axis=-1)
    out[f[outside]] = 0
    return out


def _crossed(sa, sb, ga, gb, pa, pb, end):
    """(A, B) bool: the segment between point a and point b crosses one of the occluders, given signed
    distances sa (A, F), sb (B, F) and edge values ga (A, F, 4), gb (B, F, 4) of their ends. At the crossing
    x = a + u (b − a), u = sa / (sa − sb), the edge value is (sa gb − sb ga) / (sa − sb): inside where
    sign(sa) (sa gb − sb ga) >= 0 on every edge, no division. A crossing within ``end`` of either end does not
    count (looked at only for the occluders that close to a point)."""
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
            h[i, j, f] = (u * dist > end) & (u * dist < dist - end)
            hit[..., close] = h
    return hit.any(axis=2)


def _box(p):
    lo, hi = p.min(axis=0), p.max(axis=0)
    return np.stack(np.meshgrid(*zip(lo, hi), indexing="ij"), -1).reshape(8, 3)


def visibility_faces(patches, occ, offset=1e-4, progress=None, leaf=CLUSTER_LEAF):
    """Centre-to-centre visibility (N, N) bool against :class:`Occluders` ``occ`` (:func:`occluders`): the
    pairs each in front of the other's plane (as :func:`candidate_pair_blocks`), each segment from centre to
    centre lifted ``offset`` along the normals, a crossing within ``2 offset`` of its ends not counted (as
    lab.radiosity.visibility_bvh casts it). Only the occluders with points on both sides of their plane count;
    the points are grouped in :func:`clusters` and every pair of clusters is first classified against each
    occluder (:func:`_classify`): rays are tested only against the occluders it leaves undecided.
    ``progress()`` is called between rows of clusters."""
    n = len(patches)
    pts = patches.center + offset * patches.normal
    c, nrm = patches.center, patches.normal
    occ = blocking(occ, pts)
    V = np.zeros((n, n), bool)
    S = occ.side(pts)
    G = occ.edges(pts)
    groups = clusters(pts, leaf)
    boxes = [_box(pts[g]) for g in groups]
    end = 2 * offset
    for a, ia in enumerate(groups):
        if progress:
            progress()
        for b in range(a, len(groups)):
            ib = groups[b]
            d = c[ib][None, :, :] - c[ia][:, None, :]
            ok = (np.einsum("abk,ak->ab", d, nrm[ia]) > 1e-9) & (np.einsum("abk,bk->ab", d, nrm[ib]) < -1e-9)
            if a == b:
                ok &= ia[None, :] > ia[:, None]
            if not ok.any():
                continue
            cls = _classify(occ, boxes[a], boxes[b], S[ia], S[ib], end) if len(occ) else np.zeros(0, np.int8)
            if (cls == 1).any():
                continue
            f = np.flatnonzero(cls == 2)
            if len(f):
                ok &= ~_crossed(S[ia][:, f], S[ib][:, f], G[ia][:, f], G[ib][:, f], pts[ia], pts[ib], end)
            ra, rb = np.nonzero(ok)
            V[ia[ra], ib[rb]] = True
            V[ib[rb], ia[ra]] = True
    return V
