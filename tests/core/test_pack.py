"""core.pack: charts found through shared corners, placed by their texels: every chart inside the map and its
border, two charts' texels more than 2 × margin − 2 apart, the covered texels the packing claims are those a raster of the
moved layout covers, each chart moved rigidly at one scale, and more texels covered than side-by-side boxes give."""
import numpy as np

from addon.core import lightmap, pack


def _labels(tris, vert, uv):
    """pack.chart_labels of loop triangles ``tris`` (T, 3) over per-corner vertices and UVs."""
    corners = np.asarray(tris).ravel()
    return pack.chart_labels(np.repeat(np.arange(len(corners) // 3), 3), np.asarray(vert)[corners],
                             np.asarray(uv)[corners])


def _ring(n, r0, r1):
    """A flat annulus of n quads as loop-triangle corners: (tris (2n, 3) corners, corner vertices, corner UVs)."""
    a = np.linspace(0, 2 * np.pi, n + 1)[:-1]
    inner = np.stack([r0 * np.cos(a), r0 * np.sin(a)], 1)
    outer = np.stack([r1 * np.cos(a), r1 * np.sin(a)], 1)
    verts = np.concatenate([inner, outer])
    tris = []
    for i in range(n):
        j = (i + 1) % n
        tris += [(i, j, n + j), (i, n + j, n + i)]
    tris = np.array(tris)
    return tris.ravel(), verts[tris.ravel()]


def _layout():
    """Six charts in a 1 x 1 UV square: three annuli (concave: a box around one wastes its middle) and three
    right triangles, each its own chart (no vertex shared between charts)."""
    tri, vert, uv, base = [], [], [], 0
    for k, (cx, cy) in enumerate([(0.2, 0.2), (0.55, 0.2), (0.2, 0.6)]):
        v, p = _ring(16, 0.05, 0.15)
        tri.append(np.arange(len(v)).reshape(-1, 3) + base)
        vert.append(v + 1000 * k)
        uv.append(p + (cx, cy))
        base += len(v)
    for k, (x, y) in enumerate([(0.6, 0.55), (0.75, 0.55), (0.6, 0.8)]):
        tri.append(np.arange(3).reshape(1, 3) + base)
        vert.append(np.arange(3) + 5000 + 10 * k)
        uv.append(np.array([(x, y), (x + 0.12, y), (x, y + 0.12)]))
        base += 3
    return np.concatenate(tri), np.concatenate(vert), np.concatenate(uv)


def test_charts_join_through_corners_at_one_vertex_with_equal_uvs():
    tris = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    vert = np.array([0, 1, 2, 2, 1, 3, 2, 4, 5])
    uv = np.array([(0, 0), (1, 0), (0, 1), (0, 1), (1, 0), (1, 1), (0.5, 1), (0, 0), (0, 0.5)], float)
    labels = _labels(tris, vert, uv)
    assert labels[0] == labels[1] != labels[2]             # the third shares vertex 2, at another UV: a seam


def test_packed_charts_keep_their_margins_and_cover_what_the_packing_claims():
    tris, vert, uv = _layout()
    labels = _labels(tris, vert, uv)
    assert labels.max() + 1 == 6
    side, margin = 64, 2.0
    packing = pack.largest(uv[tris], labels, side, margin)
    assert packing is not None and packing.scale > 1.0
    corner_chart = np.empty(len(uv), int)
    corner_chart[tris.ravel()] = np.repeat(labels, 3)
    moved = pack.moved(uv, corner_chart, packing, side)
    t = moved[tris]
    assert t.min() >= 0 and t.max() <= 1
    f = pack.FINE
    touched = lightmap.coverage_mask(t, f * side, f * side).reshape(side, f, side, f).any(axis=(1, 3))
    border = int(np.ceil(margin)) - 1                     # the texels a chart touches keep off the border ring
    assert not (touched[:border].any() or touched[-border:].any() or touched[:, :border].any()
                or touched[:, -border:].any())
    masks = [lightmap.coverage_mask(t[labels == k], side, side) for k in range(6)]
    assert sum(int(m.sum()) for m in masks) == packing.covered == int(lightmap.coverage_mask(t, side, side).sum())
    for k, m in enumerate(masks):
        near = lightmap.nearest_covered(m, 2 * margin - 2) >= 0      # texels within 2m - 2 of chart k
        others = np.any([masks[j] for j in range(6) if j != k], axis=0)
        assert not (near & others).any(), k
    for k in range(6):                                   # rigid: each chart's edge lengths scale by one factor
        a, b = uv[tris][labels == k], t[labels == k]
        ratio = np.linalg.norm(np.diff(b, axis=1), axis=2) / np.linalg.norm(np.diff(a, axis=1), axis=2)
        assert np.allclose(ratio, packing.scale)


def test_texel_packing_covers_more_than_the_charts_boxes_side_by_side():
    tris, vert, uv = _layout()
    labels = _labels(tris, vert, uv)
    side, margin = 64, 2.0
    packing = pack.largest(uv[tris], labels, side, margin)
    before = int(lightmap.coverage_mask(uv[tris], side, side).sum())
    assert packing.covered > 1.3 * before
    assert pack.largest(uv[tris] * 40, labels, side, margin) is None     # charts larger than the map: no place


def test_charts_that_find_no_place_at_their_size_are_packed_a_little_smaller():
    """Two rectangles 0.48 x 0.96 of a 32² map side by side, 4-texel margins: at their own size their footprints
    (16 x 31 texels, 6 apart and 3 from the border) do not fit; the packing steps down (pack.SHRINK) to a scale where
    they do, keeps every chart inside the map, and grows back by bisection as far as they fit."""
    quad = np.array([(0, 0), (0.48, 0), (0.48, 0.96), (0, 0.96)])
    uv = np.concatenate([quad, quad + (0.5, 0)])
    tris = np.array([(0, 1, 2), (0, 2, 3), (4, 5, 6), (4, 6, 7)])
    labels = np.array([0, 0, 1, 1])
    side, margin = 32, 4.0
    assert pack.pack(uv[tris], labels, side, margin, 1.0) is None
    packing = pack.largest(uv[tris], labels, side, margin)
    assert packing is not None and 0.5 <= packing.scale < 1.0
    moved = pack.moved(uv[tris].reshape(-1, 2), np.repeat(labels, 3), packing, side)
    assert moved.min() >= 0 and moved.max() <= 1
    assert pack.largest(uv[tris] * 2.5, labels, side, margin) is None    # under half their size still no place


def test_a_chart_thinner_than_a_texel_keeps_its_distance():
    """A 16 x 16 texel square and a 22 x 0.25 texel strip (no texel centre, no fine-raster centre inside it) at 32²:
    the strip's outline is traced into its footprint, so its texel box keeps clear of the square's by the margin's
    spacing (2m - 2, at least 1 texel) instead of landing on it."""
    side = 32
    square = np.array([[(1, 1), (17, 1), (17, 17)], [(1, 1), (17, 17), (1, 17)]], float) / side
    strip = np.array([[(1, 22.2), (23, 22.2), (23, 22.45)], [(1, 22.2), (23, 22.45), (1, 22.45)]], float) / side
    tri = np.concatenate([square, strip])
    labels = np.array([0, 0, 1, 1])
    uv = tri.reshape(-1, 2)
    corner_chart = np.repeat(labels, 3)
    for margin in (1.0, 2.0):
        packing = pack.lowest(tri, labels, side, margin)
        t = pack.moved(uv, corner_chart, packing, side).reshape(-1, 3, 2) * side
        boxes = [(np.floor(t[labels == k].reshape(-1, 2).min(0)), np.ceil(t[labels == k].reshape(-1, 2).max(0)))
                 for k in (0, 1)]
        (lo0, hi0), (lo1, hi1) = boxes
        gap = np.maximum(lo1 - hi0, lo0 - hi1).max()              # texels between the boxes along one axis
        assert gap >= max(1, 2 * margin - 2) - 1, (margin, boxes)
        assert lo1.min() >= np.ceil(margin) - 1 - 1 and hi1.max() <= side - (np.ceil(margin) - 1) + 1


def test_the_band_search_finds_the_first_free_place_in_row_major_order():
    """pack._first_free (bands of rows, a row filter on the longest free run, shifted ORs for small footprints and
    the FFT for large ones) against the exhaustive scan of every offset, row by row, on random maps and footprints;
    a bound on the top only stops the search early, it never gives another place."""
    rng = np.random.default_rng(11)
    for trial in range(200):
        side = int(rng.integers(8, 48))
        occupied = rng.random((side, side)) < rng.uniform(0.2, 0.8)
        h, w = int(rng.integers(1, 12)), int(rng.integers(1, 12))
        foot = rng.random((h, w)) < 0.7
        foot[0, 0] = foot[-1, -1] = True
        want = None
        for y in range(side - h + 1):
            for x in range(side - w + 1):
                if not (occupied[y:y + h, x:x + w] & foot).any():
                    want = (y, x)
                    break
            if want:
                break
        runs = pack._longest_runs(~occupied)
        low = int(np.argmin(occupied.all(axis=1))) if not occupied.all() else side
        assert pack._first_free(occupied, runs, foot, low, None) == want, trial
        if want is not None:
            top = want[0] + h
            assert pack._first_free(occupied, runs, foot, low, top) == want
            assert pack._first_free(occupied, runs, foot, low, top - 1) in (None, want)   # a bound only prunes


def test_a_footprint_grows_by_chessboard_distance_and_pools_its_fine_texels():
    """pack._grown is the texels within chessboard distance r of the mask (lightmap.nearest_covered's rings), and
    pack._pooled whether a FINE x FINE block holds a fine texel, on random masks."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        h, w, r = int(rng.integers(1, 14)), int(rng.integers(1, 14)), int(rng.integers(0, 4))
        mask = rng.random((h, w)) < rng.uniform(0.02, 0.5)
        want = lightmap.nearest_covered(np.pad(mask, r), r) >= 0 if r else mask
        assert np.array_equal(pack._grown(mask, r), want)
        fine = rng.random((pack.FINE * h, pack.FINE * w)) < 0.05
        assert np.array_equal(pack._pooled(fine), fine.reshape(h, pack.FINE, w, pack.FINE).any(axis=(1, 3)))


def test_the_side_that_fills_is_the_least_at_which_a_packing_of_the_charts_covers_the_goal(monkeypatch):
    """The six charts at 24² with 2-texel margins: pack.side_that_fills names a side at which a packing of them at one
    scale covers the goal (the reference: pack.pack at 61 scales around the one at which their triangles' area is
    the goal), no less than the least such side and at most twice it (a greedy packing's fill moves by ±0.03 from one
    side to the next, so the least side is not sharper than its doubling), never above the cap; 0 when the cap is
    under that side or the work limit is passed. One strip 10 times longer than wide covers a tenth of a square at
    the most: 0, at once."""
    tris, vert, uv = _layout()
    labels = _labels(tris, vert, uv)
    t, margin, goal = uv[tris], 2.0, 0.45
    area = lightmap.uv_area(t)

    def fills(n):
        for f in np.linspace(0.85, 1.15, 61):
            got = pack.pack(t, labels, n, margin, f * np.sqrt(goal / area))
            if got is not None and got.covered >= goal * n * n:
                return True
        return False

    least = next(n for n in range(25, 400) if fills(n))
    named = pack.side_that_fills(t, labels, 24, margin, goal, 400)
    assert fills(named) and least <= named <= 2 * least, (least, named)
    for cap in (least + 3, 50, 2 * least - 1, 100):               # not 24 × 2^k
        got = pack.side_that_fills(t, labels, 24, margin, goal, cap)
        assert got == 0 or (fills(got) and least <= got <= cap), (cap, got)
    assert pack.side_that_fills(t, labels, 24, margin, goal, least - 1) == 0
    assert pack.side_that_fills(t, labels, 24, margin, goal, 400, work=6 * (least - 1)) == 0
    strip = np.array([[(0, 0), (1, 0), (1, 0.1)], [(0, 0), (1, 0.1), (0, 0.1)]])
    packed = []
    monkeypatch.setattr(pack, "pack", lambda *a: packed.append(a[2]))
    assert pack.side_that_fills(strip, np.zeros(2, np.int64), 16, margin, 0.2, 16384) == 0 and packed == []


def test_pieces_that_do_not_fit_side_by_side_are_stacked_in_the_square_they_fill():
    """Two 2 × 1 rectangles (0.6 × 0.3 of a 64² map: 38 × 19 texels each) placed at their size take the lowest
    places: the second, with no room beside the first, is turned upright next to it, an L in a 63 × 40 box they fill
    0.57 of (2-texel margins). With squares=(0.85, 0.7) they are also placed in the square their texels fill so,
    stacked in a 40 × 43 box (0.84), and that placement is kept: the same texels (same density), every chart inside
    that box."""
    rect = np.array([(0, 0), (0.6, 0), (0.6, 0.3), (0, 0.3)])
    uv = np.concatenate([rect, rect + (0, 0.4)])
    tris = np.array([(0, 1, 2), (0, 2, 3), (4, 5, 6), (4, 6, 7)])
    labels = np.array([0, 0, 1, 1])
    side, margin = 64, 2.0
    wide = pack.lowest(uv[tris], labels, side, margin)
    square = pack.lowest(uv[tris], labels, side, margin, squares=(0.85, 0.7))
    fill = lambda p: p.covered / (p.extent[0] * p.extent[1])
    assert wide.extent[0] > 50 and fill(wide) < 0.7
    assert square.covered == wide.covered and square.scale == 1.0
    assert fill(square) > 0.8 and max(square.extent) < 46
    moved = pack.moved(uv[tris].reshape(-1, 2), np.repeat(labels, 3), square, side) * side
    assert moved.min() >= 0 and np.all(moved.max(axis=0) <= square.extent)
    assert int(lightmap.coverage_mask(moved.reshape(-1, 3, 2) / side, side, side).sum()) == square.covered
