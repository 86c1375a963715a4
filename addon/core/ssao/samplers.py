"""Random directions and sample budgets of the SSAO methods: tangent frames, ball and cosine-hemisphere samples, horizon slices."""
import numpy as np


# --------------------------------------------------------------------------- sampling

def orthonormal_basis(n):
    """Tangent frame (t, b) of unit normals n (Duff et al. 2017, branchless, no singularity)."""
    sign = np.where(n[..., 2] >= 0, 1.0, -1.0).astype(np.float32)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1.0 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], -1)
    bb = np.stack([b, sign + n[..., 1] ** 2 * a, -n[..., 1]], -1)
    return t.astype(np.float32), bb.astype(np.float32)


def uniform_ball(rng, shape):
    """Points uniform in the unit ball: direction uniform on the sphere, radius u^(1/3)."""
    return np.stack(ball_from_uniform(rng.random(shape + (3,), dtype=np.float32)), -1)


def ball_from_uniform(u):
    """:func:`uniform_ball` from its uniforms u (..., 3): z = 2u0 - 1, φ = 2π u1, ρ = u2^(1/3);
    returns (x, y, z) arrays ρ (√(1-z²) cos φ, √(1-z²) sin φ, z)."""
    z = 2.0 * u[..., 0] - 1.0
    phi = 2.0 * np.pi * u[..., 1]
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    r = np.cbrt(u[..., 2])
    x = s * np.cos(phi)
    x *= r
    s *= np.sin(phi)
    s *= r
    z *= r
    return x, s, z


def cosine_hemisphere(rng, shape):
    """Cosine-weighted unit directions about +Z (Malley: uniform disk lifted), pdf = cosθ/π."""
    return np.stack(hemisphere_from_uniform(rng.random(shape + (2,), dtype=np.float32)), -1)


def hemisphere_from_uniform(u):
    """:func:`cosine_hemisphere` from its uniforms u (..., 2): returns (x, y, z) arrays
    (√u0 cos 2πu1, √u0 sin 2πu1, √(1 - u0))."""
    r = np.sqrt(u[..., 0])
    phi = 2.0 * np.pi * u[..., 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[..., 0]))
    x = np.cos(phi)
    x *= r
    r *= np.sin(phi)
    return x, r, z


def split_samples(samples):
    """Horizon methods: ``samples`` lookups = slices x 2 sides x steps; slices ~ sqrt(samples/2)."""
    slices = max(1, int(np.sqrt(samples / 2.0)))
    steps = max(1, int(samples) // (2 * slices))
    return slices, steps
