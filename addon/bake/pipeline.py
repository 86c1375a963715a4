"""The light-map pipeline: validate, UVs, temporary materials (white at the baked point), Cycles bakes, files,
restore."""
import contextlib
import hashlib
import json
import math
import os
import time

import bpy
import numpy as np

from ..blender import compat, interrupt
from ..core import budget, errors, lightmap
from ..core.io import png as io_png
from ..core.io import exr, names
from ..core.errors import ILError, InputError
from ..core.io.files import remove_stale_temporaries, write_json
from ..core.result import JobResult
from ..blender.progress import Progress
from ..blender import materials, render, scene as sc
from ..blender.state import SavedState, rna_settings, world_settings
from . import cost, orientation, uv as uvmod
from .options import BakeOptions, article, check_out_dir, shard_of, validate_maps

REPORT = "bake_report.json"
SHARD_REPORT = "bake_report.shard-{k}-of-{n}.json"
ATLAS = "atlas"
ATTRIBUTE = {"ao": "IL AO", "irradiance": "IL Irradiance"}
QUANTITY = {"ao": ("ambient occlusion k_A (1 = open)", "1"), "irradiance": ("irradiance E", "W/m^2")}
# what "estimated_error" is, per mode (bake_report.json "error_estimate", EXR "il:error_estimate")
ESTIMATES = {
    "binomial": "binomial bound: sqrt(mean k_A(1 - k_A)/N) (REFERENCE.md section 3); Cycles' stratified sampler "
                "stays below it",
    "halves": "measured: RMS of the difference of two independent half bakes, halved",
    "pilots": "measured: pairs of independent bakes (a pilot first), each pair's error from its halves' "
              "difference, inverse-variance combined",
    "none": "not estimated: a single sample of a non-binary quantity",
}
ALPHA = 0.7        # err ∝ N^-α of Cycles' AO and irradiance bakes (measured; stratified sampling of a 2-D
                   # integrand with visibility edges converges as N^-3/4, Mitchell 1996)
MAX_PAIRS = 4      # pairs of bakes target_error may spend (pilot included)
MIN_COVERAGE_TEXT = (f"covered texels >= {uvmod.MIN_COVERAGE:g} x side^2 x chart_area (the charts' UV area inside "
                     "the unit square)")
DENOISED = "; noise of the map before denoising: the denoised map's error is lower (measured) but not estimated"


class BakeResult:
    """One baked map of one object group, in Blender's pixel order (row 0 at v = 0).

    values          (H, W) k_A or (H, W, 3) E in W/m² for images; {object: (V,) or (V, 3)} for vertices
    mask            (H, W) bool covered texels (images) / None (vertices)
    samples         total Cycles samples per texel (pilots included); pilot_samples: the pilots' share
    seconds         the whole map (bakes, read-back, denoising); cycles_seconds: inside the Cycles bake calls
    estimated_error RMS over covered texels, same units as values (NaN when not estimated)
    estimate        which estimate ``estimated_error`` is (one of ESTIMATES, plus DENOISED when denoised)
    capped          a target error missed within max_samples / MAX_PAIRS (:func:`_capped`)
    """

    def __init__(self, values, mask, samples, seconds, estimated_error, estimate, pilot_samples=0,
                 cycles_seconds=0.0):
        self.values, self.mask, self.samples = values, mask, samples
        self.seconds, self.estimated_error, self.pilot_samples = seconds, estimated_error, pilot_samples
        self.estimate, self.cycles_seconds = estimate, cycles_seconds
        self.capped = False


# ------------------------------------------------------------------ validation

def applicable(scene, objects, options):
    """Split the asked objects into (the ones a bake applies to, {skipped name: reason}).

    Skipped, as Blender's own operators skip what they do not apply to: non-meshes (cameras, lights,
    curves, text, metaballs), meshes without faces, meshes linked from a library (their UV layers and
    materials cannot be edited), objects of another scene, and objects Cycles cannot see (in a collection
    excluded from the view layer or disabled for renders)."""
    vl = scene.view_layers[0]
    vl.update()
    keep, skipped = [], {}
    seen = set()
    for o in objects:
        if o is None:
            raise InputError("no such object")
        if o.name in seen:
            continue
        seen.add(o.name)
        if o.type != "MESH":
            skipped[o.name] = f"not a mesh ({article(o.type.lower())})"
        elif len(o.data.polygons) == 0:
            skipped[o.name] = "a mesh with no faces"
        elif o.library is not None or o.data.library is not None:
            skipped[o.name] = "linked from a library (not editable: make it local)"
        elif scene.objects.get(o.name) != o:
            skipped[o.name] = f"not in scene '{scene.name}'"
        elif not _renderable(vl.layer_collection, o):
            skipped[o.name] = "in a collection excluded from the view layer or disabled for renders"
        else:
            keep.append(o)
    return keep, skipped


def _renderable(layer_collection, obj):
    """``obj`` is in a collection reachable from ``layer_collection`` through collections neither excluded
    nor disabled for renders."""
    if layer_collection.exclude or layer_collection.collection.hide_render:
        return False
    if obj.name in layer_collection.collection.objects:
        return True
    return any(_renderable(child, obj) for child in layer_collection.children)


def _say_skipped(skipped):
    if skipped:
        errors.warn("skipped " + "; ".join(f"{name}: {why}" for name, why in skipped.items()))


def validate(scene, objects, maps, out, options):
    """Every input check, before anything in the file is touched. Returns (objects, maps, out, skipped, flips):
    ``flips`` {object name: mesh} are meshes inside out (:mod:`.orientation`) whose normals the bake flips."""
    options.validate()
    maps = validate_maps(maps)
    options.check_target(maps)
    objects = list(objects)
    if not objects:
        raise InputError("nothing selected: select or name at least one mesh object")
    objects, skipped = applicable(scene, objects, options)
    if not objects:
        raise InputError("nothing to bake: " + "; ".join(f"'{n}' is {why}" for n, why in skipped.items()))
    failed, first = {}, None
    for o in objects:
        if o.mode != "OBJECT":
            raise InputError(f"'{o.name}' is in {o.mode.lower()} mode: switch to object mode first")
        if options.uv_layer and options.target == "image":
            uvmod.check_layer(o, options.uv_layer)
        try:
            uvmod.check_valid(o)
            if uvmod.world_area(o) <= 0:
                raise InputError(f"mesh '{o.name}' has no surface area: all its faces are degenerate")
            if options.target == "vertex":
                _check_vertex_bakeable(o)
        except InputError as e:               # a bad mesh fails alone; the others are baked
            failed[o.name] = str(e)
            first = first or e
    objects = [o for o in objects if o.name not in failed]
    if not objects:
        raise first
    flips, inward = orientation.check(scene, objects)
    if inward:
        skipped.update(inward)
        objects = [o for o in objects if o.name not in inward]
        if not objects:
            raise InputError("nothing to bake: " + "; ".join(f"'{n}': {why}" for n, why in inward.items()))
    if options.atlas and options.target == "image":
        meshes, shared = {}, {}
        for o in objects:
            if o.data.name in meshes:
                shared[o.name] = f"shares its mesh with {meshes[o.data.name]} (one atlas place per mesh: bake it separately)"
            else:
                meshes[o.data.name] = o.name
        objects = [o for o in objects if o.name not in shared]
        skipped.update(shared)
    if options.target == "image":
        for w, h in _fixed_sizes(objects, options):
            refusal = cost.check(w, h, maps, options.denoise)
            if refusal:
                raise InputError(refusal)
        sizes = _fixed_sizes(objects, options)
        if sizes and not options.sizes and not options.atlas:
            sizes *= len(shard(objects, options)[0] if options.shard else objects)
        _check_time(sizes, maps, options, speed=speed(scene, options))
    if options.target == "vertex":
        _warn_coarse(scene, objects, maps, options)
    out = check_out_dir(out)
    if not options.overwrite:
        for path in output_files(shard(objects, options)[0] if options.shard else objects, maps, out, options,
                                 file_stems()):
            if os.path.exists(path):
                raise InputError(f"{path} exists: turn on Overwrite (--overwrite) to replace it")
    return objects, maps, out, skipped, flips, failed


#: Modifiers whose new vertices have no original vertex: Blender's vertex-colour bake writes past its buffers
#: through them (heap corruption: crashes measured in 4.5.15, 5.2.3 and 5.3.0, from a plain bpy script).
VERTEX_BAKE_UNSAFE_MODIFIERS = {"BOOLEAN": "Boolean", "REMESH": "Remesh"}


def _check_vertex_bakeable(obj):
    """InputError naming a render-enabled Boolean or Remesh modifier of ``obj`` (vertex target only)."""
    for m in obj.modifiers:
        if m.type in VERTEX_BAKE_UNSAFE_MODIFIERS and m.show_render:
            raise InputError(f"'{obj.name}': vertex colours cannot be baked through its "
                             f"{VERTEX_BAKE_UNSAFE_MODIFIERS[m.type]} modifier '{m.name}' (Blender's vertex bake "
                             f"crashes on the vertices it makes): apply the modifier, or bake an image map")


def vertex_spacing(obj):
    """Typical distance (m) between neighbouring vertices of ``obj``'s mesh in world space: 2 √(area / vertices)
    (a square's edge for a 4-vertex plane)."""
    n = max(1, len(obj.data.vertices))
    return 2.0 * math.sqrt(uvmod.world_area(obj) / n)


def _occluder_size(scene, obj):
    """The smallest largest dimension (m) of the other meshes that render, or None."""
    sizes = [max(o.dimensions) for o in scene.view_layers[0].objects
             if o.type == "MESH" and o is not obj and not o.hide_render and max(o.dimensions) > 0]
    return min(sizes) if sizes else None


def _warn_coarse(scene, objects, maps, options):
    """Warn for each object too coarse for the vertex target: its vertex spacing (:func:`vertex_spacing`) above
    the scale of what shades it (the AO distance for AO, the smallest other mesh for irradiance; the smaller of
    both when baking both), so shadows between vertices are lost; names the mesh and what to do."""
    for o in objects:
        scales = []
        if "ao" in maps:
            scales.append(("the AO distance", float(options.ao_distance)))
        near = _occluder_size(scene, o)
        if near is not None:
            scales.append(("the smallest other object", near))
        if not scales:
            continue
        what, scale = min(scales, key=lambda x: x[1])
        spacing = vertex_spacing(o)
        if spacing <= scale:
            continue
        cuts = math.ceil(2 * spacing / scale)
        errors.warn(f"'{o.name}': too coarse for vertex colours: its {len(o.data.vertices)} vertices lie about "
                    f"{spacing:.3g} m apart, more than {what} ({scale:.3g} m), so contact shadows between them are "
                    f"lost: subdivide it (about {cuts} cuts per edge) or bake an image map (--target image)")


def _check_time(sizes, maps, options, side_option="resolution", speed=None):
    """InputError when the maps of ``sizes`` take longer than ``core.budget.MAX_SECONDS`` by the progress line's
    figures (:func:`cost.check_time` with :func:`_planned_samples` and ``speed``); a target error names the side,
    not samples."""
    cost.check_time(sizes, maps, _planned_samples(options), None if options.target_error is not None else "samples",
                    side_option, speed)


def speed(scene, options):
    """The :class:`cost.Speed` of ``scene``'s bakes: the largest image of its world's node tree (an Environment or
    Image Texture), its lights that render, ``options.bounces``."""
    pixels = 0
    world = scene.world
    if world is not None and world.node_tree is not None:
        for node in world.node_tree.nodes:
            image = getattr(node, "image", None)
            if node.type in ("TEX_ENVIRONMENT", "TEX_IMAGE") and not node.mute and image is not None:
                pixels = max(pixels, int(image.size[0]) * int(image.size[1]) or 1024 * 512)
    lights = sum(1 for o in scene.view_layers[0].objects if o.type == "LIGHT" and not o.hide_render)
    return cost.Speed(pixels, lights, int(options.bounces))


def _fixed_sizes(objects, options):
    """The map sizes known before the UV step (fixed resolution, per-object sizes)."""
    if options.sizes:
        return [tuple(options.sizes[o.name]) for o in objects if o.name in options.sizes]
    if options.texel_density is None:
        return [(int(options.resolution), int(options.resolution))]
    return []


def file_stems():
    """{object name: file stem} for every object of the file (core.io.names.file_stems: one path component,
    unique also where case is ignored, the same in every shard and rerun), the atlas' own stem included. Object
    names are user data: a map's file name is built from its stem only."""
    stems = names.file_stems(o.name for o in bpy.data.objects)
    stems[ATLAS] = ATLAS
    return stems


def map_file(out, stems, name, kind, suffix=".exr"):
    """``<out>/<stem>_<kind><suffix>`` of the map of object (or atlas) ``name``."""
    return os.path.join(out, f"{stems[name]}_{kind}{suffix}")


def output_files(objects, maps, out, options, stems=None):
    """The map files a bake would write (EXR and PNG per map, or one vertex EXR per object and map)."""
    stems = stems or file_stems()
    files = []
    groups = [ATLAS] if (options.atlas and options.target == "image") else [o.name for o in objects]
    for name in groups:
        for m in maps:
            if options.target == "image":
                files += [map_file(out, stems, name, m), map_file(out, stems, name, m, ".png")]
            else:
                files.append(map_file(out, stems, name, m, "_vertex.exr"))
    return files


# ------------------------------------------------------------------ resume: what determines a map

HASH_KEY = "il:input_hash"


def _rna_digest(h, struct):
    """A modifier's type and every setting (objects and node groups it uses by name, a node group's tree)."""
    h.update(struct.bl_rna.identifier.encode())
    for prop in struct.bl_rna.properties:
        if prop.identifier in ("rna_type", "name", "is_override_data_editable", "show_expanded", "is_active",
                               "show_viewport", "show_in_editmode", "show_on_cage", "persistent_uid"):
            continue
        value = getattr(struct, prop.identifier, None)
        if hasattr(value, "name") and hasattr(value, "bl_rna"):
            h.update(f"{prop.identifier}={value.name}".encode())
            if isinstance(value, bpy.types.NodeTree):
                _node_tree_digest(h, value)
        elif isinstance(value, (int, float, str, bool)) or value is None:
            h.update(f"{prop.identifier}={value!r}".encode())
        elif hasattr(value, "__len__") and not hasattr(value, "bl_rna"):
            try:
                h.update(f"{prop.identifier}={tuple(value)!r}".encode())
            except TypeError:
                pass
_HASHED_OPTIONS = ("resolution", "texel_density", "max_resolution", "samples", "target_error", "pilot_samples",
                   "max_samples", "ao_distance", "margin", "denoise", "uv_layer", "target", "atlas", "seed")


def _node_tree_digest(h, tree):
    """Node types, their unlinked input values and the links of a node tree (what shades, not where nodes sit)."""
    if tree is None:
        h.update(b"-")
        return
    for n in sorted(tree.nodes, key=lambda n: n.name):
        h.update(f"{n.name}:{n.bl_idname}".encode())
        if getattr(n, "image", None) is not None:
            h.update(n.image.name.encode())
        for sock in n.inputs:
            value = getattr(sock, "default_value", None)
            if value is not None and not sock.is_linked:
                h.update(repr(tuple(value) if hasattr(value, "__len__") else value).encode())
    for link in tree.links:
        h.update(f"{link.from_node.name}.{link.from_socket.identifier}>{link.to_node.name}.{link.to_socket.identifier}"
                 .encode())


def lighting_digest(scene):
    """Digest of what lights the scene: every renderable light (type, colour, power, size, transform) and the world's
    node tree."""
    h = hashlib.blake2b(digest_size=16)
    for o in sorted(scene.objects, key=lambda o: o.name):
        if o.type == "LIGHT" and not o.hide_render:
            d = o.data
            h.update(f"{o.name}:{d.type}:{tuple(d.color)}:{d.energy}:{getattr(d, 'shadow_soft_size', 0)}:"
                     f"{getattr(d, 'angle', 0)}:{getattr(d, 'spot_size', 0)}:{getattr(d, 'size', 0)}".encode())
            h.update(np.array(o.matrix_world, np.float64).tobytes())
            _node_tree_digest(h, d.node_tree if compat.uses_nodes(d) else None)
    world = scene.world
    h.update(b"world" if world is not None else b"no world")
    if world is not None:
        _node_tree_digest(h, world.node_tree)
    return h.hexdigest()


def input_hash(scene, group, kind, options, lighting):
    """Hash of what determines map ``kind`` of ``group``: each object's evaluated mesh, as its base mesh (positions
    and triangles, exact), its modifiers' settings and the evaluated counts (the evaluated positions themselves
    change in their last bit when a UV layer is added under a Subdivision; the UVs of ``options.uv_layer`` when
    given), its transform and its materials' node trees, the
    lights and world (``lighting``, :func:`lighting_digest`; irradiance only) and the options that change the map.
    Other objects are not in it: moving an occluder leaves its neighbours' maps as they are (``force`` bakes them)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(f"{kind}:{bpy.app.version_string}".encode())
    for name in _HASHED_OPTIONS:
        h.update(f"{name}={getattr(options, name)!r};".encode())
    if kind != "ao":
        h.update(f"bounces={options.bounces};{lighting}".encode())
    depsgraph = scene.view_layers[0].depsgraph
    for o in group:
        h.update(o.name.encode())
        if options.sizes and o.name in options.sizes:
            h.update(repr(tuple(options.sizes[o.name])).encode())
        h.update(np.array(o.matrix_world, np.float64).tobytes())
        me = o.data
        co = np.zeros(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        me.calc_loop_triangles()
        tris = np.zeros(len(me.loop_triangles) * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tris)
        h.update(co.tobytes())
        h.update(tris.tobytes())
        for mod in o.modifiers:
            if mod.show_render:
                _rna_digest(h, mod)
        ev = o.evaluated_get(depsgraph).data
        h.update(f"{len(ev.vertices)}:{len(ev.polygons)}".encode())
        if options.uv_layer and options.uv_layer in me.uv_layers:
            uv = np.zeros(len(me.loops) * 2, np.float32)
            me.uv_layers[options.uv_layer].data.foreach_get("uv", uv)
            h.update(uv.tobytes())
        for slot in o.material_slots:
            mat = slot.material
            h.update((mat.name if mat else "-").encode())
            if kind != "ao" and mat is not None:
                h.update(repr(tuple(mat.diffuse_color)).encode())
                _node_tree_digest(h, mat.node_tree)
    return h.hexdigest()


def stored_hash(path):
    """The input hash in the header of a map file this pipeline wrote, or None."""
    stored = _stored(path)
    return None if stored is None else _text(stored[0].get(HASH_KEY))


def _stored(path):
    """(header, (width, height)) of a map file on disk, or None when it is missing or cannot be read."""
    if not os.path.exists(path):
        return None
    try:
        channels, header = exr.read_exr(path)
    except (OSError, RuntimeError, ValueError):
        return None
    shape = next(iter(channels.values())).shape if channels else (0, 0)
    return header, (int(shape[1]), int(shape[0]))


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def _map_file(name, kind, out, options, group, stems):
    if options.target == "image":
        return map_file(out, stems, name, kind)
    return map_file(out, stems, group[0].name, kind, "_vertex.exr")


# ------------------------------------------------------------------ public entry point

def bake_lightmaps(objects, maps, out, options=None, scene=None, on_step=None):
    """Bake ``maps`` ("ao", "irradiance"; None: ``options.maps``) of mesh ``objects`` into folder ``out``;
    return a :class:`core.result.JobResult` (reads as the report, ``path`` is bake_report.json).

    Writes ``<out>/<object>_<map>.exr`` (+ ``.png`` preview) per object (``atlas_<map>``
    with ``options.atlas``), or ``<object>_<map>_vertex.exr`` for the vertex target, and
    merges ``<out>/bake_report.json`` (a shard's part with ``options.shard``), which then holds every asked-for
    map on disk: maps unchanged under ``overwrite`` too (:func:`_kept_entries`), also when nothing is baked. The user's file comes back as it was (materials,
    images, UV layers, selection, active object, render settings), also on errors and
    interruptions; only the products (generated "Lightmap" UV layer, "IL AO" /
    "IL Irradiance" colour attributes) stay when ``options.keep_products``.
    ``on_step(message)`` is called at every step (progress hooks, tests).

    Report entry per object and map: DESIGN.md's "file", "resolution", "samples" (per texel, all bakes),
    "seconds" (the map's bakes, denoising and files) and "estimated_error" (RMS over covered texels,
    None when not estimated), plus "error_estimate" (which estimate that is, see ESTIMATES),
    "cycles_seconds" (inside the Cycles bake calls), "pilot_samples" (target_error runs) and, for
    images, "preview", "uv_layer", "coverage", "denoised".
    """
    options = options or BakeOptions()
    scene = scene or bpy.context.scene
    objects, maps, out, skipped, flips, failed = validate(scene, objects, maps, out, options)
    remove_stale_temporaries(out)              # what a killed earlier run was writing
    _say_skipped(skipped)
    if options.denoise and options.target != "image":
        errors.warn("denoise ignored: the denoiser works on image maps, not on vertex colours")
    t_all = time.perf_counter()
    everyone = list(objects)                   # show their bake materials to the others' bakes, baked or not
    report_name = REPORT
    if options.shard:
        objects, report_name = shard(objects, options)
    groups = [(ATLAS, objects)] if (options.atlas and options.target == "image") else [(o.name, [o]) for o in objects]
    lighting = lighting_digest(scene)
    digests = {(name, m): input_hash(scene, group, m, options, lighting) for name, group in groups for m in maps}
    stems = file_stems()
    unchanged, kept = {}, {}
    report_path = os.path.join(out, report_name)
    if options.overwrite and not options.force:
        old_reports = [_read_objects(report_path), _read_objects(os.path.join(out, REPORT))]
        for name, group in groups:
            for m in maps:
                stored = _stored(_map_file(name, m, out, options, group, stems))
                if stored is not None and _text(stored[0].get(HASH_KEY)) == digests[(name, m)]:
                    unchanged.setdefault(name, []).append(m)
                    for o, e in _kept_entries(name, group, m, out, options, stems, stored, old_reports).items():
                        kept.setdefault(o, {})[m] = e
    groups = [(name, group) for name, group in groups if len(unchanged.get(name, ())) < len(maps)]
    objects = [o for _, group in groups for o in group]
    steps = (1 if options.target == "image" and groups else 0) + sum(len(maps) - len(unchanged.get(n, ()))
                                                                        for n, _ in groups)
    report = {"objects": {}, "skipped": dict(skipped), "unchanged": unchanged, "failed": failed}
    if kept or not groups:                 # the report describes the unchanged maps too, also if nothing is baked
        _merge_report(report_path, {"objects": kept, "seconds": time.perf_counter() - t_all, "skipped": dict(skipped),
                                    "unchanged": unchanged, "failed": failed})
    if not groups:
        report["seconds"] = time.perf_counter() - t_all
        return JobResult(report, report_path, summary(report))
    with Progress("bake", steps) as progress, SavedState(scene, everyone, _settings(scene)) as state:
        def step(message):
            progress.step(message)
            if on_step:
                on_step(message)

        _show(everyone, state)
        _flip_inside_out(scene, everyone, flips, state)
        _setup_render(scene, options, state)
        layers, sides, margins = {}, {}, {}
        temporary = TemporaryMaterials(state)
        errors_ = []

        def fail(name, error):
            """Record a group's failure; the level goes on (the error itself is raised when nothing else is baked)."""
            failed[name] = str(error)
            errors_.append(error)
            errors.warn(f"'{name}' failed: {error}")

        if options.target == "image":
            step("light-map UVs")
            if options.atlas:
                layers, sides, margins = uvmod.prepare(scene, objects, state, options, together=True)
            else:
                for name, group in groups:
                    try:
                        made = uvmod.prepare(scene, group, state, options)
                    except (InputError, ILError) as e:
                        fail(name, e)
                        continue
                    for have, new in zip((layers, sides, margins), made):
                        have.update(new)
        plan = []
        for name, group in groups:             # every size and coverage check before the first bake
            if name in failed:
                continue
            try:
                size = _map_size(group, layers, sides, options)
                areas, overlap = None, None
                if size is not None:
                    refusal = cost.check(size[0], size[1], maps, options.denoise, what=_size_option(options))
                    if refusal:
                        raise InputError(f"'{name}': {refusal}")
                    areas = uvmod.check_coverage(group, layers, size)
                    overlap = uvmod.check_overlap(scene, group, layers, size)
            except (InputError, ILError) as e:
                fail(name, e)
                continue
            plan.append((name, group, size, areas, overlap))
        if not plan:
            raise errors_[0]
        if options.texel_density is not None and not options.sizes:
            _check_time([e[2] for e in plan if e[2]], maps, options, "max resolution", speed(scene, options))
        batched, singles = batches(scene, plan, layers, state, options, maps)
        tracker = _Tracker(plan, maps, unchanged, options)

        def finish(entry, m, result, t_map):
            name, group, size, areas, overlap = entry
            if size is not None:
                _check_covered(name, group, m, result, layers, areas)
            if m == "ao":
                _check_plausible(scene, name, group, result, options)
            margin = margins.get(group[0].name, float(options.margin))
            t_files = time.perf_counter()
            result.seconds += t_files - t_map     # the header's il:seconds: bakes and checks, not the files
            entries = _write(name, group, m, result, out, options, layers, margin, overlap, digests[(name, m)],
                             stems)
            part = {"objects": {}, "skipped": report["skipped"], "unchanged": unchanged}
            for o in group:
                entries[o.name]["seconds"] = round(result.seconds + time.perf_counter() - t_files, 4)  # files included
                report["objects"].setdefault(o.name, {})[m] = entries[o.name]
                part["objects"].setdefault(o.name, {})[m] = entries[o.name]
            part["seconds"] = time.perf_counter() - t_all
            _merge_report(report_path, part)      # finished maps are in the report, also if a later one fails

        pace = speed(scene, options)

        def announce(entry, m):
            name, _, size = entry[:3]
            estimate = ""
            if size:
                peak = cost.peak_bytes(size[0], size[1], [m], options.denoise)
                estimate = (f" {size[0]}x{size[1]} (about {budget.format_bytes(peak)}, "
                            f"{cost.seconds(size[0], size[1], [m], _planned_samples(options), pace):.2g} s)")
            step(f"{name}: {m}" + (estimate or " (vertices)") + tracker.line())
            tracker.done(entry, m)

        for m in maps:
            temporary.assign(everyone, m)      # every object shows the same materials to the others' bakes
            alone = []
            for batch in batched:
                batch = [e for e in batch if m not in unchanged.get(e[0], ()) and e[0] not in failed]
                if not batch:
                    continue
                try:
                    results = bake_batch(scene, batch, m, options, layers, temporary, state)
                except ILError:
                    alone += batch              # one of them breaks the shared call: bake each alone to find it
                    continue
                for entry in batch:
                    announce(entry, m)
                    try:
                        finish(entry, m, results.pop(entry[0]), time.perf_counter())
                    except (InputError, ILError) as e:
                        fail(entry[0], e)
            for entry in alone + singles:
                if m in unchanged.get(entry[0], ()) or entry[0] in failed:
                    continue
                name, group, size = entry[:3]
                announce(entry, m)
                t_map = time.perf_counter()
                try:
                    result = bake_map(scene, group, m, options, layers, size, temporary.assign(group, m), state)
                    result.seconds = 0.0
                    finish(entry, m, result, t_map)
                except (InputError, ILError) as e:
                    fail(name, e)
        if errors_ and not report["objects"]:
            raise errors_[0]
        if options.keep_products:       # products stay only when the whole bake succeeded (failed objects aside)
            state.keep |= {(o.data.name, uvmod.LIGHTMAP) for o in objects if o.name not in failed}
            state.keep |= {(o.data.name, ATTRIBUTE[m]) for o in objects for m in maps if o.name not in failed}
        progress_line = tracker.final(report)
    report["seconds"] = time.perf_counter() - t_all
    if failed:
        _merge_report(report_path, {"objects": {}, "seconds": report["seconds"], "failed": failed})
    return JobResult(report, report_path, summary(report) + progress_line)


class _Tracker:
    """Objects and texels done of a level bake, the elapsed time and the ETA from the texels per second so far."""

    def __init__(self, plan, maps, unchanged, options):
        self.t0 = time.perf_counter()
        self.texels = {}
        for name, group, size, *_ in plan:
            per = size[0] * size[1] if size else sum(len(o.data.vertices) for o in group)
            for m in maps:
                if m not in unchanged.get(name, ()):
                    self.texels[(name, m)] = per
        self.total = sum(self.texels.values())
        self.objects = {name for name, _ in self.texels}
        self.finished, self.texels_done, self.objects_done = set(), 0, set()

    def done(self, entry, m):
        key = (entry[0], m)
        if key in self.texels and key not in self.finished:
            self.finished.add(key)
            self.texels_done += self.texels[key]
            if all((entry[0], k) in self.finished for n, k in self.texels if n == entry[0]):
                self.objects_done.add(entry[0])

    def line(self):
        elapsed = time.perf_counter() - self.t0
        rate = self.texels_done / elapsed if elapsed > 0 and self.texels_done else 0.0
        eta = f"{(self.total - self.texels_done) / rate:.0f} s" if rate else "?"
        text = (f" | objects {len(self.objects_done)}/{len(self.objects)}, texels {self.texels_done}/{self.total}, "
                f"{elapsed:.1f} s, ETA {eta}")
        try:
            if not bpy.app.background and bpy.context.workspace is not None:
                bpy.context.workspace.status_text_set(f"Light maps:{text[2:]}")
        except (AttributeError, RuntimeError):
            pass
        return text

    def final(self, report):
        try:
            if not bpy.app.background and bpy.context.workspace is not None:
                bpy.context.workspace.status_text_set(None)
        except (AttributeError, RuntimeError):
            pass
        elapsed = time.perf_counter() - self.t0
        return f" ({self.texels_done} texels in {elapsed:.1f} s, {self.texels_done / max(elapsed, 1e-9):.0f} texels/s)"


def estimated_texels(obj, options):
    """Texels of ``obj``'s map before its UVs exist: its fixed size, else T² × world area / 0.6 (a typical chart
    coverage), else one; what shards balance."""
    if options.sizes and obj.name in options.sizes:
        w, h = options.sizes[obj.name]
        return int(w) * int(h)
    if options.texel_density is None:
        return int(options.resolution) ** 2 if options.target == "image" else len(obj.data.vertices)
    return float(options.texel_density) ** 2 * uvmod.world_area(obj) / 0.6


def shard(objects, options):
    """(objects of shard K of N, its report file name). Deterministic: objects (those sharing a mesh together: the
    first one's light-map layer is reused by the others) by estimated texels, largest first, then by name, each go
    to the shard with the fewest texels so far (ties: lowest index); an atlas is one map and is baked whole by
    shard 1."""
    k, n = shard_of(options.shard)
    name = SHARD_REPORT.format(k=k, n=n)
    if options.atlas and options.target == "image":
        return (list(objects) if k == 1 else []), name
    units = {}                    # objects sharing a mesh share its light-map layer: one shard bakes them all
    for o in objects:
        units.setdefault(o.data.name, []).append(o)
    load = [0.0] * n
    mine = []
    for unit in sorted(units.values(), key=lambda u: (-sum(estimated_texels(o, options) for o in u), u[0].name)):
        i = min(range(n), key=lambda j: (load[j], j))
        load[i] += sum(estimated_texels(o, options) for o in unit)
        if i == k - 1:
            mine += unit
    order = {o.name: i for i, o in enumerate(objects)}
    return sorted(mine, key=lambda o: order[o.name]), name


def merge_reports(folder):
    """Join the shard report parts (bake_report.shard-K-of-N.json) of ``folder`` into its bake_report.json; return
    a JobResult. The report's entries stay and the parts' update them (per object and map); "skipped" and
    "unchanged" are the parts' unions, "seconds" their sum. Only the parts of the latest split (the N of the newest
    part) are joined; parts of other splits and missing shares are named in a warning. A part (or report) that
    cannot be read is moved aside (:func:`_aside`) with a warning and the rest merged."""
    import re
    pattern = re.compile(r"bake_report\.shard-(\d+)-of-(\d+)\.json")
    found = {}
    for entry in sorted(os.listdir(folder)) if os.path.isdir(folder) else []:
        match = pattern.fullmatch(entry)
        if match:
            found[os.path.join(folder, entry)] = (int(match.group(1)), int(match.group(2)))
    if not found:
        raise InputError(f"no shard reports (bake_report.shard-K-of-N.json) in {folder}")
    n = found[max(found, key=lambda p: (os.path.getmtime(p), found[p][1]))][1]
    stale = sorted(os.path.basename(p) for p, (_, m) in found.items() if m != n)
    if stale:
        errors.warn(f"ignored the parts of an earlier split (the latest has {n} shares): " + ", ".join(stale))
    parts = sorted((p for p, (_, m) in found.items() if m == n), key=lambda p: found[p][0])
    missing = sorted(set(range(1, n + 1)) - {found[p][0] for p in parts})
    if missing:
        errors.warn(f"no report part of shard(s) {', '.join(f'{k}/{n}' for k in missing)} in {folder}: "
                    "their maps are not in the merged report")
    path = os.path.join(folder, REPORT)
    with report_lock(folder):
        old = _load_report(path, "a new report started") or {}
        merged = {"objects": old.get("objects", {}), "skipped": {}, "unchanged": {}, "failed": {}, "seconds": 0.0,
                  "shards": []}
        joined = []
        for part_path in parts:
            part = _load_report(part_path, "merged without it")
            if part is None:
                continue
            joined.append(part)
            for obj, maps in part.get("objects", {}).items():
                merged["objects"].setdefault(obj, {}).update(maps)
            merged["skipped"].update(part.get("skipped", {}))
            for obj, maps in part.get("unchanged", {}).items():
                have = merged["unchanged"].setdefault(obj, [])
                have.extend(m for m in maps if m not in have)
            merged["seconds"] += float(part.get("seconds", 0.0))
            merged["shards"].append(os.path.basename(part_path))
            merged["blender_version"] = part.get("blender_version")
        if not joined:
            raise InputError(f"no readable shard reports (bake_report.shard-K-of-N.json) in {folder}")
        named = {obj for part in joined for obj in part.get("objects", {})}
        merged["failed"] = {k: v for k, v in old.get("failed", {}).items() if k not in named}
        for part in joined:
            merged["failed"].update(part.get("failed", {}))
        write_json(path, merged)
    return JobResult(merged, path, summary(merged) + f" ({len(joined)} shard reports merged)")


def summary(report):
    """One line: what was baked and what was skipped, with the reason."""
    baked = ", ".join(f"{o} ({', '.join(maps)})" for o, maps in report["objects"].items()) or "nothing"
    line = f"baked {baked}"
    if report.get("unchanged"):
        line += f"; unchanged (skipped, inputs as baked) {sum(len(m) for m in report['unchanged'].values())} map(s): " \
                + ", ".join(f"{o} ({', '.join(m)})" for o, m in report["unchanged"].items())
    if report.get("skipped"):
        line += "; skipped " + "; ".join(f"{n} ({why})" for n, why in report["skipped"].items())
    if report.get("failed"):
        line += f"; FAILED {len(report['failed'])}: " + "; ".join(f"{n} ({why})" for n, why in report["failed"].items())
    return line


def _planned_samples(options):
    return int(options.samples) if options.target_error is None else int(options.max_samples)


def _show(objects, state):
    """Hidden objects are baked: shown in the viewport for the bake (Cycles ignores viewport hiding); objects
    hidden for render are shown to Cycles only while their own map bakes (:func:`_bake_once`), so they
    occlude and light themselves but no other object, as in a render without them."""
    vl = state.scene.view_layers[0]
    state.render_hidden = [o for o in objects if o.hide_render]
    for o in objects:
        state.unhide(o)
    if state.render_hidden:
        errors.warn("baked although hidden for render: " + ", ".join(o.name for o in state.render_hidden)
                    + " (each is shown to Cycles only for its own map: it occludes itself, and other objects' "
                    "maps are baked without it, as a render sees them)")
    return vl


def _flip_inside_out(scene, objects, flips, state):
    """Flip the normals of the inside-out meshes found by :func:`validate` for the bake (with a warning), and
    check that the evaluated meshes now face out (a modifier may depend on the side the normals face)."""
    if not flips:
        return
    for mesh in dict.fromkeys(flips.values()):
        state.flip_normals(mesh)
    scene.view_layers[0].update()
    for o in objects:
        if o.name in flips and orientation.empty_inward_shells(scene, o)[0] > 0:
            raise InputError(f"'{o.name}': its normals point into a closed, empty surface and flipping them does "
                             f"not turn its evaluated mesh outward (a modifier depends on them): {orientation.FIX}")
    errors.warn(orientation.describe(list(flips)))


def _check_plausible(scene, name, group, result, options):
    """An AO map that is 0 on every covered texel (vertex) of objects whose faces look into the objects themselves
    (most face normals hit their own object: a surface wound inside out that :mod:`.orientation` could not turn,
    e.g. faces split apart) with nothing inside (no light, no other object: not a room) measures the empty inside
    of the object: refuse it instead of writing it."""
    values = _flat(result.values) if isinstance(result.values, dict) else result.values[result.mask]
    if values.size and float(np.max(values)) <= 0.0 and all(
            orientation.faces_into_itself(scene, o) > 0.5 and not orientation.holds_something(scene, o) for o in group):
        raise ILError(f"'{name}' ao: 0 on every {'texel' if result.mask is not None else 'vertex'}: its faces look "
                      f"into the object itself, so the bake measured its inside (normals pointing inward; "
                      f"{orientation.FIX}): nothing written")


def _check_covered(name, group, kind, result, layers, areas):
    """The baked mask must cover MIN_COVERAGE of the charts' area (never report an empty map as a success)."""
    h, w = result.mask.shape
    expected = sum(areas.values()) * w * h
    covered = int(result.mask.sum())
    if covered < uvmod.MIN_COVERAGE * expected:
        raise ILError(f"'{name}' {kind}: Cycles covered {covered} texels of the {expected:.0f} its charts span "
                      f"(minimum {100 * uvmod.MIN_COVERAGE:.0f} %): nothing written")


# ------------------------------------------------------------------ bakes

def _size_option(options):
    """The option a refused map side is lowered with: the fixed resolution, or the cap of the texel-density side."""
    return "resolution" if options.texel_density is None or options.sizes else "max resolution"


def _map_size(group, layers, sides, options):
    """(width, height) of the group's image map (None for the vertex target): ``options.sizes``, else the
    fixed resolution or the texel-density side, never below the side a generated layout's margin was made for."""
    if options.target != "image":
        return None
    if options.sizes and group[0].name in options.sizes:
        w, h = options.sizes[group[0].name]
        return int(w), int(h)
    res = max(uvmod.resolution(group, layers, options), sides.get(group[0].name, 0))
    return res, res


def _settings(scene):
    """What a bake may change besides its objects, saved and put back by SavedState: the Cycles setup, every
    bounce limit, the bake settings, the world and its AO distance."""
    cy = scene.cycles
    bounces = [(cy, a) for a in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                                 "volume_bounces", "transparent_max_bounces", "sample_offset") if hasattr(cy, a)]
    return render.settings(scene) + bounces + rna_settings(scene.render.bake) + world_settings(scene)


def _setup_render(scene, options, state):
    """Cycles on the CPU (each bake call sets the rest, :func:`_bake_once`), the AO distance; a black world if none."""
    render.use_cycles_cpu(scene)
    state.world(sc.black_world).light_settings.distance = float(options.ao_distance)


class TemporaryMaterials:
    """The temporary materials of a run, made once and assigned per map.

    AO (geometry only): one material with no closure (materials.no_closure) shared by every slot, just a
    carrier of the active image node: Cycles then samples no BSDF and no light at the baked points, and
    the AO pass, which reads the geometry only, is the same bit for bit as with a white Lambert (measured
    on the demo's four objects) in less than half the time.

    Irradiance: per original slot material a copy whose surface is
    ``Mix(original, white Lambert, factor = Light Path "Is Camera Ray")``. Cycles starts
    every bake sample at the baked point with a camera path state (PATH_RAY_CAMERA,
    cleared at the first bounce), so the receiving point is white Lambertian (the
    DIFFUSE bake without COLOR then returns E/π even on black, metallic or textured
    surfaces, REFERENCE.md §1) while every ray that reaches the object later sees its
    own albedo and emission: bounces between baked objects stay physical. The copy's
    Displacement input is unlinked so that E is taken about the mesh normal.
    """

    def __init__(self, state):
        self.state = state
        self.ao = {}              # group key (None: per-object bakes) -> (material, image node)
        self.copies = {}          # (original material or None, group key) -> (copy, image node)

    def assign(self, group, kind):
        """Put the ``kind`` materials on every slot of ``group``; return their image nodes."""
        nodes = []
        for o in group:
            originals = [mat for _, mat in self.state.slots[o.name]] or [None]
            if len(o.material_slots) == 0:
                o.data.materials.append(None)
            for slot, orig in zip(o.material_slots, originals):
                mat, tex = self._ao() if kind == "ao" else self._irradiance(orig)
                if slot.material != mat:
                    slot.material = mat
                if tex not in nodes:
                    nodes.append(tex)
        return nodes

    def batch_slots(self, obj, kind, key, image):
        """The ``kind`` materials of ``obj``'s slots (one for an object without slots) for a batched bake, their
        image nodes on ``image``: made once per group ``key`` and original material."""
        originals = [mat for _, mat in self.state.slots[obj.name]] or [None]
        out = []
        for orig in originals:
            mat, tex = self._ao(key) if kind == "ao" else self._irradiance(orig, key)
            tex.image = image
            out.append(mat)
        return out

    def _new(self, name):
        return self.state.track(bpy.data.materials, materials.empty_material(name))

    @staticmethod
    def _image_node(nt):
        tex = nt.nodes.new("ShaderNodeTexImage")
        nt.nodes.active = tex
        return tex

    def _ao(self, key=None):
        if key not in self.ao:
            mat = materials.no_closure("IL bake AO", self._new("IL bake AO"))
            self.ao[key] = (mat, self._image_node(mat.node_tree))
        return self.ao[key]

    def _irradiance(self, orig, key=None):
        if (orig, key) in self.copies:
            return self.copies[(orig, key)]
        if orig is None or not compat.uses_nodes(orig) or orig.node_tree is None:
            # Cycles shades such a slot with a plain diffuse of the viewport colour (grey without material)
            mat = self._new(f"IL bake {orig.name if orig else 'default'}")
            nt = mat.node_tree
            base = nt.nodes.new("ShaderNodeBsdfDiffuse")
            base.inputs["Color"].default_value = tuple(orig.diffuse_color) if orig else (0.8, 0.8, 0.8, 1.0)
            surface = base.outputs["BSDF"]
            out = None
        else:
            mat = self.state.track(bpy.data.materials, orig.copy())
            mat.name = f"IL bake {orig.name}"
            nt = mat.node_tree
            out = nt.get_output_node("CYCLES")
            surface = None
            if out is not None:
                links = out.inputs["Surface"].links
                surface = links[0].from_socket if links else None
                for link in out.inputs["Displacement"].links:
                    nt.links.remove(link)
        if out is None:
            for n in nt.nodes:
                if n.bl_idname == "ShaderNodeOutputMaterial":
                    n.is_active_output = False
            out = nt.nodes.new("ShaderNodeOutputMaterial")
            out.target = "ALL"
            out.is_active_output = True
        mix = nt.nodes.new("ShaderNodeMixShader")
        path = nt.nodes.new("ShaderNodeLightPath")
        nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
        if surface is not None:
            nt.links.new(surface, mix.inputs[1])
        nt.links.new(materials.white_diffuse_node(nt).outputs["BSDF"], mix.inputs[2])
        nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
        self.copies[(orig, key)] = (mat, self._image_node(nt))
        return self.copies[(orig, key)]


def bake_map(scene, group, kind, options, layers, size, image_nodes, state):
    """Bake one map of one object group (UVs and materials in place); return a :class:`BakeResult`.

    Samples and the error estimate (``ESTIMATES``), per mode:
    - target_error: pilot pairs and a final pair (:func:`_bake_to_error`), error measured;
    - irradiance, N >= 2 samples: two independent half bakes, error measured from their difference
      (E is not a binary quantity: there is no a-priori bound);
    - AO: one N-sample bake (Cycles' stratified sampler converges faster than two independent halves
      would), error = the binomial bound √(mean k_A(1 - k_A)/N) of REFERENCE.md §3.
    Denoising (image target) runs last; the estimate then stays that of the map before denoising.
    Each bake is the Cycles calls of :func:`_passes` (one call unless it is estimated beyond cost.PASS_SECONDS).
    """
    t0 = time.perf_counter()
    for o in state.render_hidden:               # hidden for render: seen by Cycles only for its own map
        if o.hide_render != (o not in group):
            o.hide_render = o not in group
    image_target = options.target == "image"
    image = None
    if image_target:
        image = state.track(bpy.data.images, bpy.data.images.new(f"IL {kind}", size[0], size[1],
                                                                 float_buffer=True, alpha=True))
        for tex in image_nodes:
            tex.image = image
    else:
        for o in group:
            me = o.data
            name = ATTRIBUTE[kind]
            if name not in me.color_attributes:
                me.color_attributes.new(name, "FLOAT_COLOR", "POINT")
                state.created_attribute(me, name)
            me.color_attributes.active_color_name = name
    uv_name = layers.get(group[0].name) if image_target else None
    inside = _centre_texels(group, layers, size) if image_target else None
    timer = {"cycles": 0.0}

    texels = size[0] * size[1] if image_target else sum(len(o.data.loops) for o in group)
    pace = speed(scene, options)

    def once(samples, seed):
        total = _PassSum(samples)
        for n, s in _passes(kind, samples, seed, texels, pace):
            values, mask, seconds = _bake_once(scene, group, kind, n, s, image, uv_name, options, inside)
            timer["cycles"] += seconds
            total.add(values, mask, n)
        return total.result()

    pilot, capped = 0, False
    if options.target_error is not None:
        values, mask, n, pilot, err = _bake_to_error(once, options)
        estimate = ESTIMATES["pilots"]
        capped = _capped(group, kind, n, err, options)
    else:
        values, mask, n, err, estimate = _estimated(kind, options, [once(m, seed) for m, seed in _calls(kind, options)])
    if image is not None:
        bpy.data.images.remove(image)           # one map's image at a time (memory, cost.BYTES_PER_TEXEL)
    if image_target and options.denoise:
        values, estimate = _denoised(values, mask, kind), estimate + DENOISED
    result = BakeResult(values, mask, n, time.perf_counter() - t0, err, estimate, pilot, timer["cycles"])
    result.capped = capped
    return result


def _calls(kind, options):
    """[(samples, seed)] of the Cycles calls of a fixed-sample map: two independent halves for irradiance
    (its error is measured from their difference), one call otherwise."""
    n = int(options.samples)
    if kind == "irradiance" and n >= 2:
        return [(n // 2, int(options.seed)), (n - n // 2, int(options.seed) + 1)]
    return [(n, int(options.seed))]


SEED_STRIDE = 2 * MAX_PAIRS
"""Seeds of the passes of one bake step by this: a map's bakes have seeds seed .. seed + 2 MAX_PAIRS - 1."""


def _passes(kind, samples, seed, texels, pace=None):
    """[(samples, seed)] of the Cycles calls of one bake of ``samples`` at ``seed`` over ``texels`` texels: that
    one call when it fits cost.PASS_SECONDS (:func:`cost.seconds`, as the progress line), else near-equal sample
    passes of at most :func:`cost.pass_samples`, seeds seed + j SEED_STRIDE, whose sample-weighted mean
    (:class:`_PassSum`) is the bake; Ctrl-C (deferred inside a call) stops between them. ``pace``: the scene's
    :class:`cost.Speed`."""
    samples, seed = int(samples), int(seed)
    most = cost.pass_samples(texels, kind, pace)
    if samples <= most:
        return [(samples, seed)]
    k = -(-samples // most)
    return [(samples // k + (j < samples % k), (seed + j * SEED_STRIDE) % 2 ** 31) for j in range(k)]


class _PassSum:
    """The sample-weighted mean of the passes of one bake of ``samples``, summed as they come (one pass's values
    held at a time); a single pass comes back as it is, and the mask is the first pass's."""

    def __init__(self, samples):
        self.samples, self.sum, self.mask, self.single = int(samples), None, None, None

    def add(self, values, mask, samples):
        if self.sum is None and self.single is None and samples == self.samples:
            self.single = values, mask
            return
        w = samples / self.samples
        if isinstance(values, dict):
            self.sum = {k: (self.sum[k] if self.sum else 0.0) + np.asarray(v, np.float64) * w for k, v in values.items()}
        elif self.sum is None:
            self.sum, self.mask = values.astype(np.float64) * w, mask
        else:
            self.sum += values * w

    def result(self):
        """(values, mask) of the whole bake."""
        if self.single is not None:
            return self.single
        return (self.sum if isinstance(self.sum, dict) else self.sum.astype(np.float32)), self.mask


def _estimated(kind, options, parts):
    """(values, mask, samples, estimated error, estimate) of a fixed-sample map from its calls' (values, mask)
    (:func:`_calls`): irradiance halves combined, error from their difference; AO the binomial bound."""
    n = int(options.samples)
    if len(parts) == 2:
        h = n // 2
        (a, mask), (b, _) = parts
        var = lightmap.per_sample_variance_pair(_flat(a), _flat(b), h, n - h, _flat_mask(mask, a))
        return _combine([a, b], [h, n - h]), mask, n, lightmap.expected_error(var, n), ESTIMATES["halves"]
    values, mask = parts[0]
    if kind == "ao":
        var = lightmap.per_sample_variance_ao(_flat(values), _flat_mask(mask, values))
        return values, mask, n, lightmap.expected_error(var, n), ESTIMATES["binomial"]
    return values, mask, n, float("nan"), ESTIMATES["none"]


#: The range a map's quantity lives in: k_A in [0, 1], E >= 0. A filter (the denoiser) may overshoot it.
VALUE_RANGE = {"ao": (0.0, 1.0), "irradiance": (0.0, None)}


def _denoised(values, mask, kind):
    """OIDN on the map (empty texels filled from the nearest covered one first), clipped to VALUE_RANGE:
    the denoiser's overshoot at edges put k_A above 1 (Sponza's floors: 1,320 of 4,940 texels, up to 1.022)."""
    filled, _ = lightmap.nearest_fill(values, mask)
    from .denoise import denoise
    lo, hi = VALUE_RANGE[kind]
    smooth = np.clip(denoise(filled), lo, hi)
    return np.where((mask[..., None] if values.ndim == 3 else mask), smooth, 0.0).astype(np.float32)


def _bake_to_error(once, options):
    """Bake pairs until the RMS error meets ``options.target_error``; return (values, mask, samples, pilot, error).

    Every bake is one of a pair of independent bakes (different seeds) with the same samples; the RMS
    error of a pair's mean is measured from the difference of its halves
    (:func:`lightmap.per_sample_variance_pair`), and all pairs are combined with inverse-variance weights
    (:func:`lightmap.inverse_variance_weights`, 1/e² = Σ 1/e_i²), so the reported error is measured.
    The pilot pair has pilot_samples / 2 samples per bake; each next pair gets the samples predicted to
    bring the combination to the target, from err ∝ N^-α: α = ALPHA for the first prediction, then α
    measured between the last two pairs (:func:`lightmap.convergence_exponent`), rounded to the nearest
    power of two (Cycles' tabulated Sobol sequence is stratified best there: measured 16 samples beat 19,
    32 beat 28). Assuming independent samples (α = 1/2, N = σ²/E²) would bake several times too many
    samples with Cycles' stratified sampler.
    Up to MAX_PAIRS pairs and max_samples samples in all.
    """
    target = float(options.target_error)
    per, errors, parts, seed, mask = [], [], [], int(options.seed), None
    total = 0
    m = max(1, int(options.pilot_samples) // 2)
    while True:
        (a, mask_a), (b, _) = once(m, seed), once(m, seed + 1)
        seed, total = seed + 2, total + 2 * m
        mask = mask_a if mask is None else mask
        var = lightmap.per_sample_variance_pair(_flat(a), _flat(b), m, m, _flat_mask(mask, a))
        per.append(m)
        parts.append(_combine([a, b], [1, 1]))
        errors.append(lightmap.expected_error(var, 2 * m))
        weights, err = lightmap.inverse_variance_weights(errors)
        left = int(options.max_samples) - total
        if err <= target or len(per) == MAX_PAIRS or left < 2:
            break
        wanted = 1.0 / math.sqrt(1.0 / target ** 2 - 1.0 / err ** 2)     # error the next pair must reach
        alpha = ALPHA if len(per) == 1 else lightmap.convergence_exponent(errors[-2], per[-2], errors[-1], per[-1])
        m = lightmap.samples_for_error(errors[-1], per[-1], wanted, alpha, minimum=1, maximum=left // 2)
        m = min(2 ** round(math.log2(m)), left // 2)      # Cycles' Sobol sampler is best at powers of two
    return _combine(parts, weights), mask, total, 2 * per[0], err


def _capped(group, kind, samples, error, options):
    """True, with a warning naming the samples spent and the error reached, when the bake stopped at its sample
    bound (max_samples, MAX_PAIRS pairs) above ``options.target_error``."""
    if not error > float(options.target_error):
        return False
    errors.warn(f"'{group[0].name}' {kind}: target error {float(options.target_error):g} not reached: capped at "
                f"{samples} samples (at most {int(options.max_samples)} in {MAX_PAIRS} pairs of bakes), error "
                f"reached {error:.3g}")
    return True


def _flat(values):
    if isinstance(values, dict):
        return np.concatenate([np.asarray(v, float).reshape(len(v), -1) for v in values.values()])
    return values


def _flat_mask(mask, values):
    if isinstance(values, dict):
        return np.ones(sum(len(v) for v in values.values()), bool)
    return mask


def _combine(parts, weights):
    """Weighted mean of independent bakes (image arrays or {object: vertex values})."""
    if isinstance(parts[0], dict):
        return {k: lightmap.combine([p[k] for p in parts], weights) for k in parts[0]}
    return lightmap.combine(parts, weights).astype(np.float32)


def _set_bounces(cy, kind, options):
    """AO needs the first hit only: no bounces (same k_A, measured, and much cheaper); irradiance: the
    chosen number of diffuse bounces."""
    diffuse, total = (0, 0) if kind == "ao" else (int(options.bounces), max(int(options.bounces), 1))
    if cy.diffuse_bounces != diffuse:
        cy.diffuse_bounces = diffuse
    if cy.max_bounces != total:
        cy.max_bounces = total


def _bake_once(scene, group, kind, samples, seed, image, uv_name, options, inside=None):
    """One Cycles bake call; returns (values, mask, seconds inside the call) with E already multiplied by π
    (an image's mask within ``inside``, see :func:`_read_image`)."""
    if image is not None:
        image.pixels.foreach_set(np.zeros(image.size[0] * image.size[1] * 4, np.float32))
    seconds = _call_bake(scene, group, kind, samples, seed, uv_name if image is not None else None, options)
    if image is not None:
        values, mask = _read_image(image, kind, inside)
        return values, mask, seconds
    scale = np.pi if kind == "irradiance" else 1.0
    values = {}
    for o in group:
        attr = o.data.color_attributes[ATTRIBUTE[kind]]
        c = np.zeros(len(attr.data) * 4, np.float32)
        attr.data.foreach_get("color", c)
        c = c.reshape(-1, 4)
        values[o.name] = c[:, 0].copy() if kind == "ao" else c[:, :3] * scale
    return values, None, seconds


def _call_bake(scene, group, kind, samples, seed, uv_name, options):
    """One ``object.bake`` of the objects ``group`` (into their active image nodes with ``uv_name``, else into
    their active colour attributes); returns the seconds inside the call.

    Cycles: ``samples`` and ``seed``, no denoising, adaptive sampling or sample clamping (Blender clamps
    indirect light at 10 by default: a biased E where light is trapped, e.g. under a lamp near a ceiling)."""
    render.cycles_cpu(scene, samples, seed, clamp=0.0)
    _set_bounces(scene.cycles, kind, options)
    vl = scene.view_layers[0]
    for o in filter(None, vl.objects):
        want = o in group
        if o.select_get(view_layer=vl) != want:
            o.select_set(want, view_layer=vl)
    vl.objects.active = group[0]
    kwargs = dict(margin=0, use_clear=False, use_selected_to_active=False, save_mode="INTERNAL",
                  target="IMAGE_TEXTURES" if uv_name is not None else "VERTEX_COLORS")
    if uv_name is not None:
        kwargs["uv_layer"] = uv_name
    if kind == "ao":
        kwargs["type"] = "AO"
    else:
        kwargs["type"] = "DIFFUSE"
        kwargs["pass_filter"] = {"DIRECT", "INDIRECT"} if options.bounces > 0 else {"DIRECT"}
    ctx = dict(scene=scene, view_layer=vl, active_object=group[0], object=group[0],
               selected_objects=list(group), selected_editable_objects=list(group))
    t = time.perf_counter()
    try:
        with interrupt.blender_call(), bpy.context.temp_override(**ctx):
            result = bpy.ops.object.bake(**kwargs)
    except RuntimeError as e:
        raise ILError(f"Cycles bake failed: {str(e).strip().splitlines()[-1]}") from e
    seconds = time.perf_counter() - t
    if "FINISHED" not in result:
        raise ILError(f"Cycles bake did not finish ({', '.join(result)})")
    return seconds


def _read_image(image, kind, inside=None):
    """(values, covered mask) of a baked image (E multiplied by π): the texels Cycles baked, within the mask
    ``inside`` when given (:func:`_centre_texels`); values 0 elsewhere."""
    w, h = image.size
    px = np.zeros(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, 4)
    mask = px[..., 3] > 0.5
    values = px[..., 0].copy() if kind == "ao" else px[..., :3] * (np.pi if kind == "irradiance" else 1.0)
    if inside is not None:
        mask &= inside
        values[~mask] = 0.0
    return values.astype(np.float32), mask


def _centre_texels(group, layers, size):
    """Where Cycles also bakes texels a UV triangle only touches (``compat.BAKE_TOUCHED_TEXELS``): the (H, W)
    mask of texels whose centre lies inside one of the group's UV triangles, the texels a map holds everywhere
    (coverage, margins and dilation are measured on them; a touched texel between two charts holds whichever
    chart Cycles rasterised last). None where Cycles bakes those texels only."""
    if not compat.BAKE_TOUCHED_TEXELS:
        return None
    w, h = size
    inside = np.zeros((h, w), bool)
    for o in group:
        inside |= lightmap.coverage_mask(uvmod.triangles_uv(o, layers[o.name]), w, h)
    return inside


# ------------------------------------------------------------------ batched bakes (one scene sync per call)

BATCH_TEXELS = 1 << 22
"""Most map texels one batched Cycles call bakes: its images live together (4 Mi texels: 64 MiB of float RGBA
images, as much again read back), so a level never holds more than that beyond one map's arrays."""
PROXY = "IL bake batch"
PROXY_UV = "IL bake UV"
_RAY_VISIBILITY = ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
                   "visible_volume_scatter", "visible_shadow")


def _batch_refusal(obj, layers, state, depsgraph, instanced):
    """Why ``obj`` is baked by its own Cycles call instead of in a batch (:func:`bake_batch`), or None.

    A batch stands a joined copy of the objects' evaluated meshes in for them, so an object is batched only
    when that copy is the same surface to Cycles: positive scale (a mirrored object's winding would flip),
    visible to every ray kind, no holdout or shadow catcher, no custom normals (they do not survive the join),
    its light-map layer in the evaluated mesh, not hidden for render, and not part of a collection another
    object instances (hiding it would hide the instances too)."""
    if obj in state.render_hidden:
        return "hidden for render"
    if obj.matrix_world.determinant() <= 0:
        return "negative scale"
    if not all(getattr(obj, a, True) for a in _RAY_VISIBILITY) or obj.is_holdout or obj.is_shadow_catcher:
        return "ray visibility"
    if obj.name in instanced:
        return "instanced"
    me = obj.evaluated_get(depsgraph).data
    if getattr(me, "has_custom_normals", False):
        return "custom normals"
    if layers.get(obj.name) not in me.uv_layers:
        return "light-map layer not in the evaluated mesh"
    return None


def _instanced(scene):
    """Names of the objects in a collection some object of the scene instances."""
    members = set()
    for o in scene.objects:
        if o.instance_type == "COLLECTION" and o.instance_collection is not None:
            members.update(x.name for x in o.instance_collection.all_objects)
    return members


def batches(scene, plan, layers, state, options, maps=None):
    """Split the image-target ``plan`` [(name, group, size, ...)] into (batches, singles): batches are lists of
    plan entries whose maps (of kinds ``maps``, default ``options.maps``) share Cycles calls (one pass plan,
    at most the texels :func:`_pass_plan` allows each, at least one entry),
    singles are baked by their own calls (target error: each map chooses its own samples; vertex target;
    objects :func:`_batch_refusal` refuses)."""
    if options.target != "image" or options.target_error is not None or not options.batch:
        return [], list(plan)
    scene.view_layers[0].update()
    depsgraph = scene.view_layers[0].depsgraph
    instanced = _instanced(scene)
    pace = speed(scene, options)
    batched, singles = [], []
    for entry in plan:
        group = entry[1]
        if any(_batch_refusal(o, layers, state, depsgraph, instanced) for o in group):
            singles.append(entry)
        else:
            batched.append(entry)
    if sum(len(entry[1]) for entry in batched) < 2:      # one object: its own call is the same call
        return [], list(plan)
    out, open_ = [], {}
    for entry in batched:
        t = entry[2][0] * entry[2][1]
        plan_, cap = _pass_plan(t, maps or options.maps, options, pace)
        batch = open_.get(plan_)
        if batch is None or batch[1] + t > cap:
            batch = open_[plan_] = [[], 0]
            out.append(batch[0])
        batch[0].append(entry)
        batch[1] += t
    return out, singles


def _pass_plan(texels, maps, options, pace=None):
    """(the samples of every Cycles call of a fixed-sample map of ``texels`` texels, per kind of ``maps``; the most
    texels a batch of such maps may hold: BATCH_TEXELS, and each call within cost.PASS_SECONDS). A batch joins
    maps of one plan only, so each image comes out as its own calls make it. ``pace``: :class:`cost.Speed`."""
    pace = pace or cost.PLAIN
    plan_, cap = [], BATCH_TEXELS
    for kind in maps:
        calls = tuple(n for samples, seed in _calls(kind, options)
                      for n, _ in _passes(kind, samples, seed, texels, pace))
        plan_.append((kind, calls))
        cap = min(cap, max(1, int(cost.pass_budget(kind, pace) // (pace.rate(kind) * max(calls)))))
    return tuple(plan_), cap


class _Proxy:
    """A temporary object whose mesh joins the batch's evaluated meshes in world space (modifiers applied),
    one UV layer (each object's light-map layer) and one material slot per object slot, whose material's
    active image node is that object's group image; the objects themselves are hidden for render while it
    stands in for them. Cycles bakes every material's image in one call (one scene sync)."""

    def __init__(self, scene, batch, kind, layers, temporary, images, state):
        self.scene, self.batch, self.kind, self.layers = scene, batch, kind, layers
        self.temporary, self.images, self.state = temporary, images, state
        self.obj, self.hidden = None, []

    def __enter__(self):
        import bmesh
        self.scene.view_layers[0].update()       # the light-map UVs written since the last evaluation
        depsgraph = self.scene.view_layers[0].depsgraph
        bm = bmesh.new()
        materials_ = []
        try:
            for name, group, *_ in self.batch:
                for o in group:
                    me = bpy.data.meshes.new_from_object(o.evaluated_get(depsgraph), preserve_all_data_layers=True,
                                                         depsgraph=depsgraph)
                    try:
                        tri = _triangulated(me, self.layers[o.name], o.matrix_world)
                    finally:
                        bpy.data.meshes.remove(me)
                    try:
                        slots = self.temporary.batch_slots(o, self.kind, name, self.images[name])
                        index = np.zeros(len(tri.polygons), np.int32)
                        tri.polygons.foreach_get("material_index", index)
                        tri.polygons.foreach_set("material_index", len(materials_) + np.clip(index, 0, len(slots) - 1))
                        materials_ += slots
                        bm.from_mesh(tri)
                    finally:
                        bpy.data.meshes.remove(tri)
            mesh = self.state.track(bpy.data.meshes, bpy.data.meshes.new(PROXY))
            bm.to_mesh(mesh)
        finally:
            bm.free()
        for mat in materials_:
            mesh.materials.append(mat)
        self.obj = self.state.track(bpy.data.objects, bpy.data.objects.new(PROXY, mesh))
        self.scene.collection.objects.link(self.obj)
        for _, group, *_ in self.batch:
            for o in group:
                if not o.hide_render:
                    o.hide_render = True
                    self.hidden.append(o)
        return self

    def __exit__(self, *exc):
        for o in self.hidden:
            o.hide_render = False
        if self.obj is not None:
            mesh = self.obj.data
            bpy.data.objects.remove(self.obj)
            bpy.data.meshes.remove(mesh)
            self.scene.view_layers[0].update()
        return False


def _triangulated(me, layer, matrix):
    """A mesh of ``me``'s loop triangles (the triangles Blender bakes, chosen in object space) in world space
    (``matrix``): UVs of ``layer`` as PROXY_UV, material indices, flat faces and sharp edges kept."""
    me.calc_loop_triangles()
    t = len(me.loop_triangles)
    tv = np.zeros(t * 3, np.int64)
    tl = np.zeros(t * 3, np.int64)
    tp = np.zeros(t, np.int64)
    me.loop_triangles.foreach_get("vertices", tv)
    me.loop_triangles.foreach_get("loops", tl)
    me.loop_triangles.foreach_get("polygon_index", tp)
    co = np.zeros(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    uv = np.zeros(len(me.loops) * 2, np.float32)
    me.uv_layers[layer].data.foreach_get("uv", uv)
    mat = np.zeros(len(me.polygons), np.int32)
    me.polygons.foreach_get("material_index", mat)
    smooth = np.zeros(len(me.polygons), bool)
    me.polygons.foreach_get("use_smooth", smooth)
    ev = np.zeros(len(me.edges) * 2, np.int64)
    me.edges.foreach_get("vertices", ev)
    sharp = np.zeros(len(me.edges), bool)
    me.edges.foreach_get("use_edge_sharp", sharp)
    out = bpy.data.meshes.new("IL bake batch part")
    out.vertices.add(len(me.vertices))
    out.vertices.foreach_set("co", co)
    out.loops.add(3 * t)
    out.loops.foreach_set("vertex_index", tv)
    out.polygons.add(t)
    out.polygons.foreach_set("loop_start", np.arange(0, 3 * t, 3))
    out.update(calc_edges=True)
    out.polygons.foreach_set("material_index", mat[tp])
    out.polygons.foreach_set("use_smooth", smooth[tp])
    layer_out = out.uv_layers.new(name=PROXY_UV, do_init=False)
    layer_out.data.foreach_set("uv", uv.reshape(-1, 2)[tl].ravel())
    if sharp.any():
        key = lambda e: np.minimum(e[:, 0], e[:, 1]) * (len(co) + 1) + np.maximum(e[:, 0], e[:, 1])
        sharp_keys = set(key(ev.reshape(-1, 2)[sharp]).tolist())
        new = np.zeros(len(out.edges) * 2, np.int64)
        out.edges.foreach_get("vertices", new)
        out.edges.foreach_set("use_edge_sharp", np.isin(key(new.reshape(-1, 2)), list(sharp_keys)))
    out.transform(matrix)
    out.update()
    return out


def bake_batch(scene, batch, kind, options, layers, temporary, state):
    """Bake map ``kind`` of every group of ``batch`` (plan entries (name, group, size, ...) of one pass plan,
    :func:`batches`) in the Cycles calls of one map (:func:`_calls`, :func:`_passes`) through a :class:`_Proxy`;
    return ``{name: BakeResult}``.

    Same texels, samples and seeds as the groups' own calls: Cycles seeds a bake sample by its pixel in its
    image, so each image comes out as its own call makes it (tests/test_bake_level.py). The call's seconds
    are shared among the groups by texels."""
    t0 = time.perf_counter()
    for o in state.render_hidden:               # hidden for render: seen by Cycles only for its own map
        if not o.hide_render:
            o.hide_render = True
    images = {name: state.track(bpy.data.images, bpy.data.images.new(f"IL {kind} {name}", size[0], size[1],
                                                                     float_buffer=True, alpha=True))
              for name, _, size, *_ in batch}
    parts = {name: [] for name in images}
    inside = {name: _centre_texels(group, layers, size) for name, group, size, *_ in batch}
    cycles = 0.0
    try:
        with _Proxy(scene, batch, kind, layers, temporary, images, state) as proxy:
            largest = max(size[0] * size[1] for _, _, size, *_ in batch)   # batches() joins maps of one pass plan
            pace = speed(scene, options)
            for samples, seed in _calls(kind, options):
                sums = {name: _PassSum(samples) for name in images}
                for n, s in _passes(kind, samples, seed, largest, pace):
                    for image in images.values():
                        image.pixels.foreach_set(np.zeros(image.size[0] * image.size[1] * 4, np.float32))
                    cycles += _call_bake(scene, [proxy.obj], kind, n, s, PROXY_UV, options)
                    for name, image in images.items():
                        sums[name].add(*_read_image(image, kind, inside[name]), n)
                for name in images:
                    parts[name].append(sums[name].result())
    finally:
        for image in images.values():
            bpy.data.images.remove(image)
    texels = {name: size[0] * size[1] for name, _, size, *_ in batch}
    total = sum(texels.values())
    elapsed = time.perf_counter() - t0
    results = {}
    for name in list(parts):
        values, mask, n, err, estimate = _estimated(kind, options, parts.pop(name))
        if options.denoise:
            values, estimate = _denoised(values, mask, kind), estimate + DENOISED
        share = texels[name] / total
        results[name] = BakeResult(values, mask, n, elapsed * share, err, estimate, 0, cycles * share)
    return results


# ------------------------------------------------------------------ files

def _attributes(kind, result, options, uv_name):
    quantity, units = QUANTITY[kind]
    return {"il:quantity": quantity, "il:units": units, "il:samples": result.samples,
            "il:ao_distance": options.ao_distance, "il:uv_layer": uv_name or "",
            "il:blender_version": bpy.app.version_string, "il:bounces": options.bounces if kind != "ao" else "",
            "il:denoised": int(bool(options.denoise and options.target == "image")),
            "il:estimated_error": result.estimated_error, "il:error_estimate": result.estimate,
            "il:pilot_samples": int(result.pilot_samples), "il:seconds": round(result.seconds, 4),
            "il:cycles_seconds": round(result.cycles_seconds, 4)}


def _channels(kind, values, alpha):
    if kind == "ao":
        return {"Y": values, "A": alpha}
    return {"R": values[..., 0], "G": values[..., 1], "B": values[..., 2], "A": alpha}


def _preview(kind, values, mask):
    if kind == "ao":
        display = io_png.srgb_encode(values)
    else:
        display = io_png.tonemap(values)
    display = np.where(mask[..., None] if display.ndim == 3 else mask, display, 0.0)
    return io_png.to_uint8(display)


def _entry(path, res, result, extra=None):
    """One bake_report.json entry (DESIGN.md keys first; "error_estimate" says what estimated_error is)."""
    e = {"file": path, "resolution": list(res), "samples": int(result.samples), "seconds": round(result.seconds, 4),
         "estimated_error": None if not np.isfinite(result.estimated_error) else float(result.estimated_error),
         "error_estimate": result.estimate, "cycles_seconds": round(result.cycles_seconds, 4)}
    if result.pilot_samples:
        e["pilot_samples"] = int(result.pilot_samples)
    if getattr(result, "capped", False):
        e["capped"] = True
    e.update(extra or {})
    return e


def _finite(name, kind, values):
    """A map with NaN or Inf is an error, not a file."""
    flat = _flat(values) if isinstance(values, dict) else values
    if not np.all(np.isfinite(flat)):
        raise ILError(f"'{name}' {kind}: the baked values are not finite (NaN or Inf, e.g. from an emission or a "
                      f"light of infinite strength): nothing written")


def _write(name, group, kind, result, out, options, layers, margin=None, overlap=None, digest=None, stems=None):
    """Write the files of one baked map; return ``{object: report entry}``. ``margin``: the layout's margin in
    texels (default the asked one; the map is dilated by :func:`uv.dilation` texels; both in the report and the
    header). ``overlap`` = ({object: fraction}, group fraction) of covered texels shared by several faces;
    ``stems`` the file stems of :func:`file_stems`."""
    stems = stems or file_stems()
    margin = uvmod.margin_value(options.margin if margin is None else margin)
    grow = uvmod.dilation(options.margin, margin)
    if options.target == "image":
        _finite(name, kind, result.values[result.mask])
        values, grown = lightmap.dilate(result.values, result.mask, grow)
        values = np.where(grown[..., None] if values.ndim == 3 else grown, values, 0.0)
        alpha = result.mask.astype(np.float32)
        uv_name = layers.get(group[0].name)
        h, w = result.mask.shape
        areas = {o.name: uvmod.chart_area(uvmod.triangles_uv(o, layers[o.name])) for o in group}
        covered = {o.name: float((lightmap.coverage_mask(uvmod.triangles_uv(o, layers[o.name]), w, h) & result.mask).mean())
                   for o in group} if len(group) > 1 else {group[0].name: float(result.mask.mean())}
        attrs = _attributes(kind, result, options, uv_name)
        if digest:
            attrs[HASH_KEY] = digest
        attrs["il:coverage"] = float(result.mask.mean())
        attrs["il:chart_area"] = float(sum(areas.values()))
        attrs["il:min_coverage"] = MIN_COVERAGE_TEXT
        if overlap is not None:
            attrs["il:overlap"] = float(overlap[1])
        attrs["il:margin"] = margin
        attrs["il:dilation"] = grow
        if len(group) > 1:
            attrs["il:objects"] = json.dumps({o.name: {"coverage": covered[o.name], "chart_area": areas[o.name]}
                                              | ({"overlap": float(overlap[0][o.name])} if overlap else {})
                                              for o in group})
        path = map_file(out, stems, name, kind)
        exr.write_exr(path, _channels(kind, np.flipud(values), np.flipud(alpha)), attrs)
        png = map_file(out, stems, name, kind, ".png")
        io_png.write_png(png, np.flipud(_preview(kind, values, grown)))
        res = (values.shape[1], values.shape[0])
        entries = {}
        for o in group:
            extra = {"preview": png, "uv_layer": uv_name, "coverage": covered[o.name],
                     "chart_area": areas[o.name], "margin": margin, "dilation": grow,
                     "denoised": bool(options.denoise)}
            if overlap is not None:
                extra["overlap"] = float(overlap[0][o.name])
            entries[o.name] = _entry(path, res, result, extra)
        return entries
    entries = {}
    _finite(name, kind, result.values)
    for o in group:
        v = np.asarray(result.values[o.name], np.float32)
        row = v[None, :] if v.ndim == 1 else v[None, :, :]
        path = map_file(out, stems, o.name, kind, "_vertex.exr")
        attrs = _attributes(kind, result, options, None)
        if digest:
            attrs[HASH_KEY] = digest
        attrs["il:layout"] = "one texel per mesh vertex, in vertex order"
        exr.write_exr(path, _channels(kind, row, np.ones(row.shape[:2], np.float32)), attrs)
        attr = o.data.color_attributes.get(ATTRIBUTE[kind])
        if attr is not None:
            rgba = np.ones((len(v), 4), np.float32)
            rgba[:, :3] = v[:, None] if v.ndim == 1 else v
            attr.data.foreach_set("color", rgba.ravel())
        entries[o.name] = _entry(path, (len(v), 1), result, {"attribute": ATTRIBUTE[kind]})
    return entries


def _kept_entries(name, group, kind, out, options, stems, stored, old_reports):
    """``{object: report entry}`` of an unchanged map on disk (``stored``: :func:`_stored` of its file): the entry
    of the first of ``old_reports`` ("objects" of reports) that agrees with the file (name, resolution, samples,
    estimated error and its kind, UV layer), else one rebuilt from the header's il:* attributes ("seconds" the
    bake's without the files; figures a file written before they were kept lacks are 0, the margin the
    option's). Writes the PNG preview of an image map when it is missing."""
    header, res = stored

    def number(key, default=0.0):
        try:
            return float(_text(header.get(key)))
        except (TypeError, ValueError):
            return default

    path = _map_file(name, kind, out, options, group, stems)
    result = BakeResult(None, None, int(number("il:samples")), number("il:seconds"),
                        number("il:estimated_error", float("nan")), _text(header.get("il:error_estimate")) or "",
                        int(number("il:pilot_samples")), number("il:cycles_seconds"))
    extras, png = {group[0].name: {"attribute": ATTRIBUTE[kind]}}, None
    if options.target == "image":
        png = map_file(out, stems, name, kind, ".png")
        if not os.path.exists(png):
            channels, _ = exr.read_exr(path)
            values = channels["Y"] if kind == "ao" else np.stack([channels[c] for c in "RGB"], axis=-1)
            io_png.write_png(png, _preview(kind, values, np.ones(values.shape[:2], bool)))
        try:
            per = json.loads(_text(header.get("il:objects")) or "{}")
        except ValueError:
            per = {}
        whole = {"coverage": number("il:coverage"), "chart_area": number("il:chart_area")}
        if header.get("il:overlap") is not None:
            whole["overlap"] = number("il:overlap")
        extras = {}
        for o in group:
            own = per.get(o.name) if isinstance(per, dict) and isinstance(per.get(o.name), dict) else whole
            extras[o.name] = {"preview": png, "uv_layer": _text(header.get("il:uv_layer")) or None,
                              "coverage": own.get("coverage"), "chart_area": own.get("chart_area"),
                              "margin": uvmod.margin_value(number("il:margin", float(options.margin))),
                              "dilation": int(number("il:dilation", uvmod.dilation(
                                  options.margin, number("il:margin", float(options.margin))))),
                              "denoised": _text(header.get("il:denoised")) == "1"}
            if "overlap" in own:
                extras[o.name]["overlap"] = own["overlap"]
    entries = {}
    for o in group:
        fresh = _entry(path, res, result, extras[o.name])
        old = next((r[o.name][kind] for r in old_reports if kind in r.get(o.name, {})), None)
        if old is not None and _agrees(old, fresh):
            fresh = dict(old, file=path, **({"preview": png} if png else {}))
        entries[o.name] = fresh
    return entries


def _agrees(old, new):
    """Whether report entry ``old`` describes the same map file as ``new`` (rebuilt from its header)."""
    try:
        same_error = (old.get("estimated_error") is None) == (new["estimated_error"] is None) and (
            new["estimated_error"] is None
            or math.isclose(float(old["estimated_error"]), new["estimated_error"], rel_tol=1e-6))
        return (os.path.basename(str(old.get("file"))) == os.path.basename(new["file"])
                and list(old.get("resolution", ())) == new["resolution"] and old.get("samples") == new["samples"]
                and old.get("error_estimate") == new["error_estimate"] and old.get("uv_layer") == new.get("uv_layer")
                and same_error)
    except (TypeError, ValueError):
        return False


def _merge_report(path, report):
    """Merge this run's entries into ``path`` under a lock on the folder (concurrent bakes of other objects
    into the same folder keep theirs); the top-level "seconds" is this run's. A report that cannot be read
    is kept aside under a new name, with a warning, never replaced silently."""
    with report_lock(os.path.dirname(path)):
        old = _load_report(path, "a new report started") or {}
        objects = old.get("objects", {})
        for name, maps in report["objects"].items():
            objects.setdefault(name, {}).update(maps)
        merged = {"objects": objects, "seconds": round(report["seconds"], 4),
                  "blender_version": bpy.app.version_string}
        failed = {k: v for k, v in old.get("failed", {}).items() if k not in report["objects"]}
        failed.update(report.get("failed", {}))
        if failed:
            merged["failed"] = failed
        for key in ("skipped", "unchanged"):           # the last run's, kept by the writes that do not say
            value = report[key] if key in report else old.get(key)
            if value:
                merged[key] = value
        write_json(path, merged)


def _shape_error(report):
    """Why ``report`` (parsed JSON) is not a bake report, or None."""
    if not isinstance(report, dict):
        return "not a JSON object"
    objects = report.get("objects", {})
    if not isinstance(objects, dict) or not all(isinstance(maps, dict) and all(isinstance(e, dict)
                                                                                for e in maps.values())
                                                 for maps in objects.values()):
        return '"objects" is not {object: {map: entry}}'
    for key in ("skipped", "failed", "unchanged"):
        if not isinstance(report.get(key, {}), dict):
            return f'"{key}" is not a JSON object'
    if not all(isinstance(m, list) for m in report.get("unchanged", {}).values()):
        return '"unchanged" is not {object: [map]}'
    if not isinstance(report.get("seconds", 0.0), (int, float)):
        return '"seconds" is not a number'
    return None


def _load_report(path, then):
    """The report in ``path``, None when there is none. One that cannot be read or is not a bake report is
    moved aside under a new name (:func:`_aside`) with a warning ending in ``then``, and None returned; call
    under :func:`report_lock`."""
    if not os.path.exists(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
        why = _shape_error(report)
        if why:
            raise ValueError(why)
        return report
    except (OSError, ValueError) as e:
        aside = _aside(path)
        os.replace(path, aside)
        errors.warn(f"{path} could not be read ({e}): kept as {aside}, {then}")
        return None


def _read_objects(path):
    """The "objects" of the report in ``path`` as it is; {} when it is missing or unreadable (nothing moved)."""
    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
    except (OSError, ValueError):
        return {}
    return report.get("objects", {}) if _shape_error(report) is None else {}


def _aside(path):
    stem, ext = os.path.splitext(path)
    n = 1
    while os.path.exists(f"{stem}.unreadable-{n}{ext}"):
        n += 1
    return f"{stem}.unreadable-{n}{ext}"


@contextlib.contextmanager
def report_lock(folder):
    """Exclusive lock of ``folder`` for one report merge: ``flock`` on the folder itself (POSIX, no lock
    file left behind); on Windows ``msvcrt.locking`` on a ``.bake_report.lock`` file in the folder."""
    os.makedirs(folder, exist_ok=True)
    try:
        import fcntl
    except ImportError:
        fcntl = None
    if fcntl is not None:
        fd = os.open(folder, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)              # closing releases the lock
        return
    import msvcrt
    with open(os.path.join(folder, ".bake_report.lock"), "a+b") as f:
        while True:
            try:
                msvcrt.locking(f.fileno(), msvcrt.LK_LOCK, 1)
                break
            except OSError:           # LK_LOCK gives up after 10 s: keep waiting
                continue
        try:
            yield
        finally:
            f.seek(0)
            msvcrt.locking(f.fileno(), msvcrt.LK_UNLCK, 1)
