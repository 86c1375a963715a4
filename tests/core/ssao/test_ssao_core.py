"""SSAO methods on analytic G-buffers (numpy ray casting), against closed forms (no bpy)."""
import numpy as np
import pytest

from addon.core.ssao import blur as ssao_blur
from addon.core.ssao import gbuffer
from addon.core.ssao import methods as ssao_methods
from addon.core.ssao import metrics as ssao_metrics
from addon.core.errors import InputError

from tests.core.ssao.test_ssao_synthetic import corner, corner_k_a, floor_only


@pytest.fixture(scope="module")
def plane():
    return floor_only(64)


@pytest.fixture(scope="module")
def room():
    gb, world, pid = corner(80)
    return gb, corner_k_a(world, pid, 1.0)


def test_flat_plane_hemisphere_and_gtao_read_open_sphere_kernel_half(plane):
    gb, _, _ = plane
    assert 0.05 < 1 - gb.mask.mean() < 0.5              # some sky in the frame
    for method in ("hemisphere", "gtao"):
        k = ssao_methods.run_method(method, gb, 1.0, 16)[0][gb.mask]
        assert k.mean() >= 0.98, method
        assert np.percentile(k, 1) >= 0.98, method
    # sphere kernel: half of the ball lies under the plane (seed 003) -> about 0.5; radius small
    # so that the ball of most pixels projects inside the frame (off-screen samples count as open)
    k = ssao_methods.crytek(gb, 0.1, 64)
    inner = gb.mask.copy()
    inner[:, :6] = inner[:, -6:] = inner[-6:, :] = False
    n = inner.sum() * 64
    assert abs(k[inner].mean() - 0.5) < 0.02 + 4 * 0.5 / np.sqrt(n)
    # seed 000's AO = 1 - (1/|S|) sum V is the occluded fraction: the complement
    assert abs((1 - k[inner]).mean() - 0.5) < 0.03


def test_corner_gtao_beats_hemisphere_beats_sphere_kernel(room):
    gb, ref = room
    rmse = {m: ssao_metrics.error_metrics(ssao_methods.run_method(m, gb, 1.0, 32)[0], ref, gb.mask)["rmse"]
            for m in ("gtao", "hemisphere", "crytek")}
    assert rmse["gtao"] < rmse["hemisphere"] < rmse["crytek"], rmse
    assert rmse["gtao"] < 0.08


def test_gtao_converges_to_the_closed_form_as_samples_grow(room):
    gb, ref = room
    errors = [ssao_metrics.error_metrics(ssao_methods.gtao(gb, 1.0, n), ref, gb.mask)["rmse"] for n in (4, 16, 128)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.05


@pytest.mark.parametrize("method", ssao_methods.METHODS)
def test_error_falls_as_samples_grow(room, method):
    gb, ref = room
    low = np.mean([ssao_metrics.error_metrics(ssao_methods.run_method(method, gb, 1.0, 4, seed=s)[0], ref, gb.mask)["rmse"]
                   for s in (0, 1)])
    high = ssao_metrics.error_metrics(ssao_methods.run_method(method, gb, 1.0, 64)[0], ref, gb.mask)["rmse"]
    assert high < low


def test_noise_of_the_point_methods_falls_like_one_over_root_n(plane):
    gb, _, _ = plane
    # crytek on a plane is a binomial estimate of p ~ 0.5: per-pixel std = sqrt(p(1-p)/N)
    for n in (16, 64):
        k = ssao_methods.crytek(gb, 0.1, n)[gb.mask]
        resid = k - ssao_methods.crytek(gb, 0.1, 1024, seed=7)[gb.mask]
        assert abs(resid.std() - 0.5 / np.sqrt(n)) < 0.25 * 0.5 / np.sqrt(n)


@pytest.mark.parametrize("method", ssao_methods.METHODS)
def test_sky_pixels_are_open_finite_and_excluded(plane, method):
    gb, _, _ = plane
    k = ssao_methods.run_method(method, gb, 1.0, 8, blur=True)[0]
    assert np.isfinite(k).all()
    assert (k[~gb.mask] == 1.0).all()
    ref = np.where(gb.mask, 1.0, np.nan)         # garbage on sky must not reach the metrics
    e = ssao_metrics.error_metrics(k, ref, gb.mask)
    assert np.isfinite([e["rmse"], e["bias"], e["mean"]]).all()
    assert e["pixels"] == gb.mask.sum()


def test_bad_input_is_a_clear_error(plane):
    gb, _, _ = plane
    with pytest.raises(InputError, match="unknown SSAO method 'ssdo'"):
        ssao_methods.run_method("ssdo", gb, 1.0, 8)
    for radius in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match="radius"):
            ssao_methods.run_method("gtao", gb, radius, 8)
    for samples in (0, -4, 2.5):
        with pytest.raises(InputError, match="samples"):
            ssao_methods.run_method("hemisphere", gb, 1.0, samples)


def test_gtao_inner_integral_matches_quadrature():
    for h, g in [(1.2, 0.3), (-0.7, 0.3), (0.4, -0.9), (np.pi / 2, 0.0)]:
        phi = np.linspace(0, h, 20001)
        f = np.cos(phi - g) * np.abs(np.sin(phi))
        trapezoid = getattr(np, "trapezoid", None) or np.trapz      # NumPy 2 renamed trapz (removed in 2.4)
        num = trapezoid(f, phi) * np.sign(h)          # ∫_0^h for h > 0, ∫_h^0 for h < 0
        assert abs(ssao_methods.gtao_inner(h, g) - num) < 1e-6
    # open hemisphere, normal facing the viewer: â(-π/2) + â(π/2) = 1
    assert abs(ssao_methods.gtao_inner(-np.pi / 2, 0.0) + ssao_methods.gtao_inner(np.pi / 2, 0.0) - 1.0) < 1e-12


def test_depth_aware_blur_keeps_constants_and_does_not_bleed_across_depth(plane):
    gb, _, _ = plane
    k = np.where(gb.mask, 0.7, 1.0).astype(np.float32)
    np.testing.assert_allclose(ssao_blur.depth_aware_blur(gb, k)[gb.mask], 0.7, atol=1e-6)
    # two depth layers: rows of the far half 10x deeper; a value step along the depth step stays sharp
    gb2 = gbuffer.GBuffer(gb.position, gb.normal, gb.depth.copy(), gb.mask, gb.proj)
    gb2.depth[:40] *= 10.0
    k2 = np.where(np.arange(64)[:, None] < 40, 0.2, 0.9) * np.ones((1, 64))
    out = ssao_blur.depth_aware_blur(gb2, k2.astype(np.float32))
    np.testing.assert_allclose(out[gb.mask & (np.arange(64)[:, None] < 40)], 0.2, atol=1e-4)
    np.testing.assert_allclose(out[gb.mask & (np.arange(64)[:, None] >= 40)], 0.9, atol=1e-4)


def test_metrics_and_reference_noise():
    k = np.array([[1.0, 0.5], [0.25, 9.0]])
    ref = np.array([[0.5, 0.5], [0.5, np.nan]])
    mask = np.array([[True, True], [True, False]])
    e = ssao_metrics.error_metrics(k, ref, mask)
    assert e["rmse"] == pytest.approx(np.sqrt((0.25 + 0 + 0.0625) / 3))
    assert e["bias"] == pytest.approx((0.5 + 0 - 0.25) / 3)
    assert e["mean"] == pytest.approx(1.75 / 3)
    assert ssao_metrics.reference_noise(ref, 100, mask) == pytest.approx(0.05)   # sqrt(0.25/100)


def test_sub_pixel_depth_reconstructs_planes_exactly(plane):
    gb, world, _ = plane
    # a point on the floor between pixel centres: its depth from the buffer equals its own depth
    ys, xs = np.nonzero(gb.mask)
    i = len(ys) // 2
    p = 0.5 * (gb.position[ys[i], xs[i]] + gb.position[ys[i] + 1, xs[i] + 1])
    x, y, _ = gbuffer.view_to_pixels(p[None], gb.proj, gb.width, gb.height)
    d, on = gbuffer.depth_at(gb, x, y)
    assert on[0] and abs(d[0] + p[2]) < 1e-4 * abs(p[2])
