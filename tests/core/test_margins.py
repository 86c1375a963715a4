"""core.margins: the margin of a layout the bake did not make, measured as the unwrappers' rule defines it: the empty
texels (chessboard distance) between charts' footprints against the boxes of texels axis-aligned rectangles touch
(closed form), a chart that is one face split without shared vertices, and every layout core.pack packs with margin m
measuring at least m."""
import numpy as np
import pytest

from addon.core import margins, pack
from tests.core.test_pack import _labels, _layout


def _rect(x0, y0, x1, y1, first):
    """Two triangles of the texel-unit rectangle [x0, x1] x [y0, y1] (UVs of a 64² map) and their vertex ids."""
    p = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], float) / 64
    return p[[[0, 1, 2], [0, 2, 3]]], np.array([[0, 1, 2], [0, 2, 3]]) + first


def _layout_of(rects):
    tri, vert = zip(*(_rect(*r, 4 * i) for i, r in enumerate(rects)))
    return np.concatenate(tri), np.concatenate(vert)


def _box(r):
    """The texels a rectangle with no side on a texel line touches: floor(low) .. floor(high)."""
    return np.floor(r[:2]).astype(int), np.floor(r[2:]).astype(int)


@pytest.mark.parametrize("second, gap", [((8.25, 1.25, 12.75, 5.75), 2),      # texels 6 and 7 empty
                                         ((6.25, 1.25, 9.75, 5.75), 0),       # side by side: touching
                                         ((5.5, 1.25, 9.75, 5.75), 0),        # sharing texel column 5
                                         ((9.3, 9.3, 12.7, 12.7), 3)])        # diagonal: chessboard 4, 3 empty
def test_the_gap_is_the_empty_texels_between_the_footprints(second, gap):
    tri, vert = _layout_of([(1.25, 1.25, 5.75, 5.75), second])
    assert margins.footprint_gap(tri, vert, 64, 64, 10) == gap
    assert margins.footprint_gap(tri, vert, 64, 64, 1) == min(gap, 1)       # nothing nearer than the limit


def test_random_rectangles_against_their_texel_boxes():
    """Ten rectangles at random (sides off texel lines): the gap is the least over pairs of max(dx, dy) - 1 of their
    texel boxes (0 for boxes that meet), and half the margins of 64² become twice the texels at 128²."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        lo = rng.uniform(1, 50, (10, 2)) + 0.37
        rects = np.concatenate([lo, lo + rng.uniform(1, 6, (10, 2)) + 0.11], axis=1)
        boxes = [_box(r) for r in rects]
        want = 10
        for i in range(10):
            for j in range(i + 1, 10):
                d = np.maximum(boxes[j][0] - boxes[i][1], boxes[i][0] - boxes[j][1]).max()
                want = min(want, max(int(d) - 1, 0))
        tri, vert = _layout_of(rects)
        assert margins.footprint_gap(tri, vert, 64, 64, 10) == want


def test_one_face_split_into_triangles_that_share_no_vertex_is_one_chart_only_when_welded():
    tri, _ = _rect(1.25, 1.25, 5.75, 5.75, 0)
    assert margins.footprint_gap(tri, [[0, 1, 2], [0, 2, 3]], 64, 64, 5) == 5        # one chart: no other one
    assert margins.footprint_gap(tri, [[0, 1, 2], [3, 4, 5]], 64, 64, 5) == 0        # a soup's two faces touch


def test_the_margin_of_a_gap_is_the_largest_whose_packing_rule_it_keeps():
    assert margins.margin_from_gap(0) == 0
    for m in (0.5, 1, 1.5, 2, 3, 4.5):
        rule = pack.spacing(m)                               # footprints this many texels apart
        assert margins.margin_from_gap(rule) >= m
        assert margins.margin_from_gap(rule - 1) < m or rule == 1


@pytest.mark.parametrize("margin", [1.0, 2.0, 3.0])
def test_a_layout_packed_with_a_margin_measures_at_least_it(margin):
    tris, vert, uv = _layout()
    labels = _labels(tris, vert, uv)
    side = 64
    packing = pack.largest(uv[tris], labels, side, margin)
    corner_chart = np.empty(len(uv), int)
    corner_chart[tris.ravel()] = np.repeat(labels, 3)
    t = pack.moved(uv, corner_chart, packing, side)[tris]
    limit = pack.spacing(margin)
    gap = margins.footprint_gap(t, np.asarray(vert)[tris], side, side, 10)
    assert limit <= gap < 10
    assert margins.margin_from_gap(gap) >= margin


def test_stacked_faces_each_outlining_the_whole_map_stop_at_the_first_shared_texel():
    """3,000 faces that each cover the whole UV square (a layer reset by "Reset" in UV editing) at 4096²: their
    outlines would be 3,000 × 16,384 texels; they share a texel at once, 0, after the first chunk of points."""
    one = np.array([[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]], float)
    tri = np.tile(one, (1500, 1, 1))
    vert = np.arange(3 * len(tri)).reshape(-1, 3)
    assert margins.footprint_gap(tri, vert, 4096, 4096, 6) == 0
