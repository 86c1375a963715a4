"""The project's physics held to published numbers, typed in here with their source (no bpy).

Every expected value below comes from a publication or from a closed form written here from
the publication; none is produced by the project's code. The integrals over the hemisphere are
also written here, independently of the project's own quadrature helpers.
"""
import numpy as np
import pytest

from addon.core import brdf
from addon.core.envmap import irradiance
from addon.core.envmap import sh9
from addon.core.radiosity import form_factors
from addon.core.radiosity import patches as rad_patches
from addon.core.radiosity import subdivision

N = np.array([0.0, 0.0, 1.0])
ONE = np.ones(3)


# -- Howell, "A Catalog of Radiation Heat Transfer Configuration Factors" -----------------------------

#: Howell catalogue C-11 (directly opposed parallel rectangles), a = b = c = 1: F = 0.19982.
HOWELL_OPPOSED_UNIT_SQUARES = 0.19982
#: Howell catalogue C-14 (perpendicular rectangles with a common edge), all sides 1: F = 0.20004.
HOWELL_PERPENDICULAR_UNIT_SQUARES = 0.20004
SQUARE_Z0 = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]        # faces +z
SQUARE_Z1 = [(0, 0, 1), (0, 1, 1), (1, 1, 1), (1, 0, 1)]        # faces -z, opposed at distance 1
SQUARE_Y0 = [(0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0)]        # faces +y, shares the edge y = z = 0


def _square_to_square(other, n):
    """F from the unit square z = 0 to ``other``, both split into n x n patches: sum_i A_i sum_j F_ij / A."""
    meshes = [{"name": "a", "vertices": np.array(SQUARE_Z0, float), "faces": [(0, 1, 2, 3)]},
              {"name": "b", "vertices": np.array(other, float), "faces": [(0, 1, 2, 3)]}]
    p = subdivision.subdivide_to_size(rad_patches.patches_from_meshes(meshes), 1.0 / n + 1e-9)
    assert len(p) == 2 * n * n
    F = form_factors.form_factors(p)
    a, b = p.owner == 0, p.owner == 1
    return float(np.sum(p.area[a, None] * F[np.ix_(a, b)]) / np.sum(p.area[a]))


@pytest.mark.parametrize("other, howell", [(SQUARE_Z1, HOWELL_OPPOSED_UNIT_SQUARES),
                                           (SQUARE_Y0, HOWELL_PERPENDICULAR_UNIT_SQUARES)])
def test_form_factors_converge_to_howell_as_patches_are_subdivided(other, howell):
    values = {n: _square_to_square(other, n) for n in (2, 4, 8, 16)}
    errors = [abs(values[n] - howell) for n in (2, 4, 8, 16)]
    # midpoint rule over the emitter, exact inner integral: the error falls about 4x per halving
    assert all(e2 < e1 / 3 for e1, e2 in zip(errors, errors[1:])), errors
    assert errors[-1] < 2e-4
    # Richardson extrapolation of the last two levels lands on the catalogue's five digits
    assert (4 * values[16] - values[8]) / 3 == pytest.approx(howell, abs=1e-5)


def test_differential_element_to_coaxial_disk_converges_to_R2_over_R2_plus_h2():
    # Howell catalogue B-13 (differential planar element to a parallel coaxial disk): F = R^2 / (R^2 + h^2)
    for R_, h in ((1.0, 1.0), (0.5, 2.0), (3.0, 0.7)):
        howell = R_ * R_ / (R_ * R_ + h * h)
        errors = []
        for k in (8, 32, 128, 512):
            a = 2 * np.pi * np.arange(k + 1) / k
            rim = np.stack([R_ * np.cos(a), R_ * np.sin(a), np.full_like(a, h)], -1)
            centre = np.array([0.0, 0.0, h])
            # the disk as a fan of k triangle patches (a repeated last corner), wound to face the element
            tris = np.stack([np.broadcast_to(centre, (k, 3)), rim[1:], rim[:-1], rim[:-1]], axis=1)
            F = form_factors.point_polygon_form_factors(np.zeros((1, 3)), N[None], tris).sum()
            errors.append(abs(F - howell))
        assert all(e2 < e1 / 10 for e1, e2 in zip(errors, errors[1:])), errors  # inscribed polygon: O(1/k^2)
        assert errors[-1] < 1e-5


# -- Ramamoorthi & Hanrahan 2001, "An Efficient Representation for Irradiance Environment Maps" ------

#: Table 2 of the paper: the nine RGB lighting coefficients L_lm of the Grace Cathedral light probe,
#: in the order L00, L1-1, L10, L11, L2-2, L2-1, L20, L21, L22.
GRACE_CATHEDRAL = np.array([
    [0.79, 0.44, 0.54],
    [0.39, 0.35, 0.60],
    [-0.34, -0.18, -0.27],
    [-0.29, -0.06, 0.01],
    [-0.11, -0.05, -0.12],
    [-0.26, -0.22, -0.47],
    [-0.16, -0.09, -0.15],
    [0.56, 0.21, 0.14],
    [0.21, -0.05, -0.30],
])
#: Eq. 8-9 of the paper: A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4.
A_L = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)


def _Y(d):
    """Real spherical harmonics of the paper's eq. 3, constants in closed form (not the rounded ones)."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    c1, c2 = np.sqrt(3 / (4 * np.pi)), 0.5 * np.sqrt(15 / np.pi)
    return np.stack([np.full_like(x, 0.5 / np.sqrt(np.pi)), c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z,
                     0.25 * np.sqrt(5 / np.pi) * (3 * z * z - 1), c2 * x * z,
                     0.25 * np.sqrt(15 / np.pi) * (x * x - y * y)], axis=-1)


def _grace_latlong(h):
    """L(d) = sum L_lm Y_lm(d) on an equirectangular (h, 2h) map in Blender's layout (row 0 up, the centre
    column looking along +X, u = (pi - atan2(y, x)) / 2 pi), at the pixel centres."""
    theta = (np.arange(h) + 0.5) * np.pi / h
    phi = np.pi - 2 * np.pi * (np.arange(2 * h) + 0.5) / (2 * h)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    return _Y(d) @ GRACE_CATHEDRAL


def _normals(k=200, seed=3):
    d = np.random.default_rng(seed).normal(size=(k, 3))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_grace_cathedral_coefficients_survive_synthesis_and_projection():
    env = _grace_latlong(128)
    got = sh9.sh9_coefficients(env)
    np.testing.assert_allclose(got, GRACE_CATHEDRAL, rtol=0, atol=1e-3)


def test_grace_cathedral_irradiance_sh9_and_brute_force_match_the_papers_formula():
    env = _grace_latlong(128)
    n = _normals()
    expect = (_Y(n) * A_L) @ GRACE_CATHEDRAL                     # eq. 7: E(n) = sum A_l L_lm Y_lm(n)
    assert np.ptp(expect) > 1.0                                  # a strongly directional probe
    np.testing.assert_allclose(sh9.sh9_irradiance(sh9.sh9_coefficients(env), n), expect, rtol=0, atol=2e-3)
    np.testing.assert_allclose(irradiance.irradiance_brute(env, n), expect, rtol=0, atol=2e-3)


# -- microfacet distributions (Walter et al. 2007) and the white furnace ---------------------------

ROUGHNESS = np.geomspace(1e-3, 1.0, 13)


@pytest.mark.parametrize("D", [brdf.D_beckmann, brdf.D_ggx], ids=["beckmann", "ggx"])
def test_microfacet_D_is_normalised_for_roughness_1e3_to_1(D):
    # Walter et al. 2007, eq. 4: integral of D(h) (n.h) dh = 1. In t = tan(theta_h):
    # 2 pi integral of D t / (1 + t^2)^2 dt, a smooth integrand in ln t whatever the lobe's width.
    for r in ROUGHNESS:
        u = np.linspace(np.log(r) - 25, np.log(r) + 25, 40001)
        t = np.exp(u)
        g = 2 * np.pi * D(1 / np.sqrt(1 + t * t), r) * t * t / (1 + t * t) ** 2
        total = np.sum((g[1:] + g[:-1]) / 2 * np.diff(u))
        assert total == pytest.approx(1.0, abs=1e-6), (D.__name__, r, total)


def _albedo(radiance, theta_v, width, n_x=400, n_phi=200):
    """(1/pi) integral of L(l, v) dl for I = 1, written in the half vector: l = 2 (v.h) h - v, dl = 4 (v.h) dh,
    tan(theta_h) = width tan(x pi/2) with x on a midpoint grid, phi_h in [0, pi] (mirror symmetry)."""
    x = (np.arange(n_x) + 0.5) / n_x
    tx = np.tan(x * np.pi / 2)
    th = np.arctan(width * tx)
    dth = width * (np.pi / 2) / np.cos(x * np.pi / 2) ** 2 / (1 + (width * tx) ** 2) / n_x
    ph = (np.arange(n_phi) + 0.5) * np.pi / n_phi
    t, p = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    v = np.array([np.sin(theta_v), 0.0, np.cos(theta_v)])
    vh = h @ v
    l = 2 * np.maximum(vh, 0)[..., None] * h - v
    w = np.where(vh > 0, 4 * vh * np.sin(t) * dth[:, None] * 2 * np.pi / n_phi, 0.0)
    return float(np.sum(radiance(l, v) * w) / np.pi)


INCIDENCES = np.radians([0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 85.0, 89.0, 89.9])


@pytest.mark.parametrize("dist", [0.0, 1.0], ids=["beckmann", "ggx"])
@pytest.mark.parametrize("geom", [0.0, 1.0], ids=["ct1982", "smith"])
def test_white_furnace_cook_torrance_F1_reflects_at_most_what_it_receives(dist, geom):
    worst = 0.0
    for r in (1e-3, 1e-2, 0.1, 0.4, 1.0):
        for tv in INCIDENCES:
            a = _albedo(lambda l, v: brdf.cook_torrance(N, l, v, ONE, kd=(0, 0, 0), ks=1.0, F0=1.0, roughness=r,
                                                        distribution=dist, geometry=geom)[..., 0], tv, min(3 * r, 1),
                        n_x=300, n_phi=120)
            assert np.isfinite(a) and a <= 1.0 + 1e-4, (r, np.degrees(tv), a)
            worst = max(worst, a)
    assert worst > 0.98  # a smooth mirror at normal incidence reflects (nearly) everything


# -- energy-conserving local models: directional albedo <= 1 ---------------------------------------

EXPONENTS = [0.0, 0.3, 1.0, 2.0, 5.0, 9.0, 20.0, 100.0, 1000.0, 10000.0]


def _lobe(model, e):
    return lambda l, v: model(N, l, v, ONE, kd=(0, 0, 0), ks=1.0, shininess=e, normalized=1.0)[..., 0]


@pytest.mark.parametrize("model", [brdf.phong, brdf.blinn_phong], ids=["phong", "blinn_phong"])
def test_normalised_lobes_albedo_is_one_at_normal_incidence_and_never_more(model):
    # Lafortune & Willems 1994 ((n+2)/2) and Giesen 2009 ((n+2)(n+4)/(8 (2^(-n/2) + n))): exact at v = n
    for e in EXPONENTS:
        width = 3 / np.sqrt(e + 1)
        albedo = [_albedo(_lobe(model, e), tv, min(width, 1.0)) for tv in INCIDENCES]
        assert albedo[0] == pytest.approx(1.0, abs=5e-5), (e, albedo[0])
        assert max(albedo) <= 1.0 + 5e-5, (e, albedo)
        assert all(a2 <= a1 + 5e-5 for a1, a2 in zip(albedo, albedo[1:])), (e, albedo)  # falls with incidence


def test_old_blinn_phong_factor_gained_energy():
    # the figures for (n+8)/8 at normal incidence, from the same integral: 1.024, 1.075, 1.018
    for e, old in ((1.0, 1.024), (9.0, 1.075), (100.0, 1.018)):
        ratio = ((e + 8) / 8) / brdf.blinn_energy_factor(e)
        assert _albedo(_lobe(brdf.blinn_phong, e), 0.0, min(3 / np.sqrt(e + 1), 1.0)) * ratio == pytest.approx(
            old, abs=1e-3)


def _gbar(s, theta_v):
    """Mean over the azimuth of h of (v.h) max(0, n.l) for l = 2 (v.h) h - v, n.h = s (closed form)."""
    mu = np.cos(theta_v)
    a, b = np.sin(theta_v) * np.sqrt(1 - s * s), mu * s
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(a > 0, (mu / (2 * s) - b) / np.where(a > 0, a, 1), np.where(b > mu / (2 * s), -2.0, 2.0))
    p0 = np.arccos(np.clip(x, -1, 1))
    return (2 * s * (a * a * (p0 + np.sin(p0) * np.cos(p0)) / 2 + 2 * a * b * np.sin(p0) + b * b * p0)
            - mu * (a * np.sin(p0) + b * p0)) / np.pi


def test_blinn_phong_bound_argument_holds():
    # docs/shading.md: albedo(theta_v) = 8 N integral_0^1 s^n gbar(s, theta_v) ds. D = gbar(., 0) - gbar(., theta_v)
    # integrates to 0 (n = 0: the constant lobe has albedo 1 everywhere) and changes sign once, from - to +;
    # s^n is non-decreasing, so integral s^n D >= 0 for every n >= 0: no incidence beats normal incidence.
    s = (np.arange(20000) + 0.5) / 20000
    g0 = _gbar(s, 0.0)
    np.testing.assert_allclose(g0, s * np.maximum(2 * s * s - 1, 0), atol=1e-15)
    for tv in np.radians(np.linspace(0.5, 90.0, 180)):
        D = g0 - _gbar(s, tv)
        assert abs(np.mean(D)) < 1e-9
        signs = np.sign(D[np.abs(D) > 1e-12])
        assert signs[0] < 0 < signs[-1] and np.count_nonzero(np.diff(signs)) == 1, np.degrees(tv)
    # normalised Phong, in c = l.r_v: k(c, theta_v) = integral over the ring l.r_v = c of max(0, n.l) dphi
    c = np.linspace(-1, 1, 40001)[1:-1]
    for tv in np.radians(np.linspace(0.5, 90.0, 180)):
        a, b = c * np.cos(tv), np.sqrt(1 - c * c) * np.sin(tv)
        p0 = np.arccos(np.clip(-a / b, -1, 1))
        D = 2 * np.pi * np.maximum(c, 0) - 2 * (a * p0 + b * np.sin(p0))
        signs = np.sign(D[np.abs(D) > 1e-12])
        assert signs[0] < 0 < signs[-1] and np.count_nonzero(np.diff(signs)) == 1, np.degrees(tv)
        assert abs(np.sum(D) * (c[1] - c[0])) < 5e-4  # n = 0: albedo 1 everywhere (sqrt ends limit the sum)
    # and the same integral reproduces the numpy twin's albedo
    for e, tv in ((9.0, 0.5), (0.3, 1.2)):
        semi = 8 * brdf.blinn_energy_factor(e) * np.mean(s ** e * _gbar(s, tv))
        assert semi == pytest.approx(_albedo(_lobe(brdf.blinn_phong, e), tv, 1.0), abs=5e-5)


def test_lambert_albedo_is_one_at_every_incidence():
    for tv in INCIDENCES:
        assert _albedo(lambda l, v: brdf.lambert(N, l, ONE)[..., 0], tv, 1.0) == pytest.approx(1.0, abs=5e-5)


def _on_A_B(sigma):
    s2 = sigma * sigma
    return 1 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)     # Oren & Nayar 1994, qualitative model


def _on_albedo_closed_form(sigma, tv):
    """Directional albedo of the qualitative model (rho = 1), integrated by hand from the paper's formula:
    A + B (2/pi) [sin(tv) (tv/2 - sin(2 tv)/4) + tan(tv) (1 - sin^3 tv)/3]."""
    A, B = _on_A_B(sigma)
    T = 2 / np.pi * (np.sin(tv) * (tv / 2 - np.sin(2 * tv) / 4) + np.tan(tv) * (1 - np.sin(tv) ** 3) / 3)
    return A + B * T


def _albedo_in_l(radiance, theta_v, k=64):
    """(1/pi) integral of L(l, v) dl over l's polar and azimuth angles, Gauss-Legendre on panels split where the
    Oren-Nayar integrand has kinks (theta_l = theta_v, dphi = pi/2), the xz plane a mirror plane."""
    x, w = np.polynomial.legendre.leggauss(k)

    def panels(edges):
        pts = [(a + b) / 2 + (b - a) / 2 * x for a, b in zip(edges, edges[1:])]
        wts = [(b - a) / 2 * w for a, b in zip(edges, edges[1:])]
        return np.concatenate(pts), np.concatenate(wts)
    th, wt = panels([0.0, theta_v, np.pi / 2] if theta_v > 0 else [0.0, np.pi / 2])
    ph, wp = panels([0.0, np.pi / 2, np.pi])
    t, p = np.meshgrid(th, ph, indexing="ij")
    l = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    v = np.array([np.sin(theta_v), 0.0, np.cos(theta_v)])
    return float(np.sum(radiance(l, v) * np.sin(t) * wt[:, None] * wp[None, :]) * 2 / np.pi)


def test_oren_nayar_albedo_matches_the_papers_model_and_its_bound():
    for sigma in (0.0, 0.1, 0.2, 0.3, 0.5, 1.0, 3.0):
        for tv in INCIDENCES:
            got = _albedo_in_l(lambda l, v: brdf.oren_nayar(N, l, v, ONE, ONE, sigma)[..., 0], tv)
            closed = _on_albedo_closed_form(sigma, tv)
            assert got == pytest.approx(closed, abs=1e-9), (sigma, np.degrees(tv))
            A, B = _on_A_B(sigma)
            assert closed <= A + B / 2 + 1e-12  # the grazing limit bounds every incidence
            if A + B / 2 <= 1:                  # sigma = 0 or sigma >= 0.326 rad: energy-conserving
                assert got <= 1 + 1e-9
    # The published qualitative model is NOT energy-conserving for 0 < sigma < 0.326 rad at grazing incidence
    # (Fujii notes the same of the Oren-Nayar models): rho (A + B/2) peaks at 1.0152 rho near sigma = 0.19.
    sig = np.linspace(0.0, 0.5, 5001)
    A, B = _on_A_B(sig)
    assert np.max(A + B / 2) == pytest.approx(1.01518, abs=1e-4) and sig[np.argmax(A + B / 2)] == pytest.approx(
        0.19, abs=0.01)


# -- Oren-Nayar against the 1994 paper, angles form ------------------------------------------------

def _oren_nayar_1994(theta_i, phi_i, theta_r, phi_r, sigma):
    """Oren & Nayar 1994, qualitative model, as printed: L_r = (rho/pi) E0 cos(theta_i) (A + B max(0,
    cos(phi_r - phi_i)) sin(alpha) tan(beta)), alpha = max(theta_i, theta_r), beta = min(...); zero when
    either direction is below the surface. Here rho = 1 and E0 = pi I with I = 1."""
    A, B = _on_A_B(sigma)
    alpha, beta = np.maximum(theta_i, theta_r), np.minimum(theta_i, theta_r)
    with np.errstate(over="ignore", invalid="ignore"):
        L = np.cos(theta_i) * (A + B * np.maximum(0, np.cos(phi_r - phi_i)) * np.sin(alpha) * np.tan(beta))
    return np.where((theta_i < np.pi / 2) & (theta_r < np.pi / 2), L, 0.0)


def _dir(theta, phi):
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def test_oren_nayar_equals_the_1994_paper_over_random_directions_and_the_horizon():
    rng = np.random.default_rng(11)
    k = 4000
    near = np.pi / 2 - 10.0 ** -rng.integers(2, 10, k)            # within 0.6 deg ... 6e-8 deg above the horizon
    below = np.pi / 2 + rng.uniform(1e-9, np.pi / 2, k)           # under the surface
    pool = np.concatenate([rng.uniform(0, np.pi / 2, k), near, below])
    ti, tr = rng.choice(pool, 3 * k), rng.choice(pool, 3 * k)
    ti[:k], tr[:k] = near, rng.permutation(near)                  # both within 0.6 deg of the horizon
    pi_, pr = rng.uniform(0, 2 * np.pi, 3 * k), rng.uniform(0, 2 * np.pi, 3 * k)
    for sigma in (0.2, 0.5, 1.2):
        expect = _oren_nayar_1994(ti, pi_, tr, pr, sigma)
        got = brdf.oren_nayar(N, _dir(ti, pi_), _dir(tr, pr), ONE, ONE, sigma)[:, 0]
        np.testing.assert_allclose(got, expect, rtol=1e-8, atol=1e-12)
        # at the horizon the model is not small (up to B): the old max(n.l, n.v, 1e-4) guard cut it up to 400x
        assert np.max(expect[:k]) > 0.9 * _on_A_B(sigma)[1]
        assert np.all(got[(ti > np.pi / 2) | (tr > np.pi / 2)] == 0)
    # the case: a viewer below the horizon sees nothing (was 0.794 I for sigma = 0.5)
    assert np.all(brdf.oren_nayar(N, (0.3, 0, 1), (0.5, 0, -1), ONE, ONE, 0.5) == 0)
