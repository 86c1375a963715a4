"""core.smoothing: the steps follow the two-texel radius; a wave along the normal of a plane decays as the umbrella
Laplacian's eigenvalue says while vertices keep their place on it; loose triangles (a soup) never move."""
import numpy as np

from addon.core import smoothing


def _grid(n, noise, seed=3):
    """An n x n vertex grid of unit quads in z = 0 with z noise of ``noise``: (positions, corner vertices, next)."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    z = np.random.default_rng(seed).uniform(-noise, noise, x.shape)
    co = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v = (j * n + i).ravel()
    corners = np.stack([v, v + 1, v + n + 1, v + n], 1).ravel()
    total = np.full(len(v), 4)
    return co, corners, smoothing.corner_next(np.arange(len(v)) * 4, total)


def test_steps_reach_a_radius_of_two_texels():
    assert smoothing.steps(1.0, 0.5) == 16                # (2 × 1 / 0.5)²
    assert smoothing.steps(1.0, 2.0) == 0                 # one step: not worth an unwrap
    assert smoothing.steps(1.0, 1.0) == 4
    assert smoothing.steps(1.0, 0.01) == smoothing.MAX_STEPS
    assert smoothing.steps(1.0, 0.0) == smoothing.steps(0.0, 1.0) == 0


def test_a_wave_along_the_normal_decays_as_the_umbrella_laplacian_says_and_vertices_keep_their_place():
    """z = a sin(πx) + b sin(2πx / 20) on a unit grid: each wave is an eigenvector of the umbrella Laplacian
    (mean of the 4 edge neighbours, each edge counted once per face), L z = (cos ω − 1) / 2 · z, so k steps of
    λ along the normal (z for small slopes) scale it by (1 − λ (1 − cos ω) / 2)^k: the two-edge wave by 0.5^k,
    the twenty-edge wave by 0.82 at k = 16. Checked away from the border, to 1 % of the amplitudes."""
    n, k, a, b = 48, 16, 0.05, 0.05
    co, corners, nxt = _grid(n, 0.0)
    x = co[:, 0]
    co[:, 2] = a * np.sin(np.pi * x + 0.5) + b * np.sin(2 * np.pi * x / 20)
    out = smoothing.smoothed(co, corners, nxt, k)
    gain = lambda w: (1 - smoothing.LAMBDA * (1 - np.cos(w)) / 2) ** k      # noqa: E731
    want = a * gain(np.pi) * np.sin(np.pi * x + 0.5) + b * gain(2 * np.pi / 20) * np.sin(2 * np.pi * x / 20)
    inner = ((co[:, :2] >= 12) & (co[:, :2] <= n - 13)).all(axis=1)
    np.testing.assert_allclose(out[inner, 2], want[inner], atol=0.01 * (a + b))
    assert np.abs(out[:, :2] - co[:, :2]).max() < 0.1 * np.abs(out[:, 2] - co[:, 2]).max()
    assert np.array_equal(smoothing.smoothed(co, corners, nxt, 0), co)


def test_loose_triangles_do_not_move():
    rng = np.random.default_rng(5)
    co = rng.normal(size=(30, 3))
    corners = np.arange(30)
    nxt = smoothing.corner_next(np.arange(0, 30, 3), np.full(10, 3))
    np.testing.assert_allclose(smoothing.smoothed(co, corners, nxt, 20), co, atol=1e-12)


def test_surface_area_is_the_faces_area():
    co, corners, nxt = _grid(5, 0.0)
    assert smoothing.surface_area(co * 0.5, corners, nxt, np.arange(16) * 4) == 16 * 0.25
    tri = np.array([[0, 0, 0], [2, 0, 0], [0, 0, 3]], float)
    assert np.isclose(smoothing.surface_area(tri, np.arange(3), np.array([1, 2, 0]), [0]), 3.0)


def test_a_small_mesh_is_smoothed_over_an_eighth_of_its_size_at_most():
    assert smoothing.steps(1.0, 0.5, size=12.0) == 9      # (12 / 8 / 0.5)², not (2 / 0.5)² = 16
    assert smoothing.steps(1.0, 0.5, size=20.0) == 16
    assert smoothing.steps(1.0, 0.1, size=4.0) == 0       # under 8 texels: a few texels whatever the unwrapper does
