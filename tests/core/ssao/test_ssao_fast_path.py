"""The fast SSAO path (issue 14) against the implementation it replaced (tests/core/ssao/seed_ssao.py).

The restructuring keeps every floating-point operation and its order (coordinate planes instead of
(..., 3) stacks, flat gathers, other chunk sizes, random numbers drawn in the same blocks), so k_A
must agree to float32 rounding: within 1e-6, where one flipped depth test would move a pixel by 1/N.
G-buffers: non-square perspective frames with a lens shift, curved surfaces, a depth step and sky,
and an orthographic one; compute chunks of the default size and of an odd small size.
"""
import numpy as np
import pytest

from addon.core.camera import SKY_DEPTH, pixels_to_ndc
from addon.core.ssao import blur as ssao_blur
from addon.core.ssao import gbuffer
from addon.core.ssao import methods as ssao_methods

from tests.core.ssao import seed_ssao
from tests.core.ssao.test_ssao_synthetic import corner

ATOL = 1e-6


def bumpy(width=56, height=40, orthographic=False):
    """A wavy surface with a raised block (a depth step) and a sky corner, seen by a camera whose
    projection has a lens shift; positions on the pixel rays, normals from the positions' gradient."""
    if orthographic:
        proj = np.array([[0.3, 0, 0, 0.05], [0, 0.3 * width / height, 0, -0.02],
                         [0, 0, -0.01, -1.0], [0, 0, 0, 1.0]])
    else:
        f = 2.0 * 50.0 / 36.0
        proj = np.array([[f, 0, 0.08, 0], [0, f * width / height, -0.05, 0],
                         [0, 0, -1.001, -0.1], [0, 0, -1.0, 0]])
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    depth = 4.0 + 0.6 * np.sin(xs / 5.0) * np.cos(ys / 7.0) + 0.02 * xs
    block = (xs > 0.55 * width) & (xs < 0.8 * width) & (ys > 0.3 * height) & (ys < 0.7 * height)
    depth[block] -= 1.2
    mask = ~((xs < 0.2 * width) & (ys < 0.25 * height))
    ndc_x, ndc_y = pixels_to_ndc(xs, ys, width, height)
    if orthographic:
        pos = np.stack([(ndc_x - proj[0, 3]) / proj[0, 0], (ndc_y - proj[1, 3]) / proj[1, 1], -depth], -1)
    else:
        pos = np.stack([depth * (ndc_x + proj[0, 2]) / proj[0, 0], depth * (ndc_y + proj[1, 2]) / proj[1, 1],
                        -depth], -1)
    nrm = np.cross(np.gradient(pos, axis=1), np.gradient(pos, axis=0))
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    view = -pos if not orthographic else np.array([0.0, 0.0, 1.0])
    nrm = np.where((np.sum(nrm * view, -1) < 0)[..., None], -nrm, nrm)
    pos, nrm = pos.astype(np.float32), nrm.astype(np.float32)
    pos[~mask] = nrm[~mask] = 0.0
    return gbuffer.GBuffer(pos, nrm, np.where(mask, depth, SKY_DEPTH).astype(np.float32), mask, proj)


@pytest.fixture(scope="module")
def frames():
    return {"bumpy": bumpy(), "orthographic": bumpy(48, 36, orthographic=True), "corner": corner(40)[0]}


CASES = [("crytek", {}), ("crytek", {"range_check": True}),
         ("hemisphere", {}), ("hemisphere", {"range_check": False, "bias": 0.01}),
         ("hbao", {}), ("hbao", {"attenuation": False, "slices": 3, "steps": 5}),
         ("gtao", {}), ("gtao", {"normalise": False, "slices": 4, "steps": 2})]


@pytest.mark.parametrize("chunk", [ssao_methods.CHUNK, 777])
@pytest.mark.parametrize("method, params", CASES)
def test_fast_methods_reproduce_the_seed_implementation(frames, method, params, chunk, monkeypatch):
    monkeypatch.setattr(ssao_methods, "CHUNK", chunk)
    fast = ssao_methods.check_method(method)
    for name, gb in frames.items():
        for radius, samples, seed in ((0.7, 16, 0), (2.5, 5, 3), (0.7, 1, 1)):
            new = fast(gb, radius, samples, seed=seed, **params)
            old = seed_ssao.FUNCS[method](gb, radius, samples, seed=seed, **params)
            assert new.dtype == np.float32 and new.shape == gb.depth.shape
            np.testing.assert_allclose(new, old, rtol=0, atol=ATOL, err_msg=f"{method} {params} on {name}, "
                                       f"r={radius}, {samples} samples, chunk {chunk}")
            assert (new[~gb.mask] == 1.0).all()


@pytest.mark.parametrize("method", ssao_methods.METHODS)
def test_fast_methods_reproduce_the_seed_across_random_number_blocks(frames, method):
    gb = frames["bumpy"]
    samples = 2 * ssao_methods.RNG_BLOCK // int(gb.mask.sum()) + 3     # more than two blocks of draws
    new = ssao_methods.check_method(method)(gb, 1.0, samples, seed=5)
    old = seed_ssao.FUNCS[method](gb, 1.0, samples, seed=5)
    np.testing.assert_allclose(new, old, rtol=0, atol=ATOL)


def test_blur_reproduces_the_seed_blur(frames):
    rng = np.random.default_rng(2)
    for name, gb in frames.items():
        k = np.where(gb.mask, rng.random(gb.depth.shape), 1.0).astype(np.float32)
        for params in ({}, {"size": 1, "depth_sigma": 0.2, "normal_power": 3.0}, {"normal_power": 2.5}):
            new = ssao_blur.depth_aware_blur(gb, k, **params)
            old = seed_ssao.depth_aware_blur(gb, k, **params)
            np.testing.assert_allclose(new, old, rtol=0, atol=ATOL, err_msg=f"{name} {params}")
    # the curved frame's normals differ between neighbours: the normal weight is exercised
    gb = frames["bumpy"]
    cos = np.sum(gb.normal[:, 1:] * gb.normal[:, :-1], -1)[gb.mask[:, 1:] & gb.mask[:, :-1]]
    assert cos.min() < 0.99


def test_lookups_reproduce_the_seed_lookups(frames):
    rng = np.random.default_rng(4)
    for name, gb in frames.items():
        x = rng.uniform(-3.0, gb.width + 2.0, (300, 7)).astype(np.float32)
        y = rng.uniform(-3.0, gb.height + 2.0, (300, 7)).astype(np.float32)
        d, on = gbuffer.depth_at(gb, x, y)
        d_old, on_old = seed_ssao.depth_at(gb, x, y)
        assert (~on).any() and on.any()
        np.testing.assert_array_equal(on, on_old)
        np.testing.assert_allclose(d, d_old, rtol=1e-6, err_msg=name)
        p, valid = gbuffer.position_at(gb, x, y)
        p_old, valid_old = seed_ssao.position_at(gb, x, y)
        np.testing.assert_array_equal(valid, valid_old)
        np.testing.assert_allclose(p[valid], p_old[valid], rtol=1e-6, err_msg=name)
        pts = rng.normal(0.0, 2.0, (50, 3)).astype(np.float32) - [0.0, 0.0, 4.0]
        for a, b in zip(gbuffer.view_to_pixels(pts, gb.proj, gb.width, gb.height),
                        seed_ssao.view_to_pixels(pts, gb.proj, gb.width, gb.height)):
            np.testing.assert_array_equal(a, b)


def test_the_largest_radius_the_options_take_gives_finite_ao(frames):
    """24.12: radius 1e300 wrote NaN images; at the options' maximum every method stays finite and in [0, 1]."""
    from addon.lab.options import MAX_SSAO_RADIUS
    for name, gb in frames.items():
        for method in ssao_methods.METHODS:
            k = ssao_methods.check_method(method)(gb, MAX_SSAO_RADIUS, 4, seed=0)
            assert np.isfinite(k).all() and k.min() >= 0.0 and k.max() <= 1.0, (method, name)


@pytest.mark.parametrize("method", ["hbao", "gtao"])
def test_numpy_scalar_parameters_give_the_python_scalar_image(frames, method):
    """A radius, slice or step count that is a NumPy scalar (a sweep's np.float64, np.int64) gives the same
    image as the Python number: under NEP 50 (NumPy 2) it would otherwise turn the float32 planes float64."""
    fast = ssao_methods.check_method(method)
    for gb in frames.values():
        plain = fast(gb, 0.7, 16, seed=2, slices=3, steps=2)
        typed = fast(gb, np.float64(0.7), 16, seed=2, slices=np.int64(3), steps=np.int64(2))
        assert np.array_equal(plain, typed)
