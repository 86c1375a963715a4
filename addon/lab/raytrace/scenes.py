"""Built-in scenes of the ray-tracing lab, small and exact: radius-0 lights with soft falloff off, a black world
unless the scene is about sky light, materials Cycles and Whitted read the same way."""
import bpy

from ...blender import materials, scene as sc
from ...core.errors import InputError


def _principled(name, base=(0.8, 0.8, 0.8), metallic=0.0, roughness=0.5, transmission=0.0, ior=1.5):
    mat = materials.empty_material(name)
    nt = mat.node_tree
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.inputs["Base Color"].default_value = (*base, 1.0)
    p.inputs["Metallic"].default_value = metallic
    p.inputs["Roughness"].default_value = roughness
    p.inputs["IOR"].default_value = ior
    p.inputs["Transmission Weight"].default_value = transmission
    nt.links.new(p.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _diffuse(name, color):
    """A Diffuse BSDF of roughness 0: Lambert, the same k_d for Whitted and Cycles (no specular layer)."""
    mat = materials.white_lambert(name)
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*color, 1.0)
    return mat


def _assign(obj, mat):
    obj.data.materials.append(mat)
    return obj


def _base(name, resolution, sphere_mat, light="POINT", camera=(0.0, -6.0, 3.0)):
    scene = sc.new_scene(f"IL Raytrace {name}", resolution)
    scene.world = sc.black_world(f"IL Raytrace {name} World")
    _assign(sc.plane(scene, "Floor", 8.0), _diffuse("IL RT Floor", (0.8, 0.7, 0.6)))
    if sphere_mat is not None:
        _assign(sc.sphere(scene, "Sphere", 1.0, location=(0, 0, 1.0)), sphere_mat)
    if light == "POINT":
        sc.light(scene, "Light", "POINT", 400.0, location=(2.0, -2.0, 4.0))
    sc.camera(scene, "Camera", camera, target=(0, 0, 0.8), lens=35.0)
    return scene


def build(name, resolution=(64, 64)):
    """A new scene ``name`` (RAYTRACE_SCENE_CHOICES); the caller removes it (blender.scene.remove_scene)."""
    if name == "diffuse":
        return _base(name, resolution, _diffuse("IL RT Sphere", (0.3, 0.5, 0.8)))
    if name == "mirror":
        return _base(name, resolution, _principled("IL RT Mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    if name == "glass":
        return _base(name, resolution, _principled("IL RT Glass", (1.0, 1.0, 1.0), roughness=0.0, transmission=1.0))
    if name == "ior1":
        return _base(name, resolution, _principled("IL RT Glass 1", (1.0, 1.0, 1.0), roughness=0.0,
                                                   transmission=1.0, ior=1.0))
    if name == "tir":
        return _base(name, resolution, _principled("IL RT Diamond", (1.0, 1.0, 1.0), roughness=0.0,
                                                   transmission=1.0, ior=2.4))
    if name == "grazing":
        scene = _base(name, resolution, None, camera=(0.0, -7.0, 0.35))
        _assign(sc.box(scene, "Block", (1.0, 1.0, 1.0), location=(0, 2.0, 0.5)),
                _diffuse("IL RT Block", (0.2, 0.6, 0.3)))
        floor = next(o for o in scene.objects if o.data is not None and o.data.name.startswith("Floor"))
        floor.data.materials[0] = _principled("IL RT Mirror Floor", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0)
        return scene
    if name == "walls":
        scene = _base(name, resolution, None, camera=(0.0, -6.0, 2.0))
        wall = _diffuse("IL RT Wall", (0.8, 0.8, 0.8))
        _assign(sc.plane(scene, "Left Wall", 4.0, location=(-1.5, 0, 2.0), rotation=sc.deg(0, 90, 0)), wall)
        _assign(sc.plane(scene, "Right Wall", 4.0, location=(1.5, 0, 2.0), rotation=sc.deg(0, -90, 0)), wall)
        next(o for o in scene.objects if o.type == "LIGHT").location = (0.0, 0.0, 3.5)
        return scene
    if name == "area":
        scene = _base(name, resolution, _diffuse("IL RT Sphere", (0.3, 0.5, 0.8)), light=None)
        sc.light(scene, "Area", "AREA", 400.0, location=(2.0, -2.0, 4.0), rotation=sc.deg(35, 0, 45))
        sc.world(scene, strength=0.3)
        return scene
    raise InputError(f"unknown built-in scene '{name}'")


def remove(scene):
    """Remove a built-in scene and what it made."""
    mats = {m for o in scene.objects if o.type == "MESH" for m in o.data.materials if m is not None}
    sc.remove_scene(scene, list(mats))
    for w in [w for w in bpy.data.worlds if w.users == 0 and w.name.startswith("IL Raytrace")]:
        bpy.data.worlds.remove(w)
