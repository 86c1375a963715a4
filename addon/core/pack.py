"""Raster packing of a UV layout's charts: each chart's texels at a common scale, placed one after the other, the
largest first, at the lowest free row and then column of the map in the quarter turn whose top is then lowest, no
texel of it nearer than the margin to another chart's; the scale is the largest at which every chart finds a place
(bisection), or the charts keep their size and the map is cut to the rows they reach.

Blender's packers place charts by their bounding boxes (Smart UV Project, ``uv.pack_islands`` with AABB shapes) or
by their outlines at seconds per hundred charts (CONCAVE). A subdivided Suzanne's Smart UV Project charts at 128²
(2-texel margins) leave half the map between their boxes; placed by their texels they fill 0.52 of it instead of
0.33, and at 256² 0.65 instead of 0.42 (docs/lightmaps.md).

A chart's footprint is every texel its triangles touch (the texel centres inside them, the texels a 3 × finer
raster finds inside them, and the texels along their edges: slivers between centres), so that no texel is touched
by two charts. With a margin of m
texels (the map is dilated by m) the unwrappers leave 2m texels between charts' outlines and m to the map's border
(a sampler that wraps reads the opposite border), where the texels they touch may reach a texel beyond the
outline: footprints here are 2m − 2 texels apart (at least one) and m − 1 from the border, what those layouts
keep at the least. A footprint's free places are searched in bands of rows, from the first row whose longest free
run holds the footprint's longest row up, for all offsets of a band at once: one shifted OR of the band per texel of
a small footprint, the correlation of the band with a larger one (FFT).
"""
import dataclasses
import math

import numpy as np

from .graph import components
from .lightmap import coverage_mask, uv_area
from .rows import unique_rows

FINE = 3
"""A footprint holds the texels in which a FINE × finer raster of the chart finds a texel centre (odd: the middle
fine centre of a texel is its own centre)."""


def chart_labels(owner, vertex, uv):
    """Chart 0..K-1 of each face (or triangle), from its corners: ``owner`` (N,) the face of each corner,
    ``vertex`` (N,) its vertex, ``uv`` (N, 2) its UVs; faces join through corners at one vertex with equal UVs
    (bit for bit as float32): the parts of the graph of faces and such corners (:func:`graph.components`)."""
    owner = np.asarray(owner, np.int64)
    if not len(owner):
        return np.zeros(0, np.int64)
    bits = np.ascontiguousarray(uv, np.float32).reshape(-1, 2).view(np.uint32).astype(np.int64)
    key = np.stack([np.asarray(vertex, np.int64), (bits[:, 0] << 32) | bits[:, 1]], axis=1)
    corner = unique_rows(key)                                         # one id for equal corners
    faces = int(owner.max()) + 1
    root = components(owner, faces + corner, faces + int(corner.max()) + 1)[:faces]
    return np.unique(root, return_inverse=True)[1].ravel()


@dataclasses.dataclass
class Placement:
    """How one chart moved: texel coordinates p = uv · side are rotated ``turns`` quarter turns, scaled by the
    layout's ``scale``, shifted by ``-low`` (the footprint's corner) and placed at ``offset`` (x, y) texels."""
    turns: int
    low: np.ndarray
    offset: tuple


@dataclasses.dataclass
class Packing:
    """Charts placed at ``scale`` × the layout's size: ``placements`` by chart, ``covered`` texel centres, ``extent``
    (width, height) texels of their footprints' box from the map's corner."""
    scale: float
    placements: list
    covered: int
    extent: tuple = (0, 0)
    _moves: tuple = None

    def moves(self):
        """(K,) quarter turns and (K, 2) shifts (offset − low) of the charts, made once."""
        if self._moves is None:
            self._moves = (np.array([p.turns % 4 for p in self.placements], np.int64),
                           np.array([np.asarray(p.offset, float) - p.low for p in self.placements]).reshape(-1, 2))
        return self._moves


def _turned(p, turns):
    for _ in range(turns % 4):
        p = np.stack([-p[..., 1], p[..., 0]], axis=-1)
    return p


SHELF = 2048
"""Widest row (texels) of the sheet the charts are rasterised on together (:func:`_footprints`)."""


def _footprints(tri, charts, scale, side):
    """Per chart (``charts``: its triangles' indices in ``tri`` (T, 3, 2) UVs) at ``scale``, its 4 quarter turns
    [(covered (h, w), footprint (h, w), low)], each with its texel box's corner ``low`` moved to the origin. The
    charts are rasterised once, a texel apart on the shelves of one sheet (the tallest first, shelves at most SHELF
    texels wide), FINE × finer (a texel's centre is the centre of its middle fine texel, FINE odd), and their edges
    are traced at fine-texel steps (:func:`_traced`: a chart thinner than a fine texel still has its outline in its
    footprint); a quarter turn maps fine texels onto fine texels, so the turned rasters are the rasters turned
    (:func:`_quarter`)."""
    p = np.asarray(tri, float) * (scale * side)
    lows, sizes = [], []
    for c in charts:
        q = p[c].reshape(-1, 2)
        low = np.floor(q.min(axis=0))
        lows.append(low)
        sizes.append(tuple(int(v) + 1 for v in np.ceil(q.max(axis=0) - low)))
    width = max([SHELF] + [w for w, _ in sizes])
    corner = [None] * len(charts)
    x = y = shelf = sheet_w = 0
    for k in sorted(range(len(charts)), key=lambda k: (-sizes[k][1], k)):
        w, h = sizes[k]
        if x and x + w > width:
            x, y, shelf = 0, y + shelf + 1, 0
        corner[k] = (x, y)
        x += w + 1
        shelf = max(shelf, h)
        sheet_w = max(sheet_w, x)
    sheet_h = y + shelf + 1
    sheet = np.empty_like(p)
    for c, low, xy in zip(charts, lows, corner):
        sheet[c] = p[c] - low + xy
    fine = coverage_mask(sheet / (sheet_w, sheet_h), FINE * sheet_w, FINE * sheet_h)
    edges = _traced(sheet * FINE, FINE * sheet_w, FINE * sheet_h)
    centres, pooled = fine[FINE // 2::FINE, FINE // 2::FINE], _pooled(fine | edges)
    out = []
    for low, (w, h), (x0, y0) in zip(lows, sizes, corner):
        box = slice(y0, y0 + h), slice(x0, x0 + w)
        turns = [(centres[box], pooled[box], low)]
        for _ in range(3):
            turns.append(_quarter(*turns[-1]))
        out.append(turns)
    return out


def _pooled(fine):
    """(h, w): whether each FINE x FINE block of ``fine`` (FINE h, FINE w) holds a True (the OR of its FINE² strided
    views: numpy's ``any`` over two short axes is slower)."""
    out = fine[::FINE, ::FINE].copy()
    for dy in range(FINE):
        for dx in range(FINE):
            if dy or dx:
                out |= fine[dy::FINE, dx::FINE]
    return out


def spacing(margin):
    """Empty texels (chessboard distance) the unwrappers keep between two charts' footprints with a margin of
    ``margin`` texels: max(1, ⌈2m⌉ − 2) (see the module's docstring)."""
    return max(1, int(math.ceil(2 * margin)) - 2)


def edge_points(a, b):
    """(P, 2) points along the segments from ``a`` to ``b`` (N, 2 each), at most a unit apart (both ends included),
    and (P,) the segment of each."""
    n = np.ceil(np.linalg.norm(b - a, axis=1)).astype(np.int64) + 1
    edge = np.repeat(np.arange(len(n)), n)
    t = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(np.maximum(n - 1, 1), n)
    return a[edge] + t[:, None] * (b - a)[edge], edge


def _traced(tri, width, height):
    """(height, width) mask of the cells that points along every edge of the triangles ``tri`` (T, 3, 2), in cell
    units, fall in, taken at most a cell apart (both ends included)."""
    pts = np.floor(edge_points(tri.reshape(-1, 2), tri[:, [1, 2, 0]].reshape(-1, 2))[0]).astype(np.int64)
    mask = np.zeros((height, width), bool)
    mask[np.clip(pts[:, 1], 0, height - 1), np.clip(pts[:, 0], 0, width - 1)] = True
    return mask


def _quarter(covered, footprint, low):
    """A chart's texel rasters and box corner turned a quarter (x, y) -> (-y, x) (:func:`_turned`). The fine texels
    of a texel are turned onto those of the turned texel (and the middle one, FINE odd, onto the middle one), so
    the rasters of the turned chart are the texel rasters turned."""
    return covered[::-1].T, footprint[::-1].T, np.array([-low[1] - covered.shape[0], low[0]])


def _fast(n):
    """The smallest 2^a 3^b 5^c >= n (a size the FFT is quick for)."""
    best = 1 << max(0, int(n - 1).bit_length())
    f5 = 1
    while f5 < best:
        f3 = f5
        while f3 < best:
            f2 = f3
            while f2 < n:
                f2 *= 2
            best = min(best, f2)
            f3 *= 3
        f5 *= 5
    return best


def _grown(mask, r):
    """``mask`` grown by ``r`` texels (chessboard distance) on every side: (h + 2r, w + 2r), the OR of its shifts by
    0..2r texels, along the rows and then the columns."""
    if r <= 0:
        return mask
    h, w = mask.shape
    rows = np.zeros((h, w + 2 * r), bool)
    for dx in range(2 * r + 1):
        rows[:, dx:dx + w] |= mask
    out = np.zeros((h + 2 * r, w + 2 * r), bool)
    for dy in range(2 * r + 1):
        out[dy:dy + h] |= rows
    return out


BAND = 32
"""Rows of the map searched at once for a chart's place, from the lowest row with a free texel up (doubled at each
band without a place; a turn's search stops where no place could have a lower top than the best found)."""
DIRECT = 48
"""Footprint texels up to which the offsets that hit an occupied texel are found by one shifted OR per texel;
larger footprints by the correlation of the map with the footprint (FFT)."""


def _conflicts(occupied, foot, rows):
    """(rows, W - w + 1) bool: whether the footprint ``foot`` (h, w) placed at (y, x) of ``occupied``
    (rows + h - 1, W) meets an occupied texel."""
    h, w = foot.shape
    cols = occupied.shape[1] - w + 1
    cells = np.argwhere(foot)
    if len(cells) <= DIRECT:
        out = np.zeros((rows, cols), bool)
        for dy, dx in cells:
            out |= occupied[dy:dy + rows, dx:dx + cols]
        return out
    size = (_fast(occupied.shape[0]), _fast(occupied.shape[1]))
    hits = np.fft.irfft2(np.fft.rfft2(occupied.astype(np.float64), s=size)
                         * np.fft.rfft2(foot[::-1, ::-1].astype(np.float64), s=size), s=size)
    return hits[h - 1:h - 1 + rows, w - 1:w - 1 + cols] >= 0.5


def _longest_runs(free):
    """(R,) the longest run of True in each row of ``free`` (R, W)."""
    padded = np.zeros((free.shape[0], free.shape[1] + 2), np.int8)
    padded[:, 1:-1] = free
    step = np.diff(padded, axis=1)
    rows, start = np.nonzero(step == 1)
    _, end = np.nonzero(step == -1)
    out = np.zeros(free.shape[0], np.int64)
    np.maximum.at(out, rows, end - start)
    return out


def _first_free(occupied, runs, foot, low, best_top):
    """(y, x) of the footprint's first free place in row-major order whose first texel row is at ``low`` or above
    (the rows below are full), or None when there is none. Searched in bands of rows (BAND) from the first row where
    the map's longest free run (``runs``, per row) holds the footprint's longest run of texels in a row; with
    ``best_top`` (None: no bound) no band is searched whose places would all have a top y + h above it, so None also
    when no place's top can be at most ``best_top`` (a place found in a band may still be above it: the caller
    compares)."""
    side_h, side_w = occupied.shape
    h, w = foot.shape
    if h > side_h or w > side_w or not foot.any():
        return None
    need = _longest_runs(foot)
    dy = int(np.argmax(need))
    start = max(0, low - int(np.argmax(foot.any(axis=1))))
    fits = np.flatnonzero(runs[start + dy:side_h - h + 1 + dy] >= need[dy])
    if not len(fits):
        return None
    y, band = start + int(fits[0]), max(BAND, 2 * h)
    while y <= side_h - h and (best_top is None or y + h <= best_top):
        rows = min(band, side_h - h + 1 - y)
        free = np.flatnonzero(~_conflicts(occupied[y:y + rows + h - 1], foot, rows))
        if len(free):
            dy, x = divmod(int(free[0]), side_w - w + 1)
            return y + dy, x
        y += rows
        band *= 2
    return None


def pack(tri, labels, side, margin, scale):
    """:class:`Packing` of the charts (``labels`` of the triangles ``tri`` (T, 3, 2), UVs of a ``side``² map) at
    ``scale`` with a margin of ``margin`` texels, or None when one finds no place."""
    r = spacing(margin)
    border = max(0, int(math.ceil(margin)) - 1)
    occupied = np.zeros((side, side), bool)
    if border:
        occupied[:border], occupied[-border:], occupied[:, :border], occupied[:, -border:] = True, True, True, True
    runs = _longest_runs(~occupied)
    charts = _charts(labels)
    shapes = _footprints(tri, charts, scale, side)
    order = sorted(range(len(charts)), key=lambda i: (-int(shapes[i][0][1].sum()), i))
    placements, covered, right, top = [None] * len(charts), 0, 0, 0
    for i in order:
        if min(max(s[1].shape[0] for s in shapes[i]), max(s[1].shape[1] for s in shapes[i])) > side:
            return None
        low = int(np.argmin(occupied.all(axis=1))) if not occupied.all() else side
        best = None                                  # ((top, y, x, turn)): the lowest top, then row, column, turn
        for turns in sorted(range(4), key=lambda t: (shapes[i][t][1].shape[0], t)):
            foot = shapes[i][turns][1]
            place = _first_free(occupied, runs, foot, low, best[0][0] if best else None)
            if place is not None:
                key = (place[0] + foot.shape[0], place[0], place[1], turns)
                if best is None or key < best[0]:
                    best = (key, turns)
        if best is None:
            return None
        (_, y, x, _), turns = best
        cov, foot, low = shapes[i][turns]
        h, w = foot.shape
        if (occupied[y:y + h, x:x + w] & foot).any():     # the correlation's round-off, never seen: no place
            return None
        grown = _grown(foot, r)
        y0, x0 = y - r, x - r
        ys, xs = max(y0, 0), max(x0, 0)
        ye, xe = min(y0 + h + 2 * r, side), min(x0 + w + 2 * r, side)
        occupied[ys:ye, xs:xe] |= grown[ys - y0:ye - y0, xs - x0:xe - x0]
        runs[ys:ye] = _longest_runs(~occupied[ys:ye])
        placements[i] = Placement(turns, low, (int(x), int(y)))
        covered += int(cov.sum())
        right, top = max(right, int(x) + w), max(top, int(y) + h)
    return Packing(scale, placements, covered, (right, top))


def _charts(labels):
    """The triangles of each chart 0..K-1 (``labels``: each triangle's chart)."""
    if not len(labels):
        return []
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(int(labels.max()) + 2))
    return [order[bounds[k]:bounds[k + 1]] for k in range(len(bounds) - 1)]


SHRINK = 0.9
"""Step down from ``start`` while the charts find no place at it (:func:`largest`), to at most half of it: a layout
whose charts lie 8 texels apart by their boxes (4-texel margins) may not fit at its own size by footprints 6 texels
apart from its charts' outlines, and still fit a little smaller (a cylinder's six charts at 128²: 0.50 of the map
by their boxes, 0.54 placed by their texels, the search starting at 0.9 times their size)."""


def largest(tri, labels, side, margin, start=1.0, steps=5):
    """The :class:`Packing` at the largest scale found by bisection between the first of ``start``, SHRINK ×
    ``start``, ... (down to half of it) at which every chart finds a place and the scale at which the charts' covered
    texels would fill the map, or None when none of those finds places."""
    tri = np.asarray(tri, float).reshape(-1, 3, 2)
    labels = np.asarray(labels, np.int64)
    best = pack(tri, labels, side, margin, start)
    lowest_start = 0.5 * start
    while best is None and start * SHRINK >= lowest_start:
        start *= SHRINK
        best = pack(tri, labels, side, margin, start)
    if best is None or not best.covered:
        return None
    hi = start * math.sqrt(side * side / best.covered)
    lo = start
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        got = pack(tri, labels, side, margin, mid)
        if got is not None:
            lo, best = mid, got
        else:
            hi = mid
    return best


def side_that_fills(tri, labels, side, margin, goal, cap, work=math.inf):
    """A map side in (``side``, ``cap``] at which the charts (``labels`` of the triangles ``tri``, UVs of a ``side``²
    map), placed by their texels with ``margin`` texels (:func:`pack`) at the scale at which their triangles cover
    ``goal`` of the map, find a place and cover it: doubling, then bisection to an eighth of the side. The fill is not
    monotone in the side (a greedy placement on a raster): the side named fills, the one an eighth below it did not,
    a smaller one may. 0 (not None: a memo keeps it) when no side up to ``cap`` does, or once charts × side passes
    ``work``; a side at which a chart's box, so scaled, is wider than the map is not packed."""
    tri = np.asarray(tri, float).reshape(-1, 3, 2)
    labels = np.asarray(labels, np.int64)
    side, cap = max(1, int(side)), int(cap)
    charts = _charts(labels)
    area = uv_area(tri)
    if not charts or not area > 0:
        return 0
    extent = max(float(np.ptp(tri[c].reshape(-1, 2), axis=0).max()) for c in charts)

    def fills(n):
        scale = math.sqrt(goal / area)
        for _ in range(2):                 # the texels a chart covers grow with the square of its scale, about
            if scale * extent > 1:
                return False
            got = pack(tri, labels, n, margin, scale)
            if got is None:
                return False
            if got.covered >= goal * n * n:
                return True
            scale *= math.sqrt(goal * n * n / max(got.covered, 1))
        return False

    low, high = side, None
    while high is None and low < cap:
        n = min(2 * low, cap)
        if len(charts) * n > work:
            return 0
        low, high = (low, n) if fills(n) else (n, None)
    if high is None:
        return 0
    while high - low > max(1, high // 8):
        mid = (low + high) // 2
        low, high = (low, mid) if fills(mid) else (mid, high)
    return high


def lowest(tri, labels, side, margin, squares=()):
    """:class:`Packing` of the charts at their size (the same texels per UV unit) in a ``side``² map, or None when
    one finds no place. Each chart takes the place whose top is lowest, so the charts stay in the fewest rows this
    placement reaches (a limit on the rows would only take away places it did not choose); the map is then cut to
    them: the same texel density, fewer texels. For each fill f of ``squares`` the charts are also placed in the
    smaller square n² that their texels would fill so, n = ⌈√(covered / f)⌉, and the placement whose box they fill
    most is kept (two pieces of a strip, :func:`core.merging.cut_long`, laid side by side in a wide map rather than
    stacked: 0.49 of their box, 0.86 in the square)."""
    tri = np.asarray(tri, float).reshape(-1, 3, 2)
    labels = np.asarray(labels, np.int64)
    best = pack(tri, labels, side, margin, 1.0)
    if best is None or not best.covered:
        return None
    fill = lambda p: p.covered / max(p.extent[0] * p.extent[1], 1)
    for f in squares:
        n = int(math.ceil(math.sqrt(best.covered / f)))
        if n >= side:
            continue
        got = pack(tri, labels, n, margin, side / n)        # the same texels, placed in the n² corner of the map
        if got is not None and got.covered and fill(got) > fill(best):
            best = Packing(1.0, got.placements, got.covered, got.extent)
    return best


def moved(uv, labels, packing, side):
    """UVs ``uv`` (N, 2) whose charts are ``labels`` (N,) moved by ``packing`` (:func:`pack`) in a ``side``² map."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    labels = np.asarray(labels, np.int64)
    all_turns, all_shifts = packing.moves()
    turns, shift = all_turns[labels], all_shifts[labels]
    p = uv * (packing.scale * side)
    x, y = p[:, 0].copy(), p[:, 1].copy()
    for t in range(1, 4):                    # (x, y) -> (-y, x) per quarter turn (:func:`_turned`)
        sel = turns == t
        for _ in range(t):
            x[sel], y[sel] = -y[sel], x[sel].copy()
    return (np.stack([x, y], axis=1) + shift) / side
