"""The user's file comes back as it was; bad input fails with a clear message and changes nothing."""
import json
import os

import bpy
import numpy as np
import pytest

from addon.blender import compat
from addon.bake import BakeOptions, bake_lightmaps
from addon.core.io import exr
from addon.core.errors import InputError
from addon.blender import scene as sc


def black_metal():
    m = bpy.data.materials.new("Black metal")
    compat.ensure_use_nodes(m)
    bsdf = m.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (0, 0, 0, 1)
    bsdf.inputs["Metallic"].default_value = 1.0
    return m


def user_file():
    """A scene as a user leaves it: black metallic material, two UV layers, an old "Lightmap" layer,
    face selection, EEVEE, odd settings."""
    scene = bpy.context.scene
    scene.render.engine = compat.EEVEE
    scene.cycles.samples = 7
    scene.cycles.seed = 3
    scene.cycles.diffuse_bounces = 2
    scene.render.bake.margin = 5
    world = bpy.data.worlds.new("W")
    world.light_settings.distance = 2.5
    scene.world = world
    a = sc.box(scene, "A", 1.0)
    b = sc.plane(scene, "B", 4.0)
    c = sc.sphere(scene, "C", 0.3, location=(2, 0, 1), segments=8, rings=4)
    a.data.materials.append(black_metal())
    a.data.uv_layers.new(name="First")
    a.data.uv_layers.new(name="Second")
    a.data.uv_layers.active_index = 1
    a.data.uv_layers["First"].active_render = True
    a.data.color_attributes.new("Col", "BYTE_COLOR", "CORNER")
    a.data.polygons.foreach_set("select", [True, False, True, False, False, False])
    a.data.polygons.foreach_set("hide", [False, False, False, False, False, True])
    old = b.data.uv_layers.new(name="Lightmap")                   # an earlier bake's layer, hand-edited
    old.data.foreach_set("uv", [0.1, 0.1, 0.3, 0.1, 0.3, 0.3, 0.1, 0.3])
    img = bpy.data.images.new("User image", 8, 8)
    vl = bpy.context.view_layer
    c.select_set(True)
    vl.objects.active = c
    return scene, [a, b], img


def snapshot(scene):
    vl = bpy.context.view_layer
    s = {
        "engine": scene.render.engine,
        "cycles": [getattr(scene.cycles, k) for k in ("samples", "seed", "diffuse_bounces", "max_bounces",
                                                      "device", "use_denoising", "use_adaptive_sampling")],
        "bake_margin": scene.render.bake.margin, "bake_target": scene.render.bake.target,
        "world": scene.world.name if scene.world else None,
        "distance": scene.world.light_settings.distance if scene.world else None,
        "selected": sorted(o.name for o in vl.objects if o.select_get()),
        "active": vl.objects.active.name if vl.objects.active else None,
        "data": {k: sorted(x.name for x in getattr(bpy.data, k))
                 for k in ("materials", "images", "worlds", "scenes", "node_groups", "meshes", "objects")},
        "objects": {},
    }
    for o in scene.objects:
        if o.type != "MESH":
            continue
        me = o.data
        uv = {}
        for layer in me.uv_layers:
            a = np.zeros(len(me.loops) * 2)
            layer.data.foreach_get("uv", a)
            uv[layer.name] = a.round(6).tolist()
        s["objects"][o.name] = {
            "slots": [(sl.link, sl.material.name if sl.material else None) for sl in o.material_slots],
            "uv": uv, "uv_active": me.uv_layers.active_index,
            "uv_render": [l.name for l in me.uv_layers if l.active_render],
            "colors": [c.name for c in me.color_attributes], "color_active": me.color_attributes.active_color_name,
            "attributes": sorted(a.name for a in me.attributes),
            "select": [[bool(x.select) for x in items] for items in (me.vertices, me.edges, me.polygons)],
            "hide": [[bool(x.hide) for x in items] for items in (me.vertices, me.edges, me.polygons)],
            "mode": o.mode}
    return s


@pytest.mark.both_versions
def test_state_restored_after_success(tmp_path):
    scene, objs, _ = user_file()
    before = snapshot(scene)
    rep = bake_lightmaps(objs, ["ao", "irradiance"], tmp_path,
                         BakeOptions(resolution=16, samples=2, keep_products=False, denoise=True), scene=scene)
    assert snapshot(scene) == before
    assert set(rep["objects"]) == {"A", "B"}
    # with the products kept only the "Lightmap" layer is new; the render layer and the active layer stay
    bake_lightmaps(objs, ["ao"], tmp_path, BakeOptions(resolution=16, samples=1, overwrite=True), scene=scene)
    after = snapshot(scene)
    a = after["objects"]["A"]
    assert list(a["uv"]) == ["First", "Second", "Lightmap"] and a["uv_render"] == ["First"] and a["uv_active"] == 1
    # every face got its chart, the one the user hid too
    uv = np.array(a["uv"]["Lightmap"]).reshape(6, 4, 2)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 3] - uv[:, 0]
    assert np.all(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) > 1e-3)
    for k in ("engine", "cycles", "selected", "active", "data", "distance", "bake_margin"):
        assert after[k] == before[k]


@pytest.mark.parametrize("bounces", [0, 2])
def test_black_metal_bakes_the_same_irradiance_as_white(tmp_path, bounces):
    scene = sc.new_scene("T")
    p = sc.plane(scene, "P", 2.0)
    sc.world(scene, strength=0.5)
    m = black_metal()
    p.data.materials.append(m)
    bake_lightmaps([p], ["irradiance"], tmp_path, BakeOptions(resolution=8, samples=2, bounces=bounces),
                   scene=scene)
    ch, _ = exr.read_exr(tmp_path / "P_irradiance.exr")
    np.testing.assert_allclose(ch["R"], np.pi * 0.5, rtol=1e-4)
    assert p.material_slots[0].material == m


@pytest.mark.parametrize("error,atlas", [(RuntimeError, False), (KeyboardInterrupt, True)])
def test_state_restored_after_failure_and_interruption(tmp_path, error, atlas):
    """The atlas run re-unwraps B's old "Lightmap" layer: its hand-edited UVs must come back too."""
    scene, objs, _ = user_file()
    before = snapshot(scene)
    calls = []

    def on_step(message):
        calls.append(message)
        if len(calls) == 3:            # after UVs and the first map, in the middle of the run
            raise error("injected")

    with pytest.raises(error):
        bake_lightmaps(objs, ["ao", "irradiance"], tmp_path, BakeOptions(resolution=16, samples=2, atlas=atlas),
                       scene=scene, on_step=on_step)
    assert snapshot(scene) == before
    assert len(calls) == 3


BAD = [
    ("nothing", lambda o: ([], {}), "nothing selected"),
    ("non-mesh", lambda o: ([o["lamp"]], {}), "nothing to bake: .Lamp. is not a mesh"),
    ("no faces", lambda o: ([o["edges"]], {}), "nothing to bake: .Edges. is a mesh without faces"),
    ("uv layer", lambda o: ([o["A"]], {"uv_layer": "Nope"}), "has no UV layer 'Nope'"),
    ("res 0", lambda o: ([o["A"]], {"resolution": 0}), "resolution must be between 1 and 16384"),
    ("res big", lambda o: ([o["A"]], {"resolution": 16385}), "resolution must be between 1 and 16384"),
    ("samples 0", lambda o: ([o["A"]], {"samples": 0}), "samples must be between 1 and"),
    ("size 0", lambda o: ([o["A"]], {"sizes": {"A": (8, 0)}}), "map size of 'A' must be between 1 and 16384"),
    ("sizes+vertex", lambda o: ([o["A"]], {"sizes": {"A": (8, 8)}, "target": "vertex"}), "image target"),
]


def test_bad_input_fails_clearly_and_changes_nothing(tmp_path):
    scene, objs, _ = user_file()
    lamp = sc.light(scene, "Lamp", "POINT", 10.0)
    me = bpy.data.meshes.new("Edges")
    me.from_pydata([(0, 0, 0), (1, 0, 0)], [(0, 1)], [])
    edges = bpy.data.objects.new("Edges", me)
    scene.collection.objects.link(edges)
    named = {"lamp": lamp, "edges": edges, "A": objs[0]}
    before = snapshot(scene)
    for label, make, message in BAD:
        objects, kw = make(named)
        with pytest.raises(InputError, match=message):
            bake_lightmaps(objects, ["ao"], tmp_path / "x", BakeOptions(**kw), scene=scene)
        assert snapshot(scene) == before, label
    locked = tmp_path / "locked"
    locked.mkdir()
    os.chmod(locked, 0o500)
    # root ignores permission bits: /proc takes no new files for anyone
    unwritable = locked / "maps" if os.geteuid() != 0 else "/proc/il_lab_maps"
    try:
        with pytest.raises(InputError, match="output folder cannot be written"):
            bake_lightmaps([objs[0]], ["ao"], unwritable, BakeOptions(resolution=8, samples=1), scene=scene)
    finally:
        os.chmod(locked, 0o700)
    with pytest.raises(InputError, match="cannot be written|is a file"):
        (tmp_path / "file").write_text("x")
        bake_lightmaps([objs[0]], ["ao"], tmp_path / "file", BakeOptions(resolution=8, samples=1), scene=scene)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "A_ao.exr").write_bytes(b"mine")
    with pytest.raises(InputError, match=r"exists: turn on Overwrite \(--overwrite\)"):
        bake_lightmaps([objs[0]], ["ao"], tmp_path / "out", BakeOptions(resolution=8, samples=1), scene=scene)
    assert (tmp_path / "out" / "A_ao.exr").read_bytes() == b"mine"
    assert snapshot(scene) == before
    assert not (tmp_path / "x").exists()


def test_operator_bakes_selected_meshes_and_reports_errors(tmp_path):
    scene = bpy.context.scene
    p = sc.plane(scene, "P", 2.0)
    worlds = list(bpy.data.worlds)                                # none: the bake adds a black one for a while
    s = scene.illumination.lightmaps
    s.output_dir = str(tmp_path)
    s.resolution, s.samples, s.maps = 8, 1, {"ao"}
    assert not bpy.ops.illumination.bake_lightmaps.poll()        # nothing selected
    p.select_set(True)
    bpy.context.view_layer.objects.active = p
    assert bpy.ops.illumination.bake_lightmaps() == {"FINISHED"}
    assert (tmp_path / "P_ao.exr").exists()
    with pytest.raises(RuntimeError, match=r"exists: turn on Overwrite \(--overwrite\)"):
        bpy.ops.illumination.bake_lightmaps()
    assert p.select_get() and bpy.context.view_layer.objects.active == p
    assert list(bpy.data.worlds) == worlds and scene.world is None


def test_script_bakes_a_blend_without_modifying_it(tmp_path, script):
    scene = bpy.context.scene
    sc.plane(scene, "Floor", 4.0)
    sc.box(scene, "Box", 1.0, location=(0, 0, 0.5))
    blend = tmp_path / "s.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    data = blend.read_bytes()
    out = tmp_path / "maps"
    r = script("bake.py", blend, "--objects", "Floor", "Box", "--maps", "ao", "irradiance", "--out", out,
               "--resolution", "16", "--samples", "4")
    assert r.returncode == 0, r.stderr
    assert "[bake" in r.stderr and "report:" in r.stdout and "(binomial bound)" in r.stdout
    rep = json.loads((out / "bake_report.json").read_text())
    assert set(rep["objects"]) == {"Floor", "Box"} and rep["objects"]["Box"]["irradiance"]["samples"] == 4
    for k in ("file", "resolution", "samples", "seconds", "estimated_error"):
        assert k in rep["objects"]["Floor"]["ao"]
    assert blend.read_bytes() == data
    r = script("bake.py", blend, "--objects", "Floor", "--out", out, "--samples", "0")
    assert r.returncode == 2 and "argument --samples: must be 1 <= value" in r.stderr
    r = script("bake.py", blend, "--objects", "Floor", "--out", out, "--resolution", "16")
    assert r.returncode == 2 and "exists: turn on Overwrite (--overwrite)" in r.stderr.strip().splitlines()[-1]


@pytest.mark.both_versions
def test_ao_bakes_without_the_worlds_importance_map_and_the_world_comes_back(tmp_path, monkeypatch):
    """AO sees no light, yet Cycles built the world's importance map at every AO call (21 s of a 64² atlas's AO
    call under the corpus's 64x32 environment texture, 0.6 s without): AO calls now run with the world's
    sampling method NONE, irradiance with the user's, the AO pixels are those of a world the user set to NONE
    themselves, bit for bit, and the user's setting comes back."""
    from addon.bake import cycles
    scene = bpy.context.scene
    floor = sc.plane(scene, "Floor", 4.0)
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.5))
    env = bpy.data.images.new("sky", 64, 32, float_buffer=True)
    env.pixels.foreach_set(np.linspace(0.0, 2.0, 64 * 32 * 4, dtype=np.float32))
    world = sc.world(scene, strength=1.0)
    tex = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    tex.image = env
    world.node_tree.links.new(tex.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    world.cycles.sampling_method = "MANUAL"
    seen, real = [], cycles.call_bake
    monkeypatch.setattr(cycles, "call_bake", lambda scene, group, kind, *a, **k: (
        seen.append((kind, scene.world.cycles.sampling_method)), real(scene, group, kind, *a, **k))[1])
    opts = BakeOptions(resolution=16, samples=4, keep_products=False)
    bake_lightmaps([floor], ["ao", "irradiance"], tmp_path / "manual", opts)
    assert sorted(set(seen)) == [("ao", "NONE"), ("irradiance", "MANUAL")]
    assert world.cycles.sampling_method == "MANUAL"
    world.cycles.sampling_method = "NONE"
    bake_lightmaps([floor], ["ao"], tmp_path / "none", opts)
    a, b = (exr.read_exr(tmp_path / d / "Floor_ao.exr")[0] for d in ("manual", "none"))
    assert a.keys() == b.keys() and all(np.array_equal(a[c], b[c]) for c in a) and a["Y"].max() > 0


def _emissive(name, strength):
    m = bpy.data.materials.new(name)
    compat.ensure_use_nodes(m)
    bsdf = m.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Emission Color"].default_value = (1.0, 0.9, 0.8, 1.0)
    bsdf.inputs["Emission Strength"].default_value = strength
    return m


@pytest.mark.both_versions
def test_a_bake_lights_the_scene_through_the_users_materials_under_previews_and_shading_models(tmp_path):
    """The add-on's own layers on slots (the light-map preview, a shading model) are looked through: the lamp that
    lights the floor is an emissive material the preview and the Phong model hide, also on an object not baked.
    Baked again with them shown, the maps are those of the first bake bit for bit, the inputs hash as unchanged, and
    the layers are on the slots again afterwards."""
    from addon.nodes import lightmap_preview as lp, material
    scene = bpy.context.scene
    floor = sc.plane(scene, "Floor", 4.0)
    lamp = sc.plane(scene, "Lamp", 1.0, location=(0, 0, 1.5))
    lamp.rotation_euler = (np.pi, 0.0, 0.0)
    lamp.data.materials.append(_emissive("Bulb", 20.0))
    box = sc.box(scene, "Box", 0.5)
    box.location = (1.0, 1.0, 0.25)
    box.data.materials.append(_emissive("Glow", 5.0))
    opts = BakeOptions(resolution=16, samples=4, bounces=1, overwrite=True)
    first = bake_lightmaps([floor, lamp], ["irradiance"], str(tmp_path / "a"), opts, scene=scene)
    before = {n: exr.read_exr(first["objects"][n]["irradiance"]["file"])[0] for n in ("Floor", "Lamp")}
    lp.apply_lightmaps([floor, lamp], str(tmp_path / "a"))
    material.assign_materials(scene, [box], "PHONG")
    shown = {o.name: [s.material for s in o.material_slots] for o in (floor, lamp, box)}
    assert all(m.get("il_lightmap") or m.get("il_model") for ms in shown.values() for m in ms)
    again = bake_lightmaps([floor, lamp], ["irradiance"], str(tmp_path / "b"), opts, scene=scene)
    for name, chans in before.items():
        after = exr.read_exr(again["objects"][name]["irradiance"]["file"])[0]
        assert all(np.array_equal(chans[c], after[c]) for c in "RGB"), name
    assert {o.name: [s.material for s in o.material_slots] for o in (floor, lamp, box)} == shown
    resumed = bake_lightmaps([floor, lamp], ["irradiance"], str(tmp_path / "a"), opts, scene=scene)
    assert resumed["unchanged"] == {"Floor": ["irradiance"], "Lamp": ["irradiance"]}


def test_an_object_that_cannot_take_its_own_material_back_is_named(tmp_path):
    """A curve showing an add-on material (made by hand: the operators shade meshes only) keeps it for the bake, which
    says so instead of failing on it."""
    scene = bpy.context.scene
    floor = sc.plane(scene, "Floor", 2.0)
    curve = bpy.data.objects.new("Rail", bpy.data.curves.new("Rail", "CURVE"))
    scene.collection.objects.link(curve)
    own, shown = bpy.data.materials.new("Own"), bpy.data.materials.new("IL Phong: Own")
    shown["il_model"], shown["il_original"] = "PHONG", own
    curve.data.materials.append(shown)
    with pytest.warns(UserWarning, match="the bakes see the Illumination Lab materials shown on Rail"):
        bake_lightmaps([floor], ["irradiance"], str(tmp_path / "out"), BakeOptions(resolution=8, samples=1))
    assert curve.material_slots[0].material == shown


@pytest.mark.both_versions
def test_objects_disabled_in_viewports_but_rendered_are_baked_as_rendered(tmp_path):
    """Blender leaves an object disabled in viewports (the monitor icon), or held by a collection so disabled, out of
    the viewport's evaluation, modifiers unapplied, while renders see it whole. A batched bake of an arrayed cube and
    a subdivided one in such a collection (and a subdivided cube disabled itself) gives the maps of the same bake with
    everything shown, bit for bit (the joined mesh held the bare cubes: the subdivided cube's mean E moved by 2x),
    the checks read the triangles Cycles baked, and the settings come back."""
    scene = bpy.context.scene
    sc.world(scene, strength=1.0)
    sc.plane(scene, "Ground", 6.0)
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    cubes = []
    for name, x, mod in (("Arrayed", -1.5, "ARRAY"), ("Rounded", 0.0, "SUBSURF"), ("Alone", 1.5, "SUBSURF")):
        cube = sc.box(scene, name, 0.5, location=(x, 0.0, 0.5))
        cube.modifiers.new(mod, mod)
        if name != "Alone":
            scene.collection.objects.unlink(cube)
            props.objects.link(cube)
        cubes.append(cube)
    opts = BakeOptions(resolution=24, samples=4, bounces=1, batch=True, keep_products=False)
    shown = bake_lightmaps(cubes, ["irradiance"], str(tmp_path / "shown"), opts)
    props.hide_viewport, cubes[2].hide_viewport = True, True
    bpy.context.view_layer.update()
    hidden = bake_lightmaps(cubes, ["irradiance"], str(tmp_path / "hidden"), opts)
    assert props.hide_viewport and cubes[2].hide_viewport
    for cube in cubes:
        a = exr.read_exr(str(tmp_path / "shown" / f"{cube.name}_irradiance.exr"))[0]
        b = exr.read_exr(str(tmp_path / "hidden" / f"{cube.name}_irradiance.exr"))[0]
        assert all(np.array_equal(a[c], b[c]) for c in "RGBA"), cube.name
        assert hidden["objects"][cube.name]["irradiance"]["overlap"] == shown["objects"][cube.name]["irradiance"][
            "overlap"], cube.name
    assert hidden["objects"]["Arrayed"]["irradiance"]["overlap"] > 0.9     # the Array's copies share its texels
