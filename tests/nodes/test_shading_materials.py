"""Assign Shading Model keeps the user's materials (per slot, textures, emission), Remove Shading Model gives them
back (also after save and reopen), area lights as Lambertian spots (bpy)."""
import math

import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.blender import compat, render
from addon.blender import scene as sc
from addon.core import brdf, lights as twin_lights
from addon.nodes import material, source

SUN = 3.0
RED, GREEN, IMAGE, BASE = (0.8, 0.1, 0.1), (0.1, 0.7, 0.1), (0.2, 0.3, 0.9), (0.5, 0.5, 0.5)
EMISSION, STRENGTH = (1.0, 0.5, 0.2), 2.0
ROUGHNESS = 0.3


def _principled(name, base, emission=None):
    mat = bpy.data.materials.new(name)
    compat.ensure_use_nodes(mat)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Roughness"].default_value = ROUGHNESS
    if emission is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = STRENGTH
    return mat, bsdf


def _textured(tmp_path):
    mat, bsdf = _principled("Label", (1.0, 1.0, 1.0))
    image = bpy.data.images.new("Label", 4, 4, float_buffer=True, is_data=True)   # pixels used as they are
    image.pixels[:] = [*IMAGE, 1.0] * 16
    image.filepath_raw = str(tmp_path / "label.exr")
    image.file_format = "OPEN_EXR"
    image.save()
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def _strip_scene(tmp_path):
    """Four unit quads along x (slots red, green, image, emissive), an orthographic camera above, a sun 45 deg
    off the normal."""
    scene = bpy.context.scene
    render.cycles_cpu(scene, samples=1)
    scene.cycles.filter_width = 0.01
    scene.cycles.max_bounces = 0
    scene.render.resolution_x, scene.render.resolution_y = 84, 24
    scene.render.resolution_percentage = 100
    verts, faces = [], []
    for k in range(4):
        x0 = k - 2.0
        base = len(verts)
        verts += [(x0, -0.5, 0.0), (x0 + 1, -0.5, 0.0), (x0 + 1, 0.5, 0.0), (x0, 0.5, 0.0)]
        faces.append((base, base + 1, base + 2, base + 3))
    mesh = bpy.data.meshes.new("Strip")
    mesh.from_pydata(verts, [], faces)
    mesh.uv_layers.new(name="UVMap")
    obj = bpy.data.objects.new("Strip", mesh)
    sc.link(scene, obj)
    mats = [_principled("Red", RED)[0], _principled("Green", GREEN)[0], _textured(tmp_path),
            _principled("Lamp", BASE, EMISSION)[0]]
    for m in mats:
        mesh.materials.append(m)
    for k, poly in enumerate(mesh.polygons):
        poly.material_index = k
    sc.camera(scene, "Cam", (0, 0, 5), target=(0, 0, 0), ortho_scale=4.2)
    sc.world(scene, 0.0)
    sc.light(scene, "Sun", "SUN", SUN, rotation=sc.deg(45, 0, 0))
    scene.view_layers[0].use_pass_position = True
    return scene, obj, mats


def _region_means(scene):
    passes = render.render_layers(scene)
    x = passes["Position"][..., 0]
    hit = np.linalg.norm(passes["Position"], axis=-1) > 0   # geometry (the strip lies at z = 0, |y| <= 0.5)
    hit &= np.abs(passes["Position"][..., 1]) < 0.45
    rgb = passes["Combined"][..., :3].astype(float)
    out = []
    for k in range(4):
        sel = hit & (x > k - 2.0 + 0.1) & (x < k - 1.0 - 0.1)
        assert sel.sum() > 20, k
        out.append(rgb[sel].mean(axis=0))
    return np.array(out)


def _trees(mats):
    """A comparable description of each material's node tree: nodes, their input values, links."""
    out = []
    for m in mats:
        nodes = sorted((n.name, n.bl_idname, tuple((i.identifier, tuple(i.default_value) if hasattr(
            getattr(i, "default_value", 0), "__len__") else getattr(i, "default_value", None)) for i in n.inputs))
                       for n in m.node_tree.nodes)
        links = sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name, lk.to_socket.identifier)
                       for lk in m.node_tree.links)
        out.append((m.name, nodes, links))
    return out


@pytest.mark.parametrize("model", ["PHONG", "COOK_TORRANCE"])
def test_slots_keep_their_colours_textures_and_emission_and_restore_gives_the_originals_back(model, tmp_path):
    scene, obj, mats = _strip_scene(tmp_path)
    before = _trees(mats)
    mats_il, warnings = material.assign_materials(scene, [obj], model)
    assert len(mats_il) == 4 and [s.material for s in obj.material_slots] == mats_il
    assert all(m["il_original"] == o for m, o in zip(mats_il, mats))
    textured = mats_il[2].node_tree
    tex = next(n for n in textured.nodes if n.bl_idname == "ShaderNodeTexImage")
    assert tex.image.name == "Label" and tex.outputs["Color"].is_linked      # the texture node stays linked
    assert mats_il[3].cycles.emission_sampling != "NONE"                  # the emitter still lights other surfaces
    means = _region_means(scene)
    # expected: Lambert k_d I (n.l) (+ Phong's ambient k_a I_a) + emission; tolerance: the model's specular at
    # this geometry (the twin with k_d = 0 and the converted parameters) plus float32 rounding
    n, v = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]])
    sun = scene.objects["Sun"]
    direction = np.array(sun.matrix_world.to_3x3() @ Vector((0, 0, -1)))
    l, I = twin_lights.sun_light(n, direction, (1.0, 1.0, 1.0), SUN)
    n_l = float(np.dot(-direction, n[0]))
    for k, (base, emission) in enumerate(((RED, 0), (GREEN, 0), (IMAGE, 0), (BASE, 1))):
        params = material.read_parameters(mats_il[k])
        expected = np.array(base) * I[0] * n_l + (np.array(EMISSION) * STRENGTH if emission else 0.0)
        if model == "PHONG":
            expected = expected + params["Ka"] * np.array(params["Ambient Light"][:3])
            spec = brdf.phong(n, l, v, I, kd=(0, 0, 0), ks=params["Ks"], shininess=params["Shininess"],
                              normalized=params["Normalized"])
        else:
            spec = brdf.cook_torrance(n, l, v, I, kd=(0, 0, 0), ks=params["Ks"], F0=params["F0"],
                                      roughness=params["Roughness"])
        tol = float(np.max(spec)) + 1e-4 * float(np.max(expected))
        assert np.all(np.abs(means[k] - expected) <= tol), (k, means[k], expected, tol)
        assert float(np.max(spec)) < 0.01 * float(np.max(expected)), (k, "the tolerance stays tight")
    assert means[3].min() > STRENGTH * min(EMISSION) * 0.99                   # the emitter emits

    # Restore: the same materials per slot, node trees as they were, IL materials unused
    bpy.context.view_layer.objects.active = obj
    for o in scene.objects:
        o.select_set(o == obj)
    assert bpy.ops.illumination.remove_shading_model() == {"FINISHED"}
    assert [s.material for s in obj.material_slots] == mats and _trees(mats) == before
    assert all(m.users == 0 for m in mats_il)
    assert not bpy.ops.illumination.remove_shading_model.poll()
    assert "Nothing to restore" in _poll_message("remove_shading_model")


def _poll_message(op):
    try:
        getattr(bpy.ops.illumination, op)()
    except RuntimeError as e:
        return str(e)
    return ""


def test_restore_survives_save_and_reopen_and_shared_materials_give_one_il_material(tmp_path):
    scene, obj, mats = _strip_scene(tmp_path)
    other = bpy.data.objects.new("Other", bpy.data.meshes.new("Other"))
    other.data.from_pydata([(0, 0, -1), (1, 0, -1), (1, 1, -1)], [], [(0, 1, 2)])
    other.data.materials.append(mats[0])     # shares Red
    sc.link(scene, other)
    empty = bpy.data.objects.new("Bare", bpy.data.meshes.new("Bare"))
    empty.data.from_pydata([(0, 0, -2), (1, 0, -2), (1, 1, -2)], [], [(0, 1, 2)])
    sc.link(scene, empty)
    before = _trees(mats)
    for o in scene.objects:
        o.select_set(o.type == "MESH")
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.illumination.assign_shading_model(model="COOK_TORRANCE") == {"FINISHED"}
    assert other.material_slots[0].material == obj.material_slots[0].material
    assert len({m.name for m in bpy.data.materials if m.get("il_model")}) == 5    # 4 originals + the defaults
    assert len(empty.material_slots) == 1 and empty.material_slots[0].material.get("il_empty")
    # a second model replaces the first IL materials and still knows the originals
    assert bpy.ops.illumination.assign_shading_model(model="PHONG") == {"FINISHED"}
    assert len([m for m in bpy.data.materials if m.get("il_model")]) == 5
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    for o in bpy.context.scene.objects:
        o.select_set(o.type == "MESH")
    assert bpy.ops.illumination.remove_shading_model() == {"FINISHED"}
    strip, other, bare = (bpy.data.objects[n] for n in ("Strip", "Other", "Bare"))
    assert [s.material.name for s in strip.material_slots] == ["Red", "Green", "Label", "Lamp"]
    assert other.material_slots[0].material.name == "Red" and len(bare.material_slots) == 0
    restored = [bpy.data.materials[n] for n in ("Red", "Green", "Label", "Lamp")]
    assert _trees(restored) == before
    assert all(m.users == 0 for m in bpy.data.materials if m.get("il_model"))


def test_materials_without_a_principled_bsdf_get_their_colour_and_a_warning(tmp_path):
    scene = bpy.context.scene
    cube = sc.box(scene, "Cube", 1.0)
    diffuse = bpy.data.materials.new("Matte")
    compat.ensure_use_nodes(diffuse)
    nt = diffuse.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.3, 0.6, 0.2, 1.0)
    nt.links.new(d.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    glow = bpy.data.materials.new("Glow")
    compat.ensure_use_nodes(glow)
    nt = glow.node_tree
    nt.nodes.clear()
    e = nt.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (1.0, 0.2, 0.1, 1.0)
    e.inputs["Strength"].default_value = 5.0
    nt.links.new(e.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    bare = bpy.data.materials.new("Bare")
    bare.diffuse_color = (0.9, 0.1, 0.5, 1.0)
    if compat.uses_nodes(bare) and bare.node_tree is not None:
        bare.node_tree.nodes.clear()
    for m in (diffuse, glow, bare):
        cube.data.materials.append(m)
    mats, warnings = material.assign_materials(scene, [cube], "OREN_NAYAR")
    p = [material.read_parameters(m) for m in mats]
    assert p[0]["Albedo"][:3] == pytest.approx((0.3, 0.6, 0.2))
    assert p[1]["Albedo"][:3] == pytest.approx((0, 0, 0)) and p[1]["Emission Color"][:3] == pytest.approx((5, 1, .5))
    assert p[2]["Albedo"][:3] == pytest.approx((0.9, 0.1, 0.5), abs=1e-6)
    text = "\n".join(warnings)
    for words in ("'Matte'", "no specular", "'Glow'", "Emission only", "'Bare'", "viewport display colour"):
        assert words in text, (words, text)


def test_area_lights_are_lambertian_spots_matching_the_twin_and_say_so():
    """A scene lit only by an area light renders lit, with a warning naming it; on the axis the material gets
    I = (P/pi) / d^2 / pi (E = (P/pi) cos / d^2 (n.l)), the twin's area_light everywhere."""
    scene = bpy.context.scene
    render.cycles_cpu(scene, samples=1)
    scene.cycles.filter_width = 0.01
    scene.cycles.max_bounces = 0
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    floor = sc.plane(scene, "Floor", 4.0)
    sc.camera(scene, "Cam", (0, 0, 6), target=(0, 0, 0), ortho_scale=4.0)
    sc.world(scene, 0.0)
    P, height = 200.0, 2.0
    area = sc.light(scene, "Panel", "AREA", P, location=(0.4, 0.2, height), rotation=sc.deg(20, 0, 0))
    area.data.size = 0.2
    vl = scene.view_layers[0]
    vl.use_pass_position = vl.use_pass_normal = True
    for o in scene.objects:
        o.select_set(o == floor)
    mat, warnings = material.assign_shading_model(scene, [floor], "OREN_NAYAR", params={"Albedo": (1, 1, 1),
                                                                                        "Sigma": 0.0})
    assert mat["il_light_names"] == ["Panel"]
    assert any("Panel" in w and "Lambertian" in w for w in warnings)
    passes = render.render_layers(scene)
    hit = np.linalg.norm(passes["Normal"], axis=-1) > 0.5
    p, L = passes["Position"][hit].astype(float), passes["Combined"][..., :3][hit].astype(float)
    assert L.max() > 0.1
    position = np.array(area.matrix_world.translation)
    axis = np.array(area.matrix_world.to_3x3() @ Vector((0, 0, -1)))
    lv, I = twin_lights.area_light(p, position, axis, (1, 1, 1), P)
    ref = brdf.oren_nayar(np.broadcast_to([0, 0, 1.0], p.shape), lv, np.broadcast_to([0, 0, 1.0], p.shape), I,
                          (1, 1, 1), 0.0)
    assert np.max(np.abs(L - ref)) <= 1e-4 * np.max(ref)
    # the analytic value: radiance = I_light (n.l) with I_light = (P/pi) cos(theta) / (pi d^2)
    d = position - p
    dist = np.linalg.norm(d, axis=-1)
    cos_theta = np.maximum((-d / dist[:, None]) @ axis, 0.0)
    analytic = (P / math.pi) * cos_theta / dist ** 2 / math.pi * np.maximum(d[:, 2] / dist, 0.0)
    np.testing.assert_allclose(L[:, 0], analytic, rtol=1e-4, atol=1e-6 * analytic.max())
    # the operator's report: a warning, and a scene with the light switched off says it is black
    area.data.energy = 0.0
    _, warnings = material.assign_shading_model(scene, [floor], "PHONG")
    assert any("zero power" in w for w in warnings)


def test_source_reads_roughness_as_alpha_and_metal_as_f0():
    mat, bsdf = _principled("Metal", (0.9, 0.6, 0.2))
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.4
    params, sources = source.model_parameters("COOK_TORRANCE", source.read_surface(mat))
    assert not sources and params["Roughness"] == pytest.approx(0.16)
    assert params["F0"] == pytest.approx((0.9 + 0.6 + 0.2) / 3) and params["Kd"] == pytest.approx((0, 0, 0))
