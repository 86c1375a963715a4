"""Minimal scene building blocks from bpy.data and bmesh (no operators, no context needed)."""
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


def evaluated_triangles(obj, depsgraph):
    """(object-space vertices (V, 3) float64, loop-triangle vertex indices (T, 3)) of ``obj``'s evaluated mesh
    (modifiers applied, what Cycles renders); empty arrays when it has no mesh."""
    ev = obj.evaluated_get(depsgraph)
    me = ev.to_mesh()
    if me is None:
        ev.to_mesh_clear()
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    try:
        me.calc_loop_triangles()
        co = np.zeros(len(me.vertices) * 3, np.float64)
        me.vertices.foreach_get("co", co)
        tris = np.zeros(len(me.loop_triangles) * 3, np.int64)
        me.loop_triangles.foreach_get("vertices", tris)
    finally:
        ev.to_mesh_clear()
    return co.reshape(-1, 3), tris.reshape(-1, 3)


def black_world(name="IL temporary world"):
    """A world that emits nothing, as Cycles renders a scene without a world. ``bpy.data.worlds.new`` gives
    5.0 worlds a node tree whose Background is grey (0.05, strength 1), which ``world.color`` does not
    change: the tree is emptied (no World Output: black). 4.5 worlds have no tree and use ``color``."""
    w = bpy.data.worlds.new(name)
    w.color = (0.0, 0.0, 0.0)
    if w.node_tree is not None:
        w.node_tree.nodes.clear()
    return w
