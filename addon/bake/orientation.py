"""Which side of a mesh a bake measures, and meshes whose closed surfaces face inward.

Cycles bakes the side a face's normal points to. ``bpy.ops.mesh.primitive_cube_add(scale=(-1, 1, 1))``
(and other primitives added with a negative scale) writes the scale into the vertices and keeps the
winding, so the object's scale is 1 and every normal of the closed cube points into it: the bake then
measures the inside of an empty box, AO = 0 and E = 0 on every texel, while a render (which shades a
diffuse face on the side a ray hits) shows the cube lit. A true negative object scale (det < 0) is
handled by Cycles and bakes the outside.

A closed shell of the evaluated mesh wound inside out (negative signed volume,
``core.lightmap.inward_shells``) with nothing inside its bounding box (no light but suns, no other
object, no other shell of the mesh) and no emissive material is such a mistake: a room modelled with inward normals holds its
lights or objects and keeps its orientation. When every face of the evaluated mesh belongs to such
shells the mesh's normals are flipped for the bake (``Mesh.flip_normals``, which moves each corner's
UVs with it) and flipped back afterwards; when only some do, the object is skipped with one line.
"""
import numpy as np
from mathutils import Vector

from ..core import lightmap
from ..core.memo import FIGURES
from ..blender import scene as sc
from . import uv as uvmod

FIX = "Mesh > Normals > Recalculate Outside in edit mode"


def _world_box(obj):
    mw = obj.matrix_world
    pts = np.array([tuple(mw @ Vector(c)) for c in obj.bound_box])
    return pts.min(axis=0), pts.max(axis=0)


def _inside(points, lo, hi):
    p = np.asarray(points, float).reshape(-1, 3)
    return bool(np.any(np.all((p > lo) & (p < hi), axis=1)))


def _contents(view_layer, obj):
    """World points that make the inside of a closed surface matter: lights but suns (their position means
    nothing) and the bounding-box centres of the other renderable objects."""
    points = [o.matrix_world.translation[:] for o in view_layer.objects
              if o.type == "LIGHT" and o.data.type != "SUN" and not o.hide_render]
    points += [np.mean(_world_box(o), axis=0) for o in view_layer.objects
               if o != obj and o.type in {"MESH", "CURVE", "SURFACE", "META", "FONT"} and not o.hide_render]
    return points


def _emits(obj):
    """One of ``obj``'s materials has an Emission shader or a Principled BSDF with Emission Strength > 0 (its
    inside may be lit by itself)."""
    for slot in obj.material_slots:
        nt = slot.material.node_tree if slot.material is not None else None
        for n in (nt.nodes if nt is not None else ()):
            if n.bl_idname == "ShaderNodeEmission" and (n.inputs["Strength"].is_linked
                                                        or n.inputs["Strength"].default_value > 0):
                return True
            if n.bl_idname == "ShaderNodeBsdfPrincipled" and "Emission Strength" in n.inputs:
                strength = n.inputs["Emission Strength"]
                if strength.is_linked or strength.default_value > 0:
                    return True
    return False


def holds_something(scene, obj):
    """A light (not a sun) or another object lies inside ``obj``'s bounding box, or ``obj`` emits light."""
    return _emits(obj) or _inside(_contents(scene.view_layers[0], obj), *_world_box(obj))


def empty_inward_shells(scene, obj):
    """(fraction of the evaluated mesh's triangles in empty inward shells, number of such shells). A mesh only
    subdivided (:func:`blender.scene.subdivided_only`) is read as it is, before the subdivision: the same closed
    parts facing the same side (a shell's box is then its cage's, which holds the subdivided one); for such a mesh,
    or one without modifiers, the shells are a figure of its shape (``uv.geometry_figure``)."""
    vl = scene.view_layers[0]
    me = obj.data
    if sc.from_its_mesh(obj):
        labels, inward, _ = uvmod.geometry_figure(me, lambda: _shells(*sc.mesh_triangles(me), remember=False),
                                                  "inward shells")
        if not inward.any() or _emits(obj):
            return 0.0, 0
        co, tris = sc.mesh_triangles(me)
    else:
        co, tris = sc.evaluated_triangles(obj, vl.depsgraph)
        labels, inward, _ = _shells(co, tris)
        if not inward.any() or _emits(obj):
            return 0.0, 0
    mw = np.array(obj.matrix_world, float)
    world = co @ mw[:3, :3].T + mw[:3, 3]
    others = _contents(vl, obj)
    centres = [world[tris[labels == k].ravel()].mean(axis=0) for k in range(len(inward))]
    empty = np.zeros(len(inward), bool)
    for k in np.flatnonzero(inward):
        shell = world[tris[labels == k].ravel()]
        lo, hi = shell.min(axis=0), shell.max(axis=0)
        held = [c for j, c in enumerate(centres) if j != k]
        empty[k] = not _inside(others, lo, hi) and not _inside(held, lo, hi)
    return float(empty[labels].mean()), int(empty.sum())


def _shells(co, tris, remember=True):
    """``lightmap.inward_shells`` of a mesh's triangles (none for a mesh without faces), remembered by their digest
    unless ``remember`` is False (the caller keeps the result under a key of its own)."""
    if not len(tris):
        return np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0)
    return FIGURES.call(lightmap.inward_shells, co, tris) if remember else lightmap.inward_shells(co, tris)


def check(scene, objects):
    """Return ``({object name: mesh to flip for the bake}, {object name: why it is skipped})``."""
    flips, skipped = {}, {}
    for o in objects:
        fraction, shells = empty_inward_shells(scene, o)
        if fraction == 0.0:
            continue
        if fraction == 1.0:
            flips[o.name] = o.data
        else:
            skipped[o.name] = (f"{shells} of its closed parts have normals pointing inward and nothing inside "
                               f"(they would bake black): {FIX}")
    return flips, skipped


def describe(names):
    """The warning for objects baked with their normals flipped."""
    return (", ".join(f"'{n}'" for n in names) + ": normals point into a closed, empty surface (e.g. a primitive "
            f"added with a negative scale): baked the outside, as a render shows it (normals flipped for the bake "
            f"only; {FIX} fixes the file)")


def faces_into_itself(scene, obj, faces=64):
    """Fraction of (up to ``faces``, evenly spread) faces of ``obj`` whose normal ray, from just off the face
    centre, hits ``obj`` itself: 1 for a closed surface whose normals point inward, 0 for an outward convex one."""
    vl = scene.view_layers[0]
    me = obj.data
    n = len(me.polygons)
    if n == 0:
        return 0.0
    centre = np.zeros(n * 3)
    normal = np.zeros(n * 3)
    me.polygons.foreach_get("center", centre)
    me.polygons.foreach_get("normal", normal)
    pick = np.unique(np.linspace(0, n - 1, min(n, faces)).astype(int))
    mw = np.array(obj.matrix_world, float)
    lin = mw[:3, :3]
    p = centre.reshape(-1, 3)[pick] @ lin.T + mw[:3, 3]
    d = normal.reshape(-1, 3)[pick] @ np.linalg.inv(lin)
    d *= np.sign(np.linalg.det(lin)) / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    lo, hi = _world_box(obj)
    eps = 1e-4 * max(float(np.max(hi - lo)), 1e-3)
    own = 0
    for origin, direction in zip(p + eps * d, d):
        hit = scene.ray_cast(vl.depsgraph, Vector(origin), Vector(direction))
        own += bool(hit[0]) and hit[4] is not None and hit[4].name == obj.name
    return own / len(pick)
