"""Merging a layout's charts (core.merging): which neighbours are joined, and which joined layouts are kept."""
import numpy as np

from addon.core import lightmap, merging


def grid(nx, ny, skip=(), fold=0.0):
    """A grid of nx × ny unit quads (the cells in ``skip`` left out), flat or with the columns past x = 1 turned by
    ``fold`` degrees about that line, as corner arrays: (surface, co, per-face cell (x, y), corner UVs = the flat
    positions)."""
    flat = np.array([(x, y, 0.0) for y in range(ny + 1) for x in range(nx + 1)], float)
    t = np.radians(fold)
    co = np.where(flat[:, :1] > 1, np.stack([1 + (flat[:, 0] - 1) * np.cos(t), flat[:, 1],
                                            (flat[:, 0] - 1) * np.sin(t)], axis=1), flat)
    vid = lambda x, y: y * (nx + 1) + x
    cells = [(x, y) for y in range(ny) for x in range(nx) if (x, y) not in skip]
    vertex = np.array([v for x, y in cells for v in (vid(x, y), vid(x + 1, y), vid(x + 1, y + 1), vid(x, y + 1))])
    owner = np.repeat(np.arange(len(cells)), 4)
    after = vertex.reshape(-1, 4)[:, [1, 2, 3, 0]].ravel()
    base = 4 * np.arange(len(cells))[:, None]
    tri = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    surf = merging.surface(owner, vertex, after, co, tri, tri[:, 0] // 4)
    return surf, co, cells, flat[vertex, :2]


def test_a_surface_knows_each_edges_two_faces_and_length():
    surf, co, cells, _ = grid(2, 1)
    inner = (surf.edge_faces >= 0).all(axis=1)
    assert inner.sum() == 1 and sorted(surf.edge_faces[inner][0]) == [0, 1]
    assert len(surf.edge_faces) == 7 and np.allclose(surf.edge_length, 1.0)
    assert np.isclose(surf.tri_area.sum(), 2.0)


def test_the_longest_border_for_its_size_is_joined_first_and_each_chart_once():
    surf, co, cells, _ = grid(3, 2)
    # charts: 0 = the left column (2 quads), 1 = the middle-bottom quad, 2 = the middle-top quad, 3 = the right column
    labels = np.array([{0: 0, 1: 1, 2: 3}[x] if x != 1 else (1 if y == 0 else 2) for x, y in cells])
    pairs = merging.pairs(surf, labels)
    # every neighbour pair shares 1 m and its smaller chart is 1 m² (score 1): ties go by chart number
    assert pairs == [(0, 1), (2, 3)]
    assert merging.joined(labels, pairs).tolist() == [0, 0, 2, 0, 2, 2]


def test_a_join_that_would_close_a_ring_is_never_proposed():
    surf, co, cells, _ = grid(3, 3, skip={(1, 1)})
    # two C-shaped charts around the hole: they meet along two separate edges, so joined they would make a ring
    labels = np.array([0 if x == 0 or (x == 1 and y == 0) else 1 for x, y in cells])
    assert merging.pairs(surf, labels) == []
    # without the hole the same charts meet along one path: joined, a disc
    surf, co, cells, _ = grid(3, 3)
    labels = np.array([0 if x == 0 or (x == 1 and y == 0) else 1 for x, y in cells])
    assert merging.pairs(surf, labels) == [(0, 1)]


def test_charts_are_never_joined_across_a_hard_edge():
    """Two quads folded along their shared edge: joined at 60° apart (a bevel), not at 90° (a box's edge: above
    merging.CREASE, Unity's default hard angle of 88°)."""
    for fold, want in ((60.0, [(0, 1)]), (87.0, [(0, 1)]), (90.0, []), (180.0, [])):
        surf, co, cells, _ = grid(2, 1, fold=fold)
        inner = (surf.edge_faces >= 0).all(axis=1)
        assert np.isclose(surf.edge_cos[inner][0], np.cos(np.radians(fold)))
        assert merging.pairs(surf, np.array([0, 1])) == want, fold


def test_a_chart_across_a_hard_edge_is_told_from_charts_split_at_it():
    """A layout given to the bake (a mesh's own UV layer) may hold a chart across a hard edge: two quads folded
    along their shared edge in one chart cross it at 88° and more (merging.CREASE), not at 87°; split in two charts
    they never do, nor does a chart with faces on both sides of the fold whose faces along it are another chart's."""
    for fold, want in ((60.0, False), (87.0, False), (88.5, True), (90.0, True), (180.0, True)):
        surf, co, cells, _ = grid(2, 1, fold=fold)
        assert merging.crosses_crease(surf, np.array([0, 0])) is want, fold
        assert merging.crosses_crease(surf, np.array([0, 1])) is False
    surf, co, cells, _ = grid(3, 1, fold=90.0)
    assert merging.crosses_crease(surf, np.array([0, 1, 0])) is False


def test_a_flat_layout_is_kept_and_a_turned_over_folded_or_uneven_one_is_not():
    surf, co, cells, uv = grid(4, 4)
    tri = uv[surf.tri]
    assert merging.chart_ok(tri, surf.tri_area)
    assert merging.chart_ok(tri * (-1.0, 1.0), surf.tri_area)           # mirrored as a whole: kept (mirrored back)
    turned = tri.copy()
    turned[0] = turned[0][:, ::-1]                                     # one triangle mirrored: turned over
    assert not merging.chart_ok(turned, surf.tri_area)
    stretched = uv.copy()
    stretched[:, 0] = np.where(stretched[:, 0] > 2, 2 + 3 * (stretched[:, 0] - 2), stretched[:, 0])
    assert not merging.chart_ok(stretched[surf.tri], surf.tri_area)   # half the chart at 3 × the density
    folded = uv.copy()
    folded[:, 0] = np.where(folded[:, 0] > 2, 4 - folded[:, 0], folded[:, 0])
    tri_folded = folded[surf.tri]
    # the right half folded onto the left: the same area twice, its triangles turned over
    assert not merging.chart_ok(tri_folded, surf.tri_area)
    assert not merging.chart_ok(np.full_like(tri, np.nan), surf.tri_area)
    strip, _, _, flat = grid(20, 1)                    # a strip of 40 triangles round a ring of radii 3 and 3.5:
    radius = 3 + 0.5 * flat[:, 1]                      # no triangle turned over, its density as even (3 / 3.5)
    for turns, kept in ((0.9, True), (1.5, False)):    # wound 1.5 times it lies over itself
        angle = flat[:, 0] / 20 * 2 * np.pi * turns
        ring = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
        assert merging.chart_ok(ring[strip.tri], strip.tri_area) == kept, turns


def test_kept_joins_take_the_layouts_density_and_a_place_of_their_own():
    surf, co, cells, uv = grid(4, 2)
    labels = np.array([x for x, y in cells])                           # four columns of two quads
    old = uv * 0.1                                                     # the layout so far: 0.01 UV area per m²
    k = merging.density(old, surf)
    assert np.isclose(k, 0.01)
    pairs = merging.pairs(surf, labels)
    assert pairs == [(0, 1), (2, 3)]
    new = uv * 7.0                                                     # the unwrap's scale is its own
    bad = new.copy()
    right = np.isin(surf.owner, np.flatnonzero(labels >= 2))
    bad[right, 0] = np.where(bad[right, 0] > 21, 21 + 4 * (bad[right, 0] - 21), bad[right, 0])   # uneven: refused
    out, joined, cursor, kept = merging.placed(old, bad, surf, labels, pairs, k, 2.0)
    assert kept == 1 and sorted(set(joined.tolist())) == [0, 2, 3]
    left = ~right
    assert np.allclose(out[right], old[right])                         # refused: as they were
    placed = out[left]
    assert placed[:, 0].min() == 2.0 and np.isclose(placed[:, 1].min(), 2.0) and cursor > placed[:, 0].max()
    tri = out[surf.tri[np.isin(surf.tri_face, np.flatnonzero(left[::4]))]]
    assert np.isclose(lightmap.uv_areas(tri).sum(), k * 4.0)          # 4 m² at the layout's density


def _pieces(surf, uv):
    """Per face its chart after a cut (core.pack.chart_labels of the cut UVs)."""
    from addon.core import pack
    return pack.chart_labels(surf.owner, surf.vertex, uv)


def test_a_strip_k_squared_times_longer_than_wide_is_cut_into_k_pieces_that_stack_into_a_square():
    """A 4 × 1 grid of 16 × 4 quads is cut into 2 pieces of 8 × 4 quads (2 × 1: stacked, a square), a 9 × 1 one into
    3 (3 × 1), a 1.5 × 1 one (merging.LONG) into 2, or into as many pieces as asked (``pieces``), each piece moved
    rigidly (a translation along the strip, every corner of a face alike); a 1.25 × 1 strip, a square, one long face
    and a chart collapsed onto a line are left whole (None)."""
    for nx, ny, k, pieces in ((16, 4, 2, None), (18, 2, 3, None), (6, 4, 2, None), (16, 4, 4, 4), (18, 2, 3, 3)):
        surf, _, cells, uv = grid(nx, ny)
        uv = uv / ny
        out = merging.cut_long(uv, surf.owner, np.zeros(len(uv), np.int64), pieces)
        labels = _pieces(surf, out)
        assert labels.max() + 1 == k
        x = np.array([c[0] for c in cells])
        for p in range(k):
            assert set(x[labels == p]) == set(range(p * nx // k, (p + 1) * nx // k))
        shift = out - uv
        assert np.allclose(shift[:, 1], 0)
        per_face = shift[:, 0].reshape(-1, 4)
        assert np.allclose(per_face, per_face[:, :1])
        box = [np.ptp(out[np.repeat(labels, 4) == p], axis=0) for p in range(k)]
        assert np.allclose(box, (nx / (k * ny), 1.0))
    for nx, ny in ((5, 4), (4, 4)):
        surf, _, _, uv = grid(nx, ny)
        assert merging.cut_long(uv, surf.owner, np.zeros(len(uv), np.int64)) is None
    surf, _, _, uv = grid(1, 1)                                   # one long face: nothing to cut
    assert merging.cut_long(uv * (8, 1), surf.owner, np.zeros(len(uv), np.int64)) is None
    surf, _, _, uv = grid(8, 1)                                   # a chart collapsed onto a line
    line = np.stack([uv[:, 0], np.zeros(len(uv))], axis=1)
    assert merging.cut_long(line, surf.owner, np.zeros(len(uv), np.int64)) is None


def test_only_the_long_chart_of_a_layout_is_cut_whatever_its_direction():
    """Two charts: a 1 × 4 column turned 30° and a square beside it. The column (its principal axis, not its box) is
    cut in 2 at its middle row; the square keeps its UVs."""
    surf, _, cells, uv = grid(5, 4, skip=[(x, y) for y in range(4) for x in range(1, 2)])
    col = np.repeat(np.array([c[0] == 0 for c in cells]), 4)
    t = np.radians(30)
    turned = uv @ np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]])
    uv = np.where(col[:, None], turned, uv)
    out = merging.cut_long(uv, surf.owner, (~col).astype(np.int64))
    assert np.array_equal(out[~col], uv[~col])
    pieces = _pieces(surf, out)
    rows = np.array([c[1] for c in cells])
    column = np.array([c[0] == 0 for c in cells])
    assert len(set(pieces[column])) == 2
    assert set(rows[column & (pieces == pieces[column][0])]) in ({0, 1}, {2, 3})
