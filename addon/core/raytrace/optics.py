"""Specular transport of Whitted's model (seed 004, "Ray-tracing", eq. 2): the mirror direction r, the
refracted direction t (Snell's law), total internal reflection and the Fresnel split k_s / k_t.

Directions are unit (..., 3) arrays; ``d`` is the incoming ray's direction (travelling toward the
surface), ``n`` the unit normal on the side the ray comes from (n·d < 0).
"""
import numpy as np

from ..brdf import F_dielectric, F_schlick, dot


def reflect_dir(d, n):
    """r = d - 2 (n·d) n: the mirror direction of the ray d about n (law of reflection)."""
    return d - 2.0 * dot(n, d)[..., None] * n


def refract_dir(d, n, eta):
    """Snell's law η₁ sin θ₁ = η₂ sin θ₂ with ``eta`` = η₁/η₂ (pbrt-v3 eq. 8.8):
    t = η d + (η cos θ₁ - cos θ₂) n, cos θ₁ = -n·d, cos²θ₂ = 1 - η² (1 - cos²θ₁).

    Returns (t, tir): ``tir`` True where cos²θ₂ < 0, total internal reflection (t is then 0).
    """
    eta = np.asarray(eta, np.float64)
    cos_i = -dot(n, d)
    cos2_t = 1.0 - eta ** 2 * np.maximum(1.0 - cos_i ** 2, 0.0)
    tir = cos2_t < 0.0
    cos_t = np.sqrt(np.maximum(cos2_t, 0.0))
    t = eta[..., None] * d + (eta * cos_i - cos_t)[..., None] * n
    return np.where(tir[..., None], 0.0, t), tir


def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of a smooth dielectric for light arriving at cos θ₁ from the side of
    index η₁, ``eta`` = η₁/η₂; 1 under total internal reflection (core.brdf.F_dielectric with the relative
    index η₂/η₁)."""
    return F_dielectric(cos_i, 1.0 / np.asarray(eta, np.float64))


def fresnel_conductor(cos_i, f0):
    """A metal's reflectance k_s(θ) = F0 + (1 - F0)(1 - cos θ)⁵ (Schlick 1994) with F0 = Base Color: what Cycles'
    Principled BSDF gives a metal of specular tint 1 (the F82-tint model reduces to Schlick)."""
    return F_schlick(np.asarray(cos_i, np.float64)[..., None], np.asarray(f0, np.float64))


def glass_split(d, n_geo, ior, n_shade=None):
    """For a ray d hitting a glass surface of index ``ior`` whose outward geometric normal is ``n_geo`` (which
    side the ray comes from) and shading normal ``n_shade`` (default n_geo, outward): the shading normal on the
    ray's side, η = η₁/η₂ (1/ior entering, ior leaving), k_s = F (the reflected share), k_t = 1 - F and the
    total-internal-reflection mask. Energy: k_s + k_t = 1 at every angle."""
    entering = dot(n_geo, d) < 0.0
    n_shade = n_geo if n_shade is None else n_shade
    n = np.where(entering[..., None], n_shade, -n_shade)
    eta = np.where(entering, 1.0 / ior, ior)
    cos_i = np.clip(-dot(n, d), 0.0, 1.0)
    _, tir = refract_dir(d, n, eta)
    ks = np.where(tir, 1.0, fresnel_dielectric(cos_i, eta))
    return n, eta, ks, 1.0 - ks, tir
