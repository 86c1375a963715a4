"""Light-map bakes against closed forms (REFERENCE.md §3); tolerances from the Monte Carlo variance."""
import math

import bpy
import numpy as np
import pytest

from addon.blender import compat
from addon.bake import BakeOptions, bake_lightmaps
from addon.core import lightmap as lm, pack
from addon.core.io import exr
from addon.blender import scene as sc


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


def roof_reference(n, size, side, height):
    """Analytic k_A = 1 - F (Lambert's polygon formula) at the texel centres of an n x n map of a
    ``size`` receiver under a centred parallel square of side ``side`` at ``height``; EXR row order."""
    x, y = texel_xy(n, size)
    h = side / 2
    roof = np.array([(-h, -h, height), (h, -h, height), (h, h, height), (-h, h, height)], float)
    return np.array([[1 - lm.view_factor_polygon((xx, yy, 0), (0, 0, 1), roof) for xx, yy in zip(xr, yr)]
                     for xr, yr in zip(x, y)])


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
    rep = bake(scene, [r], ["ao"], tmp_path, resolution=n, samples=samples, ao_distance=100.0)
    k = read(tmp_path, "R", "ao")[0]["Y"]
    ref = roof_reference(n, 1.0, a, c)
    _check_ao(k, ref, samples)
    # plain AO reports the binomial bound of REFERENCE.md §3, and it is one: the real error is below it
    e = rep["objects"]["R"]["ao"]
    assert e["error_estimate"].startswith("binomial bound")
    assert e["estimated_error"] == pytest.approx(math.sqrt(np.mean(ref * (1 - ref)) / samples), rel=0.05)
    assert lm.rms(k, ref) < e["estimated_error"]
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
    box.data.materials.append(_wall_material("Wall", rho, le))
    r = receiver(scene, 0.2)
    for k in (0, 1, 3):
        rep = bake(scene, [r], ["irradiance"], tmp_path / str(k), resolution=16, samples=16, bounces=k)
        e = read(tmp_path / str(k), "R", "irradiance")[0]["R"]
        expected = lm.irradiance_enclosure(le, rho, k)
        se = e.std() / math.sqrt(e.size)
        assert abs(e.mean() - expected) < 4 * se + 0.01 * expected, (k, e.mean(), expected)
        # E is uniform here, so the texels' scatter is the noise: the half-bake estimate must match it
        # (4 standard errors of a standard deviation from 256 texels: 4/√512 = 18 %)
        est = rep["objects"]["R"]["irradiance"]
        assert est["error_estimate"].startswith("measured")
        assert abs(est["estimated_error"] - e.std()) <= 0.18 * e.std() + 1e-6 * expected, (k, est, e.std())


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


def test_bright_enclosure_is_not_clamped(tmp_path):
    """Blender clamps indirect samples at 10 by default; a bright room (rho L_e = 30 per bounce) must still
    follow E = pi Le (1 - rho^(K+1)) / (1 - rho), and the user's clamp settings come back."""
    scene = sc.new_scene("T")
    scene.cycles.sample_clamp_direct, scene.cycles.sample_clamp_indirect = 0.0, 10.0
    le, rho = 50.0, 0.6
    box = sc.box(scene, "Room", 2.0, location=(0, 0, 0))
    box.data.materials.append(_wall_material("Wall", rho, le))
    r = receiver(scene, 0.2)
    bake(scene, [r], ["irradiance"], tmp_path, resolution=16, samples=16, bounces=3)
    e = read(tmp_path, "R", "irradiance")[0]["R"]
    expected = lm.irradiance_enclosure(le, rho, 3)
    se = e.std() / math.sqrt(e.size)
    assert abs(e.mean() - expected) < 4 * se + 0.01 * expected, (e.mean(), expected)
    assert (scene.cycles.sample_clamp_direct, scene.cycles.sample_clamp_indirect) == (0.0, 10.0)


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


def test_target_error_meets_the_error_with_no_more_samples_than_needed(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 1.0)
    sc.plane(scene, "Roof", 1.0, location=(0, 0, 0.5))
    n, goal = 32, 0.03
    ref = roof_reference(n, 1.0, 1.0, 0.5)
    rep = bake(scene, [r], ["ao"], tmp_path / "t", resolution=n, target_error=goal, ao_distance=100.0)
    e = rep["objects"]["R"]["ao"]
    err = lm.rms(read(tmp_path / "t", "R", "ao")[0]["Y"], ref)
    # the target is met, and the reported error is measured: it agrees with the error against the closed form
    # (both carry the sampling noise of an RMS over 1024 texels: 4/√2048 ≈ 9 % each)
    assert e["error_estimate"].startswith("measured") and e["pilot_samples"] == 8
    assert err < goal * 1.1 and e["estimated_error"] <= goal
    assert abs(e["estimated_error"] / err - 1) < 0.2, (e["estimated_error"], err)
    # no more than needed: far fewer samples than independent sampling needs (σ²/E², σ² = mean k_A(1 - k_A)),
    # and one plain bake with half of them misses the target
    assert e["samples"] < 0.5 * np.mean(ref * (1 - ref)) / goal ** 2
    bake(scene, [r], ["ao"], tmp_path / "p", resolution=n, samples=e["samples"] // 2, ao_distance=100.0)
    assert lm.rms(read(tmp_path / "p", "R", "ao")[0]["Y"], ref) > goal


def test_denoise_lowers_the_error_of_a_noisy_map(tmp_path):
    scene = sc.new_scene("T")
    r = receiver(scene, 1.0)
    sc.plane(scene, "Roof", 1.0, location=(0, 0, 0.5))
    n = 32
    ref = roof_reference(n, 1.0, 1.0, 0.5)
    bake(scene, [r], ["ao"], tmp_path / "a", resolution=n, samples=4, ao_distance=100.0)
    rep = bake(scene, [r], ["ao"], tmp_path / "b", resolution=n, samples=4, ao_distance=100.0, denoise=True)
    plain = lm.rms(read(tmp_path / "a", "R", "ao")[0]["Y"], ref)
    den = lm.rms(read(tmp_path / "b", "R", "ao")[0]["Y"], ref)
    assert den < 0.6 * plain, (plain, den)
    e = rep["objects"]["R"]["ao"]
    assert read(tmp_path / "b", "R", "ao")[1]["il:denoised"] == "1" and e["denoised"]
    # the report says its estimate is the noise before denoising, and the denoised map's error is below it
    assert "before denoising" in e["error_estimate"] and den < e["estimated_error"]


def test_denoised_maps_stay_in_their_range(tmp_path):
    """25.4: the denoiser overshoots at sharp edges (k_A above 1 on Sponza's floors): a denoised AO map stays in
    [0, 1] and an irradiance map non-negative. The scene: a small post on a floor, open sky elsewhere (k_A = 1
    next to the contact shadow), 4 samples."""
    from addon.bake.denoise import denoise
    scene = sc.new_scene("T")
    r = receiver(scene, 2.0, cuts=0)
    sc.box(scene, "Post", (0.15, 0.15, 0.6), location=(0.0, 0.0, 0.3))
    sc.light(scene, "Sun", "SUN", 3.0, rotation=(0.6, 0.0, 0.3))
    sc.world(scene, strength=1.0)
    bake(scene, [r], ["ao"], tmp_path / "a", resolution=64, samples=4, ao_distance=0.4)
    rep = bake(scene, [r], ["ao", "irradiance"], tmp_path / "b", resolution=64, samples=4, ao_distance=0.4,
               denoise=True)
    noisy, _ = read(tmp_path / "a", "R", "ao")
    filled, _ = lm.nearest_fill(np.flipud(noisy["Y"]), np.flipud(noisy["A"] > 0.5))
    assert denoise(filled).max() > 1.0                 # the filter overshoots here (1.026 with OIDN 2.x)
    k = read(tmp_path / "b", "R", "ao")[0]["Y"]
    assert k.min() >= 0.0 and k.max() <= 1.0, (k.min(), k.max())
    e = read(tmp_path / "b", "R", "irradiance")[0]
    assert min(float(e[c].min()) for c in "RGB") >= 0.0
    assert rep["objects"]["R"]["ao"]["denoised"]


def _lightmap_uvs(obj):
    """(loops, 2) UVs of the generated "Lightmap" layer."""
    uv = np.zeros(len(obj.data.loops) * 2)
    obj.data.uv_layers["Lightmap"].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)


def _chart_masks(obj, res, height=None):
    """Coverage mask of each quad of ``obj`` in "Lightmap" (each face of a box or plane is a chart) in a res x height
    map (square without ``height``)."""
    uv = _lightmap_uvs(obj)
    return [lm.coverage_mask(uv[list(p.loop_indices)][[[0, 1, 2], [0, 2, 3]]], res, height or res)
            for p in obj.data.polygons]


def test_generated_atlas_keeps_texel_density_and_margins_and_dilation_hides_seams(tmp_path):
    scene = sc.new_scene("T")
    a = sc.box(scene, "A", 1.0)                                    # 6 m²
    b = sc.plane(scene, "B", 2.0, location=(30, 0, 0))             # 4 m², out of the box's AO reach
    a.data.uv_layers.new(name="Mine")
    before = np.zeros(len(a.data.loops) * 2)
    a.data.uv_layers["Mine"].data.foreach_get("uv", before)
    density, margin = 16.0, 2
    rep = bake_lightmaps([a, b], ["ao"], tmp_path, BakeOptions(texel_density=density, samples=1, atlas=True,
                                                               margin=margin, ao_distance=1.0), scene=scene)
    ch = read(tmp_path, "atlas", "ao")[0]
    height, res = ch["A"].shape
    assert rep["objects"]["A"]["ao"]["resolution"] == [res, height] and rep["objects"]["B"]["ao"]["file"].endswith(
        "atlas_ao.exr")
    # the texel density holds: covered texels = T² × 10 m² (within the rasterisation of the chart borders)
    assert abs((ch["A"] > 0).sum() / (density ** 2 * 10.0) - 1) < 0.06
    # the 7 charts' covered texels lie at least 2 × margin − 1 texels apart (chessboard: the texels they touch keep
    # 2m − 2 free texels between them, core.pack), so each gap texel the dilation fills is nearest to one chart
    charts = _chart_masks(a, res, height) + _chart_masks(b, res, height)
    for i, mask in enumerate(charts):
        others = np.any([m for j, m in enumerate(charts) if j != i], axis=0)
        src = lm.nearest_covered(others).ravel()
        ys, xs = np.nonzero(mask)
        sy, sx = np.divmod(src[ys * res + xs], res)
        assert np.maximum(abs(sy - ys), abs(sx - xs)).min() >= 2 * margin - 1
    # nothing is occluded (k_A = 1 exactly on every covered texel), so a bilinear lookup anywhere on the
    # surface, even at a chart corner on a UV seam, must read 1; without the dilation it reads black there
    y, cov = np.flipud(ch["Y"]), np.flipud(ch["A"]) > 0
    assert np.all(y[cov] == 1.0)
    corners = np.concatenate([_lightmap_uvs(o) for o in (a, b)])
    np.testing.assert_allclose(lm.bilinear(y, corners), 1.0, atol=1e-6)
    assert lm.bilinear(np.where(cov, y, 0.0), corners).min() < 0.5
    # the user's own layer and the active layer are untouched
    after = np.zeros_like(before)
    a.data.uv_layers["Mine"].data.foreach_get("uv", after)
    assert np.array_equal(before, after) and a.data.uv_layers.active.name == "Mine"


def _footprint_gap(charts, res):
    """Empty texels (chessboard) between the nearest two of ``charts`` (UV triangles (T, 3, 2) each): their
    footprints are the texels a 15 x finer raster of them touches, their gap the least over texel pairs."""
    f = 15
    feet = [np.argwhere(lm.coverage_mask(t, f * res, f * res).reshape(res, f, res, f).any(axis=(1, 3)))
            for t in charts]
    return min(int(np.abs(a[:, None] - b[None]).max(axis=2).min()) - 1
               for i, a in enumerate(feet) for b in feet[i + 1:])


def test_a_reused_layer_reports_the_margin_it_keeps_not_the_asked_one(tmp_path):
    """A box baked with margin 1 keeps its "Lightmap" layer; a bake into another folder with margin 4 reuses it and
    reports the margin its charts keep (core.margins: the largest whose packing rule, footprints max(1, ⌈2m⌉ − 2)
    texels apart, the layout keeps), from its footprints' gap; the map is still dilated by the asked 4."""
    from addon.core.margins import margin_from_gap
    scene = sc.new_scene("T")
    box = sc.box(scene, "Box", 1.0)
    first = bake_lightmaps([box], ["ao"], tmp_path / "a", BakeOptions(resolution=32, samples=1, margin=1),
                           scene=scene)["objects"]["Box"]["ao"]
    assert first["margin"] == 1 and first["unwrap"]
    with pytest.warns(UserWarning, match=r"'Box': light-map layer 'Lightmap' keeps a margin of [0-9.]+ texel\(s\) "
                                         r"between its charts at 32x32, below the asked 4"):
        rep = bake_lightmaps([box], ["ao"], tmp_path / "b", BakeOptions(resolution=32, samples=1, margin=4),
                             scene=scene)
    entry = rep["objects"]["Box"]["ao"]
    uv = _lightmap_uvs(box)
    faces = [uv[list(p.loop_indices)][[[0, 1, 2], [0, 2, 3]]] for p in box.data.polygons]
    corners = [list(p.loop_indices) for p in box.data.polygons]
    chart = pack.chart_labels(np.repeat(np.arange(len(corners)), 4), [box.data.loops[i].vertex_index
                                                                      for c in corners for i in c],
                              uv[[i for c in corners for i in c]])
    gap = _footprint_gap([np.concatenate([f for f, k in zip(faces, chart) if k == c]) for c in set(chart)], 32)
    assert "unwrap" not in entry and len(set(chart)) > 1 and 1 <= gap < 6
    assert entry["margin"] == margin_from_gap(gap) and 1 <= entry["margin"] < 4
    assert entry["dilation"] == 4
    assert float(read(tmp_path / "b", "Box", "ao")[1]["il:margin"]) == entry["margin"]


def test_a_users_layer_whose_charts_touch_reports_a_margin_of_zero(tmp_path):
    """Blender's cone UVMap lays the side's fan and the base's disc as two circles of radius 1/4 that touch at
    (0.5, 0.5): the layer keeps no margin, which the report says (0, with the warning) instead of the asked 2; the
    map is dilated by 2 all the same."""
    scene = sc.new_scene("T")
    bpy.ops.mesh.primitive_cone_add(vertices=32)
    cone = bpy.context.object
    scene.collection.objects.link(cone)
    with pytest.warns(UserWarning, match="'Cone': light-map layer 'UVMap' keeps a margin of 0 texel.* below the "
                                         "asked 2 .*bake without a UV layer of your own"):
        rep = bake(scene, [cone], ["ao"], tmp_path, resolution=64, samples=1, uv_layer="UVMap", margin=2)
    entry = rep["objects"]["Cone"]["ao"]
    assert entry["margin"] == 0 and entry["dilation"] == 2


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


def test_a_users_layer_with_overlapping_charts_is_used_as_it_is(tmp_path):
    """Each face of a cube fills the whole UV square (a tiled layout): the layer is baked as it is, with the
    overlap reported, not refused for a chart area counted six times. Open sky: k_A = 1 on every face."""
    scene = sc.new_scene("T")
    cube = sc.box(scene, "Cube", 1.0)
    me = cube.data
    layer = me.uv_layers.new(name="Tiled")
    corners = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)
    uv = np.concatenate([corners[: p.loop_total] for p in me.polygons])
    layer.data.foreach_set("uv", uv.ravel())
    rep = bake(scene, [cube], ["ao"], tmp_path, resolution=16, samples=4, uv_layer="Tiled")
    entry = rep["objects"]["Cube"]["ao"]
    ch, _ = read(tmp_path, "Cube", "ao")
    assert entry["chart_area"] == pytest.approx(1.0, abs=0.01)
    assert ch["A"].mean() == 1.0 and entry["overlap"] > 0.9
    np.testing.assert_array_equal(ch["Y"], 1.0)


def test_unreachable_target_errors_are_refused_before_any_bake_and_a_missed_one_is_reported_capped(tmp_path, script):
    """Item 11: a target below what max_samples can reach (AO: 0.5 / max_samples; any map: the smallest normal
    float32) is refused before any bake, in one line naming the smallest; a target the pilot cannot reach within
    the cap is baked to the cap, with a warning and "capped" in the report."""
    from addon.core.errors import ILWarning, InputError
    scene = sc.new_scene("T")
    r = receiver(scene, 1.0)
    sc.plane(scene, "Roof", 1.0, location=(0, 0, 0.5))
    sc.world(scene, strength=1.0)
    for maps, goal, least in ((["ao"], 1e-9, 0.5 / 4096), (["irradiance"], 1e-300, lm.SMALLEST_TARGET_ERROR),
                              (["ao"], 0.5 / 64 * 0.99, 0.5 / 64)):
        with pytest.raises(InputError, match=f"smallest target error is {least:.3g}"):
            bake(scene, [r], maps, tmp_path / "no", resolution=8, target_error=goal,
                 max_samples=64 if goal > 1e-4 else 4096)
    assert not (tmp_path / "no").exists()
    for maps, goal in ((["irradiance"], 1e-6), (["ao"], 0.04)):     # AO: 0.04 >= 0.5 / 16, missed at 16 samples
        with pytest.warns(ILWarning, match=f"target error {goal:g} not reached: capped at 16 samples"):
            rep = bake(scene, [r], maps, tmp_path / maps[0], resolution=8, target_error=goal, max_samples=16,
                       bounces=0, ao_distance=100.0)
        e = rep["objects"]["R"][maps[0]]
        assert e["capped"] is True and e["samples"] == 16 and e["estimated_error"] > goal
    rep = bake(scene, [r], ["ao"], tmp_path / "met", resolution=8, target_error=0.3, ao_distance=100.0)
    assert "capped" not in rep["objects"]["R"]["ao"]
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "s.blend"))
    for goal, least in (("1e-300", "1.18e-38"), ("1e-9", "0.000122")):
        res = script("bake.py", tmp_path / "s.blend", "--objects", "R", "--maps", "ao", "--resolution", "8",
                     "--target-error", goal, "--out", tmp_path / goal)
        lines = [l for l in res.stderr.strip().splitlines() if l.startswith("bake.py")]
        assert res.returncode == 2 and len(lines) == 1 and f"smallest target error is {least}" in lines[0], res.stderr
        assert "Traceback" not in res.stderr and not (tmp_path / goal).exists()


def test_very_large_and_very_small_objects_get_the_light_map_of_a_one_metre_object(tmp_path, monkeypatch):
    """Item 13: a 4e6 m plane and a 1e-6 m cube were refused at any resolution ("the charts do not fit even the
    largest map"): Smart UV Project lost their charts. Their unwrap copies are scaled to about 1 m, so a fixed
    resolution covers them as it covers a 1 m plane and cube; --texel-density stays texels per metre of the real
    object, and on the huge plane the memory limit refuses the side it asks for, naming the --max-resolution."""
    from addon.bake import cost, unwrap_copy
    from addon.core import budget
    from addon.core.errors import InputError
    scene = sc.new_scene("T")
    made = {"Huge": sc.plane(scene, "Huge", 4e6), "Plane": sc.plane(scene, "Plane", 1.0, location=(0, 0, 1e7)),
            "Tiny": sc.box(scene, "Tiny", 1e-6, location=(0, 0, -1e7)),
            "Cube": sc.box(scene, "Cube", 1.0, location=(0, 0, 2e7))}
    assert unwrap_copy.unwrap_scale([made["Huge"].data]) == 2.0 ** -22 and unwrap_copy.unwrap_scale([made["Cube"].data]) == 1.0
    rep = bake_lightmaps(list(made.values()), ["ao"], tmp_path / "fixed", BakeOptions(resolution=32, samples=1),
                         scene=scene)["objects"]
    for big, one in (("Huge", "Plane"), ("Tiny", "Cube")):
        assert rep[big]["ao"]["resolution"] == [32, 32]
        assert rep[big]["ao"]["coverage"] == pytest.approx(rep[one]["ao"]["coverage"], abs=0.02)
        assert rep[big]["ao"]["coverage"] > 0.25
        assert rep[big]["ao"]["chart_area"] == pytest.approx(rep[one]["ao"]["chart_area"], abs=0.02)
    monkeypatch.setattr(budget, "available_bytes", lambda: 8 * 2 ** 30)
    largest = cost.largest_side(8 * 2 ** 30, ["ao"])
    with pytest.raises(InputError, match=r"'Huge': a 16384x16384 map needs about 60\.0 GiB of memory and 8\.0 GiB "
                                         f"is available: the largest max resolution that fits is {largest}$"):
        bake_lightmaps([made["Huge"]], ["ao"], tmp_path / "density", BakeOptions(texel_density=32,
                       max_resolution=16384, samples=1), scene=scene)
    me = made["Tiny"].data                # a layout made for the density (the 32² one would be reused)
    me.uv_layers.remove(me.uv_layers["Lightmap"])
    tiny = bake_lightmaps([made["Tiny"]], ["ao"], tmp_path / "tiny", BakeOptions(texel_density=4e6, samples=1),
                          scene=scene)["objects"]["Tiny"]["ao"]
    covered = tiny["coverage"] * tiny["resolution"][0] * tiny["resolution"][1]    # a window: width x height
    assert abs(covered / (4e6 ** 2 * 6e-12) - 1) < 0.1, tiny          # T² × area, as for a 1 m object
