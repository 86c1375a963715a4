"""The SSAO lab's built-in minimal scenes (bpy.data + bmesh), each showing one behaviour.

- ``plane``: one open plane (k_A = 1 everywhere; the sphere kernel reads 0.5);
- ``corner``: a box in a room corner (floor + two walls 3 m high; closed forms of
  REFERENCE.md §3 away from the box);
- ``thin``: a thin pole and a thin plate over a floor (depth buffers treat them
  as infinitely thick: the floor behind them, seen from the camera, is over-darkened);
- ``edge``: a box cut by the right screen edge (occluders off screen are lost);
- ``discontinuity``: a ball floating far in front of a wall (halos on the wall).

Every scene: a camera, an empty world (strength 1) whose AO distance is the
given radius, metres as units, and ``scene["il_ssao_scene"]`` = its name.
``REGIONS`` gives, per failure scene, functions of the world positions (H, W, 3)
and the G-buffer that pick the pixels where the failure shows and, where one
exists, a control: the same kind of pixels where the method's assumption holds
(the box fully on screen; the floor in front of the pole).
"""
import bmesh
import numpy as np

from ...core.errors import InputError
from ...core import analytic
from ...core.ssao import limits
from ...core.ssao import metrics
from ...core.ssao.limits import SCENES
from ...blender import scene as sc
from ..options import SSAOOptions

#: Geometry of the corner scene (metres): floor [0, ROOM]², walls x = 0 and y = 0 of height WALL.
ROOM, WALL = 8.0, 3.0
#: The box in the corner: centre and edge length.
BOX_CENTRE, BOX_SIZE = (2.2, 1.6, 0.5), 1.0
#: Edge scene: a 1.2 x 1.2 x 2 m box just beyond the right screen edge, and the same box on screen.
EDGE_BOX, INNER_BOX = (3.0, 0.0, 1.0), (-0.6, 0.3, 1.0)
#: Thin scene: pole (x, y, radius), 1.6 m high; plate centre and half extents (2 cm thick).
POLE, PLATE, PLATE_HALF = (-0.7, 0.4, 0.04), (0.7, 0.2, 0.3), (0.45, 0.45, 0.01)


def _floor(scene, size=40.0, location=(0, 0, 0)):
    return sc.plane(scene, "Floor", size, location=location)


def _cylinder(scene, name, radius, height, location):
    def build(bm):
        bmesh.ops.create_cone(bm, cap_ends=True, cap_tris=False, segments=16,
                              radius1=radius, radius2=radius, depth=height)
    return sc.mesh_object(scene, name, build, location)


def _plane_scene(scene, radius):
    _floor(scene)
    sc.camera(scene, "Camera", (0.0, -7.0, 2.2), target=(0.0, 0.0, 0.0))


def _corner_scene(scene, radius):
    sc.plane(scene, "Floor", ROOM, location=(ROOM / 2, ROOM / 2, 0.0))
    sc.plane(scene, "Wall X", 1.0, location=(0.0, ROOM / 2, WALL / 2), rotation=sc.deg(0, 90, 0)).scale = (WALL, ROOM, 1)
    sc.plane(scene, "Wall Y", 1.0, location=(ROOM / 2, 0.0, WALL / 2), rotation=sc.deg(90, 0, 0)).scale = (ROOM, WALL, 1)
    sc.box(scene, "Box", BOX_SIZE, location=BOX_CENTRE)
    sc.camera(scene, "Camera", (7.0, 6.0, 4.2), target=(1.3, 1.1, 0.5))


def _thin_scene(scene, radius):
    _floor(scene)
    _cylinder(scene, "Pole", POLE[2], 1.6, (POLE[0], POLE[1], 0.8))
    sc.box(scene, "Plate", (2 * PLATE_HALF[0], 2 * PLATE_HALF[1], 2 * PLATE_HALF[2]), location=PLATE)
    sc.camera(scene, "Camera", (0.0, -5.0, 2.5), target=(0.0, 0.2, 0.3))


def _edge_scene(scene, radius):
    _floor(scene)
    sc.box(scene, "Box", (1.2, 1.2, 2.0), location=EDGE_BOX)
    sc.box(scene, "Inner Box", (1.2, 1.2, 2.0), location=INNER_BOX)
    sc.camera(scene, "Camera", (0.0, -6.0, 3.0), target=(0.0, 0.0, 0.3))


def _discontinuity_scene(scene, radius):
    _floor(scene)
    sc.plane(scene, "Wall", 1.0, location=(0.0, 2.0, 2.0), rotation=sc.deg(90, 0, 0)).scale = (12, 4, 1)
    sc.sphere(scene, "Ball", 0.5, location=(0.0, -0.5, 1.6), segments=32, rings=16)
    sc.camera(scene, "Camera", (0.0, -6.0, 1.4), target=(0.0, 2.0, 1.2))


_BUILDERS = {"plane": _plane_scene, "corner": _corner_scene, "thin": _thin_scene,
             "edge": _edge_scene, "discontinuity": _discontinuity_scene}
assert tuple(_BUILDERS) == SCENES


def build_scene(name, resolution=SSAOOptions.resolution, radius=SSAOOptions.BUILTIN_RADIUS):
    """A new scene ``SSAO <name>`` (square ``resolution``), world AO distance = ``radius``."""
    limits.check_scene(name)
    if radius <= 0:
        raise InputError(f"radius must be positive, got {radius}")
    scene = sc.new_scene(f"SSAO {name}", (int(resolution), int(resolution)))
    _BUILDERS[name](scene, radius)
    sc.world(scene, strength=1.0, ao_distance=radius)
    scene["il_ssao_scene"] = name
    return scene


# ---------------------------------------------------------------- failure regions
# Each: (label, region(world, gb, radius), control(world, gb, radius) or None) -> bool masks.

def _near_box(world, centre, half, reach):
    x, y, z = world[..., 0], world[..., 1], world[..., 2]
    return (z < 1e-3) & (np.abs(x - centre[0]) < half + reach) & (np.abs(y - centre[1]) < half + reach)


def _edge_region(world, gb, radius):
    """Floor within R of the box cut by the screen edge."""
    return _near_box(world, EDGE_BOX, 0.6, radius)


def _edge_control(world, gb, radius):
    """Floor within R of the same box fully on screen."""
    return _near_box(world, INNER_BOX, 0.6, radius)


def _halo(world, gb, radius):
    """Wall pixels (y = 2, above the floor's reach) next to the ball's silhouette: true k_A = 1 there."""
    wall = (np.abs(world[..., 1] - 2.0) < 1e-3) & (world[..., 2] > radius + 0.05)
    return wall & metrics.behind_silhouette(gb, jump=radius)


def _behind_pole(world, radius, sign):
    """Floor within R of the pole's surface, beyond it (sign +1) or before it (sign -1) seen from
    the camera (which looks along +y)."""
    x, y, z = world[..., 0], world[..., 1], world[..., 2]
    near = np.hypot(x - POLE[0], y - POLE[1]) < POLE[2] + radius
    return (z < 1e-3) & near & (sign * (y - POLE[1]) > POLE[2])


def _thin_region(world, gb, radius):
    """Floor within R beyond the pole or beyond the plate's far edge, seen from the camera.

    The depth buffer fills the free space behind a thin occluder: horizon and depth tests there
    meet the occluder's front face and count everything behind it as solid, so SSAO darkens
    floor that is truly open (k_A near 1). Floor under the plate is left out: what hides it
    there is a different failure (geometry the camera cannot see)."""
    x, y, z = world[..., 0], world[..., 1], world[..., 2]
    edge = PLATE[1] + PLATE_HALF[1]
    gap_x = np.maximum(np.abs(x - PLATE[0]) - PLATE_HALF[0], 0.0)
    plate = (z < 1e-3) & (y > edge) & (np.hypot(gap_x, y - edge) < radius)
    return _behind_pole(world, radius, +1) | plate


def _thin_control(world, gb, radius):
    """Floor within R in front of the pole: the pole's front face is the true horizon there."""
    return _behind_pole(world, radius, -1)


def _open_plane(world, gb, radius):
    return np.abs(world[..., 2]) < 1e-3


REGIONS = {"plane": ("open plane", _open_plane, None),
           "thin": ("floor behind thin occluders", _thin_region, _thin_control),
           "edge": ("floor next to the box cut by the screen edge", _edge_region, _edge_control),
           "discontinuity": ("wall next to the ball's silhouette", _halo, None)}


def corner_closed_form(world, radius):
    """k_A of the corner scene's floor and wall pixels where REFERENCE.md §3 has a closed form; NaN elsewhere.

    core.analytic.corner_k_a of the distances to the two other room planes, valid where the box and
    the room's open edges are more than R away (the planes count as infinite there).
    """
    x, y, z = world[..., 0], world[..., 1], world[..., 2]
    eps = 1e-3
    on_floor = (np.abs(z) < eps) & (x > 0) & (y > 0)
    on_wx = (np.abs(x) < eps) & (y > 0) & (z > 0)
    on_wy = (np.abs(y) < eps) & (x > 0) & (z > 0)
    a = np.where(on_floor, x, np.where(on_wx, y, x)) / radius
    b = np.where(on_floor, y, z) / radius
    bx, by, bz = BOX_CENTRE
    half = BOX_SIZE / 2
    gap = np.sqrt(np.maximum(np.abs(x - bx) - half, 0) ** 2 + np.maximum(np.abs(y - by) - half, 0) ** 2
                  + np.maximum(np.abs(z - bz) - half, 0) ** 2)
    far = ROOM - radius
    ok = (on_floor | on_wx | on_wy) & (gap > radius) & (x < far) & (y < far) & (z < WALL - radius)
    return np.where(ok, analytic.corner_k_a(a, b), np.nan)
