"""Built-in minimal shadow scenes: no more geometry than each case needs.

Every scene has a floor "Floor" (an open plane: a receiver only), closed occluders, a camera
and one light named "Light" of the requested kind (point, spot or sun), radius 0.

  sphere  a sphere over the floor (the baseline every method should get right)
  stairs  a sphere over four steps: a non-planar receiver (planar shadows fail)
  acne    a box on the floor under a grazing sun: acne / peter-panning for shadow maps
  plate   a thin plate just above the floor: peter-panning and light leaks
  inside  a high slab with the camera standing in its shadow volume (z-pass fails)
"""
import math

from mathutils import Vector

from ...core.errors import InputError
from ...blender import scene as sc
from ..options import SHADOW_SCENE_CHOICES

SCENES = tuple(c[0] for c in SHADOW_SCENE_CHOICES)
LIGHT_KINDS = ("sun", "point", "spot")
LIGHT_NAME = "Light"


def build(name, light="sun", resolution=(128, 128), segments=32, rings=16):
    """Build the built-in scene ``name`` as a new bpy scene with a ``light`` of that kind; return it."""
    if name not in SCENES:
        raise InputError(f"unknown shadow scene '{name}' (choose from {', '.join(SCENES)})")
    if light not in LIGHT_KINDS:
        raise InputError(f"unknown light kind '{light}' (choose from {', '.join(LIGHT_KINDS)})")
    scene = sc.new_scene(f"IL Shadows {name}", resolution)
    floor = sc.plane(scene, "Floor", 12.0)
    spec = globals()[f"_{name}"](scene, segments, rings)
    lamp = _light(scene, light, spec["target"], spec["sun"], spec["distance"])
    # names may get a ".001" suffix when the file already has a "Light" or "Floor": keep the real ones
    scene["il_shadow_light"] = lamp.name
    scene["il_shadow_receiver"] = floor.name
    return scene


def _sphere(scene, segments, rings):
    sc.sphere(scene, "Sphere", 0.7, location=(0.0, 0.0, 1.1), segments=segments, rings=rings, smooth=False)
    sc.camera(scene, "Camera", (0.5, -3.2, 3.2), target=(0.4, 0.6, 0.3), lens=30)
    return {"target": (0.0, 0.0, 1.1), "sun": (45.0, 0.0, 120.0), "distance": 4.0}


def _stairs(scene, segments, rings):
    for i in range(4):
        h = 0.3 * (i + 1)
        sc.box(scene, f"Step{i}", (3.0, 0.6, h), location=(0.0, -0.9 + 0.6 * i, h / 2))
    sc.sphere(scene, "Sphere", 0.5, location=(0.0, -0.2, 2.4), segments=segments, rings=rings, smooth=False)
    sc.camera(scene, "Camera", (4.0, -5.0, 4.5), target=(0.0, 0.0, 0.6), lens=40)
    return {"target": (0.0, -0.2, 2.4), "sun": (20.0, 0.0, 30.0), "distance": 3.5}


def _acne(scene, segments, rings):
    sc.box(scene, "Box", (1.0, 1.0, 1.0), location=(0.0, 0.0, 0.5), rotation=sc.deg(0, 0, 35))
    sc.camera(scene, "Camera", (0.0, -6.0, 3.5), target=(0.6, 1.0, 0.0), lens=40)
    return {"target": (0.0, 0.0, 0.5), "sun": (75.0, 0.0, 110.0), "distance": 5.0}


def _plate(scene, segments, rings):
    sc.box(scene, "Plate", (1.6, 1.6, 0.04), location=(0.0, 0.0, 0.07))
    sc.camera(scene, "Camera", (0.0, -5.0, 3.5), target=(0.4, 0.4, 0.0), lens=40)
    return {"target": (0.0, 0.0, 0.07), "sun": (45.0, 0.0, 30.0), "distance": 3.0}


def _inside(scene, segments, rings):
    sc.box(scene, "Slab", (3.0, 3.0, 0.3), location=(0.0, 0.0, 3.0))
    sc.camera(scene, "Camera", (0.0, -0.5, 1.2), target=(0.0, 4.0, 0.0), lens=24)
    return {"target": (0.0, 0.0, 3.0), "sun": (10.0, 0.0, 0.0), "distance": 4.0}


def _light(scene, kind, target, sun_rotation, distance):
    """One radius-0 light named "Light": the sun rotated by ``sun_rotation`` (degrees), the point
    and spot lights ``distance`` above ``target`` along the same direction."""
    rot = sc.deg(*sun_rotation)
    if kind == "sun":
        return sc.light(scene, LIGHT_NAME, "SUN", 3.0, rotation=rot)
    obj = sc.light(scene, LIGHT_NAME, kind.upper(), 1000.0)
    from mathutils import Euler
    down = Euler(rot).to_matrix() @ Vector((0.0, 0.0, -1.0))
    obj.location = Vector(target) - distance * down
    sc.look_at(obj, target)
    if kind == "spot":
        obj.data.spot_size = math.radians(150.0)
        obj.data.spot_blend = 0.0
    return obj
