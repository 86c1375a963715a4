"""Geometry shared by the core: the one ray–triangle intersection (Möller & Trumbore 1997).

Used by the shadow volumes (distance along a ray, core.shadow.volume) and the radiosity
visibility rays (any hit on a segment, core.radiosity.visibility).
"""
import numpy as np


def _dot(a, b):
    return np.einsum("...k,...k->...", a, b)


def ray_triangle(origins, dirs, v0, v1, v2, eps=1e-12, edge_eps=0.0):
    """Möller-Trumbore: distance t along rays o + t d to triangles (v0, v1, v2); NaN on a miss.

    Arrays (..., 3) broadcast against each other (one ray per triangle, or (S, 1, 3) rays against
    (1, T, 3) triangles); t is in units of |d| and may be negative (caller filters). Edges are
    inclusive, widened by ``edge_eps`` in barycentric units (u >= -edge_eps, v >= -edge_eps,
    u + v <= 1 + edge_eps); ``eps`` is the smallest |det| (rays parallel to the plane miss).
    """
    e1 = v1 - v0
    e2 = v2 - v0
    p = np.cross(dirs, e2)
    det = _dot(e1, p)
    ok = np.abs(det) > eps
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins - v0
    u = _dot(s, p) * inv
    q = np.cross(s, e1)
    v = _dot(dirs, q) * inv
    t = _dot(e2, q) * inv
    hit = ok & (u >= -edge_eps) & (v >= -edge_eps) & (u + v <= 1 + edge_eps)
    return np.where(hit, t, np.nan)


def ray_triangle_hits(origins, targets, tris, eps=1e-7, chunk=2048):
    """Does the open segment origin -> target (S, 3) hit any triangle (T, 3, 3)? (S,) bool.

    :func:`ray_triangle` of every segment against every triangle, ``chunk`` segments at a time,
    edges widened by ``eps``; hits at the segment's ends (t within 1e-6 of 0 or 1) do not count.
    A brute-force numpy occlusion test for small scenes and tests; Blender's BVHTree does the
    same for big ones.
    """
    o = np.asarray(origins, np.float64)
    dvec = np.asarray(targets, np.float64) - o
    tris = np.asarray(tris, np.float64)
    v0, v1, v2 = tris[None, :, 0], tris[None, :, 1], tris[None, :, 2]
    hit = np.zeros(len(o), bool)
    for s in range(0, len(o), chunk):
        t = ray_triangle(o[s:s + chunk, None, :], dvec[s:s + chunk, None, :], v0, v1, v2, eps=1e-14, edge_eps=eps)
        with np.errstate(invalid="ignore"):
            hit[s:s + chunk] = ((t > 1e-6) & (t < 1 - 1e-6)).any(axis=1)
    return hit
