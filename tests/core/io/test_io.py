"""EXR and PNG files round-trip exactly; files appear atomically."""
import json
import os
import time
import zlib

import numpy as np
import pytest

from addon.core.io import files as io_files
from addon.core.io import png
from addon.core.io import exr
from addon.core.errors import ILError


def test_exr_roundtrip_channels_and_attributes(tmp_path):
    rng = np.random.default_rng(1)
    y = rng.random((5, 7)).astype(np.float32) * 1e4
    a = (rng.random((5, 7)) > 0.5).astype(np.float32)
    path = tmp_path / "m.exr"
    exr.write_exr(path, {"Y": y, "A": a}, {"il:units": "1", "il:samples": 64})
    channels, header = exr.read_exr(path)
    assert set(channels) == {"Y", "A"}
    np.testing.assert_array_equal(channels["Y"], y)
    np.testing.assert_array_equal(channels["A"], a)
    assert header["il:units"] == "1" and header["il:samples"] == "64"
    assert os.listdir(tmp_path) == ["m.exr"]


def test_exr_rejects_mismatched_channels(tmp_path):
    from addon.core.errors import ILError
    with pytest.raises(ILError):
        exr.write_exr(tmp_path / "x.exr", {"R": np.zeros((2, 2)), "G": np.zeros((3, 2))})
    assert not os.listdir(tmp_path)


def test_png_roundtrip_grey_and_rgb(tmp_path):
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    rgb = np.random.default_rng(0).integers(0, 256, (4, 3, 3)).astype(np.uint8)
    for pixels in (grey, rgb):
        png.write_png(tmp_path / "p.png", pixels)
        data = (tmp_path / "p.png").read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        np.testing.assert_array_equal(png.decode_png(data), pixels)


def test_png_crc_is_valid(tmp_path):
    data = png.encode_png(np.zeros((2, 2), np.uint8))
    n = int.from_bytes(data[8:12], "big")
    body = data[12:16 + n]
    assert int.from_bytes(data[16 + n:20 + n], "big") == zlib.crc32(body)


def test_srgb_encode_matches_the_standard_at_known_points():
    x = np.array([0.0, 0.0031308, 0.18, 1.0])
    expected = np.array([0.0, 12.92 * 0.0031308, 1.055 * 0.18 ** (1 / 2.4) - 0.055, 1.0])
    np.testing.assert_allclose(png.srgb_encode(x), expected, atol=1e-6)


def test_srgb_decode_inverts_encode():
    x = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(png.srgb_decode(png.srgb_encode(x)), x, atol=1e-12)
    assert png.srgb_decode(np.array([128 / 255]))[0] == pytest.approx(0.21586, abs=1e-5)


def test_tonemap_is_finite_on_bad_values():
    out = png.tonemap(np.array([np.nan, np.inf, -1.0, 0.5, 2.0]))
    assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1


@pytest.mark.parametrize("n", [1, 2, 3, 7, 100, 101, 4097])
def test_the_white_point_is_numpys_99th_percentile_bit_for_bit(n):
    """png.percentile_99 (the previews' white point) against np.percentile's linear rule: ties, spreads over six
    decades and both sides of its blend's 0.5 switch."""
    rng = np.random.default_rng(n)
    draws = [rng.lognormal(0.0, 3.0, n) for _ in range(40)] + [np.round(rng.random(n) * 4) + 0.25, np.full(n, 0.7)]
    for v in draws:
        assert png.percentile_99(v.copy()) == float(np.percentile(v, 99))


def test_failed_write_leaves_nothing(tmp_path):
    target = tmp_path / "r.json"
    with pytest.raises(ILError, match=r"r.json: non-finite number at x \(nan\)"):
        io_files.write_json(target, {"x": float("nan")})
    with pytest.raises(ILError, match=r"non-finite number at methods.gtao.rmse.1 \(inf\)"):
        io_files.write_json(target, {"methods": {"gtao": {"rmse": [0.1, float("inf")]}}})
    assert not os.listdir(tmp_path)
    io_files.write_json(target, {"x": 1})
    assert json.loads(target.read_text()) == {"x": 1}


def test_exr_refuses_non_finite_values_naming_the_file_and_channel(tmp_path):
    good = np.ones((4, 8), np.float32)
    for bad, text in ((np.nan, "1 NaN, 0 infinite"), (np.inf, "0 NaN, 1 infinite"), (3e38 * 10, "0 NaN, 1 infinite")):
        r = good.astype(np.float64).copy()
        r[2, 3] = bad
        with pytest.raises(ILError, match=f"irr.exr: non-finite values \\(R: {text}\\)"):
            exr.write_exr(tmp_path / "irr.exr", {"R": r, "G": good})
    assert not os.listdir(tmp_path)


def test_a_process_removes_its_own_temporaries_and_no_others(tmp_path):
    """A Ctrl-C inside atomic_path's clean-up left the temporary behind (seen once in
    test_ctrl_c_during_the_demo_stops_with_130_and_no_report): a script that stops removes the temporaries it still
    has, by their names, and no file of another process that shares its host name and PID (containers), nor the
    user's."""
    from addon.core.io import files
    (tmp_path / "per_object").mkdir()
    held = files.atomic_path(tmp_path / "per_object" / "Floor_ao.exr")
    tmp = held.__enter__()                                     # a writer stopped before its clean-up
    assert os.path.exists(tmp) and files._TEMPORARY.match(os.path.basename(tmp))["pid"] == str(os.getpid())
    twin = tmp_path / f".Floor_ao.{files._HOST}-{os.getpid()}.a8d7f6q1.tmp.exr"   # same host and PID, not ours
    keep = [twin, tmp_path / ".hidden.tmp.exr", tmp_path / "Floor_ao.exr"]
    for f in keep:
        f.write_bytes(b"x")
    assert files.remove_own_temporaries() == [tmp] and not os.path.exists(tmp)
    assert all(f.exists() for f in keep) and files.remove_own_temporaries() == []
    with files.atomic_path(tmp_path / "Wall_ao.exr") as t:
        open(t, "wb").close()
    assert (tmp_path / "Wall_ao.exr").exists() and not files._LIVE


def test_stale_temporaries_of_killed_writers_are_removed_and_no_others(tmp_path):
    """A SIGKILL during atomic_path leaves '.<stem>.<host>-<pid>.<random>.tmp<ext>': removed once its process is
    gone and it is older than STALE_AFTER; a live process's, another host's and the user's own dotfiles stay."""
    import subprocess
    import sys
    from addon.core.io import files
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    names = {"dead": f".Floor_ao.{files._HOST}-{dead}.k2j4x9_a.tmp.exr",
             "live": f".Floor_ao.{files._HOST}-{os.getpid()}.a8d7f6q1.tmp.exr",
             "other host": f".Floor_ao.farm-node-7-{dead}.zz81kk2m.tmp.png",
             "user": ".hidden.tmp.exr"}
    for name in names.values():
        (tmp_path / name).write_bytes(b"x")
    assert files.remove_stale_temporaries(str(tmp_path)) == []        # younger than STALE_AFTER: kept
    later = time.time() + files.STALE_AFTER + 1
    assert files.remove_stale_temporaries(str(tmp_path), now=later) == [names["dead"]]
    assert sorted(os.listdir(tmp_path)) == sorted(v for k, v in names.items() if k != "dead")
    with files.atomic_path(tmp_path / "Floor_ao.exr") as tmp:
        assert files._TEMPORARY.match(os.path.basename(tmp))["pid"] == str(os.getpid())
        open(tmp, "wb").close()
