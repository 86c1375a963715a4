"""Preview Light Maps shows base colour x E/pi (irradiance) or x k_A (AO) on the user's materials, measured in a
Cycles render against the EXR maps; Remove Preview gives every slot its material back, also after save and reopen;
objects without maps or without the light-map UV layer are named (issue 28, item 1)."""
import json
import math
import os

import bpy
import numpy as np
import pytest

from addon.bake import bake_lightmaps
from addon.bake.options import BakeOptions
from addon.blender import compat, render
from addon.blender import scene as sc
from addon.core.errors import InputError
from addon.core.io import exr
from addon.nodes import lightmap_preview as lp

PAINT, LABEL = (0.8, 0.4, 0.2), (0.2, 0.6, 0.9)
SIDE = 40            # render pixels over the 2 m plane


def _principled(name, base):
    mat = bpy.data.materials.new(name)
    compat.ensure_use_nodes(mat)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    return mat, bsdf


def _scene(tmp_path):
    """A 2 m plane (Principled colour) under a 0.5 m cube (image texture) and a sphere nobody baked, made with
    Blender's operators, under a white sky of radiance 1."""
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(0.0, 0.0, 0.25))
    cube = bpy.context.active_object
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.2, location=(3.0, 0.0, 0.2), segments=8, ring_count=4)
    sphere = bpy.context.active_object
    paint, _ = _principled("Paint", PAINT)
    plane.data.materials.append(paint)
    label, bsdf = _principled("Label", (1.0, 1.0, 1.0))
    image = bpy.data.images.new("Label", 4, 4, float_buffer=True, is_data=True)
    image.pixels[:] = [*LABEL, 1.0] * 16
    image.filepath_raw = str(tmp_path / "label.exr")
    image.file_format = "OPEN_EXR"
    image.save()
    tex = label.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    label.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    cube.data.materials.append(label)
    cube.material_slots[0].link = "OBJECT"          # an object-linked slot (its data slot stays empty)
    cube.material_slots[0].material = label
    sphere.data.materials.append(paint)
    sc.world(scene, strength=1.0)
    return scene, plane, cube, sphere


def _trees(mats):
    """Nodes with their input values, and links, of each material (as tests/nodes/test_shading_materials.py)."""
    out = []
    for m in mats:
        nodes = sorted((n.name, n.bl_idname, tuple((i.identifier, tuple(i.default_value) if hasattr(
            getattr(i, "default_value", 0), "__len__") else getattr(i, "default_value", None)) for i in n.inputs))
                       for n in m.node_tree.nodes)
        links = sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name, lk.to_socket.identifier)
                       for lk in m.node_tree.links)
        out.append((m.name, nodes, links))
    return out


def _slots(objects):
    return [(o.name, [(s.link, s.material.name if s.material else None) for s in o.material_slots],
             [m.name if m else None for m in o.data.materials]) for o in objects]


def _select(scene, objects):
    for o in scene.objects:
        o.select_set(o in objects)
    bpy.context.view_layer.objects.active = objects[0]


def _bilinear(img, u, v):
    """Blender's Linear lookup (texel centres at (i + 1/2)/w, edges extended); ``img`` row 0 at v = 0."""
    h, w = img.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    xs0, xs1 = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
    ys0, ys1 = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    a = img.reshape(h, w, -1)
    return ((1 - fy) * ((1 - fx) * a[ys0, xs0] + fx * a[ys0, xs1]) + fy * ((1 - fx) * a[ys1, xs0] + fx * a[ys1, xs1]))


def _uv_at(obj, layer, points):
    """Light-map UVs of ``obj`` at world points (x, y) seen from above (its triangles facing +z)."""
    me = obj.data
    me.calc_loop_triangles()
    mw = obj.matrix_world
    uvs = np.full((len(points), 2), np.nan)
    for tri in me.loop_triangles:
        normal = mw.to_3x3() @ tri.normal
        if normal.z < 0.9:
            continue
        p = np.array([(mw @ me.vertices[v].co)[:2] for v in tri.vertices])
        t = np.array([me.uv_layers[layer].uv[lo].vector[:] for lo in tri.loops])
        m = np.array([p[1] - p[0], p[2] - p[0]]).T
        b = np.linalg.solve(m, (points - p[0]).T).T
        w = np.column_stack([1 - b.sum(1), b])
        inside = np.all(w >= -1e-9, axis=1)
        uvs[inside] = w[inside] @ t
    return uvs


def _render_errors(scene, objects, report, kind, bases, scale, engine="CYCLES"):
    """|render - base x map x scale| / the largest expected value at each pixel centre over the objects' upward
    faces (away from the cube's edges), and the median of render / expected. World black, no lights: only the
    preview's emission is seen; one sample through each pixel's centre (filter 0.01 px)."""
    world = scene.world.node_tree.nodes["Background"]
    world.inputs["Strength"].default_value = 0.0
    if engine == "CYCLES":
        render.cycles_cpu(scene, samples=1, pixel_filter=0.01)
    else:
        render.eevee(scene, 1, 0.01)
    scene.render.resolution_x = scene.render.resolution_y = SIDE
    scene.render.resolution_percentage = 100
    if scene.camera is None:
        sc.camera(scene, "Camera", (0.0, 0.0, 5.0), ortho_scale=2.0)
    rgb = render.render_layers(scene)["Combined"][..., :3].astype(float)
    centres = (np.arange(SIDE) + 0.5) / SIDE * 2.0 - 1.0
    xs, ys = np.meshgrid(centres, -centres)             # row 0 at the top (+y)
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    half = 0.25
    on_cube = np.all(np.abs(pts) < half - 0.06, axis=1)
    on_plane = np.any(np.abs(pts) > half + 0.06, axis=1) & np.all(np.abs(pts) < 0.97, axis=1)
    got, expected = [], []
    for obj, sel in ((objects[0], on_plane), (objects[1], on_cube)):
        entry = report[obj.name][kind]
        channels, _ = exr.read_exr(entry["file"])
        img = np.stack([channels[c] for c in ("R", "G", "B")], -1) if "R" in channels else channels["Y"][..., None]
        img = np.flipud(img)                             # the file's first row is the top (v = 1)
        uv = _uv_at(obj, entry["uv_layer"], pts[sel])
        assert not np.isnan(uv).any()
        expected.append(np.array(bases[obj.name]) * _bilinear(img, uv[:, 0], uv[:, 1]) * scale)
        got.append(rgb.reshape(-1, 3)[sel])
    got, expected = np.concatenate(got), np.concatenate(expected)
    assert expected.max() > 0.05 and expected.min() < 0.8 * expected.max()       # lit, with contact shadows
    return np.abs(got - expected).max(axis=1) / expected.max(), float(np.median(got / expected))


def _baked(tmp_path):
    scene, plane, cube, sphere = _scene(tmp_path)
    out = str(tmp_path / "maps")
    result = bake_lightmaps([plane, cube], ["ao", "irradiance"], out,
                            BakeOptions(resolution=32, samples=8, bounces=1, margin=2), scene=scene)
    return scene, plane, cube, sphere, out, dict(result["objects"])


@pytest.mark.both_versions
def test_preview_shows_base_colour_times_the_maps_and_remove_gives_everything_back(tmp_path):
    scene, plane, cube, sphere, out, report = _baked(tmp_path)
    originals = [bpy.data.materials["Paint"], bpy.data.materials["Label"]]
    before, slots = _trees(originals), _slots([plane, cube, sphere])
    scene.illumination.lightmaps.output_dir = out + os.sep

    # the sphere has no maps, the camera is no mesh: both named, the baked meshes previewed
    sc.camera(scene, "Camera", (0.0, 0.0, 5.0), ortho_scale=2.0)
    _select(scene, [plane, cube, sphere, scene.camera])
    shown, warnings = lp.apply_lightmaps(bpy.context.selected_objects, out, "IRRADIANCE")
    assert set(shown["objects"]) == {plane.name, cube.name}
    assert any("Camera" in w and "not a mesh" in w for w in warnings), warnings
    assert any("Sphere" in w and "no irradiance map" in w for w in warnings), warnings
    assert sphere.material_slots[0].material.name == "Paint"
    mat = cube.material_slots[0].material
    assert mat[lp.TAG] == "irradiance" and mat["il_lightmap_original"] == originals[1]
    emit = mat.node_tree.nodes["IL light-map radiance"]
    assert emit.inputs["Strength"].default_value == pytest.approx(1 / math.pi)
    times = mat.node_tree.nodes["IL base x map"]
    assert times.inputs[0].links[0].from_node.bl_idname == "ShaderNodeTexImage"      # the label's texture
    assert plane.data.materials[0].name == "Paint"      # the mesh's own slots are not touched
    # tolerance: float32 rounding (1e-6) plus the pixel filter's 0.005 px offset times the steepest change of the
    # maps (under 40 % of the largest value per pixel): 2e-3; measured 1.1e-6 (1.3e-6 on 4.5, 1.4e-6 on 5.2)
    err, _ = _render_errors(scene, [plane, cube], report, "irradiance", {plane.name: PAINT, cube.name: LABEL},
                            1 / math.pi)
    print(f"irradiance preview: {len(err)} pixels, max error {err.max():.2e} of the largest radiance")
    assert err.max() < 2e-3, err.max()

    # AO through the operator replaces the irradiance preview (no stale preview materials left)
    _select(scene, [plane, cube])
    assert bpy.ops.illumination.apply_lightmaps(source="AO") == {"FINISHED"}
    assert len([m for m in bpy.data.materials if m.get(lp.TAG)]) == 2
    assert plane.material_slots[0].material[lp.TAG] == "ao"
    err, _ = _render_errors(scene, [plane, cube], report, "ao", {plane.name: PAINT, cube.name: LABEL}, 1.0)
    print(f"AO preview: {len(err)} pixels, max error {err.max():.2e} of the largest radiance")
    assert err.max() < 2e-3, err.max()         # the one-channel ("Y") AO map is read as grey

    # save, reopen, remove: every slot and node tree as before
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    objs = [scene.objects[n] for n in ("Plane", "Cube", "Sphere")]
    _select(scene, objs)
    assert bpy.ops.illumination.remove_lightmaps() == {"FINISHED"}
    assert _slots(objs) == slots
    assert _trees([bpy.data.materials["Paint"], bpy.data.materials["Label"]]) == before
    assert all(m.users == 0 for m in bpy.data.materials if m.get(lp.TAG))      # dropped at the next save
    assert not bpy.ops.illumination.remove_lightmaps.poll()


@pytest.mark.eevee
def test_eevee_shows_the_same_radiance(tmp_path):
    """EEVEE (software GL here: 4-12 s) against the maps: the scale is exact (median ratio), the texel values
    are filtered by the GPU (mipmapped, half-float film), measured median 0.7 %, max 7.6 % of the largest value
    at the steepest gradient (the cube's contact shadow)."""
    scene, plane, cube, _, out, report = _baked(tmp_path)
    lp.apply_lightmaps([plane, cube], out, "IRRADIANCE")
    err, ratio = _render_errors(scene, [plane, cube], report, "irradiance", {plane.name: PAINT, cube.name: LABEL},
                                1 / math.pi, engine="EEVEE")
    print(f"EEVEE irradiance preview: median ratio {ratio:.4f}, error median {np.median(err):.2e}, "
          f"max {err.max():.2e}")
    assert ratio == pytest.approx(1.0, abs=0.01)
    assert np.median(err) < 0.02 and err.max() < 0.15


def _fake_report(folder, entries):
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "bake_report.json"), "w", encoding="utf-8") as f:
        json.dump({"objects": entries, "seconds": 0.0}, f)


@pytest.mark.both_versions
def test_missing_report_layer_or_maps_are_named_and_nothing_changes(tmp_path):
    scene, plane, cube, sphere = _scene(tmp_path)
    before = _slots([plane, cube, sphere])
    folder = str(tmp_path / "maps")
    with pytest.raises(InputError, match="no bake_report.json"):
        lp.apply_lightmaps([plane], folder)
    ao = os.path.join(folder, "Plane_ao.exr")
    _fake_report(folder, {"Plane": {"ao": {"file": ao, "uv_layer": "Lightmap"}},
                          "Cube": {"ao": {"file": os.path.join(folder, "Cube_ao.exr"), "uv_layer": "UVMap"}}})
    exr.write_exr(ao, {"Y": np.full((4, 4), 0.5, np.float32)})
    with pytest.raises(InputError, match="no UV layer 'Lightmap'") as e:      # a batch bake: no layer in this file
        lp.apply_lightmaps([plane, cube, sphere], folder, "AO")
    assert "'Cube'" in str(e.value) and "is missing" in str(e.value)
    assert _slots([plane, cube, sphere]) == before
    plane.data.uv_layers.new(name="Lightmap")
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(5.0, 0.0, 0.0))
    bare = bpy.context.active_object                 # no material slot: one is added, then taken away
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(7.0, 0.0, 0.0))
    dots = bpy.context.active_object                 # a vertex-target map: its colour attribute
    dots.data.color_attributes.new("IL AO", "FLOAT_COLOR", "POINT")
    dots.data.materials.append(bpy.data.materials["Paint"])
    _fake_report(folder, {"Plane": {"ao": {"file": ao, "uv_layer": "Lightmap"}},
                          "Cube": {"ao": {"file": os.path.join(folder, "Cube_ao.exr"), "uv_layer": "UVMap"}},
                          bare.name: {"ao": {"file": ao, "uv_layer": "UVMap"}},
                          dots.name: {"ao": {"file": ao, "attribute": "IL AO"}}})
    everything = [plane, cube, sphere, bare, dots]
    before = _slots(everything)
    shown, warnings = lp.apply_lightmaps(everything, folder, "AO")
    assert list(shown["objects"]) == ["Plane", bare.name, dots.name]
    assert any("Sphere" in w for w in warnings) and any("Cube" in w and "missing" in w for w in warnings)
    assert len(bare.material_slots) == 1
    assert dots.material_slots[0].material.node_tree.nodes["IL light map (ao)"].layer_name == "IL AO"
    images = [im for im in bpy.data.images if im.get(lp.TAG)]
    assert len(images) == 1 and images[0].colorspace_settings.name == "Non-Color"     # one image per file
    scene.illumination.lightmaps.output_dir = folder
    _select(scene, [cube])
    assert not bpy.ops.illumination.remove_lightmaps.poll()
    _select(scene, everything)
    assert bpy.ops.illumination.remove_lightmaps() == {"FINISHED"}
    assert _slots(everything) == before and len(bare.material_slots) == 0


@pytest.mark.both_versions
def test_a_failure_halfway_gives_the_done_objects_back(tmp_path, monkeypatch):
    scene, plane, cube, sphere = _scene(tmp_path)
    folder = str(tmp_path / "maps")
    ao = os.path.join(folder, "ao.exr")
    _fake_report(folder, {"Plane": {"ao": {"file": ao, "uv_layer": "UVMap"}},
                          "Cube": {"ao": {"file": ao, "uv_layer": "UVMap"}}})
    exr.write_exr(ao, {"Y": np.full((4, 4), 0.5, np.float32)})
    before, trees = _slots([plane, cube]), _trees([bpy.data.materials["Paint"], bpy.data.materials["Label"]])
    build, calls = lp.build_preview, []

    def failing(*args):
        calls.append(args)
        if len(calls) == 2:
            raise InputError("disk on fire")
        return build(*args)
    monkeypatch.setattr(lp, "build_preview", failing)
    with pytest.raises(InputError, match="disk on fire"):
        lp.apply_lightmaps([plane, cube], folder, "AO")
    assert len(calls) == 2 and _slots([plane, cube]) == before
    assert _trees([bpy.data.materials["Paint"], bpy.data.materials["Label"]]) == trees
    assert not [m for m in bpy.data.materials if m.get(lp.TAG)]


def test_layers_are_made_from_the_users_material_and_come_off_top_down(tmp_path):
    """The preview shows the user's base colour x the map also over environment mapping (it read the environment
    material's, black); a shading model over the preview or environment mapping is made from the user's material
    (Kd its base colour: it was made from the layer, Kd 0, with the layer's tags, so that layer's Remove took it) and
    replaces the layer; Remove Shading Model under another layer says to remove that one first; the Removes, top
    down, give each slot its material and link back, and a mesh without slots none (the mark of the slot the
    shading model added was dropped by a Remove that found it under environment mapping)."""
    from addon.lab import envmap as lab_envmap
    from addon.nodes import environment, material
    from addon.ui import shading as shading_ui
    scene, plane, cube, _ = _scene(tmp_path)
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=16, samples=1, bounces=1))
    sky = bpy.data.images.new("sky", 8, 4, float_buffer=True)
    sky.pixels.foreach_set(np.full(8 * 4 * 4, 0.5, np.float32))
    lab_envmap.set_world_environment(scene, sky, strength=1.0)
    before = [(s.link, s.material) for o in (plane, cube) for s in o.material_slots]

    environment.assign_environment_mapping(scene, [plane])
    lp.apply_lightmaps([plane], str(out), "IRRADIANCE")
    base = plane.material_slots[0].material.node_tree.nodes["IL base x map"].inputs[0]
    assert not base.is_linked and tuple(base.default_value) == pytest.approx(PAINT)

    material.assign_shading_model(scene, [plane, cube], "PHONG")
    for obj, colour in ((plane, PAINT), (cube, (1.0, 1.0, 1.0))):
        phong = obj.material_slots[0].material
        assert tuple(material.read_parameters(phong)["Kd"][:3]) == pytest.approx(colour), obj.name
        assert not lp.is_preview(phong) and phong.get("il_envmap") is None
    assert [(s.link, s.material.name) for s in cube.material_slots] == [("OBJECT", "IL Phong: Label")]
    assert not lp.previewed([plane]) and not environment.restorable([plane])
    material.restore_materials([plane, cube])
    assert [(s.link, s.material) for o in (plane, cube) for s in o.material_slots] == before

    material.assign_shading_model(scene, [plane], "PHONG")
    environment.assign_environment_mapping(scene, [plane])
    said = []
    poll = type("Poll", (), {"poll_message_set": staticmethod(said.append)})
    with bpy.context.temp_override(selected_objects=[plane]):
        assert not shading_ui._restorable(poll, bpy.context)
    assert said == ["The shading model is under the environment mapping: remove that first"]
    environment.remove_environment_mapping([plane])
    material.restore_materials([plane])
    assert [(s.link, s.material) for o in (plane, cube) for s in o.material_slots] == before
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1, location=(0.0, 3.0, 0.5))
    ico = bpy.context.active_object                  # no slots: the shading model adds one, and takes it back
    material.assign_shading_model(scene, [plane, ico], "PHONG")
    environment.assign_environment_mapping(scene, [ico])
    material.restore_materials([plane, ico])         # the plane's Phong; the ico's is under environment mapping
    environment.remove_environment_mapping([ico])
    material.restore_materials([ico])
    assert len(ico.material_slots) == 0 and [(s.link, s.material) for s in plane.material_slots] == before[:1]


def test_a_shading_model_that_fails_midway_leaves_the_preview_and_the_slots_as_they_were(tmp_path, monkeypatch):
    """The preview shown on a plane and a cube (object-linked slot); building the shading model's material fails on
    the second material: the preview is still shown (it was taken off before the first material was made, and not
    put back), the slots and links are those of before, and no material of the failed call is left."""
    from addon.nodes import material
    scene, plane, cube, _ = _scene(tmp_path)
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=16, samples=1, bounces=1))
    lp.apply_lightmaps([plane, cube], str(out), "IRRADIANCE")
    shown = [(s.link, s.material) for o in (plane, cube) for s in o.material_slots]
    data = [list(o.data.materials) for o in (plane, cube)]
    names = {m.name for m in bpy.data.materials}
    real, calls = material._convert, []

    def failing(orig, *args):
        calls.append(orig)
        if len(calls) == 2:
            raise RuntimeError("node building failed")
        return real(orig, *args)

    monkeypatch.setattr(material, "_convert", failing)
    with pytest.raises(RuntimeError, match="node building failed"):
        material.assign_shading_model(scene, [plane, cube], "PHONG")
    assert len(calls) == 2 and lp.previewed([plane]) and lp.previewed([cube])
    assert [(s.link, s.material) for o in (plane, cube) for s in o.material_slots] == shown
    assert [list(o.data.materials) for o in (plane, cube)] == data
    assert {m.name for m in bpy.data.materials} == names


def test_environment_mapping_that_fails_midway_leaves_the_preview_and_the_slots_as_they_were(tmp_path, monkeypatch):
    """As for a shading model: the preview on a plane and a cube, environment mapping whose second material fails to
    build: the preview is still shown, the slots and links are those of before, no material of the call is left."""
    from addon.lab import envmap as lab_envmap
    from addon.nodes import environment
    scene, plane, cube, _ = _scene(tmp_path)
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=16, samples=1, bounces=1))
    sky = bpy.data.images.new("sky", 8, 4, float_buffer=True)
    lab_envmap.set_world_environment(scene, sky, strength=1.0)
    lp.apply_lightmaps([plane, cube], str(out), "IRRADIANCE")
    shown = [(s.link, s.material) for o in (plane, cube) for s in o.material_slots]
    names = {m.name for m in bpy.data.materials}
    real, calls = environment.build_material, []

    def failing(mat, *args):
        calls.append(mat.name)
        if len(calls) == 2:
            raise RuntimeError("node building failed")
        return real(mat, *args)

    monkeypatch.setattr(environment, "build_material", failing)
    with pytest.raises(RuntimeError, match="node building failed"):
        environment.assign_environment_mapping(scene, [plane, cube])
    assert len(calls) == 2 and lp.previewed([plane]) and lp.previewed([cube])
    assert [(s.link, s.material) for o in (plane, cube) for s in o.material_slots] == shown
    assert {m.name for m in bpy.data.materials} == names
    monkeypatch.setattr(environment, "build_material", real)
    environment.assign_environment_mapping(scene, [plane, cube])       # then it takes the preview off, as before
    assert not lp.previewed([plane, cube]) and environment.restorable([plane, cube])
    environment.remove_environment_mapping([plane, cube])
    assert [s.material.name for o in (plane, cube) for s in o.material_slots] == ["Paint", "Label"]


@pytest.mark.both_versions
def test_a_batch_bakes_folder_is_previewed_through_the_layout_its_maps_were_baked_on(tmp_path):
    """A batch bake leaves the opened file without its generated 'Lightmap' layer (bake.py saves no .blend; here
    the layer is taken off after the bake): Preview adds it from the bake folder's UV cache, UV for UV the layer
    the bake used, shows base colour x map as after an in-file bake, and Remove Preview takes it away again. A
    mesh edited since the bake is refused with its line, nothing added."""
    import bmesh
    scene, plane, cube, sphere = _scene(tmp_path)
    out = str(tmp_path / "maps")
    report = dict(bake_lightmaps([plane, cube], ["irradiance"], out, BakeOptions(resolution=32, samples=8, bounces=1,
                                                                                 margin=2), scene=scene)["objects"])
    baked = {}
    for o in (plane, cube):
        baked[o.name] = np.zeros(2 * len(o.data.loops), np.float32)
        o.data.uv_layers["Lightmap"].data.foreach_get("uv", baked[o.name])
        o.data.uv_layers.remove(o.data.uv_layers["Lightmap"])
    layers, slots = {o.name: [la.name for la in o.data.uv_layers] for o in (plane, cube)}, _slots([plane, cube])

    shown, warnings = lp.apply_lightmaps([plane, cube], out, "IRRADIANCE")
    assert warnings == [] and all(shown["objects"][o.name]["uv_from_cache"] for o in (plane, cube))
    for o in (plane, cube):
        uv = np.zeros(2 * len(o.data.loops), np.float32)
        o.data.uv_layers["Lightmap"].data.foreach_get("uv", uv)
        assert np.array_equal(uv, baked[o.name]) and o.data[lp.ADDED_UV] == "Lightmap"
    err, _ = _render_errors(scene, [plane, cube], report, "irradiance", {plane.name: PAINT, cube.name: LABEL},
                            1 / math.pi)
    assert err.max() < 2e-3, err.max()          # the tolerance of the in-file preview's test above
    assert lp.remove_lightmaps([plane, cube]) == 2
    assert {o.name: [la.name for la in o.data.uv_layers] for o in (plane, cube)} == layers
    assert _slots([plane, cube]) == slots and not any(lp.ADDED_UV in o.data for o in (plane, cube))

    bm = bmesh.new()
    bm.from_mesh(cube.data)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:1], cuts=1)
    bm.to_mesh(cube.data)
    bm.free()
    with pytest.raises(InputError, match="no UV layer 'Lightmap'.*nor its layout"):
        lp.apply_lightmaps([cube], out, "IRRADIANCE")
    assert [la.name for la in cube.data.uv_layers] == layers[cube.name] and _slots([cube]) == slots[-1:]


def test_a_previewed_layer_follows_the_bake_shown_and_a_bake_that_keeps_it_makes_it_its_own(tmp_path):
    """Two batch bakes (32² and 16²: other layouts): previewing the second after the first rewrites the layer the
    first preview added with the second's layout (it showed the second's maps through the first's layout); a bake
    in the file while a preview shows keeps the layer as its own, so Remove Preview leaves it (it removed it)."""
    scene, plane, cube, sphere = _scene(tmp_path)
    layouts = {}
    for name, side in (("a", 32), ("b", 16)):
        bake_lightmaps([plane, cube], ["ao"], str(tmp_path / name), BakeOptions(resolution=side, samples=2,
                                                                                   margin=2), scene=scene)
        layouts[name] = {}
        for o in (plane, cube):
            layouts[name][o.name] = np.zeros(2 * len(o.data.loops), np.float32)
            o.data.uv_layers["Lightmap"].data.foreach_get("uv", layouts[name][o.name])
            o.data.uv_layers.remove(o.data.uv_layers["Lightmap"])
    assert not np.array_equal(layouts["a"]["Cube"], layouts["b"]["Cube"])
    for name in ("a", "b", "a"):
        shown, warnings = lp.apply_lightmaps([plane, cube], str(tmp_path / name), "AO")
        assert warnings == []
        for o in (plane, cube):
            uv = np.zeros(2 * len(o.data.loops), np.float32)
            o.data.uv_layers["Lightmap"].data.foreach_get("uv", uv)
            assert np.array_equal(uv, layouts[name][o.name]), (name, o.name)
    bake_lightmaps([cube], ["ao"], str(tmp_path / "c"), BakeOptions(resolution=32, samples=2, margin=2), scene=scene)
    assert lp.ADDED_UV not in cube.data and lp.ADDED_UV in plane.data
    lp.remove_lightmaps([plane, cube])
    assert "Lightmap" in cube.data.uv_layers and "Lightmap" not in plane.data.uv_layers
