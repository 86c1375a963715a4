"""Resume: the input hash of a map (what determines it) and the maps on disk whose inputs are unchanged."""
import dataclasses
import hashlib
import os

import bpy
import numpy as np

from ..blender import compat
from ..blender.digest import node_tree_digest, rna_digest
from ..blender.materials import user_material
from ..blender.scene import corner_uv, corner_vertices, positions, subdivided_only
from ..core.io import exr
from . import uv as uvmod
from .kinds import KINDS
from .plan import map_file


HASH_KEY = "il:input_hash"


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
    lights and world (``lighting``, :func:`lighting_digest`; a ``lit`` kind only: irradiance) and the options that
    change the map.
    Other objects are not in it: moving an occluder leaves its neighbours' maps as they are (``force`` bakes them).
    ``parts``: a dict keeping each object's :class:`_ObjectParts` for the next kind's hash and :func:`scene_inputs`."""
    h = hashlib.blake2b(digest_size=16)
    h.update(f"{kind}:{bpy.app.version_string}".encode())
    for name in _HASHED_OPTIONS:
        h.update(f"{name}={getattr(options, name)!r};".encode())
    if KINDS[kind].lit:
        h.update(f"bounces={options.bounces};{lighting}".encode())
    depsgraph = scene.view_layers[0].depsgraph
    for o in group:
        for data in object_parts(o, options, depsgraph, parts).all():
            h.update(data)
        for data in _material_parts(o, kind):
            h.update(data)
    return h.hexdigest()


@dataclasses.dataclass
class _ObjectParts:
    """What :func:`input_hash` digests of an object before its materials: its name, its size option, ``placement``
    (transform, base positions, triangles), ``modifiers`` (their settings, the evaluated counts) and the UVs of the
    ``uv_layer`` option."""
    name: list
    size: list
    placement: list
    modifiers: list
    uvs: list

    def all(self):
        return self.name + self.size + self.placement + self.modifiers + self.uvs


def object_parts(o, options, depsgraph, parts=None):
    """The :class:`_ObjectParts` of ``o`` (kept in ``parts`` by pointer when given)."""
    key = o.as_pointer()
    if parts is not None and key in parts:
        return parts[key]
    me = o.data
    out = _ObjectParts([o.name.encode()], [], [], [], [])
    if options.sizes and o.name in options.sizes:
        out.size.append(repr(tuple(options.sizes[o.name])).encode())
    out.placement += [np.array(o.matrix_world, np.float64).tobytes(), positions(me).tobytes(),
                      corner_vertices(me)[uvmod.corners(me)].tobytes()]
    subdivided = subdivided_only(o)             # the mesh and the settings hashed give the evaluated mesh
    for mod in o.modifiers:
        if mod.show_render or (subdivided and mod.show_viewport):
            out.modifiers.append(repr((mod.show_viewport, mod.show_render)).encode())
            h = _Bytes()
            rna_digest(h, mod)
            out.modifiers.append(h.data())
    if not subdivided:
        ev = o.evaluated_get(depsgraph).data
        out.modifiers.append(f"{len(ev.vertices)}:{len(ev.polygons)}".encode())
    if options.uv_layer and options.uv_layer in me.uv_layers:
        out.uvs.append(corner_uv(me, options.uv_layer).tobytes())
    if parts is not None:
        parts[key] = out
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


#: What :func:`scene_inputs` digests, with the words an export's note says of a change to it.
SCENE_PARTS = {"placement": "moved or its mesh edited", "modifiers": "its modifiers", "materials": "its materials",
               "lighting": "the lights or the world"}


def scene_inputs(scene, obj, kind, lighting, parts=None):
    """{part of :data:`SCENE_PARTS`: hex digest, "blender": version} of what in the scene map ``kind`` of ``obj``
    was baked from (the options aside), kept in its report entry ("inputs") and header, so that an export can say
    what changed since (:func:`changed_since`). "placement" depends on the mesh and transform only; the others on
    settings whose set differs between Blender versions."""
    found = object_parts(obj, _NO_OPTIONS, scene.view_layers[0].depsgraph, parts)
    out = {}
    for part, data in (("placement", found.placement), ("modifiers", found.modifiers),
                       ("materials", _material_parts(obj, kind)),
                       ("lighting", [lighting.encode()] if KINDS[kind].lit else [])):
        h = hashlib.blake2b(digest_size=16)
        for d in data:
            h.update(d)
        out[part] = h.hexdigest()
    out["blender"] = bpy.app.version_string
    return out


def changed_since(scene, stored):
    """{object name: [the :data:`SCENE_PARTS` that differ]} of ``stored`` {(object, kind): the map's
    :func:`scene_inputs` at its bake}, objects with no change left out: every part is compared when the same
    Blender reads the file, "placement" alone under another version; a value that is not such a record (a map baked
    before they were kept) is not compared. The scene is evaluated first (transforms and evaluated meshes are stale
    after a bake put its settings back, or after a script moved an object)."""
    scene.view_layers[0].update()
    lighting, out = lighting_digest(scene), {}
    for (obj, kind), then in stored.items():
        if not isinstance(then, dict) or not all(isinstance(then.get(p), str) for p in SCENE_PARTS):
            continue
        now = scene_inputs(scene, obj, kind, lighting)
        same_blender = then.get("blender") == now["blender"]
        differ = {p for p in SCENE_PARTS if (same_blender or p == "placement") and then[p] != now[p]}
        if differ:
            out.setdefault(obj.name, set()).update(differ)
    return {name: [p for p in SCENE_PARTS if p in parts] for name, parts in out.items()}


@dataclasses.dataclass(frozen=True)
class _NoOptions:
    sizes: dict = None
    uv_layer: str = None


_NO_OPTIONS = _NoOptions()


class _Bytes:
    """A hash stand-in that keeps what it is fed (a digest fed the same bytes later is the same)."""

    def __init__(self):
        self.parts = []

    def update(self, data):
        self.parts.append(bytes(data))

    def data(self):
        return b"".join(self.parts)


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
