"""Cook-Torrance microfacet model (Walter et al. 2007; REFERENCE.md §2):
L = I k_d (n.l) + pi I k_s F D G / (4 (n.v)), D Beckmann or GGX, G Cook-Torrance 1982 or Smith."""
import math

from ...core import brdf
from ._common import C, F, Input, Model, half_vector_cosines, light_common, surface_common


def _twin(n, l, v, I, p):
    """brdf.cook_torrance with the group's inputs."""
    return brdf.cook_torrance(n, l, v, I, kd=p["Kd"], ks=p["Ks"], F0=p["F0"], roughness=p["Roughness"],
                              distribution=p["Distribution"], geometry=p["Geometry"])


def _surface(g, i):
    """Surface half: roughness registers, n.v terms, 1 + Lambda(v), k = pi k_s / (4 n.v) times F0 and 1 - F0."""
    s = surface_common(g)
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


def _light(g, i, s):
    """Light half: k_d max(n.l, 0) + F k D G, D and G selected by Distribution and Geometry."""
    l, n_l = light_common(g, i, s)
    n_h, lv2, inv_lv = half_vector_cosines(g, s, l)
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


MODEL = Model(
    id="COOK_TORRANCE", label="Cook-Torrance", description="Microfacet specular: F D G / (4 n.l n.v)",
    group="IL Cook-Torrance", group_description="Cook-Torrance microfacet: I k_d n.l + pi I k_s F D G / (4 n.v)",
    order=40,
    params=(Input("Kd", C, (0.2, 0.2, 0.2, 1.0), None, "Lambertian part k_d"),
            Input("Ks", F, 1.0, (0.0, 1.0), "Weight k_s of the microfacet lobe"),
            Input("F0", F, 0.04, (0.0, 1.0), "Fresnel reflectance at normal incidence (Schlick)"),
            Input("Roughness", F, 0.3, (0.0, 1.0), "m (Beckmann) or alpha (GGX) itself, clamped to >= 1e-3"),
            Input("Distribution", F, 1.0, (0.0, 1.0), "0 Beckmann, 1 GGX"),
            Input("Geometry", F, 1.0, (0.0, 1.0), "0 Cook-Torrance 1982, 1 height-correlated Smith")),
    surface=_surface, light=_light, twin=_twin, switches=("Distribution", "Geometry"),
    sweep=(dict(Roughness=0.3, Distribution=0.0, Geometry=0.0, F0=0.2),
           dict(Roughness=0.2, Distribution=1.0, Geometry=1.0, F0=0.9),
           dict(Roughness=0.5, Distribution=0.0, Geometry=1.0, F0=0.04),
           dict(Roughness=0.4, Distribution=1.0, Geometry=0.0, F0=0.5)))
