"""Radiance RGBE (.hdr/.pic) files (Ward 1991, "Real pixels"): read flat and run-length encoded, write flat."""
import re

import numpy as np

from ..errors import InputError
from .files import write_bytes


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
