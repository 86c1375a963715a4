"""Materials the labs and the bake build from bpy.data (no operators, no context needed)."""
import bpy

from . import compat


def empty_material(name):
    """A new material with an empty node tree (in 5.0 and 4.5 alike)."""
    mat = bpy.data.materials.new(name)
    compat.ensure_use_nodes(mat)
    mat.node_tree.nodes.clear()
    return mat


def white_diffuse_node(node_tree):
    """A Diffuse BSDF of albedo 1 and roughness 0 (white Lambert) in ``node_tree``."""
    bsdf = node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    return bsdf


def white_lambert(name, material=None):
    """A white Lambertian material (``material``, empty, or a new one): white Diffuse BSDF -> Surface."""
    mat = material or empty_material(name)
    nt = mat.node_tree
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(white_diffuse_node(nt).outputs["BSDF"], out.inputs["Surface"])
    mat.diffuse_color = (1.0, 1.0, 1.0, 1.0)
    return mat


def no_closure(name, material=None):
    """A material with no closure at all (an Emission of strength 0 -> Surface): Cycles samples no BSDF and no
    light at its points, so a render that reads only the geometry there (the AO pass, depth, alpha) costs
    the camera and AO rays alone."""
    mat = material or empty_material(name)
    nt = mat.node_tree
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 0.0
    nt.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    return mat


def user_material(mat):
    """The user's own material under the add-on's layers on a slot (None: an empty slot): a light-map preview
    (``il_lightmap_link``: the slot's material before it, ``il_lightmap_original``), a shading model (``il_model``) or
    environment mapping (``il_envmap``) material (``il_original``, or nothing when ``il_empty``), unwound however they
    are stacked; ``mat`` when it is none of them. A bake lights the scene through these, not through the layers shown
    on top of them."""
    return layers(mat)[1]


#: The add-on's material layers by the name their Remove operator says.
LAYER_NAMES = {"preview": "light-map preview", "shading": "shading model", "environment": "environment mapping"}


def is_preview(mat):
    """Whether ``mat`` is a light-map preview material (``il_lightmap``, keeping the link it replaced in
    ``il_lightmap_link``)."""
    return mat is not None and bool(mat.get("il_lightmap")) and "il_lightmap_link" in mat


def under_preview(mat):
    """What a slot showing ``mat`` shows once a light-map preview on it is taken off."""
    return mat.get("il_lightmap_original") if is_preview(mat) else mat


def layers(mat):
    """([(kind of :data:`LAYER_NAMES`, material)] of the add-on's layers on a slot holding ``mat``, top first;
    :func:`user_material`)."""
    out = []
    for _ in range(8):
        if mat is None:
            break
        if is_preview(mat):
            out.append(("preview", mat))
            mat = under_preview(mat)
        elif mat.get("il_model") or mat.get("il_envmap") is not None:
            if mat.get("il_empty"):
                out.append(("shading" if mat.get("il_model") else "environment", mat))
                return out, None
            if mat.get("il_original") is None:
                break
            out.append(("shading" if mat.get("il_model") else "environment", mat))
            mat = mat["il_original"]
        else:
            break
    return out, mat


def buried(objects, kind):
    """The name (:data:`LAYER_NAMES`) of a layer shown over a ``kind`` layer on a slot of ``objects`` (its Remove
    must come first: each Remove takes off the layer on top), or None."""
    for obj in objects:
        for slot in getattr(obj, "material_slots", ()):
            found = layers(slot.material)[0]
            if any(k == kind for k, _ in found[1:]):
                return LAYER_NAMES[found[0][0]]
    return None


def user_link(slot):
    """How the user's own material is linked on ``slot`` ("OBJECT" or "DATA"): a light-map preview shows itself on
    the object and keeps the link it replaced (``il_lightmap_link``); the other layers keep the slot's link."""
    return slot.material["il_lightmap_link"] if is_preview(slot.material) else slot.link


def shows_layers(obj):
    """Whether a slot of ``obj`` shows an add-on material over the user's own (:func:`user_material`)."""
    return any(slot.material is not None and user_material(slot.material) != slot.material
               for slot in getattr(obj, "material_slots", ()))
