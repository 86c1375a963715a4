""".blend file headers, checked before Blender's loader sees the file (a damaged version field crashes it).

Layout (Blender's BLO_core_blend_header.hh and BLO_core_bhead.hh): 'BLENDER' + pointer size ('_' 4, '-' 8) +
endianness ('v' little, 'V' big) + version in 3 digits (to 4.5), or 'BLENDER17-01v' + version in 4 digits
(the 17-byte header of 5.0 and later: 64-bit little-endian, larger block headers). Blocks follow, each a
header (code, length, old address, SDNA index, count) and its data; the 'GLOB' block (FileGlobal) starts
with subvstr[4], subversion, minversion: the oldest Blender that can read the file.
"""
import gzip
import re
import struct

from ..errors import InputError

_LEGACY = re.compile(rb"BLENDER([_-])([vV])(\d{3})")
_LARGE = re.compile(rb"BLENDER17-01v(\d{4})")
_ZSTD = b"\x28\xb5\x2f\xfd"
_GZIP = b"\x1f\x8b"
SCAN_BYTES = 4 << 20            # GLOB follows REND and the thumbnail: well inside the first MiB


def _first_bytes(path, n):
    with open(path, "rb") as f:
        magic = f.read(4)
        f.seek(0)
        if magic.startswith(_GZIP):
            with gzip.open(path, "rb") as g:
                return g.read(n)
        if magic == _ZSTD:
            try:
                import zstandard                  # Blender and the bpy module ship it
            except ImportError:
                return None
            try:
                return zstandard.ZstdDecompressor().stream_reader(f).read(n)
            except zstandard.ZstdError as e:
                raise ValueError(str(e)) from None
        return f.read(n)


def _block_heads(data, large, pointer_size, endian):
    """Yield (code, data offset, length) of the blocks in ``data``."""
    if large:
        fmt, order = endian + "4siQqq", (0, 3)
    else:
        fmt, order = endian + ("4siQii" if pointer_size == 8 else "4siIii"), (0, 1)
    size = struct.calcsize(fmt)
    pos = 17 if large else 12
    while pos + size <= len(data):
        fields = struct.unpack_from(fmt, data, pos)
        code, length = fields[order[0]], fields[order[1]]
        if length < 0:
            return
        yield code, pos + size, length
        pos += size + length


def _min_version(data, large, pointer_size, endian):
    for code, start, length in _block_heads(data, large, pointer_size, endian):
        if code == b"GLOB":
            return struct.unpack_from(endian + "h", data, start + 6)[0] if length >= 8 else None
        if code == b"ENDB":
            return None
    return None


def _damaged(path, what):
    return InputError(f"cannot open {path}: damaged or not a Blender file ({what})")


def blend_version(path):
    """The Blender version a .blend says it was written by (e.g. 405, 503), read from its header, plain,
    gzip or zstd compressed; None when it cannot be read here (zstd without the zstandard module).

    Raises InputError for a file that is not a .blend, whose header is damaged, or whose header version is
    older than the oldest Blender that can read the file (FileGlobal.minversion): Blender's loader takes
    such a file for an old one, versions it and crashes.
    """
    try:
        data = _first_bytes(path, SCAN_BYTES)
    except (OSError, EOFError, ValueError) as e:
        raise _damaged(path, str(e)) from None
    if data is None:
        return None
    legacy, large = _LEGACY.match(data), _LARGE.match(data)
    if legacy:
        version, pointer_size = int(legacy.group(3)), 4 if legacy.group(1) == b"_" else 8
        endian = "<" if legacy.group(2) == b"v" else ">"
    elif large:
        version, pointer_size, endian = int(large.group(1)), 8, "<"
    else:
        raise _damaged(path, f"{'damaged header' if data.startswith(b'BLENDER') else 'no Blender header'}: "
                             f"{data[:17]!r}")
    minimum = _min_version(data, bool(large), pointer_size, endian)
    if minimum is not None and version < minimum:
        raise _damaged(path, f"its header says version {version}, older than the {minimum} it needs")
    return version
