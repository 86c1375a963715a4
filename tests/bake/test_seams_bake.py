"""The seam figure of baked maps (addon/bake/seams.py): in the report and the EXR header, below the bake's noise."""
import math

import numpy as np
import pytest

from addon.bake import BakeOptions, bake_lightmaps
from addon.bake.kinds import KINDS
from addon.bake.seams import mesh_seams
from addon.blender import scene as sc
from addon.core import seams
from addon.core.io import exr


@pytest.mark.both_versions
def test_seams_of_a_smooth_sphere_are_below_the_noise_and_hard_edges_are_no_seams(tmp_path):
    scene = sc.new_scene("T")
    sc.world(scene, strength=1.0)
    sc.plane(scene, "Floor", 6.0)
    ball = sc.sphere(scene, "Ball", 1.0, location=(0, 0, 1.0), segments=24, rings=12)     # smooth: seams are seams
    box = sc.box(scene, "Box", 1.0, location=(30, 0, 0.5))                              # flat: every UV split a crease
    rep = bake_lightmaps([ball, box], ["ao", "irradiance"], tmp_path,
                         BakeOptions(resolution=64, samples=16, margin=2, bounces=0), scene=scene)
    for kind in ("ao", "irradiance"):
        entry = rep["objects"]["Ball"][kind]
        s = entry["seams"]
        assert s["edges"] > 0 and s["samples"] >= s["edges"] and s["creases"] == 0
        # the jump noise alone gives: σ √(mean Σ c²), between √½ σ (two four-texel averages) and √2 σ (two copies)
        sigma = entry["estimated_error"]
        assert math.sqrt(0.5) * sigma <= s["noise"] <= math.sqrt(2) * sigma
        # without the dilation the sampler reads black beside the charts
        assert s["undilated_rms"] > s["noise"] and s["undilated_rms"] > s["rms"]
        # below the noise: E[jump²] = noise² for a pure-noise jump, its mean over n samples (each sharing texels with
        # its two neighbours at most) within 4 sd, √(2·3/n) relative
        assert s["rms"] <= s["noise"] * math.sqrt(1 + 4 * math.sqrt(6 / s["samples"]))
        # a client reading the EXR sees the same figure (the file holds the stitched map), inside the value range
        channels, header = exr.read_exr(tmp_path / f"Ball_{kind}.exr")
        values = np.flipud(KINDS[kind].from_exr(channels))
        mask = np.flipud(channels["A"]) > 0.5
        h, w = mask.shape
        found = mesh_seams(ball, entry["uv_layer"], scene.view_layers[0].depsgraph, w, h)
        again = seams.measure(values, found, mask)
        np.testing.assert_allclose(again.rms, s["rms"], rtol=1e-4)
        np.testing.assert_allclose(float(header["il:seam_rms"]), s["rms"], rtol=1e-4)
        assert header["il:seam_fixed"] == str(int(s["fixed"]))
        lo, hi = KINDS[kind].value_range
        assert values.min() >= lo and (hi is None or values.max() <= hi)
        cube = rep["objects"]["Box"][kind]["seams"]
        assert cube["edges"] == 0 and cube["samples"] == 0 and cube["creases"] == 12 and not cube["fixed"]
