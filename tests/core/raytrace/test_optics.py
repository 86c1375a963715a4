"""Snell's law, total internal reflection and Fresnel energy against closed forms."""
import numpy as np

from addon.core.raytrace import optics


def _dir(theta):
    return np.array([np.sin(theta), 0.0, -np.cos(theta)])


def test_refraction_obeys_snell_and_stays_unit():
    n = np.array([0, 0, 1.0])
    for theta in np.radians([0, 10, 30, 60, 89]):
        t, tir = optics.refract_dir(_dir(theta), n, 1 / 1.5)
        assert not tir
        np.testing.assert_allclose(np.linalg.norm(t), 1.0, atol=1e-12)
        np.testing.assert_allclose(1.0 * np.sin(theta), 1.5 * np.hypot(t[0], t[1]), atol=1e-12)
        assert t[2] < 0


def test_total_internal_reflection_beyond_the_critical_angle():
    n = np.array([0, 0, 1.0])
    critical = np.arcsin(1 / 1.5)
    _, tir_below = optics.refract_dir(_dir(critical - 1e-6), n, 1.5)
    _, tir_above = optics.refract_dir(_dir(critical + 1e-6), n, 1.5)
    assert not tir_below and tir_above
    # leaving the glass: the ray travels down, the outward normal points down (-z)
    _, _, ks, kt, tir = optics.glass_split(_dir(critical + 0.1), -n, 1.5)
    assert tir and ks == 1.0 and kt == 0.0


def test_fresnel_normal_incidence_and_energy():
    assert np.isclose(optics.fresnel_dielectric(1.0, 1 / 1.5), 0.04)
    assert np.isclose(optics.fresnel_dielectric(1.0, 1.5), 0.04)           # reciprocal at normal incidence
    theta = np.radians(np.linspace(0, 89.9, 50))
    d = np.stack([np.sin(theta), 0 * theta, -np.cos(theta)], -1)
    n = np.tile([0, 0, 1.0], (50, 1))
    _, _, ks, kt, _ = optics.glass_split(d, n, 1.5)
    np.testing.assert_allclose(ks + kt, 1.0)
    assert np.all(np.diff(ks) >= -1e-12) and ks[-1] > 0.9                     # grows to 1 at grazing


def test_ior_one_reflects_nothing_and_bends_nothing():
    d = _dir(np.radians(70))
    n = np.array([0, 0, 1.0])
    _, eta, ks, kt, tir = optics.glass_split(d[None], n[None], 1.0)
    t, _ = optics.refract_dir(d, n, 1.0)
    np.testing.assert_allclose(t, d, atol=1e-12)
    assert ks[0] == 0.0 and kt[0] == 1.0 and not tir[0]


def test_mirror_direction_and_conductor_fresnel():
    r = optics.reflect_dir(_dir(np.radians(30)), np.array([0, 0, 1.0]))
    np.testing.assert_allclose(r, [0.5, 0, np.cos(np.radians(30))], atol=1e-12)
    np.testing.assert_allclose(optics.fresnel_conductor(1.0, (0.9, 0.5, 0.1)), [0.9, 0.5, 0.1])
    np.testing.assert_allclose(optics.fresnel_conductor(0.0, (0.9, 0.5, 0.1)), [1, 1, 1])
