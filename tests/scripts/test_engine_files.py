"""export_lightmaps.py --godot --unity (issue 28, item 4): the files each engine reads, checked against the bake's
own EXRs and the .glb's node names (what Godot's and Unity's glTF importers name the nodes). Not run in the
engines: docs/lightmaps.md says what was verified."""
import json
import math
import os
import re

import numpy as np
import pytest

from addon.core.io import exr
from tests.scripts.test_export_lightmaps import _read_glb, baked  # noqa: F401  (the fixture)

pytestmark = pytest.mark.both_versions


def _rgb(path):
    ch, _ = exr.read_exr(path)
    return np.stack([ch[c] for c in "RGB"], -1)


def test_godot_and_unity_files_hold_e_over_pi_for_each_glb_node(baked, tmp_path, script):  # noqa: F811
    blend, out, report = baked
    glb = tmp_path / "scene.glb"
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", glb, "--godot", "--unity")
    assert r.returncode == 0, r.stderr
    gltf, _ = _read_glb(glb)
    nodes = {n["name"] for n in gltf["nodes"] if "mesh" in n}
    names = sorted(report)
    assert nodes >= set(names)
    maps = {name: _rgb(report[name]["irradiance"]["file"]) for name in names}

    tres = (tmp_path / "scene.lightmap.tres").read_text()
    assert 'path="scene.lightmap.exr"' in tres
    users = re.findall(r'NodePath\("\.\./([^"]+)"\), Rect2\(0, 0, ([0-9.]+), ([0-9.]+)\), (\d+), -1', tres)
    assert sorted(u[0] for u in users) == names
    stack = _rgb(tmp_path / "scene.lightmap.exr")
    side = stack.shape[1]
    assert stack.shape[0] == side * len(names)
    assert f"slices/vertical={len(names)}" in (tmp_path / "scene.lightmap.exr.import").read_text()
    for name, sx, sy, k in users:
        h, w = maps[name].shape[:2]
        assert (float(sx), float(sy)) == (w / side, h / side)
        part = stack[int(k) * side:int(k) * side + h, :w]
        np.testing.assert_allclose(part, maps[name] / math.pi, rtol=1e-6, atol=0)

    layout = json.loads((tmp_path / "scene.unity.json").read_text())
    assert sorted(layout["renderers"]) == names
    for name in names:
        entry = layout["renderers"][name]
        assert entry["lightmapScaleOffset"] == [1.0, 1.0, 0.0, 0.0]
        color = layout["lightmaps"][entry["lightmapIndex"]]["lightmapColor"]
        np.testing.assert_allclose(_rgb(tmp_path / color), maps[name] / math.pi, rtol=1e-6, atol=0)
    assert len({layout["renderers"][n]["lightmapIndex"] for n in names}) == len(names)
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("scene.")) == sorted(
        ["scene.glb", "scene.lightmap.exr", "scene.lightmap.exr.import", "scene.lightmap.tres", "scene.unity.json"]
        + [f"scene.unity_lightmap_{i}.exr" for i in range(len(names))])


def test_names_godot_makes_alike_are_refused_for_godot(tmp_path, script):
    """Objects named 'x.y' and 'x_y' become two Godot nodes 'x_y' and 'x_y2' (its glTF import writes . as _ and
    numbers the copies), so a LightmapGIData naming '../x_y' twice would light one node with both maps: --godot is
    refused naming them, before anything is written; Unity, which keys renderers by the glTF's names, is not."""
    import bpy
    from addon.bake import bake_lightmaps
    from addon.bake.options import BakeOptions
    from tests.scripts.test_export_lightmaps import _scene
    scene, plane, cube = _scene()
    plane.name, cube.name = "x.y", "x_y"
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=8, samples=1, bounces=1),
                   scene=scene)
    blend = tmp_path / "named.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    dest = tmp_path / "godot"
    dest.mkdir()
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", dest / "s.glb", "--godot")
    assert r.returncode == 2 and "'x.y', 'x_y'" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert os.listdir(dest) == []
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", dest / "s.glb", "--unity")
    assert r.returncode == 0, r.stderr
    assert sorted(json.loads((dest / "s.unity.json").read_text())["renderers"]) == ["x.y", "x_y"]


def test_godot_paths_follow_the_glb_and_what_no_engine_file_takes_is_said(tmp_path, script):
    """A cube parented to a sun lamp (the .glb leaves lights out, so the cube is a root node) and a plane named
    'Skeleton3D' (a name Godot keeps for itself: its node is 'Skeleton3D2') get the paths Godot's import gives them
    (before: '../Sun/Cube' and '../Skeleton3D', lighting nothing). An object parented to a bone is refused for
    Godot. With directional maps only, --unity is refused before anything is written; an object with a directional
    map only among objects with irradiance only is named as in no engine file."""
    import bpy
    from addon.bake import bake_lightmaps
    from addon.bake.options import BakeOptions
    from tests.scripts.test_export_lightmaps import _scene
    scene, plane, cube = _scene()
    plane.name = "Skeleton3D"
    bpy.ops.object.light_add(type="SUN", location=(0.0, 0.0, 3.0))
    sun = bpy.context.active_object
    cube.parent = sun
    cube.matrix_parent_inverse = sun.matrix_world.inverted()
    out = tmp_path / "maps"
    opts = BakeOptions(resolution=8, samples=1, bounces=1)
    bake_lightmaps([plane, cube], ["irradiance"], str(out), opts, scene=scene)
    blend = tmp_path / "lamp.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", tmp_path / "s.glb", "--godot", "--unity")
    assert r.returncode == 0, r.stderr
    paths = re.findall(r'NodePath\("([^"]+)"\)', (tmp_path / "s.lightmap.tres").read_text())
    assert sorted(paths) == ["../Cube", "../Skeleton3D2"]

    bpy.ops.object.armature_add(location=(2.0, 0.0, 0.0))
    rig = bpy.context.active_object
    cube.parent, cube.parent_type, cube.parent_bone = rig, "BONE", rig.data.bones[0].name
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    dest = tmp_path / "bone"
    dest.mkdir()
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", dest / "s.glb", "--godot")
    assert r.returncode == 2 and "parented to a bone" in r.stderr and "'Cube'" in r.stderr, r.stderr
    assert os.listdir(dest) == []

    cube.parent = None
    mixed = tmp_path / "mixed"
    bake_lightmaps([cube], ["directional"], str(mixed), opts, scene=scene)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    r = script("export_lightmaps.py", blend, "--lightmaps", mixed, "--out", dest / "s.glb", "--unity")
    assert r.returncode == 2 and "--unity: no exported object has an irradiance map" in r.stderr, r.stderr
    assert os.listdir(dest) == []
    bake_lightmaps([plane], ["irradiance"], str(mixed), opts.replace(overwrite=True), scene=scene)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    r = script("export_lightmaps.py", blend, "--lightmaps", mixed, "--out", dest / "s.glb", "--godot", "--unity")
    assert r.returncode == 0, r.stderr
    assert "not in the Godot files (a directional map only" in r.stderr and r.stderr.count(": Cube\n") == 2, r.stderr


def test_a_collection_instance_copy_does_not_take_the_objects_light_map(tmp_path, script):
    """A cube in a collection that an empty instances elsewhere: the .glb holds the cube's own node and the copy under
    the instance, both named 'Cube' (Blender 4.5's exporter writes the copy first, 5.x after). Godot's path and Unity's
    renderer path name the cube's own root node (on 4.5 before: the copy's, Godot's 'Cube2' lit by nothing)."""
    import bpy
    from addon.bake import bake_lightmaps
    from addon.bake.options import BakeOptions
    from tests.scripts.test_export_lightmaps import _scene
    scene, plane, cube = _scene()
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    props.objects.link(cube)
    scene.collection.objects.unlink(cube)
    copy = bpy.data.objects.new("Props Instance", None)
    copy.instance_type, copy.instance_collection, copy.location = "COLLECTION", props, (4.0, 0.0, 0.0)
    scene.collection.objects.link(copy)
    out = tmp_path / "maps"
    bake_lightmaps([plane, cube], ["irradiance"], str(out), BakeOptions(resolution=8, samples=1, bounces=1),
                   scene=scene)
    blend = tmp_path / "inst.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    r = script("export_lightmaps.py", blend, "--lightmaps", out, "--out", tmp_path / "s.glb", "--godot", "--unity")
    assert r.returncode == 0, r.stderr
    gltf, _ = _read_glb(tmp_path / "s.glb")
    nodes = gltf["nodes"]
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}
    cubes = [i for i, n in enumerate(nodes) if n["name"] == "Cube"]
    own = [i for i in cubes if i not in parent]
    assert len(cubes) == 2 and len(own) == 1 and nodes[parent[(set(cubes) - set(own)).pop()]]["name"] == "Props Instance"
    godot_name = "Cube" if own[0] < max(cubes) else "Cube2"          # Godot numbers the later one
    paths = re.findall(r'NodePath\("([^"]+)"\)', (tmp_path / "s.lightmap.tres").read_text())
    assert sorted(paths) == sorted(["../Plane", f"../{godot_name}"])
    renderers = json.loads((tmp_path / "s.unity.json").read_text())["renderers"]
    assert renderers["Cube"]["path"] == "Cube" and renderers["Plane"]["path"] == "Plane"
