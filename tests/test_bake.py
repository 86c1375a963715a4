"""Light-map bakes against closed forms (REFERENCE.md §3); tolerances from the Monte Carlo variance."""
import math

import bpy
import numpy as np
import pytest

from addon import compat
from addon.bake import BakeOptions, bake_lightmaps
from addon.core import exr, lightmap as lm
from addon.lab import scene as sc


def receiver(scene, size, name="R", location=(0, 0, 0), cuts=0):
    """A square plane with a UV layer "UVMap" mapping x, y in [-size/2, size/2] linearly to [0, 1]."""
    obj = sc.plane(scene, name, size, location=location, subdivisions=cuts)
    me = obj.data
    layer = me.uv_layers.new(name="UVMap")
    co = np.zeros(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    vi = np.zeros(len(me.loops), int)
    me.loops.foreach_get("vertex_index", vi)
    layer.data.foreach_set("uv", (co[vi, :2] / size + 0.5).ravel())
    return obj


def texel_xy(n, size, location=(0, 0)):
    """World x, y of texel centres, (n, n) each, row 0 at the top (v = 1) as the EXR stores them."""
    c = (np.arange(n) + 0.5) / n
    x = (c - 0.5) * size + location[0]
    y = (c[::-1] - 0.5) * size + location[1]
    return np.meshgrid(x, y)


def bake(scene, objs, maps, out, **kw):
    kw.setdefault("uv_layer", "UVMap")
    kw.setdefault("margin", 0)
    return bake_lightmaps(objs, maps, out, BakeOptions(**kw), scene=scene)


def read(out, name, kind):
    ch, header = exr.read_exr(out / f"{name}_{kind}.exr")
    return ch, header


@pytest.mark.both_versions
def test_open_plane_ao_is_one_and_uniform_sky_gives_pi_l(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 2.0)
    sc.world(scene, strength=0.7)
    rep = bake(scene, [r], ["ao", "irradiance"], tmp_path, resolution=16, samples=4, bounces=0)
    ao, hd = read(tmp_path, "R", "ao")
    assert ao["A"].min() == 1.0 and np.all(ao["Y"] == 1.0)
    ir, hi = read(tmp_path, "R", "irradiance")
    for c in "RGB":
        np.testing.assert_allclose(ir[c], math.pi * 0.7, rtol=1e-4)
    assert hi["il:units"] == "W/m^2" and hd["il:quantity"].startswith("ambient occlusion")
    assert hd["il:samples"] == "4" and hd["il:uv_layer"] == "UVMap" and hd["il:blender_version"] == bpy.app.version_string
    assert float(hd["il:ao_distance"]) == 10.0
    e = rep["objects"]["R"]["ao"]
    assert e["resolution"] == [16, 16] and e["samples"] == 4 and e["estimated_error"] == 0.0
    assert (tmp_path / "R_ao.png").exists() and (tmp_path / "bake_report.json").exists()


def _check_ao(k, ref, samples):
    """Mean and per-row checks of k_A against the reference, at 4 binomial standard errors."""
    sd = lm.binomial_sd(ref, samples)
    n = ref.size
    assert abs(np.mean(k - ref)) < 4 * math.sqrt(np.sum(sd ** 2)) / n + 2e-3
    rows = np.abs(np.mean(k - ref, axis=1)) / (np.sqrt(np.sum(sd ** 2, axis=1)) / k.shape[1] + 1e-3)
    assert rows.max() < 4.5


def test_receiver_beside_a_long_tall_wall_tends_to_one_half(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 2.0)
    sc.box(scene, "Wall", (400.0, 0.2, 30.0), location=(0, 1.1, 15.0))   # face at y = 1.0
    samples, n = 64, 32
    bake(scene, [r], ["ao"], tmp_path, resolution=n, samples=samples, ao_distance=1000.0)
    k = read(tmp_path, "R", "ao")[0]["Y"]
    x, y = texel_xy(n, 2.0)
    faces = _box_faces((-200, 1.0, 0.0), (200, 1.2, 30.0))
    ref = np.array([[1 - lm.view_factor_convex((xx, yy, 0), (0, 0, 1), faces) for xx, yy in zip(xr, yr)]
                    for xr, yr in zip(x, y)])
    _check_ao(k, ref, samples)
    # the long-wall formula and its limit 1/2 at the foot of the wall
    d = 1.0 - y[:, 0]
    np.testing.assert_allclose(ref[:, n // 2], 1 - np.array([lm.view_factor_long_wall(di, 30.0) for di in d]),
                               atol=2e-3)
    assert abs(k[0].mean() - 0.5) < 0.05 and abs(k[-1].mean() - 1 + lm.view_factor_long_wall(2.0, 30)) < 0.05


def test_centred_parallel_square_occluder_matches_howell_b3(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 1.0)
    a, c = 2.0, 1.0
    sc.plane(scene, "Roof", a, location=(0, 0, c))
    samples, n = 64, 32
    bake(scene, [r], ["ao"], tmp_path, resolution=n, samples=samples, ao_distance=100.0)
    k = read(tmp_path, "R", "ao")[0]["Y"]
    x, y = texel_xy(n, 1.0)
    roof = np.array([(-1, -1, c), (1, -1, c), (1, 1, c), (-1, 1, c)], float)
    ref = np.array([[1 - lm.view_factor_polygon((xx, yy, 0), (0, 0, 1), roof) for xx, yy in zip(xr, yr)]
                    for xr, yr in zip(x, y)])
    _check_ao(k, ref, samples)
    centre = 1 - lm.view_factor_rect_centered(a, a, c)
    mid = k[n // 2 - 2:n // 2 + 2, n // 2 - 2:n // 2 + 2]
    assert abs(mid.mean() - centre) < 4 * lm.binomial_sd(centre, samples * mid.size) + 2e-3


def test_sun_and_point_light_irradiance(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 4.0)
    sc.world(scene, strength=0.0)
    theta = math.radians(60)
    sun = sc.light(scene, "Sun", "SUN", 3.0, rotation=(theta, 0, 0))
    bake(scene, [r], ["irradiance"], tmp_path / "sun", resolution=16, samples=2, bounces=0)
    e = read(tmp_path / "sun", "R", "irradiance")[0]
    np.testing.assert_allclose(e["R"], 3.0 * math.cos(theta), rtol=1e-3)
    sun.hide_render = True
    sc.light(scene, "Point", "POINT", 100.0, location=(0.5, -0.3, 2.0))
    n = 32
    bake(scene, [r], ["irradiance"], tmp_path / "pt", resolution=n, samples=2, bounces=0)
    e = read(tmp_path / "pt", "R", "irradiance")[0]["G"]
    x, y = texel_xy(n, 4.0)
    d = np.sqrt((x - 0.5) ** 2 + (y + 0.3) ** 2 + 4.0)
    ref = lm.irradiance_point(100.0, d, 2.0 / d)
    np.testing.assert_allclose(e, ref, rtol=0.01)


def test_closed_enclosure_follows_the_truncated_bounce_series(tmp_path):
    scene = sc.new_scene("T")
    le, rho = 0.5, 0.6
    box = sc.box(scene, "Room", 2.0, location=(0, 0, 0))
    mat = bpy.data.materials.new("Wall")
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    dif = nt.nodes.new("ShaderNodeBsdfDiffuse")
    dif.inputs["Color"].default_value = (rho, rho, rho, 1)
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = le
    add = nt.nodes.new("ShaderNodeAddShader")
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(dif.outputs[0], add.inputs[0])
    nt.links.new(em.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], out.inputs["Surface"])
    box.data.materials.append(mat)
    r = receiver(scene, 0.2)
    for k in (0, 1, 3):
        bake(scene, [r], ["irradiance"], tmp_path / str(k), resolution=16, samples=16, bounces=k)
        e = read(tmp_path / str(k), "R", "irradiance")[0]["R"]
        expected = lm.irradiance_enclosure(le, rho, k)
        se = e.std() / math.sqrt(e.size)
        assert abs(e.mean() - expected) < 4 * se + 0.01 * expected, (k, e.mean(), expected)


def _inward_cube(scene, name, half, strip=4):
    """A closed cube [-half, half]³ with inward normals; UV layer "UVMap" gives face i the columns
    [i, i + 1) × strip of a 6·strip map (all of v). Returns (object, faces as (4, 3) corner arrays)."""
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = -sign                              # inward
            t = np.zeros(3)
            t[(axis + 1) % 3] = 1.0
            b = np.cross(n, t)
            c = -half * n                                # the face plane
            faces.append(np.array([c + half * (-t - b), c + half * (t - b), c + half * (t + b), c + half * (-t + b)]))
    verts = np.concatenate(faces)
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(range(4 * i, 4 * i + 4)) for i in range(6)])
    me.update()
    uv = me.uv_layers.new(name="UVMap")
    u = np.array([[i, i + 1, i + 1, i] for i in range(6)], float).ravel() / 6
    v = np.tile([0.0, 0.0, 1.0, 1.0], 6)
    uv.data.foreach_set("uv", np.stack([u, v], -1).ravel())
    obj = bpy.data.objects.new(name, me)
    scene.collection.objects.link(obj)
    return obj, faces


def _wall_material(name, rho, le):
    """Diffuse of albedo rho plus Emission of radiance le (an Emission shader alone when rho = 0)."""
    mat = bpy.data.materials.new(name)
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = le
    if rho == 0:
        nt.links.new(em.outputs[0], out.inputs["Surface"])
        return mat
    dif = nt.nodes.new("ShaderNodeBsdfDiffuse")
    dif.inputs["Color"].default_value = (rho, rho, rho, 1)
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(dif.outputs[0], add.inputs[0])
    nt.links.new(em.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], out.inputs["Surface"])
    return mat


@pytest.mark.both_versions
def test_baked_enclosure_walls_keep_their_own_albedo_and_emission(tmp_path):
    """The box IS the baked object: its walls must light each other with their own rho and L_e
    (not as white non-emitters), E = pi Le (1 - rho^(K+1)) / (1 - rho) on every wall."""
    scene = sc.new_scene("T")
    sc.world(scene, strength=0.0)
    le, rho = 0.5, 0.6
    box, _ = _inward_cube(scene, "Room", 1.0)
    box.data.materials.append(_wall_material("Wall", rho, le))
    for k in (0, 1, 3):
        bake(scene, [box], ["irradiance"], tmp_path / str(k), resolution=24, samples=16, bounces=k)
        ch = read(tmp_path / str(k), "Room", "irradiance")[0]
        assert ch["A"].min() == 1.0                    # the six strips cover the whole map
        e = ch["R"]
        expected = lm.irradiance_enclosure(le, rho, k)
        se = e.std() / math.sqrt(e.size)
        assert abs(e.mean() - expected) < 4 * se + 2e-3 * expected, (k, e.mean(), expected)


def test_multi_material_object_keeps_each_slot_for_the_bounces(tmp_path):
    """One object, two slots: floor and ceiling pure emitters (albedo 0), the four walls emit and reflect rho.
    One bounce: E(p) = pi Le (1 + rho sum over the walls j in view F(p -> j)), per face at the texel centres."""
    scene = sc.new_scene("T")
    sc.world(scene, strength=0.0)
    le, rho, strip, res = 0.5, 0.6, 4, 24
    box, faces = _inward_cube(scene, "Room", 1.0, strip)
    box.data.materials.append(_wall_material("Emitter", 0.0, le))
    box.data.materials.append(_wall_material("Wall", rho, le))
    walls = [i for i, f in enumerate(faces) if abs(f[0, 2] - f[2, 2]) > 0]    # faces spanning z
    box.data.polygons.foreach_set("material_index", [int(i in walls) for i in range(6)])
    bake(scene, [box], ["irradiance"], tmp_path, resolution=res, samples=64, bounces=1)
    e = read(tmp_path, "Room", "irradiance")[0]["R"]
    v = 1 - (np.arange(res) + 0.5) / res                     # EXR row 0 = top
    for i, f in enumerate(faces):
        cols = np.arange(i * strip, (i + 1) * strip)
        s = (cols + 0.5) / res * 6 - i
        n = np.cross(f[1] - f[0], f[3] - f[0])
        n /= np.linalg.norm(n)
        ref = []
        for vv in v:
            for ss in s:
                p = f[0] + (f[1] - f[0]) * ss + (f[3] - f[0]) * vv
                ref.append(1 + rho * sum(lm.view_factor_polygon(p, n, faces[j]) for j in walls if j != i))
        got, ref = e[:, cols].mean(), np.pi * le * np.mean(ref)
        assert abs(got / ref - 1) < 0.01, (i, got, ref)
    # the wrong answers this guards against: every slot white (no emission at all), or one slot for all
    assert abs(e.mean() - np.pi * le) > 0.3


@pytest.mark.both_versions
def test_vertex_colour_bake_agrees_with_image_bake(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 2.0, cuts=3)
    sc.world(scene, strength=0.0)
    sc.light(scene, "Point", "POINT", 50.0, location=(0.3, 0.2, 1.0))
    bake(scene, [r], ["irradiance"], tmp_path, resolution=64, samples=1, bounces=0, margin=2)
    img = np.flipud(read(tmp_path, "R", "irradiance")[0]["R"])
    rep = bake(scene, [r], ["irradiance"], tmp_path, samples=1, bounces=0, target="vertex", uv_layer=None)
    vert = exr.read_exr(tmp_path / "R_irradiance_vertex.exr")[0]["R"][0]
    me = r.data
    attr = me.color_attributes["IL Irradiance"]
    c = np.zeros(len(me.vertices) * 4, np.float32)
    attr.data.foreach_get("color", c)
    np.testing.assert_allclose(c.reshape(-1, 4)[:, 0], vert, rtol=1e-6)
    co = np.array([v.co[:] for v in me.vertices])
    inner = (np.abs(co[:, 0]) < 0.99) & (np.abs(co[:, 1]) < 0.99)
    uv = co[inner, :2] / 2.0 + 0.5
    np.testing.assert_allclose(vert[inner], lm.bilinear(img, uv), rtol=0.02)
    d2 = (co[:, 0] - 0.3) ** 2 + (co[:, 1] - 0.2) ** 2 + 1.0
    np.testing.assert_allclose(vert, lm.irradiance_point(50.0, np.sqrt(d2), 1.0 / np.sqrt(d2)), rtol=2e-3)
    assert rep["objects"]["R"]["irradiance"]["resolution"] == [len(me.vertices), 1]


def test_target_error_chooses_samples_and_meets_the_error(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 1.0)
    sc.plane(scene, "Roof", 1.0, location=(0, 0, 0.5))
    n = 32
    rep = bake(scene, [r], ["ao"], tmp_path, resolution=n, target_error=0.03, pilot_samples=8, ao_distance=100.0)
    e = rep["objects"]["R"]["ao"]
    k = read(tmp_path, "R", "ao")[0]["Y"]
    x, y = texel_xy(n, 1.0)
    roof = np.array([(-.5, -.5, .5), (.5, -.5, .5), (.5, .5, .5), (-.5, .5, .5)])
    ref = np.array([[1 - lm.view_factor_polygon((xx, yy, 0), (0, 0, 1), roof) for xx, yy in zip(xr, yr)]
                    for xr, yr in zip(x, y)])
    var = np.mean(ref * (1 - ref))
    # N = σ²/E² from the pilots' measured variance: at most the binomial bound k_A(1 - k_A)/E²
    assert 8 <= e["samples"] <= 1.15 * var / 0.03 ** 2
    assert e["estimated_error"] <= 0.03 and e["pilot_samples"] == 8
    assert lm.rms(k, ref) < 0.03 * 1.15


def test_denoise_lowers_the_error_of_a_noisy_map(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 1.0)
    sc.plane(scene, "Roof", 1.0, location=(0, 0, 0.5))
    n = 32
    x, y = texel_xy(n, 1.0)
    roof = np.array([(-.5, -.5, .5), (.5, -.5, .5), (.5, .5, .5), (-.5, .5, .5)])
    ref = np.array([[1 - lm.view_factor_polygon((xx, yy, 0), (0, 0, 1), roof) for xx, yy in zip(xr, yr)]
                    for xr, yr in zip(x, y)])
    bake(scene, [r], ["ao"], tmp_path / "a", resolution=n, samples=4, ao_distance=100.0)
    rep = bake(scene, [r], ["ao"], tmp_path / "b", resolution=n, samples=4, ao_distance=100.0, denoise=True)
    plain = lm.rms(read(tmp_path / "a", "R", "ao")[0]["Y"], ref)
    den = lm.rms(read(tmp_path / "b", "R", "ao")[0]["Y"], ref)
    assert den < 0.6 * plain, (plain, den)
    assert read(tmp_path / "b", "R", "ao")[1]["il:denoised"] == "1" and rep["objects"]["R"]["ao"]["denoised"]


def test_generated_uvs_atlas_and_texel_density(tmp_path):
    scene = sc.new_scene("T")
    a = sc.box(scene, "A", 1.0)
    b = sc.sphere(scene, "B", 0.5, location=(2, 0, 0), segments=16, rings=8)
    a.data.uv_layers.new(name="Mine")
    before = np.zeros(len(a.data.loops) * 2)
    a.data.uv_layers["Mine"].data.foreach_get("uv", before)
    rep = bake_lightmaps([a, b], ["ao"], tmp_path, BakeOptions(texel_density=16.0, samples=1, atlas=True),
                         scene=scene)
    from addon.bake import uv as uvmod
    res = rep["objects"]["A"]["ao"]["resolution"][0]
    masks = [lm.coverage_mask(uvmod.triangles_uv(o, "Lightmap"), res, res) for o in (a, b)]
    assert not np.any(masks[0] & masks[1])                     # charts of the atlas do not overlap
    area = uvmod.world_area(a) + uvmod.world_area(b)
    cover = sum(lm.uv_area(uvmod.triangles_uv(o, "Lightmap")) for o in (a, b))
    assert res == math.ceil(16.0 * math.sqrt(area / cover))
    after = np.zeros_like(before)
    a.data.uv_layers["Mine"].data.foreach_get("uv", after)
    assert np.array_equal(before, after) and a.data.uv_layers.active.name == "Mine"
    assert (tmp_path / "atlas_ao.exr").exists() and rep["objects"]["B"]["ao"]["file"].endswith("atlas_ao.exr")


def _box_faces(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    return [np.array(f, float) for f in (
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)])]
