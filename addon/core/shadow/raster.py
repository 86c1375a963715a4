"""Screen-space helpers shared by the numpy shadow methods: clipping triangles at a plane,
triangle bounding boxes on the pixel grid, candidate (triangle, pixel) pairs in bounded chunks,
a depth-tested triangle rasteriser (ray-triangle hits are core.geometry.ray_triangle) and a
depth-image rasteriser (the shadow map's depth, as Cycles' Depth pass gives it).

Pixel conventions are those of :mod:`core.camera`: pixel (0, 0) is the centre of the
top-left pixel, x right, y down; ``proj`` is OpenGL clip space (Blender's calc_matrix_camera).
"""
import numpy as np

from ..camera import SKY_DEPTH, ndc_to_pixels

#: Upper bound on (triangle, pixel) pairs examined at once (memory ~ 100 bytes each).
CHUNK = 2_000_000
#: Pixel centres this close to a triangle's edge (pixels) count as inside: no crack along shared edges.
EDGE_EPS = 1e-6


def to_clip(points, world_to_view, proj):
    """(..., 3) world points -> (..., 4) clip coordinates ``proj @ world_to_view @ [p, 1]``."""
    m = proj @ world_to_view
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([p, np.ones(p.shape[:-1] + (1,))], -1) @ m.T


def clip_to_pixels(clip, width, height):
    """Clip coordinates -> pixel x, y (row 0 at the top) and NDC z; valid where w > 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = clip[..., :3] / clip[..., 3:4]
    x, y = ndc_to_pixels(ndc[..., 0], ndc[..., 1], width, height)
    return x, y, ndc[..., 2]


def view_depth_to_ndc_z(depth, proj):
    """Planar view depth d (> 0 in front, Cycles' Depth pass) -> NDC z of the same camera."""
    z = -np.asarray(depth, dtype=np.float64)
    return (proj[2, 2] * z + proj[2, 3]) / (proj[3, 2] * z + proj[3, 3])


def clip_triangles(tris, plane):
    """The parts of triangles (T, 3, 3) on the side P·[x, 1] >= 0 of ``plane`` P = (a, b, c, d).

    Sutherland-Hodgman against one plane: a triangle with one vertex inside keeps the triangle
    (a, a + t_b (b - a), a + t_c (c - a)), t = d_a / (d_a - d_out); one with two inside keeps the
    quad they cut off, as two triangles. Winding is kept; wholly outside triangles vanish.
    """
    tris = np.asarray(tris, np.float64).reshape(-1, 3, 3)
    plane = np.asarray(plane, np.float64)
    d = tris @ plane[:3] + plane[3]
    inside = d >= 0
    n_in = inside.sum(1)
    parts = [tris[n_in == 3]]
    for count in (1, 2):
        sel = n_in == count
        if not sel.any():
            continue
        t, dd, ins = tris[sel], d[sel], inside[sel]
        # roll each triangle so that its odd vertex (the lone inside or lone outside one) comes first
        first = np.argmax(ins if count == 1 else ~ins, axis=1)
        order = (first[:, None] + np.arange(3)) % 3
        t = np.take_along_axis(t, order[..., None], 1)
        dd = np.take_along_axis(dd, order, 1)
        v0, v1, v2 = t[:, 0], t[:, 1], t[:, 2]
        p01 = v0 + (dd[:, 0] / (dd[:, 0] - dd[:, 1]))[:, None] * (v1 - v0)
        p02 = v0 + (dd[:, 0] / (dd[:, 0] - dd[:, 2]))[:, None] * (v2 - v0)
        if count == 1:
            parts.append(np.stack([v0, p01, p02], 1))
        else:
            parts += [np.stack([v1, v2, p02], 1), np.stack([v1, p02, p01], 1)]
    return np.concatenate(parts, 0)


def near_plane(world_to_view, near):
    """The world-space plane P with P·[x, 1] = (view depth of x) - near: >= 0 in front of the near plane."""
    return -np.asarray(world_to_view, np.float64)[2] - np.array([0.0, 0.0, 0.0, near])


def triangle_boxes(tris, world_to_view, proj, width, height, near):
    """Inclusive pixel boxes (x0, x1, y0, y1) of world triangles (T, 3, 3) on the screen.

    A triangle wholly behind the near plane gets an empty box; one that crosses it gets the
    whole screen (conservative: rays decide). Boxes are clipped to the image.
    """
    v = np.asarray(tris, np.float64) @ world_to_view[:3, :3].T + world_to_view[:3, 3]
    depth = -v[..., 2]
    clip = np.concatenate([v, np.ones(v.shape[:-1] + (1,))], -1) @ proj.T
    x, y, _ = clip_to_pixels(clip, width, height)
    behind = depth < near
    all_behind, some_behind = behind.all(1), behind.any(1)
    x0 = np.floor(np.where(behind, np.inf, x).min(1) + 0.5 - 1e-9)
    x1 = np.ceil(np.where(behind, -np.inf, x).max(1) - 0.5 + 1e-9)
    y0 = np.floor(np.where(behind, np.inf, y).min(1) + 0.5 - 1e-9)
    y1 = np.ceil(np.where(behind, -np.inf, y).max(1) - 0.5 + 1e-9)
    full = some_behind & ~all_behind
    x0 = np.where(full, 0, x0)
    y0 = np.where(full, 0, y0)
    x1 = np.where(full, width - 1, x1)
    y1 = np.where(full, height - 1, y1)
    x0 = np.clip(np.nan_to_num(x0, nan=width), 0, width).astype(np.int64)
    y0 = np.clip(np.nan_to_num(y0, nan=height), 0, height).astype(np.int64)
    x1 = np.clip(np.nan_to_num(x1, nan=-1.0), -1, width - 1).astype(np.int64)
    y1 = np.clip(np.nan_to_num(y1, nan=-1.0), -1, height - 1).astype(np.int64)
    x1 = np.where(all_behind, -1, x1)
    return x0, x1, y0, y1


def candidates(boxes, chunk=CHUNK):
    """Yield (tri, px, py) int arrays: every pixel of every triangle's box, at most ``chunk`` per batch."""
    x0, x1, y0, y1 = boxes
    bw = np.maximum(x1 - x0 + 1, 0)
    bh = np.maximum(y1 - y0 + 1, 0)
    counts = bw * bh
    live = np.nonzero(counts)[0]
    start = 0
    while start < len(live):
        cum = np.cumsum(counts[live[start:]])
        stop = start + max(1, int(np.searchsorted(cum, chunk, side="right")))
        idx = live[start:stop]
        c = counts[idx]
        tri = np.repeat(idx, c)
        offsets = np.repeat(np.cumsum(c) - c, c)
        local = np.arange(int(c.sum()), dtype=np.int64) - offsets
        w = bw[tri]
        yield tri, x0[tri] + local % w, y0[tri] + local // w
        start = stop


def span_candidates(tris, world_to_view, proj, width, height, near, chunk=CHUNK):
    """Yield (tri, px, py): pixels along each row's span of each triangle, one pixel of margin.

    Thin, long triangles (extruded shadow-volume sides) cover a small part of their bounding
    box; walking spans row by row keeps the candidates near the covered pixels. Triangles that
    cross the near plane cannot be projected and fall back to the whole screen.
    """
    tris = np.asarray(tris, np.float64)
    boxes = triangle_boxes(tris, world_to_view, proj, width, height, near)
    x0, x1, y0, y1 = boxes
    v = tris @ world_to_view[:3, :3].T + world_to_view[:3, 3]
    behind = (-v[..., 2] < near).any(1)
    full = behind & (x1 >= x0)
    if full.any():
        idx = np.nonzero(full)[0]
        for tri, px, py in candidates(tuple(b[idx] for b in boxes), chunk):
            yield idx[tri], px, py
    x, y, _ = clip_to_pixels(to_clip(tris, world_to_view, proj), width, height)
    live = np.nonzero(~behind & (x1 >= x0) & (y1 >= y0))[0]
    rows_per = (y1 - y0 + 1)[live]
    start = 0
    while start < len(live):
        cum = np.cumsum(rows_per[start:])
        stop = start + max(1, int(np.searchsorted(cum, chunk // 8, side="right")))
        idx = live[start:stop]
        c = rows_per[start:stop]
        tri = np.repeat(idx, c)
        row = y0[tri] + np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        xs, ys = x[tri], y[tri]
        lo = np.full(len(tri), np.inf)
        hi = np.full(len(tri), -np.inf)
        for a, b in ((0, 1), (1, 2), (2, 0)):
            ya, yb, xa, xb = ys[:, a], ys[:, b], xs[:, a], xs[:, b]
            ymin, ymax = np.minimum(ya, yb) - 0.5, np.maximum(ya, yb) + 0.5
            on = (row >= ymin) & (row <= ymax)
            dy = yb - ya
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.clip(np.where(np.abs(dy) > 1e-12, (row - ya) / dy, 0.0), 0.0, 1.0)
            xi = xa + f * (xb - xa)
            # the edge's x over the row's height (row +- 0.5) bounds the span conservatively
            with np.errstate(divide="ignore", invalid="ignore"):
                slope = np.where(np.abs(dy) > 1e-12, np.abs((xb - xa) / dy) * 0.5, np.abs(xb - xa))
            lo = np.where(on, np.minimum(lo, xi - slope), lo)
            hi = np.where(on, np.maximum(hi, xi + slope), hi)
        lo = np.maximum(np.floor(lo) - 1, x0[tri])
        hi = np.minimum(np.ceil(hi) + 1, x1[tri])
        n = np.where(np.isfinite(lo) & np.isfinite(hi), np.maximum(hi - lo + 1, 0), 0).astype(np.int64)
        lo = np.where(n > 0, lo, 0).astype(np.int64)
        keep = n > 0
        tri, row, lo, n = tri[keep], row[keep], lo[keep], n[keep]
        t2 = np.repeat(tri, n)
        px = np.repeat(lo, n) + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        yield t2, px, np.repeat(row, n)
        start = stop


def rasterize_depth_tested(tris, world_to_view, proj, width, height, scene_depth, near=1e-4):
    """Cover mask of world triangles (T, 3, 3) drawn with a LESS_EQUAL depth test against the scene.

    Pixel centres inside a triangle (edges inclusive) whose interpolated NDC z (linear in screen
    space for perspective and orthographic cameras) is <= the scene's NDC z pass. Triangles are
    clipped at the near plane first (a shadow on the floor reaches behind the camera).
    """
    cover = np.zeros((height, width), bool)
    tris = clip_triangles(tris, near_plane(world_to_view, near))
    if len(tris) == 0:
        return cover
    clip = to_clip(tris, world_to_view, proj)
    x, y, z = clip_to_pixels(clip, width, height)
    scene_z = view_depth_to_ndc_z(scene_depth, proj)
    boxes = triangle_boxes(tris, world_to_view, proj, width, height, 0.5 * near)   # clipped vertices sit at near
    area = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    for tri, px, py in candidates(boxes):
        a = area[tri]
        good = np.abs(a) > 1e-12
        tri, px, py, a = tri[good], px[good], py[good], a[good]
        xs, ys = x[tri], y[tri]
        w0 = (xs[:, 1] - px) * (ys[:, 2] - py) - (xs[:, 2] - px) * (ys[:, 1] - py)
        w1 = (xs[:, 2] - px) * (ys[:, 0] - py) - (xs[:, 0] - px) * (ys[:, 2] - py)
        b0, b1 = w0 / a, w1 / a
        b2 = 1.0 - b0 - b1
        inside = (b0 >= -1e-9) & (b1 >= -1e-9) & (b2 >= -1e-9)
        zs = z[tri]
        frag = b0 * zs[:, 0] + b1 * zs[:, 1] + b2 * zs[:, 2]
        ok = inside & (frag <= scene_z[py, px])
        cover[py[ok], px[ok]] = True
    return cover


def rasterize_depth(tris, world_to_view, proj, width, height, near, far=np.inf, chunk=CHUNK, stats=None):
    """(H, W) planar view depth of the nearest world triangle (T, 3, 3) at each pixel centre, SKY_DEPTH where none.

    What a camera ray through the pixel centre hits first, as Cycles' Depth pass at one sample through
    the centre gives it: no back-face culling, the scene clipped to near <= d <= far (Cycles starts
    camera rays on the plane d = clip_start and ends them on d = clip_end), centres on an edge inside
    (EDGE_EPS). Along a row of a triangle's span the depth is affine in the pixel x for an orthographic
    camera, 1/d for a perspective one; the nearest fragment wins (z-buffer minimum). ``stats``, a dict,
    gets the counts "triangles" (after clipping), "spans" and "fragments" (covered pixel-triangle pairs) added.
    """
    w2v = np.asarray(world_to_view, np.float64)
    proj = np.asarray(proj, np.float64)
    depth = np.full(height * width, SKY_DEPTH)
    v = np.asarray(tris, np.float64).reshape(-1, 3, 3) @ w2v[:3, :3].T + w2v[:3, 3]
    v = clip_triangles(v, (0.0, 0.0, -1.0, -near))
    if np.isfinite(far) and len(v):
        v = clip_triangles(v, (0.0, 0.0, 1.0, far))
    if len(v) == 0:
        return depth.reshape(height, width)
    ortho = proj[3, 2] == 0.0 and proj[3, 3] == 1.0
    x, y, _ = clip_to_pixels(np.concatenate([v, np.ones(v.shape[:-1] + (1,))], -1) @ proj.T, width, height)
    q = -v[..., 2] if ortho else -1.0 / v[..., 2]
    counts = {"triangles": len(v), "spans": 0, "fragments": 0}
    for row, lo, hi, qa, qb in _spans(x, y, q, width, height, chunk):
        _fill(depth, row * width + lo, hi - lo + 1, qa, qb, ortho, chunk)
        counts["spans"] += len(row)
        counts["fragments"] += int((hi - lo + 1).sum())
    if stats is not None:
        for k, n in counts.items():
            stats[k] = stats.get(k, 0) + n
    return depth.reshape(height, width)


def _spans(x, y, q, width, height, chunk):
    """Yield (row, lo, hi, q(lo), q(hi)): for each triangle and pixel row, the inclusive run of pixel
    centres inside it and the attribute ``q`` (affine in screen space) at both ends, clamped to the
    triangle's range of q. Inside: s E_k(x, y) >= -EDGE_EPS |edge k| for the three edge functions
    E_k = (x_b - x_a)(y - y_a) - (y_b - y_a)(x - x_a), s the sign of the area; on a row each is a half-line in x.
    """
    x0, y0, q0 = x[:, 0], y[:, 0], q[:, 0]
    e1x, e1y, e2x, e2y = x[:, 1] - x0, y[:, 1] - y0, x[:, 2] - x0, y[:, 2] - y0
    area = e1x * e2y - e2x * e1y
    live = (np.abs(area) > 1e-12) & (x.max(1) >= -EDGE_EPS) & (x.min(1) <= width - 1 + EDGE_EPS)
    r0 = np.maximum(np.ceil(y.min(1) - EDGE_EPS), 0)
    r1 = np.minimum(np.floor(y.max(1) + EDGE_EPS), height - 1)
    live &= r1 >= r0
    idx = np.nonzero(live)[0]
    if len(idx) == 0:
        return
    area, r0, r1 = area[idx], r0[idx].astype(np.int64), r1[idx].astype(np.int64)
    x, y, q, x0, y0, q0 = x[idx], y[idx], q[idx], x0[idx], y0[idx], q0[idx]
    e1x, e1y, e2x, e2y, e1q, e2q = e1x[idx], e1y[idx], e2x[idx], e2y[idx], q[:, 1] - q0, q[:, 2] - q0
    qx = (e1q * e2y - e2q * e1y) / area
    qy = (e2q * e1x - e1q * e2x) / area
    qmin, qmax = q.min(1), q.max(1)
    s = np.sign(area)
    # s E_k = A x + B y + C per edge (a -> b)
    a_, b_, c_, tol = [], [], [], []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        dx, dy = x[:, b] - x[:, a], y[:, b] - y[:, a]
        a_.append(-s * dy)
        b_.append(s * dx)
        c_.append(s * (dy * x[:, a] - dx * y[:, a]))
        tol.append(EDGE_EPS * np.hypot(dx, dy))
    rows = r1 - r0 + 1
    start = 0
    while start < len(idx):
        cum = np.cumsum(rows[start:])
        stop = start + max(1, int(np.searchsorted(cum, chunk // 4, side="right")))
        c = rows[start:stop]
        t = np.repeat(np.arange(start, stop), c)
        row = r0[t] + np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        lo = np.full(len(t), -np.inf)
        hi = np.full(len(t), np.inf)
        for k in range(3):
            ak = a_[k][t]
            rhs = -(b_[k][t] * row + c_[k][t]) - tol[k][t]
            with np.errstate(divide="ignore", invalid="ignore"):
                bound = rhs / ak
            lo = np.where(ak > 0, np.maximum(lo, bound), lo)
            hi = np.where(ak < 0, np.minimum(hi, bound), hi)
            hi = np.where((ak == 0) & (rhs > 0), -np.inf, hi)
        lo = np.maximum(np.ceil(lo), 0)
        hi = np.minimum(np.floor(hi), width - 1)
        keep = hi >= lo
        t, row, lo, hi = t[keep], row[keep], lo[keep].astype(np.int64), hi[keep].astype(np.int64)
        base = q0[t] + qy[t] * (row - y0[t])
        qa = np.clip(base + qx[t] * (lo - x0[t]), qmin[t], qmax[t])
        qb = np.clip(base + qx[t] * (hi - x0[t]), qmin[t], qmax[t])
        yield row, lo, hi, qa, qb
        start = stop


def _fill(depth, first, n, qa, qb, ortho, chunk):
    """z-buffer minimum of the runs of ``n`` pixels from flat index ``first``, q linear from qa to qb."""
    step = np.where(n > 1, (qb - qa) / np.maximum(n - 1, 1), 0.0)
    start = 0
    while start < len(n):
        cum = np.cumsum(n[start:])
        stop = start + max(1, int(np.searchsorted(cum, chunk, side="right")))
        c = n[start:stop]
        offset = np.cumsum(c) - c
        k = np.arange(int(c.sum())) - np.repeat(offset, c)
        val = np.repeat(qa[start:stop], c) + np.repeat(step[start:stop], c) * k
        if not ortho:
            val = 1.0 / val
        np.minimum.at(depth, np.repeat(first[start:stop], c) + k, val)
        start = stop
