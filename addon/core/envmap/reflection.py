"""Reflection and refraction mapping (seed 002): the lookup direction and its Fresnel weight, numpy only.

v is the unit vector from the surface toward the viewer, n the unit normal (facing the viewer).

- reflection: r = reflect(−v, n) = 2 (n·v) n − v; L_o = F L_i(r)           (perfect mirror BRDF)
- refraction: t = η (−v) + (η c_i − c_t) n, c_i = n·v, c_t = √(1 − η² (1 − c_i²)), η = n_1/n_2;
  c_t² < 0 is total internal reflection: no transmitted light; L_o = (1 − F) L_i(t)
- Schlick: F = F_0 + (1 − F_0)(1 − cos θ)⁵, F_0 = ((n_2 − n_1)/(n_2 + n_1))², θ on the denser side;
  F = 0 at IOR 1 (no interface: the exact Fresnel is 0 there, Schlick's grazing term would not be).
"""
import numpy as np

from ..errors import InputError


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def reflect(v, n):
    """r = 2 (n·v) n − v (v toward the viewer; r leaves the surface)."""
    v, n = np.asarray(v, np.float64), np.asarray(n, np.float64)
    return 2.0 * _dot(n, v)[..., None] * n - v


def refract(v, n, eta):
    """(t, transmitted): Snell's t for η = n_1/n_2, zero vector and False where c_t² < 0 (TIR)."""
    v, n = np.asarray(v, np.float64), np.asarray(n, np.float64)
    ci = _dot(n, v)
    k = 1.0 - eta * eta * (1.0 - ci * ci)
    ok = k >= 0.0
    ct = np.sqrt(np.where(ok, k, 0.0))
    t = -eta * v + (eta * ci - ct)[..., None] * n
    return np.where(ok[..., None], t, 0.0), ok


def schlick_f0(ior):
    """F_0 = ((η − 1)/(η + 1))² for a relative index η = n_2/n_1."""
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def schlick(cos_theta, f0):
    """F = F_0 + (1 − F_0)(1 − cos θ)⁵."""
    c = np.clip(np.asarray(cos_theta, np.float64), 0.0, 1.0)
    return f0 + (1.0 - f0) * (1.0 - c) ** 5


def lookup(v, n, mode="REFLECT", ior=1.5, fresnel=True, inside=False):
    """(direction, weight) of environment mapping: r with F (or 1), or t with 1 − F (or 1), 0 under TIR.

    ``inside``: the ray leaves the object (η = ior instead of 1/ior). θ of Schlick is the angle on the
    denser side: θ_i entering, θ_t leaving.
    """
    if mode not in ("REFLECT", "REFRACT"):
        raise InputError(f"mode must be REFLECT or REFRACT, got {mode!r}")
    if not ior > 0:
        raise InputError(f"ior must be positive, got {ior}")
    v, n = np.asarray(v, np.float64), np.asarray(n, np.float64)
    ci = np.clip(_dot(n, v), 0.0, 1.0)
    eta = np.where(inside, ior, 1.0 / ior)
    t, ok = refract(v, n, eta)
    ct = np.abs(_dot(t, n))
    cos_dense = np.where(eta > 1.0, ct, ci)
    f = schlick(cos_dense, schlick_f0(ior)) if ior != 1.0 else np.zeros_like(ci)
    f = np.where(ok, f, 1.0)
    if mode == "REFLECT":
        return reflect(v, n), (f if fresnel else np.ones_like(f))
    w = (1.0 - f) if fresnel else np.ones_like(f)
    return t, np.where(ok, w, 0.0)
