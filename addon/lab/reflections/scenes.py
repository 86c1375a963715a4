"""Built-in scenes of the reflection lab, each measuring one limitation seed 002 names: nearby geometry
(reflected objects are taken as infinitely far), a flat mirror (almost one colour), a concave object (no
self-reflection); "sphere" has the sky alone (the maps' filtering error). Surroundings are emissive and
the world's light sampling is off, so one Cycles sample per pixel is exact (no noise in the reference).
"""
import math

import bmesh
import bpy
import numpy as np

from ...blender import compat
from ...blender import scene as S
from ...core.envmap import latlong

SCENES = ("sphere", "nearby", "flat", "concave")
#: Where the built-in scenes' maps are captured (the mirror's centre unless moved).
CAPTURE = (0.0, 0.0, 0.0)


def analytic_sky(d):
    """An analytic environment L(d) (…, 3): a blue-to-white sky, a brown ground, a warm sun blob, stripes in
    azimuth so that a wrong direction shows."""
    d = np.asarray(d, np.float64)
    z = d[..., 2]
    sky = np.stack([0.3 + 0.5 * z, 0.5 + 0.4 * z, 0.9 + 0.1 * z], -1) * (z >= 0)[..., None]
    ground = np.stack([0.35, 0.25, 0.15], -1) * np.ones_like(z)[..., None] * (z < 0)[..., None]
    sun = np.exp(40 * (d @ np.array([0.48, -0.6, 0.64]) - 1))[..., None] * np.array([6.0, 5.0, 3.5])
    stripes = 0.1 * (1 + np.cos(6 * np.arctan2(d[..., 1], d[..., 0])))[..., None]
    return sky + ground + sun + stripes


def sky_world(scene, height=128):
    """The scene's world: the analytic sky as a packed float lat-long image (2 height x height)."""
    env = analytic_sky(latlong.latlong_directions(height, 2 * height)).astype(np.float32)
    img = bpy.data.images.new("IL Lab Sky", 2 * height, height, float_buffer=True, alpha=True)
    img.pixels.foreach_set(np.flipud(np.concatenate([env, np.ones(env.shape[:2] + (1,), np.float32)], -1)).ravel())
    img.pack()
    w = bpy.data.worlds.new("IL Lab Sky")
    compat.ensure_use_nodes(w)
    nt = w.node_tree
    bg = nt.nodes.get("Background") or nt.nodes.new("ShaderNodeBackground")
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = img
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    w.cycles.sampling_method = "NONE"     # no importance map to build; mirrors never sample it
    scene.world = w
    return w


def emissive(obj, color):
    mat = bpy.data.materials.new(f"IL Lab Emit {obj.name}")
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*color, 1.0)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    obj.data.materials.append(mat)
    return obj


def _boxes(sc):
    emissive(S.box(sc, "Red Box", 0.8, (1.8, 0.6, 0.0)), (1.0, 0.2, 0.1))
    emissive(S.box(sc, "Green Box", 0.8, (-1.8, 0.9, 0.3)), (0.1, 0.9, 0.2))
    emissive(S.box(sc, "Blue Box", (3.0, 0.4, 0.4), (0.0, 2.2, -0.2)), (0.2, 0.3, 1.0))


def _bowl(bm):
    bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=1.0)
    bmesh.ops.delete(bm, geom=[v for v in bm.verts if v.co.y < -0.05], context="VERTS")


def build(name, resolution=64):
    """A new scene ``IL Reflections <name>`` with the mirror object "Mirror" and a camera; returns it."""
    sc = S.new_scene(f"IL Reflections {name}", (resolution, resolution))
    sky_world(sc)
    if name == "sphere":
        S.sphere(sc, "Mirror", 1.0, segments=64, rings=32)
    elif name == "nearby":
        S.sphere(sc, "Mirror", 0.3, segments=64, rings=32)
        _boxes(sc)
    elif name == "flat":
        S.plane(sc, "Mirror", 2.0, rotation=(math.radians(80), 0.0, 0.0))
        emissive(S.box(sc, "Red Box", 0.6, (0.5, -1.8, 0.9)), (1.0, 0.2, 0.1))
    elif name == "concave":
        S.mesh_object(sc, "Mirror", _bowl, smooth=True)      # the back half of a sphere, open to the camera
    else:
        from ...core.errors import InputError
        raise InputError(f"unknown scene {name!r}: choose from {', '.join(SCENES)}")
    S.camera(sc, "Camera", (0.0, -6.0, 1.5), target=(0.0, 0.0, 0.0), lens={"flat": 40, "nearby": 110}.get(name, 50))
    return sc
