"""Level benchmark: a generated level (walls, floor, props of every primitive kind, modifiers, linked duplicates,
a collection instance) baked AO + irradiance per object and as an atlas.

Measured in one run: the pipeline's wall time against Blender's bare ``object.bake`` calls for the same maps
(same UV layers, image sizes, samples) and against its own time inside Cycles, a rerun with unchanged meshes, the
median fill of the maps and how many warned of a low fill, peak RSS, texels per second, and the atlas's utilisation
(covered texels / map texels: baked, and of its layout) against Blender's ``uv.pack_islands`` on the same charts
(measured alike: :func:`layout_utilisation`, :func:`pack_islands_utilisation`). The per-object bake is
also run at production samples (:data:`PRODUCTION_SAMPLES`), and each is redone with its meshes unchanged but a
light changed (irradiance rebaked, AO resumed) and the "Lightmap" layers gone, in a new process that opens the level
saved (at production samples :data:`RERUNS` times: the median one's row): the layouts come from the UV cache
(``bake/uvcache.py``) and the figures from its store
(``core/memo.py``). The production run starts with no figure remembered, as a first run in a new process does (the
4-spp run before it measured the same layouts). The time outside Cycles over the time inside is
the figure issue 27 bounds (at most 1 on a first run, 0.1 on such a rerun). The production rerun's row also gives
the seconds Blender takes to evaluate the level's meshes once their UV layers changed (:func:`evaluation_seconds`,
measured last): what a pipeline that reads the baked meshes before the bake pays outside Cycles (the pipeline reads
meshes only subdivided or without modifiers from its figure store instead, ``bake/evaluated.py``).
"""
import contextlib
import dataclasses
import json
import os
import resource
import shutil
import subprocess
import sys
import time

import bpy
import numpy as np

from ...bake import unwrap, unwrap_copy, uv as uvmod
from ...bake.options import BakeOptions
from ...bake.pipeline import bake_lightmaps
from ...blender import chatter, compat, render
from ...blender.scene import remove_scene
from ...core import lightmap
from ...core.memo import FIGURES
from .result import BenchResult

KEY = "level"
TITLE = "Light maps of a level: pipeline against bare Cycles bakes"

PRIMITIVES = ("cube", "uv_sphere", "ico_sphere", "cylinder", "cone", "torus", "monkey", "grid", "circle", "plane")
MAPS = ("ao", "irradiance")
PRODUCTION_SAMPLES = 64
"""BakeOptions' default samples."""
RERUNS = 3
"""Reruns at production samples, each in its own process (a light 1 % brighter each time): their row is the median
one's, with the range of the ratio. One rerun on two shared cores varied by ±20 % (Cycles 1.75-2.3 s for the same
quick-level maps), as much as the margin the bound leaves."""


def peak_rss():
    """Peak resident set size of this process in bytes (``getrusage``; kilobytes on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _add(scene, kind, **kw):
    """A primitive added by its operator (into the context's scene), moved into ``scene``."""
    if kind == "circle":
        kw["fill_type"] = "NGON"
    getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**kw)
    obj = bpy.context.view_layer.objects.active
    for c in list(obj.users_collection):
        c.objects.unlink(obj)
    scene.collection.objects.link(obj)
    return obj


def _hard_props(scene, side, scan_level):
    """Two props as imported files bring them (issue 27): "Soup", 1,280 loose triangles (a split ico sphere, each
    triangle its own piece), and "Scan", a dense ico sphere (``scan_level``: 20,480 or 81,920 triangles) with its
    vertices moved by a fixed pseudo-random 2 % of the radius."""
    import bmesh
    out = []
    for name, level, loc in (("Soup", 4, (-side / 2 + 1.0, side / 2 - 1.0, 0.4)),
                             ("Scan", scan_level, (side / 2 - 1.0, -side / 2 + 1.0, 0.4))):
        obj = _add(scene, "ico_sphere", subdivisions=level, radius=0.4, location=loc)
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        if name == "Soup":
            bmesh.ops.split_edges(bm, edges=bm.edges[:])
        else:
            rng = np.random.default_rng(27)
            for v in bm.verts:
                v.co *= 1.0 + 0.02 * float(rng.uniform(-1, 1))
        bm.to_mesh(obj.data)
        bm.free()
        obj.name = name
        out.append(obj)
    return out


def build_level(scene, props=200, subdivision=2, floor_levels=3):
    """Fill ``scene`` with a level made by Blender's operators: a floor (Subdivision), four walls (Bevel), ``props``
    props cycling through every primitive kind (Subdivision on the floor and the monkeys, Bevel on cubes, Solidify on grids and
    planes), every tenth prop a linked duplicate of the one before, a triangle soup and a dense scan
    (:func:`_hard_props`), a "Crate stack" collection instanced by an empty, a sun and a point light. Returns the
    mesh objects to bake (the instance's objects are not in the scene)."""
    objects = []
    if True:
        side = max(8.0, 1.6 * props ** 0.5)
        floor = _add(scene, "plane", size=side)
        floor.name = "Floor"
        m = floor.modifiers.new("Subdivision", "SUBSURF")
        m.subdivision_type, m.levels, m.render_levels = "SIMPLE", floor_levels, floor_levels
        objects.append(floor)
        for i, (x, y, sx, sy) in enumerate(((0, side / 2, side / 2, 0.1), (0, -side / 2, side / 2, 0.1),
                                            (side / 2, 0, 0.1, side / 2), (-side / 2, 0, 0.1, side / 2))):
            wall = _add(scene, "cube", location=(x, y, 1.0), scale=(sx, sy, 1.0))
            wall.name = f"Wall {i}"
            bevel = wall.modifiers.new("Bevel", "BEVEL")
            bevel.width, bevel.segments = 0.05, 2
            objects.append(wall)
        grid = int(np.ceil(props ** 0.5))
        step = (side - 2.0) / grid
        rng = np.random.default_rng(13)
        for i in range(props):
            x, y = -side / 2 + 1.0 + step * (i % grid + 0.5), -side / 2 + 1.0 + step * (i // grid + 0.5)
            size = float(rng.uniform(0.3, 0.6) * min(step, 1.5))
            loc = (x, y, size / 2)
            if i % 10 == 9:
                obj = objects[-1].copy()          # linked duplicate: same mesh, its own transform
                obj.location = loc
                obj.rotation_euler = (0, 0, float(rng.uniform(0, 6.28)))
                scene.collection.objects.link(obj)
            else:
                kind = PRIMITIVES[i % len(PRIMITIVES)]
                kw = {"location": loc, "rotation": (0, 0, float(rng.uniform(0, 6.28)))}
                if kind in ("cube", "monkey", "grid", "plane"):
                    kw["size"] = size
                elif kind in ("uv_sphere", "ico_sphere", "circle"):
                    kw["radius"] = size / 2
                    if kind == "uv_sphere":
                        kw.update(segments=48, ring_count=24)
                elif kind in ("cylinder", "cone"):
                    kw.update(radius1=size / 2, depth=size) if kind == "cone" else kw.update(radius=size / 2, depth=size)
                elif kind == "torus":
                    kw.update(major_radius=size / 2, minor_radius=size / 6)
                obj = _add(scene, kind, **kw)
                if kind == "monkey":
                    sub = obj.modifiers.new("Subdivision", "SUBSURF")
                    sub.levels = sub.render_levels = subdivision
                elif kind == "cube":
                    obj.modifiers.new("Bevel", "BEVEL").width = size / 10
                elif kind in ("grid", "plane", "circle"):
                    obj.modifiers.new("Solidify", "SOLIDIFY").thickness = size / 10
            obj.name = f"Prop {i:03d}"
            objects.append(obj)
        objects += _hard_props(scene, side, 6 if subdivision < 2 else 7)
        crates = bpy.data.collections.new("Crate stack")
        for k in range(3):
            me = bpy.data.meshes.new(f"Crate {k}")
            crate = bpy.data.objects.new(f"Crate {k}", me)
            import bmesh
            bm = bmesh.new()
            bmesh.ops.create_cube(bm, size=0.5)
            bm.to_mesh(me)
            bm.free()
            crate.location = (0, 0, 0.25 + 0.5 * k)
            crates.objects.link(crate)
        empty = bpy.data.objects.new("Crate stack instance", None)
        empty.instance_type, empty.instance_collection = "COLLECTION", crates
        empty.location = (side / 2 - 1.0, side / 2 - 1.0, 0)
        scene.collection.objects.link(empty)
    for kind, energy, loc in (("SUN", 3.0, (0, 0, 10)), ("POINT", 2000.0, (0, 0, 4))):
        light = bpy.data.objects.new(f"IL level {kind.lower()}", bpy.data.lights.new(f"IL level {kind.lower()}", kind))
        light.data.energy, light.location = energy, loc
        light.rotation_euler = (0.6, 0.2, 0.4)
        scene.collection.objects.link(light)
    world = bpy.data.worlds.new("IL level sky")
    compat.ensure_use_nodes(world)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.25, 0.3, 1)
    scene.world = world
    return objects


def triangles(scene, objects):
    scene.view_layers[0].update()
    dg = scene.view_layers[0].depsgraph
    n = 0
    for o in objects:
        me = o.evaluated_get(dg).data
        me.calc_loop_triangles()
        n += len(me.loop_triangles)
    return n


def bare_bakes(scene, objects, report, options):
    """Blender's bare bake of every map in ``report``: per map kind one ``object.bake`` call with every object
    selected, each object's material carrying its own image of the report's size, its "Lightmap" layer, the same
    samples (no halves, no checks, no files). Returns {map kind: seconds}."""
    vl = scene.view_layers[0]
    render.use_cycles_cpu(scene)
    seconds = {}
    mats, images = [], []
    for kind in MAPS:
        for o in objects:
            w, h = report["objects"][o.name][kind]["resolution"]
            img = bpy.data.images.new(f"bare {o.name}", w, h, float_buffer=True, alpha=True)
            mat = bpy.data.materials.new(f"bare {o.name}")
            compat.ensure_use_nodes(mat)
            node = mat.node_tree.nodes.new("ShaderNodeTexImage")
            node.image = img
            mat.node_tree.nodes.active = node
            o.active_material = mat
            mats.append(mat)
            images.append(img)
        render.cycles_cpu(scene, int(options.samples), 0, clamp=0.0)
        scene.cycles.diffuse_bounces = 0 if kind == "ao" else int(options.bounces)
        scene.cycles.max_bounces = 0 if kind == "ao" else max(1, int(options.bounces))
        for o in vl.objects:
            o.select_set(o in objects, view_layer=vl)
        vl.objects.active = objects[0]
        ctx = dict(scene=scene, view_layer=vl, active_object=objects[0], object=objects[0],
                   selected_objects=list(objects), selected_editable_objects=list(objects))
        kw = {"type": "AO"} if kind == "ao" else {"type": "DIFFUSE", "pass_filter": {"DIRECT", "INDIRECT"}}
        with chatter.captured():
            t = time.perf_counter()
            with bpy.context.temp_override(**ctx):
                bpy.ops.object.bake(margin=0, use_clear=False, save_mode="INTERNAL", target="IMAGE_TEXTURES",
                                    uv_layer=uvmod.LIGHTMAP, **kw)
            seconds[kind] = time.perf_counter() - t
        for img in images:
            bpy.data.images.remove(img)
        images.clear()
    for mat in mats:
        bpy.data.materials.remove(mat)
    return seconds


def layout_utilisation(objects, size):
    """Covered texels (centre rule) / map texels of the objects' "Lightmap" layers in a map of ``size`` (width,
    height), over the triangles each mesh is baked with (its own loop triangles)."""
    tri = uvmod.group_triangles_uv(objects)
    return float(lightmap.coverage_mask(tri, size[0], size[1]).mean())


def pack_islands_utilisation(objects, size, margin, cut=True):
    """:func:`layout_utilisation` of the objects' "Lightmap" charts re-packed together by Blender's
    ``uv.pack_islands`` (same margin as a fraction of the side, bounding boxes, rotation; concave and convex shapes
    took minutes for a few hundred charts) in a square of the map's longer side, then (``cut``: a texel-density
    map) cut to the window of its charts as the pipeline cuts its own (``uv._cut_window``): packed as the pipeline packs, on the canonical copies
    of the meshes (``unwrap_copy.canonical_copy``, the same scale; the packer's result depends on the face order, which
    Blender's UV sphere changes from process to process), the charts carried back to the meshes' own loops (UVs of
    a w x h map given to the packer in texels / the longer side, so that its charts keep their shape)."""
    side = max(size)
    iso = np.array(size, np.float32) / side
    scene = bpy.context.scene
    vl = bpy.context.view_layer
    copies, loops = [], []
    scale = unwrap_copy.unwrap_scale(o.data for o in objects)
    try:
        for o in objects:
            me = bpy.data.meshes.new(f"IL pack {o.name}")
            copy = bpy.data.objects.new(f"IL pack {o.name}", me)
            copies.append(copy)
            loops.append(unwrap_copy.canonical_copy(o.data, me, scale)[0])
            uv = np.zeros(len(o.data.loops) * 2, np.float32)
            o.data.uv_layers[uvmod.LIGHTMAP].data.foreach_get("uv", uv)
            me.uv_layers.new(name=uvmod.LIGHTMAP, do_init=False).data.foreach_set(
                "uv", (uv.reshape(-1, 2)[loops[-1]] * iso).ravel())
            copy.matrix_world = o.matrix_world
            scene.collection.objects.link(copy)
        for o in vl.objects:
            o.select_set(o in copies)
        vl.objects.active = copies[0]
        bpy.ops.object.mode_set(mode="EDIT")
        try:
            bpy.ops.mesh.select_all(action="SELECT")
            bpy.ops.uv.select_all(action="SELECT")
            bpy.ops.uv.pack_islands(margin_method="FRACTION", margin=unwrap.margin_fraction(margin, side),
                                    rotate=True, shape_method="AABB")
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")
        tri = []
        for o, copy, back in zip(objects, copies, loops):
            packed = np.zeros(len(back) * 2, np.float32)
            copy.data.uv_layers[uvmod.LIGHTMAP].data.foreach_get("uv", packed)
            uv = np.empty_like(packed).reshape(-1, 2)
            uv[back] = packed.reshape(-1, 2)
            o.data.calc_loop_triangles()
            t = np.zeros(len(o.data.loop_triangles) * 3, np.int64)
            o.data.loop_triangles.foreach_get("loops", t)
            tri.append(uv[t].reshape(-1, 3, 2))
        tri = np.concatenate(tri)
        lo, window = (uvmod.window(tri, side, margin) if cut else None) or (np.zeros(2, np.int64),
                                                                             np.array([side, side]))
        inside = lightmap.to_window(tri.reshape(-1, 2), side, lo, window).reshape(-1, 3, 2)
        return float(lightmap.coverage_mask(inside, int(window[0]), int(window[1])).mean())
    finally:
        for copy in copies:
            me = copy.data
            bpy.data.objects.remove(copy)
            bpy.data.meshes.remove(me)


def _timed(scene, objects, out, options):
    """(wall seconds, seconds inside Cycles, report) of a bake into ``out``."""
    t = time.perf_counter()
    report = bake_lightmaps(objects, list(MAPS), out, options, scene=scene)
    wall = time.perf_counter() - t
    cycles = sum(e["cycles_seconds"] for maps in report["objects"].values() for e in maps.values())
    return wall, cycles, report


def _changed_light_rerun(scene, objects, out, options):
    """A rerun of the bake into ``out`` in a new process, as a farm or a reopened file reruns it: the level saved
    with its meshes unchanged, the "Lightmap" layers removed and the lights 1 % brighter (irradiance rebaked, AO
    unchanged), then opened and baked by another Blender (:func:`rerun_job`: layouts and figures come from the
    output folder, Blender's own caches are cold): its row figures. The saved level and the job file are written
    beside ``out`` and removed afterwards; the layers are put back here (the bare bakes bake through them)."""
    saved = {}
    for me in {o.data for o in objects}:
        if uvmod.LIGHTMAP in me.uv_layers:
            saved[me] = np.zeros(2 * len(me.loops), np.float32)
            me.uv_layers[uvmod.LIGHTMAP].data.foreach_get("uv", saved[me])
            me.uv_layers.remove(me.uv_layers[uvmod.LIGHTMAP])
    for o in scene.objects:
        if o.type == "LIGHT":
            o.data.energy *= 1.01
    folder = os.path.dirname(os.path.abspath(out))
    blend, job_file = os.path.join(folder, "rerun_level.blend"), os.path.join(folder, "rerun_job.json")
    try:
        with chatter.captured():
            bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True, check_existing=False)
        with open(job_file, "w") as f:
            json.dump({"blend": blend, "scene": scene.name, "out": os.path.abspath(out),
                       "objects": [o.name for o in objects], "options": dataclasses.asdict(options)}, f)
        code = f"import sys; sys.path.insert(0, {ROOT!r}); from addon.lab.bench import level; level.rerun_job()"
        cmd = ([bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", code]
               if bpy.app.binary_path else [sys.executable, "-c", code])
        print("[level] a rerun in a new process", file=sys.stderr, flush=True)
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace",
                              env={**os.environ, "IL_RERUN_JOB": job_file})
    finally:
        for me, uv in saved.items():
            me.uv_layers.new(name=uvmod.LIGHTMAP, do_init=False).data.foreach_set("uv", uv)
            me.update()
        for path in (blend, blend + "1", job_file):
            with contextlib.suppress(OSError):
                os.remove(path)
    rows = [line[len(_ROW):] for line in proc.stdout.splitlines() if line.startswith(_ROW)]
    if proc.returncode or not rows:          # its warnings repeat this process's own; its last lines say why it failed
        tail = " | ".join((proc.stdout.strip().splitlines() + proc.stderr.strip().splitlines())[-3:])
        raise RuntimeError(f"the rerun in a new process failed (exit {proc.returncode}): {tail}")
    return json.loads(rows[-1])


def median_rerun(rows):
    """The row of ``rows`` (of :func:`_changed_light_rerun`) with the median ratio outside / inside Cycles (the lower
    middle one of an even count), plus "reruns" and "outside_over_cycles_range" ("min-max" of the ratio)."""
    ratios = sorted(r["outside_over_cycles"] for r in rows)
    middle = ratios[(len(ratios) - 1) // 2]
    row = next(r for r in rows if r["outside_over_cycles"] == middle)
    return {**row, "reruns": len(rows), "outside_over_cycles_range": f"{ratios[0]:.3f}-{ratios[-1]:.3f}"}


ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
_ROW = "IL rerun row: "


def rerun_job():
    """The new process of :func:`_changed_light_rerun`: open the saved level, bake it, print its row."""
    with open(os.environ["IL_RERUN_JOB"]) as f:
        job = json.load(f)
    bpy.ops.wm.open_mainfile(filepath=job["blend"])
    scene = bpy.data.scenes[job["scene"]]
    objects = [bpy.data.objects[n] for n in job["objects"]]
    wall, cycles, report = _timed(scene, objects, job["out"], BakeOptions(**job["options"]))
    row = {"pipeline_seconds": round(wall, 3), "pipeline_cycles_seconds": round(cycles, 3),
           "outside_over_cycles": round((wall - cycles) / max(cycles, 1e-9), 3),
           "maps_baked": sum(len(m) for m in report["objects"].values())}
    print(_ROW + json.dumps(row), flush=True)


def evaluation_seconds(scene, objects):
    """Seconds Blender takes to evaluate the objects' meshes (their modifiers) once a UV layer is added to each, as a
    rerun adds the light-map layers: paid once by whoever reads an evaluated mesh first (a bare bake inside its
    Cycles call; the pipeline outside it for meshes its figure store does not hold). Measured last, so that no run's
    figures follow it: it leaves the meshes tagged as edited (one full-level run with it between the reruns gave
    13.5 s outside Cycles at 64 spp against 7.5 s without, though single runs on 2 shared cores vary by nearly as
    much)."""
    added = [me for me in {o.data for o in objects} if me.uv_layers.new(name="IL evaluation") is not None]
    vl = scene.view_layers[0]
    t = time.perf_counter()
    vl.update()
    for o in objects:
        len(o.evaluated_get(vl.depsgraph).data.vertices)         # a Subdivision's result is made when first read
    seconds = time.perf_counter() - t
    for me in added:
        me.uv_layers.remove(me.uv_layers["IL evaluation"])
        me.update()                                   # a layer removed does not tag the mesh for evaluation
    vl.update()
    return seconds


def run(output_dir, quick=False, props=None, texel_density=None, samples=None, reruns=None):
    """Build the level in a new scene, bake it per object (pipeline, then bare) and as an atlas; return the table
    and figures (``level`` rows: one per measurement; ``reruns`` reruns at production samples, :func:`median_rerun`)."""
    props = props or (24 if quick else 200)
    density = texel_density or 10.0
    samples = samples or (4 if quick else 8)
    reruns = reruns or RERUNS
    os.makedirs(output_dir, exist_ok=True)
    scene = bpy.data.scenes.new("IL level")
    rows, figures = [], {}
    try:
        t = time.perf_counter()
        objects = build_level(scene, props, subdivision=1 if quick else 2, floor_levels=3 if quick else 8)
        tris = triangles(scene, objects)
        figures["objects"], figures["triangles"] = len(objects), tris
        figures["build_seconds"] = time.perf_counter() - t
        rss0 = peak_rss()
        options = BakeOptions(texel_density=density, samples=samples, bounces=2, margin=2, overwrite=True,
                              max_resolution=1024)
        per_object = os.path.join(output_dir, "per_object")
        shutil.rmtree(per_object, ignore_errors=True)
        t = time.perf_counter()
        report = bake_lightmaps(objects, list(MAPS), per_object, options, scene=scene)
        wall = time.perf_counter() - t
        print(f"level: {len(objects)} objects, {tris} triangles; pipeline {wall:.1f} s", flush=True)
        rss_pipeline = peak_rss()
        t = time.perf_counter()
        bake_lightmaps(objects, list(MAPS), per_object, options, scene=scene)     # unchanged meshes: hashes only
        rerun = time.perf_counter() - t
        print(f"level: rerun with unchanged meshes {rerun:.1f} s", flush=True)
        rerun_row = _changed_light_rerun(scene, objects, per_object, options)      # before the bare bakes' materials
        print(f"level: rerun, a light changed, layouts from the UV cache {rerun_row['pipeline_seconds']:.1f} s",
              flush=True)
        baked = [o for o in objects if o.name in report["objects"]]
        texels = sum(e["resolution"][0] * e["resolution"][1] for maps in report["objects"].values()
                     for e in maps.values())
        covered = sum(e["coverage"] * e["resolution"][0] * e["resolution"][1] for maps in report["objects"].values()
                      for e in maps.values())
        cycles = sum(e["cycles_seconds"] for maps in report["objects"].values() for e in maps.values())
        fills = [maps["ao"]["coverage"] for maps in report["objects"].values() if "ao" in maps]
        low = sum("low_fill" in maps.get("ao", {}) for maps in report["objects"].values())
        bare = bare_bakes(scene, baked, report, options)
        rss_bare = peak_rss()
        bare_total = sum(bare.values())
        print(f"level: bare bakes {bare_total:.1f} s", flush=True)
        rows.append({"run": "per object", "objects": len(baked), "triangles": tris, "map_texels": texels,
                     "pipeline_seconds": round(wall, 3), "pipeline_cycles_seconds": round(cycles, 3),
                     "outside_over_cycles": round((wall - cycles) / max(cycles, 1e-9), 2),
                     "rerun_seconds": round(rerun, 3),
                     "median_fill": round(float(np.median(fills)), 3) if fills else "",
                     "maps_under_55pct": low,
                     "bare_seconds": round(bare_total, 3), "pipeline_over_bare": round(wall / bare_total, 3),
                     "texels_per_second": round(texels / wall), "covered_texels_per_second": round(covered / wall),
                     "peak_rss_mib": round(rss_pipeline / 2 ** 20, 1)})
        rows.append({"run": f"per object, light changed, {samples} spp", "objects": len(baked), **rerun_row})
        production = os.path.join(output_dir, "production")
        shutil.rmtree(production, ignore_errors=True)
        for me in {o.data for o in objects}:
            if uvmod.LIGHTMAP in me.uv_layers:
                me.uv_layers.remove(me.uv_layers[uvmod.LIGHTMAP])
        full = options.replace(samples=PRODUCTION_SAMPLES)
        FIGURES.clear()
        wall_p, cycles_p, report_p = _timed(scene, objects, production, full)
        print(f"level: pipeline at {PRODUCTION_SAMPLES} spp {wall_p:.1f} s ({cycles_p:.1f} s in Cycles)", flush=True)
        rows.append({"run": f"per object, {PRODUCTION_SAMPLES} spp", "objects": len(report_p["objects"]),
                     "triangles": tris, "pipeline_seconds": round(wall_p, 3),
                     "pipeline_cycles_seconds": round(cycles_p, 3),
                     "outside_over_cycles": round((wall_p - cycles_p) / max(cycles_p, 1e-9), 3)})
        rerun_p = median_rerun([_changed_light_rerun(scene, objects, production, full) for _ in range(reruns)])
        print(f"level: rerun at {PRODUCTION_SAMPLES} spp, a light changed {rerun_p['pipeline_seconds']:.1f} s "
              f"(median of {reruns}, outside / inside {rerun_p['outside_over_cycles_range']})", flush=True)
        production_rerun = {"run": f"per object, light changed, {PRODUCTION_SAMPLES} spp", "objects": len(baked),
                            **rerun_p}
        rows.append(production_rerun)
        atlas_dir = os.path.join(output_dir, "atlas")
        shutil.rmtree(atlas_dir, ignore_errors=True)
        t = time.perf_counter()
        atlas = bake_lightmaps(objects, list(MAPS), atlas_dir, options.replace(atlas=True, max_resolution=2048),
                               scene=scene)
        atlas_wall = time.perf_counter() - t
        print(f"level: atlas bake {atlas_wall:.1f} s", flush=True)
        members = [o for o in objects if o.name in atlas["objects"]]
        entry = atlas["objects"][members[0].name]["ao"]
        size = tuple(entry["resolution"])
        used = float(sum(atlas["objects"][o.name]["ao"]["coverage"] for o in members))
        layout = layout_utilisation(members, size)
        packed = pack_islands_utilisation(members, size, entry["margin"])
        texels = size[0] * size[1]
        rows.append({"run": "atlas", "objects": len(members), "triangles": tris, "map_texels": 2 * texels,
                     "pipeline_seconds": round(atlas_wall, 3), "texels_per_second": round(2 * texels / atlas_wall),
                     "atlas_side": "x".join(map(str, size)), "utilisation": round(used, 4), "layout_utilisation": round(layout, 4),
                     "pack_islands_utilisation": round(packed, 4),
                     "peak_rss_mib": round(peak_rss() / 2 ** 20, 1)})
        evaluation = evaluation_seconds(scene, objects)
        print(f"level: Blender's evaluation of the meshes after a UV layer is added {evaluation:.2f} s", flush=True)
        production_rerun["evaluation_seconds"] = round(evaluation, 3)
        figures.update({"evaluation_seconds": evaluation, "pipeline_over_bare": wall / bare_total,
                        "peak_rss_before_bake_mib": rss0 / 2 ** 20, "peak_rss_pipeline_mib": rss_pipeline / 2 ** 20,
                        "peak_rss_bare_mib": rss_bare / 2 ** 20,
                        "texel_density": density, "samples": samples, "skipped": dict(report.get("skipped", {})),
                        "atlas_skipped": len(atlas.get("skipped", {}))})
    finally:
        remove_scene(scene)
    keys = list(dict.fromkeys(k for row in rows for k in row))
    rows = [{k: row.get(k, "") for k in keys} for row in rows]
    return BenchResult(tables={"level": rows}, figures=figures)
