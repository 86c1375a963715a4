"""scripts/ssao.py as a pipeline runs it (subprocess), and the sweeps used by the bench."""
import json
import os

import numpy as np
import pytest

from addon.core import exr


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


@pytest.mark.parametrize("args, message", [
    (["--methods", "gtao,ssdo"], "unknown SSAO method 'ssdo'"),
    (["--scene", "attic"], "unknown SSAO scene 'attic'"),
    (["--radius", "0"], "--radius must be positive"),
    (["--radius", "-2"], "--radius must be positive"),
    (["--samples", "0"], "--samples must be positive"),
    (["--reference-samples", "-1"], "--reference-samples must be positive"),
])
def test_script_bad_input_exit_2_with_one_line(script, tmp_path, args, message):
    r = script("ssao.py", *args, "--out", tmp_path)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_quick_sweeps_write_charts_tables_and_failures(tmp_path):
    from addon.lab import ssao_sweeps
    result = ssao_sweeps.sweeps(str(tmp_path), quick=True)
    assert {"ssao_error_vs_seconds", "ssao_radius", "ssao_failures"} <= set(result["tables"])
    for path in result["charts"]:
        assert os.path.getsize(path) > 1000
    rows = result["tables"]["ssao_error_vs_seconds"]
    assert {r["method"] for r in rows} >= {"crytek", "hemisphere", "hbao", "gtao", "workbench"}
    assert result["figures"]["pareto_front"]
    # the failure cases show: the sphere kernel greys the open plane; halos darken the wall
    fail = {(r["scene"], r["method"]): r for r in result["tables"]["ssao_failures"]}
    assert fail[("plane", "crytek")]["region_bias"] < -0.3
    assert fail[("plane", "gtao")]["region_rmse"] < 0.01
    assert fail[("discontinuity", "crytek")]["region_bias"] < -0.3
    # radius sweep: GTAO is best with its radius matched to the AO distance
    gt = {r["radius_over_ao_distance"]: r["rmse"] for r in result["tables"]["ssao_radius"] if r["method"] == "gtao"}
    assert min(gt, key=gt.get) == 1.0
