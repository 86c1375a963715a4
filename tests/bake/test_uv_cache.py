"""The unwrap cache (bake/uvcache.py, issue 27): a cached layout skips the unwrapper and bakes the same pixels,
a corrupt entry is rebuilt, files stay inside the output folder; the figures of unchanged meshes are read, not
measured again, by a new process; the UV step's progress (objects done / total)."""
import functools
import json
import os
import pathlib
import re

import bpy
import numpy as np
import pytest

from addon.bake import (BakeOptions, bake_lightmaps, cycles, evaluated, pipeline, seams, unwrap, uv as uvmod, uvcache,
                        uvchecks)
from addon.blender import compat, progress, scene as sc
from addon.core import lightmap, memo
from addon.core.memo import FIGURES
from addon.core.errors import ILError, ILWarning
from addon.core.io import exr

OPTIONS = dict(resolution=16, samples=1, bounces=0, overwrite=True, force=True)


def _props():
    """A floor, a bevelled cube and a UV sphere, each with its own mesh."""
    bpy.ops.mesh.primitive_plane_add(size=4)
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-1, 0, 0.4))
    bpy.context.object.name = "Box"
    bpy.context.object.modifiers.new("Bevel", "BEVEL").width = 0.05
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(1, 0, 0.4), segments=12, ring_count=6)
    bpy.context.object.name = "Ball"
    return [bpy.data.objects[n] for n in ("Floor", "Box", "Ball")]


@pytest.fixture
def unwraps(monkeypatch):
    """Counts the unwrapper runs (:meth:`unwrap._Copies.unwrap`)."""
    calls = []
    real = unwrap._Copies.unwrap

    def counting(self, *a, **kw):
        calls.append([o.name for o in self.group])
        return real(self, *a, **kw)

    monkeypatch.setattr(unwrap._Copies, "unwrap", counting)
    return calls


def _bake(objects, out):
    for o in objects:                           # a new process opening the unsaved file has no layer
        if uvmod.LIGHTMAP in o.data.uv_layers:
            o.data.uv_layers.remove(o.data.uv_layers[uvmod.LIGHTMAP])
    rep = bake_lightmaps(objects, ["ao"], str(out), BakeOptions(**OPTIONS), scene=bpy.context.scene)
    return {n: exr.read_exr(e["ao"]["file"])[0]["Y"] for n, e in rep["objects"].items()}


def _entry_bytes(head, uv, raw=None):
    """A UV cache entry's bytes as uvcache writes them (``raw``: the head line's text instead of ``head``'s JSON)."""
    return uvcache.MAGIC + (raw if raw is not None else json.dumps(head)).encode() + b"\n" + uv.tobytes()


def _entries(out):
    folder = out / uvcache.DIR
    return sorted(p for p in folder.iterdir() if p.is_file()) if folder.exists() else []


def test_a_cached_layout_skips_the_unwrap_and_bakes_the_same_pixels(tmp_path, unwraps):
    objects = _props()
    fresh = _bake(objects, tmp_path)
    assert sorted({n for call in unwraps for n in call}) == ["Ball", "Box", "Floor"]
    assert len(_entries(tmp_path)) == 3
    unwraps.clear()
    cached = _bake(objects, tmp_path)
    assert unwraps == []
    assert sorted(cached) == sorted(fresh)
    for name in fresh:
        assert np.array_equal(cached[name], fresh[name]), name


def test_a_corrupt_or_mismatched_entry_is_ignored_and_rebuilt(tmp_path, unwraps):
    objects = _props()
    fresh = _bake(objects, tmp_path)
    entries = _entries(tmp_path)
    entries[0].write_bytes(b"PK\x03\x04 not a zip")
    head = {"side": 16, "margin": 1.0, "unwrap": "smart_project", "enlarged_from": 0, "window": [0, 0, 0],
            "loops": [3]}
    entries[1].write_bytes(_entry_bytes(head, np.zeros(6, np.float32)))                          # too few loops
    entries[2].write_bytes(b"")
    unwraps.clear()
    again = _bake(objects, tmp_path)
    assert sorted({n for call in unwraps for n in call}) == ["Ball", "Box", "Floor"]
    for name in fresh:
        assert np.array_equal(again[name], fresh[name]), name
    for path in _entries(tmp_path):                                            # rewritten, readable
        entry = uvcache._read(str(path))
        assert entry is not None and sum(uv.size for uv in entry.uvs) > 6


def test_meshes_of_equal_geometry_unwrap_once_and_files_stay_in_the_output_folder(tmp_path, unwraps):
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.5))
    first = bpy.context.object
    first.name = "../../escape"
    second = first.copy()
    second.data = first.data.copy()                     # its own mesh, the same vertices and faces
    second.name = "Twin"
    second.location = (2, 0, 0.5)
    bpy.context.scene.collection.objects.link(second)
    out = tmp_path / "maps"
    _bake([first, second], out)
    assert len(unwraps) >= 1 and all(call == ["../../escape"] for call in unwraps)
    files = [os.path.relpath(os.path.join(d, f), tmp_path) for d, _, fs in os.walk(tmp_path) for f in fs]
    assert all(f.startswith("maps" + os.sep) for f in files), files
    names = [p.name for p in _entries(out)]
    assert len(names) == 1 and re.fullmatch(r"[0-9a-f]{40}\.uv", names[0])


def test_a_bake_that_writes_no_map_writes_no_cache(tmp_path, monkeypatch):
    def broken(*args, **kw):
        raise ILError("Cycles failed")

    monkeypatch.setattr(cycles, "_bake_once", broken)
    bpy.ops.mesh.primitive_cube_add(size=1)
    with pytest.raises(ILError, match="Cycles failed"):
        bake_lightmaps([bpy.context.object], ["ao"], str(tmp_path), BakeOptions(**OPTIONS), scene=bpy.context.scene)
    assert os.listdir(tmp_path) == []


def test_the_digest_follows_modifiers_geometry_and_layout_options():
    bpy.ops.mesh.primitive_grid_add(size=1)
    grid = bpy.context.object
    solid = grid.modifiers.new("Solidify", "SOLIDIFY")
    scene = bpy.context.scene

    def key(**kw):
        scene.view_layers[0].update()
        return uvcache.key([grid], scene.view_layers[0].depsgraph, BakeOptions(**dict(OPTIONS, **kw)))

    base = key()
    assert key() == base
    solid.thickness = 0.3
    changed = key()
    assert changed != base
    assert key(margin=2) != changed and key(resolution=32) != changed
    grid.rotation_euler = (0, 0, 0.7)                   # a rotation keeps the metric: the same layout
    assert key() == changed
    grid.scale = (2, 1, 1)
    assert key() != changed
    grid.data.vertices[0].co.z += 0.1
    assert key(**{}) != changed


def test_solidify_overlap_is_named_as_the_modifier(tmp_path):
    bpy.ops.mesh.primitive_grid_add(size=1, x_subdivisions=4, y_subdivisions=4)
    grid = bpy.context.object
    grid.modifiers.new("Shell", "SOLIDIFY").thickness = 0.1
    with pytest.warns(Warning, match=r"Solidify copies share the light-map texels .*modifier 'Shell'"):
        bake_lightmaps([grid], ["ao"], str(tmp_path), BakeOptions(**dict(OPTIONS, resolution=32)),
                       scene=bpy.context.scene)


def test_a_cached_layout_reaches_the_evaluated_mesh_before_the_overlap_check(tmp_path, unwraps):
    """The Solidify shell shares its base's texels in the evaluated mesh: the rerun whose layout comes from the cache
    measures the same overlap as the bake that unwrapped (a stale evaluated mesh without the layer measured 0)."""
    bpy.ops.mesh.primitive_grid_add(size=1, x_subdivisions=4, y_subdivisions=4)
    grid = bpy.context.object
    grid.modifiers.new("Shell", "SOLIDIFY").thickness = 0.1
    overlaps = []
    for _ in range(2):
        unwraps.clear()
        if uvmod.LIGHTMAP in grid.data.uv_layers:
            grid.data.uv_layers.remove(grid.data.uv_layers[uvmod.LIGHTMAP])
        with pytest.warns(Warning, match=r"Solidify copies share the light-map texels"):
            rep = bake_lightmaps([grid], ["ao"], str(tmp_path), BakeOptions(**dict(OPTIONS, resolution=32)),
                                 scene=bpy.context.scene)
        overlaps.append(rep["objects"][grid.name]["ao"]["overlap"])
    assert unwraps == []
    assert overlaps[0] > uvchecks.MAX_OVERLAP and overlaps[1] == overlaps[0]


def test_the_uv_step_reports_objects_done_out_of_all(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(progress.Progress, "note", lambda self, message, fraction=None: seen.append((message,
                                                                                                   fraction)))
    bake_lightmaps(_props(), ["ao"], str(tmp_path), BakeOptions(**OPTIONS), scene=bpy.context.scene)
    uv = [(m, f) for m, f in seen if m.startswith("light-map UVs")]
    assert [f for _, f in uv] == [pytest.approx(1 / 3), pytest.approx(2 / 3)]
    assert uv[0][0].startswith("light-map UVs: 1/3 (3 objects), elapsed") and "ETA" in uv[0][0]


def test_the_ui_progress_moves_within_a_step_and_shows_the_line():
    class WindowManager:
        def __init__(self):
            self.values = []

        def progress_begin(self, lo, hi):
            self.values.append(("begin", lo, hi))

        def progress_update(self, value):
            self.values.append(value)

        def progress_end(self):
            self.values.append("end")

    wm = WindowManager()
    with progress.Progress("bake", 4) as p:
        p.wm = wm
        p.step("light-map UVs")
        p.note("light-map UVs: 1/4", 0.25)
        p.note("light-map UVs: 3/4", 0.75)
        p.step("Floor: ao")
    assert wm.values == [0, 0.25, 0.75, 1, "end"]


def test_an_atlas_covers_at_least_the_texels_pack_islands_gives_its_charts(tmp_path):
    from addon.lab.bench.level import pack_islands_utilisation
    objects = _props()
    bpy.ops.mesh.primitive_torus_add(major_radius=0.4, minor_radius=0.15, location=(0, 1.2, 0.2))
    objects.append(bpy.context.object)
    rep = bake_lightmaps(objects, ["ao"], str(tmp_path), BakeOptions(**dict(OPTIONS, resolution=64, margin=1,
                                                                            atlas=True)), scene=bpy.context.scene)
    entry = rep["objects"][objects[0].name]["ao"]
    side = entry["resolution"][0]
    tri = np.concatenate([uvmod.triangles_uv(o, uvmod.LIGHTMAP) for o in objects])
    ours = float(lightmap.coverage_mask(tri, side, side).mean())
    assert ours >= pack_islands_utilisation(objects, (side, side), entry["margin"], cut=False) > 0.3


@pytest.mark.both_versions
def test_a_rerun_in_a_new_process_reads_the_figures_instead_of_measuring_them_again(tmp_path, monkeypatch):
    """The overlap, seams, inward shells and coverage masks of unchanged meshes and layouts come from the store
    beside the maps (core.memo.Store), with the same pixels and report figures; code that changed measures them again. (The
    box has no bevel here: 4.5's Bevel modifier gives UVs that differ in the last bit from one evaluation to the
    next, whose figures are then measured again.)"""
    objects = _props()
    objects[1].modifiers.clear()
    calls = []

    def counted(module, name):
        real = getattr(module, name)

        @functools.wraps(real)
        def wrapper(*args):
            calls.append(name)
            return real(*args)
        monkeypatch.setattr(module, name, wrapper)

    for module, name in ((lightmap, "overlap_fraction"), (lightmap, "inward_shells"), (seams, "_seam_edges"),
                         (lightmap, "coverage_mask"), (uvmod, "_world_area")):
        counted(module, name)

    def bake():
        for o in objects:
            if uvmod.LIGHTMAP in o.data.uv_layers:
                o.data.uv_layers.remove(o.data.uv_layers[uvmod.LIGHTMAP])
        FIGURES.clear()                                      # a new process remembers nothing
        calls.clear()
        return bake_lightmaps(objects, ["ao"], str(tmp_path), BakeOptions(**OPTIONS), scene=bpy.context.scene)

    def figures(rep):
        return {n: {k: e["ao"][k] for k in ("overlap", "coverage", "chart_area", "seams")}
                for n, e in rep["objects"].items()}

    first = bake()
    assert {"overlap_fraction", "inward_shells", "_seam_edges", "coverage_mask", "_world_area"} <= set(calls)
    packs = os.listdir(pipeline.figures_folder(tmp_path))
    assert packs and all(re.fullmatch(r"[0-9a-f]{32}\.npz", p) for p in packs)
    again = bake()
    assert calls == []
    assert figures(again) == figures(first)
    for name, e in first["objects"].items():
        assert np.array_equal(exr.read_exr(again["objects"][name]["ao"]["file"])[0]["Y"],
                              exr.read_exr(e["ao"]["file"])[0]["Y"]), name
    monkeypatch.setattr(memo, "code_digest", lambda: b"another version")
    bake()
    assert {"overlap_fraction", "inward_shells", "_seam_edges"} <= set(calls)


@pytest.mark.both_versions
def test_the_shape_figures_of_a_changed_mesh_are_measured_again(tmp_path, monkeypatch):
    """uv.geometry_figure: a mesh's area and inward shells are kept under a digest of its shape, which the layers a bake
    keeps (the "Lightmap" UVs) leave unchanged: a rerun in a new process reads them. Scaling the vertices or turning
    the mesh inside out gives the new figures (area × 4, flipped for the bake); a face broken after a first run is
    refused (Mesh.validate runs every time: it also reads the UVs)."""
    objects = _props()
    box = objects[1]
    box.modifiers.clear()
    calls = []
    for module, name in ((uvmod, "_world_area"), (lightmap, "inward_shells")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, functools.partial(lambda real, name, *a: calls.append(name) or real(*a),
                                                            real, name))

    def bake():
        FIGURES.clear()
        calls.clear()
        return bake_lightmaps(objects, ["ao"], str(tmp_path), BakeOptions(**OPTIONS), scene=bpy.context.scene)

    def area():
        FIGURES.clear()
        with FIGURES.stored(pipeline.figures_folder(tmp_path)) as store:
            return uvmod.world_area(box), len(store.used)

    bake()
    assert {"_world_area", "inward_shells"} <= set(calls) and uvmod.LIGHTMAP in box.data.uv_layers
    bake()                                                        # the kept "Lightmap" layers in place
    assert calls == []
    assert area() == (pytest.approx(6 * 0.8 ** 2, rel=1e-6), 1)   # read from the pack the bake wrote
    box.data.transform(np.diag([2.0, 2.0, 2.0, 1.0]))
    assert area()[0] == pytest.approx(4 * 6 * 0.8 ** 2, rel=1e-6)
    box.data.transform(np.diag([-0.5, 0.5, 0.5, 1.0]))          # mirrored in place: every normal points inward
    box.data.update()
    with pytest.warns(ILWarning, match="'Box': normals point into a closed, empty surface"):
        rep = bake()
    ao = exr.read_exr(rep["objects"]["Box"]["ao"]["file"])[0]["Y"]
    assert ao.max() > 0.5                                         # the outside, not the inside of an empty box
    cv = sc.attribute(box.data, ".corner_vert", np.int32)
    cv[1] = cv[0]                                                 # a face that repeats a vertex
    sc.set_attribute(box.data, ".corner_vert", "INT", "CORNER", cv)
    rep = bake()
    assert "is invalid" in rep["failed"]["Box"] and set(rep["objects"]) == {"Floor", "Ball"}


@pytest.mark.both_versions
def test_a_mesh_its_parent_deforms_is_read_every_run(tmp_path, monkeypatch):
    """A lattice parent of type Lattice deforms the mesh through a modifier ``Object.modifiers`` does not list: the
    mesh is not unmodified, so its evaluated figures are not kept under its cage, and moving the lattice's points
    bakes the moved surface (the batch's triangles are read again)."""
    objects = _props()
    objects[1].modifiers.clear()
    box = objects[1]
    bpy.ops.object.add(type="LATTICE", location=box.location)
    lattice = bpy.context.object
    box.parent, box.parent_type = lattice, "LATTICE"
    box.matrix_parent_inverse = lattice.matrix_world.inverted()
    assert not sc.unmodified(box) and sc.unmodified(objects[0])
    read, real = [], evaluated._of
    monkeypatch.setattr(evaluated, "_of", lambda obj, *a: read.append(obj.name) or real(obj, *a))

    def bake():
        FIGURES.clear()
        read.clear()
        rep = bake_lightmaps(objects, ["ao"], str(tmp_path), BakeOptions(**OPTIONS), scene=bpy.context.scene)
        return exr.read_exr(rep["objects"]["Box"]["ao"]["file"])[0]["Y"]

    first = bake()
    for p in lattice.data.points:
        p.co_deform.z *= 3.0                                      # the box stretched upward through the lattice
    moved = bake()
    assert "Box" in read and "Floor" not in read
    assert not np.array_equal(first, moved)


@pytest.mark.both_versions
def test_a_rerun_reads_no_evaluated_mesh_of_a_subdivided_mesh_and_bakes_the_same_pixels(tmp_path, monkeypatch):
    """bake/evaluated.py: a rerun takes the overlap, seams, batch check and batched triangles of a mesh only subdivided
    (Blender does not subdivide it outside Cycles) or without modifiers from the store, per object and in an atlas;
    its maps are those of a run that reads the evaluated mesh (into a new folder), byte for byte. A mesh with another
    modifier (the bevelled box) is read every run; a crease, the render levels, the modifier's render switch or
    Simplify make the mesh read again, and the maps follow them."""
    objects = _props()
    sc.light(bpy.context.scene, "Sun", "SUN", 3.0, rotation=(0.6, 0.3, 0.0))     # E = 3 cos θ: the normals show
    ball = objects[2]
    subsurf = ball.modifiers.new("Subdivision", "SUBSURF")
    subsurf.levels = subsurf.render_levels = 1
    read = []
    real = evaluated._of

    def reading(obj, depsgraph, fn, args):
        read.append((obj.name, fn.__qualname__))
        return real(obj, depsgraph, fn, args)
    monkeypatch.setattr(evaluated, "_of", reading)

    def bake(out, **kw):
        for o in objects:
            if uvmod.LIGHTMAP in o.data.uv_layers:
                o.data.uv_layers.remove(o.data.uv_layers[uvmod.LIGHTMAP])
        FIGURES.clear()                                      # a new process remembers nothing
        read.clear()
        rep = bake_lightmaps(objects, ["irradiance"], str(out), BakeOptions(**OPTIONS, **kw), scene=bpy.context.scene)
        return {n: exr.read_exr(e["irradiance"]["file"])[0]["R"] for n, e in rep["objects"].items()}

    def ball_read():
        return {fn for name, fn in read if name == "Ball"}

    first = bake(tmp_path / "a")
    assert "Triangles.of" in ball_read() and {"Floor", "Box"} <= {name for name, _ in read}   # batched: triangles
    again = bake(tmp_path / "a")
    assert not ball_read() and {name for name, _ in read} == {"Box"}
    fresh = bake(tmp_path / "b")
    assert ball_read()
    assert first.keys() == again.keys() == fresh.keys() == {"Floor", "Box", "Ball"}
    for name in first:
        assert np.array_equal(again[name], fresh[name]) and np.array_equal(first[name], fresh[name]), name
    bake(tmp_path / "atlas", atlas=True)
    assert ball_read()
    bake(tmp_path / "atlas", atlas=True)
    assert not ball_read()

    def crease():
        ball.data.attributes.new("crease_edge", "FLOAT", "EDGE").data.foreach_set(
            "value", np.ones(len(ball.data.edges), np.float32))

    def simplify():
        bpy.context.scene.render.use_simplify = True
        bpy.context.scene.render.simplify_subdivision_render = 0          # what renders, and bakes, use

    def unsimplify():
        bpy.context.scene.render.use_simplify = False

    before = first["Ball"]
    for change, new in ((crease, True), (lambda: setattr(subsurf, "render_levels", 2), True),
                        (lambda: setattr(subsurf, "show_render", False), True),      # not subdivided: read
                        (lambda: setattr(subsurf, "show_render", True), False),      # back: figures stored before
                        (simplify, True), (unsimplify, False)):
        change()
        changed = bake(tmp_path / "a")
        assert bool(ball_read()) == new
        assert np.array_equal(changed["Ball"], bake(tmp_path / "c")["Ball"])
        assert not np.array_equal(changed["Ball"], before)
        before = changed["Ball"]
    ball.modifiers.new("Solidify", "SOLIDIFY")
    assert evaluated.cage_key(ball, bpy.context.evaluated_depsgraph_get()) is None


def test_entries_beyond_the_bytes_allowed_are_removed_least_recently_used_first(tmp_path, monkeypatch):
    """uvcache.UVCache.MAX_BYTES: a run that writes an entry removes the least recently written or read entries
    beyond it, never one it read or wrote; a rerun that reads a layout keeps it (and makes it the most recent)."""
    old = []
    for k in range(3):
        path = tmp_path / f"{k:040x}.uv"
        path.write_bytes(bytes(10000))
        os.utime(path, (10**9 + k, 10**9 + k))
        old.append(path)
    (tmp_path / ("e" * 40 + ".npz")).write_bytes(bytes(100))           # an entry of the format before: removed
    (tmp_path / "figures").mkdir()
    monkeypatch.setattr(uvcache.UVCache, "MAX_BYTES", 25000)     # the new entry is under 5,000 bytes
    cache = uvcache.UVCache(str(tmp_path))
    cache.used.add(str(old[0]))                                   # read by this run: kept although the oldest
    cache.put("f" * 40, uvcache.Entry([np.zeros(6, np.float32)], 16, 1.0, "smart_project"))
    cache.flush()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([old[0].name, old[2].name, "f" * 40 + ".uv",
                                                                 "figures"])
    objects = _props()
    _bake(objects, tmp_path / "out")
    monkeypatch.setattr(uvcache.UVCache, "MAX_BYTES", 1)
    first = _entries(tmp_path / "out")
    objects[2].data.vertices[0].co.z += 0.01                       # the ball's layout is made again
    _bake(objects, tmp_path / "out")
    after = _entries(tmp_path / "out")
    assert len(first) == len(after) == 3                            # the ball's old entry is gone, the two read kept
    assert len(set(first) - set(after)) == len(set(after) - set(first)) == 1


def test_temporaries_a_killed_run_left_in_the_cache_folders_are_removed(tmp_path):
    """A run killed while it wrote a layout or a figure pack leaves '.<stem>.<host>-<pid>.<random>.tmp.uv' in
    .il-uv-cache/ or its figures/ folder: the next bake removes them (older than files.STALE_AFTER, process gone),
    as it does in the output folder."""
    import subprocess
    import sys
    import time
    from addon.core.io import files
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    left = [tmp_path / uvcache.DIR / f".{'a' * 40}.{files._HOST}-{dead}.k2j4x9_a.tmp.uv",
            pathlib.Path(pipeline.figures_folder(tmp_path)) / f".{'b' * 32}.{files._HOST}-{dead}.q1w2e3r4.tmp.npz"]
    for path in left:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"x")
        os.utime(path, (time.time() - 600, time.time() - 600))
    _bake(_props()[:1], tmp_path)
    assert not any(p.exists() for p in left)


def test_an_entry_whose_head_does_not_match_its_uvs_reads_as_none(tmp_path):
    """uvcache._read: the loop counts of the head must add up to the UV array, every field be there, the head be
    JSON; a good entry reads back as written."""
    good = {"side": 16, "margin": 1.0, "unwrap": "smart_project", "enlarged_from": 0, "window": [0, 0, 0],
            "loops": [3, 2]}
    uv = np.linspace(0, 1, 10, dtype=np.float32)

    def entry(head, uvs=uv, raw=None):
        path = tmp_path / f"{len(list(tmp_path.iterdir()))}.uv"
        path.write_bytes(_entry_bytes(head, uvs, raw))
        return uvcache._read(str(path))

    read = entry(good)
    assert [u.tolist() for u in read.uvs] == [uv[:6].tolist(), uv[6:].tolist()] and read.side == 16
    assert entry({**good, "loops": [3, 3]}) is None                        # 12 UVs said, 10 stored
    assert entry({k: v for k, v in good.items() if k != "margin"}) is None
    assert entry(good, raw="{not json") is None
    assert entry(good, raw="[1]") is None                                  # a head that is not a mapping
    assert entry(good, uvs=uv.astype(np.float64)) is None                  # 20 float32 read, 10 said
    assert entry(good, uvs=uv[:9]) is None                                 # a truncated block
    path = tmp_path / "odd.uv"
    path.write_bytes(_entry_bytes(good, uv)[:-1])                          # a block that is not whole float32s
    assert uvcache._read(str(path)) is None
    path.write_bytes(_entry_bytes(good, uv)[len(uvcache.MAGIC):])          # no magic line
    assert uvcache._read(str(path)) is None


@pytest.mark.both_versions
def test_a_bake_reads_each_mesh_triangles_once_and_again_after_flipping_it(tmp_path, monkeypatch):
    """uv.fixed_geometry spans a bake from its input checks to its last map: each mesh's loop triangles are read from
    Blender once (input hash, UV step, plan, files), also on a first run whose UV step tries several layouts; a mesh
    the bake turns outward (its normals flipped: cycles.flip_inside_out) is read again after the flip, and its
    map shows the outside (lit: AO above 0.9 on the cube's top)."""
    reads = []
    real = uvmod.corner_triangles

    def counted(me):
        reads.append(me.as_pointer())                # the meshes themselves and their evaluated copies
        return real(me)

    monkeypatch.setattr(uvmod, "corner_triangles", counted)
    objects = _props()
    objects[1].modifiers.clear()
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0, 1.2, 0.3))
    inside_out = bpy.context.object
    inside_out.name = "Inside out"
    inside_out.data.flip_normals()
    rep = bake_lightmaps(objects + [inside_out], ["ao"], str(tmp_path), BakeOptions(**OPTIONS),
                         scene=bpy.context.scene)
    assert {o.name: reads.count(o.data.as_pointer()) for o in objects} == {o.name: 1 for o in objects}
    assert reads.count(inside_out.data.as_pointer()) == 2
    ao = exr.read_exr(rep["objects"]["Inside out"]["ao"]["file"])[0]["Y"]
    assert ao.max() > 0.9


@pytest.mark.parametrize("scale", [1, 2], ids=["moved", "larger"])
def test_a_linked_duplicates_layout_is_written_once_and_a_rerun_rewrites_no_entry(tmp_path, monkeypatch, unwraps,
                                                                                   scale):
    """A linked duplicate takes the layout its mesh got in the run and puts it under its own key (a rerun that bakes
    only the duplicate finds it). Moved and turned, the key is its mesh's, whose entry stays as the unwrap made it
    (Suzanne at 2 texels/m: enlarged from 8 to 16 texels, which the duplicate's own entry would not say); twice the
    size, a key of its own. Written by the first bake, no entry is written again by a rerun, and both objects' maps
    come out as before."""
    bpy.ops.mesh.primitive_monkey_add()
    first = bpy.context.object
    dup = first.copy()                                  # the same mesh
    dup.name = "Suzanne copy"
    dup.location, dup.rotation_euler, dup.scale = (3, 0, 0), (0, 0, 0.7), (scale,) * 3
    bpy.context.scene.collection.objects.link(dup)
    out = tmp_path / "maps"
    writes = []
    real = uvcache.write_bytes
    monkeypatch.setattr(uvcache, "write_bytes", lambda path, data: writes.append(os.path.basename(path))
                        or real(path, data))
    opts = BakeOptions(texel_density=2, samples=1, bounces=0, overwrite=True, force=True)

    def bake(objects):
        first.data.uv_layers.remove(first.data.uv_layers[uvmod.LIGHTMAP]) if uvmod.LIGHTMAP in first.data.uv_layers \
            else None
        with pytest.warns(ILWarning):
            rep = bake_lightmaps(objects, ["ao"], str(out), opts, scene=bpy.context.scene)
        return {n: exr.read_exr(e["ao"]["file"])[0]["Y"] for n, e in rep["objects"].items()}

    fresh = bake([first, dup])
    assert len(unwraps) >= 1 and all(call == ["Suzanne"] for call in unwraps)
    assert len(writes) == len(set(writes)) == len(_entries(out)) == (1 if scale == 1 else 2)
    assert any(uvcache._read(p).enlarged_from == 8 for p in _entries(out))
    made = {p.name: p.read_bytes() for p in _entries(out)}
    writes.clear()
    unwraps.clear()
    again = bake([first, dup])
    assert writes == [] and unwraps == [] and {p.name: p.read_bytes() for p in _entries(out)} == made
    for name in fresh:
        assert np.array_equal(again[name], fresh[name])
    alone = bake([dup])
    assert unwraps == [] and np.array_equal(alone["Suzanne copy"], fresh["Suzanne copy"])


def test_an_entry_is_written_only_when_the_folder_does_not_hold_it(tmp_path, monkeypatch):
    """``UVCache.put`` then ``flush``: a new entry is written; put again by a later run (a new cache on the folder)
    with the same UVs, side, margin, unwrapper and window (None, stored as 0 0 0) it is not written again, but counts
    as used (kept by the pruning, its time touched); a changed entry is written; of two puts before a flush the
    last is written and read back."""
    written = []
    real = uvcache.write_bytes
    monkeypatch.setattr(uvcache, "write_bytes", lambda path, data: written.append(path) or real(path, data))
    folder = str(tmp_path / uvcache.DIR)
    uv = np.linspace(0.1, 0.9, 8, dtype=np.float32)
    entry = lambda **kw: uvcache.Entry(**({"uvs": [uv.copy()], "side": 16, "margin": 1.5, "unwrap": unwrap.SMART}
                                          | kw))
    first = uvcache.UVCache(folder)
    first.put("a" * 40, entry())
    first.flush()
    assert written == [first.path("a" * 40)]
    os.utime(first.path("a" * 40), (1, 1))
    again = uvcache.UVCache(folder)
    again.put("a" * 40, entry())
    again.flush()
    assert written == [first.path("a" * 40)] and again.path("a" * 40) in again.used
    assert os.path.getmtime(first.path("a" * 40)) > 1
    for changed in (dict(side=17), dict(margin=1.0), dict(window=(16, 8, 16)), dict(enlarged_from=8),
                    dict(uvs=[uv + np.float32(0.01)])):
        written.clear()
        later = uvcache.UVCache(folder)
        later.put("a" * 40, entry(**changed))
        later.flush()
        assert written == [later.path("a" * 40)], changed
        later = uvcache.UVCache(folder)
        later.put("a" * 40, entry())                         # back to the first, for the next change
        later.flush()
    written.clear()
    twice = uvcache.UVCache(folder)
    twice.put("b" * 40, entry(side=20))
    twice.put("b" * 40, entry(side=24))
    twice.flush()
    assert written == [twice.path("b" * 40)] and uvcache._read(twice.path("b" * 40)).side == 24


@pytest.mark.both_versions
def test_flip_corners_is_the_order_blenders_flip_normals_gives_a_faces_corners():
    """A triangle, a quad and a pentagon: flip_corners of each corner's vertex index is Blender's own order after
    mesh.flip_normals(), and applied twice it is the identity."""
    me = bpy.data.meshes.new("faces")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (3, 1, 0), (2.5, 1.5, 0),
                    (2, 1, 0), (4, 0, 0), (5, 0, 0), (4, 1, 0)], [], [(0, 1, 2, 3), (4, 5, 6, 7, 8), (9, 10, 11)])
    before = np.zeros(len(me.loops), np.int64)
    me.loops.foreach_get("vertex_index", before)
    as_uv = np.repeat(before, 2).astype(np.float32)
    me.flip_normals()
    after = np.zeros(len(me.loops), np.int64)
    me.loops.foreach_get("vertex_index", after)
    assert not np.array_equal(before, after)
    assert np.array_equal(uvcache.flip_corners(me, as_uv)[::2], after)
    assert np.array_equal(uvcache.flip_corners(me, uvcache.flip_corners(me, as_uv)), as_uv)


@pytest.mark.both_versions
def test_an_inside_out_meshs_cached_layout_reaches_the_files_corners_and_survives_fixing_its_normals(tmp_path,
                                                                                                     unwraps):
    """The bake flips an inside-out mesh's normals (its corners reversed) before the UV step, so its cached layout
    follows the flipped corners: Export and Preview, writing it onto the file's mesh as it was, gave its corners
    other UVs (modifiers.blend's 'Negative Scale': 0.35 apart). file_layout now turns it onto the file's corners,
    UV for UV the layer the bake kept, also for an entry written before the corners were recorded. Once the user
    fixes the normals (the corners now in the bake's order, the same key), a rerun takes the layout as it is,
    unwraps nothing and bakes the same pixels, and file_layout takes it as it is too."""
    bpy.ops.mesh.primitive_plane_add(size=4)
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0, 0, 0.3))
    cube = bpy.context.object
    cube.data.flip_normals()
    objects = [bpy.data.objects["Plane"], cube]
    opts = BakeOptions(**OPTIONS)
    scene = bpy.context.scene
    with pytest.warns(ILWarning, match="normals point into"):
        rep = bake_lightmaps(objects, ["ao"], str(tmp_path), opts, scene=scene)
    kept = uvmod.corner_uv(cube.data, uvmod.LIGHTMAP).ravel().copy()
    ref = rep["objects"]["Cube"]["ao"]["uv_cache"]
    assert np.array_equal(uvcache.file_layout(str(tmp_path), ref, cube, scene), kept)
    pixels = exr.read_exr(rep["objects"]["Cube"]["ao"]["file"])[0]["Y"]

    path = uvcache.cached_entry(str(tmp_path), ref)       # as the code before wrote it: no corners
    entry = uvcache._read(path)
    head = {"side": entry.side, "margin": entry.margin, "unwrap": entry.unwrap, "enlarged_from": entry.enlarged_from,
            "window": list(entry.window or (0, 0, 0)), "loops": [len(u) // 2 for u in entry.uvs]}
    pathlib.Path(path).write_bytes(_entry_bytes(head, np.concatenate(entry.uvs)))
    assert uvcache._read(path).corners is None
    assert np.array_equal(uvcache.file_layout(str(tmp_path), ref, cube, scene), kept)

    cube.data.flip_normals()                               # fixed: facing out, the corners in the bake's order
    for o in objects:
        o.data.uv_layers.remove(o.data.uv_layers[uvmod.LIGHTMAP])
    unwraps.clear()
    again = bake_lightmaps(objects, ["ao"], str(tmp_path), opts, scene=scene)
    assert unwraps == [] and again["objects"]["Cube"]["ao"]["uv_cache"] == ref
    now = uvmod.corner_uv(cube.data, uvmod.LIGHTMAP).ravel()
    assert np.array_equal(now, uvcache.flip_corners(cube.data, kept))      # each corner keeps its UV
    assert np.array_equal(exr.read_exr(again["objects"]["Cube"]["ao"]["file"])[0]["Y"], pixels)
    assert uvcache._read(path).corners is not None
    assert np.array_equal(uvcache.file_layout(str(tmp_path), ref, cube, scene), now)


def _alpha(report, name):
    channels, _ = exr.read_exr(report["objects"][name]["ao"]["file"])
    return np.flipud(channels["A"]) > 0.5


def _on_layer(alpha, obj):
    """Whether a map's texels are the coverage of ``obj``'s "Lightmap" layer at 32²: exactly where Cycles bakes the
    texels a triangle touches and the map keeps the centre texels (compat.BAKE_TOUCHED_TEXELS), else to 1 % of the
    texels (Cycles' own centre rule at triangle edges)."""
    differ = np.mean(alpha != lightmap.coverage_mask(uvmod.triangles_uv(obj, "Lightmap"), 32, 32))
    return differ == 0 if compat.BAKE_TOUCHED_TEXELS else differ <= 0.01


def test_a_map_stays_unchanged_only_while_its_layout_is_the_layer_or_the_cache(tmp_path):
    """The map's header keeps a digest of the UVs it was baked through (inputs.UV_DIGEST_KEY). A generated layer
    edited by hand, or removed, keeps the map: the UV cache makes its layout again, and the next bake that needs
    the layer (one more map) writes it back, so the kept map lies on the layer again (its texels are the layer's
    coverage). A plane's own "Lightmap" layer, reused (no cache entry): edited, the map is baked again through the
    edited layer; removed, baked again (before, both were kept "unchanged" on UVs the mesh no longer had: the
    input hash leaves that layer out, so that a rerun without it agrees with the first bake)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
    obj = bpy.context.object
    opts = BakeOptions(resolution=32, samples=1, bounces=0, overwrite=True)
    first = bake_lightmaps([obj], ["ao"], tmp_path / "a", opts)
    layout = sc.corner_uv(obj.data, "Lightmap").copy()
    mirrored = layout.copy()
    mirrored[:, 0] = 1.0 - mirrored[:, 0]
    obj.data.uv_layers["Lightmap"].data.foreach_set("uv", mirrored.ravel())
    assert obj.name in bake_lightmaps([obj], ["ao"], tmp_path / "a", opts)["unchanged"]
    more = bake_lightmaps([obj], ["ao", "irradiance"], tmp_path / "a", opts)
    assert more["unchanged"] == {obj.name: ["ao"]}
    assert np.array_equal(sc.corner_uv(obj.data, "Lightmap"), layout)
    assert _on_layer(_alpha(first, obj.name), obj)
    obj.data.uv_layers.remove(obj.data.uv_layers["Lightmap"])
    assert obj.name in bake_lightmaps([obj], ["ao"], tmp_path / "a", opts)["unchanged"]

    bpy.ops.mesh.primitive_plane_add(location=(0, 0, -2))
    plane = bpy.context.object
    own = sc.corner_uv(plane.data, "UVMap")
    plane.data.uv_layers.new(name="Lightmap").data.foreach_set("uv", (0.1 + 0.8 * own).ravel())
    reused = bake_lightmaps([plane], ["ao"], tmp_path / "b", opts)["objects"][plane.name]["ao"]
    assert reused["uv_layer"] == "Lightmap" and not reused.get("uv_cache") and "unwrap" not in reused
    assert plane.name in bake_lightmaps([plane], ["ao"], tmp_path / "b", opts)["unchanged"]
    plane.data.uv_layers["Lightmap"].data.foreach_set("uv", (0.2 + 0.7 * own).ravel())
    edited = bake_lightmaps([plane], ["ao"], tmp_path / "b", opts)
    assert plane.name not in edited["unchanged"]
    assert _on_layer(_alpha(edited, plane.name), plane)
    plane.data.uv_layers.remove(plane.data.uv_layers["Lightmap"])
    assert plane.name not in bake_lightmaps([plane], ["ao"], tmp_path / "b", opts)["unchanged"]


def test_the_layout_check_keeps_inside_out_meshes(tmp_path):
    """The digest of the UVs a map was baked through (inputs.layout_digest) is taken face by face in the order of
    the corners' vertices: an inside-out cube, flipped for its bake and back, is kept on a rerun, with a generated
    layer and with ``uv_layer`` (before, its corners' order changed and it was baked again on every rerun)."""
    bpy.ops.mesh.primitive_plane_add(size=4)
    plane = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0, 0, 0.3))
    cube = bpy.context.object
    cube.data.flip_normals()
    for name, extra in (("made", {}), ("given", {"uv_layer": "UVMap"})):
        opts = BakeOptions(resolution=16, samples=1, bounces=0, overwrite=True, **extra)
        bake_lightmaps([plane, cube], ["ao"], tmp_path / name, opts)
        assert sorted(bake_lightmaps([plane, cube], ["ao"], tmp_path / name, opts)["unchanged"]) == ["Cube", "Plane"]
