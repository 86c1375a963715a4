"""Lat-long (equirectangular) environments: reading and checking them, directions and solid angles, sampling.

Directions are unit vectors in Blender's world frame (Z up). A lat-long map is
an (H, W, C) array with row 0 at the TOP, laid out as Blender's Environment
Texture (equirectangular) reads it, verified against Cycles renders
(tests/lab/test_envmap.py)::

    u = (pi - atan2(y, x)) / (2 pi)      (column, left -> right)
    v = 1/2 + asin(z) / pi               (v = 1 at the top row: straight up)

so the image centre looks along +X, a quarter of the width to its left (u = 1/4)
along +Y, and a quarter to its right (u = 3/4) along -Y.
"""
import os

import numpy as np

from ..errors import ILError, InputError
from ..io.hdr import read_hdr


def read_latlong(path):
    """A lat-long environment from ``.exr`` (R, G, B or Y channels) or ``.hdr``: float32 (H, W, 3)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"no such environment file: {path}")
    ext = os.path.splitext(path)[1].lower()
    if ext in (".hdr", ".pic", ".rgbe"):
        env = read_hdr(path)
    elif ext == ".exr":
        from ..io.exr import read_exr
        try:
            ch, _ = read_exr(path)
        except ILError:
            raise
        except Exception as e:  # noqa: BLE001 - OpenEXR raises plain exceptions
            raise InputError(f"{path}: not a readable EXR ({e})") from e
        if all(k in ch for k in "RGB"):
            env = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
        elif "Y" in ch:
            env = np.repeat(ch["Y"][..., None], 3, axis=-1)
        else:
            raise InputError(f"{path}: needs R, G, B or Y channels, has {sorted(ch)}")
    else:
        raise InputError(f"{path}: environment must be .exr or .hdr")
    check_latlong(env, path)
    return env.astype(np.float32)


def check_radiance(env, name="environment"):
    """Raise InputError where radiance is negative (no physical environment emits less than nothing)."""
    low = float(np.min(env)) if np.size(env) else 0.0
    if low < 0:
        count = int(np.count_nonzero(np.asarray(env) < 0))
        raise InputError(f"{name}: {count} negative radiance values (down to {low:g}): radiance is >= 0")


def check_latlong(env, name="environment"):
    """Raise InputError unless ``env`` is (H, W, 3) finite with W == 2 H."""
    env = np.asarray(env)
    if env.ndim != 3 or env.shape[2] != 3:
        raise InputError(f"{name}: expected an (H, W, 3) image, got shape {env.shape}")
    if env.shape[1] != 2 * env.shape[0]:
        raise InputError(f"{name}: a lat-long map is twice as wide as high, got {env.shape[1]}x{env.shape[0]}")
    if not np.all(np.isfinite(env)):
        raise InputError(f"{name}: contains NaN or infinite values")




def direction_to_latlong_uv(d):
    """Unit directions (…, 3) -> (u, v) in [0, 1]: u = (π − atan2(y, x))/2π, v = 1/2 + asin(z)/π."""
    d = np.asarray(d, np.float64)
    u = (np.pi - np.arctan2(d[..., 1], d[..., 0])) / (2 * np.pi)
    v = 0.5 + np.arcsin(np.clip(d[..., 2], -1.0, 1.0)) / np.pi
    return u, v


def latlong_uv_to_direction(u, v):
    """Inverse of :func:`direction_to_latlong_uv`: φ = π − 2πu, elevation = π(v − 1/2)."""
    phi = np.pi - 2 * np.pi * np.asarray(u, np.float64)
    elev = np.pi * (np.asarray(v, np.float64) - 0.5)
    c = np.cos(elev)
    return np.stack([c * np.cos(phi), c * np.sin(phi), np.sin(elev)], axis=-1)


def latlong_angles(h, w):
    """Polar angle θ (from +Z) of each row centre (h,) and azimuth φ = atan2(y, x) of each column centre (w,)."""
    theta = (np.arange(h) + 0.5) * np.pi / h
    phi = np.pi - 2 * np.pi * (np.arange(w) + 0.5) / w
    return theta, phi


def latlong_directions(h, w):
    """(h, w, 3) unit directions of the pixel centres, row 0 at the top."""
    theta, phi = latlong_angles(h, w)
    st = np.sin(theta)[:, None]
    return np.stack([st * np.cos(phi)[None, :], st * np.sin(phi)[None, :],
                     np.repeat(np.cos(theta)[:, None], w, axis=1)], axis=-1)


def latlong_row_solid_angles(h, w):
    """Exact solid angle of one pixel in each row (h,): (2π/w)(cos θ_top − cos θ_bottom); they sum to 4π."""
    edges = np.arange(h + 1) * np.pi / h
    return (2 * np.pi / w) * (np.cos(edges[:-1]) - np.cos(edges[1:]))


def sample_latlong(env, d):
    """Bilinear lookup of ``env`` (H, W, C) in directions ``d`` (…, 3); wraps in u, clamps in v."""
    env = np.asarray(env)
    h, w = env.shape[:2]
    u, v = direction_to_latlong_uv(d)
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    x0 = np.floor(x).astype(np.int64)
    y0 = np.floor(y).astype(np.int64)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    xa, xb = x0 % w, (x0 + 1) % w
    ya, yb = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    top = env[ya, xa] * (1 - fx) + env[ya, xb] * fx
    bot = env[yb, xa] * (1 - fx) + env[yb, xb] * fx
    return top * (1 - fy) + bot * fy


def downsample_latlong(env, factor):
    """Box-filter a lat-long map by an integer ``factor``, weighting rows by their solid angle."""
    env = np.asarray(env, np.float64)
    h, w, c = env.shape
    if factor <= 1:
        return env
    if h % factor or w % factor:
        raise InputError(f"map size {w}x{h} is not a multiple of {factor}")
    wt = latlong_row_solid_angles(h, w)[:, None, None]
    num = (env * wt).reshape(h // factor, factor, w // factor, factor, c).sum(axis=(1, 3))
    den = np.broadcast_to(wt, (h, w, 1)).reshape(h // factor, factor, w // factor, factor, 1).sum(axis=(1, 3))
    return num / den
