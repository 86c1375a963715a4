"""The embedded demo scene: a floor, three objects for three shading models, a sun and a point light."""
import bpy

from ...blender import scene as sc

DEMO_NAME = "IL Demo"
ROLE = "il_demo_role"
ROLES = ("Floor", "Box", "Sphere", "Torus", "Sun", "Key", "Camera")


def get(scene, role):
    """The demo object playing ``role`` in ``scene`` (its name may carry a .001 suffix)."""
    for obj in scene.objects:
        if obj.get(ROLE) == role:
            return obj
    obj = scene.objects.get(role)
    if obj is None:
        from ...core.errors import InputError
        raise InputError(f"scene '{scene.name}' has no demo object '{role}'")
    return obj


def build_demo_scene(new_scene=True, resolution=(320, 240)):
    """Build the demo scene and return it.

    With ``new_scene`` a scene named "IL Demo" (or "IL Demo.001", ...) is added
    and the user's scenes are left untouched; otherwise the current scene is filled.
    """
    scene = sc.new_scene(DEMO_NAME, resolution) if new_scene else bpy.context.scene
    objs = (
        sc.plane(scene, "Floor", 8.0),
        sc.box(scene, "Box", 1.0, location=(-1.6, 0.3, 0.5), rotation=sc.deg(0, 0, 25)),
        sc.sphere(scene, "Sphere", 0.6, location=(0.0, -0.4, 0.6)),
        sc.mesh_object(scene, "Torus", _torus, location=(1.6, 0.3, 0.35), smooth=True),
        sc.light(scene, "Sun", "SUN", 2.0, rotation=sc.deg(40, 0, 30)),
        sc.light(scene, "Key", "POINT", 300.0, location=(2.0, -3.0, 3.5)),
        sc.camera(scene, "Camera", (0.0, -7.0, 4.0), target=(0.0, 0.0, 0.4), lens=40),
    )
    sc.world(scene, strength=0.3, color=(0.8, 0.9, 1.0))
    for obj, role in zip(objs, ROLES):
        obj[ROLE] = role
    return scene


def _torus(bm, major=0.55, minor=0.3, segments=48, sides=18):
    import math
    verts = []
    for i in range(segments):
        u = 2 * math.pi * i / segments
        for j in range(sides):
            v = 2 * math.pi * j / sides
            r = major + minor * math.cos(v)
            verts.append(bm.verts.new((r * math.cos(u), r * math.sin(u), minor * math.sin(v))))
    for i in range(segments):
        for j in range(sides):
            a = verts[i * sides + j]
            b = verts[((i + 1) % segments) * sides + j]
            c = verts[((i + 1) % segments) * sides + (j + 1) % sides]
            d = verts[i * sides + (j + 1) % sides]
            bm.faces.new((a, b, c, d))
