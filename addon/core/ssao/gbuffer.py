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
    return project(points[..., 0], points[..., 1], points[..., 2], proj, width, height)


def _row(row, px, py, pz):
    """row · (px, py, pz, 1) in float32, summed left to right; zero terms skipped and ±1 not multiplied
    (both exact, so the result is the full sum's bit for bit)."""
    acc = None
    for c, v in zip(row[:3], (px, py, pz)):
        if c == 0:
            continue
        term = v if c == 1 else (-v if c == -1 else c * v)
        acc = term if acc is None else acc + term
    if acc is None:
        return np.full(np.shape(px), row[3], np.float32)
    if row[3] != 0:
        return acc + row[3]
    return acc.copy() if any(acc is v for v in (px, py, pz)) else acc


def project(px, py, pz, proj, width, height):
    """:func:`view_to_pixels` on separate coordinate arrays (the methods' layout): returns x, y, w."""
    p = proj.astype(np.float32)
    w = _row(p[3], px, py, pz)
    safe = np.where(w > 1e-6, w, np.float32(1.0))
    ndc_x = _row(p[0], px, py, pz)
    ndc_x /= safe
    ndc_y = _row(p[1], px, py, pz)
    ndc_y /= safe
    x, y = ndc_to_pixels(ndc_x, ndc_y, width, height)
    return x, y, w


def pixels_per_metre(gb, depth):
    """Screen-space scale at view depth z: f/z pixels per metre (perspective), f (orthographic).

    f = (P00 W/2 + P11 H/2)/2, the mean focal length in pixels, in float32 like the depth (the dtype
    NumPy 1's value-based casting gave f/z; NEP 50 would make it float64).
    """
    f = np.float32(0.25 * (gb.proj[0, 0] * gb.width + gb.proj[1, 1] * gb.height))
    return f / depth if gb.perspective else np.full_like(depth, f)


def view_vectors(gb, pos):
    """Unit vectors from the surface toward the camera: -p/|p| (perspective) or +Z (orthographic)."""
    if gb.perspective:
        return -pos / np.maximum(np.linalg.norm(pos, axis=-1, keepdims=True), 1e-12)
    return np.broadcast_to(np.array([0, 0, 1], np.float32), pos.shape)


def _cell(x, n):
    """(x0, f) of sub-pixel coordinates ``x`` along an axis of ``n`` pixels: x clamped to [0, n - 1],
    x0 = min(floor(x), n - 2) (0 when n = 1), f = x - x0 in float32."""
    f = np.maximum(x, np.float32(0.0), out=np.empty(x.shape, np.result_type(x, np.float32)))
    np.minimum(f, np.float32(n - 1), out=f)
    x0 = np.floor(f)
    np.minimum(x0, np.float32(n - 2 if n > 1 else 0), out=x0)
    f -= x0
    return x0, f.astype(np.float32, copy=False)


def lookup_at(gb, x, y):
    """Bilinear interpolation of :attr:`GBuffer.lookup` (1/z or z) at sub-pixel (x, y); returns (value, on_screen).

    Positions are clamped to the pixel centres, so off-screen ones read the edge; on_screen =
    -1/2 <= x <= W - 1/2 and -1/2 <= y <= H - 1/2. v = (q00 (1-fx) + q01 fx)(1-fy) + (q10 (1-fx) + q11 fx) fy.
    """
    h, w = gb.depth.shape
    x, y = np.asanyarray(x), np.asanyarray(y)
    on = np.greater_equal(x, -0.5, out=np.empty(x.shape, bool))
    on &= x <= w - 0.5
    on &= y >= -0.5
    on &= y <= h - 0.5
    x0, fx = _cell(x, w)
    y0, fy = _cell(y, h)
    index = y0.astype(np.int32)
    index *= w
    index += x0.astype(np.int32)
    q = gb.lookup.ravel()
    right, down = (1 if w > 1 else 0), (w if h > 1 else 0)       # x1 = min(x0 + 1, W - 1), y1 likewise
    gx = 1 - fx
    top = np.take(q, index, mode="clip")
    top *= gx
    index += right
    t = np.take(q, index, mode="clip")
    t *= fx
    top += t
    index += down - right
    bot = np.take(q, index, mode="clip")
    bot *= gx
    index += right
    np.take(q, index, out=t, mode="clip")
    t *= fx
    bot += t
    top *= 1 - fy
    bot *= fy
    top += bot
    return top, on


def depth_from_lookup(gb, v):
    """Depth from an interpolated :attr:`GBuffer.lookup` value: 1/max(v, 1/SKY_DEPTH) (perspective) or v."""
    if gb.perspective:
        return 1.0 / np.maximum(v, np.float32(1.0 / SKY_DEPTH))
    return v


def depth_at(gb, x, y):
    """Depth buffer at sub-pixel positions; returns (depth, on_screen).

    Bilinear in 1/z for a perspective camera (1/z is affine in screen space on a
    plane, so planes are reconstructed exactly), in z for an orthographic one
    (:func:`lookup_at`). Off-screen positions return SKY_DEPTH and on_screen False.
    """
    v, on = lookup_at(gb, np.asanyarray(x), np.asanyarray(y))
    return np.where(on, depth_from_lookup(gb, v), np.float32(SKY_DEPTH)), on


def position_at(gb, x, y):
    """View-space surface position at sub-pixel (x, y): the pixel's view ray scaled to :func:`depth_at`.

    Perspective: X = z (x_ndc + P02)/P00, Y = z (y_ndc + P12)/P11, Z = -z;
    orthographic: X = (x_ndc - P03)/P00, Y = (y_ndc - P13)/P11. Points along a
    screen line through a pixel stay in the plane through the eye containing
    that pixel's ray (GTAO's slice). Returns (positions, valid) where valid =
    on screen and not sky; off screen the position is the ray at the edge pixel's depth.
    """
    x, y = np.asanyarray(x), np.asanyarray(y)
    px, py, pz, valid = positions_at(gb, x, y)
    return np.stack([px, py, pz], -1).astype(np.float32), valid


def positions_at(gb, x, y):
    """:func:`position_at` as separate coordinate arrays: returns (X, Y, Z, valid)."""
    v, on = lookup_at(gb, x, y)
    d = depth_from_lookup(gb, v)
    on &= d < 0.5 * SKY_DEPTH
    p = gb.proj.astype(np.float32)     # P's scalars in float32 with the coordinates (NumPy 1 and NEP 50 alike)
    ndc_x, ndc_y = pixels_to_ndc(x, y, gb.width, gb.height)
    if gb.perspective:
        ndc_x += p[0, 2]
        ndc_x /= p[0, 0]
        ndc_x *= d
        ndc_y += p[1, 2]
        ndc_y /= p[1, 1]
        ndc_y *= d
    else:
        ndc_x -= p[0, 3]
        ndc_x /= p[0, 0]
        ndc_y -= p[1, 3]
        ndc_y /= p[1, 1]
    return ndc_x, ndc_y, np.negative(d), on


DEFAULT_RADIUS_FRACTION = 0.1
"""The default SSAO radius is this fraction of the frame's width in metres at the median depth of the geometry
pixels (:func:`default_radius`)."""


def default_radius(gb, fraction=DEFAULT_RADIUS_FRACTION):
    """The radius (metres) used when none is given: ``fraction`` × the frame's width at the median view depth
    z of the geometry pixels, W / pixels_per_metre(z) (perspective: about 2 z / P00; orthographic: the view
    width). It scales with the scene (a scene and camera scaled by s get s × the radius) and is the same
    share of the frame, ``fraction`` × W pixels, at any distance. None when no pixel is geometry."""
    depth = gb.depth[gb.mask]
    if not depth.size:
        return None
    z = np.float32(np.median(depth))
    return float(fraction * gb.width / float(pixels_per_metre(gb, np.asarray([z], np.float32))[0]))
