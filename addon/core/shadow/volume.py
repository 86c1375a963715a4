"""Shadow volumes with stencil counting (seed 003 "Shadow volume"; Crow 1977; Heidmann 1991;
Everitt & Kilgard 2002 for z-fail; REFERENCE.md §4).

For each closed occluder: the silhouette edges (shared by a light-facing and a light-averted
triangle) are extruded away from the light; the light-facing triangles close the volume at
the near end (near cap) and, pushed out by the same extrusion with their winding reversed,
at the far end (far cap). Every triangle of the volume is wound outward.

Counting per pixel, along the camera ray from the near plane, with τ the distance of the
visible surface: a front face (ray entering, d·n < 0) counts +1, a back face -1.
  z-pass: stencil = Σ over faces with t < τ   (wrong when the camera is inside a volume)
  z-fail: stencil = -Σ over faces with t >= τ (needs the caps; right everywhere)
The pixel is in shadow where the stencil is not 0. A surface lying on a near cap is
treated as in front of it (t = τ counts as behind), so lit faces never shadow themselves.
"""
import numpy as np

from ..geometry import ray_triangle
from ..shadow import raster
from ..errors import InputError


def directed_edges(tris):
    """(3T, 2) directed edges (a, b) of triangles (T, 3), face i owning rows 3i..3i+2."""
    t = np.asarray(tris, np.int64)
    return np.stack([t, np.roll(t, -1, axis=1)], -1).reshape(-1, 2)


def edge_neighbours(tris, name="mesh"):
    """For each directed edge (a, b) of each face, the face holding (b, a).

    Raises InputError unless the mesh is closed and consistently wound (every edge shared by
    exactly two faces, traversed once each way) -- shadow volumes need a closed occluder.
    """
    e = directed_edges(tris)
    if len(e) == 0:
        raise InputError(f"'{name}' has no faces")
    n = int(e.max()) + 1
    key = e[:, 0] * n + e[:, 1]
    rev = e[:, 1] * n + e[:, 0]
    order = np.argsort(key)
    sk = key[order]
    if np.any(sk[1:] == sk[:-1]):
        raise InputError(f"'{name}' is not a closed, consistently wound mesh (an edge is used twice "
                         "in the same direction): shadow volumes need closed meshes")
    pos = np.searchsorted(sk, rev)
    found = (pos < len(sk)) & (sk[np.minimum(pos, len(sk) - 1)] == rev)
    if not found.all():
        raise InputError(f"'{name}' is not a closed mesh ({int((~found).sum())} open edges): "
                         "shadow volumes need closed meshes")
    return order[pos] // 3


def is_closed(tris):
    """True when :func:`edge_neighbours` accepts the mesh."""
    try:
        edge_neighbours(tris)
        return True
    except InputError:
        return False


def face_normals(verts, tris):
    """Unnormalised face normals (v1 - v0) × (v2 - v0) (outward for counter-clockwise winding)."""
    v = np.asarray(verts, np.float64)[np.asarray(tris)]
    return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])


def light_facing(verts, tris, light_h):
    """True for faces whose front side sees the light: n·(L_xyz - L_w c) > 0, c the face centroid."""
    v = np.asarray(verts, np.float64)[np.asarray(tris)]
    c = v.mean(1)
    light_h = np.asarray(light_h, np.float64)
    to_light = light_h[:3] - light_h[3] * c
    return np.einsum("ij,ij->i", face_normals(verts, tris), to_light) > 0


def silhouette(tris, neighbours, facing):
    """(S, 2) silhouette edges, each oriented as in its light-facing face."""
    e = directed_edges(tris)
    owner = np.repeat(np.arange(len(tris)), 3)
    sel = facing[owner] & ~facing[neighbours]
    return e[sel]


def extrude(points, light_h, distance):
    """Push points away from the light by ``distance``: along -L for a directional light, radially for a point."""
    p = np.asarray(points, np.float64)
    light_h = np.asarray(light_h, np.float64)
    if light_h[3] == 0:
        away = -light_h[:3] / np.linalg.norm(light_h[:3])
        return p + distance * away
    away = p - light_h[:3] / light_h[3]
    return p + distance * away / np.linalg.norm(away, axis=-1, keepdims=True)


def volume_triangles(verts, tris, light_h, distance, name="mesh"):
    """Outward-wound triangles (M, 3, 3) of the closed shadow volume of one closed occluder.

    Near cap: the light-facing triangles; far cap: the same extruded by ``distance``, reversed;
    sides: each silhouette edge (a, b) as the quad (b, a, a', b') split in two.
    """
    verts = np.asarray(verts, np.float64)
    tris = np.asarray(tris, np.int64)
    nb = edge_neighbours(tris, name)
    facing = light_facing(verts, tris, light_h)
    sil = silhouette(tris, nb, facing)
    near = verts[tris[facing]]
    far = extrude(near, light_h, distance)[:, ::-1]
    a, b = verts[sil[:, 0]], verts[sil[:, 1]]
    a2, b2 = extrude(a, light_h, distance), extrude(b, light_h, distance)
    side1 = np.stack([b, a, a2], 1)
    side2 = np.stack([b, a2, b2], 1)
    return np.concatenate([near, far, side1, side2], 0), len(sil)


def stencil(volume, origins, dirs, tau, world_to_view, proj, width, height, near, mask=None, mode="zfail"):
    """Per-pixel stencil count (H, W) of volume triangles (M, 3, 3) for camera rays.

    ``origins``/``dirs``: (H, W, 3) rays through pixel centres starting on the near plane
    (core.camera.pixel_rays); ``tau``: (H, W) distance to the visible surface along each ray;
    ``mask``: pixels to evaluate (others stay 0); ``mode``: "zpass" or "zfail".
    """
    if mode not in ("zpass", "zfail"):
        raise InputError(f"unknown stencil mode '{mode}' (zpass, zfail)")
    count = np.zeros(height * width, np.int64)
    volume = np.asarray(volume, np.float64).reshape(-1, 3, 3)
    if len(volume) == 0:
        return count.reshape(height, width)
    o = origins.reshape(-1, 3)
    d = dirs.reshape(-1, 3)
    tau = np.asarray(tau, np.float64).reshape(-1)
    keep = np.ones(height * width, bool) if mask is None else np.asarray(mask, bool).reshape(-1)
    normals = np.cross(volume[:, 1] - volume[:, 0], volume[:, 2] - volume[:, 0])
    for tri, px, py in raster.span_candidates(volume, world_to_view, proj, width, height, near):
        pix = py * width + px
        sel = keep[pix]
        tri, pix = tri[sel], pix[sel]
        if len(pix) == 0:
            continue
        v = volume[tri]
        t = ray_triangle(o[pix], d[pix], v[:, 0], v[:, 1], v[:, 2])
        hit = np.isfinite(t) & (t > 0)
        sign = np.where(np.einsum("ij,ij->i", d[pix], normals[tri]) < 0, 1, -1)
        if mode == "zpass":
            use = hit & (t < tau[pix])
            np.add.at(count, pix[use], sign[use])
        else:
            use = hit & (t >= tau[pix])
            np.add.at(count, pix[use], -sign[use])
    return count.reshape(height, width)


def surface_distance(positions, origins, dirs, eps=1e-4):
    """τ: distance along each ray to its visible surface point, pulled toward the camera by ``eps`` relative."""
    t = np.einsum("...i,...i->...", np.asarray(positions, np.float64) - origins, dirs)
    return t * (1.0 - eps) - 1e-6
