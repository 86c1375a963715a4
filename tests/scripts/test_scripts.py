"""Scripts run as a pipeline runs them: --help, exit codes, one error line, real output."""
import json

import numpy as np
import pytest

from addon.core.io import png as io_png
from addon.core.io import exr

pytestmark = pytest.mark.both_versions


def test_help_exits_zero(script):
    proc = script("demo.py", "--help")
    assert proc.returncode == 0
    assert "--out" in proc.stdout


def test_bad_argument_exits_two_with_one_line(script):
    proc = script("demo.py", "--samples", "many")
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1
    assert "--samples" in proc.stderr


def test_value_error_exits_two_with_one_line(script, tmp_path):
    proc = script("demo.py", "--samples", "0", "--out", tmp_path / "o")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["demo.py: error: argument --samples: must be 1 <= value <= 4096, got 0"]
    assert not (tmp_path / "o").exists()


def test_after_double_dash_arguments_belong_to_the_script():
    import _cli_path  # noqa: F401
    import _cli
    assert _cli.script_argv(["blender", "-b", "-P", "x.py", "--", "--out", "d"]) == ["--out", "d"]
    assert _cli.script_argv(["scripts/x.py", "f.blend", "--out", "d"]) == ["f.blend", "--out", "d"]


def test_a_switch_that_turns_an_option_off_says_so():
    """A True-default option becomes --no-NAME (store_false): its help says what it stops, not what it does."""
    import argparse
    import _cli_path  # noqa: F401
    import _cli
    from addon.lab.options import RadiosityOptions
    p = _cli.add_options(_cli.parser("x.py", "test", blend_file=False), RadiosityOptions)
    off = [a for a in p._actions if isinstance(a, argparse._StoreFalseAction)]
    assert [a.option_strings for a in off] == [["--no-compare"]]
    assert off[0].help == "do not bake the same objects with Cycles and report the difference"
    assert p.parse_args(["--no-compare"]).compare is False and p.parse_args([]).compare is True


def test_missing_blend_file_exits_two(script, tmp_path):
    proc = script("build_extension.py", "--help")
    assert proc.returncode == 0
    import _cli_path  # noqa: F401
    import _cli
    p = _cli.parser("x.py", "test")
    with pytest.raises(SystemExit) as e:
        _cli.run(p, lambda args: None, ["x.py", str(tmp_path / "nope.blend")])
    assert e.value.code == 2


def test_demo_writes_render_exr_png_and_report(script, tmp_path):
    proc = script("demo.py", "--quick", "--out", tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "[demo 1/" in proc.stderr
    channels, header = exr.read_exr(tmp_path / "demo_render.exr")
    rgb = np.stack([channels[c] for c in "RGB"], -1)
    assert rgb.shape == (120, 160, 3)
    assert np.all(np.isfinite(rgb)) and rgb.mean() > 0.01
    assert header["il:units"] == "W/(m^2 sr)"
    png = io_png.decode_png((tmp_path / "demo_render.png").read_bytes())
    assert png.shape == (120, 160, 3)
    report = json.loads((tmp_path / "demo_report.json").read_text())
    assert report["steps"]["render"]["samples"] == 8
    refl = report["steps"]["reflections"]
    assert set(refl["methods"]) == {"latlong", "cube", "sphere", "raytraced"}
    assert refl["methods"]["raytraced"]["relative_rmse"] == 0.0
    sweep = [row["latlong"] for row in refl["distance_sweep"]]
    assert sweep[-1] > sweep[0], sweep          # the notes' limit: the map is right only at its capture point
    rt = report["steps"]["raytrace"]
    assert rt["rays"] > 0 and np.isfinite(rt["rmse_vs_cycles"])


def test_bench_level_prints_only_its_own_lines(script, tmp_path):
    """Its bare bakes, the saved rerun level and the rerun's own process printed Blender's "Info: Baking map saved",
    "Info: Saved copy" and two-line Python warnings: stdout now holds its figures only, stderr its progress and
    one-line warnings."""
    import re
    proc = script("bench_level.py", "--quick", "--props", "2", "--reruns", "1", "--out", tmp_path)
    assert proc.returncode == 0, proc.stderr
    ours = re.compile(r'^(level: |run=|figures: \{$| "\w+": |\}$)')
    assert [ln for ln in proc.stdout.splitlines() if not ours.match(ln)] == []
    assert [ln for ln in proc.stderr.splitlines() if not ln.startswith(("[", "bench_level.py: warning: "))] == []
    assert any(ln.startswith("run=per object, light changed, 64 spp") for ln in proc.stdout.splitlines())
