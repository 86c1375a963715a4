"""Figures of what Cycles bakes of an object, its evaluated mesh (modifiers applied), read without making Blender
evaluate it again when they are known.

For a mesh only subdivided (``blender.scene.subdivided_only``) the evaluated mesh is a function of the mesh (every
attribute, its UV layers among them, and its faces), the modifiers' settings, the scene's Simplify cap and Blender's
version: :func:`cage_key` digests them, and :func:`figure` remembers each figure under that digest (in the figure
store too, ``core.memo.FIGURES``), so a rerun reads the overlap, the seams and the batch's triangles of such a mesh
from the output folder. Blender makes a Subdivision's result when an evaluated mesh is first read after a change, a
new UV layer too (0.05-0.08 s a prop of the level benchmark): a rerun that reads none leaves it to Cycles, which
skips the objects a batch's joined mesh stands in for. Other meshes are read as they are evaluated, every time.
"""
import hashlib

import bpy
import numpy as np

from ..blender.digest import rna_digest
from ..blender.scene import evaluated_mesh, read, subdivided_only
from ..core.memo import FIGURES, digest

_DTYPES = {"FLOAT": (np.float32, "value", 1), "INT": (np.int32, "value", 1), "BOOLEAN": (bool, "value", 1),
           "INT8": (np.int32, "value", 1), "FLOAT_VECTOR": (np.float32, "vector", 3),
           "FLOAT2": (np.float32, "vector", 2), "INT32_2D": (np.int32, "value", 2),
           "FLOAT_COLOR": (np.float32, "color", 4), "BYTE_COLOR": (np.float32, "color", 4)}

_UNREAD = (".select_", ".uv_select_", ".hide_")
"""Attributes a Subdivision Surface does not read (Edit Mode's selection and hiding)."""


def cage_key(obj, depsgraph):
    """16-byte digest of everything ``obj``'s evaluated mesh is made from, or None when that is not known without
    evaluating it (not only subdivided, in Edit Mode, custom normals: Blender 4.5 keeps them outside the attributes,
    an attribute of a kind not read here)."""
    me = obj.data
    if obj.mode == "EDIT" or not subdivided_only(obj) or getattr(me, "has_custom_normals", False):
        return None
    h = hashlib.blake2b(repr(tuple(bpy.app.version)).encode(), digest_size=16)
    render = depsgraph.scene.render
    h.update(repr((render.use_simplify, render.simplify_subdivision, depsgraph.mode)).encode())
    for mod in obj.modifiers:
        if mod.show_viewport or mod.show_render:
            rna_digest(h, mod)
    h.update(repr((len(me.vertices), len(me.edges), len(me.loops), len(me.polygons))).encode())
    h.update(read(me.polygons, "loop_start", np.int32).tobytes())
    for a in sorted(me.attributes, key=lambda a: a.name):
        if a.name.startswith(_UNREAD):
            continue
        kind = _DTYPES.get(a.data_type)
        if kind is None:
            return None
        dtype, prop, width = kind
        h.update(f"{a.name}:{a.domain}:{a.data_type}".encode())
        h.update(read(a.data, prop, dtype, width).tobytes())
    return h.digest()


def figure(obj, depsgraph, name, fn, *args):
    """``fn(mesh, *args)`` of ``obj``'s evaluated mesh (None when it has none); remembered, and stored, under
    :func:`cage_key` with ``name`` and ``args`` when that is known, so the mesh is read only when the figure is new.
    ``fn`` returns what a figure store holds (numbers, arrays, tuples, storable dataclasses)."""
    key = cage_key(obj, depsgraph)
    if key is None:
        return _of(obj, depsgraph, fn, args)
    return FIGURES.get(digest("evaluated", name, key, *args), lambda: _of(obj, depsgraph, fn, args))


def _of(obj, depsgraph, fn, args):
    with evaluated_mesh(obj, depsgraph) as me:
        return None if me is None else fn(me, *args)
