"""The node groups of the shading models ("IL Phong", "IL Blinn-Phong", "IL Oren-Nayar", "IL Cook-Torrance":
one per record of :mod:`.models`, which holds each model's inputs and node builders) and "IL Light".

Each group evaluates, term by term and with the same clamps, the numpy twin in
``addon/core/brdf.py`` / ``addon/core/lights.py`` (REFERENCE.md §1-2). Normal and
view vectors come from the Geometry node; the light from the "Light Vector" and
"Light Color" inputs (I = E_perp/pi). Outputs: "Color" (radiance) and "Emission"
(an Emission shader of that radiance, strength 1).

:func:`add_node_groups` is idempotent: a group carrying the current
``GROUP_VERSION`` in its "il_version" property is left alone; an older one is
rebuilt in place (same datablock, sockets kept by name), so materials using it
update without relinking.

Materials use internal groups built from the same code (names start with a dot, see
:data:`INTERNAL`): each model's surface half and light half, and "IL Light" for one light type;
and their variants with the switch inputs fixed at 0 or 1 (:func:`variant`), which hold only the
chosen branches.
"""
import math

import bpy

from ..core import brdf
from .builder import Graph, is_socket
from .models import MODELS
from .models._common import BLACK, C, F, LIGHT_IN as _LIGHT_IN, V, WHITE

#: Bump whenever a group's contents or sockets change: older groups in a file are rebuilt.
GROUP_VERSION = 10

LIGHT = "IL Light"
#: {model id: public group name}, in the registry's order (nodes/models).
MODEL_GROUPS = {m.id: m.group for m in MODELS}

#: (name, socket type, default, (min, max) or None, description) per input, per group.
INPUTS = {m.group: list(m.inputs) for m in MODELS}
INPUTS[LIGHT] = [
    ("Type", F, 0.0, (0.0, 3.0), "0 point, 1 spot, 2 sun, 3 hemisphere"),
    ("Position", V, (0.0, 0.0, 0.0), None, "World position of a point or spot light"),
    ("Direction", V, (0.0, 0.0, -1.0), None, "Where a spot, sun or hemisphere light points"),
    ("Color", C, WHITE, None, "Light colour (sky colour for a hemisphere light)"),
    ("Power", F, 1000.0, (0.0, 1e9), "Watts (point, spot) or W/m^2 (sun, hemisphere)"),
    ("Physical", F, 1.0, (0.0, 1.0), "1: 1/d^2, 0: min(1/(c1 + c2 d + c3 d^2), 1)"),
    ("C1", F, 1.0, (0.0, 1e6), "Constant attenuation c1"),
    ("C2", F, 0.0, (0.0, 1e6), "Linear attenuation c2"),
    ("C3", F, 1.0, (0.0, 1e6), "Quadratic attenuation c3"),
    ("Spot Cutoff", F, math.pi / 4, (0.0, math.pi), "Half angle of the spot cone, radians"),
    ("Spot Exponent", F, 0.0, (0.0, 1e4), "Falloff exponent k of (s.s')^k"),
    ("Ground Color", C, BLACK, None, "Ground colour of a hemisphere light")]
OUTPUTS = {m.group: [("Color", C), ("Emission", "NodeSocketShader")] for m in MODELS}
OUTPUTS[LIGHT] = [("Light Vector", V), ("Light Color", C)]
DESCRIPTIONS = {m.group: m.group_description for m in MODELS}
DESCRIPTIONS[LIGHT] = "One light as Light Vector and Light Color (I = E_perp / pi)"


# -- interface --------------------------------------------------------------------------------------

def sync_interface(tree, inputs, outputs):
    """Make the interface exactly ``inputs`` + ``outputs``, keeping sockets whose name and type match."""
    wanted = [(n, "OUTPUT", t) for n, t in outputs] + [(n, "INPUT", t) for n, t, *_ in inputs]
    items = [i for i in tree.interface.items_tree if i.item_type == "SOCKET"]
    keep = {}
    for item in items:
        key = (item.name, item.in_out, item.socket_type)
        if key in wanted and key not in keep:
            keep[key] = item
        else:
            tree.interface.remove(item)
    for pos, key in enumerate(wanted):
        item = keep.get(key) or tree.interface.new_socket(key[0], in_out=key[1], socket_type=key[2])
        tree.interface.move(item, pos)
    specs = {n: (d, r, desc) for n, _, d, r, desc in inputs}
    for item in tree.interface.items_tree:
        if item.item_type == "SOCKET" and item.in_out == "INPUT" and item.name in specs:
            default, rng, desc = specs[item.name]
            item.description = desc
            if rng is not None:
                item.min_value, item.max_value = rng
            if default is not None:
                item.default_value = default
            if item.name == "Light Vector":
                item.hide_value = True


def fresh_tree(name, inputs, outputs, description):
    """The shader node group ``name``, emptied, with exactly this interface (links to kept sockets survive).

    A node group of another kind that holds the name is renamed out of the way.
    """
    tree = bpy.data.node_groups.get(name)
    if tree is not None and tree.bl_idname != "ShaderNodeTree":
        tree.name = name + " (not shader)"
        tree = None
    if tree is None:
        tree = bpy.data.node_groups.new(name, "ShaderNodeTree")
    tree.nodes.clear()
    sync_interface(tree, inputs, outputs)
    tree.description = description
    return tree


def _fresh(name):
    tree = fresh_tree(name, INPUTS[name], OUTPUTS[name], DESCRIPTIONS[name])
    tree["il_version"] = GROUP_VERSION
    return tree


def _io(g):
    gin = g.node("NodeGroupInput")
    gout = g.node("NodeGroupOutput")
    return gin.outputs, gout.inputs


def _finish(g, o, color):
    with g.block("Output: radiance and emission"):
        em = g.node("ShaderNodeEmission")
        g.feed(color, em.inputs["Color"])
        em.inputs["Strength"].default_value = 1.0
    g.feed(color, o["Color"])
    g.feed(em.outputs[0], o["Emission"])


#: model group: (surface half, light half, the switch inputs the light half reads, surface term added once);
#: each model's own file in nodes/models holds them (see its docstring for the two halves' contract).
HALVES = {m.group: (m.surface, m.light, list(m.switches), m.once) for m in MODELS}


def _build_model(tree, name):
    """The public group: both halves in one tree, radiance = I times the light half's factor (+ the once-only
    term)."""
    g = Graph(tree)
    i, o = _io(g)
    surface, light, _, once = HALVES[name]
    s = surface(g, i)
    factor = light(g, i, s)
    with g.block("Radiance: I times the factor" + (" + " + once if once else "")):
        color = (g.vmath("MULTIPLY_ADD", i["Light Color"], factor, s[once], label="radiance") if once
                 else g.vmul(i["Light Color"], factor, label="radiance"))
    _finish(g, o, color)
    g.layout()


def surface_group_name(name):
    return f".{name} Surface"


def light_group_name(name):
    return f".{name} Light"


_SOCKET = {"VALUE": F, "VECTOR": V, "RGBA": C}
#: Input of a light half: the radiance of the lights before it (one multiply-add per light, no sum nodes).
SUM = ("Radiance So Far", C, BLACK, None, "Radiance of the lights summed before this one")


def _surface_outputs(name):
    """[(term, socket type)] of the surface half of ``name``, learnt by building it in a scratch group (so that
    rebuilding the real group keeps the outputs materials link, by name)."""
    scratch = bpy.data.node_groups.new(".IL scratch", "ShaderNodeTree")
    try:
        sync_interface(scratch, _model_params(name), [])
        i, _ = _io(Graph(scratch))
        return [(key, _SOCKET[sock.type]) for key, sock in HALVES[name][0](Graph(scratch), i).items()]
    finally:
        bpy.data.node_groups.remove(scratch)


def _build_surface_half(tree, name):
    """The surface terms as outputs (the interface is :func:`_surface_outputs`)."""
    g = Graph(tree)
    i, o = _io(g)
    for key, sock in HALVES[name][0](g, i).items():
        g.feed(sock, o[key])
    g.layout()


def _light_half_inputs(name):
    surface = ensure_group(surface_group_name(name))
    keys = [(it.name, it.socket_type, None, None, "surface term")
            for it in surface.interface.items_tree if it.item_type == "SOCKET" and it.in_out == "OUTPUT"]
    switches = [x for x in INPUTS[name] if x[0] in HALVES[name][2]]
    return list(_LIGHT_IN) + [SUM] + switches + keys


def _build_light_half(tree, name, fixed=()):
    g = Graph(tree)
    i, o = _io(g)
    i = _Fixed(i, fixed)
    keys = [it.name for it in tree.interface.items_tree if it.item_type == "SOCKET" and it.in_out == "INPUT"]
    s = {k: i[k] for k in keys}
    g.feed(g.vmath("MULTIPLY_ADD", i["Light Color"], HALVES[name][1](g, i, s), i[SUM[0]],
                   label="radiance so far + I factor"), o["Color"])
    g.prune()
    g.layout()


def _build_light(tree):
    """The public "IL Light": every type's part (the per-type groups' own builders), the one of Type selected."""
    g = Graph(tree)
    i, o = _io(g)
    with g.block("Surface"):
        geo = g.node("ShaderNodeNewGeometry")
        g.registers(geo)
        p, n = geo.outputs["Position"], geo.outputs["Normal"]
    with g.block("Type switches"):
        is_t = [g.math("COMPARE", i["Type"], float(k), 0.5, label=name)
                for k, name in enumerate(("point", "spot", "sun", "hemisphere"))]
    parts = [_point_part(g, i, p, spot=is_t[1]), _sun_part(g, i), _hemi_part(g, i, n)]
    with g.block("Select by type"):
        on = [g.add(is_t[0], is_t[1], label="point or spot"), is_t[2], is_t[3]]
        lvec = g.vadd(g.scale(parts[0][0], on[0]), g.vadd(g.scale(parts[1][0], on[1]), g.scale(parts[2][0], on[2])),
                      label="Light Vector")
        col = g.vadd(g.scale(parts[0][1], on[0]), g.vadd(g.scale(parts[1][1], on[1]), g.scale(parts[2][1], on[2])),
                     label="Light Color")
    g.feed(lvec, o["Light Vector"])
    g.feed(col, o["Light Color"])
    g.layout()


def _point_part(g, i, p, spot):
    """Light Vector and I of a point (or spot) light: P/(4 pi^2) f_att, times (s.s')^k inside a spot's cone.
    ``spot``: False, True, or a socket that is 1 for a spot and 0 for a point (the public group's switch)."""
    R = g.reg
    if not is_socket(i["Physical"]) and i["Physical"] == 1.0:
        return _point_part_physical(g, i, p, spot)
    with g.block("Vector and attenuation"):
        lvec = g.vmath("SUBTRACT", i["Position"], p, label="position - p")
        d2 = g.dot(lvec, lvec, label="d^2")
        phys = g.div(R(1.0), g.max(d2, R(brdf.TINY)), label="1/d^2")
        poly = g.madd(R(i["C3"], "c3"), d2, g.madd(R(i["C2"], "c2"), g.math("SQRT", d2, label="d"), R(i["C1"], "c1")),
                      label="c1 + c2 d + c3 d^2")
        emp = g.min(g.div(R(1.0), g.max(poly, R(brdf.TINY))), R(1.0), label="min(1/(...), 1)")
        att = g.lerp(emp, phys, i["Physical"], label="f_att")
    if spot:
        fall = _spot_falloff(g, i, lvec)
        if spot is not True:
            fall = g.lerp(R(1.0), fall, spot, label="falloff of a spot, 1 for a point")
        att = g.mul(att, fall, label="f_att (s.s')^k")
    with g.block("Colour P/(4 pi^2) f_att"):
        col = g.scale(g.scale(i["Color"], g.div(i["Power"], 4.0 * math.pi ** 2), label="colour P/(4 pi^2)"), att,
                      label="Light Color")
    return lvec, col


def _point_part_physical(g, i, p, spot):
    """:func:`_point_part` with Physical fixed at 1: I = (colour P/(4 pi^2)) (s.s')^k / d^2 in one Vector Math
    divide (Cycles' divide is 0 where d = 0, the twin's 1/max(d^2, 1e-12) is finite there too: both are
    undefined at the light's own position)."""
    with g.block("Vector, d^2"):
        lvec = g.vmath("SUBTRACT", i["Position"], p, label="position - p")
        d2 = g.dot(lvec, lvec, label="d^2")
    col = g.scale(i["Color"], g.div(i["Power"], 4.0 * math.pi ** 2), label="colour P/(4 pi^2)")
    if spot:
        col = g.scale(col, _spot_falloff(g, i, lvec), label="colour P/(4 pi^2) (s.s')^k")
    with g.block("Colour P/(4 pi^2) (s.s')^k / d^2"):
        return lvec, g.vmath("DIVIDE", col, d2, label="Light Color")


def _spot_falloff(g, i, lvec):
    """(s.s')^k inside the spot's cone, 0 outside."""
    R = g.reg
    with g.block("Spot: cutoff and (s.s')^k"):
        minus_s = g.scale(g.normalize(i["Direction"]), -1.0, label="-s")
        cos_ss = g.dot(g.normalize(lvec), minus_s, label="s.s'")
        inside = g.math("GREATER_THAN", cos_ss, g.math("COSINE", i["Spot Cutoff"]), label="inside cone")
        return g.mul(inside, g.pow(g.max(cos_ss, R(0.0)), R(i["Spot Exponent"], "k")), label="spot falloff")


def _sun_part(g, i):
    """Light Vector -direction and I = colour S/pi of a sun."""
    with g.block("Sun: -direction, colour S/pi"):
        lvec = g.scale(i["Direction"], -1.0, label="-direction")
        col = g.scale(i["Color"], g.div(i["Power"], math.pi, label="S/pi"), label="sun colour")
    return lvec, col


def _hemi_part(g, i, n):
    """Light Vector n and I = mix(ground, sky, (1 + n.u)/2) S/pi of a hemisphere light (u = -direction)."""
    with g.block("Hemisphere: l = n, mix(ground, sky, (1 + n.u)/2) S/pi"):
        sun_l = g.scale(i["Direction"], -1.0, label="u = -direction")
        w = g.div(g.add(1.0, g.dot(g.normalize(n), g.normalize(sun_l))), 2.0, label="(1 + n.u)/2")
        hemi_c = g.vlerp(i["Ground Color"], i["Color"], w, label="mix(ground, sky)")
        col = g.scale(hemi_c, g.div(i["Power"], math.pi, label="S/pi"), label="hemisphere colour")
    return n, col


def _build_light_of(tree, kind, fixed=()):
    """One light type only (what "IL Light" computes for that Type, without the other types' nodes)."""
    g = Graph(tree)
    i, o = _io(g)
    i = _Fixed(i, fixed)
    if kind in ("POINT", "SPOT", "HEMI"):
        with g.block("Surface"):
            geo = g.node("ShaderNodeNewGeometry")
            g.registers(geo)
    if kind in ("POINT", "SPOT"):
        lvec, col = _point_part(g, i, geo.outputs["Position"], kind == "SPOT")
    elif kind == "SUN":
        lvec, col = _sun_part(g, i)
    else:
        lvec, col = _hemi_part(g, i, geo.outputs["Normal"])
    g.feed(lvec, o["Light Vector"])
    g.feed(col, o["Light Color"])
    g.prune()
    g.layout()


BUILDERS = {name: (lambda t, k=name: _build_model(t, k)) for name in HALVES}
BUILDERS[LIGHT] = _build_light


#: Internal per-type light groups (interface of "IL Light"): what a material links per light, so that
#: Blender converts only the nodes of that light's type at every render.
LIGHT_OF_TYPE = {kind: f".IL Light {kind.title()}" for kind in ("POINT", "SPOT", "SUN", "HEMI")}


def _model_params(name):
    return [x for x in INPUTS[name] if x[0] not in ("Light Vector", "Light Color")]


def _internal():
    """{name: (inputs(), outputs(), description, build(tree, fixed), switches)} of the groups materials use
    (names start with a dot); ``switches``: the inputs a variant can fix (see :func:`variant`)."""
    out = {}
    for kind, name in LIGHT_OF_TYPE.items():
        out[name] = (lambda: INPUTS[LIGHT], lambda: OUTPUTS[LIGHT], f"{DESCRIPTIONS[LIGHT]}: {kind.lower()} only",
                     lambda t, f, k=kind: _build_light_of(t, k, f),
                     ("Physical",) if kind in ("POINT", "SPOT") else ())
    for model in HALVES:
        out[surface_group_name(model)] = (lambda m=model: _model_params(m), lambda m=model: _surface_outputs(m),
                                          f"{model}: the terms every light shares",
                                          lambda t, f, m=model: _build_surface_half(t, m), ())
        out[light_group_name(model)] = (lambda m=model: _light_half_inputs(m), lambda: [("Color", C)],
                                        f"{model}: one light's radiance from the surface terms",
                                        lambda t, f, m=model: _build_light_half(t, m, f), tuple(HALVES[model][2]))
    return out


INTERNAL = _internal()
#: {variant name: (internal group, fixed switches)}, filled by :func:`variant`.
VARIANTS = {}

#: What each value of a switch input selects (0, 1): the words in a variant's name.
SWITCH_VALUES = {"Distribution": ("Beckmann", "GGX"), "Geometry": ("Cook-Torrance 1982", "Smith"),
                 "Normalized": ("classic", "normalised"), "Physical": ("empirical", "1 over d^2")}


class _Fixed:
    """Group inputs where the switches a variant fixes read as their numbers (0 or 1)."""

    def __init__(self, sockets, fixed):
        self.sockets, self.fixed = sockets, dict(fixed)

    def __getitem__(self, key):
        return self.fixed[key] if key in self.fixed else self.sockets[key]


def switches(base):
    """The switch inputs of the internal group ``base`` that a variant can fix (empty: no variants)."""
    return INTERNAL[base][4] if base in INTERNAL else ()


def variant(base, values):
    """The internal group ``base`` built with its switches fixed at ``values`` ({switch: 0 or 1}, every
    switch of ``base``), so that it holds only the chosen branches; ``base`` itself when a value is missing
    or not 0 or 1 (then the switches stay Mix factors, both branches converted).

    Blender converts every node a material reaches at every render, also a switch's unused branch (Cycles
    folds it only afterwards), so a material links the variant its switches select. Same interface as
    ``base``, so a material's links survive swapping one for the other.
    """
    names = switches(base)
    if not names or any(values.get(k) not in (0.0, 1.0) for k in names):
        return ensure_group(base)
    fixed = tuple((k, float(values[k])) for k in names)
    name = f"{base} [{', '.join(SWITCH_VALUES[k][int(v)] for k, v in fixed)}]"
    VARIANTS[name] = (base, fixed)
    return ensure_group(name)


def is_current(name):
    tree = bpy.data.node_groups.get(name)
    return tree is not None and tree.bl_idname == "ShaderNodeTree" and tree.get("il_version") == GROUP_VERSION


def ensure_group(name):
    """The group ``name``, built if missing or older than GROUP_VERSION."""
    if is_current(name):
        return bpy.data.node_groups[name]
    base, fixed = VARIANTS.get(name, (name, ()))
    if base in INTERNAL:
        inputs, outputs, description, build, _ = INTERNAL[base]
        if fixed:
            description += f" ({', '.join(f'{k} {v:g}' for k, v in fixed)})"
        tree = fresh_tree(name, inputs(), outputs(), description)
        tree["il_version"] = GROUP_VERSION
        tree["il_base"] = base
        build = (lambda t, b=build: b(t, fixed))
    else:
        tree, build = _fresh(name), BUILDERS[name]
    build(tree)
    return tree


def add_node_groups():
    """Create or update every IL group; returns {"created": [...], "updated": [...], "current": [...]}."""
    result = {"created": [], "updated": [], "current": []}
    for name in BUILDERS:
        existing = bpy.data.node_groups.get(name)
        if is_current(name):
            result["current"].append(name)
            continue
        ensure_group(name)
        result["updated" if existing is not None else "created"].append(name)
    return result
