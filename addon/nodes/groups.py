"""The node groups "IL Phong", "IL Blinn-Phong", "IL Oren-Nayar", "IL Cook-Torrance" and "IL Light".

Each group evaluates, term by term and with the same clamps, the numpy twin in
``addon/core/brdf.py`` / ``addon/core/lights.py`` (REFERENCE.md §1-2). Normal and
view vectors come from the Geometry node; the light from the "Light Vector" and
"Light Color" inputs (I = E_perp/pi). Outputs: "Color" (radiance) and "Emission"
(an Emission shader of that radiance, strength 1).

:func:`add_node_groups` is idempotent: a group carrying the current
``GROUP_VERSION`` in its "il_version" property is left alone; an older one is
rebuilt in place (same datablock, sockets kept by name), so materials using it
update without relinking.
"""
import math

import bpy

from ..core import brdf
from .builder import Graph

#: Bump whenever a group's contents or sockets change: older groups in a file are rebuilt.
GROUP_VERSION = 4

PHONG, BLINN_PHONG, OREN_NAYAR, COOK_TORRANCE, LIGHT = (
    "IL Phong", "IL Blinn-Phong", "IL Oren-Nayar", "IL Cook-Torrance", "IL Light")
MODEL_GROUPS = {"PHONG": PHONG, "BLINN_PHONG": BLINN_PHONG, "OREN_NAYAR": OREN_NAYAR,
                "COOK_TORRANCE": COOK_TORRANCE}

F, V, C = "NodeSocketFloat", "NodeSocketVector", "NodeSocketColor"
WHITE, BLACK = (1.0, 1.0, 1.0, 1.0), (0.0, 0.0, 0.0, 1.0)

_LIGHT_IN = [("Light Vector", V, (0.0, 0.0, 1.0), None, "World-space vector from the surface toward the light"),
             ("Light Color", C, WHITE, None, "Incident intensity I = E_perp / pi")]
_PHONG_IN = _LIGHT_IN + [
    ("Ka", F, 0.1, (0.0, 1.0), "Ambient reflection coefficient k_a"),
    ("Ambient Light", C, (0.2, 0.2, 0.2, 1.0), None, "Ambient intensity I_a"),
    ("Kd", C, (0.8, 0.8, 0.8, 1.0), None, "Diffuse reflection coefficient k_d"),
    ("Ks", F, 0.5, (0.0, 1.0), "Specular reflection coefficient k_s"),
    ("Shininess", F, 32.0, (0.0, 1e5), "Specular exponent n"),
    ("Emission Color", C, BLACK, None, "Emitted radiance I_e"),
    ("Normalized", F, 0.0, (0.0, 1.0), "0 classic, 1 energy-normalised lobe")]

#: (name, socket type, default, (min, max) or None, description) per input, per group.
INPUTS = {
    PHONG: _PHONG_IN,
    BLINN_PHONG: _PHONG_IN,
    OREN_NAYAR: _LIGHT_IN + [
        ("Albedo", C, (0.8, 0.8, 0.8, 1.0), None, "Diffuse albedo rho"),
        ("Sigma", F, 0.3, (0.0, 10.0), "Standard deviation of the facet slopes, radians")],
    COOK_TORRANCE: _LIGHT_IN + [
        ("Kd", C, (0.2, 0.2, 0.2, 1.0), None, "Lambertian part k_d"),
        ("Ks", F, 1.0, (0.0, 1.0), "Weight k_s of the microfacet lobe"),
        ("F0", F, 0.04, (0.0, 1.0), "Fresnel reflectance at normal incidence (Schlick)"),
        ("Roughness", F, 0.3, (0.0, 1.0), "m (Beckmann) or alpha (GGX) itself, clamped to >= 1e-3"),
        ("Distribution", F, 1.0, (0.0, 1.0), "0 Beckmann, 1 GGX"),
        ("Geometry", F, 1.0, (0.0, 1.0), "0 Cook-Torrance 1982, 1 height-correlated Smith")],
    LIGHT: [
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
        ("Ground Color", C, BLACK, None, "Ground colour of a hemisphere light")],
}
OUTPUTS = {name: [("Color", C), ("Emission", "NodeSocketShader")] for name in MODEL_GROUPS.values()}
OUTPUTS[LIGHT] = [("Light Vector", V), ("Light Color", C)]
DESCRIPTIONS = {
    PHONG: "Phong (seed 004): k_a I_a + I (k_d n.l + k_s N (r.v)^n) + I_e",
    BLINN_PHONG: "Blinn-Phong: k_a I_a + I (k_d n.l + k_s N (n.h)^n) + I_e",
    OREN_NAYAR: "Oren-Nayar qualitative model, bounded vector form",
    COOK_TORRANCE: "Cook-Torrance microfacet: I k_d n.l + pi I k_s F D G / (4 n.v)",
    LIGHT: "One light as Light Vector and Light Color (I = E_perp / pi)",
}


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


def _common(g, i):
    """Normalised n, v, l and the dot products every model needs, in a frame "Vectors"."""
    with g.block("Vectors: n, v, l"):
        geo = g.node("ShaderNodeNewGeometry")
        n = g.normalize(geo.outputs["Normal"], label="n")
        v = g.normalize(geo.outputs["Incoming"], label="v (toward viewer)")
        l = g.normalize(i["Light Vector"], label="l (toward light)")
        n_l = g.dot(n, l, label="n.l")
        n_v = g.dot(n, v, label="n.v")
        lit = g.gt(n_l, 0.0, label="lit: n.l > 0")
    return n, v, l, n_l, n_v, lit


def _finish(g, o, color):
    with g.block("Output: radiance and emission"):
        em = g.node("ShaderNodeEmission")
        g.feed(color, em.inputs["Color"])
        em.inputs["Strength"].default_value = 1.0
    g.feed(color, o["Color"])
    g.feed(em.outputs[0], o["Emission"])


# -- models -----------------------------------------------------------------------------------------

def _build_phong(tree, blinn):
    g = Graph(tree)
    i, o = _io(g)
    n, v, l, n_l, n_v, lit = _common(g, i)
    shin = i["Shininess"]
    if blinn:
        with g.block("Lobe: (n.h)^n"):
            h = g.normalize(g.vadd(l, v), label="h = (l+v)/|l+v|")
            lobe = g.pow(g.max(g.dot(n, h, label="n.h"), 0.0), shin, label="(n.h)^n")
        with g.block("Normalisation: 1 or (n+2)(n+4) / (8 (2^(-n/2) + n)) n.l"):
            n0 = g.max(shin, 0.0, label="max(n, 0)")
            num = g.mul(g.add(n0, 2.0), g.add(n0, 4.0), label="(n+2)(n+4)")
            den = g.mul(g.add(g.pow(2.0, g.mul(n0, -0.5)), n0), 8.0, label="8 (2^(-n/2) + n)")
            energy = g.mul(g.div(num, den), g.max(n_l, 0.0), label="energy factor")
            norm = g.lerp(1.0, energy, i["Normalized"], label="N")
    else:
        with g.block("Lobe: (r.v)^n"):
            r = g.vmath("SUBTRACT", g.scale(n, g.mul(n_l, 2.0)), l, label="r = 2n(n.l) - l")
            lobe = g.pow(g.max(g.dot(r, v, label="r.v"), 0.0), shin, label="(r.v)^n")
        with g.block("Normalisation: 1 or ((n+2)/2) n.l"):
            energy = g.mul(g.div(g.add(shin, 2.0), 2.0), g.max(n_l, 0.0), label="energy factor")
            norm = g.lerp(1.0, energy, i["Normalized"], label="N")
    with g.block("Sum: k_a I_a + I (k_d n.l + k_s N lobe) + I_e"):
        spec = g.mul(g.mul(i["Ks"], g.mul(lobe, norm)), lit, label="k_s N lobe")
        diff = g.scale(i["Kd"], g.mul(lit, g.max(n_l, 0.0)), label="k_d n.l")
        direct = g.vmul(i["Light Color"], g.vadd(diff, g.vmath("ADD", (0, 0, 0), spec)), label="I (...)")
        amb = g.scale(i["Ambient Light"], i["Ka"], label="k_a I_a")
        color = g.vadd(g.vadd(amb, direct), i["Emission Color"], label="radiance")
    _finish(g, o, color)
    g.layout()


def _build_oren_nayar(tree):
    g = Graph(tree)
    i, o = _io(g)
    n, v, l, n_l, n_v, lit = _common(g, i)
    with g.block("A and B from sigma"):
        s2 = g.mul(i["Sigma"], i["Sigma"], label="sigma^2")
        A = g.sub(1.0, g.div(g.mul(s2, 0.5), g.add(s2, 0.33)), label="A = 1 - 0.5 s2/(s2+0.33)")
        B = g.div(g.mul(s2, 0.45), g.add(s2, 0.09), label="B = 0.45 s2/(s2+0.09)")
    with g.block("(n.l) max(0, cos dphi) sin(alpha) tan(beta), bounded vector form"):
        s = g.max(g.sub(g.dot(l, v, label="l.v"), g.mul(n_l, n_v)), 0.0, label="max(0, l.v - (n.l)(n.v))")
        den = g.max(g.max(n_l, n_v), brdf.TINY, label="max(n.l, n.v, 1e-12)")
        ratio = g.div(g.max(n_l, 0.0), den, label="n.l / max(n.l, n.v): in [0, 1]")
        ang = g.mul(s, ratio, label="angular term")
    with g.block("L = rho I (A n.l + B term), zero unless n.l > 0 and n.v > 0"):
        both = g.mul(lit, g.gt(n_v, 0.0), label="n.l > 0 and n.v > 0")
        factor = g.mul(both, g.add(g.mul(A, g.max(n_l, 0.0)), g.mul(B, ang)), label="A n.l + B term")
        color = g.scale(g.vmul(i["Albedo"], i["Light Color"]), factor, label="radiance")
    _finish(g, o, color)
    g.layout()


def _build_cook_torrance(tree):
    g = Graph(tree)
    i, o = _io(g)
    n, v, l, n_l, n_v, lit = _common(g, i)
    eps = brdf.EPS
    with g.block("Half vector and roughness"):
        h = g.normalize(g.vadd(l, v), label="h")
        n_h = g.dot(n, h, label="n.h")
        v_h = g.dot(v, h, label="v.h")
        r = g.max(i["Roughness"], brdf.MIN_ROUGHNESS, label="m or alpha (>= 1e-3)")
        r2 = g.mul(r, r, label="r^2")
        h_up = g.gt(n_h, 0.0, label="n.h > 0")
    with g.block("D: Beckmann"):
        c = g.max(n_h, eps)
        c2 = g.mul(c, c, label="cos^2")
        ex = g.math("EXPONENT", g.div(g.sub(c2, 1.0), g.mul(r2, c2)), label="exp(-tan^2/m^2)")
        d_beck = g.div(ex, g.mul(g.mul(r2, math.pi), g.mul(c2, c2)), label="D Beckmann")
    with g.block("D: GGX"):
        cg = g.max(n_h, 0.0)
        t = g.add(g.mul(g.mul(cg, cg), g.sub(r2, 1.0)), 1.0, label="cos^2 (a^2-1) + 1")
        d_ggx = g.div(r2, g.mul(g.mul(t, t), math.pi), label="D GGX")
    with g.block("D: select (0 Beckmann, 1 GGX)"):
        D = g.mul(g.lerp(d_beck, d_ggx, i["Distribution"]), h_up, label="D")
    with g.block("G: Cook-Torrance 1982"):
        vh = g.max(v_h, eps)
        nh0 = g.max(n_h, 0.0)
        g1 = g.div(g.mul(g.mul(nh0, g.max(n_v, 0.0)), 2.0), vh, label="2 (n.h)(n.v)/(v.h)")
        g2 = g.div(g.mul(g.mul(nh0, g.max(n_l, 0.0)), 2.0), vh, label="2 (n.h)(n.l)/(v.h)")
        g_ct = g.min(1.0, g.min(g1, g2), label="G Cook-Torrance")

    def tan2(cos_theta, label):
        c = g.max(cos_theta, eps)
        cc = g.mul(c, c)
        return g.div(g.max(g.sub(1.0, cc), 0.0), cc, label=label)

    def lam(cos_theta, which):
        t2 = tan2(cos_theta, f"tan^2 theta_{which}")
        lam_ggx = g.div(g.sub(g.math("SQRT", g.add(1.0, g.mul(r2, t2))), 1.0), 2.0, label=f"Lambda GGX ({which})")
        a = g.max(g.div(1.0, g.mul(r, g.math("SQRT", g.max(t2, brdf.TINY)))), eps, label=f"a ({which})")
        a2 = g.mul(a, a)
        fit = g.div(g.add(g.sub(1.0, g.mul(a, 1.259)), g.mul(a2, 0.396)),
                    g.add(g.mul(a, 3.535), g.mul(a2, 2.181)), label=f"Walter fit ({which})")
        lam_beck = g.mul(fit, g.math("LESS_THAN", a, 1.6), label=f"Lambda Beckmann ({which})")
        return g.lerp(lam_beck, lam_ggx, i["Distribution"], label=f"Lambda ({which})")

    with g.block("G: Smith height-correlated, 1/(1 + Lambda(l) + Lambda(v))"):
        g_smith = g.div(1.0, g.add(g.add(1.0, lam(n_l, "l")), lam(n_v, "v")), label="G Smith")
    with g.block("G: select (0 Cook-Torrance, 1 Smith)"):
        G = g.lerp(g_ct, g_smith, i["Geometry"], label="G")
    with g.block("F: Schlick"):
        one_minus = g.sub(1.0, g.math("MINIMUM", g.max(v_h, 0.0), 1.0), label="1 - v.h")
        Fs = g.add(i["F0"], g.mul(g.sub(1.0, i["F0"]), g.pow(one_minus, 5.0)), label="F")
    with g.block("L = I (k_d n.l + pi k_s F D G / (4 n.v))"):
        both = g.mul(lit, g.gt(n_v, 0.0), label="n.l > 0 and n.v > 0")
        spec = g.div(g.mul(g.mul(g.mul(Fs, D), G), g.mul(i["Ks"], math.pi)), g.mul(g.max(n_v, eps), 4.0),
                     label="pi k_s F D G / (4 n.v)")
        spec = g.mul(spec, both, label="specular")
        diff = g.scale(i["Kd"], g.mul(lit, g.max(n_l, 0.0)), label="k_d n.l")
        color = g.vmul(i["Light Color"], g.vadd(diff, g.vmath("ADD", (0, 0, 0), spec)), label="radiance")
    _finish(g, o, color)
    g.layout()


def _build_light(tree):
    g = Graph(tree)
    i, o = _io(g)
    four_pi2 = 4.0 * math.pi ** 2
    with g.block("Surface"):
        geo = g.node("ShaderNodeNewGeometry")
        p, n = geo.outputs["Position"], geo.outputs["Normal"]
    with g.block("Type switches"):
        is_t = [g.math("COMPARE", i["Type"], float(k), 0.5, label=name)
                for k, name in enumerate(("point", "spot", "sun", "hemisphere"))]
    with g.block("Point: vector and attenuation"):
        lvec_p = g.vmath("SUBTRACT", i["Position"], p, label="position - p")
        d = g.vmath("LENGTH", lvec_p, label="d")
        phys = g.div(1.0, g.max(g.mul(d, d), brdf.TINY), label="1/d^2")
        poly = g.add(g.add(i["C1"], g.mul(i["C2"], d)), g.mul(i["C3"], g.mul(d, d)), label="c1 + c2 d + c3 d^2")
        emp = g.min(g.div(1.0, g.max(poly, brdf.TINY)), 1.0, label="min(1/(...), 1)")
        att = g.lerp(emp, phys, i["Physical"], label="f_att")
        point_i = g.mul(g.div(i["Power"], four_pi2), att, label="P/(4 pi^2) f_att")
    with g.block("Spot: cutoff and (s.s')^k"):
        cos_ss = g.dot(g.normalize(i["Direction"]), g.scale(g.normalize(lvec_p), -1.0), label="s.s'")
        inside = g.math("GREATER_THAN", cos_ss, g.math("COSINE", i["Spot Cutoff"]), label="inside cone")
        fall = g.mul(inside, g.pow(g.max(cos_ss, 0.0), i["Spot Exponent"]), label="spot falloff")
        spot_i = g.mul(point_i, fall, label="spot intensity")
    with g.block("Sun and hemisphere"):
        sun_l = g.scale(i["Direction"], -1.0, label="-direction")
        sun_i = g.div(i["Power"], math.pi, label="S/pi")
        w = g.div(g.add(1.0, g.dot(g.normalize(n), g.normalize(sun_l))), 2.0, label="(1 + n.u)/2")
        hemi_c = g.vlerp(i["Ground Color"], i["Color"], w, label="mix(ground, sky)")
    with g.block("Select by type"):
        lvec = g.vadd(g.scale(lvec_p, g.add(is_t[0], is_t[1])),
                      g.vadd(g.scale(sun_l, is_t[2]), g.scale(n, is_t[3])), label="Light Vector")
        k_ps = g.add(g.mul(point_i, is_t[0]), g.mul(spot_i, is_t[1]), label="point/spot factor")
        k_s = g.add(k_ps, g.mul(sun_i, is_t[2]), label="+ sun factor")
        col = g.vadd(g.scale(i["Color"], k_s), g.scale(hemi_c, g.mul(sun_i, is_t[3])), label="Light Color")
    g.feed(lvec, o["Light Vector"])
    g.feed(col, o["Light Color"])
    g.layout()


BUILDERS = {
    PHONG: lambda t: _build_phong(t, blinn=False),
    BLINN_PHONG: lambda t: _build_phong(t, blinn=True),
    OREN_NAYAR: _build_oren_nayar,
    COOK_TORRANCE: _build_cook_torrance,
    LIGHT: _build_light,
}


def is_current(name):
    tree = bpy.data.node_groups.get(name)
    return tree is not None and tree.bl_idname == "ShaderNodeTree" and tree.get("il_version") == GROUP_VERSION


def ensure_group(name):
    """The group ``name``, built if missing or older than GROUP_VERSION."""
    if is_current(name):
        return bpy.data.node_groups[name]
    tree = _fresh(name)
    BUILDERS[name](tree)
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
