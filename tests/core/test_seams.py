"""The seam figure and the seam stitch on a synthetic two-chart layout of a known function (addon/core/seams.py)."""
import numpy as np
import pytest

from addon.core import lightmap, seams

SIDE, L, HC = 64, 20, 24          # map side, chart A's and B's length along s, their height (texels)
XA, YA = 4.3, 6.6                 # chart A: (s, y) -> (XA + s, YA + y)
XB, YB = 34.7, 8.2                # chart B, turned 90°: (s, y) -> (XB + y, YB + s - L)


def f(s, y):
    """A smooth function on the surface (s in [0, 2L], y in [0, HC]; 1 surface unit = 1 texel)."""
    return 0.5 + 0.2 * np.sin(0.05 * s + 0.3) * np.cos(0.04 * y)


G = 0.2 * 0.05 + 0.2 * 0.04       # max |∂f/∂s| + max |∂f/∂y|, per texel


def layout():
    """(tri_vertices, tri_uv in texels): two quads of the surface strip, s in [0, L] on chart A and [L, 2L] on B,
    sharing the edge s = L (vertices 1 and 2)."""
    a = lambda s, y: (XA + s, YA + y)                                     # noqa: E731
    b = lambda s, y: (XB + y, YB + s - L)                                 # noqa: E731
    sy = {0: (0, 0), 1: (L, 0), 2: (L, HC), 3: (0, HC), 5: (2 * L, 0), 6: (2 * L, HC)}
    tris = [(0, 1, 2), (0, 2, 3), (1, 5, 6), (1, 6, 2)]
    uv = [[a(*sy[v]) for v in tris[0]], [a(*sy[v]) for v in tris[1]],
          [b(*sy[v]) for v in tris[2]], [b(*sy[v]) for v in tris[3]]]
    return np.array(tris), np.array(uv, float)


def baked(offset=0.0, noise=0.0, rng=None, dilate=1, function=f):
    """(values, mask, source) of the map: f at covered texel centres, + ``offset`` on chart B, + Gaussian noise."""
    _, uv = layout()
    c = np.arange(SIDE) + 0.5
    x, y = np.meshgrid(c, c)
    ma = lightmap.coverage_mask(uv[:2] / SIDE, SIDE, SIDE)
    mb = lightmap.coverage_mask(uv[2:] / SIDE, SIDE, SIDE)
    v = np.where(ma, function(x - XA, y - YA), 0.0) + np.where(mb, function(L + y - YB, x - XB) + offset, 0.0)
    mask = ma | mb
    if noise:
        v = v + np.where(mask, rng.normal(0.0, noise, v.shape), 0.0)
    values, grown = lightmap.dilate(v, mask, dilate)
    source = lightmap.nearest_covered(mask, dilate + 1e-6)
    return np.where(grown, values, 0.0), mask, source.ravel()


def test_the_seam_edge_is_found_with_its_two_sides_matched_by_vertex():
    tris, uv = layout()
    s = seams.seam_edges(tris, uv)
    assert len(s) == 1 and s.creases == 0
    ends = {tuple(s.a[0, 0]), tuple(s.a[0, 1])}
    assert ends == {(XA + L, YA), (XA + L, YA + HC)}
    for k in range(2):          # the same vertex on both sides: (L, y) -> A (XA + L, YA + y), B (XB + y, YB)
        y = s.a[0, k, 1] - YA
        np.testing.assert_allclose(s.b[0, k], (XB + y, YB))
    # the edges inside each chart (diagonals, shared UVs) are no seams; a hard edge is a crease, not a seam
    normals = np.zeros(tris.shape + (3,))
    normals[:2, :, 2], normals[2:, :, 0] = 1.0, 1.0
    hard = seams.seam_edges(tris, uv, normals)
    assert len(hard) == 0 and hard.creases == 1
    normals[:] = (0, 0, 1)
    assert len(seams.seam_edges(tris, uv, normals)) == 1


def _seams_by_edge(tri_vertices, tri_uv, tri_normals, uv_tolerance, normal_tolerance):
    """``seams.seam_edges`` written edge by edge (the reference): {(lo, hi): (a, b, a_in, b_in)} and the creases."""
    corners = {}
    for t, tri in enumerate(tri_vertices):
        for c in range(3):
            corners.setdefault(tuple(sorted((tri[c], tri[(c + 1) % 3]))), []).append((t, c))
    unit = lambda v: v / max(np.linalg.norm(v), 1e-30)                       # noqa: E731
    out, creases = {}, 0
    for edge, ends in corners.items():
        if len(ends) != 2:
            continue
        (ti, ci), (tj, cj) = ends
        ai, aj = (ci, (ci + 1) % 3), (cj, (cj + 1) % 3)
        if tri_vertices[tj][cj] != tri_vertices[ti][ci]:
            aj = aj[::-1]
        a, b = tri_uv[ti][list(ai)], tri_uv[tj][list(aj)]
        split = np.abs(a - b).max() > uv_tolerance
        dots = [unit(tri_normals[ti][x]) @ unit(tri_normals[tj][y]) for x, y in zip(ai, aj)]
        smooth = 1.0 - min(dots) <= normal_tolerance
        creases += split and not smooth
        if split and smooth:
            out[edge] = (a, b, tri_uv[ti][(ci + 2) % 3], tri_uv[tj][(cj + 2) % 3])
    return out, creases


def test_seam_edges_are_those_found_edge_by_edge_on_a_mesh_with_flipped_and_shared_edges():
    """Every edge of two triangles, whichever way round each runs it, is a seam or not as the edge-by-edge
    reference says, with its sides matched vertex by vertex; edges of one or three triangles are none."""
    rng = np.random.default_rng(3)
    n = 12
    grid = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]], -1).reshape(-1, 4)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]], quads[:3, [0, 1, 2]]])    # 3 edges of 3
    flip = rng.random(len(tris)) < 0.5
    tris[flip] = tris[flip][:, ::-1]
    pos = np.stack([grid % (n + 1), grid // (n + 1)], -1).reshape(-1, 2) * 4.0
    uv = pos[tris] + (rng.random(len(tris)) < 0.3)[:, None, None] * rng.normal(0, 2, (len(tris), 1, 2))
    normals = np.tile([0.0, 0.0, 2.0], (len(tris), 3, 1)) + rng.normal(0, 0.05, (len(tris), 3, 3))
    got = seams.seam_edges(tris, uv, normals, 0.1, 1e-3)
    want, creases = _seams_by_edge(tris, uv, normals, 0.1, 1e-3)
    assert len(want) > 20 and creases > 0
    assert len(got.a) == len(want) and got.creases == creases
    for k, edge in enumerate(sorted(want)):
        for mine, theirs in zip((got.a[k], got.b[k], got.a_in[k], got.b_in[k]), want[edge]):
            assert np.array_equal(mine, theirs)


def test_footprint_reads_what_lightmap_bilinear_reads():
    rng = np.random.default_rng(1)
    img = rng.random((9, 7, 3))
    p = rng.random((50, 2)) * (7, 9) * 1.2 - 0.5
    i, w = seams.footprint(p, 9, 7)
    np.testing.assert_allclose(np.einsum("nk,nkc->nc", w, img.reshape(-1, 3)[i]),
                               lightmap.bilinear(img, p / (7, 9)), atol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 0.25])
def test_the_figure_is_the_offset_between_the_charts(offset):
    tris, uv = layout()
    s = seams.seam_edges(tris, uv)
    values, mask, source = baked(offset)
    fig = seams.measure(values, s, mask, source)
    assert fig.edges == 1 and fig.samples == HC
    # every texel the sampler reads at a seam point p holds f (+ offset) at a surface point within chessboard
    # distance 2 of p (covered texels within 1, their dilated copies 1 further), so each side reads f(p) within
    # 2 G and the jump is the offset within 4 G
    bound = 4 * G
    assert abs(fig.rms - offset) <= bound and fig.max <= offset + bound
    # without the dilation the sampler reads black beside the charts: a jump of the order of f itself
    raw = seams.measure(np.where(mask, values, 0.0), s, mask)
    assert raw.rms > 0.2
    # interior points 1 texel apart along the seam: |∂f/∂y| ≤ 0.008 per texel, f's second derivatives over a texel
    # add at most 2 × (0.2 (0.05² + 0.04²)) / 8 of bilinear error per point
    assert fig.interior_samples == 2 * HC - 2 or fig.interior_samples > HC
    assert fig.interior_rms <= 0.2 * 0.04 + 2 * 0.2 * (0.05 ** 2 + 0.04 ** 2) / 8


def test_the_interior_figure_of_a_linear_map_is_its_gradient_times_the_spacing():
    tris, uv = layout()
    s = seams.seam_edges(tris, uv)
    values, mask, source = baked(function=lambda s_, y: 0.1 + 0.003 * y)
    fig = seams.measure(values, s, mask, source)
    np.testing.assert_allclose(fig.interior_rms, 0.003, rtol=1e-6)     # float32 maps


def test_the_noise_factor_gives_the_jump_of_pure_noise():
    tris, uv = layout()
    s = seams.seam_edges(tris, uv)
    rng = np.random.default_rng(7)
    sigma, draws = 0.05, 40
    squares, factor = [], None
    for _ in range(draws):
        values, mask, source = baked(noise=sigma, rng=rng, function=lambda s_, y: 0.5 + 0 * s_)
        fig = seams.measure(values, s, mask, source)
        squares.append(fig.rms ** 2)
        factor = fig.noise_factor
    # E[rms²] = σ² factor² exactly (independent texel noise); a jump shares texels with at most its two
    # neighbours, so the mean of draws × HC squared Gaussians has a relative sd below √(2 · 3 / (draws HC))
    expected = (sigma * factor) ** 2
    assert abs(np.mean(squares) / expected - 1) < 4 * np.sqrt(6 / (draws * HC))
    # √(Σ c²) per sample: two four-texel averages (√½) up to two single texels (√2), whatever the dilation copies
    assert np.sqrt(0.5) <= factor <= np.sqrt(2)


def test_the_stitch_removes_a_known_jump_and_leaves_the_rest():
    tris, uv = layout()
    s = seams.seam_edges(tris, uv)
    offset = 0.25
    values, mask, source = baked(offset)
    fixed = seams.stitch(values, s)
    after = seams.measure(fixed, s, mask, source)
    before = seams.measure(values, s, mask, source)
    assert before.rms > offset - 4 * G and after.rms < 0.05 * offset
    # texels no seam point reads are untouched; those read move by at most the offset plus the interpolation bound
    changed = fixed != values
    pa, pb, _ = seams.seam_points(s, seams.STITCH_SPACING)
    read = np.zeros(SIDE * SIDE, bool)
    read[np.concatenate([seams.footprint(pa, SIDE, SIDE)[0], seams.footprint(pb, SIDE, SIDE)[0]]).ravel()] = True
    assert not changed.ravel()[~read].any()
    assert np.abs(fixed - values).max() <= offset + 4 * G
    # a map without a jump stays (nearly) as it was
    flat, mask, _ = baked(0.0, function=lambda s_, y: 0.3 + 0 * s_)
    np.testing.assert_allclose(seams.stitch(flat, s), flat, atol=1e-9)


def test_a_stitch_works_on_every_channel():
    tris, uv = layout()
    s = seams.seam_edges(tris, uv)
    v0, mask, source = baked(0.2)
    v1, _, _ = baked(-0.1)
    rgb = np.stack([v0, v1, v0 * 0 + 1.0 * (v0 != 0)], axis=-1)
    fixed = seams.stitch(rgb, s)
    fig = seams.measure(fixed, s, mask, source)
    assert fig.rms < 0.05 * 0.2 and fixed.shape == rgb.shape


def test_split_vertices_are_joined_so_an_imported_meshs_chart_borders_are_seams():
    """Two triangles of a quad whose vertices an importer duplicated along the diagonal: no shared edge until the
    coincident vertices are welded; then the diagonal is a seam when the UVs differ across it."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    tris = np.array([[0, 1, 2], [3, 4, 5]])
    uv = np.array([[[0, 0], [8, 0], [8, 8]], [[20, 0], [28, 8], [20, 8]]], float)
    assert len(seams.seam_edges(tris, uv)) == 0
    ids = seams.welded(pos)
    assert ids[0] == ids[3] and ids[2] == ids[4] and len(set(ids)) == 4
    assert len(seams.seam_edges(ids[tris], uv)) == 1
