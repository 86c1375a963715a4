"""Irradiance environment maps in Blender: convention checked by Cycles renders, map against a Cycles bake,
node group, script and operator."""
import json

import bpy
import numpy as np
import pytest

from addon.core import analytic
from addon.core.envmap import irradiance
from addon.core.envmap import latlong
from addon.core.io import exr
from addon.core.errors import InputError
from addon.lab import envmap as L
from addon.blender import render
from addon.blender import scene as S


def _env_image(tmp_path, env, name="env.exr"):
    path = tmp_path / name
    exr.write_exr(path, {c: env[..., k].astype(np.float32) for k, c in enumerate("RGB")})
    return bpy.data.images.load(str(path)), path


@pytest.mark.both_versions
def test_equirectangular_convention_matches_cycles(tmp_path):
    """A map whose pixels encode their own (column, row) seen by a camera in known directions."""
    H, W = 32, 64
    j, i = np.meshgrid(np.arange(W), np.arange(H))
    env = np.stack([(j + 0.5) / W, (i + 0.5) / H, np.ones((H, W))], axis=-1)
    sc = S.new_scene("conv", (3, 3))
    img, _ = _env_image(tmp_path, env)
    w = L.set_world_environment(sc, img)
    next(n for n in w.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment").interpolation = "Closest"
    render.cycles_cpu(sc, 1)
    for col, row in [(17, 15), (48, 20), (30, 3), (2, 12), (60, 27)]:   # pixel centres, away from edges
        d = latlong.latlong_uv_to_direction((col + 0.5) / W, 1 - (row + 0.5) / H)
        S.camera(sc, "cam", (0, 0, 0), target=tuple(d), lens=300)
        got = render.render_layers(sc)["Combined"][1, 1, :2]
        assert got[0] == pytest.approx((col + 0.5) / W, abs=1e-4), (col, row)
        assert got[1] == pytest.approx((row + 0.5) / H, abs=1e-4), (col, row)


def test_8bit_srgb_environment_reads_as_cycles_renders_it(tmp_path):
    """Image.pixels of an 8-bit image are sRGB-encoded; the world's radiance must be what Cycles shows."""
    codes = np.array([30, 128, 250])           # one 8-bit code per channel, uniform over the map
    png = bpy.data.images.new("ldr", 8, 4, alpha=False)
    png.pixels.foreach_set(np.tile(np.r_[codes / 255.0, 1.0], 32).astype(np.float32))
    png.filepath_raw, png.file_format = str(tmp_path / "ldr.png"), "PNG"
    png.save()
    img = bpy.data.images.load(str(tmp_path / "ldr.png"))
    assert not img.is_float and img.colorspace_settings.name == "sRGB"
    sc = S.new_scene("ldr", (3, 3))
    L.set_world_environment(sc, img)
    S.camera(sc, "cam", (0, 0, 0), target=(1, 0, 0))
    render.cycles_cpu(sc, 1)
    seen = render.render_layers(sc)["Combined"][1, 1, :3]
    env, _ = L.world_environment(sc)
    assert np.allclose(env, seen, rtol=1e-3)
    assert np.max(np.abs(seen - codes / 255.0)) > 0.2    # not the encoded values
    img.colorspace_settings.name = "Filmic Log"
    with pytest.raises(InputError, match="8-bit in colour space"):
        L.world_environment(sc)


def _asymmetric_env(h=32, w=64):
    d = latlong.latlong_directions(h, w)
    lobe = np.exp(8 * (d @ (np.array([0.6, 0.5, 0.62]) / np.linalg.norm([0.6, 0.5, 0.62])) - 1))
    return analytic.linear_sky(h, w, 0.4, 0.3) + 3.0 * lobe[..., None] * np.array([1.0, 0.7, 0.4])


def test_cycles_bake_of_a_sphere_matches_the_map(tmp_path):
    env = _asymmetric_env()
    sc = S.new_scene("sphere", (8, 8))
    img, _ = _env_image(tmp_path, env)
    L.set_world_environment(sc, img)
    sphere = S.sphere(sc, "Ball", 1.0, segments=16, rings=8)
    N = 64
    E_cycles, normals, _ = L.cycles_sphere_irradiance(sc, sphere, samples=N)
    emap, _, _ = L.compute(env, "brute", 64)
    ours = latlong.sample_latlong(emap, normals)
    # per-vertex Monte Carlo bound from the cosine-sampled variance of L: sigma_E = pi * sigma_cos(L) / sqrt(N)
    ew = env * latlong.latlong_row_solid_angles(32, 64)[:, None, None]
    dirs = latlong.latlong_directions(32, 64).reshape(-1, 3)
    cos = np.maximum(normals @ dirs.T, 0) / np.pi
    m1 = cos @ ew.reshape(-1, 3)
    m2 = cos @ (env * ew).reshape(-1, 3)
    sigma = np.pi * np.sqrt(np.maximum(m2 - m1 ** 2, 0) / N)
    assert np.all(np.abs(E_cycles - ours) < 5 * sigma + 0.01 * ours)
    # the mean over all vertices is far tighter; a mirrored convention (u -> 1 - u) fails it
    se = np.sqrt(np.sum(sigma ** 2)) / sigma.size
    assert abs(np.mean(E_cycles - ours)) < 5 * se + 0.005 * np.mean(ours)
    mirrored = latlong.sample_latlong(emap[:, ::-1], normals)
    assert np.sqrt(np.mean((E_cycles - mirrored) ** 2)) > 4 * np.sqrt(np.mean((E_cycles - ours) ** 2))


def test_node_group_gives_ambient_term(tmp_path):
    """EMIT bake of the node group's emission at a sphere's vertices = c_diff k_A E(n)/pi."""
    env = _asymmetric_env()
    emap = irradiance.irradiance_map_brute(env, 64)
    path = tmp_path / "irr.exr"
    exr.write_exr(path, {c: emap[..., k].astype(np.float32) for k, c in enumerate("RGB")})
    image = L.load_irradiance_image(str(path))
    group = L.ensure_node_group(image)
    sc = S.new_scene("node", (8, 8))
    S.world(sc, 0.0)
    sphere = S.sphere(sc, "Ball", 1.0, segments=16, rings=8)
    mat = L.irradiance_material("amb", group, diffuse=(0.5, 0.25, 1.0))
    next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup").inputs["AO"].default_value = 0.6
    assert L.ensure_node_group(image) == group   # running the operator again keeps the material's inputs
    sphere.data.materials.append(mat)
    me = sphere.data
    me.color_attributes.new("emit", "FLOAT_COLOR", "POINT")
    me.color_attributes.active_color_name = "emit"
    render.cycles_cpu(sc, 1)
    vl = sc.view_layers[0]
    sphere.select_set(True, view_layer=vl)
    vl.objects.active = sphere
    with bpy.context.temp_override(scene=sc, view_layer=vl, active_object=sphere, object=sphere,
                                   selected_objects=[sphere], selected_editable_objects=[sphere]):
        bpy.ops.object.bake(type="EMIT", target="VERTEX_COLORS")
    got = np.empty(len(me.vertices) * 4, np.float32)
    me.color_attributes["emit"].data.foreach_get("color", got)
    got = got.reshape(-1, 4)[:, :3]
    nrm = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("normal", nrm)
    want = np.array([0.5, 0.25, 1.0]) * 0.6 * latlong.sample_latlong(emap, nrm.reshape(-1, 3)) / np.pi
    ring = np.abs(nrm.reshape(-1, 3)[:, 2]) < 0.99   # the poles' lat-long lookup is a fan of directions
    assert ring.sum() == len(ring) - 2
    assert np.allclose(got[ring], want[ring], rtol=0.01, atol=1e-4)


@pytest.mark.both_versions
def test_script_with_env_file_writes_exr_and_report(script, tmp_path):
    env = analytic.linear_sky(64, 128, 1.0, 0.6)
    _, path = _env_image(tmp_path, env, "sky.exr")
    proc = script("envmap.py", "--env", path, "--out", tmp_path / "o", "--width", "32")
    assert proc.returncode == 0, proc.stderr
    ch, hdr = exr.read_exr(tmp_path / "o" / "irradiance_latlong.exr")
    got = np.stack([ch[c] for c in "RGB"], axis=-1)
    want = analytic.linear_sky_irradiance(latlong.latlong_directions(16, 32), 1.0, 0.6)
    assert got.shape == (16, 32, 3) and np.allclose(got, want, rtol=0.01)
    rep = json.loads((tmp_path / "o" / "envmap_report.json").read_text())
    assert rep["method"] == "sh9" and len(rep["sh9"]) == 9 and rep["seconds"] >= 0
    bad = script("envmap.py", "--env", tmp_path / "nope.exr", "--out", tmp_path / "o")
    assert bad.returncode == 2 and "no such environment file" in bad.stderr


def test_script_reads_the_world_of_a_blend(script, tmp_path):
    env = analytic.linear_sky(32, 64, 0.5, 0.25)
    img, _ = _env_image(tmp_path, env, "w.exr")
    sc = bpy.context.scene
    L.set_world_environment(sc, img, strength=2.0)
    blend = tmp_path / "world.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    proc = script("envmap.py", blend, "--out", tmp_path / "o", "--method", "brute", "--width", "16")
    assert proc.returncode == 0, proc.stderr
    ch, _ = exr.read_exr(tmp_path / "o" / "irradiance_latlong.exr")
    want = analytic.linear_sky_irradiance(latlong.latlong_directions(8, 16), 1.0, 0.5)   # strength 2 doubles a and b
    assert np.allclose(np.stack([ch[c] for c in "RGB"], -1), want, rtol=0.02)


def test_operator_from_world_and_errors(tmp_path):
    sc = bpy.context.scene
    S.world(sc, 1.0)   # no environment texture
    with pytest.raises(RuntimeError, match="no Environment Texture"):   # reported, cancelled
        bpy.ops.illumination.envmap_irradiance(output_dir=str(tmp_path / "o"))
    assert not (tmp_path / "o" / "irradiance_latlong.exr").exists()
    img, _ = _env_image(tmp_path, np.full((16, 32, 3), 0.5, np.float32))
    L.set_world_environment(sc, img)
    assert bpy.ops.illumination.envmap_irradiance(output_dir=str(tmp_path / "o"), width=8) == {"FINISHED"}
    ch, _ = exr.read_exr(tmp_path / "o" / "irradiance_latlong.exr")
    assert np.allclose(ch["R"], np.pi * 0.5, rtol=1e-3)
    assert L.GROUP in bpy.data.node_groups
