"""Level bakes: many objects per Cycles call (batches), resume, shards, failures (issue 13)."""
import bpy
import numpy as np
import pytest

from addon.bake import BakeOptions, bake_lightmaps
from addon.bake import pipeline
from addon.core.io import exr


def small_level():
    """A floor under a light with props as users add them: a smooth UV sphere, a subdivided Suzanne, a rotated and
    scaled cube, a linked duplicate of the sphere and a mirrored (negative scale) cylinder."""
    bpy.ops.mesh.primitive_plane_add(size=6)
    floor = bpy.context.object
    floor.name = "Floor"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(-1.5, 0, 0.5), segments=16, ring_count=8)
    bpy.ops.object.shade_smooth()
    sphere = bpy.context.object
    bpy.ops.mesh.primitive_monkey_add(size=1, location=(1.2, 0.5, 0.6))
    monkey = bpy.context.object
    mod = monkey.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 1
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0, -1.5, 0.4), rotation=(0.3, 0.2, 0.7), scale=(1, 1.5, 0.8))
    cube = bpy.context.object
    twin = sphere.copy()
    twin.location = (-1.5, 1.4, 0.5)
    bpy.context.scene.collection.objects.link(twin)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.3, depth=0.8, location=(1.5, -1.2, 0.4), vertices=12)
    mirrored = bpy.context.object
    mirrored.scale = (-1, 1, 1)
    grey = bpy.data.materials.new("Grey")
    for o in (floor, sphere, monkey, cube, mirrored):
        o.data.materials.append(grey)
    bpy.ops.object.light_add(type="POINT", location=(0, 0, 3))
    bpy.context.object.data.energy = 300
    return [floor, sphere, monkey, cube, twin, mirrored]


def maps(folder, objects, kinds):
    return {(o.name, k): exr.read_exr(str(folder / f"{o.name}_{k}.exr"))[0] for o in objects for k in kinds}


def test_batched_bake_gives_the_per_object_images(tmp_path, monkeypatch):
    """One Cycles call per map kind (the mirrored cylinder alone: a joined copy would flip its winding) gives
    the images of one call per object: AO bit for bit (Cycles seeds a sample by its pixel), irradiance within the
    float rounding of world-space vertices (relative 1e-2 per texel, 1e-4 on the mean), same covered texels."""
    objects = small_level()
    calls = []
    real = pipeline._call_bake
    monkeypatch.setattr(pipeline, "_call_bake", lambda *a, **k: calls.append([o.name for o in a[1]]) or real(*a, **k))
    kinds = ["ao", "irradiance"]
    opts = dict(texel_density=12, samples=8, bounces=2, keep_products=False)
    bake_lightmaps(objects, kinds, str(tmp_path / "one"), BakeOptions(batch=False, **opts))
    assert len(calls) == 6 * 3                           # AO once, irradiance two halves, per object
    calls.clear()
    bake_lightmaps(objects, kinds, str(tmp_path / "batch"), BakeOptions(**opts))
    proxies = [c for c in calls if c[0] == pipeline.PROXY]
    assert len(proxies) == 3 and len(calls) == 6         # batch: AO once, irradiance twice; the cylinder alone
    assert [c[0] for c in calls if c[0] != pipeline.PROXY] == ["Cylinder"] * 3
    one, batch = maps(tmp_path / "one", objects, kinds), maps(tmp_path / "batch", objects, kinds)
    for (name, kind), a in one.items():
        b = batch[(name, kind)]
        mask = a["A"] > 0.5
        assert np.array_equal(mask, b["A"] > 0.5), name
        assert mask.sum() > 50
        if kind == "ao":
            assert np.array_equal(a["Y"], b["Y"]), name
        else:
            for c in "RGB":
                x, y = a[c][mask], b[c][mask]
                assert abs(x.mean() - y.mean()) <= 1e-4 * x.mean(), (name, c)
                assert np.all(np.abs(x - y) <= 1e-2 * np.maximum(x, 1e-3)), (name, c)
    assert bpy.data.objects.get(pipeline.PROXY) is None and bpy.data.meshes.get(pipeline.PROXY) is None
    assert all(not o.hide_render for o in objects)


def test_irradiance_does_not_depend_on_bake_order(tmp_path):
    """Each object's bounce light comes from the same materials whichever object was baked first."""
    objects = small_level()[:4]
    opts = BakeOptions(texel_density=10, samples=8, bounces=2, keep_products=False, batch=False)
    bake_lightmaps(objects, ["irradiance"], str(tmp_path / "fwd"), opts)
    bake_lightmaps(objects[::-1], ["irradiance"], str(tmp_path / "rev"), opts)
    for o in objects:
        a = exr.read_exr(str(tmp_path / "fwd" / f"{o.name}_irradiance.exr"))[0]
        b = exr.read_exr(str(tmp_path / "rev" / f"{o.name}_irradiance.exr"))[0]
        assert all(np.array_equal(a[c], b[c]) for c in "RGBA"), o.name
