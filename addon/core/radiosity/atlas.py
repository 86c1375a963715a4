"""Outputs of a solve: per-vertex values and the light-map atlas (one square cell per patch)."""
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .patches import bilinear, polygon_area_normal, vertex_keys


def texel_points(patches, cell):
    """The surface points a ``cell``×``cell`` atlas cell bakes (texel centres, see :func:`atlas_uvs`):
    (N, cell², 3) and a mask (N, cell²) of the texels a comparison with a Cycles bake reads (a triangle's: strictly
    inside its half, which every Blender version bakes at the texel centre), row-major from the cell's top row.
    Quads: the bilinear map of the cell; triangles: u, v barycentric over corners (0,0), (1,0), (1,1)."""
    yy, xx = np.mgrid[0:cell, 0:cell]
    u, v = ((xx + 0.5) / cell).ravel(), (1 - (yy + 0.5) / cell).ravel()
    n = len(patches)
    c = patches.corners
    q, _ = bilinear(np.repeat(c, len(u), axis=0), np.tile(u, n), np.tile(v, n))
    q = q.reshape(n, len(u), 3)
    tri = ((1 - u)[None, :, None] * c[:, None, 0] + (u - v)[None, :, None] * c[:, None, 1]
           + v[None, :, None] * c[:, None, 2])
    pts = np.where(patches.is_tri[:, None, None], tri, q)
    mask = np.where(patches.is_tri[:, None], (v < u)[None, :], True)
    return pts, mask


def _bilinear_points(c, s, t):
    """The bilinear maps of :func:`core.radiosity.patches.bilinear` of every patch (corners c (N, 4, 3)) at the
    same parameters s, t (S,): (N, S, 3), without repeating the corners."""
    w = np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], -1)          # (S, 4)
    return np.einsum("sk,nkc->nsc", w, c)


def texel_elements(patches, cell):
    """Each patch cut along its atlas cell's texel grid (the parametrisation of :func:`texel_points`): polygons
    (N, cell², 4, 3) wound as the patch (a triangle repeats its last corner), collocation points (N, cell², 3),
    areas (N, cell²) and a mask (N, cell²) of the elements that exist. Quads: the bilinear images of the cell²
    texel squares, points = the texel centres. Triangles (u, v barycentric, the half v <= u): the squares below the
    diagonal (points = texel centres, where Cycles bakes) and the half squares on it (points = their centroids;
    texels a comparison does not read, see :func:`_cell_masks`). The elements tile the patch exactly."""
    yy, xx = (a.ravel() for a in np.mgrid[0:cell, 0:cell])
    u0, u1 = xx / cell, (xx + 1) / cell
    v0, v1 = 1 - (yy + 1) / cell, 1 - yy / cell
    us = np.stack([u0, u1, u1, u0], -1)                      # (m, 4): the square's corners, counter-clockwise
    vs = np.stack([v0, v0, v1, v1], -1)
    diag = xx + yy == cell - 1           # squares the diagonal v = u cuts: keep (u0,v0), (u1,v0), (u1,v1)
    tri_us = np.where(diag[:, None], np.stack([u0, u1, u1, u1], -1), us)
    tri_vs = np.where(diag[:, None], np.stack([v0, v0, v1, v1], -1), vs)
    pu = np.where(diag, (u0 + 2 * u1) / 3, (u0 + u1) / 2)
    pv = np.where(diag, (2 * v0 + v1) / 3, (v0 + v1) / 2)
    n, m = len(patches), len(xx)
    c = patches.corners
    quad = _bilinear_points(c, us.ravel(), vs.ravel())
    qpt = _bilinear_points(c, (u0 + u1) / 2, (v0 + v1) / 2)
    w0, w1, w2 = 1 - tri_us, tri_us - tri_vs, tri_vs                      # barycentric weights (m, 4)
    tri = (w0[None, ..., None] * c[:, None, None, 0] + w1[None, ..., None] * c[:, None, None, 1]
           + w2[None, ..., None] * c[:, None, None, 2])
    tpt = ((1 - pu)[None, :, None] * c[:, None, 0] + (pu - pv)[None, :, None] * c[:, None, 1]
           + pv[None, :, None] * c[:, None, 2])
    is_tri = patches.is_tri
    polys = np.where(is_tri[:, None, None, None], tri, quad.reshape(n, m, 4, 3))
    pts = np.where(is_tri[:, None, None], tpt, qpt.reshape(n, m, 3))
    mask = np.where(is_tri[:, None], (xx + yy >= cell - 1)[None, :], True)
    area, _ = polygon_area_normal(polys)
    return polys, pts, np.where(mask, area, 0.0), mask




def vertex_average(patches, values):
    """Area-weighted average of patch ``values`` at each welded corner position, per object.

    Returns (corner values (N, 4, C), unique positions (V, 3), corner -> unique index (N, 4)).
    """
    values = np.asarray(values, np.float64)
    keys = np.concatenate([vertex_keys(patches.corners.reshape(-1, 3)),
                           np.repeat(patches.owner, 4)[:, None]], axis=1)
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    w = np.repeat(patches.area, 4)
    acc = np.zeros((len(uniq), values.shape[1]))
    np.add.at(acc, inv, values.repeat(4, axis=0) * w[:, None])
    den = np.zeros(len(uniq))
    np.add.at(den, inv, w)
    vv = acc / den[:, None]
    pos = np.zeros((len(uniq), 3))
    pos[inv] = patches.corners.reshape(-1, 3)
    return vv[inv].reshape(len(patches), 4, -1), pos, inv.reshape(len(patches), 4)


@dataclass
class Atlas:
    """One square cell of ``cell`` texels per patch, ``gutter`` texels apart, row-major from the top-left."""
    count: int
    cell: int
    gutter: int
    columns: int
    rows: int

    @property
    def size(self):
        """(width, height) in texels."""
        pitch = self.cell + self.gutter
        return self.columns * pitch, self.rows * pitch

    def origin(self, k):
        """Top-left texel (x, y) of cell k (row 0 = top)."""
        pitch = self.cell + self.gutter
        k = np.asarray(k)
        return (k % self.columns) * pitch + self.gutter // 2, (k // self.columns) * pitch + self.gutter // 2


def make_atlas(count, cell=4, gutter=2):
    """A near-square atlas for ``count`` patches."""
    if count <= 0:
        raise InputError("an atlas needs at least one patch")
    cols = int(np.ceil(np.sqrt(count)))
    return Atlas(int(count), int(cell), int(gutter), cols, int(np.ceil(count / cols)))


def atlas_uvs(atlas, is_tri):
    """UV (N, 4, 2) of each patch's corners in its cell (v up, Blender's UV convention).

    Corner order 0..3 maps to the cell's bottom-left, bottom-right, top-right,
    top-left; a triangle uses the first three (its lower-right half).
    """
    w, h = atlas.size
    x0, y0 = atlas.origin(np.arange(atlas.count))
    x1, y1 = x0 + atlas.cell, y0 + atlas.cell
    u0, u1 = x0 / w, x1 / w
    v_top, v_bot = 1 - y0 / h, 1 - y1 / h
    uv = np.stack([np.stack([u0, v_bot], -1), np.stack([u1, v_bot], -1),
                   np.stack([u1, v_top], -1), np.stack([u0, v_top], -1)], axis=1)
    uv[is_tri, 3] = uv[is_tri, 2]
    return uv


def _cell_masks(atlas, diagonal=True):
    """Texel masks inside a cell (cell, cell): whole cell for quads, lower-right half for triangles, with the
    texels centred on the diagonal when ``diagonal`` (painting) or without them (reading a bake: Blender 4.5-5.2
    leave a texel whose centre lies on a triangle's edge unbaked, 0 with alpha 0; 5.3 bakes every texel a
    triangle overlaps, that one too, but a centre on the edge is a tie for the light-map pipeline's coverage,
    so it is read in no version); texel centres only, so a bake's edge bleeding does not count."""
    c = atlas.cell
    yy, xx = np.mgrid[0:c, 0:c]
    u, v = (xx + 0.5) / c, 1 - (yy + 0.5) / c
    return np.ones((c, c), bool), (v <= u) if diagonal else (v < u)


def paint_atlas(atlas, values, is_tri):
    """Image (H, W, C) with every patch's cell filled with its value (N, C) or its texels' values (N, cell², C),
    row-major from the cell's top row as :func:`texel_points` orders them; A channel = coverage. Row 0 = top."""
    values = np.asarray(values, np.float64)
    w, h = atlas.size
    img = np.zeros((h, w, values.shape[-1] + 1), np.float32)
    quad_m, tri_m = _cell_masks(atlas)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    for k in range(atlas.count):
        m = tri_m if is_tri[k] else quad_m
        block = img[y0[k]:y0[k] + c, x0[k]:x0[k] + c]
        block[m, :-1] = values[k] if values.ndim == 2 else values[k].reshape(c, c, -1)[m]
        block[m, -1] = 1.0
    return img


def atlas_means(atlas, image, is_tri):
    """Per-patch mean of an atlas image (H, W, C), row 0 = top, over the texels a bake covers (a triangle's
    strictly inside its half): the inverse of :func:`paint_atlas`."""
    image = np.asarray(image, np.float64)
    quad_m, tri_m = _cell_masks(atlas, diagonal=False)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    out = np.empty((atlas.count, image.shape[2]))
    for k in range(atlas.count):
        m = tri_m if is_tri[k] else quad_m
        out[k] = image[y0[k]:y0[k] + c, x0[k]:x0[k] + c][m].mean(axis=0)
    return out


def atlas_texels(atlas, image, is_tri):
    """Every patch's texels of an atlas image (H, W, C), row 0 = top: (N, cell², C), row-major from the cell's
    top row as :func:`texel_points` orders them, NaN outside a triangle's half."""
    image = np.asarray(image, np.float64)
    quad_m, tri_m = _cell_masks(atlas, diagonal=False)
    x0, y0 = atlas.origin(np.arange(atlas.count))
    c = atlas.cell
    out = np.empty((atlas.count, c * c, image.shape[2]))
    for k in range(atlas.count):
        out[k] = image[y0[k]:y0[k] + c, x0[k]:x0[k] + c].reshape(c * c, -1)
        out[k][~(tri_m if is_tri[k] else quad_m).ravel()] = np.nan
    return out
