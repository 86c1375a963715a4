"""Planar projected shadows (seed 003 "Ombre planari"; REFERENCE.md §4).

The occluders' triangles are flattened onto the receiver plane by the projection matrix
S = (P·L) I - L Pᵀ (P = plane (a, b, c, d) with a x + b y + c z + d = 0, L = light in
homogeneous form: point (x, y, z, 1), directional (toward the light, 0)), lifted by a small
offset along the plane normal against z-fighting, then drawn from the camera with the depth
test. Right on the plane, wrong on any other receiver (the shadow hides under raised steps).
"""
import numpy as np

from ..shadow import raster
from ..errors import InputError


def plane_from_point_normal(point, normal):
    """P = (n, -n·p) with |n| = 1: the plane through ``point`` with normal ``normal``."""
    n = np.asarray(normal, np.float64)
    length = np.linalg.norm(n)
    if length == 0:
        raise InputError("the receiver plane has no normal (degenerate face)")
    n = n / length
    return np.append(n, -n @ np.asarray(point, np.float64))


#: A receiver is planar when no vertex lies farther than this fraction of its extent off the plane.
PLANAR_TOLERANCE = 1e-4


def off_plane(verts, plane):
    """(max |P·(v, 1)| over the vertices, the vertices' bounding-box diagonal): how far a receiver leaves the
    plane its shadows are drawn on, and its size."""
    v = np.asarray(verts, np.float64).reshape(-1, 3)
    distance = float(np.abs(v @ plane[:3] + plane[3]).max()) if len(v) else 0.0
    extent = float(np.linalg.norm(v.max(0) - v.min(0))) if len(v) else 0.0
    return distance, extent


def oriented_toward_light(plane, light_h):
    """The same plane with its normal flipped, if needed, so that P·L > 0 (light on the + side)."""
    plane = np.asarray(plane, np.float64)
    dot = plane @ np.asarray(light_h, np.float64)
    if abs(dot) < 1e-12:
        raise InputError("the light lies in the receiver plane (or is parallel to it): no planar shadow")
    return plane if dot > 0 else -plane


def projection_matrix(plane, light_h):
    """S = (P·L) I - L Pᵀ (Blinn 1988): maps homogeneous X to its shadow on plane P from light L."""
    p = np.asarray(plane, np.float64)
    l = np.asarray(light_h, np.float64)
    return (p @ l) * np.eye(4) - np.outer(l, p)


def project(points, s):
    """Apply S to (..., 3) points: X' = S [X, 1], returned divided by its w' (> 0 for clipped occluders)."""
    p = np.asarray(points, np.float64)
    h = np.concatenate([p, np.ones(p.shape[:-1] + (1,))], -1) @ s.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return h[..., :3] / h[..., 3:4]


def shadow_triangles(tris, plane, light_h, offset):
    """Occluder triangles (T, 3, 3) -> their shadows on the plane, lifted by ``offset`` along the normal.

    Only the parts of the occluders between the plane and the light cast a shadow: the triangles
    are clipped at the plane (P·X >= 0; parts beyond it would cast "anti-shadows") and, for a point
    light, at the light's own level parallel to the plane (w' = P·L - P·X > 0; parts above the
    light project to the far side). Vertices on the plane (an object standing on it) stay.
    """
    plane = oriented_toward_light(plane, light_h)
    light_h = np.asarray(light_h, np.float64)
    tris = raster.clip_triangles(tris, plane)
    pl = plane @ light_h
    if light_h[3] != 0:
        tris = raster.clip_triangles(tris, np.append(np.zeros(3), pl * (1 - 1e-6)) - light_h[3] * plane)
    flat = project(tris, projection_matrix(plane, light_h))
    return flat + offset * plane[:3]


def planar_shadow_mask(tris, plane, light_h, world_to_view, proj, width, height, scene_depth, offset=1e-3):
    """True where a projected shadow triangle is drawn (passes the depth test) on the camera's grid."""
    shadows = shadow_triangles(tris, plane, light_h, offset)
    return raster.rasterize_depth_tested(shadows, world_to_view, proj, width, height, scene_depth)
