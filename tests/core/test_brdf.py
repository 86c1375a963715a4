"""Numpy twins of the shading models against independent values (REFERENCE.md §1-2)."""
import numpy as np
import pytest

from addon.core import brdf, lights

RNG = np.random.default_rng(7)


def _unit(k):
    d = RNG.normal(size=(k, 3))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _upper(k):
    d = _unit(k)
    d[:, 2] = np.abs(d[:, 2])
    return d


N = np.array([0.0, 0.0, 1.0])
WHITE = np.ones(3)


def test_oren_nayar_sigma_zero_is_lambert_exactly():
    l, v = _unit(2000) * 3.0, _upper(2000)
    I = np.array([2.0, 1.0, 0.5])
    got = brdf.oren_nayar(N, l, v, I, albedo=(0.7, 0.5, 0.3), sigma=0.0)
    cos = np.maximum(l[:, 2] / 3.0, 0)
    expect = I * np.array([0.7, 0.5, 0.3]) * cos[:, None]
    np.testing.assert_array_equal(got, brdf.lambert(N, l, I, (0.7, 0.5, 0.3)))
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-15)


@pytest.mark.parametrize("sigma, A, B", [(0.5, 1 - 0.125 / 0.58, 0.1125 / 0.34),
                                         (0.2, 1 - 0.02 / 0.37, 0.018 / 0.13), (0.0, 1.0, 0.0)])
def test_oren_nayar_A_B(sigma, A, B):
    assert brdf.oren_nayar_A(sigma) == pytest.approx(A, abs=1e-15)
    assert brdf.oren_nayar_B(sigma) == pytest.approx(B, abs=1e-15)


def test_oren_nayar_vector_form_equals_angle_form():
    tl, tv = RNG.uniform(0, 1.5, 500), RNG.uniform(0, 1.5, 500)
    pl, pv = RNG.uniform(0, 2 * np.pi, 500), RNG.uniform(0, 2 * np.pi, 500)
    l, v = brdf.direction(tl, pl), brdf.direction(tv, pv)
    sigma = 0.6
    A, B = 1 - 0.5 * 0.36 / 0.69, 0.45 * 0.36 / 0.45
    alpha, beta = np.maximum(tl, tv), np.minimum(tl, tv)
    expect = np.cos(tl) * (A + B * np.maximum(0, np.cos(pv - pl)) * np.sin(alpha) * np.tan(beta))
    got = brdf.oren_nayar(N, l, v, WHITE, WHITE, sigma)[:, 0]
    np.testing.assert_allclose(got, expect, rtol=1e-9, atol=1e-12)


def _projected_integral(f, n_theta=4096, n_phi=8):
    d, w = brdf.hemisphere_grid(n_theta, n_phi)
    return np.sum(f(d) * d[..., 2] * w)


@pytest.mark.parametrize("rough", [0.05, 0.2, 0.5, 1.0])
def test_D_integrates_to_one_over_projected_hemisphere(rough):
    for D in (brdf.D_beckmann, brdf.D_ggx):
        assert _projected_integral(lambda h: D(h[..., 2], rough)) == pytest.approx(1.0, abs=2e-3)


def test_D_peaks_at_closed_forms():
    assert brdf.D_beckmann(1.0, 0.3) == pytest.approx(1 / (np.pi * 0.09))
    assert brdf.D_ggx(1.0, 0.3) == pytest.approx(1 / (np.pi * 0.09))
    # GGX at 60 deg: alpha^2 / (pi (0.25 (alpha^2-1) + 1)^2)
    assert brdf.D_ggx(0.5, 0.5) == pytest.approx(0.25 / (np.pi * (0.25 * -0.75 + 1) ** 2))


def _directional_albedo(v, grid=(512, 64), **kw):
    """Integral of f_s (n.l) over l, in half-vector space: l = 2 (v.h) h - v, dl = 4 (v.h) dh. D is smooth in h,
    so the grid resolves even a near-mirror lobe seen at grazing angles (an l grid misses most of it)."""
    h, w = brdf.hemisphere_grid(*grid)
    v_h = brdf.dot(h, v)
    l = 2 * v_h[..., None] * h - v
    f = brdf.cook_torrance_brdf(N, l, v, **kw)
    return np.sum(np.where(v_h > 0, f * np.maximum(l[..., 2], 0) * 4 * v_h * w, 0.0))


@pytest.mark.parametrize("dist", [0.0, 1.0])
@pytest.mark.parametrize("geom", [0.0, 1.0])
def test_white_furnace_albedo_of_cook_torrance_with_F1_at_most_one(dist, geom):
    for rough in (0.05, 0.3, 0.7, 1.0):
        for tv in (0.0, 0.6, 1.2, 1.5):
            albedo = _directional_albedo(brdf.direction(tv), F0=1.0, roughness=rough, distribution=dist,
                                         geometry=geom)
            assert np.isfinite(albedo) and albedo <= 1.0 + 1e-3, (rough, tv, albedo)
            if tv == 0.0:
                # at v = n, l = reflect(v, h) leaves the hemisphere once theta_h > 45 deg; with G <= 1 the
                # albedo is at most the projected D mass inside 45 deg: GGX 1/(1 + a^2), Beckmann 1 - e^(-1/m^2)
                cap = 1 / (1 + rough ** 2) if dist else 1 - np.exp(-1 / rough ** 2)
                assert albedo <= cap + 1e-3
                if rough <= 0.05:
                    assert albedo > 0.99  # a near-smooth mirror reflects almost everything
            if rough <= 0.05:
                assert albedo > 0.85, (tv, albedo)  # also at 86 deg, where shadowing starts to bite


@pytest.mark.parametrize("shininess", [1.0, 10.0, 100.0])
def test_normalized_phong_albedo_is_ks_at_normal_incidence(shininess):
    d, w = brdf.hemisphere_grid(2048, 8)
    ks = 0.3
    L = brdf.phong(N, d, N, WHITE, kd=(0, 0, 0), ks=ks, shininess=shininess, normalized=1.0)[..., 0]
    # L = pi I f (n.l)  =>  albedo = integral of f (n.l) = integral of L / (pi I)
    assert np.sum(L / np.pi * w) == pytest.approx(ks, rel=2e-3)


def test_classic_phong_is_not_energy_conserving():
    d, w = brdf.hemisphere_grid(1024, 8)
    L = brdf.phong(N, d, N, WHITE, kd=(0, 0, 0), ks=1.0, shininess=1.0)[..., 0]
    # L = pi I f (n.l), so the albedo is the integral of L / (pi I); with v = n, r.v = n.l:
    # n = 1 gives the integral of cos / pi = 1, n = 0 the integral of 1 / pi = 2
    assert np.sum(L / np.pi * w) == pytest.approx(1.0, rel=2e-3)
    L0 = brdf.phong(N, d, N, WHITE, kd=(0, 0, 0), ks=1.0, shininess=0.0)[..., 0]
    assert np.sum(L0 / np.pi * w) == pytest.approx(2.0, rel=2e-3)


def test_phong_blinn_closed_values():
    I = np.array([1.0, 2.0, 3.0])
    l = brdf.direction(np.radians(30), 0.0)
    v = brdf.direction(np.radians(30), np.pi)  # mirror direction: r.v = 1, n.h = 1
    for model in (brdf.phong, brdf.blinn_phong):
        got = model(N, l * 5, v, I, ka=0.2, ambient_light=(1, 1, 1), kd=(0.5, 0.5, 0.5), ks=0.4,
                    shininess=20.0, emission=(0.1, 0, 0))
        np.testing.assert_allclose(got, 0.2 + I * (0.5 * np.cos(np.radians(30)) + 0.4) + [0.1, 0, 0], rtol=1e-12)
    v2 = brdf.direction(np.radians(60), np.pi)  # r.v = cos 30
    got = brdf.phong(N, l, v2, WHITE, kd=(0, 0, 0), ks=1.0, shininess=3.0)[0]
    assert got == pytest.approx(np.cos(np.radians(30)) ** 3)
    got = brdf.blinn_phong(N, l, v2, WHITE, kd=(0, 0, 0), ks=1.0, shininess=3.0, normalized=1.0)[0]
    # exact normalisation of the (n.h)^n lobe at n = 3 (Giesen 2009): (n+2)(n+4) / (8 (2^(-n/2) + n))
    assert got == pytest.approx(35 / (8 * (2 ** -1.5 + 3)) * np.cos(np.radians(15)) ** 3 * np.cos(np.radians(30)))


def test_cook_torrance_at_normal_incidence_closed_form():
    # l = v = n: h = n, D = 1/(pi a^2), G = 1 (both forms), F = F0  =>  L = I ks F0 / (4 a^2)
    for dist in (0, 1):
        for geom in (0, 1):
            got = brdf.cook_torrance(N, N, N, WHITE, kd=(0, 0, 0), ks=0.5, F0=0.8, roughness=0.4,
                                     distribution=dist, geometry=geom)
            np.testing.assert_allclose(got, 0.5 * 0.8 / (4 * 0.16), rtol=1e-12)


def test_schlick_approximates_exact_fresnel():
    c = np.linspace(0, 1, 101)
    exact = brdf.F_dielectric(c, 1.5)
    assert exact[-1] == pytest.approx(0.04)
    assert np.max(np.abs(brdf.F_schlick(c, 0.04) - exact)) < 0.04  # Schlick's known worst case near grazing incidence


def test_smith_ggx_is_height_correlated_form():
    a, cl, cv = 0.5, 0.6, 0.3
    lam = lambda c: (np.sqrt(1 + a * a * (1 - c * c) / (c * c)) - 1) / 2
    assert brdf.G_smith(cl, cv, a, 1.0) == pytest.approx(1 / (1 + lam(cl) + lam(cv)))


EDGE_DIRS = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 1e-9], [0, 0, -1], [1, 0, -1e-7], [0.3, 0.2, -0.9],
                      [1, 0, 1e-6], [-1, 0, 1e-6], [0, 0, 0]], float)


def _pairs():
    l = np.repeat(EDGE_DIRS, len(EDGE_DIRS), axis=0)
    v = np.tile(EDGE_DIRS, (len(EDGE_DIRS), 1))
    return l, v


@pytest.mark.parametrize("model, kwargs, bound", [
    (brdf.phong, dict(shininess=0.0, ks=1.0, kd=(1, 1, 1)), 3.0),
    (brdf.phong, dict(shininess=1e4, ks=1.0, normalized=1.0), 1e4),
    (brdf.blinn_phong, dict(shininess=0.0, ks=1.0, normalized=1.0), 3.0),
    (brdf.blinn_phong, dict(shininess=1e4, ks=1.0, normalized=1.0), 1e4),
    (brdf.oren_nayar, dict(sigma=10.0, albedo=(1, 1, 1)), 2.0),
    (brdf.oren_nayar, dict(sigma=1e3, albedo=(1, 1, 1)), 2.0),
    # roughness 0 is clamped to 1e-3: D <= 1/(pi m^2), G <= 1, n.v >= 1e-4 -> L <= 1/(4e-4 m^2) = 2.5e9
    (brdf.cook_torrance, dict(roughness=0.0, F0=1.0, distribution=1.0, geometry=1.0), 2.5e9),
    (brdf.cook_torrance, dict(roughness=0.0, F0=1.0, distribution=0.0, geometry=0.0), 2.5e9),
    (brdf.cook_torrance, dict(roughness=1.0, F0=1.0, distribution=0.0, geometry=1.0), 10.0),
])
def test_every_output_finite_and_bounded_at_the_edges(model, kwargs, bound):
    l, v = _pairs()
    out = model(N, l, v, WHITE, **kwargs)
    assert np.all(np.isfinite(out)) and np.all(out >= 0) and np.max(out) <= bound
    # a light below the horizon contributes nothing (no ambient or emission here), whatever the view
    back = np.array([0.0, 0.3, -1.0])
    assert np.all(model(N, back, v, WHITE, **kwargs) == 0)


def test_point_light_units_and_attenuation():
    p = np.array([[0, 0, 0], [0, 0, -1.0]])
    lvec, I = lights.point_light(p, (0, 0, 2), (1, 0.5, 0), 100.0)
    np.testing.assert_allclose(lvec, [[0, 0, 2], [0, 0, 3]])
    np.testing.assert_allclose(I[0], np.array([1, 0.5, 0]) * 100 / (4 * np.pi ** 2 * 4))
    # I times pi is the irradiance REFERENCE.md measured: P = 100 W at h = 2 -> E/pi = 0.63324
    assert I[0, 0] == pytest.approx(0.63324, abs=1e-4)
    _, I = lights.point_light(p, (0, 0, 2), (1, 1, 1), 100.0, physical=0.0, c1=1.0, c2=0.5, c3=0.25)
    np.testing.assert_allclose(I[:, 0], 100 / (4 * np.pi ** 2) / np.array([1 + 1 + 1, 1 + 1.5 + 2.25]))
    _, I = lights.point_light(p, (0, 0, 2), (1, 1, 1), 100.0, physical=0.0, c1=0.1, c2=0.0, c3=0.0)
    np.testing.assert_allclose(I[:, 0], 100 / (4 * np.pi ** 2))  # f_att clamped at 1


def test_spot_cutoff_and_exponent():
    p = np.array([[0, 0, 0], [1, 0, 0], [3, 0, 0]], float)
    _, I = lights.spot_light(p, (0, 0, 1), (0, 0, -1), (1, 1, 1), 40.0, cutoff=np.radians(60), exponent=2.0)
    base = 40 / (4 * np.pi ** 2)
    np.testing.assert_allclose(I[:, 0], [base, base / 2 * 0.5, 0.0])  # cos45^2 = 0.5, d^2 = 2; 71.6 deg outside


def test_sun_and_hemi():
    lvec, I = lights.sun_light(np.zeros((2, 3)), (0, 0, -1), (1, 1, 1), 3.0)
    assert I[0, 0] == pytest.approx(0.95493, abs=1e-5)  # REFERENCE.md: sun S = 3 -> 3/pi
    np.testing.assert_allclose(lvec, [[0, 0, 1]] * 2)
    n = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0]], float)
    lvec, I = lights.hemi_light(n, (0, 0, -1), (1, 1, 1), (0, 0, 0), np.pi)
    np.testing.assert_allclose(I[:, 0], [1.0, 0.0, 0.5])
    np.testing.assert_allclose(lvec, n)
