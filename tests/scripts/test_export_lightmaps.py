"""scripts/export_lightmaps.py: Blender's glTF exporter writes the baked maps (issue 28, item 2). The .glb is read
back with json/struct: TEXCOORD_1 in [0, 1] on the baked meshes, MOZ_lightmap {"index", "texCoord": 1,
"intensity"}, and decoded texel / 255 x intensity equal to the EXR's E within the stated encoding error (half an
8-bit step); occlusionTexture on texCoord 1 only where no irradiance is exported or with --ao-with-irradiance; the
.blend's bytes are unchanged; bad input exits 2 with one line."""
import json
import os
import struct

import bpy
import numpy as np
import pytest

from addon.bake import bake_lightmaps
from addon.bake.gltf import EXTENSION, encoding_error
from addon.bake.options import BakeOptions
from addon.blender import compat
from addon.blender import scene as sc
from addon.core.io import exr
from addon.core.io.png import decode_png

pytestmark = pytest.mark.both_versions


def _read_glb(path):
    data = open(path, "rb").read()
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert magic == b"glTF" and version == 2 and length == len(data)
    n, kind = struct.unpack("<I4s", data[12:20])
    assert kind == b"JSON"
    gltf = json.loads(data[20:20 + n])
    m, kind = struct.unpack("<I4s", data[20 + n:28 + n])
    assert kind == b"BIN\x00"
    return gltf, data[28 + n:28 + n + m]


def _accessor(gltf, binary, index):
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    assert acc["componentType"] == 5126 and acc["type"] == "VEC2"
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    stride = view.get("byteStride", 8)
    raw = np.frombuffer(binary, np.uint8, count=stride * (acc["count"] - 1) + 8, offset=start)
    return np.stack([raw[i * stride:i * stride + 8].view(np.float32) for i in range(acc["count"])])


def _image(gltf, binary, texture):
    img = gltf["images"][gltf["textures"][texture]["source"]]
    view = gltf["bufferViews"][img["bufferView"]]
    assert img["mimeType"] == "image/png"
    start = view.get("byteOffset", 0)
    return decode_png(binary[start:start + view["byteLength"]])


def _same_uvs(uv1, obj, layer):
    """The glTF's TEXCOORD_1 rows are the object's light-map layer (glTF v = 1 - Blender v), as sets."""
    uv = np.array([d.uv[:] for d in obj.data.uv_layers[layer].data])
    want = {(round(u, 5), round(1.0 - v, 5)) for u, v in uv}
    return {(round(float(u), 5), round(float(v), 5)) for u, v in uv1} == want


def _scene():
    """A 2 m plane (Principled colour) under a 0.5 m cube (sharing the material) made with Blender's operators,
    under a white sky."""
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(0.0, 0.0, 0.25))
    cube = bpy.context.active_object
    mat = bpy.data.materials.new("Paint")
    compat.ensure_use_nodes(mat)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.4, 0.2, 1.0)
    plane.data.materials.append(mat)
    cube.data.materials.append(mat)
    sc.world(scene, strength=1.0)
    return scene, plane, cube


@pytest.fixture
def baked(tmp_path):
    """AO and irradiance of :func:`_scene` baked at 16², saved as a copy with the generated layers."""
    scene, plane, cube = _scene()
    out = tmp_path / "maps"
    result = bake_lightmaps([plane, cube], ["ao", "irradiance"], str(out),
                            BakeOptions(resolution=16, samples=4, bounces=1, margin=2), scene=scene)
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True, compress=False)
    return blend, out, result["objects"]


def test_glb_carries_the_maps(baked, tmp_path, script):
    blend, out, report = baked
    before = blend.read_bytes()
    glb = tmp_path / "export" / "scene.glb"
    glb.parent.mkdir()
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", glb)
    assert r.returncode == 0, r.stderr
    assert ", ao" not in r.stdout                     # irradiance holds the occlusion: no occlusionTexture
    assert all("occlusionTexture" not in m for m in _read_glb(glb)[0]["materials"])
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", glb, "--ao-with-irradiance")
    assert r.returncode == 0, r.stderr
    assert r.stdout.count(", ao") == 2
    assert blend.read_bytes() == before
    assert sorted(os.listdir(glb.parent)) == ["scene.glb"]
    gltf, binary = _read_glb(glb)
    assert EXTENSION in gltf["extensionsUsed"] and EXTENSION not in gltf.get("extensionsRequired", [])
    nodes = {n["name"]: n for n in gltf["nodes"]}
    for name in ("Plane", "Cube"):
        mesh = gltf["meshes"][nodes[name]["mesh"]]
        assert mesh["name"] == bpy.data.objects[name].data.name          # the original mesh's, not the copy's
        e_exr = report[name]["irradiance"]
        chans, _ = exr.read_exr(e_exr["file"])
        E = np.stack([chans[c] for c in "RGB"], axis=-1)
        k, _ = exr.read_exr(report[name]["ao"]["file"])
        for prim in mesh["primitives"]:
            uv1 = _accessor(gltf, binary, prim["attributes"]["TEXCOORD_1"])
            assert uv1.min() >= 0.0 and uv1.max() <= 1.0
            assert _same_uvs(uv1, bpy.data.objects[name], e_exr["uv_layer"])
            mat = gltf["materials"][prim["material"]]
            assert mat["name"] == "Paint"
            occ = mat["occlusionTexture"]
            assert occ["texCoord"] == 1
            ao = _image(gltf, binary, occ["index"])
            assert np.abs(ao[..., 0] / 255.0 - k["Y"]).max() <= 0.5 / 255 + 1e-6
            moz = mat["extensions"][EXTENSION]
            assert moz["texCoord"] == 1 and moz["intensity"] == pytest.approx(float(E.max()), rel=1e-6)
            img = _image(gltf, binary, moz["index"])
            assert img.shape == E.shape
            decoded = img / 255.0 * moz["intensity"]
            rng = np.random.default_rng(0)
            rows, cols = rng.integers(0, E.shape[0], 64), rng.integers(0, E.shape[1], 64)
            err = np.abs(decoded[rows, cols] - E[rows, cols]).max()
            assert err <= encoding_error(moz["intensity"]) * (1 + 1e-5), err
    # the plane's and the cube's maps are different images on different materials
    mats = {gltf["meshes"][nodes[n]["mesh"]]["primitives"][0]["material"] for n in ("Plane", "Cube")}
    assert len(mats) == 2


def test_atlas_parts(tmp_path, script):
    """A shared atlas: both materials point at the one image, each mesh carries its own part's UVs."""
    scene, plane, cube = _scene()
    out = tmp_path / "maps"
    report = bake_lightmaps([plane, cube], ["irradiance"], str(out),
                            BakeOptions(resolution=16, samples=4, bounces=1, margin=1, atlas=True),
                            scene=scene)["objects"]
    blend, glb = tmp_path / "atlas.blend", tmp_path / "atlas.glb"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True, compress=False)
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", glb)
    assert r.returncode == 0, r.stderr
    gltf, binary = _read_glb(glb)
    nodes = {n["name"]: n for n in gltf["nodes"]}
    textures = set()
    for obj in (plane, cube):
        prim = gltf["meshes"][nodes[obj.name]["mesh"]]["primitives"][0]
        textures.add(gltf["materials"][prim["material"]]["extensions"][EXTENSION]["index"])
        uv1 = _accessor(gltf, binary, prim["attributes"]["TEXCOORD_1"])
        assert _same_uvs(uv1, obj, report[obj.name]["irradiance"]["uv_layer"])
    assert len(textures) == 1 and len(gltf["images"]) == 1


def test_session_left_as_it_was(baked, tmp_path):
    """In a session (the panel's case): the add-on entry of the hooks, the mesh and material copies are gone after
    the export, the objects have their meshes, slots and UV layers back."""
    from addon.bake.gltf import export_glb
    _, out, _ = baked
    scene = bpy.context.scene

    def state():
        return (sorted(bpy.context.preferences.addons.keys()), sorted(m.name for m in bpy.data.meshes),
                sorted(m.name for m in bpy.data.materials),
                [(o.name, o.data.name, [s.material.name if s.material else None for s in o.material_slots],
                  [lay.name for lay in o.data.uv_layers], o.data.uv_layers.active.name) for o in scene.objects
                 if o.type == "MESH"])

    before = state()
    result = export_glb(scene, str(out), str(tmp_path / "session.glb"))
    assert sorted(result["objects"]) == ["Cube", "Plane"] and not result["notes"]
    assert state() == before
    import sys
    assert not hasattr(sys.modules["addon.bake.gltf"], "glTF2ExportUserExtension")


def test_ao_alone_is_the_occlusion_texture(baked, tmp_path):
    """A report with AO and no irradiance: occlusionTexture on texCoord 1 by default, no MOZ_lightmap."""
    from addon.bake.gltf import export_glb
    _, out, _ = baked
    path = out / "bake_report.json"
    report = json.loads(path.read_text())
    report["objects"] = {name: {"ao": maps["ao"]} for name, maps in report["objects"].items()}
    path.write_text(json.dumps(report))
    result = export_glb(bpy.context.scene, str(out), str(tmp_path / "ao.glb"))
    assert result["objects"] == {"Cube": {"ao": 1.0}, "Plane": {"ao": 1.0}}
    gltf, _ = _read_glb(tmp_path / "ao.glb")
    assert len(gltf["materials"]) == 2
    for mat in gltf["materials"]:
        assert mat["occlusionTexture"]["texCoord"] == 1 and EXTENSION not in mat.get("extensions", {})


def test_bad_input_exits_2(baked, tmp_path, script):
    blend, _, _ = baked
    empty = tmp_path / "empty"
    empty.mkdir()
    r = script("export_lightmaps.py", blend, "--lightmaps", empty, "--out", tmp_path / "x.glb")
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "bake_report.json" in r.stderr
    assert not (tmp_path / "x.glb").exists()


def _poke(path, value, scale=1.0):
    """Rewrite map file ``path`` with every value times ``scale`` and texel (0, 0) set to ``value`` (None: kept)."""
    ch, header = exr.read_exr(path)
    ch = {k: v * scale if k != "A" else v for k, v in ch.items()}
    if value is not None:
        for k in "RGB":
            ch[k][0, 0] = value
    _write_raw(path, ch)          # exr.write_exr refuses values that are not finite


def _write_raw(path, channels):
    import OpenEXR
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}) as f:
        f.write(str(path))


def test_a_copied_folder_exports_its_own_maps(baked, tmp_path, script):
    """The report of a copied bake folder still names the original's files: the export reads the maps of the folder
    it is given (the copy's, here twice as bright), never files elsewhere."""
    import shutil
    blend, out, report = baked
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    _poke(copy / os.path.basename(report["Cube"]["irradiance"]["file"]), None, scale=2.0)
    chans, _ = exr.read_exr(report["Cube"]["irradiance"]["file"])
    peak = max(float(chans[c].max()) for c in "RGB")
    r = script("export_lightmaps.py", blend, "--lightmaps", copy, "--out", tmp_path / "copy.glb")
    assert r.returncode == 0, r.stderr
    line = next(l for l in r.stdout.splitlines() if l.startswith("Cube:"))
    assert float(line.split("intensity ")[1].split()[0]) == pytest.approx(2 * peak, rel=1e-5)


@pytest.mark.parametrize("value", [float("nan"), float("inf")], ids=["nan", "inf"])
def test_a_map_that_is_not_finite_is_refused_before_anything_is_written(baked, tmp_path, script, value):
    blend, out, report = baked
    path = report["Cube"]["irradiance"]["file"]
    _poke(path, value)
    for extra in ((), ("--godot", "--unity")):
        dest = tmp_path / f"out{len(extra)}"
        dest.mkdir()
        r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", dest / "s.glb", *extra)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert path in r.stderr and "not finite" in r.stderr
        assert os.listdir(dest) == []


def test_engine_files_refused_before_the_glb_when_nothing_can_be_handed_over(baked, tmp_path, script):
    """AO alone gives an engine nothing to hand over: --godot / --unity refuse before writing the .glb; --out naming
    a folder is refused as such."""
    blend, out, _ = baked
    path = out / "bake_report.json"
    report = json.loads(path.read_text())
    report["objects"] = {name: {"ao": maps["ao"]} for name, maps in report["objects"].items()}
    path.write_text(json.dumps(report))
    dest = tmp_path / "engines"
    dest.mkdir()
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", dest / "s.glb", "--unity")
    assert r.returncode == 2 and "irradiance or directional" in r.stderr and os.listdir(dest) == []
    (dest / "s.glb").mkdir()
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", dest / "s.glb")
    assert r.returncode == 2 and "--out: is a folder" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_modifiers_are_exported_applied_as_the_bake_baked_them(tmp_path):
    """A cube with a Subdivision Surface (1 level in the viewport, 2 in renders: the bake bakes 2) and an Array: the
    .glb carries the mesh the bake baked (2 x 6 x 16 quads), its TEXCOORD_1 the evaluated light-map UVs, under the
    original mesh's name with its map; the modifier's viewport level is 1 again after the export; its shape keys,
    which the exporter drops with the modifiers applied, are named."""
    from addon.bake.gltf import export_glb
    scene, plane, cube = _scene()
    sub = cube.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 1, 2
    cube.modifiers.new("Array", "ARRAY").count = 2
    out = tmp_path / "maps"
    report = bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=32, samples=1, bounces=1),
                            scene=scene)["objects"]
    glb = tmp_path / "mods.glb"
    cube.shape_key_add(name="Basis")
    result = export_glb(scene, str(out), str(glb))
    assert sorted(result["objects"]) == ["Cube", "Plane"] and sub.levels == 1
    assert result["notes"] == ["shape keys not exported, as Blender's glTF exporter applies the modifiers of these "
                               "objects (so that the triangles are those baked): Cube"]
    gltf, binary = _read_glb(glb)
    node = next(n for n in gltf["nodes"] if n["name"] == "Cube")
    mesh = gltf["meshes"][node["mesh"]]
    assert mesh["name"] == cube.data.name
    (prim,) = mesh["primitives"]
    assert gltf["accessors"][prim["indices"]]["count"] == 3 * 2 * 2 * 6 * 16
    assert EXTENSION in gltf["materials"][prim["material"]]["extensions"]
    sub.levels = 2
    try:
        evaluated = cube.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
        uv = np.array([d.uv[:] for d in evaluated.uv_layers[report["Cube"]["irradiance"]["uv_layer"]].data])
    finally:
        sub.levels = 1
    uv1 = _accessor(gltf, binary, prim["attributes"]["TEXCOORD_1"])
    assert {(round(u, 4), round(1.0 - v, 4)) for u, v in uv} == {(round(float(u), 4), round(float(v), 4))
                                                                  for u, v in uv1}


def test_the_export_says_what_it_carries_that_is_not_the_bakes_answer(baked, tmp_path):
    """A map the bake found unlit (its entry's "unlit") is exported black with a note naming it; an object a collection
    instance places again is named with the instance (its copies carry the map baked where the object stands)."""
    from addon.bake.gltf import export_glb
    _, out, _ = baked
    scene = bpy.context.scene
    cube = bpy.data.objects["Cube"]
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    props.objects.link(cube)
    instance = bpy.data.objects.new("Instance", None)
    instance.instance_type, instance.instance_collection = "COLLECTION", props
    scene.collection.objects.link(instance)
    path = out / "bake_report.json"
    report = json.loads(path.read_text())
    report["objects"]["Plane"]["irradiance"]["unlit"] = "'Plane' irradiance: 0 on every texel"
    path.write_text(json.dumps(report))
    notes = export_glb(scene, str(out), str(tmp_path / "notes.glb"))["notes"]
    assert len(notes) == 2, notes
    assert notes[0].startswith("exported black") and notes[0].endswith(": Plane")
    assert notes[1].endswith("Cube (by 'Instance')")


def test_the_file_a_batch_bake_left_as_it_was_exports_through_the_bakes_uv_cache(tmp_path, script):
    """bake.py never writes the file it bakes, so that file lacks the generated light-map layers (or holds an old
    "Lightmap" layer the bake could not reuse and made again: all zeros here): the export finds them in the bake
    folder's UV cache (the report entries' "uv_cache"), the same TEXCOORD_1 and maps as the copy --save-as wrote; a
    mesh whose corners changed since (though the file holds a layer of that name), or an entry naming no cache file,
    is skipped with its note."""
    for o in _scene()[1:]:
        o.data.uv_layers.new(name="Lightmap").data.foreach_set("uv", np.zeros(2 * len(o.data.loops), np.float32))
    original, copy = tmp_path / "level.blend", tmp_path / "copy.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(original), copy=True)
    maps = tmp_path / "maps"
    r = script("bake.py", original, "--objects", "Plane", "Cube", "--maps", "irradiance", "--resolution", "16",
               "--samples", "2", "--out", maps, "--save-as", copy)
    assert r.returncode == 0, r.stderr
    report = json.loads((maps / "bake_report.json").read_text())["objects"]
    assert all(len(report[n]["irradiance"]["uv_cache"][0]) == 40 for n in ("Plane", "Cube"))
    glbs = {}
    for blend in (original, copy):
        glbs[blend] = tmp_path / f"{blend.stem}.glb"
        r = script("export_lightmaps.py", blend, "--lightmaps", maps, "--out", glbs[blend])
        assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
    texcoords = []
    for glb in glbs.values():
        gltf, binary = _read_glb(glb)
        nodes = {n["name"]: n for n in gltf["nodes"]}
        prims = {name: gltf["meshes"][nodes[name]["mesh"]]["primitives"][0] for name in ("Plane", "Cube")}
        assert all(EXTENSION in gltf["materials"][p["material"]]["extensions"] for p in prims.values())
        texcoords.append({name: _accessor(gltf, binary, p["attributes"]["TEXCOORD_1"]) for name, p in prims.items()})
    for name in ("Plane", "Cube"):
        np.testing.assert_array_equal(texcoords[0][name], texcoords[1][name])
    path = maps / "bake_report.json"
    data = json.loads(path.read_text())
    data["objects"]["Cube"]["irradiance"]["uv_cache"] = ["../" * 3 + "x", 0]
    path.write_text(json.dumps(data))
    bpy.ops.wm.open_mainfile(filepath=str(original))
    cube = bpy.data.objects["Cube"].data
    cube.uv_layers.remove(cube.uv_layers["Lightmap"])
    import bmesh
    me = bpy.data.objects["Plane"].data            # the plane's mesh edited since the bake: its faces subdivided
    bm = bmesh.new()
    bm.from_mesh(me)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True)
    bm.to_mesh(me)
    bm.free()
    bpy.ops.wm.save_as_mainfile(filepath=str(original), copy=True)
    r = script("export_lightmaps.py", original, "--lightmaps", maps, "--out", tmp_path / "none.glb")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "UV cache" in lines[0] and "Cube ('Lightmap')" in lines[0]            # the key names no cache file
    assert "edited since the bake" in lines[0] and "Plane" in lines[0]          # its old layer is not the baked one


def test_the_export_names_the_objects_changed_since_their_bake(baked, tmp_path):
    """Each map's entry keeps digests of what in the scene it was baked from ("inputs"): the export of the scene as
    baked says nothing of changes; a moved cube, a recoloured shared material (a lit map's input: irradiance, not
    AO) and a brighter world are each named, per object; under another Blender version only the placement is
    compared (node and modifier settings differ between versions)."""
    from addon.bake.gltf import export_glb
    _, out, entries = baked
    assert set(entries["Cube"]["irradiance"]["inputs"]) == {"placement", "modifiers", "materials", "lighting",
                                                            "blender", "recipe"}
    scene = bpy.context.scene
    cube, paint = bpy.data.objects["Cube"], bpy.data.materials["Paint"]

    def changed():
        notes = export_glb(scene, str(out), str(tmp_path / "changed.glb"))["notes"]
        assert not notes or notes[0].startswith("changed since the bake") or notes[0].startswith("the lights"), notes
        return notes

    assert changed() == []
    where = cube.location.copy()
    cube.location.x += 0.1
    assert changed() == [f"{CHANGED}Cube (moved or its mesh edited)"]
    cube.location = where
    bsdf = next(n for n in paint.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.2, 0.4, 0.8, 1.0)
    assert changed() == [f"{CHANGED}Cube (its materials), Plane (its materials)"]
    background = next(n for n in scene.world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    background.inputs["Strength"].default_value = 2.0
    assert changed() == [f"{CHANGED}Cube (its materials), Plane (its materials)", RELIT]
    path = out / "bake_report.json"
    report = json.loads(path.read_text())
    for kind in ("ao", "irradiance"):
        report["objects"]["Plane"][kind]["inputs"]["blender"] = "2.79"
    path.write_text(json.dumps(report))
    bpy.data.objects["Plane"].location.z -= 0.01
    assert changed() == [f"{CHANGED}Cube (its materials), Plane (moved or its mesh edited)", RELIT]


CHANGED = "changed since the bake, so their maps show them as they were then (bake them again with --overwrite): "
RELIT = ("the lights or the world changed since the bake, so the maps of their light (irradiance, directional) show "
         "it as it was then (bake them again with --overwrite)")


def _materials_of(glb):
    """{node name: [(material name, base colour, emissive, extensions)]} of a .glb."""
    gltf, _ = _read_glb(glb)
    out = {}
    for node in gltf["nodes"]:
        if "mesh" in node:
            for prim in gltf["meshes"][node["mesh"]]["primitives"]:
                mat = gltf["materials"][prim["material"]]
                out.setdefault(node["name"], []).append(
                    (mat.get("name"), mat.get("pbrMetallicRoughness", {}).get("baseColorFactor"),
                     mat.get("emissiveFactor"), sorted(mat.get("extensions", {}))))
    return out


def test_the_export_carries_the_users_own_materials_under_a_preview_or_a_shading_model(tmp_path):
    """The glTF holds the user's materials, each with its light map, however the session shows them: a cube arrayed
    twice whose material is linked to the object (Blender's exporter reads the mesh's own materials when it applies
    modifiers) and a plane whose material is the mesh's; the same .glb materials with the irradiance preview shown
    (before: the preview's emission material, or no light map on the arrayed cube) and with a Phong shading model
    assigned; the slots show the preview again afterwards, and Remove gives each its own material and link."""
    from addon.bake.gltf import export_glb
    from addon.nodes import lightmap_preview as lp, material
    scene, plane, cube = _scene()
    cube.modifiers.new("Array", "ARRAY").count = 2
    own = bpy.data.materials.new("Own")
    own.diffuse_color = (0.1, 0.6, 0.3, 1.0)
    cube.material_slots[0].link = "OBJECT"
    cube.material_slots[0].material = own
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=16, samples=1, bounces=1),
                   scene=scene)
    assert export_glb(scene, str(out), str(tmp_path / "plain.glb"))["notes"] == []
    plain = _materials_of(tmp_path / "plain.glb")
    assert [m[0] for m in plain["Plane"]] == ["Paint"] and [m[0] for m in plain["Cube"]] == ["Own"]
    assert all(m[2] is None and m[3] == [EXTENSION] for mats in plain.values() for m in mats), plain
    lp.apply_lightmaps([plane, cube], str(out), "IRRADIANCE")
    shown = [(s.link, s.material) for o in (plane, cube) for s in o.material_slots]
    assert all(lp.is_preview(m) for _, m in shown)
    assert export_glb(scene, str(out), str(tmp_path / "shown.glb"))["notes"] == []
    assert _materials_of(tmp_path / "shown.glb") == plain
    assert [(s.link, s.material) for o in (plane, cube) for s in o.material_slots] == shown
    lp.remove_lightmaps([plane, cube])
    assert [(s.link, s.material.name) for o in (plane, cube) for s in o.material_slots] == [("DATA", "Paint"),
                                                                                               ("OBJECT", "Own")]
    material.assign_shading_model(scene, [plane, cube], "PHONG")
    assert plane.material_slots[0].material.get("il_model")
    export_glb(scene, str(out), str(tmp_path / "phong.glb"))
    assert _materials_of(tmp_path / "phong.glb") == plain


def test_objects_disabled_in_viewports_are_exported_as_they_were_baked(tmp_path):
    """An object disabled in viewports but rendered (an arrayed plane), and one in a collection so disabled (a cube
    under a Subdivision Surface, 2 levels in renders), are left out of the viewport's evaluation: the exporter wrote
    their bare meshes (2 and 12 triangles). They are exported as baked (4 and 192), and stay disabled afterwards."""
    from addon.bake.gltf import export_glb
    scene, plane, cube = _scene()
    plane.modifiers.new("Array", "ARRAY").count = 2
    cube.modifiers.new("Subdivision", "SUBSURF").render_levels = 2
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    scene.collection.objects.unlink(cube)
    props.objects.link(cube)
    plane.hide_viewport = props.hide_viewport = True
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=16, samples=1, bounces=1),
                   scene=scene)
    assert export_glb(scene, str(out), str(tmp_path / "disabled.glb"))["notes"] == []
    assert plane.hide_viewport and props.hide_viewport
    gltf, _ = _read_glb(tmp_path / "disabled.glb")
    triangles = {n["name"]: sum(gltf["accessors"][p["indices"]]["count"] // 3
                                for p in gltf["meshes"][n["mesh"]]["primitives"])
                 for n in gltf["nodes"] if "mesh" in n}
    assert triangles == {"Plane": 4, "Cube": 192}


def test_what_a_render_does_not_see_is_not_a_change_since_the_bake(tmp_path):
    """The digests the export compares are of the scene as a render sees it: a cube whose Subdivision Surface is 1
    level in the viewport and 2 in renders, under an Array, baked; then its modifier panels opened, the Array
    hidden in the viewport (still rendered), the cube disabled in viewports and the Subdivision's viewport level
    changed: no change is named (each was named "its modifiers"); the Array's count changed is."""
    from addon.bake.gltf import export_glb
    scene, plane, cube = _scene()
    sub = cube.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 1, 2
    array = cube.modifiers.new("Array", "ARRAY")
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=16, samples=1, bounces=1),
                   scene=scene)
    for name in (n for n in dir(sub) if n.startswith("open_")):
        setattr(sub, name, not getattr(sub, name))
    array.show_viewport, cube.hide_viewport, sub.levels = False, True, 0
    assert export_glb(scene, str(out), str(tmp_path / "same.glb"))["notes"] == []
    array.count = 3
    assert export_glb(scene, str(out), str(tmp_path / "more.glb"))["notes"] == [f"{CHANGED}Cube (its modifiers)"]
