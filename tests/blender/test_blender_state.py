"""blender.state.SavedState: what a job touches comes back, also after an error or Ctrl-C (the bake's own
checks are in test_bake_state.py)."""
import bpy
import pytest

from addon.blender import compat, render
from addon.blender import scene as sc
from addon.blender.state import SavedState
from addon.lab import ssao as lab
from addon.lab.options import SSAOOptions
from addon.lab.ssao import scenes as ssao_scenes


def _interrupt_render(monkeypatch, n):
    """Ctrl-C in the ``n``-th render_layers call; returns the list of the engines rendered with."""
    renders = []
    real = render.render_layers

    def interrupted(scene_, camera=None):
        renders.append(scene_.render.engine)
        if len(renders) == n:
            raise KeyboardInterrupt
        return real(scene_, camera)

    monkeypatch.setattr(render, "render_layers", interrupted)
    return renders


def _user_scene():
    scene = sc.new_scene("User", (40, 30))
    a, b = sc.plane(scene, "A", 1.0), sc.plane(scene, "B", 1.0, location=(2, 0, 0))
    vl = scene.view_layers[0]
    a.select_set(True, view_layer=vl)
    vl.objects.active = b
    return scene, a, b


def test_settings_world_and_selection_come_back_after_an_error():
    scene, a, b = _user_scene()
    im, cy, vl = scene.render.image_settings, scene.cycles, scene.view_layers[0]
    compat.set_png(im, "RGB", "16")
    cy.samples, cy.use_denoising, cy.filter_width = 7, True, 2.5
    worlds = set(bpy.data.worlds)
    assert scene.world is None
    with pytest.raises(RuntimeError, match="boom"):
        with SavedState(scene, settings=render.settings(scene) + render.output_settings(scene)) as state:
            world = state.world(sc.black_world)
            assert scene.world == world and state.world(sc.black_world) == world      # made once
            compat.set_multilayer_exr(im)
            render.cycles_cpu(scene, 1, seed=3, pixel_filter=0.01, clamp=0.0)
            a.select_set(False, view_layer=vl)
            b.select_set(True, view_layer=vl)
            vl.objects.active = a
            raise RuntimeError("boom")
    assert (im.file_format, im.color_mode, im.color_depth) == ("PNG", "RGB", "16")
    if compat.IS_5:
        assert im.media_type == "IMAGE"
    assert (cy.samples, cy.seed, cy.use_denoising, cy.filter_width) == (7, 0, True, 2.5)
    assert cy.sample_clamp_indirect == pytest.approx(10.0)
    assert scene.world is None and set(bpy.data.worlds) == worlds
    assert a.select_get(view_layer=vl) and not b.select_get(view_layer=vl) and vl.objects.active == b
    sc.remove_scene(scene)


def test_every_tracked_temporary_goes_in_one_pass_and_the_users_data_and_links_stay():
    """Materials, images, a mesh and its object, a scene, and one removed already (a proxy): all gone; the user's
    material that a temporary image was shown in keeps its node (emptied), the user's objects and scene stay."""
    scene, a, b = _user_scene()
    mine = bpy.data.materials.new("Mine")
    a.data.materials.append(mine)
    compat.ensure_use_nodes(mine)
    node = mine.node_tree.nodes.new("ShaderNodeTexImage")
    before = {c: set(getattr(bpy.data, c)) for c in ("materials", "images", "meshes", "objects", "scenes")}
    with SavedState(scene, [a, b]) as state:
        mats = [state.track(bpy.data.materials, bpy.data.materials.new(f"IL t {i}")) for i in range(40)]
        imgs = [state.track(bpy.data.images, bpy.data.images.new(f"IL t {i}", 4, 4)) for i in range(40)]
        node.image = imgs[0]
        a.material_slots[0].material = mats[0]
        me = state.track(bpy.data.meshes, bpy.data.meshes.new("IL t"))
        ob = state.track(bpy.data.objects, bpy.data.objects.new("IL t", me))
        scene.collection.objects.link(ob)
        gone = state.track(bpy.data.meshes, bpy.data.meshes.new("IL gone"))
        bpy.data.meshes.remove(gone)
        scratch = state.track(bpy.data.scenes, bpy.data.scenes.new("IL scratch"))
        scratch.collection.objects.link(ob)
    assert {c: set(getattr(bpy.data, c)) for c in before} == before
    assert node.image is None and a.material_slots[0].material == mine
    assert sorted(o.name for o in scene.objects) == ["A", "B"]
    sc.remove_scene(scene)
    bpy.data.materials.remove(mine)


def test_an_existing_world_is_used_and_kept():
    scene, _, _ = _user_scene()
    mine = sc.world(scene, strength=0.5, ao_distance=3.0)
    with SavedState(scene, settings=[(scene, "world"), (mine.light_settings, "distance")]) as state:
        assert state.world(sc.black_world) == mine
        mine.light_settings.distance = 1.0
    assert scene.world == mine and mine.name in bpy.data.worlds
    assert mine.light_settings.distance == pytest.approx(3.0)
    sc.remove_scene(scene)


def test_ssao_lab_interrupted_in_workbench_leaves_every_setting_and_adds_no_world(monkeypatch):
    """The lab renders the G-buffer, the Cycles reference, then Workbench; Ctrl-C in the Workbench render
    finds Cycles, EEVEE, passes, display, output and world settings all changed and must undo them all."""
    scene = ssao_scenes.build_scene("plane", 24, 1.0)
    world = scene.world
    scene.world = None
    bpy.data.worlds.remove(world)
    r, cy, vl, d, im = scene.render, scene.cycles, scene.view_layers[0], scene.display, scene.render.image_settings
    r.engine = compat.EEVEE
    r.film_transparent, r.filter_size, r.filepath, r.use_file_extension = False, 2.0, "//mine_", True
    r.resolution_x, r.resolution_y, r.resolution_percentage = 60, 40, 50
    compat.set_png(im, "RGB", "16")
    cy.samples, cy.seed, cy.filter_width, cy.max_bounces = 7, 5, 2.5, 9
    cy.use_denoising, cy.use_adaptive_sampling = True, True
    scene.eevee.taa_render_samples = 3
    vl.use_pass_z, vl.use_pass_normal, vl.use_pass_position, vl.use_pass_ambient_occlusion = True, False, True, False
    d.shading.light, d.shading.color_type, d.shading.show_cavity = "MATCAP", "OBJECT", False
    d.matcap_ssao_distance, d.render_aa = 0.7, "FXAA"
    worlds = set(bpy.data.worlds)

    renders = _interrupt_render(monkeypatch, 3)
    with pytest.raises(KeyboardInterrupt):
        lab.compare(scene, None, SSAOOptions(methods=["workbench"], samples=4, radius=1.0, reference_samples=8,
                                             resolution=24))
    assert renders == [compat.CYCLES, compat.CYCLES, compat.WORKBENCH]
    assert r.engine == compat.EEVEE
    assert (r.film_transparent, r.filter_size, r.filepath, r.use_file_extension) == (False, 2.0, "//mine_", True)
    assert (r.resolution_x, r.resolution_y, r.resolution_percentage) == (60, 40, 50)
    assert (im.file_format, im.color_mode, im.color_depth) == ("PNG", "RGB", "16")
    assert (cy.samples, cy.seed, cy.filter_width, cy.max_bounces) == (7, 5, 2.5, 9)
    assert cy.use_denoising and cy.use_adaptive_sampling and scene.eevee.taa_render_samples == 3
    assert (vl.use_pass_z, vl.use_pass_normal, vl.use_pass_position, vl.use_pass_ambient_occlusion) == \
        (True, False, True, False)
    assert (d.shading.light, d.shading.color_type, d.shading.show_cavity) == ("MATCAP", "OBJECT", False)
    assert d.matcap_ssao_distance == pytest.approx(0.7) and d.render_aa == "FXAA"
    assert scene.world is None and set(bpy.data.worlds) == worlds
    sc.remove_scene(scene)


def test_ssao_lab_interrupted_in_the_reference_keeps_the_users_world_and_its_ao_distance(monkeypatch):
    scene = ssao_scenes.build_scene("plane", 24, 1.0)
    world = scene.world
    world.light_settings.distance = 4.0
    worlds = set(bpy.data.worlds)
    renders = _interrupt_render(monkeypatch, 2)
    with pytest.raises(KeyboardInterrupt):
        lab.compare(scene, None, SSAOOptions(methods=["gtao"], resolution=24, reference_samples=8, radius=0.5))
    assert len(renders) == 2 and world.light_settings.distance == pytest.approx(4.0)
    assert scene.world == world and set(bpy.data.worlds) == worlds
    sc.remove_scene(scene)
