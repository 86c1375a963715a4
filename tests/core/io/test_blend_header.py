"""The .blend header check (core.io.blend) on files laid out as Blender writes them: both header forms,
both pointer sizes and byte orders, plain, gzip and zstd; a header version older than the file's
FileGlobal.minversion (which crashes Blender's loader) is refused."""
import gzip
import struct

import pytest

from addon.core.errors import InputError
from addon.core.io.blend import blend_version


def blend_bytes(version, minversion, large=False, pointer_size=8, endian="<"):
    if large:
        header = b"BLENDER17-01v%04d" % version
        bhead = lambda code, n: struct.pack("<4siQqq", code, 0, 0x1000, n, 1)          # noqa: E731
    else:
        header = b"BLENDER" + (b"-" if pointer_size == 8 else b"_") + (b"v" if endian == "<" else b"V") \
            + b"%03d" % version
        fmt = endian + ("4siQii" if pointer_size == 8 else "4siIii")
        bhead = lambda code, n: struct.pack(fmt, code, n, 0x1000, 0, 1)                 # noqa: E731
    rend, thumb = b"\0" * 72, b"\7" * 4096
    glob = b"  31" + struct.pack(endian + "hhh", 31, minversion, 5) + b"\0" * 118
    return b"".join([header, bhead(b"REND", len(rend)), rend, bhead(b"TEST", len(thumb)), thumb,
                     bhead(b"GLOB", len(glob)), glob, bhead(b"ENDB", 0)])


LAYOUTS = [dict(large=True), dict(pointer_size=8), dict(pointer_size=4), dict(pointer_size=8, endian=">")]


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("pack", ["plain", "gzip", "zstd"])
def test_versions_read_and_damaged_versions_refused(tmp_path, layout, pack):
    if pack == "zstd":
        zstandard = pytest.importorskip("zstandard")
    version = 503 if layout.get("large") else 405
    for claimed, ok in ((version, True), (100, False), (305, False)):
        data = blend_bytes(claimed, 306, **layout)
        if pack == "gzip":
            data = gzip.compress(data)
        elif pack == "zstd":
            data = zstandard.ZstdCompressor().compress(data)
        path = tmp_path / f"f{claimed}.blend"
        path.write_bytes(data)
        if ok:
            assert blend_version(str(path)) == claimed
        else:
            with pytest.raises(InputError, match=f"says version {claimed}, older than the 306"):
                blend_version(str(path))


@pytest.mark.parametrize("data, what", [(b"", "no Blender header"), (b"PK\3\4 a zip", "no Blender header"),
                                        (b"BLENDER-x405", "damaged header"), (b"BLENDER17-01v05a3", "damaged header"),
                                        (gzip.compress(b"not a blend"), "no Blender header")])
def test_what_is_no_blend_is_refused(tmp_path, data, what):
    path = tmp_path / "x.blend"
    path.write_bytes(data)
    with pytest.raises(InputError, match=what):
        blend_version(str(path))


def test_a_truncated_compressed_file_is_refused(tmp_path):
    zstandard = pytest.importorskip("zstandard")
    for n, packed in enumerate((gzip.compress(blend_bytes(405, 306)),
                                zstandard.ZstdCompressor().compress(blend_bytes(503, 405, large=True)))):
        path = tmp_path / f"cut{n}.blend"
        path.write_bytes(packed[:12])
        with pytest.raises(InputError, match="damaged or not a Blender file"):
            blend_version(str(path))
