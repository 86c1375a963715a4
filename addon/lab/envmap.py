"""Irradiance environment maps in Blender: the world's environment (or a file) -> E(n) EXR, node group.

Core maths in ``addon.core.envmap``; this module reads the world, writes files
and builds the node group "IL Irradiance Env" (ambient term of seed 003:
c_diff · k_A · E(n)/π, REFERENCE.md §1).
"""
import os
import time

import bpy
import numpy as np

from ..blender import compat
from ..core import analytic
from ..core.envmap import irradiance as env_irradiance
from ..core.envmap import latlong
from ..core.envmap import sh9 as env_sh9
from ..core.io import png as io_png
from ..core.io import exr
from ..core.result import JobResult
from .options import EnvmapOptions
from ..core.errors import ILError, InputError
from ..core.io.files import write_json
from ..nodes import groups
from ..nodes.builder import Graph
from ..blender import materials, scene as sc

GROUP = "IL Irradiance Env"
IMAGE = "IL Irradiance"
EXR_NAME = "irradiance_latlong.exr"
REPORT = "envmap_report.json"


#: Colour spaces whose stored 8-bit values Cycles renders as they are (linear, Rec.709 primaries).
LINEAR_SPACES = {"Linear Rec.709", "Non-Color", "scene_linear"}


def image_pixels(image, decode=True):
    """A Blender image's linear RGB (H, W, 3), row 0 at the top (Blender stores the bottom row first).

    ``Image.pixels`` gives a float image's linear values but an 8-bit image's encoded ones: an sRGB
    8-bit image is decoded as Cycles does (``decode=False`` leaves it encoded: Cycles filters such a texture
    before it decodes); other non-linear 8-bit colour spaces are refused.
    """
    w, h = image.size
    if w == 0 or h == 0:
        raise InputError(f"image '{image.name}' has no pixels (missing file?)")
    space = image.colorspace_settings.name
    if not image.is_float and space != "sRGB" and space not in LINEAR_SPACES:
        raise InputError(f"image '{image.name}' is 8-bit in colour space '{space}': use sRGB, a linear space "
                         "or an HDR/EXR file")
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)
    rgb = px[..., :3] if image.channels >= 3 else np.repeat(px[..., :1], 3, axis=-1)
    if decode and is_srgb_bytes(image):
        rgb = io_png.srgb_decode(rgb)
    return np.flipud(rgb).astype(np.float32)


def is_srgb_bytes(image):
    """True for an 8-bit image whose values are sRGB-encoded (Cycles decodes them after filtering)."""
    return not image.is_float and image.colorspace_settings.name == "sRGB"


def world_environment(scene):
    """L(l) of the scene's world: (H, W, 3) lat-long = Environment Texture image × Background Strength.

    Supports the usual set-up Environment Texture -> Background.Color (a Mapping
    node or other nodes in between are refused rather than silently ignored).
    """
    world = scene.world
    if world is None or world.node_tree is None:
        raise InputError(f"scene '{scene.name}' has no world with nodes")
    env_nodes = [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment"]
    if not env_nodes:
        raise InputError(f"world '{world.name}' has no Environment Texture node")
    node = env_nodes[0]
    if node.image is None:
        raise InputError(f"the Environment Texture of world '{world.name}' has no image")
    if node.projection != "EQUIRECTANGULAR":
        raise InputError("only equirectangular environment textures are supported")
    if node.inputs["Vector"].is_linked:
        raise InputError("the Environment Texture has a Vector input (Mapping): remove it, or give the "
                         "environment as a file (Environment field, --env)")
    for link in node.outputs["Color"].links:
        if link.to_node.bl_idname == "ShaderNodeBackground":
            socket = link.to_node.inputs["Strength"]
            if socket.is_linked:
                raise InputError("the Background's Strength is driven by other nodes: set it to a number")
            strength = float(socket.default_value)
            break
    else:
        raise InputError("the Environment Texture must feed a Background node's Color directly")
    env = image_pixels(node.image) * strength
    latlong.check_latlong(env, node.image.name)
    return env, f"world '{world.name}' image '{node.image.name}' × {strength:g}"


def compute(env, method="sh9", width=64):
    """(irradiance map (width/2, width, 3), sh9 (9, 3), seconds)."""
    t = time.perf_counter()
    emap, coeffs = env_irradiance.irradiance_map(env, method, width)
    return emap, coeffs, time.perf_counter() - t


def write_outputs(out, emap, coeffs, method, seconds, source):
    """``<out>/irradiance_latlong.exr`` (R, G, B = E in W/m²) and ``<out>/envmap_report.json``; returns paths."""
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, EXR_NAME)
    exr.write_exr(path, {c: emap[..., k] for k, c in enumerate("RGB")},
                  {"il:quantity": "irradiance E(n) for the normal n of each lat-long direction",
                   "il:units": "W/m^2", "il:method": method, "il:layout": "Blender equirectangular, top row = +Z",
                   "il:source": source, "il:blender_version": bpy.app.version_string})
    report = {"method": method, "seconds": round(seconds, 6), "source": source,
              "width": int(emap.shape[1]), "height": int(emap.shape[0]),
              "sh9": [[float(v) for v in row] for row in coeffs]}
    write_json(os.path.join(out, REPORT), report)
    return path, report


def run(out, options=None, scene=None, env_file=None):
    """Environment from ``env_file`` or the scene's world -> E(n) by ``options`` (lab.options.EnvmapOptions:
    method, width; None: its defaults) -> files in ``out``; returns a core.result.JobResult (reads as
    envmap_report.json plus "file", the EXR; ``arrays`` holds "map" and "sh9").

    Refused before any work: an odd or too large ``width`` (memory, and for ``brute`` time), negative
    radiance, and an environment so bright that E(n) leaves the EXR's float range.
    """
    o = (EnvmapOptions() if options is None else options.replace()).validate()
    method, width = o.method, o.width
    env_irradiance.check_cost(width, "sh9")
    if env_file:
        env, source = latlong.read_latlong(env_file), os.path.abspath(env_file)
    else:
        env, source = world_environment(scene or bpy.context.scene)
    latlong.check_radiance(env, source)
    if method == "brute":
        env_irradiance.check_cost(width, method, env_irradiance.brute_directions(env.shape))
    bound = np.pi * float(np.max(env))                # E(n) <= π max L
    with np.errstate(over="ignore", invalid="ignore"):
        emap, coeffs, seconds = compute(env, method, width) if bound <= exr.FLOAT32_MAX else (None, None, 0.0)
    if emap is None or not (np.isfinite(emap).all() and np.isfinite(coeffs).all()
                            and np.max(emap) <= exr.FLOAT32_MAX):
        raise InputError(f"{source}: the environment is too bright (radiance up to {np.max(env):.3g}): E(n) leaves "
                         f"the EXR float range ({exr.FLOAT32_MAX:.3g} W/m²); scale the radiance down")
    path, report = write_outputs(out, emap, coeffs, method, seconds, source)
    return JobResult(dict(report, file=path), os.path.join(out, REPORT),
                     f"Wrote {path} ({seconds * 1e3:.1f} ms)", arrays={"map": emap, "sh9": coeffs})


# ----------------------------------------------------------------------------- node group


def load_irradiance_image(path):
    """The irradiance EXR as the Blender image "IL Irradiance" (reloaded if it exists), linear."""
    img = bpy.data.images.get(IMAGE)
    if img is not None and bpy.path.abspath(img.filepath) == os.path.abspath(path):
        img.reload()
    else:
        img = bpy.data.images.load(os.path.abspath(path), check_existing=False)
        img.name = IMAGE
    try:
        img.colorspace_settings.name = "Linear Rec.709"
    except TypeError:
        pass
    return img


#: Interface of "IL Irradiance Env": (name, socket type, default, (min, max) or None, description).
GROUP_INPUTS = [
    ("Diffuse Color", "NodeSocketColor", (0.8, 0.8, 0.8, 1.0), None, "Diffuse albedo c_diff"),
    ("AO", "NodeSocketFloat", 1.0, (0.0, 1.0), "Ambient occlusion k_A (1 = open): link a baked AO map"),
    ("Strength", "NodeSocketFloat", 1.0, None, "Scale of the environment's radiance")]
GROUP_OUTPUTS = [("Color", "NodeSocketColor"), ("Emission", "NodeSocketShader")]


def ensure_node_group(image):
    """Node group "IL Irradiance Env" (rebuilt each time, sockets and the materials' links kept): inputs
    "Diffuse Color" (c_diff), "AO" (k_A, 1 = open), "Strength"; outputs "Color" = c_diff · k_A · E(n)/π ·
    Strength (radiance, the ambient term of seed 003) and "Emission" (that as a shader).

    E(n) is looked up in the irradiance lat-long ``image`` by the world-space shading normal.
    """
    tree = groups.fresh_tree(GROUP, GROUP_INPUTS, GROUP_OUTPUTS, "Ambient term c_diff k_A E(n)/pi of seed 003")
    g = Graph(tree)
    i = g.node("NodeGroupInput").outputs
    o = g.node("NodeGroupOutput").inputs
    with g.block("E(n): irradiance map looked up by the normal"):
        geo = g.node("ShaderNodeNewGeometry")
        tex = g.node("ShaderNodeTexEnvironment", label="E(n) in W/m^2", image=image, interpolation="Linear")
        g.feed(geo.outputs["Normal"], tex.inputs["Vector"])
    with g.block("c_diff k_A E(n) / pi"):
        k = g.mul(g.mul(i["AO"], i["Strength"]), 1.0 / np.pi, label="k_A Strength / pi")
        color = g.scale(g.vmul(tex.outputs["Color"], i["Diffuse Color"]), k, label="radiance")
        em = g.node("ShaderNodeEmission")
        g.feed(color, em.inputs["Color"])
        em.inputs["Strength"].default_value = 1.0
    g.feed(color, o["Color"])
    g.feed(em.outputs[0], o["Emission"])
    g.layout()
    return tree


def irradiance_material(name, group, diffuse=(0.8, 0.8, 0.8), ao_image=None, uv_layer=""):
    """A material whose surface is the group's "Emission"; with ``ao_image`` the baked AO (its Y/R channel,
    read through UV layer ``uv_layer``) drives "AO" (k_A)."""
    mat = materials.empty_material(name)
    nt = mat.node_tree
    g = nt.nodes.new("ShaderNodeGroup")
    g.node_tree = group
    g.inputs["Diffuse Color"].default_value = (*diffuse, 1.0)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(g.outputs["Emission"], out.inputs["Surface"])
    if ao_image is not None:
        uv = nt.nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_layer
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = ao_image
        try:
            ao_image.colorspace_settings.name = "Non-Color"
        except TypeError:
            pass
        nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
        nt.links.new(tex.outputs["Color"], g.inputs["AO"])
    return mat


# ----------------------------------------------------------------------------- Cycles comparison


def set_world_environment(scene, image, strength=1.0):
    """A world with Environment Texture(image) -> Background(strength) (a new world; the old one is kept)."""
    w = bpy.data.worlds.new(f"{scene.name} IL Env")
    compat.ensure_use_nodes(w)
    nt = w.node_tree
    bg = nt.nodes.get("Background") or nt.nodes.new("ShaderNodeBackground")
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = image
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    scene.world = w
    return w


def cycles_sphere_irradiance(scene, sphere, samples=64, out=None):
    """Cycles irradiance bake (E = π × DIFFUSE bake) at the vertices of ``sphere`` through the light-map
    pipeline (addon.bake, vertex target); returns (E (V, 3), world normals (V, 3), seconds)."""
    import tempfile
    from ..bake import BakeOptions, bake_lightmaps
    t = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="il_env_bake_") as tmp:
        folder = out or tmp
        report = bake_lightmaps([sphere], ["irradiance"], folder,
                                BakeOptions(target="vertex", samples=samples, bounces=0, force=True),
                                scene=scene)
        ch, _ = exr.read_exr(report["objects"][sphere.name]["irradiance"]["file"])
        E = np.stack([ch["R"][0], ch["G"][0], ch["B"][0]], axis=-1)
    mw = np.array(sphere.matrix_world.to_3x3().inverted().transposed())
    nrm = np.empty(len(sphere.data.vertices) * 3, np.float32)
    sphere.data.vertices.foreach_get("normal", nrm)
    nrm = nrm.reshape(-1, 3) @ mw.T
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    if len(E) != len(nrm):
        raise ILError(f"vertex bake returned {len(E)} values for {len(nrm)} vertices")
    return E, nrm, time.perf_counter() - t
