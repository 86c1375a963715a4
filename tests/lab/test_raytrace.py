"""Ray-tracing lab against Cycles on the same pixels: Whitted equals Cycles within Cycles' noise where both compute
the same light paths, and what Whitted leaves out is reported (seed 004, eq. 2; REFERENCE.md §1)."""
import json

import bpy
import numpy as np
import pytest

from addon.core.io import exr
from addon.lab import raytrace
from addon.lab.options import RaytraceOptions
from addon.lab.raytrace import scenes

RES = 48
SAMPLES = 16
EDGE_FRACTION = raytrace.EDGE_FRACTION       # at 48 px: 1-3 pixels of 2304 are silhouettes and shadow edges


def _rgb(path):
    ch, _ = exr.read_exr(path)
    return np.stack([ch[k] for k in "RGB"], -1).astype(np.float64)


def _trimmed_rmse(a, b, fraction=EDGE_FRACTION):
    e = np.sort(((a - b) ** 2).mean(-1).ravel())
    return float(np.sqrt(e[:len(e) - int(np.ceil(fraction * len(e)))].mean()))


@pytest.mark.both_versions
@pytest.mark.parametrize("name", ["diffuse", "mirror", "glass"])
def test_whitted_equals_cycles_within_its_noise_on_the_same_light_paths(tmp_path, name):
    """Cycles renders the same camera twice (seeds 0 and 1) with diffuse bounces 0 and glossy/transmission bounces
    = max_depth; σ = RMS(seed 0 - seed 1)/2 is the noise of their mean. Whitted must agree to 4σ (+1e-4 for
    float32 and the faceted sphere) on all but EDGE_FRACTION of the pixels."""
    r = raytrace.run_builtin(name, str(tmp_path), RaytraceOptions(resolution=RES, samples=SAMPLES, max_depth=4))
    w, c = _rgb(tmp_path / "whitted.exr"), _rgb(tmp_path / "cycles.exr")
    assert w.shape == c.shape == (RES, RES, 3)
    sigma = r["cycles"]["noise_rmse"]
    assert _trimmed_rmse(w, c) <= 4 * sigma + 1e-4, (name, _trimmed_rmse(w, c), sigma)
    assert np.isclose(r["rmse_vs_cycles_99"], _trimmed_rmse(w, c), rtol=1e-3)
    assert abs(w.mean() - c.mean()) <= 4 * sigma / RES + 2e-4 * c.mean() + 1e-5      # no bias in the image mean
    assert c.mean() > 0.05 and r["rays"] > RES * RES
    assert r["engines"]["same_hits"] == 1.0                 # numpy BVH and mathutils BVHTree hit the same points
    report = json.loads((tmp_path / "raytrace_report.json").read_text())
    for key in ("method", "max_depth", "rays", "seconds", "rays_per_second", "rmse_vs_cycles",
                "relative_rmse_vs_cycles"):
        assert key in report


def test_ray_casting_shows_a_black_mirror_and_whitted_depth_zero_is_ray_casting(tmp_path):
    rc = raytrace.run_builtin("mirror", str(tmp_path / "rc"), RaytraceOptions(
        method="raycast", resolution=RES, samples=4, max_depth=6))
    w0 = raytrace.run_builtin("mirror", str(tmp_path / "w0"), RaytraceOptions(
        method="whitted", resolution=RES, samples=1, max_depth=0, compare=False))
    a, b = _rgb(tmp_path / "rc" / "raycast.exr"), _rgb(tmp_path / "w0" / "whitted.exr")
    assert np.array_equal(a, b)
    c = _rgb(tmp_path / "rc" / "cycles.exr")                 # Cycles with 0 bounces: the mirror is black too
    assert _trimmed_rmse(a, c) <= 4 * rc["cycles"]["noise_rmse"] + 1e-4
    assert (a.sum(-1) == 0).mean() > 0.05                   # the sphere's pixels
    assert rc["ray_counts"]["secondary"] == 0 and w0.report["rmse_vs_cycles"] is None


def test_what_whitted_leaves_out_is_an_image_and_a_number(tmp_path):
    walls = raytrace.run_builtin("walls", str(tmp_path / "walls"), RaytraceOptions(resolution=32, samples=16))
    area = raytrace.run_builtin("area", str(tmp_path / "area"), RaytraceOptions(resolution=32, samples=4))
    diffuse = raytrace.run_builtin("diffuse", str(tmp_path / "diffuse"), RaytraceOptions(resolution=32, samples=16))
    # interreflection between the walls: a third of the light; the area light and the sky: nearly all of it
    assert walls["missing"]["fraction"] > 0.2
    assert area["missing"]["fraction"] > 0.7
    assert 0 < diffuse["missing"]["fraction"] < walls["missing"]["fraction"]
    assert any("area light" in n for n in area["left_out"]) and any("sky" in n for n in area["left_out"])
    missing = _rgb(tmp_path / "walls" / "missing.exr")
    full, w = _rgb(tmp_path / "walls" / "cycles_full.exr"), _rgb(tmp_path / "walls" / "whitted.exr")
    np.testing.assert_allclose(missing, full - w, atol=1e-6)
    assert missing.mean() > 0


def test_the_users_scene_settings_come_back(tmp_path):
    scene = scenes.build("glass", (200, 100))
    try:
        scene.cycles.samples, scene.cycles.diffuse_bounces = 77, 3
        raytrace.run(scene, str(tmp_path), RaytraceOptions(resolution=32, samples=2, max_depth=2))
        assert (scene.render.resolution_x, scene.render.resolution_y) == (200, 100)
        assert scene.cycles.samples == 77 and scene.cycles.diffuse_bounces == 3
        assert _rgb(tmp_path / "whitted.exr").shape == (16, 32, 3)
    finally:
        scenes.remove(scene)
    assert not [s for s in bpy.data.scenes if s.name.startswith("IL Raytrace")]


def test_script_writes_only_in_out_and_refuses_bad_input(tmp_path, script):
    out = tmp_path / "o"
    p = script("raytrace.py", "--scene", "tir", "--max-depth", "8", "--resolution", "24", "--samples", "2",
               "--out", out)
    assert p.returncode == 0, p.stderr
    assert sorted(f.name for f in tmp_path.iterdir()) == ["o"]
    assert sorted(f.name for f in out.iterdir()) == ["cycles.exr", "cycles_full.exr", "missing.exr",
                                                     "raytrace_report.json", "whitted.exr"]
    for bad in (["--scene", "nope"], ["--scene", "glass", "--max-depth", "-1"]):
        p = script("raytrace.py", *bad, "--out", tmp_path / "bad")
        assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, (bad, p.stderr)
    assert not (tmp_path / "bad").exists()


def test_both_intersection_engines_give_the_same_image(tmp_path):
    """The numpy BVH (the default) and Blender's BVHTree find the same hits: the same Whitted image."""
    images = []
    for engine in ("numpy", "bvhtree"):
        r = raytrace.run_builtin("tir", str(tmp_path / engine), RaytraceOptions(
            resolution=32, max_depth=6, engine=engine, compare=False))
        assert r["engine"] == engine
        images.append(_rgb(tmp_path / engine / "whitted.exr"))
    np.testing.assert_allclose(images[0], images[1], atol=1e-5)


def test_an_il_material_is_traced_with_its_models_parameters(tmp_path):
    """An IL Phong material: the local model is the numpy twin with the hub values, k_a I_a added once."""
    from addon.core import brdf
    from addon.lab.raytrace import read as reader
    from addon.nodes import material as il
    scene = scenes.build("diffuse", (32, 32))
    try:
        sphere = next(o for o in scene.objects if o.type == "MESH" and o.data.name.startswith("Sphere"))
        params = {"Kd": (0.2, 0.4, 0.6), "Ks": 0.5, "Shininess": 20.0, "Ka": 0.1, "Ambient Light": (0.3, 0.3, 0.3)}
        mat, _ = il.assign_shading_model(scene, [sphere], "PHONG", params=params)
        rt, notes = reader.read(scene)
        m = next(x for x in rt.materials if x.name == mat.name)
        n, l, v, I = np.array([[0, 0, 1.0]]), np.array([[0.3, 0, 1.0]]), np.array([[-0.2, 0.1, 1.0]]), np.ones((1, 3))
        expected = brdf.phong(n, l, v, I, kd=params["Kd"], ks=0.5, shininess=20.0, normalized=1.0)  # assign's default
        np.testing.assert_allclose(m.local(n, l, v, I), expected, rtol=1e-6)
        np.testing.assert_allclose(m.emission, [0.03] * 3, rtol=1e-6)
        assert m.mirror is None and m.ior is None
    finally:
        scenes.remove(scene)


def _textured_plane(tmp_path, srgb, mirrored=False):
    """A plane made with Blender's operator, a Diffuse BSDF whose Color is an 8x8 checker Image Texture (8-bit sRGB
    saved as PNG, or float), a point light and a camera looking down at it."""
    from addon.blender import compat
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plane = bpy.context.active_object
    if mirrored:
        plane.scale.x = -1.0                   # its triangles are reversed in world space, their UVs must follow
    bpy.ops.object.light_add(type="POINT", location=(0.5, -0.5, 3.0))
    bpy.context.active_object.data.energy = 300.0
    bpy.context.active_object.data.shadow_soft_size = 0.0
    bpy.ops.object.camera_add(location=(0.0, 0.0, 5.0))
    scene.camera = bpy.context.active_object
    scene.render.resolution_x = scene.render.resolution_y = RES
    checker = (np.indices((8, 8)).sum(0) % 2).astype(np.float32)
    rgba = np.stack([0.1 + 0.8 * checker, 0.3 + 0.0 * checker, 0.9 - 0.7 * checker, np.ones_like(checker)], -1)
    img = bpy.data.images.new("Checker", 8, 8, float_buffer=not srgb, alpha=True)
    img.pixels.foreach_set(rgba.ravel())
    if srgb:
        img.filepath_raw = str(tmp_path / "checker.png")
        img.file_format = "PNG"
        img.save()
        img = bpy.data.images.load(str(tmp_path / "checker.png"))
    mat = bpy.data.materials.new("Checker")
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    tex, bsdf, out = (nt.nodes.new(k) for k in ("ShaderNodeTexImage", "ShaderNodeBsdfDiffuse", "ShaderNodeOutputMaterial"))
    tex.image = img
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    plane.data.materials.append(mat)
    return scene


@pytest.mark.both_versions
@pytest.mark.parametrize("srgb, mirrored", [(True, False), (False, False), (False, True)])
def test_an_image_texture_is_read_through_the_uvs_as_cycles_reads_it(tmp_path, srgb, mirrored):
    """k_d from an Image Texture on the plane's UVs (bilinear, repeat; an 8-bit sRGB PNG decoded to linear; a
    mirrored object): ray casting equals Cycles within its noise, where the texture's unlinked value would be a flat
    grey."""
    scene = _textured_plane(tmp_path, srgb, mirrored)
    r = raytrace.run(scene, str(tmp_path), RaytraceOptions(method="raycast", resolution=RES, samples=SAMPLES))
    w, c = _rgb(tmp_path / "raycast.exr"), _rgb(tmp_path / "cycles.exr")
    sigma = r["cycles"]["noise_rmse"]
    assert _trimmed_rmse(w, c) <= 4 * sigma + 1e-4, (_trimmed_rmse(w, c), sigma)
    assert not [n for n in r["left_out"] if "Checker" in n], r["left_out"]
    red_over_blue = w[..., 0] / np.maximum(w[..., 2], 1e-9)
    assert red_over_blue.max() > 3 and red_over_blue.min() < 1 / 3     # both checker colours are there
