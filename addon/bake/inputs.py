"""Resume: the input hash of a map (what determines it) and the maps on disk whose inputs are unchanged."""
import hashlib
import os

import bpy
import numpy as np

from ..blender import compat
from ..blender.digest import node_tree_digest, rna_digest, shape_digest
from ..blender.materials import user_material
from ..blender.scene import (corner_uv, corner_vertices, face_sizes, face_starts, from_its_mesh, positions,
                             subdivided_only)
from ..core.io import exr
from . import uv as uvmod, uvcache
from .cycles import RENDER_VARIANTS
from .kinds import KINDS
from .plan import map_file
from .unwrap_copy import Stretches


HASH_KEY = "il:input_hash"
UV_DIGEST_KEY = "il:uv_digest"
"""The header attribute holding :func:`layout_digest` of the UVs an image map was baked through (JSON)."""


_HASHED_OPTIONS = ("resolution", "texel_density", "max_resolution", "samples", "target_error", "pilot_samples",
                   "max_samples", "ao_distance", "margin", "denoise", "seam_fix", "uv_layer", "target", "atlas",
                   "seed")


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
            node_tree_digest(h, d.node_tree if compat.uses_nodes(d) else None)
    world = scene.world
    h.update(b"world" if world is not None else b"no world")
    if world is not None:
        node_tree_digest(h, world.node_tree)
    return h.hexdigest()


def input_hash(scene, group, kind, options, lighting, parts=None):
    """Hash of what determines map ``kind`` of ``group``: each object's evaluated mesh, as its base mesh (positions
    and triangles, exact), its modifiers' settings and the evaluated counts (none for a mesh only subdivided,
    ``blender.scene.subdivided_only``, whose evaluated mesh is not read; the evaluated positions themselves
    change in their last bit when a UV layer is added under a Subdivision; the UVs of ``options.uv_layer`` when
    given), its transform and its materials' node trees (the user's own: ``blender.materials.user_material``), the
    lights and world (``lighting``, :func:`lighting_digest`; a ``lit`` kind only: irradiance), the options that
    change the map, and for a generated layout ``uvcache.LAYOUT_VERSION`` (a version whose layouts differ bakes
    the maps again: else a map kept as unchanged would lie on UVs the mesh no longer gets).
    Other objects are not in it: moving an occluder leaves its neighbours' maps as they are (``force`` bakes them).
    ``parts``: a dict keeping each object's part before its materials for the next kind's hash (and, under
    "stretches", the run's :class:`unwrap_copy.Stretches`)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(f"{kind}:{bpy.app.version_string}".encode())
    if options.target == "image" and not options.uv_layer:       # the layouts this version generates
        h.update(f"layout {uvcache.LAYOUT_VERSION}".encode())
    for name in _HASHED_OPTIONS:
        h.update(f"{name}={getattr(options, name)!r};".encode())
    if KINDS[kind].lit:
        h.update(f"bounces={options.bounces};{lighting}".encode())
    depsgraph = scene.view_layers[0].depsgraph
    stretches = Stretches() if parts is None else parts.setdefault("stretches", Stretches())
    for o in group:
        part = None if parts is None else parts.get(o.as_pointer())
        if part is None:
            part = _object_part(o, options, depsgraph, stretches)
            if parts is not None:
                parts[o.as_pointer()] = part
        for data in part:
            h.update(data)
        for data in _material_parts(o, kind):
            h.update(data)
    return h.hexdigest()


def _object_part(o, options, depsgraph, stretches):
    """What :func:`input_hash` digests of object ``o`` before its materials, in order (the same for every map
    kind). For a generated layout of a mesh other objects share, whether they stand stretched differently
    (:meth:`unwrap_copy.Stretches.shared_apart`): its layout is then made in object space, so a duplicate added or
    scaled differently changes the layout the maps of the others are baked through."""
    out = [o.name.encode()]
    if options.sizes and o.name in options.sizes:
        out.append(repr(tuple(options.sizes[o.name])).encode())
    out.append(np.array(o.matrix_world, np.float64).tobytes())
    me = o.data
    out += [positions(me).tobytes(), corner_vertices(me)[uvmod.corners(me)].tobytes()]
    if options.target == "image" and not options.uv_layer and not options.atlas:
        out.append(uvmod.own_uvs(me))         # a generated layout may be the charts of the mesh's own layers
    subdivided = subdivided_only(o)             # the mesh and the settings hashed give the evaluated mesh
    for mod in o.modifiers:
        if mod.show_render or (subdivided and mod.show_viewport):
            out.append(repr((mod.show_viewport, mod.show_render)).encode())
            h = _Bytes()
            rna_digest(h, mod)
            out.append(h.data())
    if not subdivided:
        ev = o.evaluated_get(depsgraph).data
        out.append(f"{len(ev.vertices)}:{len(ev.polygons)}".encode())
    if options.uv_layer and options.uv_layer in me.uv_layers:
        out.append(corner_uv(me, options.uv_layer).tobytes())
    elif not options.uv_layer and stretches.shared_apart(o):
        out.append(b"stretched apart")
    return out


def _material_parts(o, kind):
    """What :func:`input_hash` digests of ``o``'s materials for map ``kind``: the user's own
    (``blender.materials.user_material``) by name, and for a lit kind their colour and node tree."""
    own = [user_material(slot.material) for slot in o.material_slots]
    for mat in own if any(own) else ():          # empty slots render as none (a preview adds one)
        yield (mat.name if mat else "-").encode()
        if KINDS[kind].lit and mat is not None:
            yield repr(tuple(mat.diffuse_color)).encode()
            h = _Bytes()
            node_tree_digest(h, mat.node_tree)
            yield h.data()


#: Modifier settings only the viewport's evaluation uses (a render uses their render halves,
#: ``cycles.RENDER_VARIANTS``).
_VIEWPORT_SETTINGS = frozenset(view for pairs in RENDER_VARIANTS.values() for view, _ in pairs)
#: Modifiers whose evaluated mesh Blender subdivides when it is first read (0.05-0.08 s a level prop).
_SUBDIVIDING = ("SUBSURF", "MULTIRES")

#: The way :func:`scene_inputs` digests the scene: records made another way are not compared.
SCENE_RECIPE = 1

#: What :func:`scene_inputs` digests, with the words an export's note says of a change to it.
SCENE_PARTS = {"placement": "moved or its mesh edited", "modifiers": "its modifiers", "materials": "its materials",
               "lighting": "the lights or the world"}


def scene_inputs(scene, obj, kind, lighting, shapes=None):
    """{part of :data:`SCENE_PARTS`: hex digest, "blender": version, "recipe": :data:`SCENE_RECIPE`} of what in the
    scene map ``kind`` of ``obj`` was baked from (the options aside), kept in its report entry ("inputs") and header,
    so that an export can say what changed since (:func:`changed_since`): "placement" (transform; the mesh's
    positions, edges, faces and corners), "modifiers" (those renders use, their settings without the viewport's
    halves or the panel's layout; the evaluated counts of a mesh neither unmodified nor subdivided, whose
    subdivision Blender would compute on reading them), "materials" (:func:`input_hash`'s) and, for a lit kind,
    "lighting". Called with the render's evaluation in place (``cycles.evaluate_as_render``: the counts are those
    Cycles bakes, also of an object disabled in viewports). ``shapes``: a dict keeping each object's placement and
    modifiers for its other kinds."""
    key = obj.as_pointer()
    shape = None if shapes is None else shapes.get(key)
    if shape is None:
        placement = hashlib.blake2b(np.array(obj.matrix_world, np.float64).tobytes(), digest_size=16)
        shape_digest(placement, obj.data)
        modifiers = hashlib.blake2b(digest_size=16)
        rendered = [mod for mod in obj.modifiers if mod.show_render]
        for mod in rendered:
            rna_digest(modifiers, mod, layout=False, skip=_VIEWPORT_SETTINGS)
        if not from_its_mesh(obj) and not any(mod.type in _SUBDIVIDING for mod in rendered):
            ev = obj.evaluated_get(scene.view_layers[0].depsgraph).data
            modifiers.update(f"{len(ev.vertices)}:{len(ev.polygons)}".encode())
        shape = placement.hexdigest(), modifiers.hexdigest()
        if shapes is not None:
            shapes[key] = shape
    materials = hashlib.blake2b(digest_size=16)
    for data in _material_parts(obj, kind):
        materials.update(data)
    lit = hashlib.blake2b(lighting.encode() if KINDS[kind].lit else b"", digest_size=16)
    return {"placement": shape[0], "modifiers": shape[1], "materials": materials.hexdigest(),
            "lighting": lit.hexdigest(), "blender": bpy.app.version_string, "recipe": SCENE_RECIPE}


def changed_since(scene, stored):
    """{object name: [the :data:`SCENE_PARTS` that differ]} of ``stored`` {(object, kind): the map's
    :func:`scene_inputs` at its bake}, objects with no change left out: every part is compared when the same
    Blender reads the file, "placement" alone under another version; a value that is not such a record of this
    :data:`SCENE_RECIPE` (a map baked before they were kept, or digested another way) is not compared. Called, as
    :func:`scene_inputs`, with the render's evaluation in place; the view layer is updated first (transforms are
    stale after a script moved an object)."""
    scene.view_layers[0].update()
    lighting, shapes, out = lighting_digest(scene), {}, {}
    for (obj, kind), then in stored.items():
        if not isinstance(then, dict) or then.get("recipe") != SCENE_RECIPE:
            continue
        now = scene_inputs(scene, obj, kind, lighting, shapes)
        same_blender = then.get("blender") == now["blender"]
        differ = {p for p in SCENE_PARTS if (same_blender or p == "placement") and then.get(p) != now[p]}
        if differ:
            out.setdefault(obj.name, set()).update(differ)
    return {name: [p for p in SCENE_PARTS if p in parts] for name, parts in out.items()}


class _Bytes:
    """A hash stand-in that keeps what it is fed (a digest fed the same bytes later is the same)."""

    def __init__(self):
        self.parts = []

    def update(self, data):
        self.parts.append(bytes(data))

    def data(self):
        return b"".join(self.parts)


def layout_digest(group, layer):
    """{object: digest} of the corner UVs of UV layer ``layer`` of each object of ``group`` that has it (the layout a
    map is baked through), the corners of each face in the order of their vertices (the same when an inside-out mesh
    is flipped for its bake: each corner keeps its UV)."""
    out = {}
    for o in group:
        me = o.data
        if not layer or layer not in me.uv_layers:
            continue
        starts = face_starts(me)
        face = np.repeat(np.arange(len(starts)), face_sizes(me, starts))
        order = np.lexsort((corner_vertices(me), face))
        out[o.name] = hashlib.blake2b(corner_uv(me, layer)[order].tobytes(), digest_size=16).hexdigest()
    return out


def stored_hash(path):
    """The input hash in the header of a map file this pipeline wrote, or None."""
    stored = stored_map(path)
    return None if stored is None else header_text(stored[0].get(HASH_KEY))


def stored_header(path):
    """The header of a map file on disk (pixels unread), or None when it is missing or cannot be read."""
    if not os.path.exists(path):
        return None
    try:
        return exr.read_header(path)
    except (OSError, RuntimeError, ValueError):
        return None


def stored_map(path):
    """(header, (width, height)) of a map file on disk, or None when it is missing or cannot be read."""
    if not os.path.exists(path):
        return None
    try:
        channels, header = exr.read_exr(path)
    except (OSError, RuntimeError, ValueError):
        return None
    shape = next(iter(channels.values())).shape if channels else (0, 0)
    return header, (int(shape[1]), int(shape[0]))


def header_text(value):
    return value.decode() if isinstance(value, bytes) else value


def group_map_file(name, kind, out, options, group, stems):
    if options.target == "image":
        return map_file(out, stems, name, kind)
    return map_file(out, stems, group[0].name, kind, "_vertex.exr")
