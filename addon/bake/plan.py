"""Planning a bake before anything in the file changes: which objects, the input checks, map sizes, file
names, shards, time and memory bounds."""
import dataclasses
import math
import os

import bpy

from ..core import errors
from ..core.errors import ILError, InputError
from ..core.io import names
from . import cost, orientation, uv as uvmod, uvchecks
from .kinds import KINDS
from .options import article, check_out_dir, shard_of, validate_maps
from .report import SHARD_REPORT


ATLAS = "atlas"


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
            skipped[o.name] = "a mesh without faces"
        elif o.library is not None or o.data.library is not None:
            skipped[o.name] = "linked from a library, not editable: make it local"
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


def say_skipped(skipped):
    if skipped:
        errors.warn("skipped " + "; ".join(f"{name}: {why}" for name, why in skipped.items()))


def validate(scene, objects, maps, out, options):
    """Every input check, before anything in the file is touched. Returns (objects, maps, out, skipped, flips):
    ``flips`` {object name: mesh} are meshes inside out (:mod:`.orientation`) whose normals the bake flips."""
    with uvmod.fixed_geometry():            # each mesh's shape read once (uv.geometry_key)
        return _validate(scene, objects, maps, out, options)


def _validate(scene, objects, maps, out, options):
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
    invalid = uvmod.invalid_meshes(objects)
    for o in objects:
        if o.mode != "OBJECT":
            raise InputError(f"'{o.name}' is in {o.mode.lower()} mode: switch to object mode first")
        if options.uv_layer and options.target == "image":
            uvmod.check_layer(o, options.uv_layer)
        try:
            if o.name in invalid:
                raise InputError(invalid[o.name])
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
        check_time(sizes, maps, options, speed=speed(scene, options))
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
    the scale of what shades it (a kind's ``scale_option``: the AO distance for AO; the smallest other mesh; the
    smallest of them), so shadows between vertices are lost; names the mesh and what to do."""
    for o in objects:
        scales = [(KINDS[m].scale_option[0], float(getattr(options, KINDS[m].scale_option[1])))
                  for m in maps if KINDS[m].scale_option]
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


def check_time(sizes, maps, options, side_option="resolution", speed=None):
    """InputError when the maps of ``sizes`` take longer than ``core.budget.MAX_SECONDS`` by the progress line's
    figures (:func:`cost.check_time` with :func:`planned_samples` and ``speed``); a target error names the side,
    not samples."""
    cost.check_time(sizes, maps, planned_samples(options), None if options.target_error is not None else "samples",
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


def planned_samples(options):
    return int(options.samples) if options.target_error is None else int(options.max_samples)


def _size_option(options):
    """The option a refused map side is lowered with: the fixed resolution, or the cap of the texel-density side."""
    return "resolution" if options.texel_density is None or options.sizes else "max resolution"


def _map_size(group, layers, sides, options, windows=None):
    """(width, height) of the group's image map (None for the vertex target): ``options.sizes``, else the window
    a generated layout was carried into (``windows``: uv.Layouts.windows), else the fixed resolution or the
    texel-density side, for a generated layout :func:`uv.baked_side` (never below the side it was made for)."""
    if options.target != "image":
        return None
    if options.sizes and group[0].name in options.sizes:
        w, h = options.sizes[group[0].name]
        return int(w), int(h)
    if windows and group[0].name in windows:
        w, h, _ = windows[group[0].name]
        return int(w), int(h)
    if group[0].name in sides:
        res = uvmod.baked_side(group, layers, options, sides[group[0].name], stored=True)
    else:
        res = uvmod.resolution(group, layers, options)
    return res, res


@dataclasses.dataclass
class Target:
    """One map group of a run: ``name`` (an object's or ATLAS), its objects, and for image maps its (width,
    height), the charts' UV ``areas`` {object: area}, ``overlap`` ({object: fraction}, group fraction) and the
    ``unmapped`` lines of objects whose faces the layer leaves out ({object: line}, :func:`uvchecks.check_unmapped`)."""
    name: str
    group: list
    size: tuple = None
    areas: dict = None
    overlap: tuple = None
    unmapped: dict = None

    @property
    def texels(self):
        """Texels of its map (vertices for the vertex target)."""
        return self.size[0] * self.size[1] if self.size else sum(len(o.data.vertices) for o in self.group)


def plan(scene, groups, maps, layers, sides, options, fail, windows=None):
    """[:class:`Target`] of ``groups`` [(name, objects)] not failed yet, every size and coverage check done before
    the first bake; a group that fails a check is passed to ``fail(name, error)`` and left out."""
    targets = []
    for name, group in groups:
        try:
            target = Target(name, group, _map_size(group, layers, sides, options, windows))
            if target.size is not None:
                refusal = cost.check(target.size[0], target.size[1], maps, options.denoise,
                                     what=_size_option(options))
                if refusal:
                    raise InputError(f"'{name}': {refusal}")
                target.areas = uvchecks.check_coverage(group, layers, target.size)
                target.overlap = uvchecks.check_overlap(scene, group, layers, target.size)
                target.unmapped = uvchecks.check_unmapped(scene, group, layers)
        except (InputError, ILError) as e:
            fail(name, e)
            continue
        targets.append(target)
    return targets
