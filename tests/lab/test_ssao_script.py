"""scripts/ssao.py as a pipeline runs it (subprocess), and the sweeps used by the bench."""
import importlib.util
import json
import os

import numpy as np
import pytest

from tests.conftest import ROOT

from addon.core.io import exr
from addon.core.errors import InputError


def test_script_writes_report_and_pixel_aligned_images(script, tmp_path):
    out = tmp_path / "ssao"
    r = script("ssao.py", "--scene", "corner", "--methods", "crytek,gtao", "--resolution", "40",
               "--samples", "8", "--reference-samples", "64", "--out", out)
    assert r.returncode == 0, r.stderr
    data = json.load(open(out / "ssao_report.json"))
    assert set(data["methods"]) == {"crytek", "gtao"}
    assert data["reference"]["samples"] == 64 and data["reference"]["seconds"] > 0
    for m in ("crytek", "gtao"):
        assert {"rmse", "bias", "mean", "seconds", "params"} <= set(data["methods"][m])
        assert data["methods"][m]["params"]["radius"] == 1.0
    ref, hdr = exr.read_exr(out / "reference_ao.exr")
    gt, _ = exr.read_exr(out / "gtao_ao.exr")
    assert ref["Y"].shape == gt["Y"].shape == (40, 40)
    assert hdr["il:ao_distance"] == "1.0"
    np.testing.assert_array_equal(ref["A"], gt["A"])
    assert np.isfinite(gt["Y"]).all() and np.all(gt["Y"][gt["A"] == 0] == 1.0)
    assert any(f.startswith("ssao_reference_") for f in os.listdir(out / "cache"))
    # second run: the reference comes from the cache
    r = script("ssao.py", "--scene", "corner", "--methods", "gtao", "--resolution", "40",
               "--samples", "8", "--reference-samples", "64", "--out", out)
    assert r.returncode == 0 and json.load(open(out / "ssao_report.json"))["reference"]["cached"] is True


def _script_module(name):
    """scripts/<name>.py imported in this process (its bpy-free argument checks run without a subprocess)."""
    path = os.path.join(ROOT, "scripts", f"{name}.py")
    spec = importlib.util.spec_from_file_location(f"il_script_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_script_bad_input_exit_2_with_one_line(script, tmp_path):
    r = script("ssao.py", "--radius", "0", "--out", tmp_path / "o")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "--radius: must be greater than 0" in lines[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args, message", [
    (["--scene", "attic"], "unknown SSAO scene 'attic'"),
    (["--resolution", "2048", "--reference-samples", "65536"], "the largest reference samples that fits is"),
])
def test_script_rejects_bad_input_before_rendering(args, message):
    mod = _script_module("ssao")
    with pytest.raises(InputError, match=message):
        mod._validate(mod.build_parser().parse_args(args))


@pytest.mark.parametrize("args, message", [
    (["--methods", "gtao,ssdo"], "unknown SSAO method 'ssdo'"),
    (["--methods", ","], "no SSAO method given"),
])
def test_script_rejects_unknown_methods_at_parse_time(args, message, capsys):
    mod = _script_module("ssao")
    with pytest.raises(SystemExit) as e:
        mod.build_parser().parse_args(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1 and message in err[0]


@pytest.mark.parametrize("args, option", [
    (["--radius", "-2"], "--radius"), (["--radius", "nan"], "--radius"), (["--samples", "0"], "--samples"),
    (["--samples", "100000000"], "--samples"), (["--reference-samples", "-1"], "--reference-samples"),
    (["--resolution", "inf"], "--resolution"), (["--seed", "-1"], "--seed"),
])
def test_script_numbers_are_checked_at_parse_time(args, option, capsys):
    mod = _script_module("ssao")
    with pytest.raises(SystemExit) as e:
        mod.build_parser().parse_args(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1 and option in err[0]


def test_quick_sweeps_write_charts_tables_and_failures(tmp_path):
    from addon.lab.bench import ssao as bench_ssao
    result = bench_ssao.run(str(tmp_path), quick=True)
    assert {"ssao_error_vs_seconds", "ssao_radius", "ssao_failures"} <= set(result.tables)
    for path in result.charts:
        assert os.path.getsize(path) > 1000
    rows = result.tables["ssao_error_vs_seconds"]
    assert {r["method"] for r in rows} >= {"crytek", "hemisphere", "hbao", "gtao", "workbench"}
    assert result.figures["pareto_front"]
    # the failure cases show: the sphere kernel greys the open plane; halos darken the wall
    fail = {(r["scene"], r["method"]): r for r in result.tables["ssao_failures"]}
    assert fail[("plane", "crytek")]["region_bias"] < -0.3
    assert fail[("plane", "gtao")]["region_rmse"] < 0.01
    assert fail[("discontinuity", "crytek")]["region_bias"] < -0.3
    # thin occluders: the floor behind the pole and the plate reads darker than the truth, the floor
    # in front of the pole (where the pole's face is the true horizon) does not; the gap between the
    # two mean errors exceeds 4 standard errors (per-pixel spread over the region's pixels)
    for m in ("gtao", "hbao"):
        r = fail[("thin", m)]
        se = [np.sqrt((r[f"{k}_rmse"] ** 2 - r[f"{k}_bias"] ** 2) / r[f"{k}_pixels"]) for k in ("region", "control")]
        assert r["region_bias"] < 0 and r["control_bias"] - r["region_bias"] > 4 * np.hypot(*se), r
    # radius sweep: GTAO is best with its radius matched to the AO distance
    gt = {r["radius_over_ao_distance"]: r["rmse"] for r in result.tables["ssao_radius"] if r["method"] == "gtao"}
    assert min(gt, key=gt.get) == 1.0


def _scaled_scene_blend(path, scale):
    """A box on a floor seen by a camera, every position × ``scale``, saved as ``path``."""
    import bpy
    from addon.blender import scene as sc
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=6 * scale)
    bpy.ops.mesh.primitive_cube_add(size=1 * scale, location=(0, 0, 0.5 * scale))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (3 * scale, -3 * scale, 2.5 * scale)
    cam.rotation_euler = (1.05, 0, 0.785)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 32
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_default_radius_follows_the_scene_scale_and_is_reported(script, tmp_path):
    radii = {}
    for scale in (1.0, 0.1):
        blend = _scaled_scene_blend(tmp_path / f"s{scale}.blend", scale)
        out = tmp_path / f"o{scale}"
        r = script("ssao.py", blend, "--methods", "gtao", "--samples", "4", "--reference-samples", "16", "--out", out)
        assert r.returncode == 0, r.stderr
        data = json.load(open(out / "ssao_report.json"))
        radii[scale] = data["radius"]
        assert data["radius_rule"].startswith("default: 0.1 x the frame width")
        assert f"radius {data['radius']:.4g} m (" in r.stderr
        assert data["methods"]["gtao"]["params"]["radius"] == pytest.approx(data["radius"])
        assert data["reference"]["ao_distance"] == pytest.approx(data["radius"])
    assert radii[0.1] == pytest.approx(0.1 * radii[1.0], rel=1e-3)
    assert 0.2 < radii[1.0] < 2.0
    # a given radius is used as given
    r = script("ssao.py", tmp_path / "s1.0.blend", "--methods", "gtao", "--samples", "4", "--reference-samples", "16",
               "--radius", "0.3", "--out", tmp_path / "given")
    data = json.load(open(tmp_path / "given" / "ssao_report.json"))
    assert r.returncode == 0 and data["radius"] == 0.3 and data["radius_rule"] == "given"
