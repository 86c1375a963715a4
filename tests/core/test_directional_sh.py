"""Directional light maps in numpy: the L1 fit, its SH convention (the project's sh9), Godot's packing, frames."""
import math

import numpy as np
import pytest

from addon.core import directional as d
from addon.core.envmap import latlong, sh9


def _fit_normals(normal):
    return [d.tilted(normal, t) for t in d.tilt_vectors()]


def test_a_linear_sky_gives_the_sh_coefficients_of_its_radiance():
    """Sky L(l) = a + b (l·z) over the whole sphere: E(n) = πa + (2π/3) b (n·z) exactly (REFERENCE.md §3). Fitted at
    the five bake normals of a tilted face, the coefficients equal sh9's projection of the sky's lat-long map, and
    E(n) reconstructs as sh9_irradiance does from them."""
    a, b = np.array([0.6, 1.0, 2.0]), np.array([0.4, -0.5, 1.5])
    normal = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    ns = _fit_normals(normal)
    e = [math.pi * a + 2 * math.pi / 3 * b * n[2] for n in ns]
    coeffs = d.coefficients(*d.fit(e, ns))
    dirs = latlong.latlong_directions(256, 512)
    env = a + b * dirs[..., 2:3]
    reference = sh9.sh9_coefficients(env)[:4]                    # L00, L1-1, L10, L11 (9, C) in sh9's order
    assert np.allclose(coeffs.reshape(4, 3), reference, rtol=2e-4, atol=2e-4)
    probe = np.random.default_rng(1).normal(size=(50, 3))
    probe /= np.linalg.norm(probe, axis=1, keepdims=True)
    padded = np.concatenate([coeffs.reshape(4, 3), np.zeros((5, 3))])
    assert np.allclose(d.irradiance(coeffs, probe), sh9.sh9_irradiance(padded, probe), rtol=1e-5)
    assert np.allclose(d.irradiance(coeffs, probe), math.pi * a + 2 * math.pi / 3 * b * probe[:, 2:3], rtol=1e-9)


def test_the_tilts_determine_the_fit_on_every_normal():
    """Σ u_k u_kᵀ = (4/3)(I - N Nᵀ): the four tilts span every tangent plane, also for normals along a world axis or
    along a tetrahedron direction (where one tilt vanishes); an exactly linear E(n) is recovered everywhere."""
    rng = np.random.default_rng(7)
    normals = np.concatenate([np.eye(3), -np.eye(3), d.TETRAHEDRON, -d.TETRAHEDRON, rng.normal(size=(200, 3))])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    ns = [d.tilted(normals, t) for t in d.tilt_vectors()]
    x = np.concatenate([np.ones((len(normals), 5, 1)), np.stack(ns, axis=1)], axis=2)
    assert np.linalg.cond(np.einsum("pki,pkj->pij", x, x)).max() < 500     # 100-220: a and b·N share cos 44°
    alpha, beta = np.array([2.0]), np.array([[0.5], [-1.0], [0.7]])
    e = [alpha + n @ beta for n in ns]
    a, b = d.fit(e, ns)
    assert np.allclose(a, alpha) and np.allclose(b, np.broadcast_to(beta, b.shape))
    for t in d.tilt_vectors()[1:]:
        angle = np.degrees(np.arccos(np.clip(np.sum(d.tilted(normals, t) * normals, axis=1), -1, 1)))
        assert angle.max() <= d.FIT_ANGLE + 1e-9
    on_axis = np.degrees(np.arccos(d.tilted(np.array([0.0, 0.0, 1.0]), d.tilt_vectors()[1])[2]))
    assert on_axis == pytest.approx(math.degrees(math.atan(math.tan(math.radians(d.FIT_ANGLE)) * math.sqrt(2 / 3))))


def test_uncovered_texels_fit_to_zero():
    zeros = [np.zeros((2, 3))] * 5
    a, b = d.fit(zeros, [np.full((2, 3), -1.0)] * 5)
    assert not a.any() and not b.any()


def test_godot_packing_reconstructs_e_over_pi():
    """Godot 4.3+: shader L0' + 4 L0' Σ (2 l1' - 1) n (l1' in [0, 1]) = E(n)/π while |L1 part| <= 4 L0' per axis;
    beyond, the clamp of the packing loses the excess."""
    rng = np.random.default_rng(3)
    coeffs = np.concatenate([rng.uniform(1, 2, (20, 3)), rng.uniform(-0.4, 0.4, (20, 9))], axis=1)
    l0, l1 = d.godot_packed(coeffs)
    n = rng.normal(size=(20, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    godot = l0 + 4 * l0 * sum((2 * l1[i] - 1) * n[:, [1, 2, 0][i]][:, None] for i in range(3))
    assert np.allclose(godot, d.irradiance(coeffs, n) / math.pi, rtol=1e-12)
    assert all(((x >= 0) & (x <= 1)).all() for x in l1)
    strong = coeffs.copy()
    strong[:, 3:6] = 10 * strong[:, :3]
    assert (d.godot_packed(strong)[1][0] == 1.0).all()


def test_y_up_frame_keeps_e():
    """x' = x, y' = z, z' = -y (Blender to glTF): E'(n') = E(n)."""
    rng = np.random.default_rng(5)
    coeffs = rng.normal(size=(10, 12))
    n = rng.normal(size=(10, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    up = np.stack([n[:, 0], n[:, 2], -n[:, 1]], axis=1)
    assert np.allclose(d.irradiance(d.to_y_up(coeffs), up), d.irradiance(coeffs, n))


def test_cycles_model_limits():
    """The model Cycles' tilted bakes follow: untilted it is the plain clipped-hemisphere E (πL for a uniform sky,
    πa + (2π/3) b for L = a + b l_z at n = z); a sun at the normal is E_s; the shadowing term is 1 overhead, 2/(1 + √(1 +
    α² tan²θ)) elsewhere (measured with bpy 5.3: sun at 20° elevation over a 60° tilt, ratio 0.6763)."""
    z = np.array([0.0, 0.0, 1.0])
    assert d.cycles_irradiance(z, sky=(1.0, 0.0)) == pytest.approx(math.pi, rel=1e-4)
    assert d.cycles_irradiance(z, sky=(0.6, 0.4)) == pytest.approx(0.6 * math.pi + 0.4 * 2 * math.pi / 3, rel=1e-4)
    assert d.cycles_irradiance(z, sun=(3.0, z)) == pytest.approx(3.0, rel=1e-3)
    assert d.chiang_shadowing(1.0, 0.5) == 1.0
    assert d.chiang_shadowing(math.sin(math.radians(20)), 0.5) == pytest.approx(0.6763, abs=2e-4)


def test_l1_model_error_of_the_verification_scene():
    """The L1 model's own error in the scene of tests/bake/test_directional.py (sky 0.6 + 0.4 l_z above the horizon,
    sun 3 W/m² at 50° elevation, Cycles' shadowing term): E(n) falls so fast with the tilt that the free linear fit
    has |b| = 36 a, which Godot's packing cannot hold; the fit kept to |b| ≤ 4a is still closer to Cycles' E(n) at
    every tilt up to 60° than the L1 projection of the incident radiance itself (what an SH-projecting baker
    stores: L00 = Y00 ∫ L, L1m = Y1 ∫ L l_m over the upper hemisphere and the sun)."""
    s = np.array(_sun_direction())
    sun = (3.0, tuple(s))
    l00 = d.Y00 * (0.6 * 2 * math.pi + 0.4 * math.pi) + 3.0 * d.Y00
    l1 = 3.0 * d.Y1 * s + np.array([0.0, 0.0, d.Y1 * (0.6 * math.pi + 0.4 * 2 * math.pi / 3)])
    z = np.array([0.0, 0.0, 1.0])
    ns = _fit_normals(z)
    a, b = d.fit([np.atleast_1d(d.cycles_irradiance(n, (0.6, 0.4), sun)) for n in ns], ns)
    assert a[0] > 0 and np.linalg.norm(b[:, 0]) <= d.RATIO * a[0] * (1 + 1e-9)
    coeffs = d.coefficients(a, b)
    phi = np.radians(np.arange(12) * 30 + 7)
    for deg in (0, 15, 30, 45, 60):
        th = math.radians(deg)
        n = np.stack([np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.full_like(phi, np.cos(th))], axis=1)
        exact = d.cycles_irradiance(n, (0.6, 0.4), sun)
        fitted = d.irradiance(coeffs, n, 1)[:, 0]
        projected = d.E0 * l00 + d.E1 * (n @ l1)
        assert np.sqrt(np.mean((fitted - exact) ** 2)) < np.sqrt(np.mean((projected - exact) ** 2)), deg


def _sun_direction():
    e, a = math.radians(50), math.radians(30)
    return (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))


@pytest.mark.parametrize("elevation", [90.0, 60.0, 40.0])
def test_a_sun_alone_gives_a_model_an_engine_can_hold(elevation):
    """A sun of E_s on a horizontal texel: E(n_k) = E_s max(0, n_k·s) at the five bake normals is exactly linear with
    a = 0 near the normal, which Godot's packing cannot hold (it divides by a). The fit keeps a ≥ 0 and |b| ≤ 4a, so
    the packing never clamps, and at the surface normal it is closer to E than the sun's own L1 projection
    E_s (E0 Y00 + E1 Y1 n·s)."""
    e_s, el = 3.0, math.radians(elevation)
    sun = np.array([math.cos(el), 0.0, math.sin(el)])
    up = np.array([0.0, 0.0, 1.0])
    ns = _fit_normals(up)
    e = [np.array([e_s * max(0.0, float(n @ sun))]) for n in ns]
    a, b = d.fit(e, ns)
    assert a[0] >= 0 and np.linalg.norm(b[:, 0]) <= d.RATIO * a[0] * (1 + 1e-9)
    coeffs = d.coefficients(np.repeat(a, 3), np.repeat(b, 3, axis=-1))
    _, l1 = d.godot_packed(d.to_y_up(coeffs))
    assert all(np.all((m > 0) & (m < 1)) for m in l1)
    fitted = float(a[0] + b[:, 0] @ up)
    projection = e_s * (d.E0 * d.Y00 + d.E1 * d.Y1 * float(up @ sun))
    truth = e_s * float(up @ sun)
    assert abs(fitted - truth) < abs(projection - truth)
