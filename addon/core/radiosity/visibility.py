"""Visibility between patches by brute-force numpy rays (core.geometry.ray_triangle_hits; small scenes, tests);
Blender's BVHTree does the same for big ones (lab.radiosity)."""
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
