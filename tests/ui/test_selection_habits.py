"""Selection habits of "Assign Shading Model": everything selected (A) shades the meshes and names what it
skipped, as Blender's own operators do; it refuses only when nothing applicable is selected."""
import bpy
import pytest

from addon.nodes import material


def users_scene():
    """Objects as a user adds them: the operators of the Add menu."""
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 0))
    bpy.ops.mesh.primitive_uv_sphere_add(location=(3, 0, 0))
    bpy.ops.mesh.primitive_circle_add(fill_type="NOTHING", location=(-3, 0, 0))
    bpy.ops.object.camera_add(location=(0, -8, 2))
    bpy.ops.object.light_add(type="POINT", location=(2, -2, 4))
    bpy.ops.curve.primitive_bezier_curve_add(location=(0, 3, 0))
    bpy.ops.object.text_add(location=(0, 5, 0))
    return {o.name: o for o in bpy.context.scene.objects}


def select(objs):
    for o in bpy.context.view_layer.objects:
        o.select_set(o in objs)


@pytest.mark.both_versions
def test_everything_selected_shades_the_meshes_and_names_the_rest(capfd):
    objs = users_scene()
    bpy.ops.object.select_all(action="SELECT")
    assert bpy.ops.illumination.assign_shading_model(model="BLINN_PHONG") == {"FINISHED"}
    out = capfd.readouterr()
    text = out.out + out.err
    for name in ("Cube", "Sphere"):
        mat = objs[name].active_material
        assert mat is not None and mat.get("il_model") == "BLINN_PHONG", name
        assert list(mat["il_light_names"]) == ["Point"]
    warning = next((ln for ln in text.splitlines() if ln.startswith("Warning") and "skipped" in ln), "")
    for name in ("Camera", "BézierCurve", "Text", "Circle"):
        assert name in warning, f"{name} not named in {warning!r}"
    assert "Point" not in warning                      # a selected light is a light source, not skipped
    for name in ("Circle", "BézierCurve", "Text"):
        assert objs[name].active_material is None or not objs[name].active_material.get("il_model")


@pytest.mark.both_versions
def test_skipped_objects_are_grouped_by_reason():
    objs = users_scene()
    mat, warnings = material.assign_shading_model(bpy.context.scene, list(objs.values()), "PHONG")
    skipped = [w for w in warnings if w.startswith("skipped")]
    assert len(skipped) == 1
    parts = set(skipped[0][len("skipped "):].split("; "))
    assert parts == {"Camera, BézierCurve, Text: not meshes", "Circle: a mesh without faces"}, skipped
    assert objs["Cube"].active_material == mat and objs["Sphere"].active_material == mat


@pytest.mark.both_versions
def test_nothing_applicable_is_refused_and_nothing_changes():
    objs = users_scene()
    select([objs["Camera"], objs["Point"], objs["Circle"]])
    mats = set(bpy.data.materials)
    with pytest.raises(RuntimeError, match=r"nothing to shade") as refused:
        bpy.ops.illumination.assign_shading_model(model="PHONG")
    assert "Camera: not a mesh" in str(refused.value) and "Circle: a mesh without faces" in str(refused.value)
    assert set(bpy.data.materials) == mats
    select([])
    with pytest.raises(RuntimeError, match="nothing to shade.*nothing is selected"):
        bpy.ops.illumination.assign_shading_model(model="PHONG")


def test_a_library_linked_mesh_is_skipped_with_its_library_named(tmp_path):
    bpy.ops.mesh.primitive_monkey_add()
    bpy.context.object.name = "Lib Monkey"
    lib = tmp_path / "lib.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(lib))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.object
    with bpy.data.libraries.load(str(lib), link=True) as (src, dst):
        dst.objects = ["Lib Monkey"]
    linked = dst.objects[0]
    bpy.context.scene.collection.objects.link(linked)
    mat, warnings = material.assign_shading_model(bpy.context.scene, [cube, linked], "OREN_NAYAR")
    assert cube.active_material == mat
    assert "skipped Lib Monkey: linked from lib.blend, not editable here" in warnings
    assert linked.active_material is None or not linked.active_material.get("il_model")
