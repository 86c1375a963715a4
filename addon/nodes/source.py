"""What a user's material has, read as the parameters of a shading model (Assign Shading Model).

:func:`read_surface` reads a material into a :class:`Surface` (base colour, metallic, roughness, dielectric
F0, emission, and the sockets that feed base colour or emission from other nodes); :func:`model_parameters`
turns it into one model's inputs (docs/shading.md, "Your materials"). Nothing here changes the material.
"""
import dataclasses

from ..blender import compat
from .models import BY_ID

GREY = (0.8, 0.8, 0.8)


@dataclasses.dataclass
class Surface:
    """A material's reflectance and emission. ``base_source``/``emission_source``: the output socket that
    feeds Base Color / Emission Color (an image texture, ...), else None; ``notes``: what could not be read."""
    base: tuple = GREY
    metallic: float = 0.0
    roughness: float = 0.5
    f0: float = 0.04
    diffuse_roughness: float = 0.0
    specular: bool = True
    emission: tuple = (0.0, 0.0, 0.0)
    emission_strength: float = 0.0
    base_source: object = None
    emission_source: object = None
    notes: list = dataclasses.field(default_factory=list)


def _rgb(value):
    return tuple(float(x) for x in tuple(value)[:3])


def _value(node, name, default, notes):
    """An input's value; a linked input gives its unlinked value and a note."""
    socket = node.inputs.get(name)
    if socket is None:
        return default
    if socket.is_linked:
        notes.append(f"{name} (linked to '{socket.links[0].from_node.name}', used its value)")
    value = socket.default_value
    return _rgb(value) if hasattr(value, "__len__") else float(value)


def _color(node, name, default, notes):
    """(rgb, source socket or None) of a colour input; the source is what links it."""
    socket = node.inputs.get(name)
    if socket is None:
        return default, None
    if socket.is_linked:
        link = socket.links[0]
        if link.is_muted or link.from_node.mute:
            notes.append(f"{name} (muted link, used its value)")
        else:
            return _rgb(socket.default_value), link.from_socket
    return _rgb(socket.default_value), None


def _surface_node(tree):
    """The node linked to the active Material Output's Surface, or None."""
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    out = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    if out is None or not out.inputs["Surface"].is_linked:
        return None
    return out.inputs["Surface"].links[0].from_node


def _principled(node, s):
    notes = []
    s.base, s.base_source = _color(node, "Base Color", GREY, notes)
    s.metallic = min(max(_value(node, "Metallic", 0.0, notes), 0.0), 1.0)
    s.roughness = min(max(_value(node, "Roughness", 0.5, notes), 0.0), 1.0)
    ior = _value(node, "IOR", 1.5, notes)
    level = _value(node, "Specular IOR Level", 0.5, notes)
    s.f0 = min(max(((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * level, 0.0), 1.0)
    s.diffuse_roughness = _value(node, "Diffuse Roughness", 0.0, notes)
    colour, s.emission_source = _color(node, "Emission Color", (0.0, 0.0, 0.0), notes)
    s.emission_strength = _value(node, "Emission Strength", 0.0, notes)
    s.emission = colour
    for name in ("Normal", "Alpha", "Transmission Weight", "Coat Weight", "Sheen Weight",
                 "Subsurface Weight"):
        socket = node.inputs.get(name)
        if socket is not None and (socket.is_linked if name == "Normal" else
                                   socket.default_value != (1.0 if name == "Alpha" else 0.0)):
            notes.append(name)
    return notes


def read_surface(mat):
    """The :class:`Surface` of ``mat`` (None: Blender's default grey). Reads a Principled BSDF, a Diffuse or
    Emission shader, or a colour node (an image texture) linked straight to the output; anything else gives
    the first Principled BSDF or Diffuse BSDF of the tree, else the viewport display colour, with a note."""
    s = Surface()
    if mat is None:
        return s
    s.base = _rgb(mat.diffuse_color)
    s.roughness, s.metallic = float(mat.roughness), float(mat.metallic)
    tree = mat.node_tree if compat.uses_nodes(mat) else None
    if tree is None or not tree.nodes:
        s.notes.append("no shader nodes: its viewport display colour, metallic and roughness")
        return s
    node = _surface_node(tree)
    kind = node.bl_idname if node is not None else None
    if kind not in ("ShaderNodeBsdfPrincipled", "ShaderNodeBsdfDiffuse", "ShaderNodeEmission") and kind is not None \
            and not any(o.type == "RGBA" for o in node.outputs if o.is_linked):
        found = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None) or \
            next((n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse"), None)
        s.notes.append(f"its surface is a {node.bl_label or kind} node"
                       + (f": read '{found.name}' instead" if found else ": its viewport display colour"))
        node, kind = found, (found.bl_idname if found else None)
    if node is None:
        if not s.notes:
            s.notes.append("nothing linked to the Material Output: its viewport display colour")
        return s
    if kind == "ShaderNodeBsdfPrincipled":
        s.notes += _principled(node, s)
    elif kind == "ShaderNodeBsdfDiffuse":
        notes = []
        s.base, s.base_source = _color(node, "Color", GREY, notes)
        s.diffuse_roughness = _value(node, "Roughness", 0.0, notes)
        s.specular = False
        s.notes += notes + ["Diffuse BSDF: no specular part (k_s 0)"]
    elif kind == "ShaderNodeEmission":
        notes = []
        s.emission, s.emission_source = _color(node, "Color", (1.0, 1.0, 1.0), notes)
        s.emission_strength = _value(node, "Strength", 1.0, notes)
        s.base, s.specular = (0.0, 0.0, 0.0), False
        s.notes += notes + ["Emission only: no reflection (k_d = k_s = 0), the emission kept"]
    else:
        socket = next(o for o in node.outputs if o.type == "RGBA" and o.is_linked)
        s.base_source = socket
        s.notes.append(f"no shader ({node.bl_label or kind} straight to the output): its colour as diffuse, "
                       "no specular")
        s.specular = False
    return s


def _mean(rgb):
    return sum(rgb) / 3.0


def model_parameters(model, s):
    """({input: value}, {input: source socket}) of ``model`` for the :class:`Surface` ``s``. A sourced input's
    value is the tint the source is multiplied by. Roughness r gives alpha = r^2 (GGX, as Blender's Glossy),
    Blinn-Phong's exponent 2/alpha^2 - 2 and Phong's a quarter of it, energy-normalised lobes; F0 mixes the
    dielectric F0 and the base colour's mean by Metallic; the emission is colour times strength."""
    m = s.metallic
    diffuse = tuple(c * (1.0 - m) for c in s.base)
    tint = (1.0 - m,) * 3
    f0 = (1.0 - m) * s.f0 + m * _mean(s.base) if s.specular else 0.0
    alpha = max(s.roughness ** 2, 1e-3)
    emission = tuple(c * s.emission_strength for c in s.emission)
    params, sources = {}, {}
    diffuse_name = "Albedo" if model == "OREN_NAYAR" else "Kd"
    params[diffuse_name] = tint if s.base_source is not None else diffuse
    if s.base_source is not None:
        sources[diffuse_name] = s.base_source
    if model in ("PHONG", "BLINN_PHONG"):
        blinn = min(max(2.0 / alpha ** 2 - 2.0, 0.0), 1e5)
        params.update({"Ks": f0, "Shininess": blinn if model == "BLINN_PHONG" else blinn / 4.0,
                       "Normalized": 1.0})
    elif model == "OREN_NAYAR":
        params["Sigma"] = min(max(2.0 * s.diffuse_roughness, 0.0), 10.0)
    else:
        params.update({"Ks": 1.0 if s.specular else 0.0, "F0": f0, "Roughness": alpha})
    if s.emission_source is not None:
        params["Emission Color"] = (s.emission_strength,) * 3
        sources["Emission Color"] = s.emission_source
    elif any(emission):
        params["Emission Color"] = emission
    return params, sources


def lost(model, s):
    """What ``model`` cannot show of ``s`` (names), beside :attr:`Surface.notes`."""
    names = [n for n, *_ in BY_ID[model].inputs]
    out = []
    if model == "OREN_NAYAR" and s.specular and s.metallic > 0.0:
        out.append("Metallic (Oren-Nayar has no specular lobe)")
    if "Shininess" in names and s.metallic > 0.0:
        out.append("the metal's coloured highlight (k_s is grey)")
    return out
