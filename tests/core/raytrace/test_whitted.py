"""Ray casting and Whitted (seed 004, eq. 2) against closed forms: a diffuse plane under a point light, a
mirror's reflection of the lit floor, glass of IOR 1, energy of a glass sphere, depth 0."""
import numpy as np
import pytest

from addon.core.raytrace import Light, Material, Scene, trace
from addon.core.raytrace.optics import fresnel_conductor
from test_bvh import uv_sphere

KD = (0.5, 0.6, 0.7)


def quad(corners):
    a, b, c, d = np.asarray(corners, float)
    return np.array([[a, b, c], [a, c, d]])


FLOOR = quad([(-10, -10, 0), (10, -10, 0), (10, 10, 0), (-10, 10, 0)])


def point_irradiance_radiance(p, light_pos, power, n=(0, 0, 1)):
    """k_d I cos θ with I = P/(4π² d²) (REFERENCE.md §1)."""
    v = np.asarray(light_pos, float) - p
    d2 = v @ v
    return np.asarray(KD) * power / (4 * np.pi ** 2 * d2) * (v @ np.asarray(n, float)) / np.sqrt(d2)


def test_diffuse_plane_under_a_point_light_is_kd_I_cos():
    scene = Scene(FLOOR, [0, 0], [Material(params={"kd": KD})], [Light("POINT", 100.0, position=(0, 0, 2))])
    for method in ("raycast", "whitted"):
        L, stats = trace(scene, [[1, 0, 5]], [[0, 0, -1]], method, 3)
        np.testing.assert_allclose(L[0], point_irradiance_radiance(np.array([1.0, 0, 0]), (0, 0, 2), 100.0),
                                   rtol=1e-10)
        assert stats.primary == 1 and stats.shadow == 1


def test_sun_and_spot_lights_follow_reference_units():
    sun = Light("SUN", 3.0, direction=(0, 0, -1))
    scene = Scene(FLOOR, [0, 0], [Material(params={"kd": KD})], [sun])
    L, _ = trace(scene, [[1, 0, 5]], [[0, 0, -1]], "raycast")
    np.testing.assert_allclose(L[0], np.asarray(KD) * 3.0 / np.pi, rtol=1e-12)      # S/π per unit albedo
    spot = Light("SPOT", 100.0, position=(0, 0, 2), direction=(0, 0, -1), cutoff=np.radians(30))
    scene = Scene(FLOOR, [0, 0], [Material(params={"kd": KD})], [spot])
    L, _ = trace(scene, [[0.5, 0, 5], [2, 0, 5]], [[0, 0, -1], [0, 0, -1]], "raycast")
    np.testing.assert_allclose(L[0], point_irradiance_radiance(np.array([0.5, 0, 0]), (0, 0, 2), 100.0), rtol=1e-10)
    assert np.all(L[1] == 0)                                                         # outside the cone


def test_mirror_reflects_the_lit_floor_times_fresnel():
    mirror = quad([(3, -5, -1), (3, 5, -1), (3, 5, 5), (3, -5, 5)])
    f0 = (0.9, 0.8, 0.7)
    scene = Scene(np.concatenate([FLOOR, mirror]), [0, 0, 1, 1],
                  [Material(params={"kd": KD}), Material("mirror", mirror=f0, params={"kd": (0, 0, 0)})],
                  [Light("POINT", 100.0, position=(0, 0, 2))])
    d = np.array([[1, 0, -1]]) / np.sqrt(2)
    floor = point_irradiance_radiance(np.array([2.5, 0, 0]), (0, 0, 2), 100)
    expected = fresnel_conductor(np.cos(np.pi / 4), f0) * floor
    L, stats = trace(scene, [[1.5, 0, 2]], d, "whitted", 1)
    np.testing.assert_allclose(L[0], expected, rtol=1e-4)      # the ray leaves the mirror offset by Scene.epsilon
    assert stats.secondary == 1
    L0, _ = trace(scene, [[1.5, 0, 2]], d, "whitted", 0)
    Lc, _ = trace(scene, [[1.5, 0, 2]], d, "raycast", 5)
    assert np.all(L0 == 0) and np.all(Lc == 0)                # depth 0 = ray casting: a mirror alone is black


def test_glass_of_ior_one_is_invisible_to_camera_rays():
    glass = quad([(0.5, -1, 1), (1.5, -1, 1), (1.5, 1, 1), (0.5, 1, 1)])
    light = Light("POINT", 100.0, position=(-3, 0, 2))
    bare = Scene(FLOOR, [0, 0], [Material(params={"kd": KD})], [light])
    with_glass = Scene(np.concatenate([FLOOR, glass]), [0, 0, 1, 1],
                       [Material(params={"kd": KD}), Material("glass", ior=1.0, params={"kd": (0, 0, 0)})], [light])
    o, d = [[1, 0.2, 5]], [[0.05, 0, -1]]
    L_bare, _ = trace(bare, o, d, "whitted", 2)
    L_glass, _ = trace(with_glass, o, d, "whitted", 2)
    np.testing.assert_allclose(L_glass, L_bare, rtol=1e-6)     # offset by Scene.epsilon at the glass
    assert L_bare[0].sum() > 0


@pytest.mark.parametrize("ior", [1.33, 1.5])
def test_glass_sphere_conserves_energy_and_converges_with_depth(ior):
    """Under a white background of radiance 1 and no light, a clear glass sphere's k_s + k_t = 1 at every hit:
    each pixel's radiance is 1 minus what is still inside after max_depth bounces, rising with depth.
    (Rays entering near the silhouette of the faceted sphere, impact parameter >= 0.95, are caught by total
    internal reflection between facets and circle for hundreds of bounces: 5 % still inside at depth 200.)"""
    tris = uv_sphere(1.0, segments=48, rings=24)
    scene = Scene(tris, np.zeros(len(tris), int),
                  [Material("glass", ior=ior, params={"kd": (0, 0, 0)})], [], background=(1, 1, 1))
    ys = np.linspace(-0.85, 0.85, 21)
    o = np.stack([ys, 0.31 * ys, np.full_like(ys, 5.0)], -1)
    d = np.tile([0, 0, -1.0], (len(ys), 1))
    means = []
    for depth in (0, 1, 2, 4, 8, 40):
        L, _ = trace(scene, o, d, "whitted", depth)
        assert np.all(L <= 1 + 1e-9)
        means.append(L.mean())
    assert means[0] == 0
    assert np.all(np.diff(means) >= -1e-12)
    assert means[-1] > 0.999


def test_batches_give_the_same_image_as_one_pass(monkeypatch):
    from addon.core.raytrace import whitted
    tris = uv_sphere(1.0, segments=24, rings=12)
    scene = Scene(np.concatenate([FLOOR, tris]), np.r_[[0, 0], np.ones(len(tris), int)],
                  [Material(params={"kd": KD}), Material("glass", ior=1.5, params={"kd": (0, 0, 0)})],
                  [Light("POINT", 100.0, position=(2, -2, 4))], background=(0.1, 0.2, 0.3))
    rng = np.random.default_rng(3)
    o = np.tile([0.0, -5.0, 2.0], (300, 1))
    d = np.c_[rng.uniform(-0.3, 0.3, 300), np.ones(300), rng.uniform(-0.6, 0.1, 300)]
    one, s1 = trace(scene, o, d, "whitted", 5)
    monkeypatch.setattr(whitted, "BATCH", 64)
    many, s2 = trace(scene, o, d, "whitted", 5)
    np.testing.assert_array_equal(one, many)
    assert (s1.primary, s1.secondary, s1.shadow) == (s2.primary, s2.secondary, s2.shadow)
    assert one.max() > 0
