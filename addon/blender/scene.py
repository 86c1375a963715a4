"""Minimal scene building blocks from bpy.data and bmesh (no operators, no context needed)."""
import contextlib
import functools
import math

import bmesh
import bpy
import numpy as np
from mathutils import Vector

from . import compat, render


def new_scene(name, resolution=(256, 256)):
    """A new, empty scene with Cycles on the CPU, Filmic-free ("Standard") view, given resolution."""
    scene = bpy.data.scenes.new(name)
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    render.use_cycles_cpu(scene)
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    return scene


def link(scene, obj):
    scene.collection.objects.link(obj)
    return obj


def mesh_object(scene, name, build, location=(0, 0, 0), rotation=(0, 0, 0), smooth=False):
    """An object whose mesh ``build(bm)`` fills with bmesh operators."""
    bm = bmesh.new()
    build(bm)
    me = bpy.data.meshes.new(name)
    bm.to_mesh(me)
    bm.free()
    if smooth:
        for p in me.polygons:
            p.use_smooth = True
    obj = bpy.data.objects.new(name, me)
    obj.location = location
    obj.rotation_euler = rotation
    return link(scene, obj)


def plane(scene, name, size, location=(0, 0, 0), rotation=(0, 0, 0), subdivisions=0):
    return mesh_object(scene, name, lambda bm: bmesh.ops.create_grid(
        bm, x_segments=subdivisions + 1, y_segments=subdivisions + 1, size=size / 2), location, rotation)


def box(scene, name, size, location=(0, 0, 0), rotation=(0, 0, 0)):
    """A closed cube; ``size`` is a scalar or (x, y, z) edge lengths."""
    sx, sy, sz = (size, size, size) if isinstance(size, (int, float)) else size

    def build(bm):
        bmesh.ops.create_cube(bm, size=1.0)
        bmesh.ops.scale(bm, vec=(sx, sy, sz), verts=bm.verts)
    return mesh_object(scene, name, build, location, rotation)


def sphere(scene, name, radius, location=(0, 0, 0), segments=48, rings=24, smooth=True):
    return mesh_object(scene, name, lambda bm: bmesh.ops.create_uvsphere(
        bm, u_segments=segments, v_segments=rings, radius=radius), location, smooth=smooth)


def light(scene, name, kind, energy, location=(0, 0, 0), rotation=(0, 0, 0), color=(1, 1, 1), radius=0.0):
    """A light with physically exact defaults: point radius 0, soft falloff off, sun angle 0."""
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    data.color = color
    if kind in {"POINT", "SPOT"}:
        data.shadow_soft_size = radius
        if hasattr(data, "use_soft_falloff"):
            data.use_soft_falloff = False
    if kind == "SUN":
        data.angle = 0.0
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = rotation
    return link(scene, obj)


def camera(scene, name, location, target=(0, 0, 0), lens=50.0, ortho_scale=None):
    """A camera at ``location`` looking at ``target`` (orthographic when ``ortho_scale`` is given)."""
    data = bpy.data.cameras.new(name)
    data.lens = lens
    data.clip_start, data.clip_end = 0.05, 200.0
    if ortho_scale is not None:
        data.type = "ORTHO"
        data.ortho_scale = ortho_scale
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    look_at(obj, target)
    link(scene, obj)
    scene.camera = obj
    return obj


def look_at(obj, target):
    direction = Vector(target) - Vector(obj.location)
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def world(scene, strength=0.0, color=(1.0, 1.0, 1.0), ao_distance=None):
    """A uniform world of radiance ``strength * color`` (0 = empty, black)."""
    w = bpy.data.worlds.new(f"{scene.name} World")
    compat.ensure_use_nodes(w)
    bg = w.node_tree.nodes.get("Background")
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    if ao_distance is not None:
        w.light_settings.distance = ao_distance
    scene.world = w
    return w


def deg(*angles):
    return tuple(math.radians(a) for a in angles)


def remove_scene(scene, materials=()):
    """Remove a lab-built scene, its objects that no other scene uses, and the data, world and
    ``materials`` left without users. The user's own objects linked into it survive."""
    objs = list(scene.objects)
    world = scene.world
    bpy.data.scenes.remove(scene)
    collections = ((bpy.types.Mesh, bpy.data.meshes), (bpy.types.Light, bpy.data.lights),
                   (bpy.types.Camera, bpy.data.cameras))
    for obj in objs:
        data = obj.data
        if not obj.users_scene:
            bpy.data.objects.remove(obj)
        if data is not None and data.users == 0:
            for kind, coll in collections:
                if isinstance(data, kind):
                    coll.remove(data)
                    break
    if world is not None and world.users == 0:
        bpy.data.worlds.remove(world)
    for m in materials:
        if m.users == 0:
            bpy.data.materials.remove(m)


def read(seq, attr, dtype, width=1):
    """``seq``'s ``attr`` (``width`` values an item) as a flat numpy array, through ``foreach_get``."""
    out = np.zeros(len(seq) * width, dtype)
    seq.foreach_get(attr, out)
    return out


_ATTRIBUTE_VALUES = {"FLOAT_VECTOR": ("vector", 3), "FLOAT2": ("vector", 2), "INT32_2D": ("value", 2),
                     "FLOAT_COLOR": ("color", 4), "BYTE_COLOR": ("color", 4)}


def attribute(me, name, dtype):
    """Mesh ``me``'s attribute ``name`` as a flat array of ``dtype`` (its stored type: float32, int32 or bool),
    or None when the mesh has none. Attributes are read as one block; the older per-element collections
    (``MeshVertex.co``, ``MeshUVLoop.uv``, ``MeshLoopTriangle.vertices``) are 5-15 times slower to read."""
    a = me.attributes.get(name)
    if a is None:
        return None
    prop, width = _ATTRIBUTE_VALUES.get(a.data_type, ("value", 1))
    return read(a.data, prop, dtype, width)


def set_attribute(me, name, data_type, domain, values):
    """Write flat ``values`` (of the attribute's stored type) into mesh ``me``'s attribute ``name``, made as
    ``data_type`` on ``domain`` when missing; one block, like :func:`attribute`."""
    a = me.attributes.get(name) or me.attributes.new(name, data_type, domain)
    a.data.foreach_set(_ATTRIBUTE_VALUES.get(a.data_type, ("value", 1))[0], values)


def positions(me):
    """(V, 3) float32 object-space vertex positions of mesh ``me``."""
    co = attribute(me, "position", np.float32)
    return (co if co is not None else read(me.vertices, "co", np.float32, 3)).reshape(-1, 3)


def corner_triangles(me):
    """(T, 3) int32 corners (loop indices) of mesh ``me``'s loop triangles, the triangles Cycles renders. A mesh of
    triangles and quads is tessellated here as Blender does (:func:`_tessellated`); with a larger face, or a quad too
    close to Blender's split test to tell, the loop triangles are read (``MeshLoopTriangle.loops``, one element at a
    time: 0.13-0.17 µs a triangle)."""
    me.calc_loop_triangles()
    tris = None
    if len(me.loop_triangles) > TESSELLATED:
        tris = _tessellated(me, read(me.loop_triangle_polygons, "value", np.int32))
    return tris if tris is not None else read(me.loop_triangles, "loops", np.int32, 3).reshape(-1, 3)


TESSELLATED = 1000
"""Meshes of more loop triangles are tessellated here when they can be (below, reading them is as fast)."""


def face_starts(me):
    """(F,) int32 first corner of each face of mesh ``me`` (``MeshPolygon.loop_start``), from the faces of its loop
    triangles (a face of n corners has n − 2, its corners follow its first: Blender 4+), 1.7 times faster than
    reading it element by element on the level benchmark's meshes, which is done when they do not add up to the
    mesh's corners."""
    me.calc_loop_triangles()
    per_face = _per_face(me, read(me.loop_triangle_polygons, "value", np.int32))
    return _offsets(per_face + 2) if per_face is not None else read(me.polygons, "loop_start", np.int32)


def _per_face(me, face):
    """(F,) int32 loop triangles of each face of mesh ``me`` from ``face`` (each triangle's face) when they add up to
    its corners as faces of n corners in n − 2 triangles do, else None."""
    per_face = np.bincount(face, minlength=len(me.polygons)).astype(np.int32)
    ok = len(per_face) == len(me.polygons) and int(per_face.sum()) + 2 * len(per_face) == len(me.loops)
    return per_face if ok else None


def _offsets(counts):
    """(N,) int32 running totals of ``counts`` before each item (an exclusive cumulative sum)."""
    out = np.zeros(len(counts), np.int32)
    np.cumsum(counts[:-1], out=out[1:])
    return out


def face_sizes(me, starts=None):
    """(F,) int32 corners of each face of mesh ``me`` (``MeshPolygon.loop_total``), from :func:`face_starts`."""
    starts = face_starts(me) if starts is None else starts
    return np.diff(starts, append=np.int32(len(me.loops))).astype(np.int32)


QUAD_MARGIN = 1e-4
"""A quad is split here only when its split test's value is this far from 0, relative to its edges' product."""


def _tessellated(me, face):
    """The corners of the loop triangles of mesh ``me`` (``face``: each triangle's face, in Blender's order) when its
    faces are triangles and quads, else None. A face's corners follow its first (Blender 4+); a quad v0 v1 v2 v3 is
    split into corners (0 1 2) (0 2 3), or into (0 1 3) (1 2 3) when (v1 − v0) × (v2 − v0) · (v3 − v0) × (v2 − v0) > 0
    (Blender's ``is_quad_flip_v3_first_third_fast``; measured equal on 40,000 random quads in Blender 4.5, 5.2 and
    5.3), computed as a·c |b|² − (a·b)(b·c) (Binet-Cauchy; a, b, c = v1, v2, v3 − v0): None too when a quad's value is
    within QUAD_MARGIN × |a| |c| |b|² of 0 (float32 round-off could decide it)."""
    n_faces = len(me.polygons)
    per_face = _per_face(me, face)
    if not len(face) or per_face is None or per_face.min() < 1 or per_face.max() > 2:
        return None if len(face) or n_faces else np.zeros((0, 3), np.int32)
    start, first = _offsets(per_face + 2), _offsets(per_face)
    k = np.arange(len(face), dtype=np.int32) - first[face]
    tris = np.empty((len(face), 3), np.int32)
    tris[:, 0] = start[face]
    tris[:, 1] = tris[:, 0] + k + 1
    tris[:, 2] = tris[:, 1] + 1
    quads = np.flatnonzero(per_face == 2)
    if len(quads):
        at = positions(me)[corner_vertices(me)]
        q = at.reshape(-1, 4, 3) if len(quads) == n_faces else at[start[quads][:, None] + np.arange(4)]
        a, b, c = (q[:, i] - q[:, 0] for i in (1, 2, 3))
        dot = functools.partial(np.einsum, "ij,ij->i")
        bb = dot(b, b)
        test = dot(a, c) * bb - dot(a, b) * dot(b, c)
        if not np.all(np.abs(test) > QUAD_MARGIN * np.sqrt(dot(a, a) * dot(c, c)) * bb):
            return None
        flip = quads[test > 0]
        t = first[flip]
        tris[t] = start[flip][:, None] + np.array([0, 1, 3], np.int32)
        tris[t + 1] = start[flip][:, None] + np.array([1, 2, 3], np.int32)
    return tris


def corner_vertices(me):
    """(L,) int32 vertex of each corner (loop) of mesh ``me``."""
    cv = attribute(me, ".corner_vert", np.int32)
    return cv if cv is not None else read(me.loops, "vertex_index", np.int32)


def triangle_polygons(me):
    """(T,) int32 face of each loop triangle of mesh ``me`` (after :func:`corner_triangles`)."""
    return read(me.loop_triangle_polygons, "value", np.int32)


def corner_uv(me, layer):
    """(L, 2) float32 coordinates of mesh ``me``'s UV layer ``layer`` at each corner."""
    uv = attribute(me, layer, np.float32)
    return (uv if uv is not None else read(me.uv_layers[layer].data, "uv", np.float32, 2)).reshape(-1, 2)


@contextlib.contextmanager
def evaluated_mesh(obj, depsgraph):
    """``obj``'s evaluated mesh (modifiers applied, what Cycles renders), read-only: the depsgraph's own for a mesh
    object (no copy) out of edit mode, else ``to_mesh()`` (cleared on exit: in edit mode the depsgraph's mesh
    wraps the edit mesh and reads as empty); None when it has none."""
    ev = obj.evaluated_get(depsgraph)
    if ev.type == "MESH" and obj.mode != "EDIT" and ev.data is not None:
        yield ev.data
        return
    try:
        yield ev.to_mesh()
    finally:
        ev.to_mesh_clear()


def evaluated_triangles(obj, depsgraph):
    """(object-space vertices (V, 3) float64, loop-triangle vertex indices (T, 3)) of ``obj``'s evaluated mesh
    (modifiers applied, what Cycles renders); empty arrays when it has no mesh."""
    with evaluated_mesh(obj, depsgraph) as me:
        if me is None:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
        return mesh_triangles(me)


def mesh_triangles(me):
    """(vertices (V, 3) float64, loop-triangle vertex indices (T, 3)) of mesh ``me``."""
    return positions(me).astype(np.float64), corner_vertices(me)[corner_triangles(me)].astype(np.int64)


def subdivided_only(obj):
    """``obj``'s evaluated mesh is its mesh subdivided and nothing else: every modifier on in the viewport or for
    render is a Subdivision Surface (at least one), and neither a shape key, an animation nor a deforming parent
    drives it. That mesh is then a function of the mesh and the modifiers' settings, with the mesh's closed parts and
    the side they face, so checks of those need not read it: Blender computes it when an evaluated mesh is first read
    (0.05-0.08 s a subdivided prop of the level benchmark) and again after any change to the mesh, a new UV layer
    too."""
    mods = [m for m in obj.modifiers if m.show_viewport or m.show_render]
    return bool(mods) and all(m.type == "SUBSURF" for m in mods) and not _driven(obj)


def from_its_mesh(obj):
    """``obj``'s evaluated mesh is known from its mesh and its modifiers' settings without evaluating it:
    :func:`subdivided_only` or :func:`unmodified`."""
    return subdivided_only(obj) or unmodified(obj)


def unmodified(obj):
    """``obj``'s evaluated mesh is its mesh: no modifier on in the viewport or for render, neither a shape key, an
    animation nor a deforming parent drives it."""
    return not any(m.show_viewport or m.show_render for m in obj.modifiers) and not _driven(obj)


_PLACING_PARENTS = ("OBJECT", "BONE", "VERTEX", "VERTEX_3")
"""Parent types that only place an object; an armature's or lattice's deforming parent type adds a modifier of its
own, which ``Object.modifiers`` does not list."""


def _driven(obj):
    me = obj.data
    return (getattr(me, "shape_keys", None) is not None or obj.animation_data is not None
            or me.animation_data is not None
            or (obj.parent is not None and obj.parent_type not in _PLACING_PARENTS))


def rendered_objects(scene):
    """The objects ``scene`` renders itself (instances aside), in ``scene.objects`` order: those of its
    master collection and of collections neither excluded from its first view layer nor disabled in
    renders (the collection or a parent), themselves not hidden for render."""
    seen = set()

    def walk(lc):
        if lc.exclude or lc.collection.hide_render:
            return
        seen.update(o.name for o in lc.collection.objects if not o.hide_render)
        for child in lc.children:
            walk(child)

    walk(scene.view_layers[0].layer_collection)
    return [o for o in scene.objects if o.name in seen]


class Surface:
    """One rendered copy of an evaluated mesh: ``name`` (the object's, or "<object> (instanced by
    <instancer>)"), ``obj`` (the original object; the instancer for geometry-nodes instances),
    ``instance`` (True for a copy made by an instancer), world-space ``verts`` (V, 3) and ``tris`` (T, 3),
    counter-clockwise seen from outside also under a mirroring matrix, ``casts`` (Cycles' Ray Visibility >
    Shadow of the object and, for a copy, of its instancer: False, it casts no shadow)."""
    __slots__ = ("name", "obj", "instance", "verts", "tris", "casts")

    def __init__(self, name, obj, instance, verts, tris, casts=True):
        self.name, self.obj, self.instance, self.verts, self.tris = name, obj, instance, verts, tris
        self.casts = casts


def evaluated_surfaces(depsgraph, types):
    """([Surface], [(name, type)]): every object and instance ``depsgraph.object_instances`` yields --
    linked duplicates, collection instances, vertex/face and particle instancing, geometry-nodes
    instances -- at its instance ``matrix_world``: those of ``types`` with triangles become surfaces
    (each evaluated mesh is read once however many copies it has), those of other types are listed. Give it a
    render-mode depsgraph (blender.render.with_render_depsgraph) to get what a render draws; copies
    whose ``show_self`` is off (an instancer or particle emitter not shown) are left out, as Cycles does."""
    surfaces, other, meshes = [], [], {}
    for inst in depsgraph.object_instances:
        ob = inst.object
        original = ob.original
        if not inst.show_self:
            continue
        if inst.is_instance:
            parent = inst.parent.name
            name = f"{ob.data.name if ob.name == parent and ob.data else ob.name} (instanced by {parent})"
        else:
            name = ob.name
        if ob.type not in types:
            other.append((name, ob.type))
            continue
        key = (original.as_pointer(), ob.data.as_pointer() if ob.data else 0)
        if key not in meshes:
            meshes[key] = evaluated_triangles(ob, depsgraph)
        v, t = meshes[key]
        if not len(t):
            continue            # nothing to render: no faces, or only the instances it makes
        m = np.array(inst.matrix_world, np.float64)
        casts = ob.visible_shadow and (not inst.is_instance or inst.parent.visible_shadow)
        surfaces.append(Surface(name, original, bool(inst.is_instance), v @ m[:3, :3].T + m[:3, 3],
                                t[:, ::-1] if np.linalg.det(m[:3, :3]) < 0 else t, casts))
    return surfaces, other


def black_world(name="IL temporary world"):
    """A world that emits nothing, as Cycles renders a scene without a world. ``bpy.data.worlds.new`` gives
    5.0 worlds a node tree whose Background is grey (0.05, strength 1), which ``world.color`` does not
    change: the tree is emptied (no World Output: black). 4.5 worlds have no tree and use ``color``."""
    w = bpy.data.worlds.new(name)
    w.color = (0.0, 0.0, 0.0)
    if w.node_tree is not None:
        w.node_tree.nodes.clear()
    return w
