"""Irradiance from nine spherical-harmonic coefficients (Ramamoorthi & Hanrahan 2001)."""
import numpy as np

from .latlong import latlong_angles, latlong_directions


#: Real SH normalisation constants for (l, m) in the order of :func:`sh9_basis`.
SH9_NAMES = ("L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22")
_C0, _C1, _C2, _C3, _C4 = 0.282095, 0.488603, 1.092548, 0.315392, 0.546274

#: Â_l: the clamped cosine's SH convolution weights π, 2π/3, π/4 (R&H 2001, eq. 8).
A_HAT = np.array([np.pi, 2 * np.pi / 3, 2 * np.pi / 3, 2 * np.pi / 3,
                  np.pi / 4, np.pi / 4, np.pi / 4, np.pi / 4, np.pi / 4])


def sh9_basis(d):
    """Y_lm(d) for l <= 2, (…, 9): 1, y, z, x, xy, yz, 3z²−1, xz, x²−y² times R&H's constants."""
    d = np.asarray(d, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.full_like(x, _C0), _C1 * y, _C1 * z, _C1 * x,
                     _C2 * x * y, _C2 * y * z, _C3 * (3 * z * z - 1), _C2 * x * z, _C4 * (x * x - y * y)], axis=-1)


def sh9_coefficients(env):
    """L_lm = ∫ L(l) Y_lm(l) dl over the lat-long map (9, C), by separable quadrature.

    Each Y_lm is a product f(θ) g(φ), so the sum over a pixel grid factors into
    a column projection (H, 5, C) against g ∈ {1, cos φ, sin φ, cos 2φ, sin 2φ}
    and a row sum against f(θ) Δω(θ): O(H W C) with no per-pixel basis array.
    """
    env = np.asarray(env, np.float32)
    h, w, c = env.shape
    theta, phi = latlong_angles(h, w)
    dphi = 2 * np.pi / w
    # exact integrals over each pixel of a piecewise-constant map: sinc factors in φ, closed forms in θ
    sinc1, sinc2 = np.sin(dphi / 2) / (dphi / 2), np.sin(dphi) / dphi
    g = np.stack([np.ones(w), sinc1 * np.cos(phi), sinc1 * np.sin(phi), sinc2 * np.cos(2 * phi),
                  sinc2 * np.sin(2 * phi)], axis=1) * dphi
    cols = np.einsum("hwc,wk->hkc", env, g.astype(np.float32), optimize=True).astype(np.float64)
    g1, gc, gs, gc2, gs2 = (cols[:, k] for k in range(5))
    r = _row_integrals(h)
    coeffs = np.stack([
        _C0 * (r["1"][:, None] * g1).sum(0),
        _C1 * (r["s"][:, None] * gs).sum(0),
        _C1 * (r["c"][:, None] * g1).sum(0),
        _C1 * (r["s"][:, None] * gc).sum(0),
        _C2 * 0.5 * (r["ss"][:, None] * gs2).sum(0),          # xy = sin²θ sin2φ / 2
        _C2 * (r["sc"][:, None] * gs).sum(0),                 # yz
        _C3 * (r["3cc-1"][:, None] * g1).sum(0),
        _C2 * (r["sc"][:, None] * gc).sum(0),                 # xz
        _C4 * (r["ss"][:, None] * gc2).sum(0),                # x² − y² = sin²θ cos2φ
    ])
    return coeffs


def _row_integrals(h):
    """∫ f(θ) sin θ dθ over each row's band of θ for the θ-factors of the nine Y_lm."""
    t = np.arange(h + 1) * np.pi / h
    c, s = np.cos(t), np.sin(t)
    F = {"1": -c, "c": s * s / 2, "3cc-1": c - c ** 3, "s": t / 2 - np.sin(2 * t) / 4,
         "sc": s ** 3 / 3, "ss": c ** 3 / 3 - c}
    return {k: v[1:] - v[:-1] for k, v in F.items()}


def sh9_irradiance(coeffs, normals):
    """E(n) = Σ_lm Â_l L_lm Y_lm(n) (R&H 2001, eq. 7), (…, C) W/m²."""
    return sh9_basis(normals) @ (A_HAT[:, None] * np.asarray(coeffs, np.float64))


def irradiance_map_sh9(env, width=64, coeffs=None):
    """Irradiance lat-long map (width/2, width, C) from the nine coefficients of ``env``."""
    coeffs = sh9_coefficients(env) if coeffs is None else coeffs
    return sh9_irradiance(coeffs, latlong_directions(width // 2, width))
