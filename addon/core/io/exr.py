"""Float OpenEXR files with named channels and string attributes (OpenEXR package).

Arrays are (height, width) with row 0 at the TOP of the image, as every image
viewer shows them. Blender's pixel buffers start at the bottom row: flip them
with ``np.flipud`` before writing.
"""
import errno
import os

import numpy as np

from ..errors import ILError
from .files import atomic_path

#: Largest float32 (EXR "FLOAT" channels).
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _openexr():
    try:
        import OpenEXR
    except ImportError as e:  # pragma: no cover - the extension bundles the wheel
        raise ILError("the OpenEXR package is missing: install it with pip install OpenEXR") from e
    return OpenEXR


def write_exr(path, channels, attributes=None):
    """Write ``{name: 2-D array}`` as float32 channels, zip-compressed, atomically.

    ``attributes`` values are stored as strings (ints and floats too), so any
    tool can read them back. A channel with a value that is not finite as float32 (NaN, infinite,
    or beyond ±3.4e38) is refused with an ILError naming the file, and nothing is written.
    """
    OpenEXR = _openexr()
    shapes = {np.shape(a) for a in channels.values()}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ILError(f"EXR channels must be 2-D arrays of one shape, got {sorted(shapes)}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for key, value in (attributes or {}).items():
        header[key] = str(value)
    with np.errstate(over="ignore", invalid="ignore"):
        data = {name: np.ascontiguousarray(a, dtype=np.float32) for name, a in channels.items()}
    check_finite(path, data)
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, data) as f:
            try:
                f.write(tmp)
            except RuntimeError as e:
                raise _write_error(path, e) from None


def _write_error(path, error):
    """OpenEXR reports a failed write as RuntimeError with the C library's message: a full disk becomes the
    OSError (ENOSPC) every other file write raises, anything else an ILError naming the file."""
    text = str(error)
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EIO):
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code), os.fspath(path))
    return ILError(f"cannot write {path}: {text}")


def check_finite(path, channels):
    """Raise ILError naming ``path`` and each channel holding NaN or infinite values (and how many)."""
    bad = []
    for name, a in channels.items():
        finite = np.isfinite(a)
        if not finite.all():
            a = np.asarray(a)
            nan = int(np.isnan(a).sum())
            bad.append(f"{name}: {nan} NaN, {a.size - int(finite.sum()) - nan} infinite")
    if bad:
        raise ILError(f"not writing {path}: non-finite values ({'; '.join(bad)})")


def read_exr(path):
    """Return ``(channels, attributes)``: float32 2-D arrays by channel name, header dict."""
    OpenEXR = _openexr()
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = {name: np.array(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}
        header = dict(f.header())
    return channels, header


def read_header(path):
    """The header dict of an EXR file, its pixels left unread."""
    OpenEXR = _openexr()
    with OpenEXR.File(str(path), header_only=True) as f:
        return dict(f.header())


def read_multipart(path):
    """Return ``{part name: {channel: array}}`` of a multi-part EXR (Blender's multilayer output).

    Blender names channels ``<layer>.<pass>.<channel>``; they are returned with
    the full name as stored.
    """
    OpenEXR = _openexr()
    out = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            out[part.name()] = {n: np.array(c.pixels, dtype=np.float32) for n, c in part.channels.items()}
    return out
