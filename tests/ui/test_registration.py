"""Registration: classes in order, nothing left behind, enable/disable/enable works."""
import bpy
import pytest

import addon
from addon.nodes import material

pytestmark = pytest.mark.both_versions

OPERATORS = ("build_demo_scene",)
PANELS = ("IL_PT_main", "IL_PT_shading", "IL_PT_lightmaps", "IL_PT_envmap", "IL_PT_comparisons", "IL_PT_shadows",
          "IL_PT_ssao", "IL_PT_reflections", "IL_PT_raytrace")


def _registered_panels():
    return {name for name in PANELS if hasattr(bpy.types, name)}


def test_settings_group_and_sections(addon_registered):
    s = bpy.context.scene.illumination
    for section in ("shading", "lightmaps", "shadows", "ssao", "reflections", "raytrace"):
        assert getattr(s, section) is not None
    assert _registered_panels() == set(PANELS)
    assert bpy.types.IL_PT_main.bl_category == "Illumination"
    assert bpy.types.IL_PT_main.bl_space_type == "VIEW_3D"
    parents = {p: getattr(bpy.types, p).bl_parent_id for p in PANELS[1:]}
    assert parents == {"IL_PT_shading": "IL_PT_main", "IL_PT_lightmaps": "IL_PT_main",
                       "IL_PT_envmap": "IL_PT_main", "IL_PT_comparisons": "IL_PT_main", "IL_PT_shadows": "IL_PT_comparisons",
                       "IL_PT_ssao": "IL_PT_comparisons", "IL_PT_reflections": "IL_PT_comparisons",
                       "IL_PT_raytrace": "IL_PT_comparisons"}


def test_unregister_leaves_nothing_and_register_again_works(addon_registered):
    addon.unregister()
    try:
        assert not hasattr(bpy.types.Scene, "illumination")
        assert _registered_panels() == set()
        for op in OPERATORS:
            assert not hasattr(bpy.types, f"ILLUMINATION_OT_{op}")
        leftovers = [c for c in dir(bpy.types) if c.startswith(("IL_", "ILLUMINATION_"))]
        assert leftovers == []
        handlers = [fn for name in ("depsgraph_update_post", "render_pre", "load_post")
                    for fn in getattr(bpy.app.handlers, name) if fn.__module__.startswith("addon.")]
        assert handlers == []
    finally:
        addon.register()
    assert _registered_panels() == set(PANELS)
    assert material.on_depsgraph_update in bpy.app.handlers.depsgraph_update_post
    assert bpy.context.scene.illumination is not None


def test_demo_operator_builds_a_new_scene_and_keeps_the_users(addon_registered):
    user_scene = bpy.context.scene
    user_scene.name = "Mine"
    assert bpy.ops.illumination.build_demo_scene.poll()
    assert bpy.ops.illumination.build_demo_scene() == {"FINISHED"}
    demo = bpy.data.scenes["IL Demo"]
    assert {"Floor", "Box", "Sphere", "Torus", "Sun", "Key", "Camera"} <= set(demo.objects.keys())
    assert "Mine" in bpy.data.scenes and len(bpy.data.scenes["Mine"].objects) == 0


def test_a_second_demo_scene_finds_its_own_objects(addon_registered):
    from addon.lab.demo import scene as demo
    first, second = demo.build_demo_scene(), demo.build_demo_scene()
    for role in demo.ROLES:
        a, b = demo.get(first, role), demo.get(second, role)
        assert a != b and a.name in first.objects and b.name in second.objects
    assert demo.get(second, "Torus").name == "Torus.001"
