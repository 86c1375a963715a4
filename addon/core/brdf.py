"""Local shading models of the notes as numpy twins of the node groups (REFERENCE.md §1-2).

Directions are arrays of shape (..., 3) in world space: ``n`` the surface normal,
``l`` toward the light (any length), ``v`` toward the viewer. Colours are (3,) or
(..., 3). Model functions return outgoing radiance (..., 3) for a light of
intensity ``I`` = E_perp / pi (REFERENCE.md §1), so a white Lambertian surface
facing the light returns ``I``. Every term is zero where n.l <= 0; dot products are
clamped at 0 before a power, and every division is guarded, so every output is
finite for every direction pair. The node groups in ``addon/nodes`` evaluate the
same expressions, with the same clamps, term by term.
"""
import numpy as np

#: Smallest roughness (m or alpha): below it D is a delta and float32 breaks (REFERENCE.md §2).
MIN_ROUGHNESS = 1e-3
#: Guard for divisions by cosines (n.l, n.v, n.h, v.h).
EPS = 1e-4
#: Guard for vector lengths.
TINY = 1e-12


# -- vector helpers ---------------------------------------------------------------------------

def dot(a, b):
    """a . b over the last axis."""
    return np.sum(np.asarray(a, float) * np.asarray(b, float), axis=-1)


def normalize(a):
    """a / |a|, and 0 for a zero vector (like the shader's safe normalize)."""
    a = np.asarray(a, float)
    length = np.linalg.norm(a, axis=-1, keepdims=True)
    return np.where(length > TINY, a / np.maximum(length, TINY), 0.0)


def reflect(l, n):
    """Mirror direction r = 2 n (n.l) - l (seed 004, eq. 1)."""
    return 2.0 * n * dot(n, l)[..., None] - l


def half_vector(l, v):
    """h = (l + v) / |l + v| (0 where l = -v)."""
    return normalize(np.asarray(l, float) + np.asarray(v, float))


def lit(n_l):
    """Mask 1 where n.l > 0, else 0: every term of every model is zero below the horizon."""
    return (np.asarray(n_l) > 0.0).astype(float)


def _array(x):
    return np.asarray(x, float)


def _frames(n, l, v):
    n, l, v = normalize(n), normalize(l), normalize(v)
    return n, l, v, dot(n, l), dot(n, v)


# -- Phong and Blinn-Phong (seed 004; REFERENCE.md §2) -----------------------------------------

def phong_lobe(r_v, shininess):
    """(r.v)^n with r.v clamped at 0."""
    return np.power(np.maximum(r_v, 0.0), shininess)


def blinn_lobe(n_h, shininess):
    """(n.h)^n with n.h clamped at 0."""
    return np.power(np.maximum(n_h, 0.0), shininess)


def phong_normalization(shininess, n_l, normalized):
    """Factor of the lobe: 1 (classic) or ((n+2)/2)(n.l) (modified Phong, Lafortune & Willems 1994).

    ``normalized`` in [0, 1] blends the two linearly (the node input is a plain number).
    """
    energy = (shininess + 2.0) / 2.0 * np.maximum(n_l, 0.0)
    return (1.0 - normalized) + normalized * energy


def blinn_energy_factor(shininess):
    """pi times the exact normalisation of the (n.h)^n lobe (Giesen 2009): (n+2)(n+4) / (8 (2^(-n/2) + n)).

    With it the albedo at normal incidence is exactly k_s, and at any other incidence it is lower
    (docs/shading.md gives the argument). The exponent is taken as max(n, 0).
    """
    n = np.maximum(_array(shininess), 0.0)
    return (n + 2.0) * (n + 4.0) / (8.0 * (np.exp2(-n / 2.0) + n))


def blinn_normalization(shininess, n_l, normalized):
    """Factor of the lobe: 1 (classic) or blinn_energy_factor(n) (n.l) (energy-normalised Blinn-Phong)."""
    energy = blinn_energy_factor(shininess) * np.maximum(n_l, 0.0)
    return (1.0 - normalized) + normalized * energy


def ambient_term(ka, ambient_light):
    """k_a I_a (seed 004, eq. 1)."""
    return _array(ka)[..., None] * _array(ambient_light)


def _phong_family(n, l, v, I, ka, ambient_light, kd, ks, shininess, emission, normalized, blinn):
    n, l, v, n_l, _ = _frames(n, l, v)
    shininess, normalized = _array(shininess), _array(normalized)
    if blinn:
        lobe = blinn_lobe(dot(n, half_vector(l, v)), shininess) * blinn_normalization(shininess, n_l, normalized)
    else:
        lobe = phong_lobe(dot(reflect(l, n), v), shininess) * phong_normalization(shininess, n_l, normalized)
    mask = lit(n_l)
    diffuse = _array(kd) * (mask * np.maximum(n_l, 0.0))[..., None]
    specular = _array(ks)[..., None] * (mask * lobe)[..., None]
    return ambient_term(ka, ambient_light) + _array(I) * (diffuse + specular) + _array(emission)


def phong(n, l, v, I, ka=0.0, ambient_light=(0, 0, 0), kd=(0.8, 0.8, 0.8), ks=0.5, shininess=32.0,
          emission=(0, 0, 0), normalized=0.0):
    """L = k_a I_a + I (k_d (n.l) + k_s N (r.v)^n) + I_e, N = 1 or ((n+2)/2)(n.l) (REFERENCE.md §2)."""
    return _phong_family(n, l, v, I, ka, ambient_light, kd, ks, shininess, emission, normalized, False)


def blinn_phong(n, l, v, I, ka=0.0, ambient_light=(0, 0, 0), kd=(0.8, 0.8, 0.8), ks=0.5, shininess=32.0,
                emission=(0, 0, 0), normalized=0.0):
    """L = k_a I_a + I (k_d (n.l) + k_s N (n.h)^n) + I_e, N = 1 or (n+2)(n+4)/(8 (2^(-n/2) + n)) (n.l)."""
    return _phong_family(n, l, v, I, ka, ambient_light, kd, ks, shininess, emission, normalized, True)


# -- Oren-Nayar, qualitative model (Oren & Nayar 1994; REFERENCE.md §2, §6) ----------------------

def oren_nayar_A(sigma):
    """A = 1 - 0.5 sigma^2 / (sigma^2 + 0.33)."""
    s2 = np.square(_array(sigma))
    return 1.0 - 0.5 * s2 / (s2 + 0.33)


def oren_nayar_B(sigma):
    """B = 0.45 sigma^2 / (sigma^2 + 0.09)."""
    s2 = np.square(_array(sigma))
    return 0.45 * s2 / (s2 + 0.09)


def oren_nayar_angular(n_l, n_v, l_v):
    """(n.l) max(0, cos(phi_v - phi_l)) sin(alpha) tan(beta) in the bounded vector form, for n.l, n.v > 0:
    max(0, l.v - (n.l)(n.v)) * (n.l) / max(n.l, n.v, 1e-12), each factor in [0, 1].

    The guard only acts where both cosines are below 1e-12; elsewhere this is the model exactly.
    """
    s = np.maximum(l_v - n_l * n_v, 0.0)
    return s * np.maximum(n_l, 0.0) / np.maximum(np.maximum(n_l, n_v), TINY)


def oren_nayar(n, l, v, I, albedo=(0.8, 0.8, 0.8), sigma=0.3):
    """L = rho I (n.l) (A + B max(0, cos dphi) sin alpha tan beta), zero unless n.l > 0 and n.v > 0;
    sigma = 0 is Lambert exactly (for n.v > 0)."""
    n, l, v, n_l, n_v = _frames(n, l, v)
    factor = (oren_nayar_A(sigma) * np.maximum(n_l, 0.0)
              + oren_nayar_B(sigma) * oren_nayar_angular(n_l, n_v, dot(l, v)))
    return _array(I) * _array(albedo) * (lit(n_l) * lit(n_v) * factor)[..., None]


def lambert(n, l, I, albedo=(1.0, 1.0, 1.0)):
    """L = rho I (n.l)+ : the white Lambertian surface facing the light returns I (REFERENCE.md §1)."""
    n_l = dot(normalize(n), normalize(l))
    return _array(I) * _array(albedo) * np.maximum(n_l, 0.0)[..., None]


# -- Cook-Torrance microfacet specular (Walter et al. 2007; REFERENCE.md §2) ---------------------

def clamp_roughness(roughness):
    """m or alpha clamped to >= MIN_ROUGHNESS so that D never becomes a delta."""
    return np.maximum(_array(roughness), MIN_ROUGHNESS)


def D_beckmann(n_h, m):
    """D = exp(-tan^2(theta_h)/m^2) / (pi m^2 cos^4(theta_h)), written as exp((c^2-1)/(m^2 c^2))."""
    c = np.maximum(n_h, EPS)
    c2 = c * c
    m2 = np.square(m)
    return np.exp((c2 - 1.0) / (m2 * c2)) / (np.pi * m2 * c2 * c2) * (np.asarray(n_h) > 0)


def D_ggx(n_h, alpha):
    """D = alpha^2 / (pi (cos^2(theta_h) (alpha^2 - 1) + 1)^2)."""
    c = np.maximum(n_h, 0.0)
    a2 = np.square(alpha)
    t = c * c * (a2 - 1.0) + 1.0
    return a2 / (np.pi * t * t) * (np.asarray(n_h) > 0)


def G_cook_torrance(n_h, n_v, n_l, v_h):
    """G = min(1, 2 (n.h)(n.v)/(v.h), 2 (n.h)(n.l)/(v.h)) (Cook & Torrance 1982)."""
    vh = np.maximum(v_h, EPS)
    nh = np.maximum(n_h, 0.0)
    return np.minimum(1.0, np.minimum(2 * nh * np.maximum(n_v, 0.0) / vh, 2 * nh * np.maximum(n_l, 0.0) / vh))


def tan2(cos_theta):
    """tan^2(theta) = (1 - c^2)/c^2 with c clamped to >= eps."""
    c = np.maximum(cos_theta, EPS)
    return np.maximum(1.0 - c * c, 0.0) / (c * c)


def lambda_ggx(cos_theta, alpha):
    """Smith Lambda for GGX: (sqrt(1 + alpha^2 tan^2 theta) - 1) / 2."""
    return (np.sqrt(1.0 + np.square(alpha) * tan2(cos_theta)) - 1.0) / 2.0


def lambda_beckmann(cos_theta, m):
    """Smith Lambda for Beckmann, Walter et al. 2007 rational fit of (erf(a) - 1)/2 + exp(-a^2)/(2 a sqrt(pi)):
    a = 1/(m tan theta); (1 - 1.259 a + 0.396 a^2)/(3.535 a + 2.181 a^2) for a < 1.6, else 0."""
    a = np.maximum(1.0 / (m * np.sqrt(np.maximum(tan2(cos_theta), TINY))), EPS)
    fit = (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a)
    return np.where(a < 1.6, fit, 0.0)


def G_smith(n_l, n_v, roughness, distribution):
    """Height-correlated Smith G = 1 / (1 + Lambda(l) + Lambda(v)); ``distribution`` 0 Beckmann, 1 GGX."""
    lam_l = (1 - distribution) * lambda_beckmann(n_l, roughness) + distribution * lambda_ggx(n_l, roughness)
    lam_v = (1 - distribution) * lambda_beckmann(n_v, roughness) + distribution * lambda_ggx(n_v, roughness)
    return 1.0 / (1.0 + lam_l + lam_v)


def F_schlick(v_h, F0):
    """F = F0 + (1 - F0)(1 - v.h)^5 (Schlick 1994)."""
    return F0 + (1.0 - F0) * np.power(1.0 - np.clip(v_h, 0.0, 1.0), 5)


def F_dielectric(cos_i, eta):
    """Exact unpolarised Fresnel reflectance of a dielectric of relative index ``eta`` (what Schlick approximates)."""
    c = np.clip(cos_i, 0.0, 1.0)
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.where(g2 > 0, 0.5 * a * a * (1.0 + b * b), 1.0)


def microfacet_terms(n_l, n_v, n_h, v_h, F0, roughness, distribution, geometry):
    """(F, D, G) of the specular lobe; ``distribution`` 0 Beckmann / 1 GGX, ``geometry`` 0 CT / 1 Smith.

    Both switches are blended linearly, so 0 and 1 select one term exactly.
    """
    r = clamp_roughness(roughness)
    distribution, geometry = _array(distribution), _array(geometry)
    D = (1 - distribution) * D_beckmann(n_h, r) + distribution * D_ggx(n_h, r)
    G = (1 - geometry) * G_cook_torrance(n_h, n_v, n_l, v_h) + geometry * G_smith(n_l, n_v, r, distribution)
    return F_schlick(v_h, _array(F0)), D, G


def cook_torrance_brdf(n, l, v, F0=0.04, roughness=0.3, distribution=1.0, geometry=1.0):
    """f_s = F D G / (4 (n.l)(n.v)) in 1/sr, zero unless n.l > 0 and n.v > 0 (for albedo integrals)."""
    n, l, v, n_l, n_v = _frames(n, l, v)
    h = half_vector(l, v)
    F, D, G = microfacet_terms(n_l, n_v, dot(n, h), dot(v, h), F0, roughness, distribution, geometry)
    both = lit(n_l) * lit(n_v)
    return both * F * D * G / (4.0 * np.maximum(n_l, EPS) * np.maximum(n_v, EPS))


def cook_torrance(n, l, v, I, kd=(0.5, 0.5, 0.5), ks=1.0, F0=0.04, roughness=0.3, distribution=1.0,
                  geometry=1.0):
    """L = I k_d (n.l) + pi I k_s F D G / (4 (n.v)), specular zero unless n.v > 0 (REFERENCE.md §2)."""
    n, l, v, n_l, n_v = _frames(n, l, v)
    h = half_vector(l, v)
    F, D, G = microfacet_terms(n_l, n_v, dot(n, h), dot(v, h), F0, roughness, distribution, geometry)
    mask = lit(n_l)
    specular = mask * lit(n_v) * np.pi * _array(ks) * F * D * G / (4.0 * np.maximum(n_v, EPS))
    diffuse = mask * np.maximum(n_l, 0.0)
    return _array(I) * (_array(kd) * diffuse[..., None] + specular[..., None])


# -- integration helpers (for albedo checks and charts) ------------------------------------------

def hemisphere_grid(n_theta=256, n_phi=512):
    """Midpoint grid over the upper hemisphere about +z: (directions (T, P, 3), solid-angle weights (T, P))."""
    theta = (np.arange(n_theta) + 0.5) * (np.pi / 2) / n_theta
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    w = np.sin(t) * (np.pi / 2 / n_theta) * (2 * np.pi / n_phi)
    return d, w


def direction(theta, phi=0.0):
    """Unit vector at polar angle ``theta`` from +z and azimuth ``phi`` (radians, broadcast)."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)


def half_vector_map(x, y, theta_v, width=1.0):
    """Map (x, y) in [0, 1]^2 to light directions through the half vector, for albedo integrals about n = +z.

    v lies at polar angle ``theta_v`` in the xz plane; theta_h = atan(width tan(x pi/2)) (dense within
    ``width`` of tan theta_h = 0, so lobes of any width are resolved), phi_h = pi y (the xz plane is a
    mirror plane: the density is doubled); l = 2 (v.h) h - v, dl = 4 (v.h) dh. Returns (h, l, v, J) with
    J = dl / (dx dy), 0 where v.h <= 0, so that the integral of g(l) over the sphere is that of g J over
    the unit square (l below the horizon included: the models are zero there).
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    tx = np.tan(x * np.pi / 2)
    theta = np.arctan(width * tx)
    dtheta = width * (np.pi / 2) / np.cos(x * np.pi / 2) ** 2 / (1 + (width * tx) ** 2)
    h = direction(theta, np.pi * y)
    v = direction(theta_v)
    v_h = h @ v
    l = 2 * np.maximum(v_h, 0.0)[..., None] * h - v
    J = np.where(v_h > 0, 4 * v_h * np.sin(theta) * dtheta * 2 * np.pi, 0.0)
    return h, l, v, J


def half_vector_quadrature(theta_v, width=1.0, n_theta=512, n_phi=256):
    """Midpoint rule of :func:`half_vector_map`: (l (T, P, 3), v (3,), weights (T, P)) with
    sum(g(l) * weights) ~ integral of g over the sphere of l."""
    x = (np.arange(n_theta) + 0.5) / n_theta
    y = (np.arange(n_phi) + 0.5) / n_phi
    _, l, v, J = half_vector_map(x[:, None], y[None, :], theta_v, width)
    return l, v, J / (n_theta * n_phi)


def lobe_width(shininess):
    """Width in tan(theta_h) of a (n.h)^n or (r.v)^n lobe, for :func:`half_vector_quadrature`."""
    return float(np.clip(3.0 / np.sqrt(np.maximum(shininess, 0.0) + 1.0), 1e-3, 1.0))


def directional_albedo(radiance, theta_v, width=1.0, n_theta=512, n_phi=256):
    """rho(v) = (1/pi) integral of L(l, v) dl for a model's radiance L under I = 1 (so rho = integral of f (n.l)).

    ``radiance(l, v)`` returns (T, P) radiance with n = +z; a white Lambertian surface gives 1.
    """
    l, v, w = half_vector_quadrature(theta_v, width, n_theta, n_phi)
    return float(np.sum(radiance(l, v) * w) / np.pi)
