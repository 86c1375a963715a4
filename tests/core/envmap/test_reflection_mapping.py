"""Reflection and refraction mapping in numpy: r, Snell's t, total internal reflection, Schlick; the three
map types' round trips, texel solid angles and lookup errors at equal texel count (issue 29)."""
import numpy as np
import pytest

from addon.core.envmap import latlong, maps, projections, reflection


def _unit(a):
    a = np.asarray(a, np.float64)
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _dirs(n=2000, seed=1):
    return _unit(np.random.default_rng(seed).normal(size=(n, 3)))


def test_reflect_is_the_mirror_direction():
    n = np.array([0.0, 0.0, 1.0])
    v = _unit([1.0, 2.0, 3.0])
    r = reflection.reflect(v, n)
    assert np.allclose(r, [-v[0], -v[1], v[2]])
    assert np.linalg.norm(r) == pytest.approx(1.0)


def test_refraction_obeys_snell_and_ior_one_goes_straight_through():
    n = np.array([0.0, 0.0, 1.0])
    v = _unit([np.sin(0.7), 0.0, np.cos(0.7)])
    t, ok = reflection.refract(v, n, 1 / 1.5)
    assert ok and np.linalg.norm(t) == pytest.approx(1.0)
    sin_t = np.hypot(t[0], t[1])
    assert np.sin(0.7) == pytest.approx(1.5 * sin_t, rel=1e-12)      # n1 sin θi = n2 sin θt
    d, w = reflection.lookup(_dirs(), _dirs(seed=2) * 0 + n, "REFRACT", ior=1.0, fresnel=True)
    vv = _dirs()
    front = vv[:, 2] > 0
    assert np.allclose(d[front], -vv[front])                           # the world behind, unchanged
    assert np.allclose(w[front], 1.0)                                  # no interface: F = 0, 1 - F = 1


def test_total_internal_reflection_transmits_nothing():
    n = np.array([0.0, 0.0, 1.0])
    crit = np.arcsin(1 / 1.5)
    for theta, transmitted in ((crit - 0.01, True), (crit + 0.01, False), (1.5, False)):
        v = np.array([np.sin(theta), 0.0, np.cos(theta)])
        t, w = reflection.lookup(v, n, "REFRACT", ior=1.5, fresnel=True, inside=True)
        assert (w > 0) == transmitted, theta
        if not transmitted:
            assert w == 0.0 and np.all(t == 0.0)
            _, wr = reflection.lookup(v, n, "REFLECT", ior=1.5, fresnel=True, inside=True)
            assert wr == 1.0                                           # all of it reflected
    # without Fresnel the refracted lookup is still dark under TIR
    v = np.array([np.sin(1.2), 0.0, np.cos(1.2)])
    assert reflection.lookup(v, n, "REFRACT", ior=1.5, fresnel=False, inside=True)[1] == 0.0


def test_schlick_values_and_energy_split():
    assert reflection.schlick_f0(1.5) == pytest.approx(0.04)
    assert reflection.schlick(1.0, 0.04) == pytest.approx(0.04)
    assert reflection.schlick(0.0, 0.04) == pytest.approx(1.0)
    n = np.broadcast_to([0.0, 0.0, 1.0], (500, 3))
    v = _dirs(500)
    v[:, 2] = np.abs(v[:, 2])
    _, fr = reflection.lookup(v, n, "REFLECT", 1.5, True)
    _, ft = reflection.lookup(v, n, "REFRACT", 1.5, True)
    assert np.allclose(fr + ft, 1.0)                                   # F + (1 - F) outside TIR


def test_round_trips_latlong_cube_sphere():
    """A smooth environment: lat-long -> cube strip -> lookup and lat-long -> sphere -> lookup give it back."""
    d = _dirs(4000)

    def env_fn(x):
        return np.stack([0.5 + 0.3 * x[..., 0], 0.5 + 0.3 * x[..., 1] * x[..., 2], 0.4 + 0.2 * x[..., 2] ** 2], -1)
    env = env_fn(latlong.latlong_directions(128, 256))
    strip = maps.convert(env, "CUBE", 96)
    assert strip.shape == (96, 576, 3)
    assert np.allclose(maps.strip_to_cube(strip), projections.latlong_to_cube(env, 96))
    assert np.abs(maps.sample(strip, "CUBE", d) - env_fn(d)).max() < 2e-3
    sph = maps.convert(env, "SPHERE", 256)
    front = d[:, 1] < 0.8                    # away from the sphere map's singular rim (the direction +Y)
    assert np.abs(maps.sample(sph, "SPHERE", d[front]) - env_fn(d[front])).max() < 5e-3
    back = projections.cube_to_latlong(maps.strip_to_cube(strip), 256)
    assert np.abs(back - env).max() < 2e-2   # nearest-texel way back
    assert np.abs(maps.sample(maps.convert(env, "LATLONG", 64), "LATLONG", d) - env_fn(d)).max() < 5e-3


def test_texel_solid_angles_and_the_notes_claims():
    """Seed 002: the cube map is "not distorted", lat-long and sphere maps are. Measured at equal texel count:
    every map is distorted; the cube least in shape, the sphere map not at all in area (equal-area)."""
    h = 64
    stats = {p: maps.distortion(p, maps.equal_texel_size(p, h)) for p in maps.PROJECTIONS}
    for p in maps.PROJECTIONS:
        size = maps.equal_texel_size(p, h)
        assert maps.texel_solid_angles(p, size).sum() == pytest.approx(4 * np.pi, rel=2e-3)
        assert abs(stats[p]["texels"] - 2 * h * h) / (2 * h * h) < 0.02
    assert stats["CUBE"]["max_over_min"] == pytest.approx(3 * np.sqrt(3), rel=0.1)   # centre vs corner: 3√3
    assert stats["LATLONG"]["max_over_min"] > 40                   # equator vs polar row: 1/sin(π/2H) ~ 2H/π
    assert stats["SPHERE"]["max_over_min"] == pytest.approx(1.0)  # equal-area: the notes' "distorted" is shape
    assert stats["SPHERE"]["anisotropy_max"] > 20 and stats["LATLONG"]["anisotropy_max"] > 20
    assert stats["CUBE"]["anisotropy_max"] < 2


def test_lookup_error_against_an_analytic_environment():
    """Equal texel count, a smooth analytic sky: every map reconstructs it; the sphere map is worst (its rim)."""
    d = _dirs(20000, seed=5)

    def env_fn(x):
        return np.stack([np.exp(2 * (x[..., 2] - 1)) + 0.2 * x[..., 0]] * 3, -1)
    err = {p: maps.lookup_error(env_fn, p, maps.equal_texel_size(p, 32), d) for p in maps.PROJECTIONS}
    assert all(e[0] < 1e-2 for e in err.values())
    assert err["SPHERE"][1] > err["CUBE"][1]


def test_a_constant_environment_reads_the_same_in_every_direction_of_every_map():
    """Bilinear weights sum to 1, so a constant world must come back exactly, also next to the sphere map's rim
    (its texels outside the disk hold the rim's direction, never black)."""
    d = np.concatenate([_dirs(5000, seed=7), [[0.0, 1.0, 0.0], [0.0, 0.999, 0.0447], [0.0447, 0.999, 0.0]]])
    for p in maps.PROJECTIONS:
        img = maps.convert(np.full((16, 32, 3), 2.5), p)
        np.testing.assert_allclose(maps.sample(img, p, d), 2.5, rtol=1e-12, err_msg=p)
        rmse, worst = maps.lookup_error(lambda x: np.full(x.shape[:-1] + (3,), 2.5), p, 12, d)
        assert worst < 1e-12, p
