"""Directional (L1 SH) light map against irradiance baked directly for tilted normals, under a sky and a sun.

Print the table: .venv/bin/python -m pytest tests/bake/test_directional.py -q -s
"""
import math

import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.bake import BakeOptions, bake_lightmaps
from addon.bake import cycles
from addon.blender import compat, materials
from addon.core import directional as d
from addon.core.io import exr

SIDE, SAMPLES = 16, 32
SKY = (0.6, 0.4)                        # L(l) = 0.6 + 0.4 l_z W/(m² sr)
SUN = 3.0                               # W/m² facing the sun
ELEVATION, AZIMUTH = 50.0, 30.0
ANGLES = (15, 30, 45, 60)
OFFSET = 0.1                            # radians: the texels' azimuths, none of the fit's 45° + k 90°


def _sun_direction():
    e, a = math.radians(ELEVATION), math.radians(AZIMUTH)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def _scene():
    """A 2 m plane (UVs the unit square) under the sky and the sun, made with Blender's operators."""
    scene = bpy.context.scene
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    compat.ensure_use_nodes(world)
    world.cycles.sampling_method, world.cycles.sample_map_resolution = "MANUAL", 32   # smooth sky: a small map
    nt = world.node_tree
    nt.nodes.clear()
    coords, split = nt.nodes.new("ShaderNodeTexCoord"), nt.nodes.new("ShaderNodeSeparateXYZ")
    ramp = nt.nodes.new("ShaderNodeMath")
    ramp.operation = "MULTIPLY_ADD"
    ramp.inputs[1].default_value, ramp.inputs[2].default_value = SKY[1], SKY[0]
    background, out = nt.nodes.new("ShaderNodeBackground"), nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(coords.outputs["Generated"], split.inputs[0])
    nt.links.new(split.outputs["Z"], ramp.inputs[0])
    nt.links.new(ramp.outputs[0], background.inputs["Color"])
    nt.links.new(background.outputs[0], out.inputs[0])
    bpy.ops.object.light_add(type="SUN")
    sun = bpy.context.active_object
    sun.data.energy, sun.data.angle = SUN, 0.0
    sun.rotation_mode = "QUATERNION"
    sun.rotation_quaternion = Vector((0, 0, 1)).rotation_difference(Vector(_sun_direction()))
    bpy.ops.mesh.primitive_plane_add(size=2)
    return scene, bpy.context.active_object


def _texel_normals(angle):
    """(SIDE, SIDE, 3) normal of each texel (row = v): tilt ``angle`` at azimuth OFFSET + 2π (i + j / SIDE) / SIDE."""
    j, i = np.mgrid[0:SIDE, 0:SIDE]
    phi = OFFSET + 2 * math.pi * (i + j / SIDE) / SIDE
    th = math.radians(angle)
    return np.stack([np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.full(phi.shape, np.cos(th))], axis=-1)


def _tilted_material(angle):
    """White Lambert whose normal is :func:`_texel_normals` of its texel, from the UV by nodes (the reference)."""
    mat = materials.empty_material(f"tilt {angle}")
    nt = mat.node_tree

    def math_node(op, a, b=None):
        node = nt.nodes.new("ShaderNodeMath")
        node.operation = op
        for k, x in enumerate((a, b)):
            if isinstance(x, (int, float)):
                node.inputs[k].default_value = x
            elif x is not None:
                nt.links.new(x, node.inputs[k])
        return node.outputs[0]

    uv, split = nt.nodes.new("ShaderNodeTexCoord"), nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(uv.outputs["UV"], split.inputs[0])
    i = math_node("FLOOR", math_node("MULTIPLY", split.outputs["X"], SIDE))
    j = math_node("FLOOR", math_node("MULTIPLY", split.outputs["Y"], SIDE))
    phi = math_node("ADD", math_node("MULTIPLY", math_node("ADD", i, math_node("DIVIDE", j, SIDE)),
                                     2 * math.pi / SIDE), OFFSET)
    th = math.radians(angle)
    normal = nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(math_node("MULTIPLY", math_node("COSINE", phi), math.sin(th)), normal.inputs["X"])
    nt.links.new(math_node("MULTIPLY", math_node("SINE", phi), math.sin(th)), normal.inputs["Y"])
    normal.inputs["Z"].default_value = math.cos(th)
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    nt.links.new(normal.outputs[0], bsdf.inputs["Normal"])
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    tex = nt.nodes.new("ShaderNodeTexImage")
    nt.nodes.active = tex
    return mat, tex


def _direct(scene, plane, angle, seed):
    """E (SIDE, SIDE, 3) baked by Cycles on the plane with the tilted reference material (DIFFUSE direct+indirect
    × π, as the irradiance map), and its mask."""
    mat, tex = _tilted_material(angle)
    image = bpy.data.images.new(f"direct {angle}", SIDE, SIDE, float_buffer=True, alpha=True)
    tex.image = image
    plane.data.materials.clear()
    plane.data.materials.append(mat)
    options = BakeOptions(resolution=SIDE, samples=SAMPLES, bounces=0)
    cycles.call_bake(scene, [plane], "irradiance", SAMPLES, seed, "UVMap", options)
    values, mask = cycles.read_image(image, "irradiance")
    plane.data.materials.clear()
    return values.astype(np.float64), mask


def _directional(plane, out, seed):
    options = BakeOptions(resolution=SIDE, samples=SAMPLES, uv_layer="UVMap", margin=0, bounces=0, seed=seed)
    report = bake_lightmaps([plane], ["directional"], str(out), options)
    entry = report["objects"][plane.name]["directional"]
    channels, header = exr.read_exr(entry["file"])
    coeffs = np.flipud(np.stack([channels[c] for c in d.CHANNELS], axis=-1)).astype(np.float64)
    return coeffs, header, entry


@pytest.mark.both_versions
def test_directional_map_follows_tilted_normals(tmp_path):
    """Per tilt angle, over the 256 texels (each its own azimuth, none of the fit's): the E(n) an engine
    reconstructs from the map against Cycles' E baked directly with that normal.

    recon - direct = model + noise: ``model`` is the L1 fit's own error, computed from Cycles' E(n) in closed form
    (:func:`core.directional.cycles_irradiance`: clipped hemisphere, Chiang's shadowing term) fitted at the map's
    five normals; the noise is measured: two maps and two direct bakes at independent seeds, σ² = mean(Δ²)/4 each
    for their means. The residual recon - direct - model must be noise: RMS ≤ σ (1 + 4/√(2M)) (χ² at 4 standard
    deviations, M samples) and |mean| ≤ 4σ/√M."""
    scene, plane = _scene()
    (a, header, entry), (b, _, _) = _directional(plane, tmp_path / "a", 11), _directional(plane, tmp_path / "b", 57)
    assert header["il:layout"].startswith("L00.RGB") and entry["estimated_error"] > 0
    z = np.array([0.0, 0.0, 1.0])
    fit_normals = [d.tilted(z, t) for t in d.tilt_vectors()]
    sun = (SUN, _sun_direction())
    model = d.coefficients(*d.fit([np.atleast_1d(d.cycles_irradiance(n, SKY, sun)) for n in fit_normals],
                                  fit_normals))
    e_normal = d.cycles_irradiance(z, SKY, sun)
    rows = []
    for angle in ANGLES:
        n = _texel_normals(angle)
        (d1, mask), (d2, _) = _direct(scene, plane, angle, 3), _direct(scene, plane, angle, 4)
        assert mask.all()
        ra, rb = d.irradiance(a, n), d.irradiance(b, n)
        exact = d.cycles_irradiance(n.reshape(-1, 3), SKY, sun).reshape(SIDE, SIDE, 1)
        model_error = d.irradiance(np.broadcast_to(model, (SIDE, SIDE, 4)), n, 1) - exact
        error = (ra + rb) / 2 - (d1 + d2) / 2
        residual = error - model_error
        sigma = math.sqrt(np.mean((ra - rb) ** 2) / 4 + np.mean((d1 - d2) ** 2) / 4)
        m = residual.size
        rms = float(np.sqrt(np.mean(error ** 2)))
        rows.append((angle, float(np.mean((d1 + d2) / 2)), rms, float(np.sqrt(np.mean(model_error ** 2))), sigma,
                     float(np.sqrt(np.mean(residual ** 2)))))
        assert np.sqrt(np.mean(residual ** 2)) <= sigma * (1 + 4 / math.sqrt(2 * m)), rows[-1]
        assert abs(np.mean(residual)) <= 4 * sigma / math.sqrt(m), rows[-1]
    print(f"\ndirectional map vs direct tilted bakes ({SIDE}x{SIDE}, {SAMPLES} samples; E at the normal "
          f"{e_normal:.4f} W/m^2)")
    print("tilt | mean E direct | RMS recon - direct | L1 model RMS | noise sigma | RMS residual (W/m^2)")
    for row in rows:
        print("{:>3}° | {:.4f} | {:.4f} ({:.2%}) | {:.4f} | {:.4f} | {:.4f}".format(
            row[0], row[1], row[2], row[2] / row[1], row[3], row[4], row[5]))
