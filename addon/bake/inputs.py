"""Resume: the input hash of a map (what determines it) and the maps on disk whose inputs are unchanged."""
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
    ``parts``: a dict keeping each object's part before its materials for the next kind's hash."""
    h = hashlib.blake2b(digest_size=16)
    h.update(f"{kind}:{bpy.app.version_string}".encode())
    for name in _HASHED_OPTIONS:
        h.update(f"{name}={getattr(options, name)!r};".encode())
    if KINDS[kind].lit:
        h.update(f"bounces={options.bounces};{lighting}".encode())
    depsgraph = scene.view_layers[0].depsgraph
    for o in group:
        part = None if parts is None else parts.get(o.as_pointer())
        if part is None:
            part = _object_part(o, options, depsgraph)
            if parts is not None:
                parts[o.as_pointer()] = part
        for data in part:
            h.update(data)
        own = [user_material(slot.material) for slot in o.material_slots]
        for mat in own if any(own) else ():          # empty slots render as none (a preview adds one)
            h.update((mat.name if mat else "-").encode())
            if KINDS[kind].lit and mat is not None:
                h.update(repr(tuple(mat.diffuse_color)).encode())
                node_tree_digest(h, mat.node_tree)
    return h.hexdigest()


def _object_part(o, options, depsgraph):
    """What :func:`input_hash` digests of object ``o`` before its materials, in order (the same for every map
    kind)."""
    out = [o.name.encode()]
    if options.sizes and o.name in options.sizes:
        out.append(repr(tuple(options.sizes[o.name])).encode())
    out.append(np.array(o.matrix_world, np.float64).tobytes())
    me = o.data
    out += [positions(me).tobytes(), corner_vertices(me)[uvmod.corners(me)].tobytes()]
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
    return out


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
