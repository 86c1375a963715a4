"""A directional (L1 SH) map in the exported .glb (issue 28, item 5): the material's extras.il_directional names four
8-bit linear textures on texCoord 1 in glTF's Y-up frame; E(n) decoded by its documented formula equals E(n) of the
EXR's coefficients within the encoding's bound, for normals tilted from the surface, the L1 part clamped as Godot
4.3's packing clamps it."""
import numpy as np
import pytest

from addon.bake import bake_lightmaps
from addon.bake.gltf import DIRECTIONAL, LEVELS
from addon.bake.options import BakeOptions
from addon.core import directional
from addon.core.io import exr
from tests.scripts.test_export_lightmaps import _image, _read_glb, _scene

pytestmark = pytest.mark.both_versions


def _normals():
    """Unit normals in glTF's frame (Y up): up, and 30° and 60° tilts at four azimuths."""
    out = [np.array([0.0, 1.0, 0.0])]
    for tilt in (30.0, 60.0):
        for az in (0.0, 90.0, 180.0, 270.0):
            t, a = np.radians(tilt), np.radians(az)
            out.append(np.array([np.sin(t) * np.cos(a), np.cos(t), np.sin(t) * np.sin(a)]))
    return np.array(out)


def test_the_directional_map_decodes_to_its_irradiance_within_the_encoding(tmp_path, script):
    scene, plane, cube = _scene()
    out = tmp_path / "maps"
    report = bake_lightmaps([plane, cube], ["directional"], str(out),
                            BakeOptions(resolution=16, samples=4, bounces=1, margin=2), scene=scene)["objects"]
    import bpy
    blend, glb = tmp_path / "d.blend", tmp_path / "d.glb"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True, compress=False)
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", glb, "--godot")
    assert r.returncode == 0, r.stderr
    tres = (tmp_path / "d.lightmap.tres").read_text()
    assert "uses_spherical_harmonics = true" in tres and tres.count("NodePath(") == 2
    assert "slices/vertical=8" in (tmp_path / "d.lightmap.exr.import").read_text()     # 2 maps x 4 SH layers
    gltf, binary = _read_glb(glb)
    nodes = {n["name"]: n for n in gltf["nodes"]}
    n = _normals()
    for name in ("Plane", "Cube"):
        mat = gltf["materials"][gltf["meshes"][nodes[name]["mesh"]]["primitives"][0]["material"]]
        d = mat["extras"][DIRECTIONAL]
        assert d["texCoord"] == 1 and len(d["l1"]) == 3 and "E(n)" in d["decode"]
        e0 = _image(gltf, binary, d["e0"]["index"]) / LEVELS * d["e0"]["intensity"]
        l1 = [_image(gltf, binary, t["index"]) / LEVELS for t in d["l1"]]
        chans, _ = exr.read_exr(report[name]["directional"]["file"])
        coeffs = directional.to_y_up(np.stack([chans[c] for c in directional.CHANNELS], -1).astype(np.float64))
        a = directional.ambient(coeffs)
        _, l1_exact = directional.godot_packed(coeffs)
        a = np.clip(a, 0.0, None)          # a negative constant term (noise at 4 samples) is encoded as 0
        assert d["e0"]["intensity"] == pytest.approx(float(a.max()), rel=1e-6)
        covered = chans["A"] > 0
        for normal in n:
            dot = sum((2 * l - 1) * normal[axis] for l, axis in zip(l1, (1, 2, 0)))
            dot_exact = sum((2 * l - 1) * normal[axis] for l, axis in zip(l1_exact, (1, 2, 0)))
            decoded = e0 * (1 + 4 * dot)
            expected = a * (1 + 4 * dot_exact)                   # the packing's own model (its clamp included)
            # half an 8-bit step on e0 (intensity / 510) and on each l1 (1/510, doubled by 2 l1 - 1)
            bound = (d["e0"]["intensity"] / (2 * LEVELS)) * np.abs(1 + 4 * dot_exact) \
                + np.abs(a) * 4 * np.abs(normal).sum() / LEVELS + 1e-6
            assert np.all(np.abs(decoded - expected)[covered] <= bound[covered] * (1 + 1e-6)), (name, normal)
            unclamped = np.all([(m > 0) & (m < 1) for m in l1_exact], axis=0).all(-1) & covered & (a > 0).all(-1)
            assert unclamped.sum() >= 10
            np.testing.assert_allclose(expected[unclamped],          # where nothing is clamped: the L1 model itself
                                       directional.irradiance(coeffs, normal)[unclamped], rtol=1e-9, atol=1e-9)
