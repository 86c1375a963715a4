"""Directional light maps: L1 spherical-harmonic irradiance fitted to irradiances baked for tilted normals.

Per texel, Cycles bakes E_k = E(n_k) for K shading normals n_k (the mesh normal N and tilts of it); the least
squares fit E(n) ≈ a + b·n over them gives the four L1 coefficients of the radiance in the convention of
:mod:`.envmap.sh9` (Ramamoorthi & Hanrahan 2001: L_lm = ∫ L Y_lm, E(n) = Σ Â_l L_lm Y_lm(n)):

    E(n) = π Y00 L00 + (2π/3) Y1 (L1-1 n_y + L10 n_z + L11 n_x),  Y00 = 1/(2√π), Y1 = √(3/(4π))
         = 0.886227 L00 + 1.023328 (L1-1 n_y + L10 n_z + L11 n_x)

stored in Godot 4's order (L0, L1 m=-1, m=0, m=+1), RGB each. numpy only.
"""
import math

import numpy as np

Y00 = 0.5 / math.sqrt(math.pi)
Y1 = math.sqrt(3.0 / (4.0 * math.pi))
E0 = math.pi * Y00
"""E(n) per unit L00: π Y00 = 0.886227."""
E1 = 2.0 * math.pi / 3.0 * Y1
"""E(n) per unit L1m and unit normal component: (2π/3) Y1 = 1.023328."""

NAMES = ("L00", "L1-1", "L10", "L11")
"""The four coefficient maps, Godot's order: L0, then the L1 maps of n_y, n_z, n_x."""
AXES = (None, 1, 2, 0)
"""The normal component each coefficient multiplies (None: the constant)."""
CHANNELS = tuple(f"{name}.{c}" for name in NAMES for c in "RGB")
"""EXR channel names of a directional map, in Godot's order."""

TETRAHEDRON = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]) / math.sqrt(3.0)
"""World directions d_k whose projections u_k = d_k - (d_k·N)N on any tangent plane span it
(Σ u_k u_kᵀ = (4/3)(I - N Nᵀ)): the tilts never degenerate."""

FIT_ANGLE = 50.0
"""τ = tan(FIT_ANGLE): a tilt of atan(τ |u_k|), 44.2° on faces normal to a world axis (|u_k| = √(2/3))."""


def tilt_vectors(angle=FIT_ANGLE):
    """[t_k] of the K = 5 bakes: 0 (n = N), then τ d_k; the material tilts n_k = normalize(N + t_k - (t_k·N) N)."""
    tau = math.tan(math.radians(angle))
    return [(0.0, 0.0, 0.0)] + [tuple(float(x) for x in tau * d) for d in TETRAHEDRON]


def tilted(normal, t):
    """n = normalize(N + t - (t·N) N): the normal the bake material uses for tilt ``t`` (numpy reference)."""
    n = np.asarray(normal, np.float64)
    t = np.asarray(t, np.float64)
    v = n + t - np.sum(n * t, axis=-1, keepdims=True) * n
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


RATIO = 4.0
"""|b| ≤ RATIO · a: the largest directional part Godot's SH packing (and the glTF extras, which use it) holds on
every axis, |b_m| ≤ 4a, bounded by the norm so that it holds in any frame. (An L1 model of a non-negative radiance
has |b| ≤ 2a; the fit may go beyond, as it describes E(n) near the surface normal, not over the whole sphere.)"""


def fit(irradiance, normals):
    """Least squares E_k ≈ a + b·n_k per texel, constrained to |b| ≤ RATIO · a: ``irradiance`` K arrays (..., C),
    ``normals`` K arrays (..., 3); returns (a (..., C), b (..., 3, C)); zero where the K normals do not determine b
    (uncovered texels).

    Near the surface normal a sun's E = E_s n·s is exactly linear with a = 0, which no L1 model of a radiance (and no
    engine's L1 decoding) can hold; where the free fit leaves the cone, b keeps its direction u and a is the least
    squares scale of E_k ≈ a (1 + RATIO u·n_k), at least 0."""
    e = np.stack([np.asarray(x, np.float64) for x in irradiance], axis=-2)              # (..., K, C)
    n = np.stack([np.asarray(x, np.float64) for x in normals], axis=-2)                 # (..., K, 3)
    x = np.concatenate([np.ones(n.shape[:-1] + (1,)), n], axis=-1)                      # (..., K, 4)
    xtx = np.einsum("...ki,...kj->...ij", x, x)
    xte = np.einsum("...ki,...kc->...ic", x, e)
    ok = np.linalg.cond(xtx) < 1e8
    beta = np.zeros(xte.shape)
    if ok.any():
        beta[ok] = np.linalg.solve(xtx[ok], xte[ok])
    a, b = beta[..., 0, :], beta[..., 1:, :]
    size = np.linalg.norm(b, axis=-2)                                                   # (..., C)
    out = (a < 0) | (size > RATIO * a)
    if out.any():
        u = b / np.maximum(size, 1e-300)[..., None, :]
        w = 1.0 + RATIO * np.einsum("...ki,...ic->...kc", n, u)                         # (..., K, C)
        scale = np.clip((e * w).sum(-2) / np.maximum((w * w).sum(-2), 1e-300), 0.0, None)
        a = np.where(out, scale, a)
        b = np.where(out[..., None, :], RATIO * scale[..., None, :] * u, b)
    return a, b


def coefficients(a, b):
    """(..., 4·C) L1 SH coefficients [L00, L1-1, L10, L11] × C channels from E(n) = a + b·n."""
    parts = [np.asarray(a) / E0] + [np.asarray(b)[..., axis, :] / E1 for axis in AXES[1:]]
    return np.concatenate(parts, axis=-1)


def linear(coeffs, channels=3):
    """(a (..., C), b (..., 3, C)) of E(n) = a + b·n from (..., 4·C) coefficients."""
    c = np.asarray(coeffs, np.float64).reshape(np.shape(coeffs)[:-1] + (4, channels))
    b = np.zeros(c.shape[:-2] + (3, channels))
    for i, axis in enumerate(AXES[1:], start=1):
        b[..., axis, :] = E1 * c[..., i, :]
    return E0 * c[..., 0, :], b


def irradiance(coeffs, normals, channels=3):
    """E(n) (..., C) reconstructed from (..., 4·C) coefficients at unit normals (..., 3), as an engine does."""
    a, b = linear(coeffs, channels)
    return a + np.einsum("...i,...ic->...c", np.asarray(normals, np.float64), b)


def combine(parts, tilts=None):
    """Coefficients (..., 12) from the bakes of a directional map: [E_0, n_0, E_1, n_1, ...] (E in W/m² RGB,
    n the world-space shading normal each E was baked with)."""
    a, b = fit(parts[0::2], parts[1::2])
    return coefficients(a, b).astype(np.float32)


def ambient(coeffs):
    """E0 L00 (..., 3): the mean of E(n) over all directions n of the fitted model (the preview's quantity)."""
    return E0 * np.asarray(coeffs)[..., :3]


def godot_packed(coeffs):
    """Godot 4.3+ LightmapGI SH textures from (..., 12) coefficients: (L0' (..., 3), [l1' (..., 3)] × 3) with
    L0' = Y00 L00 = E/π's constant and l1' = clamp(Y1' L1m / (8 L0') + 0.5, 0, 1), Y1' = E1/π, so that Godot's
    shader, L0' + 4 L0' Σ (2 l1' - 1) n, gives E(n)/π; where |Y1' L1m| > 4 L0' the clamp loses energy."""
    c = np.asarray(coeffs, np.float64)
    l0 = E0 / math.pi * c[..., 0:3]
    safe = np.where(np.abs(l0) > 0, l0, 1.0)
    l1 = [np.where(np.abs(l0) > 0, np.clip(E1 / math.pi * c[..., 3 * i:3 * i + 3] / (8 * safe) + 0.5, 0, 1), 0.5)
          for i in (1, 2, 3)]
    return l0, l1


def to_y_up(coeffs):
    """The coefficients in glTF's (and Godot's) Y-up frame from Blender's Z-up one: x' = x, y' = z, z' = -y."""
    c = np.asarray(coeffs).reshape(np.shape(coeffs)[:-1] + (4, -1))
    out = c.copy()
    out[..., 1, :] = c[..., 2, :]          # L1-1 (n_y') = L10 (n_z)
    out[..., 2, :] = -c[..., 1, :]         # L10 (n_z') = -L1-1 (n_y)
    return out.reshape(np.shape(coeffs))


def chiang_shadowing(cos_light, cos_tilt):
    """Cycles' bump-terminator term on a diffuse closure whose normal is tilted from the shading normal by θ_d
    (Chiang et al. 2019, "Taming the shadow terminator"): G = 2 / (1 + √(1 + α² tan²θ_l)), α² = min(1, tan²θ_d / 8),
    θ_l the light's angle from the shading normal (measured: a sun at elevation 5-60° over a 60° tilt, within 1e-4)."""
    c = np.clip(np.asarray(cos_light, np.float64), 1e-12, 1.0)
    a2 = min(1.0, (1.0 - cos_tilt ** 2) / max(cos_tilt ** 2, 1e-12) / 8.0)
    return 2.0 / (1.0 + np.sqrt(1.0 + a2 * (1.0 - c * c) / (c * c)))


def cycles_irradiance(n, sky=(0.0, 0.0), sun=None, shading=(0.0, 0.0, 1.0), steps=96):
    """E(n) that Cycles' DIFFUSE bake gives a white Lambert of normal ``n`` on a flat, unoccluded surface of shading
    normal ``shading``: sky L(l) = sky[0] + sky[1] l_z, sun = (E_s, direction s) or None.

    E(n) = ∫ L(l) (n·l)⁺ G(l) dl over the hemisphere l·N_s > 0 (Cycles drops directions below the surface), G the
    :func:`chiang_shadowing` term, by midpoint quadrature (``steps`` in θ, 2 steps in φ); n (..., 3) unit."""
    ns = np.asarray(shading, np.float64)
    ns = ns / np.linalg.norm(ns)
    helper = np.array([1.0, 0.0, 0.0]) if abs(ns[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(ns, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(ns, t1)
    th = (np.arange(steps) + 0.5) * (0.5 * math.pi / steps)
    ph = (np.arange(4 * steps) + 0.5) * (2 * math.pi / (4 * steps))
    T, P = np.meshgrid(th, ph, indexing="ij")
    l = (np.sin(T) * np.cos(P))[..., None] * t1 + (np.sin(T) * np.sin(P))[..., None] * t2 + np.cos(T)[..., None] * ns
    dw = (np.sin(T) * (0.5 * math.pi / steps) * (2 * math.pi / (4 * steps))).ravel()
    l = l.reshape(-1, 3)
    radiance = sky[0] + sky[1] * l[:, 2]
    n = np.asarray(n, np.float64)
    flat = n.reshape(-1, 3)
    out = np.zeros(len(flat))
    for i, v in enumerate(flat):
        g = chiang_shadowing(l @ ns, float(v @ ns)) if not np.allclose(v, ns) else 1.0
        out[i] = np.sum(radiance * np.maximum(l @ v, 0.0) * g * dw)
        if sun is not None:
            s = np.asarray(sun[1], np.float64) / np.linalg.norm(sun[1])
            if s @ ns > 0:
                gs = chiang_shadowing(s @ ns, float(v @ ns)) if not np.allclose(v, ns) else 1.0
                out[i] += sun[0] * max(float(s @ v), 0.0) * gs
    return out.reshape(n.shape[:-1])
