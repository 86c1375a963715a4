"""Figures of what Cycles bakes of an object, its evaluated mesh (modifiers applied), read without making Blender
evaluate it again when they are known.

A mesh only subdivided (``blender.scene.subdivided_only``), or without modifiers (``blender.scene.unmodified``),
evaluates to a function of the mesh, the modifiers' settings and visibility, the scene's Simplify caps and Blender's
build: :func:`cage_key` digests them, and :func:`figure` remembers each figure under that digest, in the figure store
too (``core.memo.FIGURES``), so a rerun reads the overlap, the seams and the triangles (:class:`Triangles`) of such a
mesh from the output folder: Blender does not subdivide it outside Cycles, and the figures are not made again. Other
meshes are read as evaluated every run.
"""
import dataclasses
import hashlib

import bpy
import numpy as np

from ..blender.digest import mesh_digest, rna_digest
from ..blender.scene import (attribute, corner_triangles, corner_uv, corner_vertices, evaluated_mesh, from_its_mesh,
                             positions, read, triangle_polygons)
from ..core.brdf import normalize
from ..core.memo import FIGURES, digest, storable
from . import uv as uvmod

def cage_key(obj, depsgraph):
    """16-byte digest of everything ``obj``'s evaluated mesh is made from, or None when that is not known without
    evaluating it (neither only subdivided nor unmodified, in Edit Mode, custom normals: Blender 4.5 keeps them
    outside the attributes, an attribute of a kind not read here). Read once per object while the layouts are fixed
    (``uv.fixed_layouts``)."""
    return uvmod.remembered(("cage", obj.as_pointer(), depsgraph.mode), lambda: _cage_key(obj, depsgraph))


def _cage_key(obj, depsgraph):
    me = obj.data
    if me.is_editmode or not from_its_mesh(obj) or getattr(me, "has_custom_normals", False):
        return None
    h = hashlib.blake2b(repr((tuple(bpy.app.version), bpy.app.build_hash)).encode(), digest_size=16)
    render = depsgraph.scene.render
    caps = (render.simplify_subdivision, render.simplify_subdivision_render) if render.use_simplify else None
    h.update(repr((caps, depsgraph.mode)).encode())
    for mod in obj.modifiers:
        h.update(repr((mod.show_viewport, mod.show_render)).encode())
        rna_digest(h, mod)
    return h.digest() if mesh_digest(h, me) else None


def figure(obj, depsgraph, fn, *args):
    """``fn(mesh, *args)`` of ``obj``'s evaluated mesh (None when it has none), remembered and stored under
    :func:`cage_key`, ``fn``'s name and ``args`` when that is known: the mesh is read only for a new figure.
    ``depsgraph`` is up to date with ``obj.data`` (the key is read from the mesh, the figure from the evaluation);
    ``fn`` returns what a figure store holds (numbers, arrays, tuples, storable dataclasses)."""
    key = cage_key(obj, depsgraph)
    if key is None:
        return _of(obj, depsgraph, fn, args)
    return FIGURES.get(digest("evaluated", fn.__module__, fn.__qualname__, key, *args),
                       lambda: _of(obj, depsgraph, fn, args))


def _of(obj, depsgraph, fn, args):
    with evaluated_mesh(obj, depsgraph) as me:
        return None if me is None else fn(me, *args)


@storable
@dataclasses.dataclass
class Triangles:
    """An evaluated mesh's loop triangles (the triangles Cycles bakes, chosen in object space) as arrays: positions
    (V, 3) (object space as read, world space once :meth:`placed`), triangle vertices (T, 3), UVs of one layer per
    corner (T, 3, 2), per triangle its material index and smooth flag, the sharp edges (E, 2), and the corner normals
    (T, 3, 3) of a mesh with custom normals ((0, 3, 3) without: the joined mesh makes the same ones from the sharp
    edges and smooth flags)."""
    co: np.ndarray
    tris: np.ndarray
    uv: np.ndarray
    material: np.ndarray
    smooth: np.ndarray
    sharp: np.ndarray
    normals: np.ndarray

    @classmethod
    def of(cls, me, layer):
        """Those of mesh ``me`` with UV layer ``layer``; None when it lacks the layer."""
        if layer not in me.uv_layers:
            return None
        tl = corner_triangles(me)
        tp = triangle_polygons(me)
        nf = len(me.polygons)
        mat = attribute(me, "material_index", np.int32)
        flat = attribute(me, "sharp_face", bool)
        ev = attribute(me, ".edge_verts", np.int32)
        ev = (ev if ev is not None else read(me.edges, "vertices", np.int32, 2)).reshape(-1, 2)
        sharp = attribute(me, "sharp_edge", bool)
        custom = getattr(me, "has_custom_normals", False)
        normals = read(me.corner_normals, "vector", np.float32, 3).reshape(-1, 3)[tl] if custom else \
            np.zeros((0, 3, 3), np.float32)
        return cls(positions(me), corner_vertices(me)[tl], corner_uv(me, layer)[tl],
                   (mat if mat is not None else np.zeros(nf, np.int32))[tp],
                   ~(flat if flat is not None else np.zeros(nf, bool))[tp],
                   ev[sharp] if sharp is not None else np.zeros((0, 2), np.int32), normals)

    def placed(self, matrix):
        """These triangles with their positions in world space by ``matrix`` (indices as int64, for a join), custom
        normals by its inverse transpose, made unit."""
        m = np.array(matrix, np.float64)
        world = (self.co.astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
        normals = self.normals
        if len(normals):
            normals = normalize(normals @ np.linalg.inv(m[:3, :3])).astype(np.float32)
        return Triangles(world, self.tris.astype(np.int64), self.uv, self.material, self.smooth,
                         self.sharp.astype(np.int64), normals)
