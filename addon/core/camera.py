"""Pinhole and orthographic cameras as matrices: world <-> view <-> pixels.

Conventions: view space is Blender's camera space (looking down -Z, +Y up);
``proj`` is Blender's ``calc_matrix_camera`` (OpenGL clip space); pixel (0, 0)
is the centre of the TOP-LEFT pixel, x to the right, y down, as the images the
project writes are laid out.
"""
import numpy as np

#: Depth written for sky pixels (as Cycles' Depth pass does); the labs take "no surface" as depth >= half this.
SKY_DEPTH = 1.0e10


def transform(m, points):
    """Apply a 4x4 affine matrix to (..., 3) points."""
    p = np.asarray(points, dtype=np.float64)
    return p @ m[:3, :3].T + m[:3, 3]


def ndc_to_pixels(ndc_x, ndc_y, width, height):
    """Normalised device coordinates -> pixel x, y: x = (ndc_x + 1) W/2 - 1/2, y = (1 - ndc_y) H/2 - 1/2.

    The one place of the pixel convention above (row 0 at the top, pixel centres at integers).
    """
    return (ndc_x + 1.0) * (0.5 * width) - 0.5, (1.0 - ndc_y) * (0.5 * height) - 0.5


def pixels_to_ndc(x, y, width, height):
    """Pixel x, y -> normalised device coordinates, the inverse of :func:`ndc_to_pixels`."""
    return (x + 0.5) * (2.0 / width) - 1.0, 1.0 - (y + 0.5) * (2.0 / height)


def world_to_pixels(points, world_to_view, proj, width, height):
    """(..., 3) world points -> (x, y) pixel coordinates (row 0 at the top) and view depth (> 0 in front)."""
    v = transform(world_to_view, points)
    h = np.concatenate([v, np.ones(v.shape[:-1] + (1,))], axis=-1) @ proj.T
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = h[..., :3] / h[..., 3:4]
    x, y = ndc_to_pixels(ndc[..., 0], ndc[..., 1], width, height)
    return x, y, -v[..., 2]


def pixel_rays(world_to_view, proj, width, height):
    """Per pixel (H, W, 3) ray origins and unit directions in world space through pixel centres."""
    view_to_world = np.linalg.inv(world_to_view)
    inv_proj = np.linalg.inv(proj)
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    ndc_x, ndc_y = pixels_to_ndc(xs, ys, width, height)
    near = np.stack([ndc_x, ndc_y, -np.ones_like(xs), np.ones_like(xs)], -1) @ inv_proj.T
    far = np.stack([ndc_x, ndc_y, np.ones_like(xs), np.ones_like(xs)], -1) @ inv_proj.T
    near = near[..., :3] / near[..., 3:4]
    far = far[..., :3] / far[..., 3:4]
    o = transform(view_to_world, near)
    d = transform(view_to_world, far) - o
    return o, d / np.linalg.norm(d, axis=-1, keepdims=True)
