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

Materials use internal groups built from the same code (names start with a dot, see
:data:`INTERNAL`): each model's surface half and light half, and "IL Light" for one light type;
and their variants with the switch inputs fixed at 0 or 1 (:func:`variant`), which hold only the
chosen branches.
"""
import math

import bpy

from ..core import brdf
from .builder import Graph, is_socket

#: Bump whenever a group's contents or sockets change: older groups in a file are rebuilt.
GROUP_VERSION = 10

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


def _surface_common(g):
    """n and v (unit vectors as Cycles and EEVEE give them), n.v and the constant registers: what every light
    shares (computed once)."""
    with g.block("Surface: n, v, n.v, constants (computed once for all lights)"):
        geo = g.node("ShaderNodeNewGeometry")
        g.registers(geo)
        n, v = geo.outputs["Normal"], geo.outputs["Incoming"]
        n_v = g.dot(n, v, label="n.v")
    return {"n": n, "v": v, "n.v": n_v, "0": g.reg(0.0)}


def _light_common(g, i, s):
    with g.block("Light: l, n.l"):
        l = g.normalize(i["Light Vector"], label="l (toward light)")
        n_l = g.dot(s["n"], l, label="n.l")
    return l, n_l


def _finish(g, o, color):
    with g.block("Output: radiance and emission"):
        em = g.node("ShaderNodeEmission")
        g.feed(color, em.inputs["Color"])
        em.inputs["Strength"].default_value = 1.0
    g.feed(color, o["Color"])
    g.feed(em.outputs[0], o["Emission"])


# -- models -----------------------------------------------------------------------------------------
#
# Each model is two halves: ``surface(g, i)`` returns the named terms that depend only on the shading
# point and the parameters (n, v, n.v, roughness terms, registers), ``light(g, i, s)`` the factor of one
# light's I from them (radiance = I factor, summed over the lights by one multiply-add each). The public
# group holds both; a material holds the surface half once (internal group ".IL <model> Surface") and the
# light half per light (".IL <model> Light"), so Blender converts only the light half for every light at
# every render (it converts every node reachable from the output, about 13 us each; Cycles folds the
# switches' unused branches only after that, so materials link the variants built with the switches fixed,
# :func:`variant`).
#
# Cost (Cycles SVM): a switch input left constant (Distribution, Geometry, Normalized, Physical, Type)
# keeps one branch only, so switches are Mix nodes, never math that evaluates both branches; and the
# per-light nodes take no constant operands (a constant is loaded before every node that takes it, as
# costly as the operation): they read "registers" (g.reg), nodes computed once per shading point.

def _phong_surface(g, i, blinn):
    s = _surface_common(g)
    R = g.reg
    s["n (exponent)"] = R(i["Shininess"], "n")
    if blinn:
        s[f"{brdf.TINY:g}"] = R(brdf.TINY)
        with g.block("Surface: (n+2)(n+4) / (8 (2^(-n/2) + n))"):
            n0 = g.max(i["Shininess"], 0.0, label="max(n, 0)")
            num = g.mul(g.add(n0, 2.0), g.add(n0, 4.0), label="(n+2)(n+4)")
            den = g.mul(g.add(g.pow(2.0, g.mul(n0, -0.5)), n0), 8.0, label="8 (2^(-n/2) + n)")
            s["energy factor"] = R(g.div(num, den), "energy factor")
    else:
        with g.block("Surface: (n+2)/2, 2 n.v, -v"):
            s["energy factor"] = R(g.div(g.add(i["Shininess"], 2.0), 2.0), "energy factor")
            s["2 n.v"] = g.add(s["n.v"], s["n.v"], label="2 n.v")
            s["-v"] = g.scale(s["v"], -1.0, label="-v")
    with g.block("Surface: k_d, k_s, k_a I_a + I_e"):
        s["k_d"] = g.vreg(i["Kd"], "k_d")
        s["k_s"] = g.vreg(i["Ks"], "k_s")
        s["k_a I_a + I_e"] = g.vadd(g.scale(i["Ambient Light"], i["Ka"], label="k_a I_a"), i["Emission Color"],
                                    label="+ I_e")
    return s


def _phong_light(g, i, s, blinn):
    l, n_l = _light_common(g, i, s)
    zero, shin = s["0"], s["n (exponent)"]
    with g.block("lit: n.l > 0"):
        lit = g.gt(n_l, zero, label="lit")
        a = g.mul(n_l, lit, label="max(n.l, 0)")
    if blinn:
        with g.block("Lobe: (n.h)^n"):
            n_h = _half_vector_cosines(g, s, l)[0]
            lobe = g.pow(g.max(n_h, zero), shin, label="(n.h)^n")
    else:
        with g.block("Lobe: (r.v)^n, r.v = 2 (n.l)(n.v) - l.v"):
            r_v = g.madd(n_l, s["2 n.v"], g.dot(l, s["-v"], label="-l.v"), label="r.v")
            lobe = g.pow(g.max(r_v, zero), shin, label="(r.v)^n")
    with g.block("N lit: lit (classic) or factor max(n.l, 0) (energy-normalised)"):
        norm = g.lerp(lit, g.mul(a, s["energy factor"], label="factor max(n.l, 0)"), i["Normalized"], label="N lit")
    with g.block("k_d n.l + k_s N lobe"):
        diff = g.scale(s["k_d"], a, label="k_d n.l")
        return g.add_scaled(diff, s["k_s"], g.mul(lobe, norm, label="N lobe"), label="k_d n.l + k_s N lobe")


def _oren_nayar_surface(g, i):
    s = _surface_common(g)
    R = g.reg
    n_v = s["n.v"]
    with g.block("Surface: A, B from sigma; n.v terms"):
        s2 = g.mul(i["Sigma"], i["Sigma"], label="sigma^2")
        s["A"] = R(g.sub(1.0, g.div(g.mul(s2, 0.5), g.add(s2, 0.33))), "A = 1 - 0.5 s2/(s2+0.33)")
        s["B"] = R(g.div(g.mul(s2, 0.45), g.add(s2, 0.09)), "B = 0.45 s2/(s2+0.09)")
        s["-n.v"] = g.mul(n_v, -1.0, label="-n.v")
        s["max(n.v, 1e-12)"] = g.max(n_v, brdf.TINY, label="max(n.v, 1e-12)")
        s["2 (n.v > 0)"] = g.mul(g.gt(n_v, 0.0), 2.0, label="2 (n.v > 0)")
        s["rho"] = g.vreg(i["Albedo"], "rho")
    return s


def _oren_nayar_light(g, i, s):
    l, n_l = _light_common(g, i, s)
    with g.block("(n.l)(A + B max(0, cos dphi) sin(alpha) tan(beta)), bounded vector form"):
        t0 = g.max(g.madd(n_l, s["-n.v"], g.dot(l, s["v"], label="l.v")), s["0"], label="max(0, l.v - (n.l)(n.v))")
        t = g.div(t0, g.max(n_l, s["max(n.v, 1e-12)"]), label="s / max(n.l, n.v, 1e-12)")
        a = g.min(g.max(n_l, s["0"]), s["2 (n.v > 0)"], label="max(n.l, 0), 0 unless n.v > 0")
        factor = g.mul(a, g.madd(t, s["B"], s["A"]), label="n.l (A + B s / max(n.l, n.v))")
    with g.block("rho factor"):
        return g.scale(s["rho"], factor, label="rho factor")


def _cook_torrance_surface(g, i):
    s = _surface_common(g)
    R = g.reg
    with g.block("Surface: roughness, constants"):
        r = g.max(i["Roughness"], brdf.MIN_ROUGHNESS, label="m or alpha (>= 1e-3)")
        r2 = g.mul(r, r, label="r^2 (constant)")
        # registers of constants (one node evaluated per shading point, no constant loaded per light)
        s.update({"r^2": R(r2, "r^2"), "1/r": R(g.div(1.0, r), "1/r"),
                  "r^2/4": R(g.mul(r2, 0.25), "r^2/4"), "(1 - r^2)/4": R(g.mul(g.sub(1.0, r2), 0.25), "(1 - r^2)/4"),
                  "pi r^2": R(g.mul(r2, math.pi), "pi r^2"), "r^2 - 1": R(g.sub(r2, 1.0), "r^2 - 1")})
        for value in (1.0, 5.0, brdf.EPS, brdf.TINY, 0.396, -1.259, 2.181, 3.535, 1.6, 0.5, -0.5):
            s[f"{value:g}"] = R(value)
    n_v = s["n.v"]
    with g.block("Surface: n.v terms, Lambda(v), pi k_s / (4 n.v) where n.v > 0, times F0 and 1 - F0"):
        c = g.max(n_v, brdf.EPS, label="max(n.v, 1e-4)")
        s["max(n.v, 0)"] = g.max(n_v, s["0"], label="max(n.v, 0)")
        s["1 + Lambda Beckmann(v)"] = g.add(_lambda_beckmann(g, s, n_v, "v"), 1.0, label="1 + Lambda Beckmann(v)")
        # (1 + 2 Lambda_GGX(v))/2 = sqrt(a^2 + (1 - a^2) c^2)/(2c) = sqrt(a^2/(4 c^2) + (1 - a^2)/4)
        s["s GGX(v)/2"] = g.math("SQRT", g.add(g.div(s["r^2/4"], g.mul(c, c)), s["(1 - r^2)/4"]),
                                 label="(1 + 2 Lambda GGX(v))/2")
        k = g.mul(g.div(g.mul(i["Ks"], math.pi / 4.0), c), g.gt(n_v, s["0"]),
                  label="k = pi k_s / (4 n.v), 0 unless n.v > 0")
        one_minus_f0 = g.sub(1.0, i["F0"], label="1 - F0 (constant)")
        s["F0 k"] = g.mul(k, i["F0"], label="F0 k")
        s["(1 - F0) k"] = g.mul(k, one_minus_f0, label="(1 - F0) k")
        s["F0 k r^2/pi"] = g.mul(k, g.mul(i["F0"], g.div(r2, math.pi)), label="F0 k r^2/pi")
        s["(1 - F0) k r^2/pi"] = g.mul(k, g.mul(one_minus_f0, g.div(r2, math.pi)), label="(1 - F0) k r^2/pi")
        s["r^2/pi"] = R(g.div(r2, math.pi), "r^2/pi")
        s["k_d"] = g.vreg(i["Kd"], "k_d")
    return s


def _lambda_beckmann(g, s, cos_theta, which):
    """Smith Lambda for Beckmann: Walter's rational fit of a = 1/(m tan theta), 0 for a >= 1.6."""
    one, eps = s["1"], s[f"{brdf.EPS:g}"]
    c = g.max(cos_theta, eps)
    cc = g.mul(c, c)
    t2 = g.div(g.max(g.sub(one, cc), s["0"]), cc, label=f"tan^2 theta_{which}")
    a = g.max(g.mul(g.math("INVERSE_SQRT", g.max(t2, s[f"{brdf.TINY:g}"])), s["1/r"]), eps, label=f"a ({which})")
    fit = g.div(g.madd(a, g.madd(a, s["0.396"], s["-1.259"]), one), g.mul(a, g.madd(a, s["2.181"], s["3.535"])),
                label=f"Walter fit ({which})")
    return g.mul(fit, g.math("LESS_THAN", a, s["1.6"]), label=f"Lambda Beckmann ({which})")


def _half_vector_cosines(g, s, l):
    """n.h = n.(l + v)/|l + v| and |l + v|^2 = (l + v).(l + v), kept above 1e-12 (l = -v gives 0), with
    1/|l + v|: v.h = |l + v|/2 in [0, 1] for unit l and v, without normalizing h."""
    with g.block("Half vector cosines: n.h = n.(l + v)/|l + v|, v.h = |l + v|/2"):
        l_v = g.vadd(l, s["v"], label="l + v")
        lv2 = g.max(g.dot(l_v, l_v), s[f"{brdf.TINY:g}"], label="|l + v|^2")
        inv_lv = g.math("INVERSE_SQRT", lv2, label="1/|l + v|")
        n_h = g.mul(g.dot(s["n"], l_v, label="n.(l + v)"), inv_lv, label="n.h")
    return n_h, lv2, inv_lv


def _cook_torrance_light(g, i, s):
    l, n_l = _light_common(g, i, s)
    n_h, lv2, inv_lv = _half_vector_cosines(g, s, l)
    lv = g.mul(lv2, inv_lv, label="|l + v| = 2 v.h")
    dist, geom = i["Distribution"], i["Geometry"]
    zero, one, eps = s["0"], s["1"], s[f"{brdf.EPS:g}"]
    a_l = g.max(n_l, zero, label="max(n.l, 0)")
    if (dist, geom) == (1.0, 1.0):
        return _ggx_smith_factor(g, s, n_h, lv, a_l)
    v_h = g.mul(lv, s["0.5"], label="v.h")
    # n.h enters D and G unclamped at 0 where the twin clamps it: those points have n.l <= 0 or n.v <= 0
    # (n.h = (n.l + n.v)/|l + v|), where G or k makes the specular 0 (both stay finite there).
    with g.block("D: Beckmann"):
        c = g.max(n_h, eps)
        c2 = g.mul(c, c, label="cos^2")
        ex = g.math("EXPONENT", g.div(g.sub(c2, one), g.mul(s["r^2"], c2)), label="exp(-tan^2/m^2)")
        d_beck = g.div(ex, g.mul(s["pi r^2"], g.mul(c2, c2)), label="D Beckmann")
    with g.block("D: GGX"):
        t = g.madd(g.mul(n_h, n_h), s["r^2 - 1"], one, label="cos^2 (a^2-1) + 1")
        d_ggx = g.div(s["r^2/pi"], g.mul(t, t), label="D GGX")
    with g.block("D: select (0 Beckmann, 1 GGX)"):
        D = g.lerp(d_beck, d_ggx, dist, label="D")
    with g.block("G: Cook-Torrance 1982, min(1, 2 (n.h) min(n.v, n.l) / (v.h))"):
        q = g.div(g.add(n_h, n_h), g.max(v_h, eps), label="2 (n.h) / (v.h)")
        g_ct = g.min(g.mul(q, g.min(a_l, s["max(n.v, 0)"])), one, label="G Cook-Torrance")
    with g.block("G: Smith height-correlated, 1/(1 + Lambda(l) + Lambda(v)); GGX: 2/(s(l) + s(v)), s = 1 + 2 Lambda"):
        g_beck = g.div(g.gt(n_l, zero, label="n.l > 0"),
                       g.add(_lambda_beckmann(g, s, n_l, "l"), s["1 + Lambda Beckmann(v)"]), label="G Smith Beckmann")
        # 2/(s(l) + s(v)) times a_l/a_l: 0 where n.l <= 0 without a mask, finite (the root is >= min(r, 1)/2)
        half_root = g.math("SQRT", g.madd(g.mul(a_l, a_l), s["(1 - r^2)/4"], s["r^2/4"]),
                           label="sqrt(a^2 + (1 - a^2) (n.l)^2)/2")
        g_ggx = g.div(a_l, g.madd(a_l, s["s GGX(v)/2"], half_root), label="G Smith GGX")
        g_smith = g.lerp(g_beck, g_ggx, dist, label="G Smith")
    with g.block("G: select (0 Cook-Torrance, 1 Smith)"):
        G = g.lerp(g_ct, g_smith, geom, label="G")
    with g.block("F k: Schlick, F0 + (1 - F0)(1 - v.h)^5, times k"):
        one_minus = g.sub(one, v_h, label="1 - v.h")
        Fk = g.madd(g.pow(one_minus, s["5"]), s["(1 - F0) k"], s["F0 k"], label="F k")
    # every G is 0 where n.l <= 0 (G Cook-Torrance through max(n.l, 0)), and k where n.v <= 0
    with g.block("L = I (k_d n.l + pi k_s F D G / (4 n.v)), specular 0 unless n.l, n.v > 0"):
        spec = g.mul(g.mul(Fk, D), G, label="specular")
        return g.vmath("MULTIPLY_ADD", s["k_d"], a_l, spec, label="k_d n.l + specular")


def _ggx_smith_factor(g, s, n_h, lv, a_l):
    """GGX with the height-correlated Smith G (both switches at 1, the default) in fewer nodes than the
    general form: with t = (n.h)^2 (a^2 - 1) + 1 and G = a_l / (a_l s(v)/2 + sqrt(a^2 + (1 - a^2) a_l^2)/2),
    D G = (a^2/pi) a_l / (t^2 den), so k_d a_l + F k D G = k_d a_l + a_l F k (a^2/pi) / (t^2 den) (REFERENCE.md
    sec. 1, Walter et al. 2007 eq. 33 and 34; the same values as the general form)."""
    with g.block("D G / a_l: (a^2/pi) / (t^2 (a_l s(v)/2 + sqrt(a^2 + (1 - a^2) a_l^2)/2))"):
        t = g.madd(g.mul(n_h, n_h), s["r^2 - 1"], s["1"], label="t = (n.h)^2 (a^2 - 1) + 1")
        half_root = g.math("SQRT", g.madd(g.mul(a_l, a_l), s["(1 - r^2)/4"], s["r^2/4"]),
                           label="sqrt(a^2 + (1 - a^2) (n.l)^2)/2")
        den = g.mul(g.mul(t, t, label="t^2"), g.madd(a_l, s["s GGX(v)/2"], half_root), label="t^2 den")
    with g.block("F k a^2/pi: Schlick, F0 + (1 - F0)(1 - v.h)^5, v.h = |l + v|/2"):
        one_minus = g.madd(lv, s["-0.5"], s["1"], label="1 - v.h")
        fk = g.madd(g.pow(one_minus, s["5"]), s["(1 - F0) k r^2/pi"], s["F0 k r^2/pi"], label="F k a^2/pi")
    with g.block("k_d n.l + n.l (F k D G / n.l)"):
        spec = g.mul(a_l, g.div(fk, den), label="F k D G")
        return g.vmath("MULTIPLY_ADD", s["k_d"], a_l, spec, label="k_d n.l + specular")


#: model group: (surface half, light half, the switch inputs the light half reads, surface term added once).
HALVES = {
    PHONG: (lambda g, i: _phong_surface(g, i, False), lambda g, i, s: _phong_light(g, i, s, False),
            ["Normalized"], "k_a I_a + I_e"),
    BLINN_PHONG: (lambda g, i: _phong_surface(g, i, True), lambda g, i, s: _phong_light(g, i, s, True),
                  ["Normalized"], "k_a I_a + I_e"),
    OREN_NAYAR: (_oren_nayar_surface, _oren_nayar_light, [], None),
    COOK_TORRANCE: (_cook_torrance_surface, _cook_torrance_light, ["Distribution", "Geometry"], None),
}


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
    return _LIGHT_IN + [SUM] + switches + keys


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
