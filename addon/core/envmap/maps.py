"""The three environment-map types of seed 002 as images: layouts, lookups, texel solid angles.

lat-long (H, 2H): Blender's equirectangular (latlong.py); cube map: six S x S faces in CUBE_FACES order
side by side in one (S, 6S) strip image (projections.py's face table, t = 0 at the top row); sphere map:
one S x S mirror-ball image (projections.py). Sizes "at equal texel count" as the lat-long's 2H²:
cube S = round(H/√3), sphere S = round(H √2).

Texel solid angle: lat-long (2π/W)(cos θ_top − cos θ_bot); cube ∫∫ (1 + s² + t²)^(−3/2) ds dt over the
texel (s, t ∈ [−1, 1]), in closed form atan(st/√(1+s²+t²)) at its corners; sphere map dω = 4 dA on the unit
disk (θ_r = 2θ_n, ρ = sin θ_n: dω = 4 sin θ_n cos θ_n dθ_n dφ = 4 ρ dρ dφ), i.e. the sphere map is an
equal-area projection: its distortion is of shape, not of area. Shape: :func:`anisotropy`, the ratio of
the singular values of the Jacobian d(direction)/d(texel) (1 = square texels on the sphere).
"""
import numpy as np

from ..errors import InputError
from . import latlong as ll
from . import projections as pj

PROJECTIONS = ("LATLONG", "CUBE", "SPHERE")


def equal_texel_size(projection, height):
    """Face side (CUBE), image side (SPHERE) or height (LATLONG) whose texel count equals 2·height²."""
    if projection == "CUBE":
        return max(1, int(round(height / np.sqrt(3.0))))
    if projection == "SPHERE":
        return max(2, int(round(height * np.sqrt(2.0))))
    return int(height)


def cube_to_strip(cube):
    """(6, S, S, C) -> (S, 6S, C): faces side by side, +X first."""
    return np.concatenate(list(cube), axis=1)


def strip_to_cube(strip):
    """(S, 6S, C) -> (6, S, S, C)."""
    s = strip.shape[0]
    if strip.shape[1] != 6 * s:
        raise InputError(f"a cube strip is six times as wide as high, got {strip.shape[1]}x{s}")
    return np.stack([strip[:, f * s:(f + 1) * s] for f in range(6)])


def convert(env, projection, size=None):
    """Lat-long (H, 2H, C) -> the image of ``projection`` (strip for CUBE), ``size`` None: equal texel count."""
    env = np.asarray(env, np.float64)
    if projection not in PROJECTIONS:
        raise InputError(f"projection must be one of {', '.join(PROJECTIONS)}, got {projection!r}")
    size = size or equal_texel_size(projection, env.shape[0])
    if projection == "CUBE":
        return cube_to_strip(pj.latlong_to_cube(env, size))
    if projection == "SPHERE":
        return pj.latlong_to_sphere_map(env, size)
    return env if size == env.shape[0] else ll.sample_latlong(env, ll.latlong_directions(size, 2 * size))


def _bilinear(img, x, y):
    """Bilinear lookup at pixel coordinates (centres at integers), clamped to the edge."""
    h, w = img.shape[:2]
    x, y = np.clip(x, 0, w - 1), np.clip(y, 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(np.int64), max(w - 2, 0))
    y0 = np.minimum(np.floor(y).astype(np.int64), max(h - 2, 0))
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def sample(image, projection, d):
    """Bilinear lookup of a map image in directions ``d`` (…, 3); the cube bilinear within each face."""
    image = np.asarray(image, np.float64)
    if projection == "LATLONG":
        return ll.sample_latlong(image, d)
    if projection == "SPHERE":
        s, t = pj.direction_to_sphere_map_uv(d)
        n = image.shape[0]
        return _bilinear(image, s * n - 0.5, (1 - t) * n - 0.5)
    cube = strip_to_cube(image)
    n = cube.shape[1]
    face, s, t = pj.direction_to_cube(d)
    out = np.empty(face.shape + image.shape[2:])
    for f in range(6):
        m = face == f
        out[m] = _bilinear(cube[f], s[m] * n - 0.5, t[m] * n - 0.5)
    return out


def cube_texel_solid_angles(size):
    """(S, S) solid angle of every texel of one cube face (all faces alike); 6 faces sum to 4π."""
    e = np.linspace(-1.0, 1.0, size + 1)
    a, b = np.meshgrid(e, e, indexing="ij")
    c = np.arctan2(a * b, np.sqrt(1 + a * a + b * b))
    return c[1:, 1:] - c[:-1, 1:] - c[1:, :-1] + c[:-1, :-1]


def sphere_texel_solid_angles(size, sub=8):
    """(S, S) solid angle of every sphere-map texel: dω = 4 dA in the disk's unit coordinates
    (x, y = 2s − 1, 2t − 1; the whole disk π maps to 4π), integrated on sub x sub points; 0 outside."""
    c = (np.arange(size * sub) + 0.5) / (size * sub)
    x, y = np.meshgrid(2 * c - 1, 2 * c - 1, indexing="ij")
    inside = (x * x + y * y) <= 1.0
    da = (2.0 / (size * sub)) ** 2
    return (4.0 * da * inside).reshape(size, sub, size, sub).sum(axis=(1, 3))


def texel_solid_angles(projection, size):
    """Solid angle per texel (flattened over the used texels) of a map of ``size`` (LATLONG: height)."""
    if projection == "LATLONG":
        return np.repeat(ll.latlong_row_solid_angles(size, 2 * size), 2 * size)
    if projection == "CUBE":
        return np.tile(cube_texel_solid_angles(size).ravel(), 6)
    w = sphere_texel_solid_angles(size).ravel()
    return w[w > 0]


def distortion(projection, size):
    """{"texels", "max_over_min", "max_over_mean", "min_over_mean"} of texel solid angles, and
    "anisotropy_max" (:func:`anisotropy`); the sphere map's rim texels that lie partly outside the disk are
    excluded."""
    w = texel_solid_angles(projection, size)
    if projection == "SPHERE":
        full = 4.0 * (2.0 / size) ** 2
        w = w[w > full * (1 - 1e-9)]
    mean = 4 * np.pi / (texel_count(projection, size))
    return {"texels": int(texel_count(projection, size)), "max_over_min": float(w.max() / w.min()),
            "max_over_mean": float(w.max() / mean), "min_over_mean": float(w.min() / mean),
            "anisotropy_max": float(anisotropy(projection, size).max())}


def _texel_directions(projection, size, du=0.0, dv=0.0):
    """Directions at texel centres offset by (du, dv) texels (LATLONG: size = height), and the valid mask."""
    if projection == "LATLONG":
        h, w = size, 2 * size
        i, j = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
        return ll.latlong_uv_to_direction((j + 0.5 + du) / w, 1 - (i + 0.5 + dv) / h), np.ones((h, w), bool)
    i, j = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    s, t = (j + 0.5 + du) / size, (i + 0.5 + dv) / size
    if projection == "CUBE":
        return pj.cube_to_direction(0, s, t), np.ones((size, size), bool)
    d, _ = pj.sphere_map_uv_to_direction(s, 1 - t)
    x, y = 2 * (j + 0.5) / size - 1, 2 * (i + 0.5) / size - 1
    return d, np.hypot(np.abs(x) + 1.0 / size, np.abs(y) + 1.0 / size) <= 1.0


def anisotropy(projection, size, h=1e-3):
    """σ_1/σ_2 of d(direction)/d(texel) at every fully used texel centre (one cube face stands for all six)."""
    _, ok = _texel_directions(projection, size)
    a = (_texel_directions(projection, size, du=h)[0] - _texel_directions(projection, size, du=-h)[0]) / (2 * h)
    b = (_texel_directions(projection, size, dv=h)[0] - _texel_directions(projection, size, dv=-h)[0]) / (2 * h)
    e, f, g = (a * a).sum(-1), (a * b).sum(-1), (b * b).sum(-1)
    root = np.sqrt(np.maximum((e - g) ** 2 + 4 * f * f, 0.0))
    s1, s2 = np.sqrt((e + g + root) / 2), np.sqrt(np.maximum((e + g - root) / 2, 1e-300))
    return (s1 / s2)[ok]


def texel_count(projection, size):
    return {"LATLONG": 2 * size * size, "CUBE": 6 * size * size, "SPHERE": size * size}[projection]


def lookup_error(env_fn, projection, size, directions):
    """RMSE and max |error| of looking ``env_fn(d)`` up in its map of ``size`` against ``env_fn`` itself."""
    if projection == "LATLONG":
        img = env_fn(ll.latlong_directions(size, 2 * size))
    elif projection == "CUBE":
        img = cube_to_strip(env_fn(pj.cube_face_directions(size)))
    else:
        c = (np.arange(size) + 0.5) / size
        t, s = np.meshgrid(1.0 - c, c, indexing="ij")
        d, inside = pj.sphere_map_uv_to_direction(s, t)
        d[~inside] = (0.0, 1.0, 0.0)                  # the rim's direction, as projections.latlong_to_sphere_map
        img = env_fn(d)
    err = sample(img, projection, directions) - env_fn(directions)
    return float(np.sqrt(np.mean(err ** 2))), float(np.max(np.abs(err)))
