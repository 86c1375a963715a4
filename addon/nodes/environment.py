"""Environment mapping as shading (seed 002, "Reflection mapping", "Refraction mapping"): the node group
"IL Environment Map" and the materials of ``illumination.assign_environment_mapping``.

The group reads the shading point (Geometry: n, v = Incoming) and returns the lookup direction and its weight
(core.envmap.reflection, the numpy twin):

    r = 2 (n·v) n − v                                  (Refract 0)
    t = −η v + (η c_i − c_t) n, c_t = √(1 − η² (1 − c_i²)), η = 1/IOR entering, IOR leaving (Refract 1)
    Weight = F (reflect) or (1 − F) [c_t² ≥ 0] (refract) with Fresnel 1; 1 or [c_t² ≥ 0] with Fresnel 0
    F = F_0 + (1 − F_0)(1 − cos θ)⁵, F_0 = ((IOR − 1)/(IOR + 1))², θ on the denser side (F = 0 at IOR 1)

and the image coordinates of that direction in the project's cube strip ("Cube UV": six faces side by side,
core.envmap.maps) and sphere map ("Sphere UV"). A material built here looks up the world's environment image
(LATLONG: Blender's Environment Texture with the same image and interpolation; CUBE, SPHERE: an image the
project converts from it, core.envmap.maps.convert) and emits colour × Weight × Background Strength.
"""
import dataclasses

import bpy
import numpy as np

from ..blender import compat
from ..blender.materials import under_preview
from ..core.envmap import maps
from ..core.errors import InputError
from ..core.options import Options, option
from .builder import Graph
from .groups import sync_interface
from .material import make_before_slots_change, material_slots_of, put_material, split_shadable

GROUP = "IL Environment Map"
GROUP_VERSION = 3
F, V = "NodeSocketFloat", "NodeSocketVector"
INPUTS = [("IOR", F, 1.5, (0.01, 10.0), "Relative index of refraction n2/n1 (Schlick's F0 and Snell's law)"),
          ("Refract", F, 0.0, (0.0, 1.0), "0: reflect (r), 1: refract (t)"),
          ("Fresnel", F, 1.0, (0.0, 1.0), "1: weight F (reflect) or 1 - F (refract); 0: weight 1"),
          ("Cube Size", F, 0.0, (0.0, 65536.0), "Texels per cube face side: Cube UV stays half a texel inside its "
           "face so that linear filtering never reads the next face of the strip (0: not clamped)")]
OUTPUTS = [("Direction", V), ("Weight", F), ("Cube UV", V), ("Sphere UV", V)]

MODES = (("REFLECT", "Reflect", "Look the environment up along r = reflect(-v, n)"),
         ("REFRACT", "Refract", "Look the environment up along Snell's t (no light under total internal reflection)"))
PROJECTIONS = (("LATLONG", "Lat-long", "The world's equirectangular image itself"),
               ("CUBE", "Cube map", "Six faces converted from the world's image"),
               ("SPHERE", "Sphere map", "A mirror-ball image converted from the world's image"))


@dataclasses.dataclass
class EnvironmentOptions(Options):
    """How Assign Environment Mapping shades the selected meshes."""
    mode: str = option("REFLECT", "Mode", "reflection or refraction mapping", choices=MODES)
    projection: str = option("LATLONG", "Projection", "map type the material looks up", choices=PROJECTIONS)
    ior: float = option(1.5, "IOR", "index of refraction (Fresnel and Snell)", minimum=0.01, maximum=10.0)
    fresnel: bool = option(True, "Fresnel", "weight by Schlick's F (reflect) or 1 - F (refract)")
    map_size: int = option(0, "Map Size", "cube face or sphere image side in texels (0: as many texels as the "
                           "lat-long image)", minimum=0, maximum=16384)


# -- the world's environment ------------------------------------------------------------------------

def world_environment_node(scene):
    """(Environment Texture node, Background Strength) of the scene's world; InputError naming what is missing."""
    world = scene.world
    if world is None or world.node_tree is None:
        raise InputError(f"scene '{scene.name}' has no world with nodes: add a world with an Environment Texture")
    env = [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment"]
    if not env:
        raise InputError(f"world '{world.name}' has no Environment Texture node with an image")
    node = env[0]
    if node.image is None or node.image.size[0] == 0:
        raise InputError(f"the Environment Texture of world '{world.name}' has no image (or its file is missing)")
    if node.projection != "EQUIRECTANGULAR":
        raise InputError(f"the Environment Texture of world '{world.name}' is not equirectangular")
    if node.inputs["Vector"].is_linked:
        raise InputError(f"the Environment Texture of world '{world.name}' has a Vector input (Mapping): remove it")
    for link in node.outputs["Color"].links:
        if link.to_node.bl_idname == "ShaderNodeBackground" and not link.to_node.inputs["Strength"].is_linked:
            return node, float(link.to_node.inputs["Strength"].default_value)
    raise InputError(f"the Environment Texture of world '{world.name}' must feed a Background node's Color "
                     "(with a number as Strength)")


def _pixels(image):
    """Stored pixel values (H, W, 3), row 0 at the top (as stored: converted maps keep the colour space)."""
    w, h = image.size
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)
    rgb = px[..., :3] if image.channels >= 3 else np.repeat(px[..., :1], 3, axis=-1)
    return np.flipud(rgb)


def map_image(source, projection, size=0):
    """The Blender image the material of ``projection`` reads: ``source`` itself (LATLONG) or a converted,
    packed image "IL <Cube|Sphere> Map: <source>" (made again when the source or size changed)."""
    if projection == "LATLONG":
        return source
    env = _pixels(source)
    if env.shape[1] != 2 * env.shape[0]:
        raise InputError(f"image '{source.name}' is {env.shape[1]}x{env.shape[0]}: a lat-long map is twice as "
                         "wide as high")
    size = int(size) or maps.equal_texel_size(projection, env.shape[0])
    name = f"IL {'Cube' if projection == 'CUBE' else 'Sphere'} Map: {source.name}"
    key = f"{source.name}|{source.filepath}|{size}|{env.shape}"
    img = bpy.data.images.get(name)
    if img is not None and img.get("il_source_key") == key:
        return img
    data = maps.convert(env, projection, size).astype(np.float32)
    h, w = data.shape[:2]
    if img is not None and (tuple(img.size) != (w, h)):
        bpy.data.images.remove(img)
        img = None
    if img is None:
        img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    img.colorspace_settings.name = source.colorspace_settings.name
    rgba = np.concatenate([data, np.ones((h, w, 1), np.float32)], axis=-1)
    img.pixels.foreach_set(np.flipud(rgba).ravel())
    img.update()
    try:
        img.pack()
    except RuntimeError:
        pass                        # kept in memory only; made again from the world after reopening
    img["il_source_key"] = key
    return img


# -- the node group ---------------------------------------------------------------------------------

def ensure_group():
    """The node group "IL Environment Map" (rebuilt when made by another version)."""
    tree = bpy.data.node_groups.get(GROUP)
    if tree is not None and tree.bl_idname == "ShaderNodeTree" and tree.get("il_version") == GROUP_VERSION:
        return tree
    if tree is None or tree.bl_idname != "ShaderNodeTree":
        tree = bpy.data.node_groups.new(GROUP, "ShaderNodeTree")
    tree.nodes.clear()
    sync_interface(tree, INPUTS, OUTPUTS)
    tree.description = "Reflection/refraction mapping: lookup direction r or t, weight F or 1 - F, map coordinates"
    _build_group(Graph(tree))
    tree["il_version"] = GROUP_VERSION
    return tree


def _build_group(g):
    i = g.node("NodeGroupInput").outputs
    o = g.node("NodeGroupOutput").inputs
    with g.block("Direction: r or t (Snell)"):
        geo = g.node("ShaderNodeNewGeometry")
        n, v = geo.outputs["Normal"], geo.outputs["Incoming"]
        ci = g.math("MAXIMUM", g.dot(n, v), 0.0)
        r = g.vmath("SUBTRACT", g.scale(n, g.mul(ci, 2.0)), v, label="r = 2(n.v)n - v")
        inv = g.div(1.0, i["IOR"])
        eta = g.madd(geo.outputs["Backfacing"], g.sub(i["IOR"], inv), inv, label="eta")
        k = g.sub(1.0, g.mul(g.mul(eta, eta), g.sub(1.0, g.mul(ci, ci))), label="c_t^2")
        ok = g.math("GREATER_THAN", k, 0.0, label="transmitted")
        ct = g.math("SQRT", g.math("MAXIMUM", k, 0.0))
        t = g.vmath("SUBTRACT", g.scale(n, g.sub(g.mul(eta, ci), ct)), g.scale(v, eta), label="t")
        d = g.vlerp(r, t, i["Refract"])
    with g.block("Weight: Schlick F"):
        cd = g.math("MINIMUM", g.lerp(ci, ct, g.gt(eta, 1.0)), 1.0)
        f0 = g.math("POWER", g.div(g.sub(i["IOR"], 1.0), g.add(i["IOR"], 1.0)), 2.0, label="F0")
        grazing = g.mul(g.math("POWER", g.sub(1.0, cd), 5.0), g.gt(g.math("ABSOLUTE", g.sub(i["IOR"], 1.0)), 0.0),
                        label="(1 - cos)^5, 0 at IOR 1 (no interface)")
        f = g.madd(g.sub(1.0, f0), grazing, f0, label="F")
        f = g.lerp(1.0, f, ok)
        w_reflect = g.lerp(1.0, f, i["Fresnel"])
        w_refract = g.mul(ok, g.lerp(1.0, g.sub(1.0, f), i["Fresnel"]))
        g.feed(g.lerp(w_reflect, w_refract, i["Refract"]), o["Weight"])
    g.feed(d, o["Direction"])
    with g.block("Cube UV (strip of six faces) and Sphere UV"):
        sep = g.node("ShaderNodeSeparateXYZ")
        g.feed(d, sep.inputs[0])
        x, y, z = sep.outputs
        ax, ay, az = (g.math("ABSOLUTE", c) for c in (x, y, z))
        mx = g.mul(g.gt(g.add(ax, 1e-12), ay), g.gt(g.add(ax, 1e-12), az), label="major X (argmax: first wins)")
        my = g.mul(g.sub(1.0, mx), g.gt(g.add(ay, 1e-12), az))
        mz = g.sub(g.sub(1.0, mx), my)
        neg = [g.math("LESS_THAN", c, 0.0) for c in (x, y, z)]
        face = g.add(g.add(g.mul(mx, neg[0]), g.mul(my, g.add(2.0, neg[1]))), g.mul(mz, g.add(4.0, neg[2])))
        s = g.add(g.add(g.mul(mx, g.div(g.mul(z, -1.0), x)), g.mul(my, g.div(x, ay))), g.mul(mz, g.div(x, z)))
        tt = g.add(g.add(g.mul(mx, g.div(g.mul(y, -1.0), ax)), g.mul(my, g.div(z, y))),
                   g.mul(mz, g.div(g.mul(y, -1.0), az)))
        lo = g.div(0.5, i["Cube Size"], label="half a texel (0 when Cube Size is 0)")
        hi = g.sub(1.0, lo)
        sf = g.math("MINIMUM", g.math("MAXIMUM", g.madd(s, 0.5, 0.5), lo), hi)
        tf = g.math("MINIMUM", g.math("MAXIMUM", g.madd(tt, -0.5, 0.5), lo), hi)
        cube = g.node("ShaderNodeCombineXYZ")
        g.feed(g.div(g.add(face, sf), 6.0), cube.inputs[0])
        g.feed(tf, cube.inputs[1])
        g.feed(cube.outputs[0], o["Cube UV"])
        m = g.mul(2.0, g.math("SQRT", g.add(g.add(g.mul(x, x), g.mul(z, z)), g.math("POWER", g.sub(1.0, y), 2.0))))
        m = g.math("MAXIMUM", m, 1e-12)
        sph = g.node("ShaderNodeCombineXYZ")
        g.feed(g.add(g.div(x, m), 0.5), sph.inputs[0])
        g.feed(g.add(g.div(z, m), 0.5), sph.inputs[1])
        g.feed(sph.outputs[0], o["Sphere UV"])
    g.layout()


# -- materials ---------------------------------------------------------------------------------------

def build_material(mat, options, image, strength, interpolation="Linear"):
    """Fill ``mat`` with: IL Environment Map -> image lookup -> Emission(colour, Weight × ``strength``)."""
    compat.ensure_use_nodes(mat)
    tree = mat.node_tree
    tree.nodes.clear()
    g = Graph(tree)
    grp = g.node("ShaderNodeGroup", label=GROUP)
    grp.node_tree = ensure_group()
    grp.inputs["IOR"].default_value = options.ior
    grp.inputs["Refract"].default_value = 1.0 if options.mode == "REFRACT" else 0.0
    grp.inputs["Fresnel"].default_value = 1.0 if options.fresnel else 0.0
    if options.projection == "CUBE":
        grp.inputs["Cube Size"].default_value = float(image.size[1])
    if options.projection == "LATLONG":
        tex = g.node("ShaderNodeTexEnvironment", label="Environment (lat-long)")
        g.feed(grp.outputs["Direction"], tex.inputs["Vector"])
    else:
        tex = g.node("ShaderNodeTexImage", label=f"{options.projection.title()} map", extension="EXTEND")
        g.feed(grp.outputs["Cube UV" if options.projection == "CUBE" else "Sphere UV"], tex.inputs["Vector"])
    tex.image, tex.interpolation = image, interpolation
    em = g.node("ShaderNodeEmission")
    g.feed(tex.outputs["Color"], em.inputs["Color"])
    g.feed(g.mul(grp.outputs["Weight"], strength, label="Weight x Background Strength"), em.inputs["Strength"])
    out = g.node("ShaderNodeOutputMaterial")
    g.feed(em.outputs[0], out.inputs["Surface"])
    g.layout()
    if hasattr(getattr(mat, "cycles", None), "emission_sampling"):
        mat.cycles.emission_sampling = "NONE"       # a lookup of the world, not a lamp
    mat["il_envmap"] = dataclasses.asdict(options)
    return mat


def assign_environment_mapping(scene, objects, options=None):
    """Give every slot of the meshes in ``objects`` an environment-mapping material (one per original
    material, ``il_original`` keeping it for :func:`remove_environment_mapping`); returns (materials, warnings).
    Non-meshes are skipped with a warning; InputError (nothing changed) when no mesh or no world image."""
    options = (options or EnvironmentOptions()).validate()
    objects = list(objects)
    meshes, skipped = split_shadable(objects, lights=True)
    if not meshes:
        what = "; ".join(skipped) or "nothing is selected"
        raise InputError(f"nothing to shade: select at least one mesh object ({what})")
    node, strength = world_environment_node(scene)
    image = map_image(node.image, options.projection, options.map_size)
    interp = node.interpolation if options.projection == "LATLONG" else "Linear"
    warnings = [f"skipped {'; '.join(skipped)}"] if skipped else []
    made = {}

    def environment_of(orig):
        key = orig.as_pointer() if orig is not None else None
        if key not in made:
            label = f"IL Environment {options.mode.title()}"
            mat = made[key] = bpy.data.materials.new(f"{label}: {orig.name}" if orig is not None else label)
            build_material(mat, options, image, strength, interp)
            if orig is None:
                mat["il_empty"] = True
            else:
                mat["il_original"] = orig
        return made[key]

    make_before_slots_change(meshes, [_original(under_preview(cur)) for _, _, cur in material_slots_of(meshes)],
                             environment_of, made)
    for owner, index, cur in list(material_slots_of(meshes)):
        put_material(owner, index, environment_of(_original(cur)))
    return list(made.values()), warnings


def _original(mat):
    """The material an environment-mapping material replaced, else ``mat`` itself."""
    return mat.get("il_original") if mat is not None and mat.get("il_envmap") is not None else mat


def _restores(mat):
    return mat is not None and mat.get("il_envmap") is not None and (
        mat.get("il_empty") or mat.get("il_original") is not None)


def restorable(objects):
    """Whether a slot of ``objects`` holds an environment-mapping material that knows what it replaced."""
    return any(_restores(s.material) for o in objects for s in getattr(o, "material_slots", ()))


def remove_environment_mapping(objects):
    """Give the slots of ``objects`` back the materials :func:`assign_environment_mapping` replaced; returns
    the number of slots restored."""
    count = 0
    for obj in objects:
        for i, slot in enumerate(obj.material_slots if obj.type == "MESH" else ()):
            mat = slot.material
            if not _restores(mat):
                continue
            orig = None if mat.get("il_empty") else mat["il_original"]
            if slot.link == "OBJECT":
                slot.material = orig
            else:
                obj.data.materials[i] = orig
            count += 1
        data = obj.data if obj.type == "MESH" else None
        if data is not None and data.get("il_added_slot") and len(data.materials) == 1 and data.materials[0] is None:
            data.materials.clear()
            del data["il_added_slot"]
    return count
