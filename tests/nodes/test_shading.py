"""Shading operators, node groups, light linking by drivers, bad input (bpy)."""
import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.blender import compat
from addon.core import brdf, lights as twin_lights
from addon.blender import render
from addon.blender import scene as sc
from addon.nodes import groups, material
from addon.nodes.models import BY_ID, MODELS, Model
from addon.nodes.options import MODEL_CHOICES

CONTRACT = {
    "IL Phong": ["Light Vector", "Light Color", "Ka", "Ambient Light", "Kd", "Ks", "Shininess", "Emission Color",
                 "Normalized"],
    "IL Blinn-Phong": ["Light Vector", "Light Color", "Ka", "Ambient Light", "Kd", "Ks", "Shininess",
                       "Emission Color", "Normalized"],
    "IL Oren-Nayar": ["Light Vector", "Light Color", "Albedo", "Sigma"],
    "IL Cook-Torrance": ["Light Vector", "Light Color", "Kd", "Ks", "F0", "Roughness", "Distribution", "Geometry"],
}


def _sockets(tree, in_out):
    return [i.name for i in tree.interface.items_tree if i.item_type == "SOCKET" and i.in_out == in_out]


def test_every_model_file_is_registered_in_its_order():
    """Each public module of addon/nodes/models defines one Model, and MODELS holds them all by ``order``."""
    import pathlib
    import addon.nodes.models as pkg
    import importlib
    files = sorted(f.stem for f in pathlib.Path(pkg.__file__).parent.glob("*.py") if not f.stem.startswith("_"))
    records = [importlib.import_module(f"addon.nodes.models.{f}").MODEL for f in files]
    assert len(MODELS) == len(files) >= 4 and all(r in MODELS for r in records)
    assert {m.id: m for m in MODELS} == BY_ID and [m.order for m in MODELS] == sorted(m.order for m in MODELS)
    assert [m.id for m in MODELS][:4] == ["PHONG", "BLINN_PHONG", "OREN_NAYAR", "COOK_TORRANCE"]   # menu order


@pytest.mark.both_versions
@pytest.mark.parametrize("model", MODELS, ids=[m.id for m in MODELS])
def test_model_record_is_complete_and_its_groups_build(model):
    """Every record: id, label, descriptions, a public group named "IL <label>", inputs after the light's two
    (each with a socket type, default, range or None, description), callable halves and twin, switches among
    its inputs, sweep cases naming its inputs; the options, labels and group tables read it; its public group
    and both halves build with its interface, the ``once`` term is a surface output."""
    assert isinstance(model, Model)
    assert model.id.isupper() and model.label and model.description and model.group_description
    assert model.group == f"IL {model.label}"
    names = [i.name for i in model.inputs]
    assert names[:2] == ["Light Vector", "Light Color"] and len(set(names)) == len(names)
    for i in model.params:
        assert i.socket in (groups.F, groups.C, groups.V) and i.default is not None and i.description, i
        assert i.range is None or (len(i.range) == 2 and i.range[0] <= i.default <= i.range[1]), i
    assert callable(model.surface) and callable(model.light) and callable(model.twin)
    assert set(model.switches) <= set(names) and model.sweep
    for case in model.sweep:
        assert set(case) <= set(names), case
    assert (model.id, model.label, model.description) in MODEL_CHOICES
    assert material.MODEL_LABELS[model.id] == model.label and groups.MODEL_GROUPS[model.id] == model.group
    assert groups.INPUTS[model.group] == list(model.inputs) and groups.DESCRIPTIONS[model.group]
    assert CONTRACT[model.group] == names       # the public contract (DESIGN.md) names every model's inputs
    assert model.id in {c[0] for c in MATERIAL_CASES}
    tree = groups.ensure_group(model.group)
    assert _sockets(tree, "INPUT") == names and _sockets(tree, "OUTPUT") == ["Color", "Emission"]
    surface = groups.ensure_group(model.surface_group)
    assert _sockets(surface, "INPUT") == names[2:]
    assert model.once is None or model.once in _sockets(surface, "OUTPUT")
    half = _sockets(groups.ensure_group(model.light_group), "INPUT")
    assert set(model.switches) <= set(half) and set(_sockets(surface, "OUTPUT")) <= set(half)
    # a twin of the record: finite, zero light gives only the once-only terms
    n, v = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.6, 0.8])
    from addon.lab.bench import shading as sb
    lit = sb.twin(model.group, n, v, {"Light Vector": (0.3, 0.0, 1.0), "Light Color": (1.0, 1.0, 1.0)})
    dark = sb.twin(model.group, n, v, {"Light Vector": (0.3, 0.0, 1.0), "Light Color": (0.0, 0.0, 0.0)})
    assert np.all(np.isfinite(lit)) and np.all(lit > dark)


@pytest.mark.both_versions
def test_add_node_groups_is_idempotent_and_updates_older_groups():
    assert bpy.ops.illumination.add_node_groups() == {"FINISHED"}
    for name, inputs in CONTRACT.items():
        tree = bpy.data.node_groups[name]
        assert _sockets(tree, "INPUT") == inputs
        assert _sockets(tree, "OUTPUT") == ["Color", "Emission"]
        assert any(n.bl_idname == "NodeFrame" and n.label for n in tree.nodes)  # tidy: labelled frames
    assert _sockets(bpy.data.node_groups["IL Light"], "OUTPUT") == ["Light Vector", "Light Color"]
    count = len(bpy.data.node_groups)
    assert groups.add_node_groups()["current"] == list(groups.BUILDERS)
    assert len(bpy.data.node_groups) == count
    # a group left by an older version: wrong version, a missing socket, an extra socket, contents gone
    old = bpy.data.node_groups["IL Oren-Nayar"]
    mat = bpy.data.materials.new("user")
    compat.ensure_use_nodes(mat)
    node = mat.node_tree.nodes.new("ShaderNodeGroup")
    node.node_tree = old
    node.inputs["Albedo"].default_value = (0.1, 0.2, 0.3, 1.0)
    rgb = mat.node_tree.nodes.new("ShaderNodeRGB")
    mat.node_tree.links.new(rgb.outputs[0], node.inputs["Albedo"])
    old["il_version"] = 0
    old.interface.remove(next(i for i in old.interface.items_tree if getattr(i, "name", "") == "Sigma"))
    old.interface.new_socket("Legacy", in_out="INPUT", socket_type="NodeSocketFloat")
    old.nodes.clear()
    result = bpy.ops.illumination.add_node_groups()
    assert result == {"FINISHED"}
    assert bpy.data.node_groups["IL Oren-Nayar"] == old and len(bpy.data.node_groups) == count
    assert _sockets(old, "INPUT") == CONTRACT["IL Oren-Nayar"] and old["il_version"] == groups.GROUP_VERSION
    assert len(old.nodes) > 20
    assert node.inputs["Albedo"].is_linked  # the user's material kept its link


#: Switch inputs: a constant switch reaches Cycles as the factor of a Mix node, which keeps only the chosen
#: branch (constant folding); math that blends two branches would evaluate both for every light.
SWITCHES = {"IL Phong": ["Normalized"], "IL Blinn-Phong": ["Normalized"],
            "IL Cook-Torrance": ["Distribution", "Geometry"], "IL Light": ["Physical"]}
UNARY = {"SQRT", "INVERSE_SQRT", "EXPONENT", "ABSOLUTE", "COSINE", "SINE"}
TERNARY = {"MULTIPLY_ADD", "COMPARE"}


def _downstream(sockets):
    seen, todo = set(), [lk.to_node for s in sockets for lk in s.links]
    while todo:
        node = todo.pop()
        if node.name not in seen:
            seen.add(node.name)
            todo += [lk.to_node for s in node.outputs for lk in s.links]
    return seen


@pytest.mark.both_versions
def test_switches_are_mix_factors_and_per_light_math_has_no_constant_operands():
    groups.add_node_groups()
    for name, switches in SWITCHES.items():
        gin = next(n for n in bpy.data.node_groups[name].nodes if n.bl_idname == "NodeGroupInput")
        for switch in switches:
            assert gin.outputs[switch].links, (name, switch)
            for lk in gin.outputs[switch].links:
                target = (lk.to_node.bl_idname, lk.to_socket.identifier)
                assert target == ("ShaderNodeMix", "Factor_Float"), (name, switch, target)
    # every math node that depends on the light reads its operands from links (registers computed once per
    # shading point), never from constants that Cycles' SVM would load again for every light
    for name in CONTRACT:
        tree = bpy.data.node_groups[name]
        gin = next(n for n in tree.nodes if n.bl_idname == "NodeGroupInput")
        per_light = _downstream([gin.outputs["Light Vector"], gin.outputs["Light Color"]])
        checked = 0
        for node in (tree.nodes[k] for k in per_light):
            if node.bl_idname != "ShaderNodeMath":
                continue
            arity = 1 if node.operation in UNARY else 3 if node.operation in TERNARY else 2
            assert all(node.inputs[k].is_linked for k in range(arity)), (name, node.label or node.name, node.operation)
            checked += 1
        assert checked >= 4, name


def _camera_view(scene):
    return np.array(scene.camera.matrix_world.to_3x3() @ Vector((0, 0, 1)))


def _twin_sum(objs, p, n, v, model, **kw):
    total = 0.0
    for o in objs:
        d = np.array(o.matrix_world.to_3x3() @ Vector((0, 0, -1)))
        kind = "HEMI" if o.data.get("il_hemi") else o.data.type
        lv, I = twin_lights.light(kind, p, n, position=np.array(o.matrix_world.translation), direction=d,
                                  color=np.array(o.data.color), power=o.data.energy,
                                  cutoff=getattr(o.data, "spot_size", 1.0) / 2, **kw.pop("light", {}))
        total = total + model(n, lv, v, I, **kw)
    return total


def _scene_with_ball(size=32):
    scene = bpy.context.scene
    render.cycles_cpu(scene, samples=1)
    scene.cycles.filter_width = 0.01
    scene.cycles.max_bounces = 0
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    ball = sc.sphere(scene, "Ball", 1.0, segments=48, rings=24)
    sc.camera(scene, "Cam", (0, -10, 0), target=(0, 0, 0), ortho_scale=2.2)
    sc.world(scene, 0.0)
    vl = scene.view_layers[0]
    vl.use_pass_normal = vl.use_pass_position = True
    return scene, ball


def _pixels(scene):
    passes = render.render_layers(scene)
    hit = np.linalg.norm(passes["Normal"], axis=-1) > 0.5
    return (passes["Position"][hit].astype(float), passes["Normal"][hit].astype(float),
            passes["Combined"][..., :3][hit].astype(float))


@pytest.mark.both_versions
def test_drivers_follow_moved_and_recoloured_light():
    scene, ball = _scene_with_ball()
    key = sc.light(scene, "Key", "POINT", 150.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    spot = sc.light(scene, "Spot", "SPOT", 200.0, location=(-2.0, -2.0, 0.5))
    sc.look_at(spot, (0, 0, 0))
    spot.data.spot_size = 1.2
    sun = sc.light(scene, "Sun", "SUN", 2.0, rotation=sc.deg(30, 10, 20))
    ball.select_set(True)
    bpy.context.view_layer.objects.active = ball
    assert bpy.ops.illumination.assign_shading_model(model="PHONG") == {"FINISHED"}
    mat = ball.active_material
    params = material.read_parameters(mat)
    drivers = mat.node_tree.animation_data.drivers
    # what each type reads: point position, spot position and direction and cone, sun direction; all colour, power
    assert len(drivers) == 7 + 11 + 7 and all(fc.driver.is_simple_expression and fc.driver.is_valid for fc in drivers)
    v = _camera_view(scene)
    kw = dict(ka=params["Ka"], ambient_light=params["Ambient Light"][:3], kd=params["Kd"][:3], ks=params["Ks"],
              shininess=params["Shininess"])
    objs = [key, spot, sun]
    for step in range(2):
        p, n, L = _pixels(scene)
        ref = _twin_sum(objs, p, n, v, brdf.phong, **kw) - params["Ka"] * np.array(params["Ambient Light"][:3]) * 2
        assert np.max(np.abs(L - ref)) <= 1e-4 * np.max(ref), step
        key.location = (-1.0, -3.0, -0.5)  # move and re-colour, then render again
        key.data.color = (0.2, 0.3, 1.0)
        key.data.energy = 400.0
        spot.data.spot_size = 0.6
        sun.rotation_euler = sc.deg(70, -20, 40)
    assert np.max(L[:, 2] - L[:, 0]) > 0.05  # blue light now dominates somewhere


#: (model, material parameters, twin, twin keywords) of every model summed over a point, a spot and a sun.
MATERIAL_CASES = [
    ("PHONG", {"Ka": 0.3, "Ambient Light": (0.2, 0.3, 0.4), "Emission Color": (0.05, 0.0, 0.1), "Normalized": 1.0,
               "Shininess": 12.0}, brdf.phong,
     dict(ka=0.3, ambient_light=(0.2, 0.3, 0.4), emission=(0.05, 0.0, 0.1), normalized=1.0, shininess=12.0)),
    ("BLINN_PHONG", {"Ka": 0.3, "Ambient Light": (0.2, 0.3, 0.4), "Shininess": 40.0}, brdf.blinn_phong,
     dict(ka=0.3, ambient_light=(0.2, 0.3, 0.4), shininess=40.0)),
    ("OREN_NAYAR", {"Albedo": (0.9, 0.6, 0.3), "Sigma": 0.5}, brdf.oren_nayar, dict(albedo=(0.9, 0.6, 0.3), sigma=0.5)),
    ("COOK_TORRANCE", {"Roughness": 0.35, "F0": 0.3, "Kd": (0.3, 0.2, 0.1)}, brdf.cook_torrance,
     dict(roughness=0.35, F0=0.3, kd=(0.3, 0.2, 0.1))),
    ("COOK_TORRANCE", {"Roughness": 0.25, "F0": 0.6, "Distribution": 0.0, "Geometry": 0.0}, brdf.cook_torrance,
     dict(roughness=0.25, F0=0.6, distribution=0.0, geometry=0.0, kd=(0.2, 0.2, 0.2))),
    ("COOK_TORRANCE", {"Roughness": 0.5, "Distribution": 0.0, "Geometry": 1.0}, brdf.cook_torrance,
     dict(roughness=0.5, distribution=0.0, geometry=1.0, kd=(0.2, 0.2, 0.2))),
]


@pytest.mark.parametrize("model, params, twin, kw", MATERIAL_CASES,
                         ids=[f"{c[0]}-{k}" for k, c in enumerate(MATERIAL_CASES)])
def test_material_sums_model_over_lights_like_the_twin(model, params, twin, kw):
    """The material path (one surface half, per light the light type's group and the model's light half)
    renders what the twin gives summed over the lights, ambient and emission counted once."""
    scene, ball = _scene_with_ball(32)
    key = sc.light(scene, "Key", "POINT", 120.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    spot = sc.light(scene, "Spot", "SPOT", 250.0, location=(-2.0, -2.0, 0.5))
    sc.look_at(spot, (0, 0, 0))
    spot.data.spot_size = 1.4
    sun = sc.light(scene, "Sun", "SUN", 1.5, rotation=sc.deg(30, 10, 20), color=(0.6, 0.7, 1.0))
    mat, _ = material.assign_shading_model(scene, [ball], model, params=params)
    groups_used = {n.node_tree.name for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"}
    assert groups.LIGHT not in groups_used and groups.MODEL_GROUPS[model] not in groups_used
    p, n, L = _pixels(scene)
    v = _camera_view(scene)
    once = kw.get("ka", 0.0) * np.array(kw.get("ambient_light", (0, 0, 0))) + np.array(kw.get("emission", (0, 0, 0)))
    ref = _twin_sum([key, spot, sun], p, n, v, twin, **kw) - 2 * once
    assert np.count_nonzero(np.abs(ref - once).max(axis=-1) > 0.05 * ref.max()) > 50
    assert np.max(np.abs(L - ref)) <= 2e-4 * np.max(ref)


def _halves(mat, light):
    return (mat.node_tree.nodes[f"IL Cook-Torrance: {light}"].node_tree.name,
            mat.node_tree.nodes[f"IL Light: {light}"].node_tree.name)


def _switch_links(tree):
    gin = next(n for n in tree.nodes if n.bl_idname == "NodeGroupInput")
    return [k for k in ("Distribution", "Geometry", "Physical") if k in gin.outputs and gin.outputs[k].links]


@pytest.mark.both_versions
def test_constant_switches_link_groups_without_the_unused_branches_and_follow_edits():
    """Blender converts every node a material reaches at every render, also a switch's unused branch: a material
    links the internal groups built with its switches fixed (no switch read, fewer nodes), and follows edits of
    the hub nodes; a value between 0 and 1, a keyframed or a driven switch gets the group with both branches."""
    scene, ball = _scene_with_ball(8)
    sc.light(scene, "Key", "POINT", 100.0, location=(1.0, -2.0, 1.0))
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE")
    hubs = mat.node_tree.nodes
    update = scene.view_layers[0].update
    assert _halves(mat, "Key") == (".IL Cook-Torrance Light [GGX, Smith]", ".IL Light Point [1 over d^2]")
    for name in _halves(mat, "Key"):
        variant, base = bpy.data.node_groups[name], bpy.data.node_groups[name.split(" [")[0]]
        assert _switch_links(variant) == [] and _switch_links(base) != []
        assert len(variant.nodes) < len(base.nodes)
    hubs["Distribution"].outputs[0].default_value = 0.0
    update()
    assert _halves(mat, "Key") == (".IL Cook-Torrance Light [Beckmann, Smith]", ".IL Light Point [1 over d^2]")
    hubs["Geometry"].outputs[0].default_value = 0.0
    hubs["Physical"].outputs[0].default_value = 0.0
    update()
    assert _halves(mat, "Key") == (".IL Cook-Torrance Light [Beckmann, Cook-Torrance 1982]",
                                   ".IL Light Point [empirical]")
    hubs["Distribution"].outputs[0].default_value = 0.5
    update()
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light"
    hubs["Distribution"].outputs[0].default_value = 1.0
    hubs["Distribution"].outputs[0].keyframe_insert("default_value", frame=1)
    update()
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light"
    hubs["Distribution"].outputs[0].keyframe_delete("default_value", frame=1)   # tags nothing: the next render
    bpy.ops.render.render(scene=scene.name)                                      # relinks (render handler)
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light [GGX, Cook-Torrance 1982]"
    fc = hubs["Physical"].outputs[0].driver_add("default_value")
    fc.driver.expression = "1.0"
    update()
    assert _halves(mat, "Key")[1] == ".IL Light Point"
    mat["il_version"] = groups.GROUP_VERSION - 1   # a material of an older file: its links may predate the variants
    hubs["Distribution"].outputs[0].default_value = 0.0
    update()
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light"    # the general group, which reads the switch


@pytest.mark.both_versions
def test_switches_animated_through_nla_or_on_the_group_node_keep_both_branches():
    """A switch whose value changes over time gets the group with both branches, also when its keyframes are
    in an NLA strip (no active action), when the hub node was renamed with quotes, and when the driver or
    keyframes are on the light half's own input (the hub unlinked)."""
    scene, ball = _scene_with_ball(8)
    sc.light(scene, "Key", "POINT", 100.0, location=(1.0, -2.0, 1.0))
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE")
    tree = mat.node_tree
    hub = tree.nodes["Distribution"]
    hub.name = 'Distribution "D"'
    for frame, value in ((1, 0.0), (2, 1.0)):
        hub.outputs[0].default_value = value
        hub.outputs[0].keyframe_insert("default_value", frame=frame)
    material.specialize(mat)
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light"
    ad = tree.animation_data
    ad.nla_tracks.new().strips.new("switch", 1, ad.action)
    ad.action = None
    material.specialize(mat)
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light"
    half, light = tree.nodes["IL Cook-Torrance: Key"], tree.nodes["IL Light: Key"]
    tree.links.remove(next(lk for lk in tree.links if lk.to_socket == light.inputs["Physical"]))
    light.inputs["Physical"].default_value = 1.0
    material.specialize(mat)
    assert _halves(mat, "Key")[1] == ".IL Light Point [1 over d^2]"
    light.inputs["Physical"].driver_add("default_value").driver.expression = "frame > 1"
    tree.links.remove(next(lk for lk in tree.links if lk.to_socket == half.inputs["Geometry"]))
    material.specialize(mat)
    assert _halves(mat, "Key") == (".IL Cook-Torrance Light", ".IL Light Point")


def test_a_muted_switch_hub_gets_the_group_with_both_branches():
    """A muted hub node no longer feeds its switch (Blender reads the light half's own input then): the material
    renders what the group with both branches gives, not the variant of the muted value."""
    scene, ball = _scene_with_ball(16)
    sc.light(scene, "Key", "POINT", 100.0, location=(1.0, -2.0, 1.0))
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE", params={"Roughness": 0.3})
    hub, half = mat.node_tree.nodes["Distribution"], mat.node_tree.nodes["IL Cook-Torrance: Key"]
    _, _, ggx = _pixels(scene)
    hub.outputs[0].default_value = 0.0
    _, _, beckmann = _pixels(scene)
    assert np.max(np.abs(ggx - beckmann)) > 0.01
    half.inputs["Distribution"].default_value = 1.0
    hub.mute = True
    _, _, L = _pixels(scene)
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light"
    assert np.max(np.abs(L - ggx)) <= 1e-5 * np.max(ggx)


#: Surface terms added since group version 7: a file from version 7 has materials and groups without them.
NEW_IN_8 = ("F0 k r^2/pi", "(1 - F0) k r^2/pi")
#: Surface terms version 10 added (Cook-Torrance, Blinn-Phong), and the one it dropped (Cook-Torrance).
NEW_IN_10 = ("0.5", "-0.5", "1e-12")
DROPPED_IN_10 = ("(1, 1, 1)", "NodeSocketVector")


def _old_interface(tree, group, keep, extra=()):
    """``group``'s sockets recreated in their own order without the names ``keep`` rejects, plus ``extra``
    [(name, in_out, socket type)]; the material's links to and from its users restored by name."""
    users = [n for n in tree.nodes if getattr(n, "node_tree", None) == group]
    links = [(lk.from_node.name, lk.from_socket.name, lk.to_node.name, lk.to_socket.name) for lk in tree.links
             if lk.from_node in users or lk.to_node in users]
    items = [(i.name, i.in_out, i.socket_type) for i in group.interface.items_tree
             if i.item_type == "SOCKET" and keep(i.name)] + list(extra)
    group.interface.clear()
    for name, in_out, socket_type in items:
        group.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
    nodes = tree.nodes
    for from_node, from_name, to_node, to_name in links:
        if from_name in nodes[from_node].outputs and to_name in nodes[to_node].inputs:
            tree.links.new(nodes[from_node].outputs[from_name], nodes[to_node].inputs[to_name])


def _as_version_7(mat):
    """Make the file look like one saved by version 7: materials link the light halves with both branches,
    the internal groups are version 7 (no variants, no il_base), lack the terms versions 8 and 10 added, and
    number their sockets in their own order (recreated here, the material's links restored by name)."""
    tree = mat.node_tree
    mat["il_version"] = 7
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree.get("il_base"):
            node.node_tree = bpy.data.node_groups[node.node_tree["il_base"]]
    for group in list(bpy.data.node_groups):
        if " [" in group.name:
            bpy.data.node_groups.remove(group)
            continue
        if not group.name.startswith("."):
            continue
        del group["il_base"]
        group["il_version"] = 7
        _old_interface(tree, group, lambda name: name not in NEW_IN_8 + NEW_IN_10)


def _as_version_9(mat):
    """Make the file look like one saved by version 9: the material links variants, the internal groups
    (variants too) are version 9, lack the terms version 10 added, and Cook-Torrance's surface half has the
    "(1, 1, 1)" term that version 10 dropped, linked to every light half."""
    tree = mat.node_tree
    mat["il_version"] = 9
    model = mat["il_model"]
    for group in bpy.data.node_groups:
        if not group.name.startswith(".IL"):
            continue
        group["il_version"] = 9
        base = group.get("il_base", "")
        extra = ()
        if model == "COOK_TORRANCE" and base.endswith(" Surface"):
            extra = [(DROPPED_IN_10[0], "OUTPUT", DROPPED_IN_10[1])]
        elif model == "COOK_TORRANCE" and base.endswith(" Light"):
            extra = [(DROPPED_IN_10[0], "INPUT", DROPPED_IN_10[1])]
        _old_interface(tree, group, lambda name: name not in NEW_IN_10, extra)
    if model == "COOK_TORRANCE":
        surface = next(n for n in tree.nodes if n.name.endswith("surface (shared by every light)"))
        for node in tree.nodes:
            if getattr(node, "node_tree", None) is not None and node.node_tree.get("il_base", "").endswith(" Light"):
                tree.links.new(surface.outputs[DROPPED_IN_10[0]], node.inputs[DROPPED_IN_10[0]])


@pytest.mark.both_versions
@pytest.mark.parametrize("model, params, twin, kw", [MATERIAL_CASES[1], MATERIAL_CASES[3]], ids=["BLINN_PHONG", "COOK_TORRANCE"])
def test_materials_of_a_version_9_file_render_right_after_the_groups_are_rebuilt(model, params, twin, kw):
    """Opening a file from version 9 rebuilds the internal groups in place, which drops a surface term the old
    material links and adds terms it does not link: the material renders the model (the groups with both
    branches, the new terms linked from its surface half), and Relink Lights gives it the variants again."""
    scene, ball = _scene_with_ball(24)
    key = sc.light(scene, "Key", "POINT", 120.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    sun = sc.light(scene, "Sun", "SUN", 1.5, rotation=sc.deg(30, 10, 20))
    mat, _ = material.assign_shading_model(scene, [ball], model, params=params)
    variants = {n.name: n.node_tree.name for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"}
    _as_version_9(mat)
    once = kw.get("ka", 0.0) * np.array(kw.get("ambient_light", (0, 0, 0)))
    for step in ("old material", "relinked"):
        p, n, L = _pixels(scene)
        ref = _twin_sum([key, sun], p, n, _camera_view(scene), twin, **kw) - once
        linked = {n.name: n.node_tree.name for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"}
        assert (linked == variants) == (step == "relinked"), (step, linked)
        assert np.all(np.isfinite(L)) and np.max(np.abs(L - ref)) <= 2e-4 * np.max(ref), step
        material.relink_lights(scene, [mat])


@pytest.mark.both_versions
def test_materials_of_a_version_7_file_render_right_after_the_groups_are_rebuilt():
    """Opening a file from version 7 and assigning a new material rebuilds the internal groups in place: the
    old material keeps its general groups and its links to the surface terms; Relink Lights then swaps in
    variants whose sockets are numbered differently from the rebuilt groups', and links follow socket names."""
    scene, ball = _scene_with_ball(24)
    key = sc.light(scene, "Key", "POINT", 120.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    params = {"Roughness": 0.35, "F0": 0.3, "Kd": (0.3, 0.2, 0.1)}
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE", params=params)
    _as_version_7(mat)
    other = sc.sphere(scene, "Behind the camera", 0.5, segments=8, rings=4)
    other.location = (0.0, -30.0, 0.0)
    material.assign_shading_model(scene, [other], "COOK_TORRANCE", name="New")
    for step, linked in (("old material", (".IL Cook-Torrance Light", ".IL Light Point")),
                         ("relinked", (".IL Cook-Torrance Light [GGX, Smith]", ".IL Light Point [1 over d^2]"))):
        p, n, L = _pixels(scene)
        v = _camera_view(scene)
        ref = _twin_sum([key], p, n, v, brdf.cook_torrance, roughness=0.35, F0=0.3, kd=(0.3, 0.2, 0.1))
        assert _halves(mat, "Key") == linked, step
        assert np.max(np.abs(L - ref)) <= 2e-4 * np.max(ref), step
        material.relink_lights(scene, [mat])


def test_a_material_of_an_older_version_that_links_variants_follows_its_switches():
    """A file saved by a version that already linked variants (group version 8): its materials are older
    than the groups, yet a switch edited on the hub must change the picture (the variant it links ignores
    its switch inputs), as the twin says."""
    scene, ball = _scene_with_ball(24)
    key = sc.light(scene, "Key", "POINT", 120.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE", params={"Roughness": 0.3, "F0": 0.5})
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light [GGX, Smith]"
    mat["il_version"] = groups.GROUP_VERSION - 1
    mat.node_tree.nodes["Distribution"].outputs[0].default_value = 0.0
    p, n, L = _pixels(scene)
    v = _camera_view(scene)
    ref = _twin_sum([key], p, n, v, brdf.cook_torrance, roughness=0.3, F0=0.5, distribution=0.0,
                    kd=(0.2, 0.2, 0.2))
    assert np.max(np.abs(L - ref)) <= 2e-4 * np.max(ref)


def test_a_switch_set_from_python_then_rendered_renders_the_model_it_selects():
    """A script that sets a switch and renders at once (``blender -b``: no depsgraph update in between) gets the
    group that switch selects (render handler), and the picture the twin gives; Geometry 0.4 mixes both G terms
    as the public group does."""
    scene, ball = _scene_with_ball(32)
    key = sc.light(scene, "Key", "POINT", 120.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    sun = sc.light(scene, "Sun", "SUN", 1.5, rotation=sc.deg(30, 10, 20))
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE", params={"Roughness": 0.3, "F0": 0.5})
    hubs = mat.node_tree.nodes
    hubs["Distribution"].outputs[0].default_value = 0.0
    bpy.ops.render.render(scene=scene.name)
    assert _halves(mat, "Key")[0] == ".IL Cook-Torrance Light [Beckmann, Smith]"
    v = _camera_view(scene)
    for dist, geom in ((0.0, 0.0), (1.0, 0.4)):
        hubs["Distribution"].outputs[0].default_value = dist
        hubs["Geometry"].outputs[0].default_value = geom
        p, n, L = _pixels(scene)
        ref = _twin_sum([key, sun], p, n, v, brdf.cook_torrance, roughness=0.3, F0=0.5, distribution=dist,
                        geometry=geom, kd=(0.2, 0.2, 0.2))
        assert np.max(np.abs(L - ref)) <= 2e-4 * np.max(ref), (dist, geom)


def test_public_il_light_group_gives_what_the_per_type_groups_give():
    """Materials link each light through its type's own group; the public "IL Light" (every type behind its
    Type switch) put in their place renders the same, for a point, a spot, a sun and a hemisphere light."""
    scene, ball = _scene_with_ball(24)
    sc.light(scene, "Key", "POINT", 120.0, location=(1.5, -2.5, 1.0), color=(1.0, 0.8, 0.6))
    spot = sc.light(scene, "Spot", "SPOT", 250.0, location=(-2.0, -2.0, 0.5))
    sc.look_at(spot, (0, 0, 0))
    sc.light(scene, "Sun", "SUN", 1.5, rotation=sc.deg(30, 10, 20), color=(0.6, 0.7, 1.0))
    hemi = sc.light(scene, "Hemi", "SUN", 0.8, rotation=sc.deg(-20, 0, 0))
    hemi.data["il_hemi"] = True
    hemi.data["il_ground_color"] = (0.3, 0.2, 0.1)
    mat, _ = material.assign_shading_model(scene, [ball], "COOK_TORRANCE", attenuation="EMPIRICAL",
                                           coefficients=(0.5, 0.3, 0.2), params={"Spot Exponent": 2.0})
    light_nodes = [n for n in mat.node_tree.nodes if n.get("il_light")]
    assert sorted(n.node_tree["il_base"] for n in light_nodes) == sorted(groups.LIGHT_OF_TYPE.values())
    _, _, L = _pixels(scene)
    for node in light_nodes:
        node.node_tree = bpy.data.node_groups[groups.LIGHT]
    _, _, L_public = _pixels(scene)
    assert L.max() > 0.1
    np.testing.assert_allclose(L_public, L, rtol=0, atol=1e-5 * L.max())


@pytest.mark.both_versions
def test_bad_input_reports_and_changes_nothing():
    scene = bpy.context.scene
    cube = sc.box(scene, "Cube", 1.0)
    cam = sc.camera(scene, "Cam", (0, -5, 0))
    mats = len(bpy.data.materials)
    with pytest.raises(RuntimeError, match="select at least one mesh"):
        bpy.ops.illumination.assign_shading_model(model="OREN_NAYAR")
    cam.select_set(True)
    with pytest.raises(RuntimeError, match="Cam: not a mesh"):
        bpy.ops.illumination.assign_shading_model(model="OREN_NAYAR")
    assert len(bpy.data.materials) == mats and len(cube.data.materials) == 0
    cube.select_set(True)
    # the camera skipped with a warning (tests/ui/test_selection_habits.py); no lights: a valid material
    # with ambient and emission only, and a warning
    res = bpy.ops.illumination.assign_shading_model(model="PHONG")
    assert res == {"FINISHED"} and cube.active_material.get("il_model") == "PHONG"
    _, w = material.assign_shading_model(scene, [cube], "COOK_TORRANCE")
    assert any("no lights" in x for x in w)


def test_scene_without_lights_renders_ambient_and_emission_then_relinks_and_survives_deletion():
    scene, ball = _scene_with_ball(16)
    mat, warnings = material.assign_shading_model(scene, [ball], "PHONG", params={
        "Ka": 0.5, "Ambient Light": (0.2, 0.4, 0.6), "Emission Color": (0.1, 0.0, 0.0)})
    assert warnings
    _, _, L = _pixels(scene)
    np.testing.assert_allclose(L, np.broadcast_to([0.2, 0.2, 0.3], L.shape), atol=1e-6)
    key = sc.light(scene, "Key", "POINT", 100.0, location=(0, -3, 0))
    assert bpy.ops.illumination.relink_lights() == {"FINISHED"}
    assert mat["il_light_names"] == ["Key"] and material.read_parameters(mat)["Ka"] == pytest.approx(0.5)
    p, n, L = _pixels(scene)
    assert L.max() > 0.3 + 0.1
    bpy.data.objects.remove(key)  # deleting a linked light leaves a file that still renders
    p, n, L2 = _pixels(scene)
    assert np.all(np.isfinite(L2))
    material.relink_lights(scene)
    _, _, L3 = _pixels(scene)
    np.testing.assert_allclose(L3, np.broadcast_to([0.2, 0.2, 0.3], L3.shape), atol=1e-6)


def test_il_light_types_and_empirical_attenuation_match_twins():
    scene, ball = _scene_with_ball(32)
    spot = sc.light(scene, "Spot", "SPOT", 300.0, location=(0.5, -2.5, 1.5), color=(0.4, 1.0, 0.6))
    sc.look_at(spot, (0, 0, 0.2))
    spot.data.spot_size = 0.9
    hemi = sc.light(scene, "Hemi", "SUN", 1.5, rotation=sc.deg(20, 0, 0), color=(0.5, 0.7, 1.0))
    hemi.data["il_hemi"] = True
    hemi.data["il_ground_color"] = (0.3, 0.2, 0.1)
    c = (0.5, 0.3, 0.2)
    mat, _ = material.assign_shading_model(scene, [ball], "OREN_NAYAR", attenuation="EMPIRICAL", coefficients=c,
                                           params={"Albedo": (0.9, 0.8, 0.7), "Sigma": 0.4, "Spot Exponent": 3.0})
    p, n, L = _pixels(scene)
    v = _camera_view(scene)
    lv, I = twin_lights.spot_light(p, np.array(spot.matrix_world.translation),
                                   np.array(spot.matrix_world.to_3x3() @ Vector((0, 0, -1))), spot.data.color,
                                   300.0, 0.45, 3.0, physical=0.0, c1=c[0], c2=c[1], c3=c[2])
    ref = brdf.oren_nayar(n, lv, v, I, (0.9, 0.8, 0.7), 0.4)
    lv, I = twin_lights.hemi_light(n, np.array(hemi.matrix_world.to_3x3() @ Vector((0, 0, -1))),
                                   hemi.data.color, (0.3, 0.2, 0.1), 1.5)
    ref = ref + brdf.oren_nayar(n, lv, v, I, (0.9, 0.8, 0.7), 0.4)
    assert np.count_nonzero(ref[:, 1] > ref[:, 1].max() * 0.5) > 20  # the spot cone lights part of the ball
    assert np.max(np.abs(L - ref)) <= 1e-4 * np.max(ref)


def test_demo_step_shades_the_demo_scene():
    from addon.lab.demo import job, scene as demo
    scene = demo.build_demo_scene(new_scene=True, resolution=(32, 24))
    figures = job.shading_step(scene)
    assert figures["models"] == {"Box": "PHONG", "Torus": "OREN_NAYAR", "Sphere": "COOK_TORRANCE"}
    for name, model in figures["models"].items():
        mat = scene.objects[name].active_material
        assert mat["il_model"] == model and sorted(mat["il_light_names"]) == ["Key", "Sun"]
    assert scene.objects["Floor"].active_material is None


def test_brdf_compare_script_quick(script, tmp_path):
    r = script("brdf_compare.py", "--out", tmp_path, "--quick")
    assert r.returncode == 0, r.stderr
    import json
    report = json.loads((tmp_path / "brdf_report.json").read_text())
    f = report["figures"]
    assert f["node_vs_twin_max_relative_error"] < 1e-4
    assert f["oren_nayar_sigma0_relative_rms"] < 1e-4      # sigma 0 = Lambert = Diffuse BSDF roughness 0
    assert f["cook_torrance_vs_glossy_max_relative_rms"] < 1e-3  # F = 1, GGX, Smith = Glossy GGX
    assert f["render_time_ratio_il_ct_over_principled"] > 0
    for name in ("oren_nayar_vs_diffuse.png", "cook_torrance_vs_glossy.png", "brdf_phong.png",
                 "shading_node_vs_twin.csv"):
        assert (tmp_path / name).stat().st_size > 1000 or name.endswith(".csv")
    bad = script("brdf_compare.py", "--bogus")
    assert bad.returncode == 2 and "error" in bad.stderr
