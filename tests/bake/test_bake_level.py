"""Level bakes: many objects per Cycles call (batches), resume, shards, failures (issue 13)."""
import os
import subprocess
import sys
import time

import bpy
import numpy as np
import pytest

from addon.bake import BakeOptions, bake_lightmaps
from addon.bake import batch as batching, cycles, report as reporting, write
from addon.core.errors import ILError
from addon.core.io import exr
from tests.conftest import ROOT


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
    the images of one call per object: AO bit for bit (Cycles seeds a sample by its pixel), same covered texels,
    irradiance the same estimate: its mean within 1e-4, and texel by texel no farther apart than two independent
    bakes would be. The joined copy's world-space vertices round differently from Cycles' own transforms (4.5:
    bit for bit with direct light; 5.2 and 5.3: 3e-5 apart), and through two bounces a path grazing an edge can
    take another branch (one Floor texel 4 % apart): the RMS of the difference stays within that of two
    independent bakes, sqrt(e1² + e2²) from each map's measured error, with 3 standard errors of that estimate
    (1/sqrt(2 M) relative over M texel channels) on top."""
    objects = small_level()
    calls = []
    real = cycles.call_bake
    monkeypatch.setattr(cycles, "call_bake", lambda *a, **k: calls.append([o.name for o in a[1]]) or real(*a, **k))
    kinds = ["ao", "irradiance"]
    opts = dict(texel_density=12, samples=8, bounces=2, keep_products=False)
    reports = [bake_lightmaps(objects, kinds, str(tmp_path / "one"), BakeOptions(batch=False, **opts))]
    assert len(calls) == 6 * 3                           # AO once, irradiance two halves, per object
    calls.clear()
    reports.append(bake_lightmaps(objects, kinds, str(tmp_path / "batch"), BakeOptions(**opts)))
    proxies = [c for c in calls if c[0] == batching.PROXY]
    assert len(proxies) == 3 and len(calls) == 6         # batch: AO once, irradiance twice; the cylinder alone
    assert [c[0] for c in calls if c[0] != batching.PROXY] == ["Cylinder"] * 3
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
            x, y = (np.stack([m[c][mask] for c in "RGB"]) for m in (a, b))
            e1, e2 = (r["objects"][name][kind]["estimated_error"] for r in reports)
            bound = np.hypot(e1, e2) * (1 + 3 / np.sqrt(2 * x.size))
            assert np.sqrt(np.mean((x - y) ** 2)) <= bound, (name, np.sqrt(np.mean((x - y) ** 2)), bound)
    assert bpy.data.objects.get(batching.PROXY) is None and bpy.data.meshes.get(batching.PROXY) is None
    assert all(not o.hide_render for o in objects)


def _batch_bakes_as_single_calls(objects, batched, tmp_path, monkeypatch):
    """AO of ``objects`` at 32², 8 spp, by one call per object and with the names ``batched`` in one batch (the others
    alone): equal bit for bit, each map with more than 100 covered texels; returns the per-object maps by (object
    name, "ao")."""
    opts = dict(resolution=32, samples=8, keep_products=False)
    bake_lightmaps(objects, ["ao"], str(tmp_path / "one"), BakeOptions(batch=False, **opts))
    seen, real = [], batching.bake_batch

    def counting(scene, batch, *args):
        seen.append({t.name for t in batch})
        return real(scene, batch, *args)
    monkeypatch.setattr(batching, "bake_batch", counting)
    bake_lightmaps(objects, ["ao"], str(tmp_path / "batch"), BakeOptions(**opts))
    assert seen == [set(batched)]
    one, batch = maps(tmp_path / "one", objects, ["ao"]), maps(tmp_path / "batch", objects, ["ao"])
    for key, a in one.items():
        assert (a["A"] > 0.5).sum() > 100 and np.array_equal(a["Y"], batch[key]["Y"]), key
    return one


@pytest.mark.both_versions
def test_a_batch_bakes_the_meshes_a_render_evaluates(tmp_path, monkeypatch):
    """Cycles bakes through its own render evaluation of the scene, the batch's joined mesh and the checks read the
    viewport's: for the bake the viewport takes the render's settings (cycles.render_variants). A Subdivision of 0
    levels in the viewport and 3 in renders, and a Bevel on only for renders, give the images of one call per object
    (AO bit for bit; before, the batch baked the unsubdivided cube: 0.09 apart on average); the user's settings come
    back."""
    bpy.ops.mesh.primitive_plane_add(size=4)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.7))
    blob = bpy.context.object
    sub = blob.modifiers.new("Subdivision", "SUBSURF")
    sub.levels, sub.render_levels = 0, 3
    bpy.ops.mesh.primitive_cube_add(size=1, location=(1.3, 0, 0.7))
    box = bpy.context.object
    bevel = box.modifiers.new("Bevel", "BEVEL")
    bevel.width, bevel.segments, bevel.show_viewport = 0.2, 3, False
    _batch_bakes_as_single_calls([floor, blob, box], [floor.name, blob.name, box.name], tmp_path, monkeypatch)
    assert (sub.levels, sub.render_levels, bevel.show_viewport, bevel.show_render) == (0, 3, False, True)


def _tilt_custom_normals(obj, dx):
    """Give ``obj`` custom normals: its own corner normals tilted by ``dx`` along x, as an importer gives them."""
    me = obj.data
    n = np.zeros(len(me.loops) * 3, np.float32)
    me.corner_normals.foreach_get("vector", n)
    n = n.reshape(-1, 3)
    n[:, 0] += dx
    me.normals_split_custom_set(n / np.linalg.norm(n, axis=1)[:, None])


@pytest.mark.both_versions
def test_meshes_with_custom_normals_are_batched_with_their_normals(tmp_path, monkeypatch):
    """glTF and OBJ importers give meshes custom normals; the batch's joined mesh carries them (in world space, by
    the inverse transpose of a rotated and non-uniformly scaled cube's matrix), so such meshes share the batch's
    Cycles calls: AO bit for bit as one call per object, direct irradiance (no bounces) within 1e-3 of it (the
    joined copy's normals are encoded again in its own normal spaces), and the normals count: the cube tilted 27
    degrees gets an irradiance 1 % or more away from the same cube without them, far beyond that. (With bounces a
    path may turn on a normal's last bit: at 8 spp one texel of the sphere, its grid cut in 4 pieces, took 0.66
    alone and 0.89 in the batch, a different texel in each process; with no bounces every run agrees to 3e-4.)"""
    bpy.ops.mesh.primitive_plane_add(size=4)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.7), rotation=(0.3, 0.2, 0.5), scale=(1, 1.4, 0.8))
    cube = bpy.context.object
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(1.3, 0, 0.6), segments=16, ring_count=8)
    bpy.ops.object.shade_smooth()
    sphere = bpy.context.object
    plain = cube.data.copy()
    for o in (cube, sphere):
        _tilt_custom_normals(o, 0.5)
    bpy.ops.object.light_add(type="POINT", location=(0, 0, 3))
    bpy.context.object.data.energy = 300
    objects = [floor, cube, sphere]
    _batch_bakes_as_single_calls(objects, [o.name for o in objects], tmp_path, monkeypatch)
    opts = dict(resolution=32, samples=8, bounces=0, keep_products=False, force=True, overwrite=True)
    folders = {}
    for label, batch in (("one", False), ("batch", True)):
        bake_lightmaps(objects, ["irradiance"], str(tmp_path / f"e_{label}"), BakeOptions(batch=batch, **opts))
        folders[label] = maps(tmp_path / f"e_{label}", objects, ["irradiance"])
    cube.data = plain
    bake_lightmaps([cube], ["irradiance"], str(tmp_path / "e_plain"), BakeOptions(batch=False, **opts))
    without = maps(tmp_path / "e_plain", [cube], ["irradiance"])[(cube.name, "irradiance")]
    for key, a in folders["one"].items():
        b = folders["batch"][key]
        mask = a["A"] > 0.5
        assert np.array_equal(mask, b["A"] > 0.5) and mask.sum() > 100, key
        assert np.abs(a["R"][mask] - b["R"][mask]).max() <= 1e-3 * a["R"][mask].mean(), key
    tilted = folders["one"][(cube.name, "irradiance")]
    assert abs(tilted["R"][tilted["A"] > 0.5].mean() / without["R"][without["A"] > 0.5].mean() - 1) > 0.01


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


def test_an_interrupted_bake_resumes_and_a_moved_object_alone_is_baked_again(tmp_path):
    """Ctrl-C after two maps, then the same bake with Overwrite bakes only the maps that were missing (the finished
    ones keep their files, byte for byte); moving one object re-bakes that object's maps only (the hash covers the
    object, its materials, the lights and the options, not the other objects); Force bakes everything."""
    objects = small_level()[:4]
    out = tmp_path / "maps"
    opts = BakeOptions(texel_density=8, samples=4, bounces=1)
    steps = []

    def stop_after_two(message):
        steps.append(message)
        if len([s for s in steps if ": ao" in s or ": irradiance" in s]) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts, on_step=stop_after_two)
    done = sorted(p.name for p in out.glob("*.exr"))
    assert len(done) == 2                                    # the third map was announced, not written
    before = {name: (out / name).read_bytes() for name in done}
    again = bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts.replace(overwrite=True))
    baked = {(o, m) for o, maps in again["objects"].items() for m in maps}
    skipped = {(o, m) for o, maps in again["unchanged"].items() for m in maps}
    assert len(baked) == 6 and len(skipped) == 2 and not baked & skipped
    assert {f"{o}_{m}.exr" for o, m in skipped} == set(done)
    assert all((out / name).read_bytes() == data for name, data in before.items())
    assert len(list(out.glob("*.exr"))) == 8
    assert "unchanged (skipped, inputs as baked) 2 map(s)" in again.summary
    objects[3].location.x += 0.25
    third = bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts.replace(overwrite=True))
    assert set(third["objects"]) == {objects[3].name} and len(third["unchanged"]) == 3
    fourth = bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts.replace(force=True))
    assert len(fourth["objects"]) == 4 and not fourth["unchanged"]
    bpy.data.lights[0].energy *= 2                            # lights change irradiance, not AO
    fifth = bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts.replace(overwrite=True))
    assert {m for maps in fifth["objects"].values() for m in maps} == {"irradiance"}
    assert all(maps == ["ao"] for maps in fifth["unchanged"].values()) and len(fifth["unchanged"]) == 4


def test_the_report_is_merged_now_and_then_and_holds_the_finished_maps_after_ctrl_c(tmp_path, monkeypatch):
    """Merging the whole report after every map made a level's run quadratic in its objects: finished maps are
    merged at most every MERGE_EVERY seconds (the first at once) and when the bakes end, and also when they stop
    (Ctrl-C after three maps: the report lists exactly the three map files on disk; Ctrl-C inside a merge: the maps
    it was merging are merged when the run stops)."""
    from addon.bake import pipeline
    objects = small_level()[:4]
    opts = BakeOptions(texel_density=8, samples=2, bounces=1)
    monkeypatch.setattr(pipeline, "MERGE_EVERY", 1e9)
    merges, real = [], pipeline.merge_report
    monkeypatch.setattr(pipeline, "merge_report", lambda path, part: (merges.append(len(part["objects"])),
                                                                      real(path, part))[1])
    whole = bake_lightmaps(objects, ["ao", "irradiance"], str(tmp_path / "whole"), opts)
    assert merges == [1, 4]
    on_disk = report_of(tmp_path / "whole")["objects"]
    assert {(o, m): e["resolution"] for o, ms in on_disk.items() for m, e in ms.items()} == {
        (o, m): list(e["resolution"]) for o, ms in whole["objects"].items() for m, e in ms.items()}
    assert len(on_disk) == 4 and all(len(ms) == 2 for ms in on_disk.values())
    steps = []

    def stop_at_the_fourth(message):
        steps.append(message)
        if len([s for s in steps if ": ao" in s or ": irradiance" in s]) == 4:
            raise KeyboardInterrupt

    out = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts, on_step=stop_at_the_fourth)
    listed = {os.path.basename(e["file"]) for ms in report_of(out)["objects"].values() for e in ms.values()}
    assert len(listed) == 3 and listed == {p.name for p in out.glob("*.exr")}
    calls = []

    def interrupted(path, part):                     # Ctrl-C inside the merge after the first map
        calls.append(len(part["objects"]))
        if len(calls) == 1:
            raise KeyboardInterrupt
        real(path, part)

    monkeypatch.setattr(pipeline, "merge_report", interrupted)
    out = tmp_path / "stopped in the merge"
    with pytest.raises(KeyboardInterrupt):
        bake_lightmaps(objects, ["ao", "irradiance"], str(out), opts)
    assert calls == [1, 1] and [p.name for p in out.glob("*.exr")] == [
        os.path.basename(e["file"]) for ms in report_of(out)["objects"].values() for e in ms.values()]


def test_two_shards_merged_give_the_files_of_one_run(tmp_path):
    """Shards 1/2 and 2/2 bake disjoint shares (balanced by texels: the floor alone against the props) whose files
    are those of one run with the same seeds (AO bit for bit, irradiance within float rounding: the objects of the
    other shard are seen as themselves instead of the batch's world-space copy), and --merge joins the parts."""
    objects = small_level()[:5]
    opts = BakeOptions(texel_density=8, samples=4, bounces=1, keep_products=False)
    one = bake_lightmaps(objects, ["ao", "irradiance"], str(tmp_path / "one"), opts)
    parts = [bake_lightmaps(objects, ["ao", "irradiance"], str(tmp_path / "sharded"), opts.replace(shard=f"{k}/2"))
             for k in (1, 2)]
    names = [set(p["objects"]) for p in parts]
    assert names[0] and names[1] and not names[0] & names[1] and names[0] | names[1] == set(one["objects"])
    assert names[0] == {"Floor"}                              # 8² × 36 m² of floor against 5 small props
    assert not (tmp_path / "sharded" / "bake_report.json").exists()
    merged = reporting.merge_reports(str(tmp_path / "sharded"))
    assert set(merged["objects"]) == set(one["objects"]) and len(merged["shards"]) == 2
    a, b = maps(tmp_path / "one", objects, ["ao", "irradiance"]), maps(tmp_path / "sharded", objects,
                                                                         ["ao", "irradiance"])
    for key, x in a.items():
        y = b[key]
        mask = x["A"] > 0.5
        assert np.array_equal(mask, y["A"] > 0.5), key
        if key[1] == "ao":
            assert np.array_equal(x["Y"], y["Y"]), key
        else:
            assert abs(x["R"][mask].mean() - y["R"][mask].mean()) <= 1e-4 * x["R"][mask].mean(), key
            assert np.all(np.abs(x["R"] - y["R"])[mask] <= 1e-2 * np.maximum(x["R"][mask], 1e-3)), key


def test_script_jobs_run_shards_and_merge(tmp_path, script):
    small_level()[:3]
    blend = tmp_path / "level.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "maps"
    r = script("bake.py", blend, "--objects", "Floor", "Sphere", "Suzanne", "--maps", "ao", "--out", out,
               "--texel-density", "6", "--samples", "2", "--jobs", "2")
    assert r.returncode == 0, r.stderr
    report = __import__("json").loads((out / "bake_report.json").read_text())
    assert set(report["objects"]) == {"Floor", "Sphere", "Suzanne"} and len(report["shards"]) == 2
    assert sorted(p.name for p in out.glob("*.exr")) == ["Floor_ao.exr", "Sphere_ao.exr", "Suzanne_ao.exr"]
    r = script("bake.py", "--merge", tmp_path / "nothing")
    assert r.returncode == 2 and "no shard reports" in r.stderr


def test_a_broken_object_fails_alone_and_the_script_exits_1(tmp_path, script):
    """An invalid mesh among good ones: the others are baked, the report and the last line name it, exit code 1."""
    small_level()[:2]
    me = bpy.data.meshes.new("Broken")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0.5, 0.5, 0)], [], [(0, 1, 2), (0, 3, 3)])
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Broken", me))
    blend = tmp_path / "level.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "maps"
    r = script("bake.py", blend, "--objects", "Floor", "Broken", "Sphere", "--maps", "ao", "--out", out,
               "--texel-density", "6", "--samples", "2")
    assert r.returncode == 1
    last = r.stderr.strip().splitlines()[-1]
    assert "1 object(s) failed, the others are baked: Broken:" in last and "is invalid" in last
    assert sorted(p.name for p in out.glob("*.exr")) == ["Floor_ao.exr", "Sphere_ao.exr"]
    report = __import__("json").loads((out / "bake_report.json").read_text())
    assert set(report["objects"]) == {"Floor", "Sphere"} and "is invalid" in report["failed"]["Broken"]
    assert "objects 1/2, texels" in r.stderr and "ETA" in r.stderr        # one progress line per map


def test_a_map_that_fails_in_a_batch_leaves_the_others(tmp_path, monkeypatch):
    objects = small_level()[:4]
    real = write.check_covered

    def broken(name, *a):
        if name == "Sphere":
            raise ILError("'Sphere' ao: injected failure")
        return real(name, *a)

    monkeypatch.setattr(write, "check_covered", broken)
    result = bake_lightmaps(objects, ["ao"], str(tmp_path), BakeOptions(texel_density=6, samples=2))
    assert set(result["objects"]) == {"Floor", "Suzanne", "Cube"}
    assert result["failed"] == {"Sphere": "'Sphere' ao: injected failure"} and "FAILED 1" in result.summary
    assert not (tmp_path / "Sphere_ao.exr").exists() and (tmp_path / "Cube_ao.exr").exists()


def test_an_atlas_is_one_call_with_the_same_image(tmp_path, monkeypatch):
    objects = small_level()[:4]
    calls = []
    real = cycles.call_bake
    monkeypatch.setattr(cycles, "call_bake", lambda *a, **k: calls.append(len(a[1])) or real(*a, **k))
    opts = dict(texel_density=6, samples=4, atlas=True, keep_products=False)
    bake_lightmaps(objects, ["ao"], str(tmp_path / "one"), BakeOptions(batch=False, **opts))
    rep = bake_lightmaps(objects, ["ao"], str(tmp_path / "batch"), BakeOptions(**{**opts, "keep_products": True}))
    assert calls == [4, 1]                 # Blender's multi-object call (a scene sync per object), then the proxy
    a = exr.read_exr(str(tmp_path / "one" / "atlas_ao.exr"))[0]
    b = exr.read_exr(str(tmp_path / "batch" / "atlas_ao.exr"))[0]
    assert (a["A"] > 0).sum() > 500 and all(np.array_equal(a[c], b[c]) for c in "YA")
    # the atlas fills its map at least as well as Blender's uv.pack_islands re-packing the same charts
    from addon.lab.bench.level import pack_islands_utilisation
    entry = rep["objects"]["Floor"]["ao"]
    used = sum(rep["objects"][o.name]["ao"]["coverage"] for o in objects)
    assert used >= pack_islands_utilisation(objects, tuple(entry["resolution"]), entry["margin"]) - 0.005


# ------------------------------------------------------------------ reports of resumed and sharded bakes

def report_of(folder, name="bake_report.json"):
    return __import__("json").loads((folder / name).read_text())


def test_a_bake_killed_right_after_a_map_file_resumes_with_every_map_in_the_report(tmp_path, monkeypatch):
    """Killed right after Floor_irradiance.exr is written (no preview, no report entry: what a SIGKILL leaves), the
    rerun with Overwrite finds that map unchanged, writes its preview from the EXR and puts in the report its entry
    rebuilt from the header, the same as a run that was not killed; entries of the old report that agree with
    their files stay as they were. A deleted report is written again with every map, also when nothing is baked,
    and a deleted preview is written again."""
    objects = small_level()[:3]
    kinds = ["ao", "irradiance"]
    opts = BakeOptions(texel_density=6, samples=2, bounces=1, keep_products=False)
    whole = bake_lightmaps(objects, kinds, str(tmp_path / "whole"), opts)
    out = tmp_path / "maps"
    real = write.io_png.write_png

    def killed(path, pixels):
        if str(path).endswith("Floor_irradiance.png"):
            raise KeyboardInterrupt                         # stands for SIGKILL: nothing after the EXR runs
        real(path, pixels)

    monkeypatch.setattr(write.io_png, "write_png", killed)
    with pytest.raises(KeyboardInterrupt):
        bake_lightmaps(objects, kinds, str(out), opts)
    monkeypatch.undo()
    assert (out / "Floor_irradiance.exr").exists() and not (out / "Floor_irradiance.png").exists()
    before = report_of(out)
    assert "irradiance" not in before["objects"]["Floor"]
    again = bake_lightmaps(objects, kinds, str(out), opts.replace(overwrite=True))
    assert again["unchanged"]["Floor"] == ["ao", "irradiance"] and "Floor" not in again["objects"]
    report = report_of(out)
    assert {(o, m) for o, ms in report["objects"].items() for m in ms} == {(o.name, m) for o in objects for m in kinds}
    assert report["objects"]["Sphere"]["ao"] == before["objects"]["Sphere"]["ao"]       # agrees: kept as it was
    rebuilt, reference = report["objects"]["Floor"]["irradiance"], whole["objects"]["Floor"]["irradiance"]
    assert rebuilt["file"] == str(out / "Floor_irradiance.exr")
    assert rebuilt["preview"] == str(out / "Floor_irradiance.png")
    assert set(rebuilt) == set(reference)
    for key in ("resolution", "samples", "estimated_error", "error_estimate", "uv_layer", "coverage", "chart_area",
                "margin", "overlap", "denoised", "unwrap"):
        assert rebuilt[key] == reference[key], key
    assert rebuilt["cycles_seconds"] == rebuilt["seconds"] == 0          # not baked in this run; no timing in the file
    a = exr.read_exr(str(out / "Floor_irradiance.exr"))[0]
    b = exr.read_exr(str(tmp_path / "whole" / "Floor_irradiance.exr"))[0]
    assert all(np.array_equal(a[c], b[c]) for c in "RGBA")
    assert (out / "Floor_irradiance.png").read_bytes() == (tmp_path / "whole" / "Floor_irradiance.png").read_bytes()
    preview = (out / "Sphere_ao.png").read_bytes()
    (out / "Sphere_ao.png").unlink()
    (out / "bake_report.json").unlink()
    third = bake_lightmaps(objects, kinds, str(out), opts.replace(overwrite=True))
    assert not third["objects"] and sum(len(m) for m in third["unchanged"].values()) == 6
    written = report_of(out)
    assert written["objects"]["Floor"]["irradiance"] == rebuilt
    assert {(o, m) for o, ms in written["objects"].items() for m in ms} == {(o.name, m) for o in objects for m in kinds}
    for o in objects:
        for m in kinds:
            e, r = written["objects"][o.name][m], report["objects"][o.name][m]
            timing = ("seconds", "cycles_seconds")
            assert e["seconds"] == e["cycles_seconds"] == 0
            assert {k: v for k, v in e.items() if k not in timing} == {k: v for k, v in r.items() if k not in timing}
    assert (out / "Sphere_ao.png").read_bytes() == preview
    assert written["unchanged"] == third["unchanged"]


def test_shard_parts_are_written_when_nothing_is_baked_and_merge_joins_the_latest_split(tmp_path):
    """A share whose maps are all unchanged still writes its part (with their entries), and --merge joins the parts
    of the latest split only, naming the earlier split's parts in a warning."""
    from addon.core.errors import ILWarning
    objects = small_level()[:3]
    opts = BakeOptions(texel_density=6, samples=2, keep_products=False)
    for k in (1, 2, 3):
        bake_lightmaps(objects, ["ao"], str(tmp_path), opts.replace(shard=f"{k}/3"))
    for k in (1, 2):
        part = bake_lightmaps(objects, ["ao"], str(tmp_path), opts.replace(shard=f"{k}/2", overwrite=True))
        assert not part["objects"] and part["unchanged"]
        written = report_of(tmp_path, f"bake_report.shard-{k}-of-2.json")
        assert set(written["objects"]) == set(part["unchanged"])
    with pytest.warns(ILWarning, match=r"earlier split .*bake_report\.shard-1-of-3\.json"):
        merged = reporting.merge_reports(str(tmp_path))
    assert merged["shards"] == ["bake_report.shard-1-of-2.json", "bake_report.shard-2-of-2.json"]
    assert set(report_of(tmp_path)["objects"]) == {"Floor", "Sphere", "Suzanne"}
    assert sum(len(m) for m in merged["unchanged"].values()) == 3


def test_merge_keeps_the_entries_already_in_the_report(tmp_path):
    """A plain bake of the floor, then two shards of two props, then --merge: the floor's entry stays."""
    floor, sphere, _, cube = small_level()[:4]
    opts = BakeOptions(texel_density=6, samples=2, keep_products=False)
    plain = bake_lightmaps([floor], ["ao"], str(tmp_path), opts)
    for k in (1, 2):
        bake_lightmaps([sphere, cube], ["ao"], str(tmp_path), opts.replace(shard=f"{k}/2"))
    merged = reporting.merge_reports(str(tmp_path))
    report = report_of(tmp_path)
    assert set(merged["objects"]) == set(report["objects"]) == {"Floor", "Sphere", "Cube"}
    assert report["objects"]["Floor"]["ao"] == plain["objects"]["Floor"]["ao"]
    assert len(report["shards"]) == 2


def test_damaged_shard_parts_are_set_aside_and_the_rest_merged(tmp_path, script):
    """A truncated part, then a part that is a JSON list: each is named, moved aside as the report is, with a
    warning, and the other parts merged (the script exits 0)."""
    from addon.core.errors import ILWarning
    objects = small_level()[:2]
    bake_lightmaps(objects, ["ao"], str(tmp_path), BakeOptions(texel_density=6, samples=2, keep_products=False,
                                                               shard="1/2"))
    damaged = tmp_path / "bake_report.shard-2-of-2.json"
    damaged.write_text('{"objects": {"Sph')
    with pytest.warns(ILWarning, match=r"bake_report\.shard-2-of-2\.json could not be read .* kept as "
                                       r".*bake_report\.shard-2-of-2\.unreadable-1\.json"):
        merged = reporting.merge_reports(str(tmp_path))
    assert merged["shards"] == ["bake_report.shard-1-of-2.json"] and merged["objects"]
    assert (tmp_path / "bake_report.shard-2-of-2.unreadable-1.json").read_text() == '{"objects": {"Sph'
    damaged.write_text("[1, 2]")
    r = script("bake.py", "--merge", tmp_path)
    assert r.returncode == 0, r.stderr
    assert "bake_report.shard-2-of-2.json could not be read" in r.stderr and "unreadable-2.json" in r.stderr
    assert (tmp_path / "bake_report.shard-2-of-2.unreadable-2.json").read_text() == "[1, 2]"
    assert set(report_of(tmp_path)["objects"]) == set(merged["objects"]) and not damaged.exists()


@pytest.mark.parametrize("stage", ["first map", "first preview", "report"])
def test_a_real_sigkill_at_each_stage_resumes_to_a_complete_report(tmp_path, stage):
    """24.4 with a real SIGKILL of bake.py: as soon as the first map's EXR, its preview or the report exists, the
    process is killed (-9, nothing of it runs after); a rerun with --overwrite ends with every map on disk, each
    with its preview, and all of them in the report, the map that was finished kept (found unchanged)."""
    objects = small_level()[:3]
    blend = tmp_path / "level.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    out = tmp_path / "maps"
    args = [sys.executable, os.path.join(ROOT, "scripts", "bake.py"), str(blend), "--objects",
            *(o.name for o in objects), "--maps", "ao", "irradiance", "--texel-density", "6", "--samples", "2",
            "--out", str(out)]
    def done(pattern):
        return [f for f in out.glob(pattern) if not f.name.startswith(".")]

    watch = {"first map": lambda: done("*.exr"), "first preview": lambda: done("*.png"),
             "report": lambda: (out / "bake_report.json").exists()}[stage]
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not (out.exists() and watch()) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    p.kill()
    p.wait()
    finished = {f.name for f in done("*.exr")}
    assert finished, "killed before any map was written"
    for f in out.glob(".*.tmp*"):                          # the rerun comes later than files.STALE_AFTER
        os.utime(f, (time.time() - 600, time.time() - 600))
    r = subprocess.run(args + ["--overwrite"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    report = report_of(out)
    assert {(o, m) for o, ms in report["objects"].items() for m in ms} == {(o.name, m) for o in objects
                                                                           for m in ("ao", "irradiance")}
    for maps in report["objects"].values():
        for e in maps.values():
            assert os.path.isfile(e["file"]) and os.path.isfile(e["preview"]), e
    unchanged = {f"{o}_{m}.exr" for o, ms in report.get("unchanged", {}).items() for m in ms}
    assert finished <= unchanged, (finished, unchanged)
    assert not list(out.glob(".*.tmp*"))                   # what the killed run was writing is removed


def _viewport_switch(offset):
    """A Geometry Nodes group that moves its geometry by ``offset`` in renders only (Is Viewport, in a nested group)."""
    inner = bpy.data.node_groups.new("Is viewport inside", "GeometryNodeTree")
    inner.interface.new_socket("Viewport", in_out="OUTPUT", socket_type="NodeSocketBool")
    inner.links.new(inner.nodes.new("GeometryNodeIsViewport").outputs[0],
                    inner.nodes.new("NodeGroupOutput").inputs["Viewport"])
    tree = bpy.data.node_groups.new("Render offset", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    inp, out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    group = nodes.new("GeometryNodeGroup")
    group.node_tree = inner
    move = nodes.new("GeometryNodeTransform")
    move.inputs["Translation"].default_value = offset
    switch = nodes.new("GeometryNodeSwitch")
    switch.input_type = "GEOMETRY"
    links.new(inp.outputs["Geometry"], move.inputs["Geometry"])
    links.new(group.outputs["Viewport"], switch.inputs["Switch"])
    links.new(move.outputs["Geometry"], switch.inputs["False"])
    links.new(inp.outputs["Geometry"], switch.inputs["True"])
    links.new(switch.outputs[0], out.inputs["Geometry"])
    return tree


@pytest.mark.both_versions
def test_geometry_nodes_that_branch_on_is_viewport_bake_as_rendered(tmp_path, monkeypatch):
    """An object whose Geometry Nodes give renders another surface than the viewport (Is Viewport, here in a nested
    group: a cube resting on the floor in the viewport, lifted 1.5 m in renders) is baked by its own call, which
    evaluates it as rendered: the batch and the per-object calls give the same AO, bit for bit, and the floor under
    the lifted cube is lit as in a render."""
    bpy.ops.mesh.primitive_plane_add(size=4)
    floor = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.5))
    lifted = bpy.context.object
    lifted.modifiers.new("Render offset", "NODES").node_group = _viewport_switch((0.0, 0.0, 1.5))
    bpy.ops.mesh.primitive_cube_add(size=1, location=(1.5, 0, 0.5))
    other = bpy.context.object
    one = _batch_bakes_as_single_calls([floor, lifted, other], [floor.name, other.name], tmp_path, monkeypatch)
    ao = one[(floor.name, "ao")]["Y"]
    h, w = ao.shape
    assert ao[h // 2 - 2:h // 2 + 2, w // 2 - 2:w // 2 + 2].mean() > 0.3      # not under a cube resting on it
