"""Light-map maths without bpy: closed forms against each other, dilation, coverage, Monte Carlo error."""
import math

import numpy as np
import pytest

from addon.core import lightmap as lm


def _square(cx, cy, z, a, b):
    return np.array([(cx - a / 2, cy - b / 2, z), (cx + a / 2, cy - b / 2, z),
                     (cx + a / 2, cy + b / 2, z), (cx - a / 2, cy + b / 2, z)])


@pytest.mark.parametrize("a,b,c", [(1.0, 1.0, 1.0), (2.0, 0.5, 0.7), (10.0, 3.0, 0.2)])
def test_howell_b3_corner_matches_lambert_polygon(a, b, c):
    poly = np.array([(0, 0, c), (a, 0, c), (a, b, c), (0, b, c)])
    assert lm.view_factor_rect_corner(a, b, c) == pytest.approx(lm.view_factor_polygon((0, 0, 0), (0, 0, 1), poly),
                                                                rel=1e-9)


def test_centred_rectangle_and_limits():
    assert lm.view_factor_rect_centered(2.0, 2.0, 1.0) == pytest.approx(
        lm.view_factor_polygon((0, 0, 0), (0, 0, 1), _square(0, 0, 1, 2, 2)), rel=1e-9)
    assert lm.view_factor_rect_centered(1e5, 1e5, 1.0) == pytest.approx(1.0, abs=1e-4)   # infinite ceiling
    # a 1 x 1 square at height 1, by hand: 4 corners with X = Y = 0.5,
    # F = 4 · (1/2π) · 2 · (0.5/√1.25) atan(0.5/√1.25) = 0.23945
    assert lm.view_factor_rect_centered(1.0, 1.0, 1.0) == pytest.approx(0.2395, abs=2e-4)


def test_disk_matches_polygon_of_many_sides():
    k = 720
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    poly = np.stack([0.8 * np.cos(t), 0.8 * np.sin(t), np.full(k, 0.5)], axis=1)
    assert lm.view_factor_polygon((0, 0, 0), (0, 0, 1), poly) == pytest.approx(lm.view_factor_disk(0.8, 0.5), rel=1e-4)


def test_long_wall_formula_matches_polygon_and_limits():
    d, h, half = 0.3, 1.2, 1e4
    wall = np.array([(-half, d, 0), (half, d, 0), (half, d, h), (-half, d, h)])
    assert lm.view_factor_polygon((0, 0, 0), (0, 0, 1), wall) == pytest.approx(lm.view_factor_long_wall(d, h), rel=1e-6)
    assert lm.view_factor_long_wall(1e-9, 1.0) == pytest.approx(0.5)
    assert lm.view_factor_long_wall(1.0, 1e-9) == pytest.approx(0.0, abs=1e-9)


def test_convex_box_counts_only_faces_toward_the_point():
    # a unit cube far above: only its bottom face is seen -> same as that square
    lo, hi = np.array([-0.5, -0.5, 2.0]), np.array([0.5, 0.5, 3.0])
    faces = _box_faces(lo, hi)
    bottom = _square(0, 0, 2.0, 1, 1)
    assert lm.view_factor_convex((0, 0, 0), (0, 0, 1), faces) == pytest.approx(
        lm.view_factor_polygon((0, 0, 0), (0, 0, 1), bottom), rel=1e-9)


def test_convex_view_factor_of_many_points_matches_one_point_at_a_time():
    # a box standing on the floor: points beside it see one to three faces, points under it none of
    # them from the right side; every point must give what the one-point formula gives
    faces = _box_faces(np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 1.0]))
    g = np.linspace(-3.0, 3.0, 25)
    pts = np.array([(x, y, 0.0) for y in g for x in g])
    one = np.array([lm.view_factor_convex(p, (0, 0, 1), faces) for p in pts])
    many = lm.view_factors_convex(pts, (0, 0, 1), faces)
    assert one.max() > 0.1 and (one == 0).any()
    np.testing.assert_allclose(many, one, rtol=0, atol=1e-15)


def _box_faces(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = lambda x, y, z: (x, y, z)  # noqa: E731
    return [np.array(f) for f in (
        [v(x0, y0, z0), v(x0, y1, z0), v(x1, y1, z0), v(x1, y0, z0)],   # bottom (-z)
        [v(x0, y0, z1), v(x1, y0, z1), v(x1, y1, z1), v(x0, y1, z1)],   # top (+z)
        [v(x0, y0, z0), v(x1, y0, z0), v(x1, y0, z1), v(x0, y0, z1)],   # -y
        [v(x0, y1, z0), v(x0, y1, z1), v(x1, y1, z1), v(x1, y1, z0)],   # +y
        [v(x0, y0, z0), v(x0, y0, z1), v(x0, y1, z1), v(x0, y1, z0)],   # -x
        [v(x1, y0, z0), v(x1, y1, z0), v(x1, y1, z1), v(x1, y0, z1)])]  # +x


def test_sphere_view_factor_matches_polygon_of_its_silhouette_for_a_far_sphere():
    # a sphere straight above subtends the same cone as a disk of radius R at height √(D² - R²)
    R, D = 0.3, 2.0
    assert lm.view_factor_sphere(D, 1.0, R) == pytest.approx(lm.view_factor_disk(R, math.sqrt(D * D - R * R)),
                                                             rel=1e-9)


def test_irradiance_closed_forms():
    assert lm.irradiance_uniform_sky(0.7) == pytest.approx(math.pi * 0.7)
    assert lm.irradiance_sun(3.0, math.radians(60)) == pytest.approx(1.5)
    assert lm.irradiance_point(100.0, 2.0, 1.0) == pytest.approx(100 / (16 * math.pi))
    series = math.pi * 0.5 * sum(0.6 ** k for k in range(4))
    assert lm.irradiance_enclosure(0.5, 0.6, 3) == pytest.approx(series)
    assert lm.irradiance_enclosure(0.5, 0.6, 10_000) == pytest.approx(math.pi * 0.5 / 0.4)


def test_resolution_for_density():
    # 4 m² covering a quarter of the UV square at 10 texels/m: N² / 4 = 100 · 4
    assert lm.resolution_for_density(4.0, 0.25, 10.0) == 40
    assert lm.resolution_for_density(4.0, 0.25, 1000.0, cap=512) == 512
    assert lm.resolution_for_density(16.0, 0.25, 10.0) == 2 * lm.resolution_for_density(4.0, 0.25, 10.0)


def test_coverage_mask_of_a_triangle_and_its_area():
    tri = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    m = lm.coverage_mask(tri, 64, 64)
    assert abs(m.mean() - 0.5) < 64 / 64 ** 2 + 1e-9
    assert m[0, 0] and not m[63, 63]
    assert lm.uv_area(tri) == pytest.approx(0.5)


def test_dilation_grows_by_margin_and_keeps_covered_texels():
    v = np.zeros((20, 20), np.float32)
    m = np.zeros((20, 20), bool)
    m[5:15, 5:15] = True
    v[m] = np.arange(100, dtype=np.float32)
    out, grown = lm.dilate(v, m, 2)
    assert np.array_equal(out[m], v[m])
    assert grown[3:17, 3:17].all() and not grown[2, 10] and not grown[10, 17]
    assert out[3, 10] in v[5, 8:13] and out[10, 16] in v[8:13, 14]   # a nearest border value, no black
    # a bilinear lookup straddling the chart border reads the border value, not black
    uv = np.array([[10.5 / 20, 15.0 / 20]])
    assert v[14, 8:13].min() <= lm.bilinear(out, uv)[0] <= v[14, 8:13].max()
    assert lm.bilinear(np.where(m, v, 0), uv)[0] == pytest.approx(v[14, 10] / 2)   # undilated: half black


@pytest.mark.parametrize("max_distance", [None, 3, 0.5])
def test_nearest_fill_matches_brute_force_chessboard_search(max_distance):
    rng = np.random.default_rng(7)
    h, w = 23, 31
    m = rng.random((h, w)) < 0.04
    m[0, 0] = True
    v = rng.random((h, w, 3)).astype(np.float32)
    out, filled = lm.nearest_fill(v, m, max_distance)
    ys, xs = np.nonzero(m)
    yy, xx = np.mgrid[0:h, 0:w]
    d = np.maximum(np.abs(yy[..., None] - ys), np.abs(xx[..., None] - xs))    # (H, W, covered)
    dmin = d.min(axis=2)
    reach = np.inf if max_distance is None else max_distance
    assert np.array_equal(filled, dmin <= reach)
    assert dmin.max() > 3 and (dmin == 3).any()                       # the limit really cuts
    assert np.array_equal(out[m], v[m]) and np.array_equal(out[~filled], v[~filled])
    for y, x in zip(*np.nonzero(filled & ~m)):
        nearest = d[y, x] == dmin[y, x]                               # every tie is allowed
        assert any(np.array_equal(out[y, x], v[ys[k], xs[k]]) for k in np.flatnonzero(nearest)), (y, x)
    src = lm.nearest_covered(m, max_distance)
    sy, sx = np.divmod(src[filled], w)
    assert np.array_equal(np.maximum(np.abs(sy - yy[filled]), np.abs(sx - xx[filled])), dmin[filled])
    assert np.all(src[~filled] == -1)


def test_bilinear_reproduces_a_linear_ramp():
    x = (np.arange(16) + 0.5) / 16
    img = np.tile(3.0 * x, (8, 1))
    uv = np.array([[0.3, 0.4], [0.71, 0.9]])
    np.testing.assert_allclose(lm.bilinear(img, uv), 3.0 * uv[:, 0], rtol=1e-9)


def test_binomial_sd_matches_simulated_ao():
    rng = np.random.default_rng(1)
    k, n = 0.3, 64
    est = rng.binomial(n, k, size=20000) / n
    assert np.std(est) == pytest.approx(lm.binomial_sd(k, n), rel=0.03)
    assert lm.binomial_sd(0.5, 100) == pytest.approx(0.05)
    assert lm.per_sample_variance_ao(np.full((4, 4), 0.5), np.ones((4, 4), bool)) == pytest.approx(0.25)


def test_pair_variance_and_samples_for_error():
    rng = np.random.default_rng(2)
    sigma2, na, nb = 0.09, 16, 48
    truth = rng.uniform(0, 1, (64, 64))
    a = truth + rng.normal(0, math.sqrt(sigma2 / na), truth.shape)
    b = truth + rng.normal(0, math.sqrt(sigma2 / nb), truth.shape)
    est = lm.per_sample_variance_pair(a, b, na, nb, np.ones(truth.shape, bool))
    assert est == pytest.approx(sigma2, rel=0.05)
    comb = lm.combine([a, b], [na, nb])
    assert lm.rms(comb, truth) == pytest.approx(math.sqrt(sigma2 / (na + nb)), rel=0.05)
    # independent samples (α = 1/2): N = σ²/E², the smallest N meeting the target
    n = lm.samples_for_error(lm.expected_error(est, 1), 1, 0.01)
    assert n == math.ceil(est / 0.01 ** 2)
    assert lm.expected_error(est, n) <= 0.01 < lm.expected_error(est, n - 1)
    # a faster sampler (α = 3/4): 0.2 at 4 samples -> 0.01 needs 4 · 20^(4/3) = 217.1 -> 218 samples
    assert lm.samples_for_error(0.2, 4, 0.01, alpha=0.75) == 218
    assert lm.samples_for_error(0.2, 4, 0.01, alpha=0.75, maximum=100) == 100
    with pytest.raises(ValueError):
        lm.samples_for_error(1.0, 1, 0.0)


def test_convergence_exponent_recovers_the_rate_and_clamps():
    def err(n):
        return 0.4 * n ** -0.7
    assert lm.convergence_exponent(err(4), 4, err(64), 64) == pytest.approx(0.7)
    assert lm.convergence_exponent(err(64), 64, err(4), 4) == pytest.approx(0.7)      # order does not matter
    assert lm.convergence_exponent(0.1, 4, 0.099, 8) == 0.5                          # slower than 1/√N: 1/2
    assert lm.convergence_exponent(0.1, 4, 0.01, 8) == 1.0
    assert lm.convergence_exponent(0.1, 4, 0.0, 8) == 1.0                            # noise-free


def test_inverse_variance_combination_reaches_the_predicted_error():
    rng = np.random.default_rng(3)
    truth = rng.uniform(0, 1, (128, 128))
    sigmas = (0.2, 0.05, 0.1)
    parts = [truth + rng.normal(0, s, truth.shape) for s in sigmas]
    weights, error = lm.inverse_variance_weights(sigmas)
    assert error == pytest.approx((1 / 0.04 + 1 / 0.0025 + 1 / 0.01) ** -0.5)
    # RMS of 16384 texels: relative standard error 1/√(2·16384) = 0.55 %, 4 of them ≈ 2.2 %
    assert lm.rms(lm.combine(parts, weights), truth) == pytest.approx(error, rel=0.022)
    assert lm.rms(lm.combine(parts, [1, 1, 1]), truth) > 1.2 * error             # equal weights do worse
    assert lm.inverse_variance_weights([0.1, 0.0]) == ([0.0, 1.0], 0.0)


def _loop_counts(tri_uv, width, height, strict=False):
    """The former per-triangle loop of ``coverage_mask`` counting, per texel, the triangles whose barycentric test
    holds (the reference the vectorised rasteriser must match)."""
    counts = np.zeros((height, width), np.int32)
    t = np.asarray(tri_uv, float) * (width, height)
    eps = 1e-6 if strict else -1e-6
    for a, b, c in t:
        lo = np.floor(np.minimum(np.minimum(a, b), c) - 0.5).astype(int)
        hi = np.ceil(np.maximum(np.maximum(a, b), c) - 0.5).astype(int)
        x0, y0 = max(lo[0], 0), max(lo[1], 0)
        x1, y1 = min(hi[0], width - 1), min(hi[1], height - 1)
        if x1 < x0 or y1 < y0:
            continue
        ys, xs = np.mgrid[y0:y1 + 1, x0:x1 + 1] + 0.5
        d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if abs(d) < 1e-12:
            continue
        w1 = ((xs - a[0]) * (c[1] - a[1]) - (ys - a[1]) * (c[0] - a[0])) / d
        w2 = ((b[0] - a[0]) * (ys - a[1]) - (b[1] - a[1]) * (xs - a[0])) / d
        counts[y0:y1 + 1, x0:x1 + 1] += (w1 >= eps) & (w2 >= eps) & (w1 + w2 <= 1 - eps)
    return counts


def _loop_coverage_mask(tri_uv, width, height):
    return _loop_counts(tri_uv, width, height) > 0


def _grid_mesh_uv(n, jitter, rng):
    """UV triangles of an n × n grid of quads, vertices jittered: a chart of shared edges and texel-aligned
    corners (centres exactly on edges at jitter 0)."""
    g = np.stack(np.meshgrid(np.linspace(0.05, 0.95, n + 1), np.linspace(0.05, 0.95, n + 1)), -1)
    g = g + rng.normal(0, jitter, g.shape)
    q = np.array([[g[i, j], g[i, j + 1], g[i + 1, j + 1], g[i + 1, j]] for i in range(n) for j in range(n)])
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def test_one_rasteriser_matches_the_former_loop_on_meshes_and_random_triangles():
    rng = np.random.default_rng(7)
    cases = [_grid_mesh_uv(4, 0.0, rng), _grid_mesh_uv(7, 0.01, rng),
             np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[1.0, 1.0], [0.0, 1.0], [1.0, 0.0]]]),  # two halves
             np.array([[[0.2, 0.2], [0.2, 0.2], [0.8, 0.8]]]),                                        # no area
             np.array([[[-0.5, -0.5], [2.0, 0.1], [0.1, 2.0]]])]                                       # overhanging
    for n, spread in ((300, 0.2), (2000, 0.01), (20, 2.0)):
        cases.append(rng.random((n, 1, 2)) + rng.normal(0, spread, (n, 3, 2)))
    for tri in cases:
        for w, h in ((32, 32), (40, 8), (16, 64)):
            assert np.array_equal(lm.coverage_mask(tri, w, h), _loop_coverage_mask(tri, w, h))


def test_the_rasteriser_matches_the_loop_at_its_tolerance_on_tiny_triangles_and_slivers():
    """The candidate box is cut to 1e-5 of a triangle's extent beyond it (a texel for slivers): a centre just
    inside the 1e-6 tolerance, one just outside it, ones just outside the box, a soup of triangles far below a
    texel, and slivers on both sides of the sliver bound count as the loop counts them, interiors (strict) too."""
    rng = np.random.default_rng(11)
    side = 16
    centre = (np.array([5, 9]) + 0.5) / side
    cases = []
    for size in (1e-3, 0.05, 0.7):                          # in texels: far below a texel, under one, near one
        for beyond in (0.5e-6, 2e-6, 2e-5, 1e-4, 1e-9, 0.0, -1e-9):     # a vertex past a centre, in extents
            e = size / side
            base = np.array([[0.0, 0.0], [e, 0.0], [0.0, e]]) - beyond * e
            cases.append(centre + base)                        # the centre just outside the corner, or on it
            cases.append(centre - base * [-1, 1])
    soup = rng.random((20480, 1, 2)) + rng.normal(0, 0.004, (20480, 3, 2))
    thin = rng.random((400, 1, 2)) + np.array([0, 1, 0.5])[None, :, None] * rng.normal(0, 0.3, (400, 1, 2))
    thin[:, 2] += rng.normal(0, 1, (400, 2)) * 10.0 ** rng.uniform(-13, -2, (400, 1))   # slivers of every width
    for tri in [np.array(cases)] + [soup, thin]:
        for w, h in ((side, side), (40, 8)):
            for strict in (False, True):
                assert np.array_equal(lm.triangle_counts(tri, w, h, strict), _loop_counts(tri, w, h, strict))


def test_overlap_counts_shared_texels_not_shared_edges():
    rng = np.random.default_rng(1)
    chart = _grid_mesh_uv(4, 0.0, rng) * 0.5                      # one chart in the lower-left quarter
    assert lm.overlap_fraction(chart, 64, 64) == 0.0              # edges inside a chart are not overlaps
    # an Array copy: every texel shared except the few whose centre lies on a diagonal (a strict interior
    # test counts those for neither copy); the chart's side is 28.8 texels, its 16 diagonals ≈ 16 × 7 texels
    dup = lm.overlap_fraction(np.concatenate([chart, chart]), 64, 64)
    assert 1.0 - 16 * 8 / 28.8 ** 2 <= dup <= 1.0
    # shifted by half its width (0.225 of a 0.45 chart): shared area 0.225 × 0.45 of the union 0.675 × 0.45
    half = np.concatenate([chart, chart + (0.225, 0.0)])
    assert lm.overlap_fraction(half, 64, 64) == pytest.approx(1 / 3, abs=0.05)
    assert lm.triangle_counts(np.concatenate([chart] * 3), 64, 64, strict=True).max() == 3


def _cube(offset=0.0):
    co = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float) + offset
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return co, np.array([t for q in quads for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))])


def test_inward_shells_find_a_closed_surface_wound_inside_out():
    co, tris = _cube()
    labels, inward, vol = lm.inward_shells(co, tris)
    assert list(inward) == [False] and vol[0] == pytest.approx(1.0)            # unit cube, outward
    labels, inward, vol = lm.inward_shells(co, tris[:, ::-1])                  # every face reversed
    assert list(inward) == [True] and vol[0] == pytest.approx(-1.0)
    co2, tris2 = _cube(5.0)
    labels, inward, vol = lm.inward_shells(np.vstack([co, co2]), np.vstack([tris, tris2[:, ::-1] + 8]))
    assert list(labels) == [0] * 12 + [1] * 12 and list(inward) == [False, True]
    assert not lm.inward_shells(co, tris[:-1, ::-1])[1].any()                  # open (a face missing): no inside
    mixed = tris[:, ::-1].copy()
    mixed[0] = mixed[0, ::-1]                                                  # inconsistent winding: not judged
    assert not lm.inward_shells(co, mixed)[1].any()


def test_a_chart_window_keeps_every_texel_of_the_charts():
    """The window's map is the full map's texels inside it: the same texel centres covered, none lost."""
    rng = np.random.default_rng(5)
    side, margin = 64, 2
    tri = rng.uniform([0.1, 0.05], [0.9, 0.6], (40, 3, 2))
    lo, size = lm.chart_window(tri, side, margin)
    full = lm.coverage_mask(tri, side, side)
    cut = lm.coverage_mask(lm.to_window(tri, side, lo, size).reshape(-1, 3, 2), int(size[0]), int(size[1]))
    assert full.sum() == cut.sum() > 0
    np.testing.assert_array_equal(full[lo[1]:lo[1] + size[1], lo[0]:lo[0] + size[0]], cut)
    p = tri.reshape(-1, 2) * side                    # every chart at least the margin inside the window
    assert (p.min(0) - lo >= margin).all() and (lo + size - p.max(0) >= margin).all()
    assert size[1] < 0.7 * side


def _tilted_rectangle():
    """A 3 x 2 m rectangle tilted by 0.7 rad, as 48 triangles: (isometric UVs, 1/4 UV per metre; positions)."""
    u, v = np.meshgrid(np.linspace(0, 3, 7), np.linspace(0, 2, 5))
    quads = [((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)) for i in range(6) for j in range(4)]
    tris = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    uv2 = np.stack([u[tris[..., 1], tris[..., 0]], v[tris[..., 1], tris[..., 0]]], -1) / 4
    c, s_ = math.cos(0.7), math.sin(0.7)
    return uv2, np.stack([uv2[..., 0] * 4, uv2[..., 1] * 4 * c, uv2[..., 1] * 4 * s_ + 1.0], -1)


def test_texel_aspect_of_a_stretched_layout_is_its_stretch():
    """A tilted 3 x 2 m rectangle mapped isometrically (1/4 UV per metre) has square texels on a square map
    (aspect 1); its UVs scaled by (s/w, s/h), as :func:`to_window` does, give h / w."""
    uv2, world = _tilted_rectangle()
    assert lm.texel_aspect(uv2, world) == pytest.approx(1.0, abs=1e-9)
    w, h, side = 40, 28, 40
    assert lm.texel_aspect(uv2 * [side / w, side / h], world) == pytest.approx(h / w, rel=1e-9)


def test_texel_anisotropy_is_the_stretch_whatever_its_direction():
    """The tilted 3 x 2 m rectangle of the test above, mapped isometrically: anisotropy 1; its UVs scaled 4 along u,
    or half of its triangles scaled 4 along u and the other half 4 along v: 4 (texel_aspect, which reads the
    direction too, gives 4 and, for the mix, whichever half its median falls in)."""
    uv2, world = _tilted_rectangle()
    assert lm.texel_anisotropy(uv2, world) == pytest.approx(1.0, abs=1e-9)
    assert lm.texel_anisotropy(uv2 * [4, 1], world) == pytest.approx(4.0, rel=1e-9)
    mixed = uv2.copy()
    mixed[::2] *= [4, 1]
    mixed[1::2] *= [1, 4]
    assert lm.texel_anisotropy(mixed, world) == pytest.approx(4.0, rel=1e-9)


def test_density_spread_is_the_low_quantile_density_over_the_median():
    """Three unit squares side by side on the surface, laid out at UV scales 1, 1 and 1/2 (densities 1, 1, 0.5 in
    UV length per metre): the lowest tenth of the area has density 0.5, the median 1; a uniform layout gives 1."""
    def square(x, scale):
        quad = np.array([[x, 0], [x + 1, 0], [x + 1, 1], [x, 1]], float)
        world = np.c_[quad, np.zeros(4)]
        uv = quad * scale
        idx = [[0, 1, 2], [0, 2, 3]]
        return uv[idx], world[idx]
    parts = [square(0, 1.0), square(1, 1.0), square(2, 0.5)]
    uv = np.concatenate([p[0] for p in parts])
    world = np.concatenate([p[1] for p in parts])
    assert lm.density_spread(uv, world) == pytest.approx(0.5)
    assert lm.density_spread(world[..., :2] * 0.1, world) == pytest.approx(1.0)


def _grid_chart(n=8):
    """An n × n grid of quads on the unit UV square as corner arrays: (uv (N, 2), triangles (T, 3 corners))."""
    uv, tri = [], []
    for y in range(n):
        for x in range(n):
            k = len(uv)
            uv += [(x / n, y / n), ((x + 1) / n, y / n), ((x + 1) / n, (y + 1) / n), (x / n, (y + 1) / n)]
            tri += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    return np.array(uv), np.array(tri)


def test_isotropic_charts_are_made_of_square_texels_of_a_metre_each():
    """A grid on the unit UV square laid over a 4 m × 1 m wall (x = 4u, z = v) becomes a 4 × 1 rectangle: one UV
    unit a metre in both directions (texel anisotropy 1, extents 4 and 1); a second chart over the same wall sheared
    and turned in UV (a linear map) becomes the same rectangle up to a turn; each chart on its own."""
    uv, tri = _grid_chart()
    co = np.stack([4 * uv[:, 0], np.zeros(len(uv)), uv[:, 1]], axis=1)
    a = np.array([[0.3, 0.8], [-0.5, 0.1]])                     # shear and turn: a linear map of the second chart
    uv2 = uv @ a.T
    both = np.concatenate([uv, uv2])
    tris = np.concatenate([tri, tri + len(uv)])
    chart = np.repeat([0, 1], len(uv))
    out = lm.isotropic(both, tris, chart, np.concatenate([co, co]))
    for k in (0, 1):
        t = out[tris[chart[tris[:, 0]] == k]]
        w = np.concatenate([co, co])[tris[chart[tris[:, 0]] == k]]
        assert lm.texel_anisotropy(t, w) == pytest.approx(1.0, abs=1e-9)
        assert lm.uv_area(t) == pytest.approx(4.0, rel=1e-9)     # a UV unit is a metre: the wall's 4 m²
    assert np.ptp(out[:len(uv)], axis=0) == pytest.approx([4.0, 1.0])


def test_the_density_floor_is_the_least_triangle_density_over_the_median():
    """A uniform grid's floor is 1; one triangle's UVs shrunk k times about its centre (area k², density k) leaves
    the area-weighted median where it was and brings the floor to k."""
    uv, tri = _grid_chart()
    co = np.stack([uv[:, 0], uv[:, 1], np.zeros(len(uv))], axis=1)
    assert lm.density_floor(uv[tri], co[tri]) == pytest.approx(1.0)
    t = uv[tri].copy()
    c = t[5].mean(axis=0)
    t[5] = c + 0.1 * (t[5] - c)
    assert lm.density_floor(t, co[tri]) == pytest.approx(0.1)


@pytest.fixture
def by_rows(monkeypatch):
    """The number of triangles lm._texels_by_rows is given, as the rasteriser runs."""
    taken = [0]
    rows = lm._texels_by_rows

    def spy(idx, *args):
        taken[0] += len(idx)
        yield from rows(idx, *args)

    monkeypatch.setattr(lm, "_texels_by_rows", spy)
    return taken


def test_wide_triangles_tested_row_by_row_match_the_loop(by_rows):
    """Triangles of which under ROW_FILL of their candidate squares, wider than ROW_BOXES texels, can be inside are
    tested by rows: a cap's fan of slivers, random triangles overhanging the map, slivers along a row or a column
    and triangles with corners on texel centres count as the loop counts them, interiors (strict) too; well-shaped
    triangles of a grid keep the squares (twice faster for them)."""
    rng = np.random.default_rng(5)
    a = np.linspace(0, 2 * np.pi, 33)
    rim = np.stack([0.5 + 0.45 * np.cos(a), 0.5 + 0.45 * np.sin(a)], 1)
    fan = np.stack([np.tile([0.5, 0.5], (32, 1)), rim[:-1], rim[1:]], 1)
    big = rng.random((40, 3, 2)) * 1.6 - 0.3
    flat = np.array([[[0.1, 0.3], [0.9, 0.3 + 1e-9], [0.5, 0.3 + 2e-7]], [[0.3, 0.1], [0.3 + 1e-9, 0.9], [0.3, 0.5]],
                     [[0.05, 0.05], [0.95, 0.95], [0.95, 0.95 + 1e-6]]])
    on_centres = (rng.integers(0, 96, (30, 3, 2)) + 0.5) / 96
    for tri in (fan, big, flat, on_centres):
        for w, h in ((96, 96), (200, 40)):
            for strict in (False, True):
                before = by_rows[0]
                assert np.array_equal(lm.triangle_counts(tri, w, h, strict), _loop_counts(tri, w, h, strict))
                assert by_rows[0] > before
    before = by_rows[0]
    grid = _grid_mesh_uv(3, 0.0, rng)
    assert np.array_equal(lm.coverage_mask(grid, 96, 96), _loop_coverage_mask(grid, 96, 96))
    assert by_rows[0] == before


def test_a_bound_of_a_nearly_horizontal_edge_is_left_to_the_box(by_rows):
    """An edge 4 ulps from horizontal whose strict line runs through the centres of row 0 (the second reader's
    case): its w2 is 1e-6 in the test's rounding all along the row while its slope is 5e-23, so a bound taken from
    that slope would drop centres the test keeps; the row is searched across the box, as the loop does."""
    tri = np.array([[[float.fromhex("0x1.04826fcbf7d92p+5"), float.fromhex("0x1.016e16f4b66a7p-1")],
                     [float.fromhex("0x1.afff522586e9fp+11"), float.fromhex("0x1.016e16f4b66abp-1")],
                     [float.fromhex("0x1.ee76ad208fd07p+10"), float.fromhex("-0x1.5d114596d7f9ep+11")]]]) / 4096
    for strict in (False, True):
        counts = lm.triangle_counts(tri, 4096, 4096, strict)
        assert np.array_equal(counts, _loop_counts(tri, 4096, 4096, strict))
    assert counts[0, 2467:2471].all() and by_rows[0] == 2
