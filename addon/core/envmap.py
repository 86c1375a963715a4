"""Environment maps and irradiance environment maps (seed 002; REFERENCE.md §3).

Directions are unit vectors in Blender's world frame (Z up). A lat-long map is
an (H, W, C) array with row 0 at the TOP, laid out as Blender's Environment
Texture (equirectangular) reads it, verified against Cycles renders
(tests/test_envmap.py)::

    u = (pi - atan2(y, x)) / (2 pi)      (column, left -> right)
    v = 1/2 + asin(z) / pi               (v = 1 at the top row: straight up)

so the image centre looks along +X, a quarter of the width to its left (u = 1/4)
along +Y, and a quarter to its right (u = 3/4) along -Y.

Irradiance here is E(n) = ∫ L(l) (n·l)⁺ dl in W/m² (REFERENCE.md §1: no 1/π;
seed 002 writes the same integral with 1/π, which is the reflected radiance of
a white Lambertian surface, E/π).
"""
import os
import re

import numpy as np

from . import budget
from .errors import ILError, InputError

#: Cost estimates of an irradiance map (measured on 2 cores, rounded up; README "Limits"): peak bytes
#: per output pixel (directions, SH basis, map, EXR copy; 165 measured at 4096 wide), seconds per
#: output pixel and quadrature direction of the brute-force sum (6-11e-9 measured).
BYTES_PER_MAP_PIXEL = 200
SECONDS_PER_PRODUCT = 1.2e-8
#: Largest float32 (EXR "FLOAT" channels).
FLOAT32_MAX = float(np.finfo(np.float32).max)

# ----------------------------------------------------------------------------
# Reading environments


def read_hdr(path):
    """Radiance RGBE (.hdr/.pic) -> float32 (H, W, 3), row 0 at the top (Ward 1991, "Real pixels").

    Reads flat and new-style run-length encoded scanlines, orientation ``-Y H +X W``.
    A texel (r, g, b, e) is (r, g, b) * 2^(e - 136) (0 when e = 0).
    """
    with open(path, "rb") as f:
        data = f.read()
    pos, header = 0, []
    while True:
        end = data.find(b"\n", pos)
        if end < 0:
            raise InputError(f"{path}: not a Radiance .hdr file (no resolution line)")
        line = data[pos:end].strip()
        pos = end + 1
        if line.startswith((b"-Y", b"+Y")):
            break
        header.append(line)
    if not header or not header[0].startswith((b"#?RADIANCE", b"#?RGBE")):
        raise InputError(f"{path}: not a Radiance .hdr file (magic {header[:1]})")
    if any(h.startswith(b"FORMAT=") and h != b"FORMAT=32-bit_rle_rgbe" for h in header):
        raise InputError(f"{path}: only FORMAT=32-bit_rle_rgbe is supported")
    m = re.fullmatch(rb"([-+])Y (\d+) ([-+])X (\d+)", line)
    if not m:
        raise InputError(f"{path}: unsupported orientation line {line!r}")
    h, w = int(m.group(2)), int(m.group(4))
    rgbe = _decode_scanlines(np.frombuffer(data, np.uint8, offset=pos), h, w, path)
    if m.group(1) == b"+Y":
        rgbe = rgbe[::-1]
    if m.group(3) == b"-X":
        rgbe = rgbe[:, ::-1]
    return rgbe_to_float(rgbe)


def rgbe_to_float(rgbe):
    """(…, 4) uint8 RGBE -> (…, 3) float32: mantissa · 2^(e − 128 − 8)."""
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0).astype(np.float32)
    return rgbe[..., :3].astype(np.float32) * scale[..., None]


def float_to_rgbe(rgb):
    """(…, 3) float -> (…, 4) uint8 RGBE (the inverse of :func:`rgbe_to_float`, truncating)."""
    rgb = np.maximum(np.asarray(rgb, np.float64), 0.0)
    top = rgb.max(axis=-1)
    mant, exp = np.frexp(top)
    ok = top > 1e-32
    scale = np.where(ok, mant * 256.0 / np.where(ok, top, 1.0), 0.0)
    out = np.zeros(rgb.shape[:-1] + (4,), np.uint8)
    out[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    out[..., 3] = np.where(ok, exp + 128, 0).astype(np.uint8)
    return out


def write_hdr(path, rgb):
    """Write float (H, W, 3), row 0 at the top, as a flat (not run-length encoded) Radiance file."""
    rgb = np.asarray(rgb)
    h, w = rgb.shape[:2]
    head = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    from .io.files import write_bytes
    write_bytes(path, head + float_to_rgbe(rgb).tobytes())


def _decode_scanlines(buf, h, w, path):
    out = np.empty((h, w, 4), np.uint8)
    pos = 0
    try:
        for y in range(h):
            if 8 <= w < 32768 and buf[pos] == 2 and buf[pos + 1] == 2 and not buf[pos + 2] & 0x80:
                if (int(buf[pos + 2]) << 8 | int(buf[pos + 3])) != w:
                    raise InputError(f"{path}: bad scanline width at row {y}")
                pos += 4
                for c in range(4):
                    x = 0
                    while x < w:
                        n = int(buf[pos])
                        if n > 128:  # a run
                            n -= 128
                            out[y, x:x + n, c] = buf[pos + 1]
                            pos += 2
                        else:  # literal bytes
                            if n == 0:
                                raise InputError(f"{path}: zero-length run at row {y}")
                            out[y, x:x + n, c] = buf[pos + 1:pos + 1 + n]
                            pos += 1 + n
                        x += n
            else:  # flat scanline
                out[y] = buf[pos:pos + 4 * w].reshape(w, 4)
                pos += 4 * w
    except (IndexError, ValueError) as e:
        raise InputError(f"{path}: truncated or corrupt pixel data") from e
    return out


def read_latlong(path):
    """A lat-long environment from ``.exr`` (R, G, B or Y channels) or ``.hdr``: float32 (H, W, 3)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"no such environment file: {path}")
    ext = os.path.splitext(path)[1].lower()
    if ext in (".hdr", ".pic", ".rgbe"):
        env = read_hdr(path)
    elif ext == ".exr":
        from .io.exr import read_exr
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


def check_cost(width, method="sh9", quadrature_directions=0):
    """Refuse (InputError naming the largest width that fits) a map whose estimated memory
    ((width²/2) x BYTES_PER_MAP_PIXEL) or brute-force time (pixels x directions x SECONDS_PER_PRODUCT)
    does not fit :mod:`budget`."""
    per_pixel = SECONDS_PER_PRODUCT * quadrature_directions if method == "brute" else 0.0
    budget.check("width", int(width), lambda w: ((w // 2) * w * BYTES_PER_MAP_PIXEL, (w // 2) * w * per_pixel), 4)


def brute_directions(env_shape, max_width=256):
    """How many quadrature directions :func:`quadrature` keeps for an (H, W, C) map at ``max_width``."""
    h, w = env_shape[:2]
    f = 1
    while w // f > max_width and h % (2 * f) == 0 and w % (2 * f) == 0:
        f *= 2
    return (h // f) * (w // f)


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


# ----------------------------------------------------------------------------
# Lat-long geometry (Blender's equirectangular convention, see module docstring)


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


# ----------------------------------------------------------------------------
# Irradiance E(n) by brute force


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


def irradiance_brute(env, normals, max_width=256, chunk=512):
    """E(n) = Σ_pixels L_p (n·l_p)⁺ Δω_p for each normal (…, 3) -> (…, C) W/m² (quadrature of seed 002's integral).

    The environment is first box-filtered to at most ``max_width`` columns: the
    cosine kernel is smooth, so this costs nothing in accuracy for E.
    """
    dirs, weighted = quadrature(env, max_width)
    c = weighted.shape[1]
    n = np.asarray(normals, np.float64)
    flat = n.reshape(-1, 3)
    out = np.empty((flat.shape[0], c))
    for s in range(0, flat.shape[0], chunk):
        cos = np.maximum(flat[s:s + chunk] @ dirs.T, 0.0)
        out[s:s + chunk] = cos @ weighted
    return out.reshape(n.shape[:-1] + (c,))


def irradiance_map_brute(env, width=64, max_width=256):
    """Irradiance lat-long map (width/2, width, C): E for the normal of each pixel's direction."""
    return irradiance_brute(env, latlong_directions(width // 2, width), max_width=max_width)


# ----------------------------------------------------------------------------
# Nine spherical-harmonic coefficients (Ramamoorthi & Hanrahan 2001)

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


# ----------------------------------------------------------------------------
# Pre-filtered glossy map (normalised Phong lobe)


def phong_lobe(r, l, n):
    """((n + 1)/2π) (r·l)⁺ⁿ: the normalised Phong lobe around the reflection direction r (integrates to 1)."""
    return (n + 1) / (2 * np.pi) * clamped_cosine(r, l) ** n


def prefilter_phong(env, n, width=64, max_width=256, chunk=256):
    """Pre-filtered map G(r) = ∫ L(l) ((n+1)/2π) (r·l)⁺ⁿ dl as a lat-long map (width/2, width, C).

    n = 1 gives E(r)/π; a constant environment L gives L for every n. The
    environment is box-filtered to at most ``max_width`` columns: keep its pixel
    well below the lobe width (about 1/sqrt(n) radians).
    """
    dirs, weighted = quadrature(env, max_width)
    c = weighted.shape[1]
    r = latlong_directions(width // 2, width).reshape(-1, 3)
    out = np.empty((r.shape[0], c))
    for s in range(0, r.shape[0], chunk):
        out[s:s + chunk] = phong_lobe(r[s:s + chunk, None, :], dirs[None], n) @ weighted
    return out.reshape(width // 2, width, c)


# ----------------------------------------------------------------------------
# Cube maps and sphere maps

#: Face order and, per face, (major axis, sign, s axis and sign, t axis and sign): the OpenGL
#: cube-map table applied to Blender world axes. s runs along columns, t along rows (row 0 = t 0).
CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
_CUBE_TABLE = (  # (major, sign, sc_axis, sc_sign, tc_axis, tc_sign)
    (0, 1, 2, -1, 1, -1), (0, -1, 2, 1, 1, -1),
    (1, 1, 0, 1, 2, 1), (1, -1, 0, 1, 2, -1),
    (2, 1, 0, 1, 1, -1), (2, -1, 0, -1, 1, -1),
)


def direction_to_cube(d):
    """Directions (…, 3) -> (face index, s, t) with s, t in [0, 1] (OpenGL's selection by major axis)."""
    d = np.asarray(d, np.float64)
    a = np.abs(d)
    major = np.argmax(a, axis=-1)
    sign = np.take_along_axis(d, major[..., None], -1)[..., 0] >= 0
    face = 2 * major + (~sign)
    s = np.empty(d.shape[:-1])
    t = np.empty(d.shape[:-1])
    for f, (ax, sg, sa, ss, ta, ts) in enumerate(_CUBE_TABLE):
        m = face == f
        ma = a[..., ax][m]
        s[m] = (ss * d[..., sa][m] / ma + 1) / 2
        t[m] = (ts * d[..., ta][m] / ma + 1) / 2
    return face, s, t


def cube_to_direction(face, s, t):
    """Inverse of :func:`direction_to_cube`: unit directions (…, 3)."""
    face = np.asarray(face)
    sc, tc = 2 * np.asarray(s, np.float64) - 1, 2 * np.asarray(t, np.float64) - 1
    d = np.zeros(np.broadcast(face, sc).shape + (3,))
    for f, (ax, sg, sa, ss, ta, ts) in enumerate(_CUBE_TABLE):
        m = np.broadcast_to(face == f, d.shape[:-1])
        d[..., ax][m] = sg
        d[..., sa][m] = np.broadcast_to(ss * sc, m.shape)[m]
        d[..., ta][m] = np.broadcast_to(ts * tc, m.shape)[m]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cube_face_directions(size):
    """(6, size, size, 3) directions of every cube-map texel centre, faces in :data:`CUBE_FACES` order."""
    st = (np.arange(size) + 0.5) / size
    t, s = np.meshgrid(st, st, indexing="ij")
    return np.stack([cube_to_direction(f, s, t) for f in range(6)])


def latlong_to_cube(env, size):
    """Lat-long (H, W, C) -> cube map (6, size, size, C) by bilinear lookup."""
    return sample_latlong(env, cube_face_directions(size))


def sample_cube(cube, d):
    """Nearest-texel lookup of a cube map (6, S, S, C) in directions (…, 3)."""
    size = cube.shape[1]
    face, s, t = direction_to_cube(d)
    i = np.clip((t * size).astype(np.int64), 0, size - 1)
    j = np.clip((s * size).astype(np.int64), 0, size - 1)
    return cube[face, i, j]


def cube_to_latlong(cube, width):
    """Cube map (6, S, S, C) -> lat-long (width/2, width, C) by nearest-texel lookup."""
    return sample_cube(cube, latlong_directions(width // 2, width))


def sphere_map_uv_to_direction(s, t):
    """Sphere map (mirror ball seen from −Y looking along +Y, X right, Z up; t = 1 at the top row).

    Eye frame (x, y, z) = world (X, Z, −Y). The ball normal at (s, t) is
    (2s − 1, 2t − 1, √(1 − …)) and the reflected direction r = 2 (n·e) n − e, e = (0, 0, 1).
    Returns (directions (…, 3), inside-the-disk mask).
    """
    x, y = 2 * np.asarray(s, np.float64) - 1, 2 * np.asarray(t, np.float64) - 1
    rr = x * x + y * y
    inside = rr <= 1.0
    nz = np.sqrt(np.clip(1.0 - rr, 0.0, None))
    re = np.stack([2 * nz * x, 2 * nz * y, 2 * nz * nz - 1], axis=-1)
    return np.stack([re[..., 0], -re[..., 2], re[..., 1]], axis=-1), inside


def direction_to_sphere_map_uv(d):
    """Inverse of :func:`sphere_map_uv_to_direction`: m = 2√(rx² + ry² + (rz + 1)²), s = rx/m + ½, t = ry/m + ½."""
    d = np.asarray(d, np.float64)
    rx, ry, rz = d[..., 0], d[..., 2], -d[..., 1]
    m = 2 * np.sqrt(rx * rx + ry * ry + (rz + 1) ** 2)
    m = np.where(m > 1e-12, m, 1e-12)
    return rx / m + 0.5, ry / m + 0.5


def latlong_to_sphere_map(env, size):
    """Lat-long (H, W, C) -> sphere map (size, size, C), zero outside the disk; row 0 at the top."""
    c = (np.arange(size) + 0.5) / size
    t, s = np.meshgrid(1.0 - c, c, indexing="ij")
    d, inside = sphere_map_uv_to_direction(s, t)
    return sample_latlong(env, d) * inside[..., None]


def sphere_map_to_latlong(sphere, width):
    """Sphere map (S, S, C) -> lat-long (width/2, width, C) by bilinear lookup inside the disk."""
    sphere = np.asarray(sphere, np.float64)
    size = sphere.shape[0]
    s, t = direction_to_sphere_map_uv(latlong_directions(width // 2, width))
    x = np.clip(s * size - 0.5, 0, size - 1)
    y = np.clip((1 - t) * size - 0.5, 0, size - 1)
    x0 = np.minimum(np.floor(x).astype(int), size - 2)
    y0 = np.minimum(np.floor(y).astype(int), size - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = sphere[y0, x0] * (1 - fx) + sphere[y0, x0 + 1] * fx
    bot = sphere[y0 + 1, x0] * (1 - fx) + sphere[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bot * fy


# ----------------------------------------------------------------------------
# Test environments with closed forms


def linear_sky(h, w, a, b):
    """L(l) = a + b (l·z) (REFERENCE.md §3) as a lat-long map (h, w, 3); a and b scalars or RGB."""
    z = latlong_directions(h, w)[..., 2:3]
    return (np.asarray(a, np.float64) + np.asarray(b, np.float64) * z) * np.ones(3)


def linear_sky_irradiance(normals, a, b):
    """Closed form of the linear sky: E(n) = πa + (2π/3) b (n·z) for every n."""
    nz = np.asarray(normals, np.float64)[..., 2:3]
    return (np.pi * np.asarray(a, np.float64) + 2 * np.pi / 3 * np.asarray(b, np.float64) * nz) * np.ones(3)


def linear_sky_prefiltered(r, a, b, n):
    """Closed form of the Phong-prefiltered linear sky: G(r) = a + b ((n+1)/(n+2)) (r·z)."""
    rz = np.asarray(r, np.float64)[..., 2:3]
    return (np.asarray(a, np.float64) + np.asarray(b, np.float64) * (n + 1) / (n + 2) * rz) * np.ones(3)
