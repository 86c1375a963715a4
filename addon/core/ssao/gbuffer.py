"""The G-buffer a screen-space method sees, and lookups into it.

Conventions: view space is Blender's camera space (camera looks down -Z, +Y
up); the depth buffer holds planar view depth z = -p_z > 0 (Cycles' "Depth"
pass); pixel (0, 0) is the centre of the TOP-LEFT pixel (core.camera). Sky
pixels are outside ``mask``; their depth is :data:`core.camera.SKY_DEPTH`; their k_A is
written as 1 (open) and they never enter a metric.
"""
from dataclasses import dataclass

import numpy as np

from ..camera import SKY_DEPTH, ndc_to_pixels, pixels_to_ndc


@dataclass
class GBuffer:
    """What a screen-space method sees: per-pixel view-space position and normal, depth, mask, camera.

    ``position`` (H, W, 3) and ``normal`` (H, W, 3) are view space (float32),
    ``depth`` (H, W) planar view depth (SKY_DEPTH on sky), ``mask`` (H, W) bool
    geometry pixels, ``proj`` Blender's 4x4 projection (calc_matrix_camera).
    """
    position: np.ndarray
    normal: np.ndarray
    depth: np.ndarray
    mask: np.ndarray
    proj: np.ndarray

    @property
    def height(self):
        return self.depth.shape[0]

    @property
    def width(self):
        return self.depth.shape[1]

    @property
    def perspective(self):
        return is_perspective(self.proj)

    @property
    def lookup(self):
        """What :func:`depth_at` interpolates: 1/z (perspective) or z (orthographic), cached, float32."""
        cached = getattr(self, "_lookup", None)
        if cached is None or cached.shape != self.depth.shape:
            d = self.depth.astype(np.float32)
            cached = (np.float32(1.0) / d) if self.perspective else d
            self._lookup = cached
        return cached


def is_perspective(proj):
    """A perspective projection has w_clip = -z_view (row 3 = (0, 0, -1, 0)); orthographic has w = 1."""
    return abs(proj[3, 2]) > 0.5


def gbuffer_from_passes(position_world, normal_world, mask, world_to_view, proj):
    """G-buffer from Blender's world-space Position and Normal passes and the camera matrices.

    View position p_v = M p_w (M = world_to_view); normal n_v = R n_w with R the
    rotation part of M (camera matrices carry no shear), flipped toward the
    camera where it faces away (surfaces are two-sided, as for Cycles' AO).
    Depth z = -p_v.z.
    """
    mask = np.asarray(mask, bool) & np.isfinite(position_world).all(-1) & np.isfinite(normal_world).all(-1)
    m = np.asarray(world_to_view, np.float64)
    pos = (np.asarray(position_world, np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0, keepdims=True)
    nrm = (np.asarray(normal_world, np.float64) @ rot.T).astype(np.float32)
    length = np.linalg.norm(nrm, axis=-1, keepdims=True)
    mask &= length[..., 0] > 0.5
    nrm = np.where(length > 0, nrm / np.maximum(length, 1e-12), 0.0).astype(np.float32)
    view = -pos if is_perspective(proj) else np.array([0, 0, 1], np.float32)
    nrm = np.where((np.sum(nrm * view, -1) < 0)[..., None], -nrm, nrm)     # face the camera (two-sided)
    depth = np.where(mask, -pos[..., 2], SKY_DEPTH).astype(np.float32)
    mask &= depth > 0
    pos[~mask] = 0.0
    nrm[~mask] = 0.0
    depth[~mask] = SKY_DEPTH
    return GBuffer(pos, nrm, depth, mask, np.asarray(proj, np.float64))


# --------------------------------------------------------------------------- camera helpers

def view_to_pixels(points, proj, width, height):
    """(..., 3) view points -> pixel x, y (row 0 at top) and clip w (> 0 in front of a perspective camera).

    x = (ndc_x + 1) W/2 - 1/2, y = (1 - ndc_y) H/2 - 1/2 with ndc = clip.xyz / clip.w.
    """
    p = proj.astype(np.float32)
    px, py, pz = points[..., 0], points[..., 1], points[..., 2]
    w = p[3, 0] * px + p[3, 1] * py + p[3, 2] * pz + p[3, 3]
    safe = np.where(w > 1e-6, w, np.float32(1.0))
    ndc_x = (p[0, 0] * px + p[0, 1] * py + p[0, 2] * pz + p[0, 3]) / safe
    ndc_y = (p[1, 0] * px + p[1, 1] * py + p[1, 2] * pz + p[1, 3]) / safe
    x, y = ndc_to_pixels(ndc_x, ndc_y, width, height)
    return x, y, w


def pixels_per_metre(gb, depth):
    """Screen-space scale at view depth z: f/z pixels per metre (perspective), f (orthographic).

    f = (P00 W/2 + P11 H/2)/2, the mean focal length in pixels.
    """
    f = 0.25 * (gb.proj[0, 0] * gb.width + gb.proj[1, 1] * gb.height)
    return f / depth if gb.perspective else np.full_like(depth, f)


def view_vectors(gb, pos):
    """Unit vectors from the surface toward the camera: -p/|p| (perspective) or +Z (orthographic)."""
    if gb.perspective:
        return -pos / np.maximum(np.linalg.norm(pos, axis=-1, keepdims=True), 1e-12)
    return np.broadcast_to(np.array([0, 0, 1], np.float32), pos.shape)


def depth_at(gb, x, y):
    """Depth buffer at sub-pixel positions; returns (depth, on_screen).

    Bilinear in 1/z for a perspective camera (1/z is affine in screen space on a
    plane, so planes are reconstructed exactly), in z for an orthographic one.
    Off-screen positions return SKY_DEPTH and on_screen False.
    """
    h, w = gb.depth.shape
    on = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    xc = np.clip(x, 0.0, w - 1.0)
    yc = np.clip(y, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(xc).astype(np.int32), w - 2 if w > 1 else 0)
    y0 = np.minimum(np.floor(yc).astype(np.int32), h - 2 if h > 1 else 0)
    fx = (xc - x0).astype(np.float32)
    fy = (yc - y0).astype(np.float32)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    q = gb.lookup
    top = q[y0, x0] * (1 - fx) + q[y0, x1] * fx
    bot = q[y1, x0] * (1 - fx) + q[y1, x1] * fx
    v = top * (1 - fy) + bot * fy
    if gb.perspective:
        d = 1.0 / np.maximum(v, np.float32(1.0 / SKY_DEPTH))
    else:
        d = v
    return np.where(on, d, np.float32(SKY_DEPTH)), on


def position_at(gb, x, y):
    """View-space surface position at sub-pixel (x, y): the pixel's view ray scaled to :func:`depth_at`.

    Perspective: X = z (x_ndc + P02)/P00, Y = z (y_ndc + P12)/P11, Z = -z;
    orthographic: X = (x_ndc - P03)/P00, Y = (y_ndc - P13)/P11. Points along a
    screen line through a pixel stay in the plane through the eye containing
    that pixel's ray (GTAO's slice). Returns (positions, valid) where valid =
    on screen and not sky.
    """
    d, on = depth_at(gb, x, y)
    p = gb.proj
    ndc_x, ndc_y = pixels_to_ndc(x, y, gb.width, gb.height)
    if gb.perspective:
        px = d * ((ndc_x + p[0, 2]) / p[0, 0])
        py = d * ((ndc_y + p[1, 2]) / p[1, 1])
    else:
        px = (ndc_x - p[0, 3]) / p[0, 0]
        py = (ndc_y - p[1, 3]) / p[1, 1]
    pos = np.stack([px, py, -d], -1).astype(np.float32)
    return pos, on & (d < 0.5 * SKY_DEPTH)
