"""The margin a UV layout keeps between its charts, measured: for a layer the bake did not make (an earlier bake's
"Lightmap" layer reused, the user's own ``--uv-layer``), whose margin is not known from its making.

The unwrappers' rule (:func:`core.pack.spacing`): with a margin of m texels, charts' footprints (the texels their
faces touch) are at least max(1, ⌈2m⌉ − 2) empty texels apart, chessboard distance (Blender's packers leave 2m
texels between outlines, whose footprints may each reach a texel beyond them; the raster packer keeps exactly that). The measured
margin is the largest m whose rule the layout keeps: (g + 2) / 2 for footprints g ≥ 1 texels apart, 0 when two
charts' footprints share or touch a texel. Footprints are traced along the charts' outlines (edges of one face of the
chart) on a FINE × finer raster, so a chart lying wholly over another one's faces (stacked UVs) is not seen here: the
overlap figure reports it.
"""
import numpy as np

from .pack import FINE, chart_labels, edge_points
from .rows import unique_rows

POINTS = 1 << 20
"""Outline points traced at once (a layout of stacked faces, each outlining the whole map, stops at its first)."""


def margin_from_gap(gap):
    """The largest margin (texels) whose packing rule (:func:`core.pack.spacing`) footprints ``gap`` empty texels
    apart keep: (gap + 2) / 2, 0 below one texel."""
    return 0.0 if gap < 1 else (gap + 2) / 2


def footprint_gap(tri_uv, tri_vertex, width, height, limit):
    """Empty texels (chessboard distance) between the footprints of the two nearest charts of the layout ``tri_uv``
    (T, 3, 2) UVs on a ``width`` x ``height`` map, or ``limit`` (an int) when none are nearer. Charts join faces
    through corners at one vertex (``tri_vertex`` (T, 3): welded ids) with equal UVs
    (:func:`core.pack.chart_labels`). The outlines are traced POINTS at a time, each texel kept once, and the first
    texel two charts touch ends it (0)."""
    tri_uv = np.ascontiguousarray(tri_uv, np.float32).reshape(-1, 3, 2)
    tri_vertex = np.asarray(tri_vertex, np.int64).reshape(-1, 3)
    limit = int(limit)
    if len(tri_uv) < 2 or limit <= 0:
        return limit
    labels = chart_labels(np.repeat(np.arange(len(tri_uv)), 3), tri_vertex.reshape(-1), tri_uv.reshape(-1, 2))
    if labels.max() == 0:
        return limit
    seg, seg_label = _outline(tri_uv, tri_vertex, labels)
    size = np.array([width, height], np.float64)
    seg = np.clip(seg * size, -1.0, size + 1.0)             # beyond the map: the texels of its border
    taken = np.full(width * height, -1, np.int32)
    cells, cell_label = [], []
    for flat, label in _traced(seg, seg_label, width, height):
        before = taken[flat]
        taken[flat] = label
        if ((before >= 0) & (before != label)).any() or (taken[flat] != label).any():
            return 0                                        # a texel two charts touch
        cells.append(flat[before < 0])
        cell_label.append(label[before < 0])
    cells, cell_label = np.concatenate(cells), np.concatenate(cell_label)
    x, y = cells % width, cells // width
    for k in range(1, limit + 1):
        for dx, dy in _ring(k):
            xs, ys = x + dx, y + dy
            inside = (xs >= 0) & (xs < width) & (ys >= 0) & (ys < height)
            other = taken[(ys * width + xs)[inside]]
            if ((other >= 0) & (other != cell_label[inside])).any():
                return k - 1
    return limit


def _ring(k):
    """Half the offsets at chessboard distance ``k`` (the other half are their opposites)."""
    return [(dx, k) for dx in range(-k, k + 1)] + [(k, dy) for dy in range(-k + 1, k)]


def _outline(tri_uv, tri_vertex, labels):
    """(E, 2, 2) UV segments of the edges that bound a chart (used by one face of it) and (E,) their charts."""
    bits = tri_uv.view(np.uint32).astype(np.int64)
    corner = unique_rows(np.stack([tri_vertex.reshape(-1), (bits[..., 0] << 32 | bits[..., 1]).reshape(-1)],
                                  axis=1)).reshape(-1, 3)
    a, b = corner, np.roll(corner, -1, axis=1)
    inverse = unique_rows(np.stack([np.minimum(a, b).ravel(), np.maximum(a, b).ravel()], axis=1))
    once = np.bincount(inverse)[inverse] == 1
    ends = np.stack([tri_uv, np.roll(tri_uv, -1, axis=1)], axis=2).reshape(-1, 2, 2)
    return ends[once].astype(np.float64), np.repeat(labels, 3)[once]


def _traced(seg, seg_label, width, height):
    """Chunks of (texels, charts), each pair once in its chunk: the texels that points along the segments ``seg``
    (E, 2, 2) in texel units fall in, taken a FINE-th of a texel apart at most (both ends included; texels clipped to
    the map), about POINTS points a chunk."""
    cum = np.cumsum(np.ceil(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) * FINE) + 1)
    begin = 0
    while begin < len(seg):
        end = max(begin + 1, int(np.searchsorted(cum, (cum[begin - 1] if begin else 0) + POINTS, side="right")))
        pts, edge = edge_points(seg[begin:end, 0] * FINE, seg[begin:end, 1] * FINE)
        texel = np.floor(pts / FINE).astype(np.int64)
        flat = np.clip(texel[:, 1], 0, height - 1) * width + np.clip(texel[:, 0], 0, width - 1)
        label = seg_label[begin:end][edge]
        first, _ = unique_rows(np.stack([flat, label], axis=1), return_index=True)
        yield flat[first], label[first].astype(np.int32)
        begin = end
