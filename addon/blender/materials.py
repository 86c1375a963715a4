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
