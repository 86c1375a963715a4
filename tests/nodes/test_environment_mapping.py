"""Environment mapping as shading (issue 29): the LATLONG mirror against Cycles' Glossy (roughness 0), IOR 1
refraction against a transparent surface, Schlick's F against numpy, the operator's skip/refuse/restore."""
import bpy
import numpy as np
import pytest

from addon.blender import compat, render
from addon.blender import scene as S
from addon.core import camera as cam
from addon.core.envmap import latlong, reflection
from addon.core.errors import InputError
from addon.lab import envmap as L
from addon.nodes import environment as E

H, W = 32, 64


def _world(sc, strength=2.0):
    d = latlong.latlong_directions(H, W)
    env = np.stack([0.5 + 0.4 * d[..., 0], 0.5 + 0.4 * d[..., 1] * d[..., 2],
                    0.3 + 0.3 * (d[..., 2] > 0.3)], -1).astype(np.float32)
    img = bpy.data.images.new("env", W, H, float_buffer=True, alpha=True)
    img.pixels.foreach_set(np.flipud(np.concatenate([env, np.ones((H, W, 1), np.float32)], -1)).ravel())
    img.pack()
    world = L.set_world_environment(sc, img, strength=strength)
    world.cycles.sampling_method = "NONE"     # no importance map to build (seconds); delta paths never sample it
    return env * strength


def _scene(res=40):
    sc = S.new_scene("envmap", (res, res))
    env = _world(sc)
    ball = S.sphere(sc, "Ball", 1.0, segments=48, rings=24)
    S.camera(sc, "cam", (0, -5, 1.0), target=(0, 0, 0), lens=60)
    render.cycles_cpu(sc, 1, pixel_filter=0.01)       # one ray through each pixel centre
    return sc, ball, env


def _reference(ball, kind):
    mat = bpy.data.materials.new(kind)
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    bsdf = nt.nodes.new(kind)
    if kind == "ShaderNodeBsdfGlossy":
        bsdf.inputs["Roughness"].default_value = 0.0
        bsdf.inputs["Color"].default_value = (1, 1, 1, 1)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    ball.data.materials.clear()
    ball.data.materials.append(mat)


def _tolerance(env):
    """Both look the same image up with the same bilinear filter along the same direction: the difference
    is the direction's float32 rounding (~1e-6 rad, far below 1e-3 of a texel of π/H) times the steepest
    texel-to-texel change of the map."""
    steep = max(np.abs(np.diff(env, axis=0)).max(), np.abs(np.diff(env, axis=1)).max())
    return 1e-3 * steep


@pytest.mark.both_versions
def test_latlong_mirror_equals_cycles_glossy_and_fresnel_is_schlick():
    sc, ball, env = _scene()
    vl = sc.view_layers[0]
    vl.use_pass_normal = True
    _reference(ball, "ShaderNodeBsdfGlossy")
    p = render.render_layers(sc)
    glossy, normal = p["Combined"][..., :3], p["Normal"][..., :3].astype(np.float64)
    mats, warnings = E.assign_environment_mapping(sc, [ball], E.EnvironmentOptions(fresnel=False))
    assert warnings == [] and mats[0]["il_original"].name == "ShaderNodeBsdfGlossy"
    mirror = render.render_layers(sc)["Combined"][..., :3]
    on = ball.data.materials[0] is mats[0] and np.linalg.norm(normal, axis=-1) > 0.5
    assert on.sum() > 300
    assert np.abs(mirror - glossy).max() <= _tolerance(env)           # measured 7e-7 of 1.8
    E.assign_environment_mapping(sc, [ball], E.EnvironmentOptions(fresnel=True, ior=1.5))
    fres = render.render_layers(sc)["Combined"][..., :3]
    w2v, proj, w, h = render.camera_matrices(sc)
    _, dirs = cam.pixel_rays(w2v, proj, w, h)
    n = normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    _, f = reflection.lookup(-dirs, n, "REFLECT", 1.5, True)
    expect = glossy * f[..., None]
    # the Normal pass is stored at 16 bits (compat): |dF| <= 5 (1 - cos)^4 |d cos| ~ 1e-4 away from the rim
    inner = on & (np.einsum("...i,...i", n, -dirs) > 0.3)
    assert np.abs(fres - expect)[inner].max() < 1e-3 * glossy.max()
    centre = fres[20, 20] / glossy[20, 20]
    assert centre == pytest.approx(0.04, abs=2e-3)                     # F0 of IOR 1.5 at normal incidence


@pytest.mark.both_versions
def test_ior_one_refraction_shows_the_world_behind_unchanged():
    sc, ball, env = _scene()
    _reference(ball, "ShaderNodeBsdfTransparent")
    behind = render.render_layers(sc)["Combined"][..., :3]
    E.assign_environment_mapping(sc, [ball], E.EnvironmentOptions(mode="REFRACT", ior=1.0, fresnel=True))
    refracted = render.render_layers(sc)["Combined"][..., :3]
    assert np.abs(refracted - behind).max() <= _tolerance(env)


@pytest.mark.both_versions
def test_operator_skips_refuses_and_restores():
    sc = S.new_scene("ops", (8, 8))
    ball = S.sphere(sc, "Ball", 1.0, segments=8, rings=4)
    own = bpy.data.materials.new("Mine")
    ball.data.materials.append(own)
    camera = S.camera(sc, "cam", (0, -5, 0))
    with pytest.raises(InputError, match="no world"):
        E.assign_environment_mapping(sc, [ball])
    sc.world = bpy.data.worlds.new("plain")
    compat.ensure_use_nodes(sc.world)
    with pytest.raises(InputError, match="no Environment Texture"):
        E.assign_environment_mapping(sc, [ball])
    with pytest.raises(InputError, match="nothing to shade"):
        E.assign_environment_mapping(sc, [camera])
    _world(sc)
    lamp = bpy.data.objects.new("lamp", bpy.data.lights.new("lamp", "POINT"))
    sc.collection.objects.link(lamp)
    for projection, shape in (("CUBE", (18, 108)), ("SPHERE", (45, 45))):
        mats, warnings = E.assign_environment_mapping(sc, [ball, camera, lamp],
                                                      E.EnvironmentOptions(projection=projection))
        assert warnings == ["skipped cam, lamp: not meshes"]          # one reason, named once
        img = next(n.image for n in mats[0].node_tree.nodes if n.bl_idname == "ShaderNodeTexImage")
        assert (img.size[1], img.size[0]) == shape                     # equal texel count: 2 H² = 2048
        assert mats[0]["il_original"] == own                           # the user's, not the first IL material
    assert bpy.data.node_groups[E.GROUP]["il_version"] == E.GROUP_VERSION
    assert E.restorable([ball]) and E.remove_environment_mapping([ball]) == 1
    assert ball.data.materials[0] == own and not E.restorable([ball])


@pytest.mark.both_versions
def test_operator_button_assigns_and_removes():
    sc = S.new_scene("button", (8, 8))
    bpy.context.window.scene = sc
    _world(sc)
    ball = S.sphere(sc, "Ball", 1.0, segments=8, rings=4)
    camera = S.camera(sc, "cam", (0, -5, 0))
    for o in (ball, camera):
        o.select_set(True)
    op = bpy.ops.illumination.assign_environment_mapping
    assert op(mode="REFRACT", projection="SPHERE", ior=1.33) == {"FINISHED"}
    mat = ball.data.materials[0]
    assert mat["il_envmap"]["projection"] == "SPHERE" and mat.get("il_empty")
    assert bpy.ops.illumination.remove_environment_mapping() == {"FINISHED"}
    assert len(ball.data.materials) == 0                     # the slot it added is gone again
    assert bpy.ops.illumination.add_environment_group() == {"FINISHED"} and E.GROUP in bpy.data.node_groups
