"""Shadow lab end to end: every method's mask against Cycles' hard ray-traced mask on the same pixels."""
import json
import math
import os

import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.core import camera
from addon.core.io import png
from addon.core.shadow import metrics
from addon.core.errors import InputError
from addon.lab import shadows
from addon.lab.options import ShadowOptions
from addon.lab.shadows import scenes as shadow_scenes
from addon.lab.shadows.frame import ShadowFrame

RES = 80


def _session(name, light="sun", res=RES):
    scene = shadow_scenes.build(name, light, (res, res))
    return scene, ShadowFrame(scene, scene["il_shadow_light"], res)


def _score(s, mask):
    return metrics.confusion(mask, s.reference, s.receiver)


def _assert_on_the_reference_grid(out, method, margin=0.005):
    """The method's mask PNG agrees with the reference's better than the same mask moved by one pixel
    in any of the four directions does (a mask off by one pixel either way fails this)."""
    ref = png.decode_png((out / "raytraced_mask.png").read_bytes()) > 127
    mask = png.decode_png((out / f"{method}_mask.png").read_bytes()) > 127
    assert mask.shape == ref.shape
    everywhere = np.ones_like(ref)
    aligned = metrics.confusion(mask, ref, everywhere)["error"]
    for axis in (0, 1):
        for step in (1, -1):
            moved = metrics.confusion(np.roll(mask, step, axis=axis), ref, everywhere)["error"]
            assert moved > aligned + margin, (method, axis, step, moved, aligned)


@pytest.mark.both_versions
def test_sphere_scene_volumes_and_planar_match_the_reference_and_masks_are_pixel_aligned(tmp_path):
    rep = shadows.compare_builtin("sphere", "sun", tmp_path, ShadowOptions(
        methods="raytraced,planar,volume_zfail,volume_zpass", resolution=RES))
    m = rep["methods"]
    assert rep["reference"]["shadowed_fraction"] > 0.03          # the floor shadow and the dark side exist
    assert m["volume_zfail"]["error"] <= 0.005
    assert m["volume_zpass"]["error"] <= 0.005                   # camera outside every volume
    assert m["planar"]["error"] <= 0.005
    assert m["raytraced"]["error"] == 0.0
    assert png.decode_png((tmp_path / "raytraced_mask.png").read_bytes()).shape == (RES, RES)
    for method in ("planar", "volume_zfail", "volume_zpass"):
        _assert_on_the_reference_grid(tmp_path, method)
    assert m["volume_zfail"]["params"]["skipped_open_meshes"] == ["Floor"]    # the documented fallback
    report = json.loads((tmp_path / "shadows_report.json").read_text())
    for entry in report["methods"].values():
        assert {"error", "false_shadow", "false_light", "seconds", "params"} <= set(entry)
        assert entry["seconds"] >= 0
    assert os.path.exists(tmp_path / "planar_error.png")
    assert "IL Shadows sphere" not in bpy.data.scenes and "IL Shadow Lab" not in bpy.data.scenes


def test_spot_light_perspective_map_volumes_and_planar_match_the_reference(tmp_path):
    rep = shadows.compare_builtin("sphere", "spot", tmp_path, ShadowOptions(
        methods="raytraced,planar,shadowmap,volume_zfail", resolution=48, shadowmap_size=512))
    m = rep["methods"]
    assert rep["reference"]["light_type"] == "spot" and rep["reference"]["shadowed_fraction"] > 0.05
    assert m["shadowmap"]["params"]["projection"] == "perspective"
    assert m["shadowmap"]["params"]["depth_source"] == "raster"                # the default
    assert m["planar"]["error"] <= 0.005 and m["volume_zfail"]["error"] <= 0.005
    assert m["shadowmap"]["error"] <= 0.01
    _assert_on_the_reference_grid(tmp_path, "shadowmap")


def test_camera_inside_a_volume_breaks_zpass_not_zfail():
    scene, s = _session("inside")
    with s:
        s.render_reference()
        volume, info = shadows.volume_inputs(s)
        zpass = _score(s, shadows.volume_mask(s, volume, "zpass"))
        zfail = _score(s, shadows.volume_mask(s, volume, "zfail"))
        # the slab's shadow on the floor reaches behind the camera: its triangles cross the near plane
        planar = _score(s, shadows.run_method(s, "planar", shadows.check_params({}))[0])
    assert 0.2 < 1 - s.reference[s.receiver].mean() < 0.9         # both shadow and light in view
    assert zfail["error"] <= 0.005
    assert zpass["error"] > 0.2
    assert planar["error"] <= 0.005                               # clipped at the near plane, not dropped


def test_planar_shadows_fail_on_stairs():
    scene, s = _session("stairs")
    with s:
        s.render_reference()
        planar = _score(s, shadows.run_method(s, "planar", shadows.check_params({}))[0])
        volume = _score(s, shadows.volume_mask(s, shadows.volume_inputs(s)[0], "zfail"))
    assert volume["error"] <= 0.005
    assert planar["false_light"] > 0.01                          # the shadow hides under the raised steps


def test_shadow_map_error_falls_with_resolution_and_point_light_cube_map_works():
    scene, s = _session("sphere", "point")
    p = shadows.check_params({})
    with s:
        s.render_reference()
        errors = []
        for size in (16, 64, 256):
            maps, _ = s.depth_maps(size)
            assert len(maps) == 6
            errors.append(_score(s, shadows.shadowmap_mask(s, maps, p)[0])["error"])
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] <= 0.01


def test_bias_sweep_shows_acne_then_peter_panning():
    scene, s = _session("acne")
    with s:
        s.render_reference()
        maps, _ = s.depth_maps(256)
        rows = {b: _score(s, shadows.shadowmap_mask(s, maps, shadows.check_params({"bias": b, "slope_bias": 0.0}))[0])
                for b in (0.0, 0.1, 3.0)}
    assert rows[0.0]["false_shadow"] > 0.2                        # acne: the lit floor shadows itself
    assert rows[3.0]["false_light"] > 0.02                        # peter-panning: the shadow lets go
    assert rows[0.1]["error"] < min(rows[0.0]["error"], rows[3.0]["error"]) / 2


def test_volumes_skip_open_meshes_and_fail_without_a_closed_one():
    scene = shadow_scenes.build("sphere", "sun", (32, 32))
    bpy.data.objects.remove(scene.objects["Sphere"])
    with ShadowFrame(scene, scene["il_shadow_light"], 32) as s:
        s.render_reference()
        with pytest.raises(InputError, match="closed mesh"):
            shadows.volume_inputs(s)


@pytest.mark.both_versions
def test_workbench_sun_shadows_match_the_reference(tmp_path):
    for name in ("sphere", "acne"):                               # acne: a grazing sun (floor n.l = 0.26)
        rep = shadows.compare_builtin(name, "sun", tmp_path / name, ShadowOptions(methods="raytraced,workbench", resolution=64))
        assert rep["reference"]["shadowed_fraction"] > 0.05
        assert rep["methods"]["workbench"]["error"] <= 0.005, name   # stencil volumes are exact
        _assert_on_the_reference_grid(tmp_path / name, "workbench")
    with pytest.raises(InputError, match="sun"):
        shadows.compare_builtin("sphere", "point", tmp_path, ShadowOptions(methods="workbench", resolution=32))


@pytest.mark.eevee
def test_eevee_virtual_shadow_maps_match_the_reference(tmp_path):
    rep = shadows.compare_builtin("sphere", "point", tmp_path, ShadowOptions(methods="raytraced,eevee", resolution=64))
    assert rep["methods"]["eevee"]["error"] < 0.01
    _assert_on_the_reference_grid(tmp_path, "eevee")


@pytest.mark.both_versions
def test_panel_operators_build_a_scene_and_write_the_report(tmp_path):
    user = bpy.context.scene
    st = user.illumination.shadows
    st.scene_name, st.resolution, st.output_dir = "plate", 48, str(tmp_path)
    st.methods = {"shadowmap", "volume_zfail"}
    st.shadowmap_size = 256
    assert bpy.ops.illumination.build_shadow_scene() == {"FINISHED"}
    scene = bpy.data.scenes[-1] if bpy.context.scene == user else bpy.context.scene
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.illumination.run_shadow_comparison() == {"FINISHED"}
    report = scene.illumination.shadows.last_report
    assert report == str(tmp_path / "shadows_report.json") and os.path.exists(report)
    methods = json.loads(open(report).read())["methods"]
    assert set(methods) == {"raytraced", "shadowmap", "volume_zfail"}
    assert methods["volume_zfail"]["error"] <= 0.005


def test_script_errors_are_clear(script, tmp_path):
    with pytest.raises(InputError, match="unknown shadow method 'magic'"):
        shadows.compare_builtin("sphere", "sun", tmp_path, ShadowOptions(methods="raytraced,magic"))
    with pytest.raises(InputError, match="unknown shadow scene 'teapot'"):
        shadows.compare_builtin("teapot", "sun", tmp_path, ShadowOptions(methods="raytraced"))
    with pytest.raises(InputError, match="unknown light kind 'area'"):
        shadows.compare_builtin("sphere", "area", tmp_path, ShadowOptions(methods="raytraced"))
    assert list(bpy.data.scenes) == [bpy.context.scene]              # nothing was left behind
    # a .blend without the named light, through the script as a pipeline runs it: exit 2, one line
    scene = shadow_scenes.build("sphere", "sun", (32, 32))
    with pytest.raises(InputError, match=rf"no light named 'Nope' in scene '{scene.name}' "
                                         rf"\(its lights: {scene['il_shadow_light']}\)"):
        ShadowFrame(scene, "Nope")
    blend = tmp_path / "no_light.blend"
    bpy.data.objects.remove(scene.objects[scene["il_shadow_light"]])
    bpy.context.window_manager  # noqa: B018 - keep the context alive for the save
    for s in list(bpy.data.scenes):
        if s != scene:
            bpy.data.scenes.remove(s)
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    r = script("shadows.py", blend, "--light", "Sun", "--methods", "shadowmap", "--out", tmp_path / "o")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "no light named 'Sun' in scene" in r.stderr and "(it has no lights)" in r.stderr


def test_script_writes_masks_and_report(script, tmp_path):
    r = script("shadows.py", "--scene", "plate", "--methods", "raytraced,shadowmap,volume_zfail", "--resolution", 48,
               "--shadowmap-size", 256, "--pcf", 3, "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "shadows_report.json").read_text())
    assert report["methods"]["shadowmap"]["params"]["pcf"] == 3
    for m in ("raytraced", "shadowmap", "volume_zfail"):
        img = png.decode_png((tmp_path / f"{m}_mask.png").read_bytes())
        assert img.shape == (48, 48) and set(np.unique(img)) <= {0, 255}
        assert (tmp_path / f"{m}_error.png").exists()


def test_the_light_gets_its_settings_back_after_a_run_and_an_error(tmp_path):
    scene = shadow_scenes.build("sphere", "spot", (32, 32))
    data = scene.objects[scene["il_shadow_light"]].data
    data.shadow_soft_size, data.spot_blend, data.use_shadow = 0.3, 0.4, False
    shadows.compare(scene, scene["il_shadow_light"], tmp_path, ShadowOptions(methods="raytraced,planar", resolution=32))
    assert (data.shadow_soft_size, data.spot_blend, data.use_shadow) == (pytest.approx(0.3), pytest.approx(0.4), False)
    with pytest.raises(InputError, match="sun"):                   # refused after the light was set up
        shadows.compare(scene, scene["il_shadow_light"], tmp_path,
                        ShadowOptions(methods="raytraced,workbench", resolution=32))
    assert (data.shadow_soft_size, data.spot_blend, data.use_shadow) == (pytest.approx(0.3), pytest.approx(0.4), False)
    assert set(bpy.data.scenes) == {bpy.context.scene, scene}     # the private scene is gone


@pytest.mark.eevee
def test_eevee_gives_the_light_its_shadow_jitter_back(tmp_path):
    scene = shadow_scenes.build("sphere", "point", (32, 32))
    data = scene.objects[scene["il_shadow_light"]].data
    data.use_shadow_jitter, data.shadow_soft_size = True, 0.2
    shadows.compare(scene, scene["il_shadow_light"], tmp_path, ShadowOptions(methods="raytraced,eevee", resolution=32))
    assert data.use_shadow_jitter and data.shadow_soft_size == pytest.approx(0.2)


@pytest.mark.both_versions
@pytest.mark.parametrize("light", ["sun", "spot", "point"])
def test_rasterised_shadow_map_matches_the_cycles_depth_render(light):
    """The numpy depth map against Cycles' Depth pass of the same light cameras, texel by texel: the same
    sky texels, depths within Cycles' float32 rounding (1e-5 × depth, at least 10 µm), and the same mask."""
    scene, s = _session("sphere", light, res=48)
    p = shadows.check_params({})
    with s:
        s.render_reference()
        raster, _ = s.depth_maps(96, "raster")
        cycles, _ = s.depth_maps(96, "cycles")
        masks = [shadows.shadowmap_mask(s, maps, p)[0] for maps in (raster, cycles)]
    assert len(raster) == len(cycles) == (6 if light == "point" else 1)
    seen = 0
    for a, b in zip(raster, cycles):
        np.testing.assert_allclose(a.world_to_view, b.world_to_view)
        np.testing.assert_allclose(a.proj, b.proj)
        sky = b.depth >= 0.5 * camera.SKY_DEPTH
        np.testing.assert_array_equal(a.depth >= 0.5 * camera.SKY_DEPTH, sky)
        tol = 1e-5 * np.maximum(b.depth[~sky], 1.0)
        assert np.all(np.abs(a.depth[~sky] - b.depth[~sky]) <= tol)
        seen += int((~sky).sum())
        if light != "point":
            assert 0.1 < np.ptp(b.depth[~sky])                    # sphere and floor both in the map
    assert seen > 96 * 96 // 4
    np.testing.assert_array_equal(masks[0], masks[1])
    assert 0.02 < 1 - masks[0][s.receiver].mean() < 0.98         # shadow and light both in the mask


def test_rasterised_shadow_map_includes_collection_instances_as_cycles_does():
    """A sphere that is only in the scene as a collection instance (an Empty) casts in both depth maps."""
    scene = shadow_scenes.build("sphere", "sun", (48, 48))
    sphere = scene.objects["Sphere"]
    col = bpy.data.collections.new("Instanced")
    col.objects.link(sphere)
    for c in sphere.users_collection:
        if c != col:
            c.objects.unlink(sphere)
    empty = bpy.data.objects.new("Sphere Instance", None)
    empty.instance_type, empty.instance_collection = "COLLECTION", col
    scene.collection.objects.link(empty)
    p = shadows.check_params({})
    with ShadowFrame(scene, scene["il_shadow_light"], 48) as s:
        s.render_reference()
        assert [x.name for x in s.surfaces] == [scene["il_shadow_receiver"], "Sphere (instanced by Sphere Instance)"]
        (raster,), _ = s.depth_maps(128, "raster")
        (cycles,), _ = s.depth_maps(128, "cycles")
        masks = [shadows.shadowmap_mask(s, [m], p)[0] for m in (raster, cycles)]
        shadowed = 1 - s.reference[s.reach].mean()
    sky = cycles.depth >= 0.5 * camera.SKY_DEPTH
    np.testing.assert_array_equal(raster.depth >= 0.5 * camera.SKY_DEPTH, sky)
    assert np.all(np.abs(raster.depth - cycles.depth)[~sky] <= 1e-5 * np.maximum(cycles.depth[~sky], 1.0))
    np.testing.assert_array_equal(masks[0], masks[1])
    assert shadowed > 0.02 and 1 - masks[0][s.reach].mean() > 0.02         # the instance's shadow is there


def _operator_scene(light):
    """A scene made as a user makes it, with Blender's operators: a floor; a collection "Props" (a cube
    with a default Subdivision -- viewport level 1, render level 2 -- and a sphere) excluded from the view
    layer and placed twice with Add > Collection Instance (once rotated, once mirrored by a negative
    scale); a cylinder and its Alt-D linked duplicate with an Array modifier; a plane whose
    geometry-nodes modifier puts a cube instance on each of its four vertices; a camera and ``light``."""
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 64

    def added():
        return bpy.context.view_layer.objects.active

    bpy.ops.mesh.primitive_plane_add(size=10.0)
    added().name = "Floor"
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0.0, 0.0, 0.5))
    cube = added()
    bpy.ops.object.modifier_add(type="SUBSURF")
    assert (cube.modifiers[-1].levels, cube.modifiers[-1].render_levels) == (1, 2)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(0.0, 0.9, 0.8))
    for o in (cube, added()):
        for c in list(o.users_collection):
            c.objects.unlink(o)
        props.objects.link(o)
    bpy.context.view_layer.layer_collection.children["Props"].exclude = True     # only the instances render
    bpy.ops.object.collection_instance_add(collection="Props", location=(-1.2, -0.5, 0.0))
    bpy.ops.object.collection_instance_add(collection="Props", location=(1.0, 0.3, 0.2), rotation=(0.0, 0.0, 0.7))
    added().scale = (-1.0, 1.0, 1.0)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.25, depth=0.8, location=(0.0, -1.5, 0.4))
    bpy.ops.object.select_all(action="DESELECT")
    added().select_set(True)
    bpy.ops.object.duplicate_move_linked(TRANSFORM_OT_translate={"value": (0.0, 2.6, 0.3)})
    bpy.ops.object.modifier_add(type="ARRAY")
    bpy.ops.mesh.primitive_plane_add(size=1.2, location=(-1.8, 1.8, 1.3))
    scatter = added()
    scatter.name = "Scatter"
    bpy.ops.object.modifier_add(type="NODES")
    tree = bpy.data.node_groups.new("Cubes on points", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes = {k: tree.nodes.new(t) for k, t in (("in", "NodeGroupInput"), ("out", "NodeGroupOutput"),
                                               ("cube", "GeometryNodeMeshCube"),
                                               ("place", "GeometryNodeInstanceOnPoints"))}
    nodes["cube"].inputs["Size"].default_value = (0.3, 0.3, 0.3)
    tree.links.new(nodes["in"].outputs[0], nodes["place"].inputs["Points"])
    tree.links.new(nodes["cube"].outputs["Mesh"], nodes["place"].inputs["Instance"])
    tree.links.new(nodes["place"].outputs["Instances"], nodes["out"].inputs[0])
    scatter.modifiers[-1].node_group = tree
    loc = Vector((0.5, -4.5, 3.6))
    aim = (Vector((0.0, 0.3, 0.3)) - loc).to_track_quat("-Z", "Y").to_euler()
    bpy.ops.object.camera_add(location=loc, rotation=aim)
    scene.camera = added()
    bpy.ops.object.light_add(type=light.upper(), location=(1.0, -1.0, 4.5), rotation=(0.5, 0.2, 0.4))
    added().name = "Lamp"
    return scene


def _make_real(scene, scatter=True):
    """The same geometry without instances: Object > Apply > Make Instances Real on the collection
    instances; a Realize Instances node at the end of the scatter's node tree, its modifier applied (the
    cube instances become the scatter's mesh)."""
    bpy.ops.object.select_all(action="DESELECT")
    for o in scene.objects:
        if o.instance_type == "COLLECTION":
            o.select_set(True)
    assert bpy.ops.object.duplicates_make_real() == {"FINISHED"}
    assert not any(o.instance_type == "COLLECTION" for o in scene.objects)
    if not scatter:
        return
    scatter = scene.objects["Scatter"]
    tree = scatter.modifiers[-1].node_group
    out = next(n for n in tree.nodes if n.bl_idname == "NodeGroupOutput")
    realize = tree.nodes.new("GeometryNodeRealizeInstances")
    tree.links.new(out.inputs[0].links[0].from_socket, realize.inputs[0])
    tree.links.new(realize.outputs[0], out.inputs[0])
    bpy.context.view_layer.objects.active = scatter
    assert bpy.ops.object.modifier_apply(modifier=scatter.modifiers[-1].name) == {"FINISHED"}
    assert len(scatter.data.polygons) == 4 * 6


@pytest.mark.parametrize("light", ["sun", "point"])
def test_every_method_sees_instances_as_the_same_objects_made_real(light, tmp_path):
    """Collection, geometry-nodes and Alt-D copies cast in every method as they do in Cycles: each mask is
    pixel for pixel the one of the same scene after Make Instances Real, the reference too."""
    methods = "raytraced,planar,shadowmap,volume_zpass,volume_zfail"
    scene = _operator_scene(light)
    with ShadowFrame(scene, "Lamp", 64) as s:
        names = sorted(x.name for x in s.surfaces)
    assert names == sorted(["Floor", "Cylinder", "Cylinder.001"]
                           + ["Cube (instanced by Props)", "Sphere (instanced by Props)",
                              "Cube (instanced by Props.001)", "Sphere (instanced by Props.001)"]
                           + ["Mesh (instanced by Scatter)"] * 4)       # the excluded originals are not there
    reports, masks = {}, {}
    for tag in ("instanced", "real"):
        if tag == "real":
            _make_real(scene)
        out = tmp_path / tag
        reports[tag] = shadows.compare(scene, "Lamp", out, ShadowOptions(methods=methods, resolution=64,
                                                                            shadowmap_size=1024))["methods"]
        masks[tag] = {m: png.decode_png((out / f"{m}_mask.png").read_bytes()) for m in methods.split(",")}
    for m in methods.split(","):
        np.testing.assert_array_equal(masks["instanced"][m], masks["real"][m], err_msg=m)
        assert reports["instanced"][m]["error"] == reports["real"][m]["error"], m
    ref = masks["instanced"]["raytraced"] > 127
    receiver = reports["instanced"]["raytraced"]["receiver_pixels"]
    assert 0.04 < 1 - ref.sum() / receiver < 0.5                       # the props' shadows are in the frame
    rep = reports["instanced"]
    assert rep["volume_zfail"]["error"] <= 0.002 and rep["volume_zpass"]["error"] <= 0.002
    assert rep["shadowmap"]["error"] <= 0.005
    assert rep["planar"]["error"] <= 0.02                              # shadows falling on the props are missed
    assert rep["volume_zfail"]["params"]["skipped_open_meshes"] == ["Floor"]


def test_a_receiver_drawn_only_through_collection_instances_gets_planar_shadows(tmp_path):
    """A floor and a box kept in a collection outside the scene, placed twice by collection instances (one
    copy raised 0.5 m: two receiver planes), as linked asset files bring them: "Floor" resolves, each copy
    gets its own plane, and every mask is pixel for pixel the one of the same scene after Make Instances Real;
    the copies' coplanar faces cast nothing on their own plane."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    props = bpy.data.collections.new("Set")
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(0.2, 0.0, 0.25))
    for o in list(scene.objects):
        scene.collection.objects.unlink(o)
        props.objects.link(o)
    for location in ((-1.0, 0.0, 0.0), (1.0, 0.0, 0.5)):
        bpy.ops.object.collection_instance_add(collection="Set", location=location)
    bpy.ops.object.light_add(type="SUN", rotation=(0.5, 0.3, 0.0))
    bpy.context.object.name = "Lamp"
    loc = Vector((0.0, -5.0, 4.0))
    bpy.ops.object.camera_add(location=loc, rotation=(Vector((0.0, 0.0, 0.2)) - loc).to_track_quat("-Z", "Y").to_euler())
    scene.camera = bpy.context.object
    assert "Floor" not in scene.objects
    methods = "raytraced,planar,volume_zfail"
    reports, masks = {}, {}
    for tag in ("instanced", "real"):
        if tag == "real":
            _make_real(scene, scatter=False)
            methods = "raytraced,volume_zfail"
        out = tmp_path / tag
        reports[tag] = shadows.compare(scene, "Lamp", out, ShadowOptions(methods=methods, resolution=64))["methods"]
        masks[tag] = {m: png.decode_png((out / f"{m}_mask.png").read_bytes()) for m in methods.split(",")}
    planar = reports["instanced"]["planar"]
    assert planar["params"]["copies"] == 2
    ref = masks["instanced"]["raytraced"] > 127
    assert 0.03 < 1 - ref.sum() / reports["instanced"]["raytraced"]["receiver_pixels"] < 0.5
    assert planar["error"] <= 0.01                  # the raised floor's shadow on the lower one is drawn too
    assert reports["instanced"]["volume_zfail"]["params"]["skipped_open_meshes"] == [
        "Floor (instanced by Set)", "Floor (instanced by Set.001)"]         # and missed (open): documented
    np.testing.assert_array_equal(masks["instanced"]["raytraced"], masks["real"]["raytraced"])
    np.testing.assert_array_equal(masks["instanced"]["volume_zfail"], masks["real"]["volume_zfail"])


def test_objects_without_shadow_visibility_cast_in_no_method(tmp_path):
    """Object > Visibility > Ray Visibility > Shadow off (on the cylinder, and on a collection instance's empty,
    which Cycles applies to every copy it makes): Cycles' reference loses their shadows, and so do the planar,
    raster and Cycles shadow maps and both volume methods: each stays as close to the reference as when they
    cast, while the reference's shadowed area shrinks."""
    methods = "raytraced,planar,shadowmap,volume_zpass,volume_zfail"
    scene = _operator_scene("sun")
    instancer = next(o for o in scene.objects if o.instance_type == "COLLECTION")
    reports = {}
    for tag in ("casting", "not casting"):
        if tag == "not casting":
            scene.objects["Cylinder"].visible_shadow = False
            instancer.visible_shadow = False
        for source in ("raster", "cycles"):
            out = tmp_path / f"{tag} {source}"
            options = ShadowOptions(methods=methods if source == "raster" else "raytraced,shadowmap",
                                    resolution=64, shadowmap_size=1024)
            rep = shadows.compare(scene, "Lamp", out, options, depth_source=source)["methods"]
            reports[(tag, source)] = rep
    assert scene.objects["Cylinder"].visible_camera                 # the Cycles depth maps' change is undone
    for tag in ("casting", "not casting"):
        rep = reports[(tag, "raster")]
        assert rep["volume_zfail"]["error"] <= 0.002 and rep["volume_zpass"]["error"] <= 0.002, tag
        assert rep["shadowmap"]["error"] <= 0.005, tag
        assert rep["planar"]["error"] <= 0.02, tag
        assert reports[(tag, "cycles")]["shadowmap"]["error"] <= 0.005, tag
    ref = {tag: png.decode_png(((tmp_path / f"{tag} raster") / "raytraced_mask.png").read_bytes()) > 127
           for tag in ("casting", "not casting")}
    receivers = reports[("casting", "raster")]["raytraced"]["receiver_pixels"]
    assert (ref["not casting"] & ~ref["casting"]).sum() > 0.02 * receivers      # their shadows are gone
    assert not (ref["casting"] & ~ref["not casting"]).any()


def test_shadow_map_budget_on_this_machine_follows_the_raster(script, tmp_path):
    """On this machine's memory: the raster renders a sun map one texel wider than a Cycles render of it would
    be allowed (refused for depth_source="cycles" before any work); a point light's six 16384² faces next to
    a frame that leaves them 6 GiB short are refused by the script in one line, exit 2, nothing written."""
    from addon.core import budget
    from addon.core.shadow import depth_map
    memory = budget.memory_budget()
    frame = 32 * 32 * depth_map.BYTES_PER_PIXEL
    size = math.isqrt((memory - frame) // (depth_map.BYTES_PER_TEXEL_RENDER + depth_map.BYTES_PER_TEXEL_KEPT)) + 1
    if size > depth_map.MAX_SIZE:
        pytest.skip(f"{budget.format_bytes(memory)} usable: every shadow-map size fits a Cycles render too")
    with pytest.raises(InputError, match=f"shadow-map size {size} .* the largest shadow-map size that fits is"):
        shadows.compare_builtin("sphere", "sun", tmp_path / "c", ShadowOptions(
            methods="raytraced,shadowmap", resolution=32, shadowmap_size=size), depth_source="cycles")
    assert list(bpy.data.scenes) == [bpy.context.scene] and not (tmp_path / "c").exists()
    rep = shadows.compare_builtin("sphere", "sun", tmp_path / "r", ShadowOptions(
        methods="raytraced,shadowmap", resolution=32, shadowmap_size=size))
    assert rep["methods"]["shadowmap"]["params"]["size"] == size
    assert rep["methods"]["shadowmap"]["error"] <= 0.01
    faces = 6 * 16384 ** 2 * depth_map.BYTES_PER_TEXEL_KEPT
    short = max(memory - faces + (6 << 30), 64 * 64 * depth_map.BYTES_PER_PIXEL)    # frame: 6 GiB too much
    res = math.isqrt(short // depth_map.BYTES_PER_PIXEL)
    if res > depth_map.MAX_RESOLUTION:
        pytest.skip(f"{budget.format_bytes(memory)} usable: six 16384² faces fit next to any frame")
    r = script("shadows.py", "--scene", "sphere", "--light-type", "point", "--methods", "raytraced,shadowmap",
               "--resolution", res, "--shadowmap-size", 16384, "--out", tmp_path / "o")
    lines = [line for line in r.stderr.strip().splitlines() if not line.startswith("[")]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert (f"shadow-map size 16384 (6 maps from the raster depth source, {res}x{res} pixels) needs about"
            in lines[0] and "the largest shadow-map size that fits is" in lines[0]), lines[0]
    assert not (tmp_path / "o").exists()


def test_surfaces_are_what_the_render_draws_not_the_viewport():
    """Render visibility and render settings decide, as in Cycles: a collection disabled in viewports still
    renders, itself and through its instance, one disabled in renders does neither; an object disabled
    in viewports renders, one hidden for render does not; a Subdivision gives its render level. The raster
    depth map has the same sky texels as Cycles' Depth pass; a light nobody renders is refused."""
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 32
    bpy.ops.mesh.primitive_plane_add(size=10.0)
    for name, flag, x in (("No Viewport", "hide_viewport", -2.0), ("No Render", "hide_render", 2.0)):
        col = bpy.data.collections.new(name)
        scene.collection.children.link(col)
        bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 5.0, 0.4))
        cube = bpy.context.view_layer.objects.active
        cube.name = f"{name} Cube"
        for c in list(cube.users_collection):
            c.objects.unlink(cube)
        col.objects.link(cube)
        setattr(col, flag, True)
        bpy.ops.object.collection_instance_add(collection=name, location=(x, -5.0, 0.0))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.0, 0.4))
    sub = bpy.context.view_layer.objects.active
    sub.name = "Subdivided"
    bpy.ops.object.modifier_add(type="SUBSURF")                 # levels 1, render levels 2
    sub.hide_viewport = True
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(0.0, 1.5, 0.4))
    bpy.context.view_layer.objects.active.hide_render = True
    bpy.ops.object.camera_add(location=(0.0, -9.0, 9.0), rotation=(math.radians(45), 0.0, 0.0))
    scene.camera = bpy.context.view_layer.objects.active
    bpy.ops.object.light_add(type="SUN", rotation=(0.4, 0.3, 0.0))
    lamp = bpy.context.view_layer.objects.active
    with ShadowFrame(scene, lamp.name, 32) as s:
        tris = {x.name: len(x.tris) for x in s.surfaces}
        s.render_reference()
        (raster,), _ = s.depth_maps(64, "raster")
        (cycles,), _ = s.depth_maps(64, "cycles")
    assert tris == {"Plane": 2, "No Viewport Cube": 12, "No Viewport Cube (instanced by No Viewport)": 12,
                    "Subdivided": 6 * 16 * 2}
    sky = cycles.depth >= 0.5 * camera.SKY_DEPTH
    np.testing.assert_array_equal(raster.depth >= 0.5 * camera.SKY_DEPTH, sky)
    assert np.all(np.abs(raster.depth - cycles.depth)[~sky] <= 1e-5 * np.maximum(cycles.depth[~sky], 1.0))
    hidden = bpy.data.collections.new("Lights Off")
    scene.collection.children.link(hidden)
    hidden.objects.link(lamp)
    scene.collection.objects.unlink(lamp)
    hidden.hide_render = True
    with pytest.raises(InputError, match=f"light '{lamp.name}' is not rendered"):
        with ShadowFrame(scene, lamp.name, 32):
            pass
    assert list(bpy.data.scenes) == [scene]


def test_a_receiver_that_is_not_a_plane_is_named_in_a_warning():
    """24.14: a sphere was accepted as the planar receiver with no word; the plane's own floor gives none."""
    import warnings
    from addon.core.errors import ILWarning
    scene, s = _session("sphere", res=32)
    with s:
        s.render_reference()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _, _, floor = shadows.run_method(s, "planar", shadows.check_params({}))
            assert not [w for w in caught if issubclass(w.category, ILWarning)]
            _, _, sphere = shadows.run_method(s, "planar", shadows.check_params({"receiver": "Sphere"}))
    said = [str(w.message) for w in caught if issubclass(w.category, ILWarning)]
    assert len(said) == 1 and "'Sphere' is not planar" in said[0], said
    assert floor["off_plane"] == 0.0 and 0.9 < sphere["off_plane"] / 0.7 <= 2.0     # radius 0.7: up to 2 r off


def _open_scan_scene(tmp_path, floor_name="Floor"):
    """A scan-like open mesh (a sphere with its bottom cut off) over a plane, a sun and a camera, saved."""
    scene = shadow_scenes.build("sphere", "sun", (32, 32))
    for s in list(bpy.data.scenes):
        if s != scene:
            bpy.data.scenes.remove(s)
    sphere = scene.objects["Sphere"]
    me = sphere.data
    import bmesh
    bm = bmesh.new()
    bm.from_mesh(me)
    bmesh.ops.delete(bm, geom=[f for f in bm.faces if f.calc_center_median().z < -0.2], context="FACES")
    bm.to_mesh(me)
    bm.free()
    sphere.name = "Scan"
    scene.objects[scene["il_shadow_light"]].name = "Sun"
    scene.objects[scene["il_shadow_receiver"]].name = floor_name
    del scene["il_shadow_receiver"]
    blend = tmp_path / "scan.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    return blend, scene


def test_open_scans_skip_the_volume_methods_and_the_others_run(script, tmp_path):
    """25.1: shadows.py with its default methods on an open scan exited 2 after the reference ("shadow volumes
    need at least one closed mesh"): the volume methods are skipped and said why, every other method runs."""
    blend, _ = _open_scan_scene(tmp_path)
    r = script("shadows.py", blend, "--light", "Sun", "--resolution", "32", "--shadowmap-size", "64",
               "--methods", "raytraced,planar,shadowmap,volume_zpass,volume_zfail", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "o" / "shadows_report.json").read_text())
    assert set(report["skipped"]) == {"volume_zpass", "volume_zfail"}
    assert "Scan" in report["skipped"]["volume_zfail"] and "volume_zfail skipped" in r.stderr
    assert set(report["methods"]) == {"raytraced", "planar", "shadowmap"}
    assert report["methods"]["planar"]["error"] < 0.05 and report["methods"]["shadowmap"]["error"] < 0.05
    assert "skipped: shadow volumes need" in r.stdout
    r = script("shadows.py", blend, "--light", "Sun", "--resolution", "32", "--methods", "volume_zfail",
               "--out", tmp_path / "v")
    assert r.returncode == 2 and "closed mesh" in r.stderr and not (tmp_path / "v").exists()


def test_the_planar_receiver_is_checked_before_the_reference_and_found_when_not_named(script, tmp_path):
    """25.1: a missing receiver was found only after the reference render; without a name and without a
    "Floor" the largest flat mesh receives, with a warning naming it."""
    blend, _ = _open_scan_scene(tmp_path, floor_name="Ground")
    t = __import__("time").perf_counter()
    r = script("shadows.py", blend, "--light", "Sun", "--resolution", "32", "--methods", "raytraced,planar",
               "--receiver", "Floor", "--out", tmp_path / "o")
    assert r.returncode == 2 and "no mesh named 'Floor'" in r.stderr and "'Ground'" in r.stderr, r.stderr
    assert "reference" not in r.stderr                    # refused before the ray-traced reference
    r = script("shadows.py", blend, "--light", "Sun", "--resolution", "32", "--methods", "raytraced,planar",
               "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert "planar shadows use 'Ground', the largest flat mesh" in r.stderr
    report = json.loads((tmp_path / "o" / "shadows_report.json").read_text())
    assert report["methods"]["planar"]["params"]["receiver"] == "Ground"
