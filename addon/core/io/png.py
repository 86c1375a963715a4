"""PNG previews without any imaging dependency (zlib and numpy), and tone mapping."""
import math
import struct
import zlib

import numpy as np

from .files import write_bytes


def _chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(pixels):
    """Encode 8-bit pixels (H, W) grey or (H, W, 3|4) colour, row 0 at the top, as PNG bytes."""
    a = np.asarray(pixels)
    if a.dtype != np.uint8:
        raise TypeError("encode_png takes uint8 pixels; use to_uint8 first")
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    color_type = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    raw = np.concatenate([np.zeros((h, 1), np.uint8), a.reshape(h, w * c)], axis=1)
    header = struct.pack(">IIBBBBB", w, h, 8, color_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header)
            + _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + _chunk(b"IEND", b""))


def decode_png(data):
    """Decode an 8-bit, non-interlaced PNG written by :func:`encode_png` (for tests and checks)."""
    pos, chunks = 8, {}
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        chunks.setdefault(kind, []).append(data[pos + 8:pos + 8 + n])
        pos += 12 + n
    w, h, depth, color_type = struct.unpack(">IIBB", chunks[b"IHDR"][0][:10])
    c = {0: 1, 4: 2, 2: 3, 6: 4}[color_type]
    raw = np.frombuffer(zlib.decompress(b"".join(chunks[b"IDAT"])), np.uint8).reshape(h, 1 + w * c)
    if np.any(raw[:, 0]):
        raise ValueError("only PNGs without row filters are decoded here")
    a = raw[:, 1:].reshape(h, w, c)
    return a[:, :, 0] if c == 1 else a


def srgb_decode(encoded):
    """Inverse sRGB transfer function (IEC 61966-2-1): c/12.92 below 0.04045, else ((c + 0.055)/1.055)^2.4."""
    c = np.clip(encoded, 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))


def to_uint8(values):
    """Clip display values in [0, 1] and quantise to 8 bits."""
    return np.round(np.clip(np.nan_to_num(values), 0.0, 1.0) * 255.0).astype(np.uint8)


def srgb_encode(linear):
    """sRGB transfer function (IEC 61966-2-1) of linear values in [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def percentile_99(values):
    """``np.percentile(values, 99)`` of a non-empty 1-D float64 array (its "linear" rule, bit for bit: the order
    statistics at ⌊v⌋ and ⌊v⌋ + 1 for v = 0.99 (n − 1), blended as numpy's ``_lerp`` does) without its first call
    importing numpy.ma (11 ms of a new process with numpy 2; numpy 1.26 imports it with numpy)."""
    n = len(values)
    if n == 1:
        return float(values[0])
    virtual = (n - 1) * (99 / 100)
    k = math.floor(virtual)
    part = np.partition(values, [k, k + 1])
    a, b = np.float64(part[k]), np.float64(part[k + 1])
    gamma = np.float64(virtual - k)
    return float(b - (b - a) * (1 - gamma) if gamma >= 0.5 else a + (b - a) * gamma)


def tonemap(linear, exposure=None):
    """Linear radiometric values -> display [0, 1]: scale so the 99th percentile is white, then sRGB.

    With ``exposure`` given the scale is ``2**exposure`` instead.
    """
    x = np.nan_to_num(np.asarray(linear, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    if exposure is None:
        p = percentile_99(x[x > 0]) if np.any(x > 0) else 1.0
        scale = 1.0 / p if p > 0 else 1.0
    else:
        scale = 2.0 ** exposure
    return srgb_encode(x * scale)


def write_png(path, pixels):
    """Write uint8 pixels (row 0 at the top) as a PNG, atomically."""
    write_bytes(path, encode_png(pixels))
