"""Irradiance environment maps (seed 002) against closed forms: no bpy."""
import numpy as np
import pytest

from addon.core import analytic
from addon.core.envmap import irradiance
from addon.core.envmap import latlong
from addon.core.envmap import prefilter
from addon.core.envmap import projections
from addon.core.envmap import sh9
from addon.core.io import hdr
from addon.core.errors import InputError


def _unit(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


A, B = 1.0, 0.6   # sky L = a + b cos(theta), REFERENCE.md §3


def test_linear_sky_brute_force_within_half_percent():
    env = analytic.linear_sky(256, 512, A, B)
    n = _unit(300)
    exact = analytic.linear_sky_irradiance(n, A, B)
    assert np.max(np.abs(irradiance.irradiance_brute(env, n) / exact - 1)) < 0.005


def test_linear_sky_sh9_within_three_percent():
    env = analytic.linear_sky(512, 1024, A, B)
    n = latlong.latlong_directions(16, 32)
    exact = analytic.linear_sky_irradiance(n, A, B)
    assert np.max(np.abs(sh9.sh9_irradiance(sh9.sh9_coefficients(env), n) / exact - 1)) < 0.03
    # the linear sky lives in bands 0 and 1 only: L00 = 2 sqrt(pi) a, L10 = 2 sqrt(pi/3) b
    c = sh9.sh9_coefficients(env)[:, 0]
    assert c[0] == pytest.approx(2 * np.sqrt(np.pi) * A, rel=1e-4)
    assert c[2] == pytest.approx(2 * np.sqrt(np.pi / 3) * B, rel=1e-4)
    assert np.all(np.abs(np.delete(c, [0, 2])) < 1e-4)


def test_sh9_separable_sum_equals_supersampled_projection():
    """The separable exact-per-pixel sum equals a brute per-pixel projection of the same piecewise-constant
    map sampled 16x finer in each direction (midpoint rule, error O(1/16²))."""
    env = np.random.default_rng(1).random((16, 32, 3))
    fine = np.repeat(np.repeat(env, 16, axis=0), 16, axis=1)
    d = latlong.latlong_directions(*fine.shape[:2])
    w = latlong.latlong_row_solid_angles(*fine.shape[:2])[:, None, None]
    direct = np.einsum("hwk,hwc->kc", sh9.sh9_basis(d), fine * w)
    assert np.allclose(sh9.sh9_coefficients(env), direct, atol=2e-3)


def test_sh9_basis_is_orthonormal():
    d = latlong.latlong_directions(256, 512)
    w = latlong.latlong_row_solid_angles(256, 512)[:, None, None]
    Y = sh9.sh9_basis(d)
    gram = np.einsum("hwk,hwl->kl", Y * w, Y)
    assert np.allclose(gram, np.eye(9), atol=2e-3)


def test_sh9_close_to_brute_force_on_a_sharp_environment():
    """A bright small patch plus sky: R&H's nine terms stay within a few percent of the exact E (RMS, relative
    to the mean), and of the maximum everywhere."""
    env = analytic.linear_sky(128, 256, 0.5, 0.2)
    d = latlong.latlong_directions(128, 256)
    env += 40.0 * (d @ np.array([0.5, 0.5, 0.7071]) > 0.97)[..., None] * np.array([1.0, 0.8, 0.6])
    n = latlong.latlong_directions(32, 64)
    brute = irradiance.irradiance_brute(env, n)
    sh = sh9.irradiance_map_sh9(env, 64)
    rel_rms = np.sqrt(np.mean((sh - brute) ** 2)) / np.mean(brute)
    assert rel_rms < 0.06
    assert np.max(np.abs(sh - brute)) < 0.12 * np.max(brute)


def test_uniform_environment_gives_pi_l_everywhere():
    env = np.full((32, 64, 3), 0.7)
    n = _unit(50)
    assert np.allclose(irradiance.irradiance_brute(env, n), np.pi * 0.7, rtol=1e-3)
    assert np.allclose(sh9.sh9_irradiance(sh9.sh9_coefficients(env), n), np.pi * 0.7, rtol=1e-3)


def test_solid_angles_sum_to_four_pi():
    assert latlong.latlong_row_solid_angles(37, 74).sum() * 74 == pytest.approx(4 * np.pi)


def test_blender_equirectangular_convention():
    """Top row is straight up, the centre column looks along +X, u = 1/4 along +Y (Cycles' formula;
    checked against a Cycles render in tests/lab/test_envmap.py)."""
    u, v = latlong.direction_to_latlong_uv(np.array([[0, 0, 1.0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, -1]]))
    assert v[0] == pytest.approx(1) and v[4] == pytest.approx(0)
    assert u[1] == pytest.approx(0.5) and u[2] == pytest.approx(0.25) and u[3] == pytest.approx(0.75)
    d = latlong.latlong_directions(4, 8)
    assert np.all(d[0, :, 2] > 0.9) and np.all(d[-1, :, 2] < -0.9)
    dd = _unit(500, 3)
    assert np.allclose(latlong.latlong_uv_to_direction(*latlong.direction_to_latlong_uv(dd)), dd, atol=1e-12)


def test_prefiltered_phong_closed_form():
    env = analytic.linear_sky(128, 256, A, B)
    r = latlong.latlong_directions(16, 32)
    for n in (1, 8, 32):
        g = prefilter.prefilter_phong(env, n, width=32)
        assert np.allclose(g, analytic.linear_sky_prefiltered(r, A, B, n), rtol=3e-3), n
    # n = 1 is E/pi
    assert np.allclose(prefilter.prefilter_phong(env, 1, width=32), analytic.linear_sky_irradiance(r, A, B) / np.pi, rtol=3e-3)


def test_cube_and_sphere_maps_round_trip():
    d = _unit(2000, 5)
    f, s, t = projections.direction_to_cube(d)
    assert np.allclose(projections.cube_to_direction(f, s, t), d, atol=1e-12)
    assert np.all((s >= 0) & (s <= 1) & (t >= 0) & (t <= 1))
    assert list(projections.direction_to_cube(np.eye(3))[0]) == [0, 2, 4]
    s, t = projections.direction_to_sphere_map_uv(d)
    back, inside = projections.sphere_map_uv_to_direction(s, t)
    assert inside.all() and np.allclose(back, d, atol=1e-9)
    # the ball's centre reflects back toward the viewer on -Y
    c, _ = projections.sphere_map_uv_to_direction(0.5, 0.5)
    assert np.allclose(c, [0, -1, 0])
    # smooth environment survives lat-long -> cube -> lat-long and -> sphere -> lat-long
    env = analytic.linear_sky(64, 128, 1.0, 0.5) + 0.3 * latlong.latlong_directions(64, 128)[..., :1]
    back = projections.cube_to_latlong(projections.latlong_to_cube(env, 64), 128)
    assert np.max(np.abs(back - env)) < 0.05
    sph = projections.sphere_map_to_latlong(projections.latlong_to_sphere_map(env, 256), 128)
    rows = slice(8, 56)   # away from the pinched back direction
    keep = np.abs(latlong.latlong_directions(64, 128)[rows, :, 1] - 1) > 0.3
    assert np.max(np.abs(sph[rows][keep] - env[rows][keep])) < 0.08


def test_hdr_round_trip_flat_and_rle(tmp_path):
    rng = np.random.default_rng(2)
    img = rng.random((6, 40, 3)) * np.array([1, 10, 100])
    hdr.write_hdr(tmp_path / "a.hdr", img)
    back = hdr.read_hdr(tmp_path / "a.hdr")
    # RGBE keeps 8 mantissa bits of the pixel's largest channel
    assert np.all(np.abs(back - img) <= img.max(axis=-1, keepdims=True) / 128)
    # hand-made RLE scanlines: a run of 40 then literals
    rgbe = hdr.float_to_rgbe(img)
    body = b""
    for y in range(6):
        body += bytes([2, 2, 0, 40])
        for c in range(4):
            row = rgbe[y, :, c]
            body += bytes([40]) + row.tobytes()
    (tmp_path / "b.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 6 +X 40\n" + body)
    assert np.array_equal(hdr.read_hdr(tmp_path / "b.hdr"), hdr.rgbe_to_float(rgbe))
    runs = b""
    for y in range(6):
        runs += bytes([2, 2, 0, 40]) + b"".join(bytes([128 + 40, 100 + c]) for c in range(3)) + bytes([128 + 40, 129])
    (tmp_path / "c.hdr").write_bytes(b"#?RADIANCE\n\n-Y 6 +X 40\n" + runs)
    assert np.allclose(hdr.read_hdr(tmp_path / "c.hdr"), np.array([100, 101, 102]) * 2.0 ** (129 - 136))


def test_read_latlong_errors(tmp_path):
    with pytest.raises(InputError):
        latlong.read_latlong(tmp_path / "missing.exr")
    (tmp_path / "x.png").write_bytes(b"x")
    with pytest.raises(InputError):
        latlong.read_latlong(tmp_path / "x.png")
    (tmp_path / "bad.hdr").write_bytes(b"not a radiance file\n-Y 1 +X 2\n")
    with pytest.raises(InputError):
        latlong.read_latlong(tmp_path / "bad.hdr")
    hdr.write_hdr(tmp_path / "sq.hdr", np.ones((4, 4, 3)))
    with pytest.raises(InputError, match="twice as wide"):
        latlong.read_latlong(tmp_path / "sq.hdr")
