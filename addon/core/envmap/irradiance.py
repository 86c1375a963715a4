"""Irradiance environment maps (seed 002; REFERENCE.md §3): E(n) by brute force, the method switch, cost.

Irradiance here is E(n) = ∫ L(l) (n·l)⁺ dl in W/m² (REFERENCE.md §1: no 1/π;
seed 002 writes the same integral with 1/π, which is the reflected radiance of
a white Lambertian surface, E/π).
"""
import numpy as np

from .. import budget
from ..errors import InputError
from .latlong import check_latlong, downsample_latlong, latlong_directions, latlong_row_solid_angles
from .sh9 import irradiance_map_sh9, sh9_coefficients


#: Cost estimates of an irradiance map (measured on 2 cores, rounded up; README "Limits"): peak bytes
#: per output pixel (directions, SH basis, map, EXR copy; 165 measured at 4096 wide), seconds per
#: output pixel and quadrature direction of the brute-force sum (6-11e-9 measured).
BYTES_PER_MAP_PIXEL = 200
SECONDS_PER_PRODUCT = 1.2e-8
#: Cosines per block of :func:`irradiance_brute` (16 MiB of float64): a buffer this size stays in the allocator's
#: heap, where the former 512-normal blocks (512 MiB at 131,072 directions) were fresh pages every time.
CHUNK_ELEMENTS = 1 << 21


def check_cost(width, method="sh9", quadrature_directions=0):
    """Refuse (InputError naming the largest width that fits) a map whose estimated memory
    ((width²/2) x BYTES_PER_MAP_PIXEL) or brute-force time (pixels x directions x SECONDS_PER_PRODUCT)
    does not fit :mod:`budget`."""
    per_pixel = SECONDS_PER_PRODUCT * quadrature_directions if method == "brute" else 0.0
    budget.check("width", int(width), lambda w: ((w // 2) * w * BYTES_PER_MAP_PIXEL, (w // 2) * w * per_pixel), 4, multiple=2)


def brute_directions(env_shape, max_width=256):
    """How many quadrature directions :func:`quadrature` keeps for an (H, W, C) map at ``max_width``."""
    h, w = env_shape[:2]
    f = 1
    while w // f > max_width and h % (2 * f) == 0 and w % (2 * f) == 0:
        f *= 2
    return (h // f) * (w // f)




def clamped_cosine(n, l):
    """(n·l)⁺ for unit vectors: the Lambertian kernel of E(n) = ∫ L(l) (n·l)⁺ dl."""
    return np.maximum(np.einsum("...k,...k->...", n, l), 0.0)


def quadrature(env, max_width):
    """Quadrature of ∫ L(l) g(l) dl over a lat-long map: (directions l_p (P, 3), L_p Δω_p (P, C)).

    The map is first box-filtered by powers of two to at most ``max_width`` columns.
    """
    env = np.asarray(env, np.float64)
    h, w, c = env.shape
    f = 1
    while w // f > max_width and h % (2 * f) == 0 and w % (2 * f) == 0:
        f *= 2
    env = downsample_latlong(env, f)
    h, w = env.shape[:2]
    return latlong_directions(h, w).reshape(-1, 3), (env * latlong_row_solid_angles(h, w)[:, None, None]).reshape(-1, c)


def irradiance_brute(env, normals, max_width=256, chunk=None):
    """E(n) = Σ_pixels L_p (n·l_p)⁺ Δω_p for each normal (…, 3) -> (…, C) W/m² (quadrature of seed 002's integral).

    The environment is first box-filtered to at most ``max_width`` columns: the
    cosine kernel is smooth, so this costs nothing in accuracy for E. ``chunk`` normals at a time (default:
    :data:`CHUNK_ELEMENTS` cosines and at most 512 normals, in one buffer reused).
    """
    dirs, weighted = quadrature(env, max_width)
    c = weighted.shape[1]
    n = np.asarray(normals, np.float64)
    flat = n.reshape(-1, 3)
    out = np.empty((flat.shape[0], c))
    chunk = max(1, min(512, CHUNK_ELEMENTS // len(dirs))) if chunk is None else int(chunk)
    buf = np.empty((min(chunk, flat.shape[0]), len(dirs)))
    for s in range(0, flat.shape[0], chunk):
        block = flat[s:s + chunk]
        cos = buf[:len(block)]
        np.matmul(block, dirs.T, out=cos)
        np.maximum(cos, 0.0, out=cos)
        out[s:s + chunk] = cos @ weighted
    return out.reshape(n.shape[:-1] + (c,))


def irradiance_map_brute(env, width=64, max_width=256):
    """Irradiance lat-long map (width/2, width, C): E for the normal of each pixel's direction."""
    return irradiance_brute(env, latlong_directions(width // 2, width), max_width=max_width)


def irradiance_map(env, method="sh9", width=64):
    """Dispatch: ``sh9`` or ``brute``. Returns (map (width/2, width, C), sh9 coefficients (9, C))."""
    check_latlong(env)
    if width < 4 or width % 2:
        raise InputError(f"--width must be an even number >= 4, got {width}")
    coeffs = sh9_coefficients(env)
    if method == "sh9":
        return irradiance_map_sh9(env, width, coeffs), coeffs
    if method == "brute":
        return irradiance_map_brute(env, width), coeffs
    raise InputError(f"unknown method {method!r} (sh9 or brute)")
